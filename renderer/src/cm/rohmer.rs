//! Rohmer et al.'s linear colour compensation ("Natural environment illumination: coherent
//! interactive augmented reality for mobile and non-mobile devices", Sections 4 and 6.6).
//!
//! Pairs ⟨u_i, r_i⟩ are the camera pixel linearised with gamma 2.2 and L_r (the reference
//! rendering, linear HDR) at the same real pixel. Filter 1 (Section 4.1) drops pixels that are
//! not real modelled surfaces, black in L_r, over- (any channel ≥ `saturated`) or
//! under-exposed (all ≤ `dark`) in the camera, on a strong gradient in either image (central
//! differences of display values, or a neighbour that is not real), or further apart than
//! `hs_coarse` in the hue–saturation disc (saturation as radius, hue as angle — read as the
//! HSV cone's cross-section so that greys are close whatever their hue). Filter 2 maps u_i by
//! c_{t−1} (the previous frame's C from [`CmState`], or this frame's A_t without history) and
//! drops pairs further than `hsv_fine` apart in HSV (the disc plus the relative difference of
//! the values). Weights: eq. 1, w = (1 − min(1, d_hs))^β with β = 2 for A_t and 8 for C_t.
//!
//! A_t = diag(Σw r / Σw u) (Section 4.2); C_t by eq. 2,
//! C_t = ((U W² Uᵀ + γI)⁻¹ (U W² Rᵀ + γA_t))ᵀ, γ = 0.05. At composition C_t⁻¹ maps L_rv and L_r
//! into the camera's linear space, where L'_cam + C⁻¹L_rv − C⁻¹L_r is formed and gamma-encoded
//! (Section 6.6, which inverts the compensated composite — the same thing by linearity).
//!
//! Fallbacks to the diagonal approximation A_t (as Rohmer marks such frames "approximated"):
//! fewer filtered pairs than `min_pairs` (includes fewer pairs than the nine unknowns), an
//! ill-conditioned U W² Uᵀ (normalised determinant det/(tr/3)³ < 10⁻⁶, e.g. grey-only samples),
//! or a C_t that is not safely invertible (det ≤ 0 or Frobenius condition number > 10⁴). No
//! pair at all gives A_t = I.

use super::colour::{gamma_decode, hsv, srgb_encode3, tone_map};
use super::{CmInput, CmParams, CmState, Mapping, sum_contributions};
use crate::math::luminance;
use glam::{Mat3, Vec3};

/// Approximation contribution: [1, w, w·u (3), w·r (3)].
pub const KA: usize = 8;
/// Fit contribution: [1, w·u uᵀ (9, row-major), w·u rᵀ (9, row-major)].
pub const KF: usize = 19;

pub fn from_rows(rows: [[f32; 3]; 3]) -> Mat3 {
    Mat3::from_cols_array_2d(&rows).transpose()
}

pub fn to_rows(m: Mat3) -> [[f32; 3]; 3] {
    m.transpose().to_cols_array_2d()
}

/// A point of the HSV hue–saturation disc.
pub fn disc(c: Vec3) -> (f32, f32, f32) {
    let h = hsv(c);
    let angle = h.x * std::f32::consts::TAU;
    (h.y * angle.cos(), h.y * angle.sin(), h.z)
}

/// Distance of two colours in the hue–saturation disc.
pub fn hs_distance(a: Vec3, b: Vec3) -> f32 {
    let (ax, ay, _) = disc(a);
    let (bx, by, _) = disc(b);
    ((ax - bx) * (ax - bx) + (ay - by) * (ay - by)).sqrt()
}

/// Distance in HSV: the disc plus the relative difference of the values.
pub fn hsv_distance(a: Vec3, b: Vec3) -> f32 {
    let (ax, ay, av) = disc(a);
    let (bx, by, bv) = disc(b);
    let dv = (av - bv).abs() / av.max(bv).max(1e-6);
    ((ax - bx) * (ax - bx) + (ay - by) * (ay - by) + dv * dv).sqrt()
}

/// Filter 1 for pixel `i`: Some(hue–saturation distance) when the pair is kept.
pub fn filter1(input: &CmInput, i: usize, params: &CmParams, exposure: f32) -> Option<f32> {
    let (w, h) = (input.width as usize, input.height as usize);
    let (x, y) = (i % w, i / w);
    let lum = luminance(input.l_r[i]);
    if input.flags[i] != 1 || lum.is_nan() || lum <= 1e-6 {
        return None;
    }
    let cam = input.photo[i];
    if cam.max_element() >= params.saturated || cam.max_element() <= params.dark {
        return None;
    }
    if x == 0 || y == 0 || x + 1 >= w || y + 1 >= h {
        return None;
    }
    let (l, r, u, d) = (i - 1, i + 1, i - w, i + w);
    if [l, r, u, d].iter().any(|&j| input.flags[j] != 1) {
        return None;
    }
    let gradient = |f: &dyn Fn(usize) -> Vec3| (((f(r) - f(l)).abs() + (f(d) - f(u)).abs()) * 0.5).max_element();
    if gradient(&|j| input.photo[j]) > params.gradient
        || gradient(&|j| srgb_encode3(tone_map(input.l_r[j], exposure))) > params.gradient
    {
        return None;
    }
    let d_hs = hs_distance(gamma_decode(cam), input.l_r[i]);
    (d_hs <= params.hs_coarse).then_some(d_hs)
}

/// The contribution of pixel `i` to the approximation A_t.
pub fn contribution_approx(input: &CmInput, i: usize, params: &CmParams, exposure: f32) -> Option<[f32; KA]> {
    let d = filter1(input, i, params, exposure)?;
    let w = (1.0 - d.min(1.0)).powf(params.beta_approx);
    let (u, r) = (gamma_decode(input.photo[i]), input.l_r[i]);
    Some([1.0, w, w * u.x, w * u.y, w * u.z, w * r.x, w * r.y, w * r.z])
}

/// The contribution of pixel `i` to eq. 2, after filter 2 with `previous` (c_{t−1}).
pub fn contribution_fit(
    input: &CmInput,
    i: usize,
    params: &CmParams,
    exposure: f32,
    previous: &Mat3,
) -> Option<[f32; KF]> {
    let d = filter1(input, i, params, exposure)?;
    let (u, r) = (gamma_decode(input.photo[i]), input.l_r[i]);
    if hsv_distance(*previous * u, r) > params.hsv_fine {
        return None;
    }
    let w = (1.0 - d.min(1.0)).powf(params.beta_fit);
    let mut c = [0f32; KF];
    c[0] = 1.0;
    for a in 0..3 {
        for b in 0..3 {
            c[1 + 3 * a + b] = w * u[a] * u[b];
            c[10 + 3 * a + b] = w * u[a] * r[b];
        }
    }
    Some(c)
}

/// Both reductions on the CPU: the approximation's sums (`previous` None) or the fit's.
pub fn cpu_sums(input: &CmInput, params: &CmParams, exposure: f32, previous: Option<&Mat3>) -> Vec<f64> {
    let n = input.photo.len();
    match previous {
        None => sum_contributions(n, |i| contribution_approx(input, i, params, exposure)).to_vec(),
        Some(p) => sum_contributions(n, |i| contribution_fit(input, i, params, exposure, p)).to_vec(),
    }
}

/// A_t from the approximation sums: (matrix, fallback when there was no pair).
pub fn approximation(sums: &[f64], _params: &CmParams) -> (Mat3, Option<String>) {
    if sums[1] <= 0.0 {
        return (Mat3::IDENTITY, Some("no camera/L_r pair survived filtering: identity".into()));
    }
    let s: Vec<f32> = (0..3)
        .map(|c| {
            let (u, r) = (sums[2 + c], sums[5 + c]);
            let s = r / u;
            if u > 1e-12 && s.is_finite() && s > 0.0 { s as f32 } else { 1.0 }
        })
        .collect();
    (Mat3::from_diagonal(Vec3::new(s[0], s[1], s[2])), None)
}

type M3 = [[f64; 3]; 3];

fn det(m: &M3) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

#[allow(clippy::needless_range_loop)]
fn inverse(m: &M3) -> Option<M3> {
    let d = det(m);
    if d == 0.0 || !d.is_finite() {
        return None;
    }
    let mut inv = [[0f64; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let (a, b) = ((j + 1) % 3, (j + 2) % 3);
            let (c, e) = ((i + 1) % 3, (i + 2) % 3);
            inv[i][j] = (m[a][c] * m[b][e] - m[a][e] * m[b][c]) / d;
        }
    }
    Some(inv)
}

fn mul(a: &M3, b: &M3) -> M3 {
    let mut out = [[0f64; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            out[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    out
}

fn frobenius(m: &M3) -> f64 {
    m.iter().flatten().map(|v| v * v).sum::<f64>().sqrt()
}

/// C_t by eq. 2 from the fit sums, with the fallbacks; `a` is A_t. Returns (C_t, fallback).
pub fn fit_matrix(fit: &[f64], a: &Mat3, params: &CmParams) -> (Mat3, Option<String>) {
    let n = fit[0] as usize;
    if n < params.min_pairs.max(9) {
        return (
            *a,
            Some(format!("{n} filtered pairs, fewer than {}: diagonal approximation A_t", params.min_pairs.max(9))),
        );
    }
    let mut g: M3 = [[0.0; 3]; 3];
    let mut b: M3 = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            g[i][j] = fit[1 + 3 * i + j];
            b[i][j] = fit[10 + 3 * i + j];
        }
    }
    let trace = (g[0][0] + g[1][1] + g[2][2]) / 3.0;
    if trace <= 0.0 || det(&g) / (trace * trace * trace) < 1e-6 {
        return (*a, Some("U W² Uᵀ is singular or ill-conditioned (the pairs span fewer than three colour directions): diagonal approximation A_t".into()));
    }
    let a_rows = to_rows(*a);
    let gamma = params.gamma as f64;
    let mut lhs = g;
    let mut rhs = b;
    for i in 0..3 {
        lhs[i][i] += gamma;
        for j in 0..3 {
            rhs[i][j] += gamma * a_rows[i][j] as f64;
        }
    }
    let Some(lhs_inv) = inverse(&lhs) else {
        return (*a, Some("eq. 2's normal matrix is singular: diagonal approximation A_t".into()));
    };
    let x = mul(&lhs_inv, &rhs);
    let c: M3 = [[x[0][0], x[1][0], x[2][0]], [x[0][1], x[1][1], x[2][1]], [x[0][2], x[1][2], x[2][2]]];
    let ok = det(&c) > 0.0
        && inverse(&c).is_some_and(|ci| frobenius(&c) * frobenius(&ci) < 1e4)
        && c.iter().flatten().all(|v| v.is_finite());
    if !ok {
        return (
            *a,
            Some("C_t is not safely invertible (det ≤ 0 or condition > 10⁴): diagonal approximation A_t".into()),
        );
    }
    (from_rows(c.map(|r| r.map(|v| v as f32))), None)
}

/// The mapping C⁻¹ from both sums; stores C_t in `state`.
pub fn solve(approx: &[f64], fit: &[f64], params: &CmParams, state: &mut CmState) -> (Mapping, usize, Option<String>) {
    let (a, none) = approximation(approx, params);
    let (c, fallback) = if none.is_some() { (a, none) } else { fit_matrix(fit, &a, params) };
    state.rohmer = Some(to_rows(c));
    (Mapping::Linear { rows: to_rows(c.inverse()) }, fit[0] as usize, fallback)
}
