//! The `ca` factor: simulated camera artifacts on the virtual objects and on their differential
//! effect, after Klein and Murray ("Simulating low-cost cameras for augmented reality
//! compositing", IEEE TVCG 16(3), 2010; thesis 6.4), in their order: lens distortion, lateral
//! chromatic aberration, blur, Bayer masking with demosaicing, noise, sharpening, colour-space
//! (JPEG-style) compression. This module holds the parameters, the CPU reference implementation
//! and the hash random numbers the GPU pass ([`crate::gpu::ca`], `ca.wgsl`)
//! reproduces to 1e-3; [`estimate`] measures noise, blur and JPEG quality on a photograph.
//!
//! **What is processed.** The photograph already carries the real camera's artifacts, so its
//! untouched pixels are never processed again. The frame's composite C, the photograph P and the
//! virtual coverage α split into three layers, all display-encoded: A = α·C (the virtual objects,
//! premultiplied), M = α and D = (1 − α)(C − P) (the differential effect: shadows and indirect
//! light the virtual objects add to real surfaces). The optical stages (distortion with
//! chromatic aberration, then the defocus disc) are linear and act on A, M, D, which keeps
//! virtual edges, their coverage and their shadows registered with the (distorted) photograph.
//! After them, w = mean(M) is the virtual weight — a soft edge, feathered by the optics.
//! Two images then go through the sensor and processing stages:
//! - **B = P·(1 − M) + A + D**, the composite as the camera would see it; at each mosaic site it
//!   gets the **full** camera noise, variance σ²(B), is clipped to [0, 1], demosaiced and
//!   sharpened. It is shown where the virtual objects are (weight w).
//! - **D** alone (linear stages only, so chain(P + D) ≈ P + chain(D) without re-processing P);
//!   it gets only the noise that makes the statistics match: variance max(0, σ²(P + D) − σ²(P)),
//!   since P already holds σ²(P) — a brightening adds noise, a shadow cannot remove any.
//!
//! The result is P + w·(B' − P) + (1 − w)·D', clamped to [0, 1]; then the JPEG-style stage
//! (YCbCr, 8×8 DCT, libjpeg's quality-scaled tables, 4:4:4) is blended in with weight w, so
//! differential regions of real surfaces are not compressed twice. Where w = 0 and D' = 0 the
//! output is the photograph bit for bit (tested).
//!
//! Noise is a variance table over display values (17 entries, 0, 1/16 … 1; linear in between):
//! from the scene's camera, the variance of its response R applied to the clipped noisy sensor
//! value (R(clip(y + √(a·y + b)·Z)) at d = R(y), by quadrature), or
//! measured on the photograph per intensity bin (a·d + b where bins are too few) and scaled so
//! that the chain itself reproduces the measured σ ([`estimate::params_from_photo`]). The normal
//! deviates come from a PCG hash of (seed, pixel, channel) ([`normal`]), written identically in
//! WGSL. Not simulated: vignetting, white balance and the tone curve (the composite already has
//! the frame's colour mapping), chroma subsampling; all stages work on display-encoded values.

pub mod accuracy;
pub mod estimate;
pub mod jpeg;

use crate::camera::Camera;
use crate::error::{RenderError, Result};
use crate::image::{Image, Mask};
use crate::math::pcg_hash;
use crate::sensor::{self, SensorParams, ToneCurve};
use glam::Vec3;
use serde::Serialize;

/// Entries of the noise-variance table (display values k/16, k = 0 … 16).
pub const NOISE_LUT: usize = 17;

/// Where the ca parameters came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ParamSource {
    /// The scene's camera description ([`SensorParams`]).
    Scene,
    /// Noise, blur and JPEG quality estimated from the photograph ([`estimate`]); distortion,
    /// chromatic aberration, Bayer and sharpening from the scene (not estimable from one image
    /// of an unknown scene).
    Estimate,
}

impl ParamSource {
    pub fn parse(text: &str) -> Option<ParamSource> {
        match text.trim().to_ascii_lowercase().as_str() {
            "scene" => Some(ParamSource::Scene),
            "estimate" | "estimated" => Some(ParamSource::Estimate),
            _ => None,
        }
    }
}

/// The resolved parameters of the ca chain (shared by the CPU reference and the GPU pass).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CaParams {
    pub source: ParamSource,
    /// Brown–Conrady [k1, k2, p1, p2, k3], applied like the simulated camera (same zoom).
    pub distortion: [f32; 5],
    /// Lateral chromatic aberration: red and blue magnified by 1 ± this.
    pub chromatic_aberration: f32,
    /// Defocus disc radius in pixels.
    pub defocus_px: f32,
    pub bayer: bool,
    /// Noise variance (display units²) at display values k/16.
    pub noise_variance: [f32; NOISE_LUT],
    /// Unsharp-mask amount (3×3 binomial blur).
    pub sharpen: f32,
    /// JPEG-style quality 1–100; None: no compression stage.
    pub jpeg_quality: Option<u8>,
    pub seed: u32,
}

/// What one run of the chain saw.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct CaReport {
    /// Non-finite channel values in the composite or photograph (replaced, not propagated: a
    /// bad photograph channel by 0, a bad composite channel by the photograph's).
    pub invalid_inputs: usize,
    /// Fraction of pixels that differ from the photograph or are covered by a virtual object.
    pub processed_fraction: f32,
}

impl CaParams {
    /// The chain of the scene's simulated camera: its optics, Bayer, sharpening and JPEG quality,
    /// and its noise a·y + b carried to display values through the response curve.
    pub fn from_sensor(p: &SensorParams) -> CaParams {
        CaParams {
            source: ParamSource::Scene,
            distortion: p.distortion,
            chromatic_aberration: p.chromatic_aberration,
            defocus_px: p.defocus_px,
            bayer: p.bayer,
            noise_variance: display_noise_lut(p),
            sharpen: p.sharpen,
            jpeg_quality: p.jpeg_quality,
            seed: (p.seed ^ (p.seed >> 32)) as u32 ^ 0x5eed_ca00,
        }
    }

    /// A chain with every stage off (the identity on the composite).
    pub fn off() -> CaParams {
        CaParams {
            source: ParamSource::Scene,
            distortion: [0.0; 5],
            chromatic_aberration: 0.0,
            defocus_px: 0.0,
            bayer: false,
            noise_variance: [0.0; NOISE_LUT],
            sharpen: 0.0,
            jpeg_quality: None,
            seed: 0,
        }
    }

    pub(crate) fn warps(&self) -> bool {
        self.distortion.iter().any(|k| *k != 0.0) || self.chromatic_aberration != 0.0
    }

    /// The table of normalised disc-blur taps (dx, dy, weight), empty when there is no blur.
    pub(crate) fn blur_taps(&self) -> Vec<(i32, i32, f32)> {
        if self.defocus_px <= 0.0 {
            return Vec::new();
        }
        let taps = sensor::disc_taps(self.defocus_px);
        let total: f32 = taps.iter().map(|t| t.2).sum();
        taps.iter().map(|&(dx, dy, w)| (dx as i32, dy as i32, w / total)).collect()
    }

    /// The first unusable value, if any.
    pub fn check(&self) -> std::result::Result<(), CaParamsError> {
        if self.distortion.iter().any(|k| !k.is_finite())
            || !self.chromatic_aberration.is_finite()
            || self.chromatic_aberration.abs() >= 0.5
        {
            return Err(CaParamsError::Distortion {
                distortion: self.distortion.to_vec(),
                aberration: self.chromatic_aberration,
            });
        }
        if !(self.defocus_px >= 0.0 && self.defocus_px <= 32.0) {
            return Err(CaParamsError::Defocus(self.defocus_px));
        }
        if self.noise_variance.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err(CaParamsError::NoiseVariance(self.noise_variance.to_vec()));
        }
        if !(self.sharpen.is_finite() && self.sharpen >= 0.0) {
            return Err(CaParamsError::Sharpen(self.sharpen));
        }
        if let Some(quality) = self.jpeg_quality.filter(|&q| q == 0 || q > 100) {
            return Err(CaParamsError::JpegQuality(quality));
        }
        Ok(())
    }
}

/// An unusable value of [`CaParams`], with the value; each displays as one sentence.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CaParamsError {
    #[error("ca: distortion and chromatic aberration must be finite (|aberration| < 0.5)")]
    Distortion { distortion: Vec<f32>, aberration: f32 },
    #[error("ca: the defocus radius must lie in [0, 32] pixels, not {0}")]
    Defocus(f32),
    #[error("ca: every noise variance must be finite and ≥ 0")]
    NoiseVariance(Vec<f32>),
    #[error("ca: the sharpening amount must be finite and ≥ 0, not {0}")]
    Sharpen(f32),
    #[error("ca: the JPEG quality must lie in 1..=100")]
    JpegQuality(u8),
}

/// The grey-value display curve of the simulated camera: response, then contrast (saturation
/// does not act on grey).
pub fn display_curve(p: &SensorParams, y: f32) -> f32 {
    let c = match p.response {
        ToneCurve::Linear => y.clamp(0.0, 1.0),
        ToneCurve::Srgb => crate::image::srgb_encode(y),
        ToneCurve::Filmic => {
            let x = y.max(0.0) * 1.25;
            crate::image::srgb_encode(x * (1.0 + x / 16.0) / (1.0 + x))
        }
    };
    if p.contrast != 1.0 { ((c - 0.5) * p.contrast + 0.5).clamp(0.0, 1.0) } else { c }
}

/// The camera's noise a·y + b (sensor values) as a variance table over display values: at each
/// d = R(y), the variance of R(clip(y + σ(y)·Z, 0, 1)) with σ(y)² = a·y + b and Z standard
/// normal (by quadrature over Z ∈ [−6, 6], 481 points), i.e. the noise as the camera's response
/// and clipping shape it. Near black, where the curve is steep, this is much less than the
/// delta method's R′(y)²·σ(y)².
pub fn display_noise_lut(p: &SensorParams) -> [f32; NOISE_LUT] {
    let [a, b] = p.noise;
    let mut lut = [0.0f32; NOISE_LUT];
    if a <= 0.0 && b <= 0.0 {
        return lut;
    }
    // the normal density on the quadrature nodes (trapezoid rule), normalised to sum to 1
    const NODES: usize = 481;
    let z: Vec<f64> = (0..NODES).map(|k| -6.0 + 12.0 * k as f64 / (NODES - 1) as f64).collect();
    let pdf: Vec<f64> = z.iter().map(|z| (-0.5 * z * z).exp()).collect();
    let total: f64 = pdf.iter().sum();
    for (k, out) in lut.iter_mut().enumerate() {
        let d = k as f32 / (NOISE_LUT - 1) as f32;
        // the smallest y in [0, 1] with R(y) ≥ d (R is non-decreasing)
        let (mut lo, mut hi) = (0.0f32, 1.0f32);
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if display_curve(p, mid) < d { lo = mid } else { hi = mid }
        }
        let y = hi;
        let sigma = (a * y + b).max(0.0).sqrt();
        let (mut m1, mut m2) = (0.0f64, 0.0f64);
        for (zk, wk) in z.iter().zip(&pdf) {
            let v = display_curve(p, (y + sigma * *zk as f32).clamp(0.0, 1.0)) as f64;
            m1 += wk * v;
            m2 += wk * v * v;
        }
        let (m1, m2) = (m1 / total, m2 / total);
        *out = (m2 - m1 * m1).max(0.0) as f32;
    }
    lut
}

/// The noise variance at display value `d`, linear between the table's entries.
#[inline]
pub fn lut_variance(lut: &[f32; NOISE_LUT], d: f32) -> f32 {
    let t = d.clamp(0.0, 1.0) * (NOISE_LUT - 1) as f32;
    let i = (t.floor() as usize).min(NOISE_LUT - 2);
    let f = t - i as f32;
    lut[i] * (1.0 - f) + lut[i + 1] * f
}

/// A standard normal deviate, a pure function of (seed, pixel, channel): Box–Muller on two
/// hashed uniforms (24 bits each, the first kept away from 0). `ca.wgsl` has the same.
#[inline]
pub fn normal(seed: u32, pixel: u32, channel: u32) -> f32 {
    let key = pixel.wrapping_mul(8).wrapping_add(channel.wrapping_mul(2));
    let h1 = pcg_hash(seed ^ pcg_hash(key));
    let h2 = pcg_hash(seed ^ pcg_hash(key.wrapping_add(1)));
    let u1 = ((h1 >> 8) as f32 + 0.5) * (1.0 / 16_777_216.0);
    let u2 = (h2 >> 8) as f32 * (1.0 / 16_777_216.0);
    (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
}

/// The Bayer (RGGB) channel of a mosaic site.
#[inline]
pub fn bayer_channel(x: u32, y: u32) -> usize {
    match (x % 2, y % 2) {
        (0, 0) => 0,
        (1, 1) => 2,
        _ => 1,
    }
}

/// Replaces non-finite channels (a bad photograph channel by 0, a bad composite channel by the
/// photograph's) and clamps the mask to [0, 1] (non-finite → 0); returns the count replaced.
pub fn sanitize(composite: &mut Image, photo: &mut Image, mask: &mut Mask) -> usize {
    let mut bad = 0;
    for (c, p) in composite.pixels.iter_mut().zip(photo.pixels.iter_mut()) {
        let mut pa = p.to_array();
        let mut ca = c.to_array();
        for k in 0..3 {
            if !pa[k].is_finite() {
                pa[k] = 0.0;
                bad += 1;
            }
            if !ca[k].is_finite() {
                ca[k] = pa[k];
                bad += 1;
            }
        }
        *p = Vec3::from_array(pa);
        *c = Vec3::from_array(ca);
    }
    for m in mask.values.iter_mut() {
        *m = if m.is_finite() { m.clamp(0.0, 1.0) } else { 0.0 };
    }
    bad
}

/// Three premultiplied layers (virtual colour A, coverage M, differential D), one image each.
#[derive(Clone, Debug)]
pub(crate) struct Layers {
    pub a: Image,
    pub m: Image,
    pub d: Image,
}

/// Bilinear fetch of one channel at continuous pixel coordinates (pixel centres at +0.5),
/// clamped to the edge; the same arithmetic as `sample` in ca.wgsl.
fn sample_channel(img: &Image, px: f32, py: f32, c: usize) -> f32 {
    let x = px - 0.5;
    let y = py - 0.5;
    let x0 = x.floor();
    let y0 = y.floor();
    let fx = x - x0;
    let fy = y - y0;
    let (w, h) = (img.width as i64, img.height as i64);
    let at = |xx: i64, yy: i64| img.pixels[(yy.clamp(0, h - 1) * w + xx.clamp(0, w - 1)) as usize][c];
    let (xi, yi) = (x0 as i64, y0 as i64);
    let top = at(xi, yi) + (at(xi + 1, yi) - at(xi, yi)) * fx;
    let bottom = at(xi, yi + 1) + (at(xi + 1, yi + 1) - at(xi, yi + 1)) * fx;
    top + (bottom - top) * fy
}

fn make_layers(composite: &Image, photo: &Image, mask: &Mask) -> Layers {
    let (w, h) = (composite.width, composite.height);
    let mut l = Layers { a: Image::new(w, h), m: Image::new(w, h), d: Image::new(w, h) };
    for i in 0..composite.pixels.len() {
        let alpha = mask.values[i];
        l.a.pixels[i] = composite.pixels[i] * alpha;
        l.m.pixels[i] = Vec3::splat(alpha);
        l.d.pixels[i] = (composite.pixels[i] - photo.pixels[i]) * (1.0 - alpha);
    }
    l
}

fn warp(l: &Layers, camera: &Camera, p: &CaParams) -> Layers {
    let (w, h) = (l.a.width, l.a.height);
    let mut out = Layers { a: Image::new(w, h), m: Image::new(w, h), d: Image::new(w, h) };
    let k = p.distortion;
    let ca = p.chromatic_aberration;
    let zoom = sensor::distortion_zoom(camera, k, ca);
    let (fx, fy, cx, cy) = (camera.fx, camera.fy, camera.cx, camera.cy);
    let scales = [1.0 / (1.0 + ca), 1.0, 1.0 / (1.0 - ca)];
    for y in 0..h {
        for x in 0..w {
            let xd = (x as f32 + 0.5 - cx) / fx;
            let yd = (y as f32 + 0.5 - cy) / fy;
            let (xu, yu) = sensor::undistort(xd, yd, k);
            let (xu, yu) = (xu * zoom, yu * zoom);
            let i = (y * w + x) as usize;
            let (mut a, mut m, mut d) = ([0.0f32; 3], [0.0f32; 3], [0.0f32; 3]);
            for c in 0..3 {
                let sx = cx + xu * scales[c] * fx;
                let sy = cy + yu * scales[c] * fy;
                a[c] = sample_channel(&l.a, sx, sy, c);
                m[c] = sample_channel(&l.m, sx, sy, c);
                d[c] = sample_channel(&l.d, sx, sy, c);
            }
            out.a.pixels[i] = Vec3::from_array(a);
            out.m.pixels[i] = Vec3::from_array(m);
            out.d.pixels[i] = Vec3::from_array(d);
        }
    }
    out
}

fn blur(l: &Layers, taps: &[(i32, i32, f32)]) -> Layers {
    let one = |img: &Image| {
        let mut out = Image::new(img.width, img.height);
        for y in 0..img.height as i64 {
            for x in 0..img.width as i64 {
                let mut s = Vec3::ZERO;
                for &(dx, dy, wgt) in taps {
                    s += img.get_clamped(x + dx as i64, y + dy as i64) * wgt;
                }
                out.set(x as u32, y as u32, s);
            }
        }
        out
    };
    Layers { a: one(&l.a), m: one(&l.m), d: one(&l.d) }
}

/// Bilinear demosaicing of an RGGB mosaic (the arithmetic of [`sensor::demosaic_bilinear`], on
/// unclipped values, and in the order `cs_demosaic` sums).
fn demosaic(raw: &[f32], w: u32, h: u32) -> Image {
    let mut out = Image::new(w, h);
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            let mut sum = [0.0f32; 3];
            let mut cnt = [0.0f32; 3];
            let c0 = bayer_channel(x as u32, y as u32);
            let v0 = raw[(y * w as i64 + x) as usize];
            for dy in -1..=1i64 {
                for dx in -1..=1i64 {
                    let xx = (x + dx).clamp(0, w as i64 - 1);
                    let yy = (y + dy).clamp(0, h as i64 - 1);
                    let c = bayer_channel(xx as u32, yy as u32);
                    if c == c0 && (dx != 0 || dy != 0) {
                        continue;
                    }
                    if c == 1 && dx != 0 && dy != 0 {
                        continue;
                    }
                    sum[c] += raw[(yy * w as i64 + xx) as usize];
                    cnt[c] += 1.0;
                }
            }
            let mut px = [0.0f32; 3];
            for c in 0..3 {
                px[c] = if c == c0 {
                    v0
                } else if cnt[c] > 0.0 {
                    sum[c] / cnt[c]
                } else {
                    v0
                };
            }
            out.set(x as u32, y as u32, Vec3::from_array(px));
        }
    }
    out
}

fn sharpen(img: &Image, amount: f32, clip: bool) -> Image {
    let mut out = Image::new(img.width, img.height);
    for y in 0..img.height as i64 {
        for x in 0..img.width as i64 {
            let c = img.get(x as u32, y as u32);
            let v = c + (c - sensor::binomial3(img, x, y)) * amount;
            out.set(x as u32, y as u32, if clip { v.clamp(Vec3::ZERO, Vec3::ONE) } else { v });
        }
    }
    out
}

/// The virtual weight w of a pixel from its coverage layer.
#[inline]
pub(crate) fn weight(m: Vec3) -> f32 {
    ((m.x + m.y + m.z) * (1.0 / 3.0)).clamp(0.0, 1.0)
}

/// The inputs of the chain (CPU or GPU) checked and made usable: sizes that match, parameters in
/// range, and copies with invalid values repaired by [`sanitize`] (whose count is returned last).
pub(crate) fn checked_inputs(
    composite: &Image,
    photo: &Image,
    mask: &Mask,
    p: &CaParams,
) -> Result<(Image, Image, Mask, usize)> {
    let (w, h) = (composite.width, composite.height);
    for (b_width, b_height) in [(photo.width, photo.height), (mask.width, mask.height)] {
        if (b_width, b_height) != (w, h) {
            return Err(RenderError::SizeMismatch { a_width: w, a_height: h, b_width, b_height });
        }
    }
    p.check().map_err(|error| RenderError::Unsupported(error.to_string()))?;
    let (mut comp, mut photo, mut mask) = (composite.clone(), photo.clone(), mask.clone());
    let invalid_inputs = sanitize(&mut comp, &mut photo, &mut mask);
    Ok((comp, photo, mask, invalid_inputs))
}

/// The CPU reference of the ca chain: the frame's `composite`, the `photograph` under it and the
/// virtual `mask` (coverage in [0, 1]) → the composite with camera artifacts (display-encoded,
/// [0, 1]). See the module header for what is processed and why.
pub fn apply_cpu(
    composite: &Image,
    photo: &Image,
    mask: &Mask,
    camera: &Camera,
    p: &CaParams,
) -> Result<(Image, CaReport)> {
    let (w, h) = (composite.width, composite.height);
    let (comp, photo, mask, invalid_inputs) = checked_inputs(composite, photo, mask, p)?;

    // optics
    let mut l = make_layers(&comp, &photo, &mask);
    if p.warps() {
        l = warp(&l, camera, p);
    }
    let taps = p.blur_taps();
    if !taps.is_empty() {
        l = blur(&l, &taps);
    }
    // sensor: B and D with noise, then demosaicing
    let n = (w * h) as usize;
    let mut b_img = Image::new(w, h);
    let mut d_img = Image::new(w, h);
    let mut raw_b = vec![0.0f32; if p.bayer { n } else { 0 }];
    let mut raw_d = vec![0.0f32; if p.bayer { n } else { 0 }];
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let m = l.m.pixels[i];
            let b = photo.pixels[i] * (Vec3::ONE - m) + l.a.pixels[i] + l.d.pixels[i];
            let (pb, pd, pp) = (b.to_array(), l.d.pixels[i].to_array(), photo.pixels[i].to_array());
            let noisy = |c: usize| {
                let vb = lut_variance(&p.noise_variance, pb[c]);
                let vp = lut_variance(&p.noise_variance, pp[c]);
                let z = normal(p.seed, i as u32, c as u32);
                ((pb[c] + vb.max(0.0).sqrt() * z).clamp(0.0, 1.0), pd[c] + (vb - vp).max(0.0).sqrt() * z)
            };
            if p.bayer {
                let c = bayer_channel(x, y);
                (raw_b[i], raw_d[i]) = noisy(c);
            } else {
                let (mut ob, mut od) = ([0.0f32; 3], [0.0f32; 3]);
                for c in 0..3 {
                    (ob[c], od[c]) = noisy(c);
                }
                b_img.pixels[i] = Vec3::from_array(ob);
                d_img.pixels[i] = Vec3::from_array(od);
            }
        }
    }
    if p.bayer {
        b_img = demosaic(&raw_b, w, h);
        d_img = demosaic(&raw_d, w, h);
    }
    // processing: sharpening, composition, JPEG-style compression
    if p.sharpen > 0.0 {
        b_img = sharpen(&b_img, p.sharpen, true);
        d_img = sharpen(&d_img, p.sharpen, false);
    }
    let mut out = photo.clone();
    for i in 0..n {
        let wv = weight(l.m.pixels[i]);
        let d = d_img.pixels[i];
        if wv > 0.0 || d != Vec3::ZERO {
            let pp = photo.pixels[i];
            out.pixels[i] = (pp + (b_img.pixels[i] - pp) * wv + d * (1.0 - wv)).clamp(Vec3::ZERO, Vec3::ONE);
        }
    }
    if let Some(q) = p.jpeg_quality {
        let compressed = jpeg::compress(&out, q);
        for i in 0..n {
            let wv = weight(l.m.pixels[i]);
            if wv > 0.0 {
                out.pixels[i] = out.pixels[i] + (compressed.pixels[i] - out.pixels[i]) * wv;
            }
        }
    }
    let processed = (0..n).filter(|&i| out.pixels[i] != photo.pixels[i] || mask.values[i] > 0.0).count();
    Ok((out, CaReport { invalid_inputs, processed_fraction: processed as f32 / n.max(1) as f32 }))
}

#[cfg(test)]
mod tests;
