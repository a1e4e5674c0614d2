//! Statistics-based colour mapping (thesis 4.5.3, eqs. 4.30–4.38; Reinhard et al.'s colour
//! transfer in CIELab with illuminant E, after Reinhard and Pouli). The source statistics are
//! those of TM(L_r), the target those of the (sRGB-decoded) camera image, both over the same
//! pixels: real modelled surfaces, L_r not black, camera not saturated — the black and virtual
//! pixels that eqs. 4.32 and 4.34 compensate for are simply not summed.
//!
//! Fallbacks: no usable pixel (a virtual object covers every real one, or nothing real is
//! modelled; n = n_zero) → the `off` mapping; a Lab channel of TM(L_r) with standard
//! deviation below 10⁻³ (a uniform proxy) → ratio 1 for that channel (the means still shift);
//! zero variance in the camera gives ratio 0, a constant channel, which is what 4.36 asks for.

use super::colour::{linear_to_lab, srgb_decode3, tone_map};
use super::{CmInput, CmParams, Mapping, sum_contributions, usable};

/// Contribution layout: [1, L_s, a_s, b_s, L_s², a_s², b_s², L_t, a_t, b_t, L_t², a_t², b_t²]
/// (s = TM(L_r), t = camera).
pub const K: usize = 13;

/// The contribution of pixel `i` (None: excluded).
pub fn contribution(input: &CmInput, i: usize, params: &CmParams, exposure: f32) -> Option<[f32; K]> {
    if !usable(input, i, params) {
        return None;
    }
    let s = linear_to_lab(tone_map(input.l_r[i], exposure));
    let t = linear_to_lab(srgb_decode3(input.photo[i]));
    Some([1.0, s.x, s.y, s.z, s.x * s.x, s.y * s.y, s.z * s.z, t.x, t.y, t.z, t.x * t.x, t.y * t.y, t.z * t.z])
}

pub fn cpu_sums(input: &CmInput, params: &CmParams, exposure: f32) -> [f64; K] {
    sum_contributions(input.photo.len(), |i| contribution(input, i, params, exposure))
}

/// Means, variances and the transfer from the sums: (mapping, pixels used, fallback).
pub fn solve(sums: &[f64; K]) -> (Mapping, usize, Option<String>) {
    let n = sums[0];
    if n < 1.0 {
        return (
            Mapping::Off,
            0,
            Some("no usable real pixel (all virtual, unmodelled, black or saturated): no statistics, cm off".into()),
        );
    }
    let mut mean_source = [0f32; 3];
    let mut mean_target = [0f32; 3];
    let mut ratio = [0f32; 3];
    let mut flat = Vec::new();
    for c in 0..3 {
        let ms = sums[1 + c] / n;
        let vs = (sums[4 + c] / n - ms * ms).max(0.0);
        let mt = sums[7 + c] / n;
        let vt = (sums[10 + c] / n - mt * mt).max(0.0);
        mean_source[c] = ms as f32;
        mean_target[c] = mt as f32;
        let (ss, st) = (vs.sqrt(), vt.sqrt());
        ratio[c] = if ss < 1e-3 {
            flat.push(["L", "a", "b"][c]);
            1.0
        } else {
            (st / ss) as f32
        };
    }
    let fallback = (!flat.is_empty()).then(|| {
        format!("zero variance in TM(L_r) for Lab channel(s) {}: ratio 1 there (mean shift only)", flat.join(", "))
    });
    (Mapping::Statistics { mean_source, mean_target, ratio }, n as usize, fallback)
}
