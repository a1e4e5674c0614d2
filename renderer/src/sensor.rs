//! The simulated camera: turns linear scene radiance into the image a real camera would deliver.
//! Every stage is optional (neutral parameters switch it off); presets model a 2013 USB webcam
//! (`webcam`), a current phone (`phone`) and an ideal camera (`clean`, sRGB encoding only).
//!
//! Stage order, as light meets them: optics — defocus blur (disc), lens distortion
//! (Brown–Conrady k1, k2, p1, p2, k3) with lateral chromatic aberration (red and blue magnified
//! by 1 ± `chromatic_aberration` about the principal point), vignetting (1 − v·r²); sensor —
//! exposure (× 2^EV), white-balance gains, Bayer mosaic (RGGB), Poisson–Gaussian noise
//! (variance a·y + b on values in [0, 1]), clipping at full well; processing — bilinear
//! demosaicing, saturation, response curve, contrast, unsharp-mask sharpening, 8-bit
//! quantisation, JPEG compression. Noise is a pure function of (seed, pixel, channel), so two
//! images through the same camera with the same seed share one noise realisation.

use crate::camera::Camera;
use crate::image::{Image, srgb_encode};
use crate::math::{Rng, luminance};
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// The tone response of the camera.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ToneCurve {
    /// No encoding (the output stays linear, clipped to [0, 1]).
    Linear,
    /// The sRGB transfer curve, hard clip at 1.
    Srgb,
    /// A soft shoulder (extended Reinhard, white at 4) followed by sRGB: cheap cameras' look.
    Filmic,
}

/// Fully resolved camera parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SensorParams {
    pub exposure_ev: f32,
    pub white_balance: [f32; 3],
    pub response: ToneCurve,
    pub saturation: f32,
    pub contrast: f32,
    pub vignetting: f32,
    /// Brown–Conrady [k1, k2, p1, p2, k3].
    pub distortion: [f32; 5],
    pub chromatic_aberration: f32,
    /// Defocus disc radius in pixels.
    pub defocus_px: f32,
    pub bayer: bool,
    /// Poisson–Gaussian noise [a, b]: variance a·y + b.
    pub noise: [f32; 2],
    pub sharpen: f32,
    /// JPEG quality 1–100; None: no compression.
    pub jpeg_quality: Option<u8>,
    pub seed: u64,
}

impl SensorParams {
    pub fn clean() -> Self {
        SensorParams {
            exposure_ev: 0.0,
            white_balance: [1.0; 3],
            response: ToneCurve::Srgb,
            saturation: 1.0,
            contrast: 1.0,
            vignetting: 0.0,
            distortion: [0.0; 5],
            chromatic_aberration: 0.0,
            defocus_px: 0.0,
            bayer: false,
            noise: [0.0, 0.0],
            sharpen: 0.0,
            jpeg_quality: None,
            seed: 0,
        }
    }
    /// A 2013 USB webcam (640×480 class): warm white balance, soft shoulder, strong vignetting
    /// and barrel distortion, visible chroma fringes, slight blur, strong noise, over-sharpened,
    /// heavily compressed.
    pub fn webcam() -> Self {
        SensorParams {
            exposure_ev: 0.0,
            white_balance: [1.08, 1.0, 0.86],
            response: ToneCurve::Filmic,
            saturation: 0.85,
            contrast: 1.1,
            vignetting: 0.35,
            distortion: [-0.12, 0.03, 0.0, 0.0, 0.0],
            chromatic_aberration: 0.003,
            defocus_px: 0.8,
            bayer: true,
            noise: [0.004, 0.0002],
            sharpen: 0.6,
            jpeg_quality: Some(60),
            seed: 0,
        }
    }
    /// A current phone camera: neutral balance, punchy colour, mild optics, low noise, light
    /// compression.
    pub fn phone() -> Self {
        SensorParams {
            exposure_ev: 0.0,
            white_balance: [1.0, 1.0, 1.0],
            response: ToneCurve::Srgb,
            saturation: 1.15,
            contrast: 1.15,
            vignetting: 0.12,
            distortion: [-0.03, 0.0, 0.0, 0.0, 0.0],
            chromatic_aberration: 0.001,
            defocus_px: 0.0,
            bayer: true,
            noise: [0.0008, 0.00002],
            sharpen: 0.35,
            jpeg_quality: Some(90),
            seed: 0,
        }
    }
    pub fn preset(name: &str) -> Option<Self> {
        match name {
            "clean" => Some(Self::clean()),
            "webcam" => Some(Self::webcam()),
            "phone" => Some(Self::phone()),
            _ => None,
        }
    }
    pub const PRESETS: [&'static str; 3] = ["webcam", "phone", "clean"];
}

/// The `[camera.sensor]` table: a preset and optional overrides of any of its parameters.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorDesc {
    /// `webcam`, `phone` or `clean` (default).
    pub preset: Option<String>,
    pub seed: Option<u64>,
    pub exposure_ev: Option<f32>,
    pub white_balance: Option<[f32; 3]>,
    pub response: Option<ToneCurve>,
    pub saturation: Option<f32>,
    pub contrast: Option<f32>,
    pub vignetting: Option<f32>,
    pub distortion: Option<[f32; 5]>,
    pub chromatic_aberration: Option<f32>,
    pub defocus_px: Option<f32>,
    pub bayer: Option<bool>,
    pub noise: Option<[f32; 2]>,
    pub sharpen: Option<f32>,
    pub jpeg_quality: Option<u8>,
}

impl SensorDesc {
    /// Resolves to parameters, or (key, expectation) naming the bad value.
    pub fn resolve(&self) -> Result<SensorParams, (String, String)> {
        let name = self.preset.as_deref().unwrap_or("clean");
        let mut p = SensorParams::preset(name)
            .ok_or_else(|| ("preset".to_string(), format!("\"webcam\", \"phone\" or \"clean\", not \"{name}\"")))?;
        macro_rules! set {
            ($f:ident) => {
                if let Some(v) = self.$f {
                    p.$f = v;
                }
            };
        }
        set!(exposure_ev);
        set!(white_balance);
        set!(response);
        set!(saturation);
        set!(contrast);
        set!(vignetting);
        set!(distortion);
        set!(chromatic_aberration);
        set!(defocus_px);
        set!(bayer);
        set!(noise);
        set!(sharpen);
        if let Some(s) = self.seed {
            p.seed = s;
        }
        if let Some(q) = self.jpeg_quality {
            p.jpeg_quality = if q == 0 { None } else { Some(q) };
        }
        let bad = |k: &str, e: &str| Err((k.to_string(), e.to_string()));
        if !p.exposure_ev.is_finite() {
            return bad("exposure_ev", "a finite number of stops");
        }
        if p.white_balance.iter().any(|g| !(*g > 0.0 && g.is_finite())) {
            return bad("white_balance", "three positive gains");
        }
        if !(p.saturation >= 0.0) || !(p.contrast > 0.0) {
            return bad("saturation", "saturation ≥ 0 and contrast > 0");
        }
        if !(0.0..=1.0).contains(&p.vignetting) {
            return bad("vignetting", "a strength in [0, 1]");
        }
        if !(p.defocus_px >= 0.0 && p.defocus_px <= 32.0) {
            return bad("defocus_px", "a radius in [0, 32] pixels");
        }
        if p.noise.iter().any(|v| !(*v >= 0.0)) {
            return bad("noise", "[a, b] with a, b ≥ 0");
        }
        if p.jpeg_quality.is_some_and(|q| q > 100) {
            return bad("jpeg_quality", "a quality in 1..=100 (0 for none)");
        }
        Ok(p)
    }
}

/// Runs linear radiance through the camera; returns the display-encoded image in [0, 1].
pub fn apply(radiance: &Image, camera: &Camera, p: &SensorParams) -> Image {
    let (w, h) = (radiance.width, radiance.height);
    let mut img = radiance.clone();
    // --- optics
    if p.defocus_px > 0.0 {
        img = disc_blur(&img, p.defocus_px);
    }
    if p.distortion.iter().any(|k| *k != 0.0) || p.chromatic_aberration != 0.0 {
        img = distort(&img, camera, p.distortion, p.chromatic_aberration);
    }
    if p.vignetting > 0.0 {
        let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
        let r_max2 = cx * cx + cy * cy;
        for y in 0..h {
            for x in 0..w {
                let dx = x as f32 + 0.5 - cx;
                let dy = y as f32 + 0.5 - cy;
                let r2 = (dx * dx + dy * dy) / r_max2;
                let v = img.get(x, y) * (1.0 - p.vignetting * r2);
                img.set(x, y, v);
            }
        }
    }
    // --- sensor
    let gain = 2f32.powf(p.exposure_ev) * Vec3::from_array(p.white_balance);
    for px in img.pixels.iter_mut() {
        *px *= gain;
    }
    let noisy = p.noise[0] > 0.0 || p.noise[1] > 0.0;
    if p.bayer {
        // keep one channel per site (RGGB), add noise there, clip, demosaic
        let mut raw = vec![0.0f32; (w * h) as usize];
        for y in 0..h {
            for x in 0..w {
                let c = bayer_channel(x, y);
                let i = (y * w + x) as usize;
                let mut v = img.pixels[i][c];
                if noisy {
                    let mut rng = Rng::for_stream(p.seed, i as u64, 7);
                    v += (p.noise[0] * v.clamp(0.0, 1.0) + p.noise[1]).sqrt() * rng.next_normal();
                }
                raw[i] = v.clamp(0.0, 1.0);
            }
        }
        img = demosaic_bilinear(&raw, w, h);
    } else {
        for (i, px) in img.pixels.iter_mut().enumerate() {
            let mut a = px.to_array();
            for (c, v) in a.iter_mut().enumerate() {
                if noisy {
                    let mut rng = Rng::for_stream(p.seed, i as u64, c as u64);
                    *v += (p.noise[0] * v.clamp(0.0, 1.0) + p.noise[1]).sqrt() * rng.next_normal();
                }
                *v = v.clamp(0.0, 1.0);
            }
            *px = Vec3::from_array(a);
        }
    }
    // --- processing
    for px in img.pixels.iter_mut() {
        let mut c = *px;
        if p.saturation != 1.0 {
            let l = luminance(c);
            c = (Vec3::splat(l) + (c - Vec3::splat(l)) * p.saturation).max(Vec3::ZERO);
        }
        c = match p.response {
            ToneCurve::Linear => c.clamp(Vec3::ZERO, Vec3::ONE),
            ToneCurve::Srgb => Vec3::new(srgb_encode(c.x), srgb_encode(c.y), srgb_encode(c.z)),
            ToneCurve::Filmic => {
                let f = |x: f32| {
                    let x = x * 1.25;
                    srgb_encode(x * (1.0 + x / 16.0) / (1.0 + x))
                };
                Vec3::new(f(c.x), f(c.y), f(c.z))
            }
        };
        if p.contrast != 1.0 {
            c = ((c - Vec3::splat(0.5)) * p.contrast + Vec3::splat(0.5)).clamp(Vec3::ZERO, Vec3::ONE);
        }
        *px = c;
    }
    if p.sharpen > 0.0 {
        let blurred = gaussian3(&img);
        for (px, b) in img.pixels.iter_mut().zip(&blurred.pixels) {
            *px = (*px + (*px - *b) * p.sharpen).clamp(Vec3::ZERO, Vec3::ONE);
        }
    }
    // 8-bit quantisation, then JPEG
    let bytes = img.to_rgb8();
    match p.jpeg_quality {
        Some(q) => jpeg_roundtrip(&bytes, w, h, q).unwrap_or_else(|| Image::from_rgb8(w, h, &bytes)),
        None => Image::from_rgb8(w, h, &bytes),
    }
}

#[inline]
fn bayer_channel(x: u32, y: u32) -> usize {
    match (x % 2, y % 2) {
        (0, 0) => 0,
        (1, 1) => 2,
        _ => 1,
    }
}

/// Bilinear demosaicing of an RGGB mosaic: each missing channel is the mean of the nearest
/// sites that carry it.
pub fn demosaic_bilinear(raw: &[f32], w: u32, h: u32) -> Image {
    let mut out = Image::new(w, h);
    let at = |x: i64, y: i64| -> (usize, f32) {
        let x = x.clamp(0, w as i64 - 1) as u32;
        let y = y.clamp(0, h as i64 - 1) as u32;
        (bayer_channel(x, y), raw[(y * w + x) as usize])
    };
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            let mut sum = [0.0f32; 3];
            let mut cnt = [0u32; 3];
            let (c0, v0) = at(x, y);
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (c, v) = at(x + dx, y + dy);
                    // the site's own channel is exact; the others average their neighbours
                    if c == c0 && (dx != 0 || dy != 0) {
                        continue;
                    }
                    // only direct neighbours for green, diagonals allowed for red/blue
                    if c == 1 && dx != 0 && dy != 0 {
                        continue;
                    }
                    sum[c] += v;
                    cnt[c] += 1;
                }
            }
            let mut px = [0.0f32; 3];
            for c in 0..3 {
                px[c] = if c == c0 {
                    v0
                } else if cnt[c] > 0 {
                    sum[c] / cnt[c] as f32
                } else {
                    v0
                };
            }
            out.set(x as u32, y as u32, Vec3::from_array(px));
        }
    }
    out
}

/// The taps (dx, dy, weight) of a disc of `radius` pixels: each weight is the area of the pixel
/// inside the disc, approximated by 4×4 supersampling (not normalised).
pub(crate) fn disc_taps(radius: f32) -> Vec<(i64, i64, f32)> {
    let r = radius.ceil() as i64;
    let mut taps = Vec::new();
    for dy in -r..=r {
        for dx in -r..=r {
            let mut inside = 0;
            for sy in 0..4 {
                for sx in 0..4 {
                    let px = dx as f32 + (sx as f32 + 0.5) / 4.0 - 0.5;
                    let py = dy as f32 + (sy as f32 + 0.5) / 4.0 - 0.5;
                    if px * px + py * py <= radius * radius {
                        inside += 1;
                    }
                }
            }
            if inside > 0 {
                taps.push((dx, dy, inside as f32));
            }
        }
    }
    taps
}

pub(crate) fn disc_blur(img: &Image, radius: f32) -> Image {
    let taps = disc_taps(radius);
    if taps.is_empty() {
        return img.clone();
    }
    let total: f32 = taps.iter().map(|t| t.2).sum();
    let mut out = Image::new(img.width, img.height);
    for y in 0..img.height as i64 {
        for x in 0..img.width as i64 {
            let mut s = Vec3::ZERO;
            for &(dx, dy, wgt) in &taps {
                s += img.get_clamped(x + dx, y + dy) * wgt;
            }
            out.set(x as u32, y as u32, s / total);
        }
    }
    out
}

fn gaussian3(img: &Image) -> Image {
    let mut out = Image::new(img.width, img.height);
    for y in 0..img.height as i64 {
        for x in 0..img.width as i64 {
            out.set(x as u32, y as u32, binomial3(img, x, y));
        }
    }
    out
}

/// The 3×3 binomial blur ([1 2 1]ᵀ[1 2 1] / 16, edges clamped) of `img` at (x, y): the one
/// kernel of the camera's unsharp mask, here and in the `ca` chain's sharpening
/// ([`crate::ca`]). The sum is in row order and scaled by 1/16 (a power of two: the same bits
/// as dividing by 16).
pub(crate) fn binomial3(img: &Image, x: i64, y: i64) -> Vec3 {
    let k = [1.0f32, 2.0, 1.0];
    let mut s = Vec3::ZERO;
    for (j, ky) in k.iter().enumerate() {
        for (i, kx) in k.iter().enumerate() {
            s += img.get_clamped(x + i as i64 - 1, y + j as i64 - 1) * (kx * ky);
        }
    }
    s * (1.0 / 16.0)
}

/// Brown–Conrady forward model on normalised coordinates.
pub(crate) fn brown_conrady(x: f32, y: f32, k: [f32; 5]) -> (f32, f32) {
    let r2 = x * x + y * y;
    let radial = 1.0 + k[0] * r2 + k[1] * r2 * r2 + k[4] * r2 * r2 * r2;
    let xd = x * radial + 2.0 * k[2] * x * y + k[3] * (r2 + 2.0 * x * x);
    let yd = y * radial + k[2] * (r2 + 2.0 * y * y) + 2.0 * k[3] * x * y;
    (xd, yd)
}

/// The ideal point x_u with D(x_u) = x_d (Brown–Conrady inverted by 8 fixed-point steps).
pub(crate) fn undistort(xd: f32, yd: f32, k: [f32; 5]) -> (f32, f32) {
    let (mut xu, mut yu) = (xd, yd);
    for _ in 0..8 {
        let (dx, dy) = brown_conrady(xu, yu, k);
        xu += xd - dx;
        yu += yd - dy;
    }
    (xu, yu)
}

/// Barrel distortion would show scene beyond the rendered frame at the borders; rather than
/// smear edge pixels there, [`apply`] zooms just enough that every sample stays inside the
/// frame (what a camera's "valid pixels only" rectification does). This is that zoom.
pub(crate) fn distortion_zoom(camera: &Camera, k: [f32; 5], ca: f32) -> f32 {
    let (fx, fy, cx, cy) = (camera.fx, camera.fy, camera.cx, camera.cy);
    let (x0, x1) = (-cx / fx, (camera.width as f32 - cx) / fx);
    let (y0, y1) = (-cy / fy, (camera.height as f32 - cy) / fy);
    let mut zoom = 1.0f32;
    for (xd, yd) in [(x0, y0), (x1, y0), (x0, y1), (x1, y1), (x0, 0.0), (x1, 0.0), (0.0, y0), (0.0, y1)] {
        let (xu, yu) = undistort(xd, yd, k);
        let ca_max = 1.0 / (1.0 - ca.abs()).max(0.5);
        if xu.abs() * ca_max > 1e-6 && xd != 0.0 {
            zoom = zoom.min(xd.abs() / (xu.abs() * ca_max));
        }
        if yu.abs() * ca_max > 1e-6 && yd != 0.0 {
            zoom = zoom.min(yd.abs() / (yu.abs() * ca_max));
        }
    }
    zoom
}

/// Warps the ideal image into the distorted one: the output pixel at distorted position x_d
/// shows the ideal point x_u with D(x_u) = x_d (found by fixed-point iteration), zoomed so that
/// no sample leaves the rendered frame. Lateral
/// chromatic aberration scales the red and blue sampling positions by 1 ± `ca`.
fn distort(img: &Image, camera: &Camera, k: [f32; 5], ca: f32) -> Image {
    let mut out = Image::new(img.width, img.height);
    let (fx, fy, cx, cy) = (camera.fx, camera.fy, camera.cx, camera.cy);
    let zoom = distortion_zoom(camera, k, ca);
    for y in 0..img.height {
        for x in 0..img.width {
            let xd = (x as f32 + 0.5 - cx) / fx;
            let yd = (y as f32 + 0.5 - cy) / fy;
            let (xu, yu) = undistort(xd, yd, k);
            let (xu, yu) = (xu * zoom, yu * zoom);
            let mut px = [0.0f32; 3];
            for (c, scale) in [(0usize, 1.0 / (1.0 + ca)), (1, 1.0), (2, 1.0 / (1.0 - ca))] {
                let sx = cx + xu * scale * fx;
                let sy = cy + yu * scale * fy;
                px[c] = img.sample_bilinear(sx, sy)[c];
            }
            out.set(x, y, Vec3::from_array(px));
        }
    }
    out
}

fn jpeg_roundtrip(bytes: &[u8], w: u32, h: u32, quality: u8) -> Option<Image> {
    let mut buf = Vec::new();
    let enc = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut buf, quality.clamp(1, 100));
    image::ImageEncoder::write_image(enc, bytes, w, h, image::ExtendedColorType::Rgb8).ok()?;
    let dec = image::load_from_memory_with_format(&buf, image::ImageFormat::Jpeg).ok()?.into_rgb8();
    Some(Image::from_rgb8(w, h, dec.as_raw()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn test_image() -> (Image, Camera) {
        let cam = Camera::from_fov(48, 32, 50.0, Vec3::new(0.0, 0.0, 1.0), Vec3::ZERO, Vec3::Y);
        let mut img = Image::new(48, 32);
        for y in 0..32 {
            for x in 0..48 {
                img.set(x, y, Vec3::new(x as f32 / 48.0, y as f32 / 32.0, 0.3) * 0.8);
            }
        }
        (img, cam)
    }

    #[test]
    fn deterministic_per_seed_and_different_across_seeds() {
        let (img, cam) = test_image();
        let mut p = SensorParams::webcam();
        let a = apply(&img, &cam, &p);
        let b = apply(&img, &cam, &p);
        assert_eq!(a, b);
        p.seed = 99;
        let c = apply(&img, &cam, &p);
        assert_ne!(a, c);
    }

    #[test]
    fn clean_camera_is_srgb_encoding() {
        let (img, cam) = test_image();
        let out = apply(&img, &cam, &SensorParams::clean());
        for (o, i) in out.pixels.iter().zip(&img.pixels) {
            assert!((o.x - srgb_encode(i.x)).abs() <= 0.5 / 255.0 + 1e-6);
        }
    }

    #[test]
    fn noise_variance_follows_a_y_plus_b() {
        // a flat grey field, linear response, no other stage: sample variance ≈ a·y + b
        let y = 0.4f32;
        let img = Image::filled(128, 128, Vec3::splat(y));
        let cam = Camera::from_fov(128, 128, 50.0, Vec3::Z, Vec3::ZERO, Vec3::Y);
        let mut p = SensorParams::clean();
        p.response = ToneCurve::Linear;
        p.noise = [0.01, 0.001];
        let out = apply(&img, &cam, &p);
        // quantisation adds 1/12 LSB²
        let vals: Vec<f64> = out.pixels.iter().map(|c| c.y as f64).collect();
        let mean = vals.iter().sum::<f64>() / vals.len() as f64;
        let var = vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (vals.len() - 1) as f64;
        let expected = 0.01 * y as f64 + 0.001 + (1.0 / 255.0f64).powi(2) / 12.0;
        // the sample variance of n normals has relative standard error sqrt(2/(n-1)) ≈ 1.1 %
        assert!((var / expected - 1.0).abs() < 0.06, "var {var} expected {expected}");
    }

    #[test]
    fn every_stage_runs_and_stays_in_range() {
        let (img, cam) = test_image();
        for name in SensorParams::PRESETS {
            let out = apply(&img, &cam, &SensorParams::preset(name).unwrap());
            assert!(out.pixels.iter().all(|p| p.is_finite() && p.min_element() >= 0.0 && p.max_element() <= 1.0));
        }
    }

    #[test]
    fn barrel_distortion_pulls_corners_inward() {
        // a white frame border: with k1 < 0 (barrel), the output corner samples beyond the
        // ideal image, i.e. the undistorted position of a corner lies further out.
        let (xd, yd) = (0.6f32, 0.4f32);
        let k = [-0.12, 0.03, 0.0, 0.0, 0.0];
        let (dx, _) = brown_conrady(xd, yd, k);
        assert!(dx < xd);
    }
}
