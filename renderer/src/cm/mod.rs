//! The `cm` factor: adaptive colour mapping of the two GI solution buffers before their
//! difference (thesis 4.5, equations 4.18 / 4.28), and the differential composition over the
//! photograph (4.17, or Debevec's scaled form 5.16–5.17). This module is the CPU reference
//! implementation; `gpu::cm` (`cm.wgsl`) computes the same per-pixel contributions, reduces
//! them on the GPU and maps the buffers, and `gpu::compose` (`compose.wgsl`) composes. Both
//! sides share the tiny solves in between ([`statistics::solve`], [`samples::fit`],
//! [`rohmer::solve`]), so the tests compare reductions, mappings and images.
//!
//! Methods ([`CmMethod`]):
//! * `off` — the simplified Reinhard operator x/(1+x), then sRGB encoding (4.16);
//! * `statistics` — Reinhard et al.'s colour transfer in CIELab with illuminant E (4.30–4.38):
//!   τ(c) = f⁻¹(σ_cam/σ_r (f(TM(c)) − μ_r) + μ_cam) per Lab channel, with the means and variances
//!   of the tone-mapped L_r and of the camera image over the same masked pixels (real, modelled,
//!   not black, camera not saturated), i.e. what 4.32 and 4.34 compensate for, computed exactly;
//! * `samples` — sample-based mapping (4.20–4.27): hue-matched sample pairs, the channel-swap
//!   heuristic, one of three polynomial regressions, exponential smoothing u = 0.3 across
//!   frames through [`CmState`];
//! * `rohmer` — Rohmer et al.'s linear colour compensation (their Section 4 and 6.6): filtered
//!   sample pairs, the weights of their eq. 1, the diagonal approximation A_t, the regularised
//!   least squares of eq. 2, and C_t⁻¹ applied at composition, which runs in the camera's
//!   linearised space (gamma 2.2).
//!
//! Every failure has a documented fallback that is reported ([`CmReport::fallback`]), never a
//! NaN: see each method's module. The statistics method also reports a channel ratio outside
//! [0.5, 2] ([`CmReport::warning`], [`statistics::RatioWarning`]) without changing the mapping.

pub mod colour;
pub mod rohmer;
pub mod samples;
pub mod statistics;

use crate::math::luminance;
use crate::surface;
use colour::{gamma_decode, gamma_encode, srgb_encode3, tone_map};
use glam::Vec3;
use serde::Serialize;

/// The colour-mapping method (the level of the `cm` factor and its alternatives).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CmMethod {
    /// The simplified Reinhard tone mapping (cm off).
    #[default]
    Off,
    /// Statistics-based colour transfer in CIELab (E) — the thesis's web-survey cm.
    Statistics,
    /// Sample-based mapping with polynomial regression.
    Samples,
    /// Rohmer et al.'s linear colour compensation.
    Rohmer,
}

impl CmMethod {
    pub const ALL: [CmMethod; 4] = [CmMethod::Off, CmMethod::Statistics, CmMethod::Samples, CmMethod::Rohmer];
    pub fn parse(name: &str) -> Option<CmMethod> {
        match name.trim().to_ascii_lowercase().as_str() {
            "off" | "none" | "reinhard" => Some(CmMethod::Off),
            "statistics" | "stats" => Some(CmMethod::Statistics),
            "samples" | "sample" => Some(CmMethod::Samples),
            "rohmer" => Some(CmMethod::Rohmer),
            _ => None,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            CmMethod::Off => "off",
            CmMethod::Statistics => "statistics",
            CmMethod::Samples => "samples",
            CmMethod::Rohmer => "rohmer",
        }
    }
}

/// How the mapped differential is added to the photograph.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Composition {
    /// L_final = L'_cam + (τ(L_rv) − τ(L_r)) (4.17 / 4.19 / 4.29).
    #[default]
    Additive,
    /// Debevec's scaled form (5.16–5.17): L_final = L'_cam + α (τ(L_rv) − τ(L_r)) with
    /// α = L'_cam / τ(L_r) per channel on real pixels where τ(L_r) > 10⁻⁴, else α = 1.
    Scaled,
}

impl Composition {
    pub fn parse(name: &str) -> Option<Composition> {
        match name.trim().to_ascii_lowercase().as_str() {
            "additive" | "add" => Some(Composition::Additive),
            "scaled" | "debevec" => Some(Composition::Scaled),
            _ => None,
        }
    }
}

/// The three polynomials of the sample-based method (thesis 4.5.2), per output channel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Regression {
    /// (A) C_cam(x) = a0 + a1·x, channel by channel.
    PerChannel,
    /// (B) C_cam = a0·r + a1·g + a2·b.
    Linear,
    /// (C) C_cam = a0 + a1·r + a2·g + a3·b (the thesis's best).
    #[default]
    Affine,
}

/// The knobs of colour mapping (defaults: the papers' values where they give one).
#[derive(Clone, Debug, Serialize)]
pub struct CmParams {
    pub method: CmMethod,
    /// samples: colour samples taken on virtual objects (N).
    pub samples: usize,
    pub regression: Regression,
    /// samples: exponential smoothing weight u of the new coefficients (4.27).
    pub smoothing: f32,
    /// rohmer: β of eq. 1 for the approximation A_t and for C_t.
    pub beta_approx: f32,
    pub beta_fit: f32,
    /// rohmer: γ of eq. 2.
    pub gamma: f32,
    /// rohmer: fewer filtered pairs than this use A_t (Rohmer: n > 2000 at their resolution).
    pub min_pairs: usize,
    /// Camera pixels with a channel at or above this (display) are saturated: excluded from
    /// every method's statistics and pairs.
    pub saturated: f32,
    /// rohmer: camera pixels with every channel at or below this are under-exposed: excluded.
    pub dark: f32,
    /// rohmer: pairs whose local gradient (display units, either image) exceeds this are dropped.
    pub gradient: f32,
    /// rohmer: coarse filter on the hue–saturation distance, and the fine HSV filter after c_{t−1}.
    pub hs_coarse: f32,
    pub hsv_fine: f32,
}

impl Default for CmParams {
    fn default() -> Self {
        CmParams {
            method: CmMethod::Off,
            samples: 64,
            regression: Regression::Affine,
            smoothing: 0.3,
            beta_approx: 2.0,
            beta_fit: 8.0,
            gamma: 0.05,
            min_pairs: 100,
            saturated: 250.0 / 255.0,
            dark: 5.0 / 255.0,
            gradient: 0.1,
            hs_coarse: 0.5,
            hsv_fine: 0.3,
        }
    }
}

/// What carries across frames for live use: the sample-based method's smoothed coefficients
/// (a'_i of 4.27) and Rohmer's last C_t (used to filter the next frame's pairs). A fresh state
/// is a single frame without history.
#[derive(Clone, Debug, Default, Serialize)]
pub struct CmState {
    pub samples: Option<[[f32; 4]; 3]>,
    pub rohmer: Option<[[f32; 3]; 3]>,
    pub frames: u64,
}

/// The per-pixel mapping a frame applies to both buffers, in the form the GPU map pass reads.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Mapping {
    /// sRGB(TM(x)).
    Off,
    /// Lab transfer of TM(x): per channel (ℓ − mean_source) · ratio + mean_target.
    Statistics { mean_source: [f32; 3], mean_target: [f32; 3], ratio: [f32; 3] },
    /// Rows [a_r, a_g, a_b, a_0] applied to sRGB(TM(x)) (display domain).
    Affine { rows: [[f32; 4]; 3] },
    /// A 3×3 matrix applied to linear x; composition in the gamma-2.2 linear domain.
    Linear { rows: [[f32; 3]; 3] },
}

impl Mapping {
    /// Whether composition runs on gamma-2.2-linearised camera values (Rohmer) rather than on
    /// display values.
    pub fn linear_domain(&self) -> bool {
        matches!(self, Mapping::Linear { .. })
    }

    /// τ(x) for one linear radiance value.
    pub fn apply(&self, x: Vec3, exposure: f32) -> Vec3 {
        match self {
            Mapping::Off => srgb_encode3(tone_map(x, exposure)),
            Mapping::Statistics { mean_source, mean_target, ratio } => {
                let lab = colour::linear_to_lab(tone_map(x, exposure));
                let t =
                    (lab - Vec3::from_array(*mean_source)) * Vec3::from_array(*ratio) + Vec3::from_array(*mean_target);
                srgb_encode3(colour::lab_to_linear(t).max(Vec3::ZERO))
            }
            Mapping::Affine { rows } => {
                let c = srgb_encode3(tone_map(x, exposure));
                let row = |r: &[f32; 4]| r[0] * c.x + r[1] * c.y + r[2] * c.z + r[3];
                Vec3::new(row(&rows[0]), row(&rows[1]), row(&rows[2]))
            }
            Mapping::Linear { rows } => {
                let x = x.max(Vec3::ZERO);
                let row = |r: &[f32; 3]| r[0] * x.x + r[1] * x.y + r[2] * x.z;
                Vec3::new(row(&rows[0]), row(&rows[1]), row(&rows[2]))
            }
        }
    }
}

/// What the colour mapping of one frame found.
#[derive(Clone, Debug, Serialize)]
pub struct CmReport {
    pub method: CmMethod,
    pub mapping: Mapping,
    /// Pixels (statistics) or sample pairs (samples: after the channel swap; rohmer: after both
    /// filters) the estimate used.
    pub pairs: usize,
    /// Why a simpler mapping was used, if one was.
    pub fallback: Option<String>,
    /// statistics: a Lab channel ratio outside [0.5, 2] (the mapping as specified, reported).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub warning: Option<statistics::RatioWarning>,
}

/// One frame's buffers as the colour mapping sees them (row-major, width·height each).
pub struct CmInput<'a> {
    pub width: u32,
    pub height: u32,
    /// Linear L_rv and L_r.
    pub l_rv: &'a [Vec3],
    pub l_r: &'a [Vec3],
    /// Per pixel: 0 nothing modelled, 1 real surface, 2 virtual surface.
    pub flags: &'a [u32],
    /// The photograph, display-encoded.
    pub photo: &'a [Vec3],
}

/// The mapped buffers, the composite and the report of [`cpu_frame`].
pub struct CmOutput {
    pub mapped_rv: Vec<Vec3>,
    pub mapped_r: Vec<Vec3>,
    pub composite: Vec<Vec3>,
    pub report: CmReport,
}

/// Whether pixel `i` may enter the colour statistics: a real modelled surface, L_r not black,
/// the camera not saturated.
pub fn usable(input: &CmInput, i: usize, params: &CmParams) -> bool {
    input.flags[i] == surface::REAL && luminance(input.l_r[i]) > 1e-6 && input.photo[i].max_element() < params.saturated
}

/// Composition of one pixel: `photo` display-encoded, `m_rv`/`m_r` the mapped buffers.
/// Real pixels whose differential is exactly zero keep the photograph bit for bit; virtual
/// pixels show `m_rv` alone (their L_r is 0: no real solution, so no τ(0) is subtracted).
pub fn compose(linear_domain: bool, composition: Composition, photo: Vec3, flag: u32, m_rv: Vec3, m_r: Vec3) -> Vec3 {
    if flag == surface::NOTHING || (flag == surface::REAL && m_rv == m_r) {
        return photo;
    }
    let r_p = if flag == surface::REAL { 1.0 } else { 0.0 };
    let cam = if linear_domain { gamma_decode(photo) } else { photo } * r_p;
    // A virtual pixel has no real solution (L_r = 0 there): it shows τ(L_rv) alone. Taking
    // eq. 4.19 literally would subtract τ(0), which is not 0 for a mapping with an offset (the
    // samples method's affine polynomial, the statistics method's shift of means), and darken
    // every virtual object by that offset.
    let m_r = m_r * r_p;
    let mut delta = m_rv - m_r;
    if composition == Composition::Scaled {
        let alpha = |c: f32, m: f32| if r_p > 0.0 && m > 1e-4 { c / m } else { 1.0 };
        delta *= Vec3::new(alpha(cam.x, m_r.x), alpha(cam.y, m_r.y), alpha(cam.z, m_r.z));
    }
    let out = (cam + delta).clamp(Vec3::ZERO, Vec3::ONE);
    if linear_domain { gamma_encode(out) } else { out }
}

/// The whole colour mapping and composition of one frame on the CPU: estimate the mapping
/// (updating `state`), map both buffers, compose.
pub fn cpu_frame(
    input: &CmInput,
    params: &CmParams,
    exposure: f32,
    composition: Composition,
    state: &mut CmState,
) -> CmOutput {
    let mut warning = None;
    let (mapping, pairs, fallback) = match params.method {
        CmMethod::Off => (Mapping::Off, 0, None),
        CmMethod::Statistics => {
            let sums = statistics::cpu_sums(input, params, exposure);
            warning = statistics::ratio_warning(&sums);
            statistics::solve(&sums)
        }
        CmMethod::Samples => samples::estimate(input, params, exposure, state, &|colours| {
            samples::cpu_matches(input, params, exposure, colours)
        }),
        CmMethod::Rohmer => {
            let approx = rohmer::cpu_sums(input, params, exposure, None);
            let a = rohmer::approximation(&approx, params);
            let previous = state.rohmer.map(rohmer::from_rows).unwrap_or(a.0);
            let fit = rohmer::cpu_sums(input, params, exposure, Some(&previous));
            rohmer::solve(&approx, &fit, params, state)
        }
    };
    state.frames += 1;
    let mapped_rv: Vec<Vec3> = input.l_rv.iter().map(|&x| mapping.apply(x, exposure)).collect();
    let mapped_r: Vec<Vec3> = input.l_r.iter().map(|&x| mapping.apply(x, exposure)).collect();
    let linear = mapping.linear_domain();
    let composite = (0..input.photo.len())
        .map(|i| compose(linear, composition, input.photo[i], input.flags[i], mapped_rv[i], mapped_r[i]))
        .collect();
    CmOutput {
        mapped_rv,
        mapped_r,
        composite,
        report: CmReport { method: params.method, mapping, pairs, fallback, warning },
    }
}

/// Sums per-pixel contribution vectors in f64 (the CPU side of a GPU reduction).
pub(crate) fn sum_contributions<const K: usize>(n: usize, f: impl Fn(usize) -> Option<[f32; K]>) -> [f64; K] {
    let mut sums = [0f64; K];
    for i in 0..n {
        if let Some(c) = f(i) {
            for k in 0..K {
                sums[k] += c[k] as f64;
            }
        }
    }
    sums
}

#[cfg(test)]
pub(crate) mod tests;
