//! Single-image estimates of the camera's noise, blur and JPEG quality, used to parameterise the
//! ca chain from the photograph (`--ca-params estimate`) and to measure how closely virtual
//! regions match real ones.
//!
//! - **Noise** ([`noise`]): Immerkær's fast estimator (Immerkær, "Fast noise variance
//!   estimation", CVIU 64(2), 1996): σ = √(π/2)·mean|I ∗ N|/6 with the 3×3 kernel
//!   N = [1 −2 1; −2 4 −2; 1 −2 1], which cancels constant and linear shading. Samples on edges
//!   (Sobel magnitude above 4·√12 times a first robust σ) and next to clipped values (≤ 0.01 or
//!   ≥ 0.99) are left out. For a Poisson–Gaussian fit (in the spirit of Foi et al., IEEE TIP
//!   17(10), 2008) the samples are binned by their 3×3 mean into 16 intensity bins; each bin with
//!   at least 64 samples gives σ²_k, and σ²(d) = a·d + b is fitted by least squares weighted by
//!   the bin counts, with a, b ≥ 0 (a negative coefficient is set to 0 and the other refitted).
//!   Fallbacks, never NaN: one usable bin or an intensity spread under 0.1 → a = 0, b = σ²
//!   ("gaussian"); no usable sample (a uniform or fully clipped image) → a = b = 0 ("none").
//! - **Blur** ([`blur`]): edge-based. At local maxima of the Sobel gradient, the edge profile is
//!   sampled across the edge (±8 px, 0.25 px steps, bilinear); isolated steps (flat plateaus,
//!   contrast ≥ 0.1) give a 10–90 % rise distance. Its 20th percentile over edges (shading and
//!   soft shadows make many edges wider than the camera's blur; the sharpest ones show the
//!   camera) is mapped to the radius of a defocus disc through a calibration table made by the
//!   same measurement on an ideal area-sampled disc (edges at every angle) blurred by discs of known radius (0 … 6 px).
//!   No edge → None.
//! - **JPEG quality** ([`jpeg_quality`]): the luma DCT coefficients of the 8×8 grid are
//!   quantised to multiples of the table step q. For the 9 lowest AC frequencies the candidates
//!   are the mode of round(|c|) over |c| ≥ 1.5 (the ±q cluster is usually the most populated
//!   non-zero one), its half and its third, each ±1; the one whose residuals (distance to the
//!   nearest multiple, in units of q) have the smallest mean square is taken if that is below
//!   1/48 (uniform residuals give 1/12). The libjpeg quality whose scaled table best matches the
//!   detected steps (least squares in log q) is reported. Fewer than two detected steps (quality
//!   above about 95, or no compression: steps indistinguishable from 8-bit rounding) → None.

use super::{CaParams, NOISE_LUT, ParamSource};
use crate::camera::Camera;
use crate::image::{Image, Mask};
use crate::sensor::SensorParams;
use serde::Serialize;
use std::sync::OnceLock;

/// A noise estimate on display values.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NoiseEstimate {
    /// Immerkær's σ over all usable samples (display units).
    pub sigma: f32,
    /// σ²(d) = a·d + b.
    pub a: f32,
    pub b: f32,
    /// "poisson-gaussian", "gaussian" or "none" (see the module header).
    pub fit: &'static str,
    /// Pixel-channel samples used.
    pub samples: usize,
    /// (mean intensity, σ, samples) of each usable bin.
    pub bins: Vec<(f32, f32, usize)>,
}

/// A blur estimate.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BlurEstimate {
    /// Equivalent defocus disc radius in pixels; None without a usable edge.
    pub radius_px: Option<f32>,
    /// 20th percentile of the 10–90 % edge rise distances (pixels).
    pub edge_width_px: Option<f32>,
    pub edges: usize,
}

/// A JPEG quality estimate.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct JpegEstimate {
    /// The libjpeg quality best matching the detected quantisation steps; None: not detectable.
    pub quality: Option<u8>,
    /// Detected steps of the luma table at the 9 lowest AC frequencies (1: none detected).
    pub steps: Vec<f32>,
}

/// Everything estimated from one photograph.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Estimates {
    pub noise: NoiseEstimate,
    pub blur: BlurEstimate,
    pub jpeg: JpegEstimate,
}

impl std::fmt::Display for Estimates {
    /// One line: noise σ and its fit, blur radius, JPEG quality (each or why it is missing).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let noise = &self.noise;
        let blur = match self.blur.radius_px {
            Some(radius) => format!("disc radius {radius:.2} px ({} edges)", self.blur.edges),
            None => "not measurable (no isolated edges)".into(),
        };
        let jpeg = match self.jpeg.quality {
            Some(quality) => quality.to_string(),
            None => "not detectable (none, or above about 95)".into(),
        };
        write!(
            f,
            "noise σ {:.4} (σ² = {:.2e}·d + {:.2e}, {}), blur {blur}, JPEG quality {jpeg}",
            noise.sigma, noise.a, noise.b, noise.fit
        )
    }
}

#[inline]
fn inside(region: Option<&Mask>, i: usize) -> bool {
    region.is_none_or(|m| m.values[i] > 0.5)
}

/// A value usable for statistics: finite, clamped to [0, 1] (HDR values above 1 count as clipped).
#[inline]
fn val(v: f32) -> f32 {
    if v.is_finite() { v } else { f32::NAN }
}

/// Noise of `img` (display-encoded), over `region` (pixels with value > 0.5) or the whole image.
pub fn noise(img: &Image, region: Option<&Mask>) -> NoiseEstimate {
    let (w, h) = (img.width as usize, img.height as usize);
    // (intensity, |I*N|, structure) per pixel-channel sample
    let mut samples: Vec<(f32, f32, f32)> = Vec::new();
    if w >= 3 && h >= 3 {
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let mut ok = true;
                for dy in 0..3 {
                    for dx in 0..3 {
                        ok &= inside(region, (y + dy - 1) * w + x + dx - 1);
                    }
                }
                if !ok {
                    continue;
                }
                for c in 0..3 {
                    let at = |dx: usize, dy: usize| val(img.pixels[(y + dy - 1) * w + x + dx - 1][c]);
                    let mut vals = [0.0f32; 9];
                    let mut clipped = false;
                    for (k, v) in vals.iter_mut().enumerate() {
                        *v = at(k % 3, k / 3);
                        clipped |= !(*v > 0.01 && *v < 0.99);
                    }
                    if clipped {
                        continue;
                    }
                    let lap = vals[0] - 2.0 * vals[1] + vals[2] - 2.0 * vals[3] + 4.0 * vals[4] - 2.0 * vals[5]
                        + vals[6]
                        - 2.0 * vals[7]
                        + vals[8];
                    let sx = (vals[2] + 2.0 * vals[5] + vals[8]) - (vals[0] + 2.0 * vals[3] + vals[6]);
                    let sy = (vals[6] + 2.0 * vals[7] + vals[8]) - (vals[0] + 2.0 * vals[1] + vals[2]);
                    let mean = vals.iter().sum::<f32>() / 9.0;
                    samples.push((mean, lap.abs(), (sx * sx + sy * sy).sqrt()));
                }
            }
        }
    }
    let none = NoiseEstimate { sigma: 0.0, a: 0.0, b: 0.0, fit: "none", samples: 0, bins: Vec::new() };
    if samples.is_empty() {
        return none;
    }
    // a first robust σ (median |r| / (0.6745·6)); then drop edge samples
    let mut abs: Vec<f32> = samples.iter().map(|s| s.1).collect();
    abs.sort_by(f32::total_cmp);
    let sigma0 = abs[abs.len() / 2] / (0.6745 * 6.0);
    let limit = 4.0 * 12f32.sqrt() * sigma0;
    samples.retain(|s| s.2 <= limit);
    if samples.is_empty() {
        return none;
    }
    let immerkaer = |rs: &[(f32, f32, f32)]| -> f32 {
        (std::f64::consts::FRAC_PI_2.sqrt() * rs.iter().map(|s| s.1 as f64).sum::<f64>() / (6.0 * rs.len() as f64))
            as f32
    };
    let sigma = immerkaer(&samples);
    // intensity bins
    let mut bins: Vec<Vec<(f32, f32, f32)>> = vec![Vec::new(); 16];
    for s in &samples {
        bins[((s.0 * 16.0) as usize).min(15)].push(*s);
    }
    let usable: Vec<(f32, f32, usize)> = bins
        .iter()
        .filter(|b| b.len() >= 64)
        .map(|b| (b.iter().map(|s| s.0).sum::<f32>() / b.len() as f32, immerkaer(b), b.len()))
        .collect();
    let spread = usable.iter().map(|b| b.0).fold(f32::NEG_INFINITY, f32::max)
        - usable.iter().map(|b| b.0).fold(f32::INFINITY, f32::min);
    let (a, b, fit) = if usable.len() >= 2 && spread >= 0.1 {
        let (mut sw, mut sx, mut sy, mut sxx, mut sxy) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
        for &(m, s, n) in &usable {
            let (x, y, wgt) = (m as f64, (s * s) as f64, n as f64);
            sw += wgt;
            sx += wgt * x;
            sy += wgt * y;
            sxx += wgt * x * x;
            sxy += wgt * x * y;
        }
        let det = sw * sxx - sx * sx;
        let (mut a, mut b) =
            if det > 1e-12 { ((sw * sxy - sx * sy) / det, (sxx * sy - sx * sxy) / det) } else { (0.0, sy / sw) };
        if a < 0.0 {
            a = 0.0;
            b = sy / sw;
        }
        if b < 0.0 {
            b = 0.0;
            a = if sxx > 0.0 { sxy / sxx } else { 0.0 };
        }
        (a as f32, b as f32, "poisson-gaussian")
    } else {
        (0.0, sigma * sigma, "gaussian")
    };
    NoiseEstimate { sigma, a, b, fit, samples: samples.len(), bins: usable }
}

fn gray(img: &Image) -> Vec<f32> {
    img.pixels.iter().map(|p| (p.x + p.y + p.z) / 3.0).collect()
}

fn sample_gray(g: &[f32], w: usize, h: usize, px: f32, py: f32) -> f32 {
    let x = px - 0.5;
    let y = py - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let at = |xx: i64, yy: i64| g[(yy.clamp(0, h as i64 - 1) as usize) * w + xx.clamp(0, w as i64 - 1) as usize];
    let (xi, yi) = (x0 as i64, y0 as i64);
    let top = at(xi, yi) * (1.0 - fx) + at(xi + 1, yi) * fx;
    let bottom = at(xi, yi + 1) * (1.0 - fx) + at(xi + 1, yi + 1) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// 20th percentile of the 10–90 % rise distances of isolated step edges, and their number.
fn edge_widths(img: &Image, region: Option<&Mask>) -> (Option<f32>, usize) {
    let (w, h) = (img.width as usize, img.height as usize);
    if w < 8 || h < 8 {
        return (None, 0);
    }
    let g: Vec<f32> = gray(img).into_iter().map(|v| if v.is_finite() { v.clamp(0.0, 1.0) } else { 0.0 }).collect();
    let at = |x: usize, y: usize| g[y * w + x];
    let mut mag = vec![0.0f32; w * h];
    let mut dir = vec![(0.0f32, 0.0f32); w * h];
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let sx = (at(x + 1, y - 1) + 2.0 * at(x + 1, y) + at(x + 1, y + 1))
                - (at(x - 1, y - 1) + 2.0 * at(x - 1, y) + at(x - 1, y + 1));
            let sy = (at(x - 1, y + 1) + 2.0 * at(x, y + 1) + at(x + 1, y + 1))
                - (at(x - 1, y - 1) + 2.0 * at(x, y - 1) + at(x + 1, y - 1));
            let m = (sx * sx + sy * sy).sqrt() / 8.0;
            mag[y * w + x] = m;
            if m > 0.0 {
                dir[y * w + x] = (sx / (8.0 * m), sy / (8.0 * m));
            }
        }
    }
    const REACH: f32 = 8.0;
    const STEP: f32 = 0.25;
    let n_steps = (2.0 * REACH / STEP) as usize + 1;
    let mut widths = Vec::new();
    let margin = REACH as usize + 2;
    if w <= 2 * margin || h <= 2 * margin {
        return (None, 0);
    }
    for y in margin..h - margin {
        for x in margin..w - margin {
            let i = y * w + x;
            let m = mag[i];
            if m < 0.02 || !inside(region, i) {
                continue;
            }
            let (nx, ny) = dir[i];
            // non-maximum suppression along the gradient (nearest neighbours)
            let (ox, oy) = (nx.round() as i64, ny.round() as i64);
            let j1 = ((y as i64 + oy) as usize) * w + (x as i64 + ox) as usize;
            let j0 = ((y as i64 - oy) as usize) * w + (x as i64 - ox) as usize;
            if mag[j1] > m || mag[j0] >= m {
                continue;
            }
            let (cx, cy) = (x as f32 + 0.5, y as f32 + 0.5);
            let ends = [(cx - nx * REACH, cy - ny * REACH), (cx + nx * REACH, cy + ny * REACH)];
            if ends.iter().any(|&(ex, ey)| {
                let (ex, ey) = (ex.floor() as i64, ey.floor() as i64);
                ex < 0 || ey < 0 || ex >= w as i64 || ey >= h as i64
            }) {
                continue;
            }
            let profile: Vec<f32> = (0..n_steps)
                .map(|k| {
                    let t = -REACH + k as f32 * STEP;
                    sample_gray(&g, w, h, cx + nx * t, cy + ny * t)
                })
                .collect();
            // plateaus: the outer 2 px on each side
            let plateau = (2.0 / STEP) as usize;
            let stats = |s: &[f32]| {
                let m = s.iter().sum::<f32>() / s.len() as f32;
                (m, (s.iter().map(|v| (v - m) * (v - m)).sum::<f32>() / s.len() as f32).sqrt())
            };
            let (lo, slo) = stats(&profile[..plateau]);
            let (hi, shi) = stats(&profile[n_steps - plateau..]);
            let contrast = hi - lo;
            if contrast < 0.1 || slo > 0.1 * contrast || shi > 0.1 * contrast {
                continue;
            }
            // the rising profile must stay between its plateaus
            let (l10, l90) = (lo + 0.1 * contrast, lo + 0.9 * contrast);
            let centre = n_steps / 2;
            let cross = |level: f32, backwards: bool| -> Option<f32> {
                // walk out from the centre to where the profile passes `level`
                if backwards {
                    let mut k = centre;
                    while k > 0 {
                        if profile[k - 1] <= level && profile[k] > level {
                            let f = (level - profile[k - 1]) / (profile[k] - profile[k - 1]);
                            return Some((k - 1) as f32 + f);
                        }
                        k -= 1;
                    }
                    None
                } else {
                    for k in centre..n_steps - 1 {
                        if profile[k] < level && profile[k + 1] >= level {
                            let f = (level - profile[k]) / (profile[k + 1] - profile[k]);
                            return Some(k as f32 + f);
                        }
                    }
                    None
                }
            };
            let a = if profile[centre] > l10 { cross(l10, true) } else { cross(l10, false) };
            let b = if profile[centre] < l90 { cross(l90, false) } else { cross(l90, true) };
            if let (Some(a), Some(b)) = (a, b)
                && b > a
            {
                widths.push((b - a) * STEP);
            }
        }
    }
    if widths.is_empty() {
        return (None, 0);
    }
    // the sharpest fifth: shading and soft shadows make many edges wider than the camera's blur
    widths.sort_by(f32::total_cmp);
    (Some(widths[widths.len() / 5]), widths.len())
}

/// (disc radius, median edge width) pairs of ideal edges, for radii 0, 0.25, … 6 px.
fn calibration() -> &'static Vec<(f32, f32)> {
    static TABLE: OnceLock<Vec<(f32, f32)>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let edge = calibration_edge(72);
        (0..=24)
            .filter_map(|k| {
                let r = k as f32 * 0.25;
                let img = if r > 0.0 { crate::sensor::disc_blur(&edge, r) } else { edge.clone() };
                edge_widths(&img, None).0.map(|wd| (r, wd))
            })
            .collect()
    })
}

/// Blur of `img` as an equivalent defocus disc radius, from edges centred in `region`.
pub fn blur(img: &Image, region: Option<&Mask>) -> BlurEstimate {
    let (width, edges) = edge_widths(img, region);
    let radius = width.map(|wd| {
        let table = calibration();
        // the width grows with the radius; interpolate, clamping below the first entry
        let mut r = table.last().map(|t| t.0).unwrap_or(0.0);
        if let Some(first) = table.first()
            && wd <= first.1
        {
            r = first.0;
        }
        for pair in table.windows(2) {
            let ((r0, w0), (r1, w1)) = (pair[0], pair[1]);
            if wd > w0 && wd <= w1 && w1 > w0 {
                r = r0 + (r1 - r0) * (wd - w0) / (w1 - w0);
                break;
            }
        }
        r
    });
    BlurEstimate { radius_px: radius, edge_width_px: width, edges }
}

/// The first 9 AC positions in zig-zag order, as (u, v).
const LOW_AC: [(usize, usize); 9] = [(1, 0), (0, 1), (0, 2), (1, 1), (2, 0), (3, 0), (2, 1), (1, 2), (0, 3)];

/// JPEG quality of `img` (display-encoded 8-bit values; the 8×8 grid at the origin).
pub fn jpeg_quality(img: &Image) -> JpegEstimate {
    let (w, h) = (img.width as usize, img.height as usize);
    let basis = super::jpeg::dct_basis();
    let mut coefs: Vec<Vec<f32>> = vec![Vec::new(); LOW_AC.len()];
    for by in (0..h.saturating_sub(7)).step_by(8) {
        for bx in (0..w.saturating_sub(7)).step_by(8) {
            let mut f = [0.0f32; 64];
            for y in 0..8 {
                for x in 0..8 {
                    let p = img.pixels[(by + y) * w + bx + x];
                    let p = if p.is_finite() { p.clamp(glam::Vec3::ZERO, glam::Vec3::ONE) } else { glam::Vec3::ZERO };
                    f[y * 8 + x] = super::jpeg::to_ycc(p * 255.0).x;
                }
            }
            let c = super::jpeg::dct8x8(&f, &basis);
            for (k, &(u, v)) in LOW_AC.iter().enumerate() {
                coefs[k].push(c[v * 8 + u]);
            }
        }
    }
    let mut steps = Vec::new();
    let residual = |cs: &[f32], q: f32| -> Option<f32> {
        let used: Vec<f32> = cs.iter().copied().filter(|c| c.abs() >= 0.5 * q).collect();
        (used.len() >= 20)
            .then(|| used.iter().map(|c| (c / q - (c / q).round()).powi(2)).sum::<f32>() / used.len() as f32)
    };
    for cs in &coefs {
        // the k = 1 cluster at ±q is the most populated non-zero one (coefficients fall off
        // like a Laplacian): the mode of round(|c|) over |c| ≥ 1.5, refined by ±1
        let mut hist = vec![0usize; 256];
        for c in cs {
            let a = c.abs();
            if (1.5..255.5).contains(&a) {
                hist[a.round() as usize] += 1;
            }
        }
        let mode = (2..256).max_by_key(|&k| (hist[k], std::cmp::Reverse(k))).unwrap_or(2) as f32;
        // candidates: the mode and its halves and thirds (should the mode be the ±2q or ±3q
        // cluster), each ±1; the true step has the smallest residual in units of q (its
        // divisors see the same noise relative to a smaller q, its neighbours a systematic offset)
        let mut best = (f32::INFINITY, 1.0f32);
        for k in 1..=3 {
            for delta in [-1.0f32, 0.0, 1.0] {
                let q = (mode / k as f32).round() + delta;
                if q >= 2.0
                    && let Some(ms) = residual(cs, q)
                    && ms < best.0
                {
                    best = (ms, q);
                }
            }
        }
        // uniform residuals have mean square 1/12; quantised ones next to none
        steps.push(if best.0 < 1.0 / 48.0 { best.1 } else { 1.0 });
    }
    let informative: Vec<(usize, f32)> = steps.iter().copied().enumerate().filter(|s| s.1 >= 2.0).collect();
    if informative.len() < 2 {
        return JpegEstimate { quality: None, steps };
    }
    let mut best = (f32::INFINITY, 0u8);
    for quality in 1..=100u8 {
        let table = super::jpeg::scaled_table(&super::jpeg::STD_LUMA, quality);
        let err: f32 = steps
            .iter()
            .zip(LOW_AC.iter())
            .filter(|(s, _)| **s >= 2.0)
            .map(|(s, &(u, v))| (s.ln() - table[v * 8 + u].ln()).powi(2))
            .sum();
        if err < best.0 {
            best = (err, quality);
        }
    }
    JpegEstimate { quality: Some(best.1), steps }
}

/// The image as 8-bit values (what a PNG of it holds, and what a camera delivers).
pub fn quantised(img: &Image) -> Image {
    Image::from_rgb8(img.width, img.height, &img.to_rgb8())
}

/// All three estimates of a photograph.
pub fn estimate(photo: &Image) -> Estimates {
    Estimates { noise: noise(photo, None), blur: blur(photo, None), jpeg: jpeg_quality(photo) }
}

/// The ca parameters from the photograph: noise, blur and JPEG quality estimated and calibrated
/// so that the ca chain itself reproduces the measured values (its demosaicing, sharpening and
/// compression change noise and edge width too); distortion, chromatic aberration, Bayer and
/// sharpening from the scene's camera.
pub fn params_from_photo(photo: &Image, scene: &SensorParams) -> (CaParams, Estimates) {
    let est = estimate(photo);
    let mut p = CaParams::from_sensor(scene);
    p.source = ParamSource::Estimate;
    p.jpeg_quality = est.jpeg.quality;
    // noise: the measured variance per intensity bin (linear between bin centres, constant
    // beyond; a·d + b where fewer than two bins), then scaled so that the chain itself — whose
    // demosaicing, sharpening and compression change noise strongly and non-linearly — shows
    // the measured σ at mid grey (bisection on the injected level, flat field)
    let bins = &est.noise.bins;
    let mut lut = [0.0f32; NOISE_LUT];
    for (k, v) in lut.iter_mut().enumerate() {
        let d = k as f32 / (NOISE_LUT - 1) as f32;
        *v = if bins.len() >= 2 {
            let first = bins[0];
            let last = bins[bins.len() - 1];
            if d <= first.0 {
                first.1 * first.1
            } else if d >= last.0 {
                last.1 * last.1
            } else {
                let j = bins.windows(2).position(|b| d >= b[0].0 && d <= b[1].0).unwrap_or(0);
                let (b0, b1) = (bins[j], bins[j + 1]);
                let f = (d - b0.0) / (b1.0 - b0.0).max(1e-6);
                b0.1 * b0.1 * (1.0 - f) + b1.1 * b1.1 * f
            }
        } else {
            (est.noise.a * d + est.noise.b).max(0.0)
        };
    }
    p.noise_variance = lut;
    p.defocus_px = 0.0;
    let v_mid = super::lut_variance(&lut, 0.5);
    if v_mid > 0.0 {
        let field = Image::filled(64, 64, glam::Vec3::splat(0.5));
        let mask = Mask { width: 64, height: 64, values: vec![1.0; 64 * 64] };
        let camera = Camera::from_fov(64, 64, 50.0, glam::Vec3::Z, glam::Vec3::ZERO, glam::Vec3::Y);
        let mut probe = p.clone();
        probe.distortion = [0.0; 5];
        probe.chromatic_aberration = 0.0;
        let mut measured_at = |scale: f32| -> f32 {
            probe.noise_variance = [v_mid * scale; NOISE_LUT];
            // measured on 8-bit values, as the photograph was
            super::apply_cpu(&field, &field, &mask, &camera, &probe)
                .map(|(out, _)| noise(&quantised(&out), None).sigma.powi(2))
                .unwrap_or(0.0)
        };
        // log-bisection of the scale s with measured(s) = v_mid, s in [1e-2, 1e4]
        let (mut lo, mut hi) = (-2.0f32, 4.0f32);
        for _ in 0..14 {
            let mid = 0.5 * (lo + hi);
            if measured_at(10f32.powf(mid)) < v_mid { lo = mid } else { hi = mid }
        }
        let scale = 10f32.powf(0.5 * (lo + hi));
        for v in p.noise_variance.iter_mut() {
            *v *= scale;
        }
    }
    // blur: the disc radius whose chain output (no noise) shows the measured edge width
    if let Some(target) = est.blur.edge_width_px {
        let mut probe = p.clone();
        probe.noise_variance = [0.0; NOISE_LUT];
        probe.distortion = [0.0; 5];
        probe.chromatic_aberration = 0.0;
        let edge = calibration_edge(48);
        let camera = Camera::from_fov(edge.width, edge.height, 50.0, glam::Vec3::Z, glam::Vec3::ZERO, glam::Vec3::Y);
        let mask = Mask { width: edge.width, height: edge.height, values: vec![1.0; edge.pixels.len()] };
        let width_at = |r: f32, probe: &mut CaParams| {
            probe.defocus_px = r;
            super::apply_cpu(&edge, &edge, &mask, &camera, probe)
                .ok()
                .and_then(|(out, _)| edge_widths(&quantised(&out), None).0)
        };
        let (mut lo, mut hi) = (0.0f32, 6.0f32);
        if width_at(0.0, &mut probe).is_some_and(|w0| w0 < target) {
            for _ in 0..10 {
                let mid = 0.5 * (lo + hi);
                match width_at(mid, &mut probe) {
                    Some(wd) if wd < target => lo = mid,
                    _ => hi = mid,
                }
            }
            p.defocus_px = 0.5 * (lo + hi);
        }
    }
    (p, est)
}

/// The calibration target: a bright disc of radius 0.3·size on a dark ground, area-sampled with
/// 8×8 subsamples (edges at every angle).
fn calibration_edge(size: u32) -> Image {
    let r = 0.3 * size as f32;
    let c = size as f32 / 2.0;
    let mut edge = Image::new(size, size);
    for y in 0..size {
        for x in 0..size {
            let mut s = 0.0;
            for sy in 0..8 {
                for sx in 0..8 {
                    let px = x as f32 + (sx as f32 + 0.5) / 8.0 - c;
                    let py = y as f32 + (sy as f32 + 0.5) / 8.0 - c;
                    if px * px + py * py < r * r {
                        s += 1.0;
                    }
                }
            }
            edge.set(x, y, glam::Vec3::splat(0.2 + 0.6 * s / 64.0));
        }
    }
    edge
}
