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
//!
//! A ratio σ_cam/σ_r outside [[`RATIO_WARN_BELOW`], [`RATIO_WARN_ABOVE`]] is not a fallback (the
//! mapping is as specified) but is reported as a [`RatioWarning`]: on a grey real scene such as
//! `dir-lamp-box` the camera's noise is transferred, not its colour rendering (docs/renderer.md,
//! "The statistics mapping on a grey real scene").

use super::colour::{linear_to_lab, srgb_decode3, tone_map};
use super::{CmInput, CmParams, Mapping, sum_contributions, usable};
use serde::Serialize;

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

/// A channel ratio below this is reported ([`RatioWarning`]).
pub const RATIO_WARN_BELOW: f32 = 0.5;
/// A channel ratio above this is reported ([`RatioWarning`]).
pub const RATIO_WARN_ABOVE: f32 = 2.0;

/// The section of docs/renderer.md that explains a [`RatioWarning`].
pub const RATIO_WARNING_DOC: &str =
    "docs/renderer.md, \"The statistics mapping on a grey real scene (dir-lamp-box): the method as specified\"";

/// One Lab channel's statistics: mean and standard deviation of TM(L_r) and of the camera.
#[derive(Clone, Copy, Debug)]
struct Moments {
    mean_source: f64,
    sd_source: f64,
    mean_target: f64,
    sd_target: f64,
}

/// Each Lab channel's moments from the sums (None: no usable pixel).
fn moments(sums: &[f64; K]) -> Option<[Moments; 3]> {
    let n = sums[0];
    if n < 1.0 {
        return None;
    }
    Some(std::array::from_fn(|c| {
        let ms = sums[1 + c] / n;
        let mt = sums[7 + c] / n;
        Moments {
            mean_source: ms,
            sd_source: (sums[4 + c] / n - ms * ms).max(0.0).sqrt(),
            mean_target: mt,
            sd_target: (sums[10 + c] / n - mt * mt).max(0.0).sqrt(),
        }
    }))
}

/// A Lab channel's ratio σ_cam/σ_r with its two standard deviations.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ChannelRatio {
    /// `L`, `a` or `b`.
    pub channel: &'static str,
    pub ratio: f32,
    /// σ of the camera image (the target).
    pub sd_camera: f32,
    /// σ of TM(L_r) (the source).
    pub sd_render: f32,
}

/// The statistics mapping was solved with a channel ratio outside [0.5, 2]: the mapping is the
/// method as specified (no fallback), but it multiplies that channel's differences from the
/// mean (chroma for a and b, lightness contrast for L) by the ratio, so colours may clip or
/// wash out. `message` is the sentence without the scene; [`RatioWarning::sentence`] adds it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RatioWarning {
    /// The channels outside the range, in L, a, b order.
    pub channels: Vec<ChannelRatio>,
    pub message: String,
}

impl RatioWarning {
    fn new(channels: Vec<ChannelRatio>) -> RatioWarning {
        let listed: Vec<String> = channels
            .iter()
            .map(|c| {
                format!(
                    "{} {} (σ camera {} / σ render {})",
                    c.channel,
                    round(c.ratio),
                    round(c.sd_camera),
                    round(c.sd_render)
                )
            })
            .collect();
        let effect = |names: &[&str], what: &str| {
            let picked: Vec<f32> = channels.iter().filter(|c| names.contains(&c.channel)).map(|c| c.ratio).collect();
            // the ratio furthest from 1 on a log scale
            let ratio = picked.into_iter().max_by(|x, y| x.max(1e-6).ln().abs().total_cmp(&y.max(1e-6).ln().abs()))?;
            let consequence = if ratio > 1.0 { "may clip" } else { "may wash out" };
            Some(format!("{what} multiplied about {}× (colours {consequence})", round(ratio)))
        };
        let effects: Vec<String> =
            [effect(&["a", "b"], "chroma"), effect(&["L"], "lightness contrast")].into_iter().flatten().collect();
        let message = format!(
            "the statistics colour mapping (cm) has Lab ratio σ_camera/σ_render outside [{RATIO_WARN_BELOW}, {RATIO_WARN_ABOVE}] for {}: {}; see {RATIO_WARNING_DOC}",
            listed.join(", "),
            effects.join(", ")
        );
        RatioWarning { channels, message }
    }

    /// The one-sentence warning naming the scene.
    pub fn sentence(&self, scene: &str) -> String {
        format!("scene \"{scene}\": {}", self.message)
    }
}

/// Three significant digits, at most three decimals (a ratio of 19.9, a σ of 0.146).
fn round(x: f32) -> String {
    let decimals = if x.abs() >= 100.0 {
        0
    } else if x.abs() >= 10.0 {
        1
    } else if x.abs() >= 1.0 {
        2
    } else {
        3
    };
    format!("{x:.decimals$}")
}

/// The [`RatioWarning`] of the mapping [`solve`] makes from `sums`, if a channel's ratio lies
/// outside [[`RATIO_WARN_BELOW`], [`RATIO_WARN_ABOVE`]]. A channel that fell back to ratio 1
/// (σ_r below 10⁻³) and a frame without usable pixels give none.
pub fn ratio_warning(sums: &[f64; K]) -> Option<RatioWarning> {
    let moments = moments(sums)?;
    let channels: Vec<ChannelRatio> = (0..3)
        .filter_map(|c| {
            let m = moments[c];
            let ratio = channel_ratio(m)?;
            (!(RATIO_WARN_BELOW..=RATIO_WARN_ABOVE).contains(&ratio)).then(|| ChannelRatio {
                channel: ["L", "a", "b"][c],
                ratio,
                sd_camera: m.sd_target as f32,
                sd_render: m.sd_source as f32,
            })
        })
        .collect();
    (!channels.is_empty()).then(|| RatioWarning::new(channels))
}

/// σ_cam/σ_r, or None where σ_r is below 10⁻³ (the uniform-proxy fallback: ratio 1).
fn channel_ratio(m: Moments) -> Option<f32> {
    (m.sd_source >= 1e-3).then(|| (m.sd_target / m.sd_source) as f32)
}

/// Means, variances and the transfer from the sums: (mapping, pixels used, fallback).
pub fn solve(sums: &[f64; K]) -> (Mapping, usize, Option<String>) {
    let Some(moments) = moments(sums) else {
        return (
            Mapping::Off,
            0,
            Some("no usable real pixel (all virtual, unmodelled, black or saturated): no statistics, cm off".into()),
        );
    };
    let mut mean_source = [0f32; 3];
    let mut mean_target = [0f32; 3];
    let mut ratio = [0f32; 3];
    let mut flat = Vec::new();
    for c in 0..3 {
        let m = moments[c];
        mean_source[c] = m.mean_source as f32;
        mean_target[c] = m.mean_target as f32;
        ratio[c] = channel_ratio(m).unwrap_or_else(|| {
            flat.push(["L", "a", "b"][c]);
            1.0
        });
    }
    let fallback = (!flat.is_empty()).then(|| {
        format!("zero variance in TM(L_r) for Lab channel(s) {}: ratio 1 there (mean shift only)", flat.join(", "))
    });
    (Mapping::Statistics { mean_source, mean_target, ratio }, sums[0] as usize, fallback)
}
