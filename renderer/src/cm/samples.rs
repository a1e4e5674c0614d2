//! Sample-based colour mapping (thesis 4.5.2, eqs. 4.20–4.27; Knecht et al.).
//!
//! 1. N colour samples on virtual objects: TM(L_rv) at N virtual pixels spread evenly over
//!    them in scan order ([`choose_samples`]).
//! 2. For each, the usable real pixel with the highest match (4.20–4.22; ties to the lowest
//!    index) — on the GPU one argmax reduction per sample — gives the pair
//!    ⟨C_r, C_cam⟩ = ⟨sRGB(TM(L_r)), L_cam⟩ there (4.23–4.24). The regression therefore maps
//!    what `off` would show to what the camera shows.
//! 3. The channel-swap heuristic (4.25–4.26) adds to each pair one copy with both colours'
//!    channels permuted; instead of a random permutation pair k uses the k mod 5-th of the five
//!    non-identity permutations (GRB first, as in 4.25), so frames are reproducible.
//! 4. One of three polynomial regressions ([`Regression`]) by least squares, per channel.
//! 5. Exponential smoothing a = u·a + (1 − u)·a' (4.27) with the coefficients of the previous
//!    frame from [`CmState`]; a fresh state (single frame) uses the new coefficients as they are.
//!
//! Fallbacks: no virtual pixel or no usable real pixel → identity on sRGB(TM(x)) (= `off`);
//! fewer pairs than unknowns, or a singular normal matrix → the next simpler polynomial
//! (affine or linear → per channel → identity), reported.

use super::colour::{hsv, hue_distance, srgb_encode3, tone_map};
use super::{CmInput, CmParams, CmState, Mapping, Regression, usable};
use crate::surface;
use glam::Vec3;

/// The five non-identity channel permutations, GRB first (eq. 4.25).
pub const PERMUTATIONS: [[usize; 3]; 5] = [[1, 0, 2], [0, 2, 1], [2, 1, 0], [1, 2, 0], [2, 0, 1]];

pub const IDENTITY: [[f32; 4]; 3] = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];

/// Up to `n` virtual pixels, evenly spread over the virtual pixels in scan order.
pub fn choose_samples(flags: &[u32], n: usize) -> Vec<usize> {
    let virt: Vec<usize> = (0..flags.len()).filter(|&i| flags[i] == surface::VIRTUAL).collect();
    let m = n.min(virt.len());
    (0..m).map(|k| virt[((2 * k + 1) * virt.len()) / (2 * m)]).collect()
}

/// The match of eqs. 4.20–4.22 between two tone-mapped colours.
pub fn match_score(a: Vec3, b: Vec3) -> f32 {
    let h_m = 0.5 - hue_distance(hsv(a).x, hsv(b).x);
    h_m / (1.0 + (a - b).length())
}

/// For each sample colour (already tone-mapped), the best-matching usable real pixel.
pub fn cpu_matches(input: &CmInput, params: &CmParams, exposure: f32, colours: &[Vec3]) -> Vec<Option<usize>> {
    let candidates: Vec<(usize, Vec3)> = (0..input.photo.len())
        .filter(|&i| usable(input, i, params))
        .map(|i| (i, tone_map(input.l_r[i], exposure)))
        .collect();
    colours
        .iter()
        .map(|&a| {
            let mut best: Option<(f32, usize)> = None;
            for &(i, b) in &candidates {
                let s = match_score(a, b);
                if best.is_none_or(|(bs, _)| s > bs) {
                    best = Some((s, i));
                }
            }
            best.map(|(_, i)| i)
        })
        .collect()
}

/// Least squares for one output channel: rows of regressors `x` and targets `y`; None when the
/// normal matrix is singular.
#[allow(clippy::needless_range_loop)]
fn least_squares(x: &[Vec<f64>], y: &[f64]) -> Option<Vec<f64>> {
    let p = x.first()?.len();
    let mut a = vec![vec![0f64; p + 1]; p];
    for (row, &t) in x.iter().zip(y) {
        for i in 0..p {
            for j in 0..p {
                a[i][j] += row[i] * row[j];
            }
            a[i][p] += row[i] * t;
        }
    }
    let scale = (0..p).map(|i| a[i][i]).fold(0.0, f64::max).max(1e-300);
    // Gaussian elimination with partial pivoting
    for col in 0..p {
        let pivot = (col..p).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() < 1e-9 * scale {
            return None;
        }
        a.swap(col, pivot);
        for r in 0..p {
            if r != col {
                let f = a[r][col] / a[col][col];
                for c in col..=p {
                    a[r][c] -= f * a[col][c];
                }
            }
        }
    }
    let solution: Vec<f64> = (0..p).map(|i| a[i][p] / a[i][i]).collect();
    solution.iter().all(|v| v.is_finite()).then_some(solution)
}

/// The regression of `mode` over the pairs ⟨C_r, C_cam⟩ as rows [a_r, a_g, a_b, a_0]; None when
/// there are fewer pairs than unknowns or the system is singular.
pub fn regress(pairs: &[(Vec3, Vec3)], mode: Regression) -> Option<[[f32; 4]; 3]> {
    let unknowns = match mode {
        Regression::PerChannel => 2,
        Regression::Linear => 3,
        Regression::Affine => 4,
    };
    if pairs.len() < unknowns {
        return None;
    }
    let mut rows = [[0f32; 4]; 3];
    for (o, row) in rows.iter_mut().enumerate() {
        let y: Vec<f64> = pairs.iter().map(|(_, cam)| cam[o] as f64).collect();
        match mode {
            Regression::PerChannel => {
                let x: Vec<Vec<f64>> = pairs.iter().map(|(r, _)| vec![1.0, r[o] as f64]).collect();
                let a = least_squares(&x, &y)?;
                row[o] = a[1] as f32;
                row[3] = a[0] as f32;
            }
            Regression::Linear => {
                let x: Vec<Vec<f64>> = pairs.iter().map(|(r, _)| vec![r.x as f64, r.y as f64, r.z as f64]).collect();
                let a = least_squares(&x, &y)?;
                *row = [a[0] as f32, a[1] as f32, a[2] as f32, 0.0];
            }
            Regression::Affine => {
                let x: Vec<Vec<f64>> =
                    pairs.iter().map(|(r, _)| vec![1.0, r.x as f64, r.y as f64, r.z as f64]).collect();
                let a = least_squares(&x, &y)?;
                *row = [a[1] as f32, a[2] as f32, a[3] as f32, a[0] as f32];
            }
        }
    }
    Some(rows)
}

/// Pairs with the channel-swap heuristic applied.
pub fn with_swaps(pairs: &[(Vec3, Vec3)]) -> Vec<(Vec3, Vec3)> {
    let permute = |c: Vec3, p: [usize; 3]| Vec3::new(c[p[0]], c[p[1]], c[p[2]]);
    let mut out = pairs.to_vec();
    out.extend(pairs.iter().enumerate().map(|(k, &(r, cam))| {
        let p = PERMUTATIONS[k % PERMUTATIONS.len()];
        (permute(r, p), permute(cam, p))
    }));
    out
}

/// Regression with the fallback chain; returns (rows, fallback reason).
pub fn fit(pairs: &[(Vec3, Vec3)], mode: Regression) -> ([[f32; 4]; 3], Option<String>) {
    if let Some(rows) = regress(pairs, mode) {
        return (rows, None);
    }
    if let Some(rows) = (mode != Regression::PerChannel).then(|| regress(pairs, Regression::PerChannel)).flatten() {
        return (
            rows,
            Some(format!(
                "{} pairs: too few or singular for the {mode:?} polynomial; per-channel polynomial used",
                pairs.len()
            )),
        );
    }
    (IDENTITY, Some(format!("{} pairs: too few or singular for any polynomial; identity (cm off)", pairs.len())))
}

/// The whole estimate; `matcher` returns the best real pixel per sample colour (CPU or GPU).
pub fn estimate(
    input: &CmInput,
    params: &CmParams,
    exposure: f32,
    state: &mut CmState,
    matcher: &dyn Fn(&[Vec3]) -> Vec<Option<usize>>,
) -> (Mapping, usize, Option<String>) {
    let chosen = choose_samples(input.flags, params.samples);
    let colours: Vec<Vec3> = chosen.iter().map(|&i| tone_map(input.l_rv[i], exposure)).collect();
    let matches = if colours.is_empty() { Vec::new() } else { matcher(&colours) };
    let pairs: Vec<(Vec3, Vec3)> =
        matches.iter().flatten().map(|&i| (srgb_encode3(tone_map(input.l_r[i], exposure)), input.photo[i])).collect();
    let pairs = with_swaps(&pairs);
    let (mut rows, mut fallback) = if chosen.is_empty() {
        (IDENTITY, Some("no virtual pixel to sample: identity (cm off)".to_string()))
    } else if pairs.is_empty() {
        (IDENTITY, Some("no usable real pixel to pair with: identity (cm off)".to_string()))
    } else {
        fit(&pairs, params.regression)
    };
    if let Some(previous) = state.samples {
        let u = params.smoothing.clamp(0.0, 1.0);
        for (row, prev) in rows.iter_mut().zip(previous) {
            for (a, p) in row.iter_mut().zip(prev) {
                *a = u * *a + (1.0 - u) * p;
            }
        }
        if fallback.is_some() {
            fallback = fallback.map(|f| f + ", smoothed with the previous frame");
        }
    }
    state.samples = Some(rows);
    (Mapping::Affine { rows }, pairs.len(), fallback)
}
