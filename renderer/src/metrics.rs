//! Image metrics, over the whole image or over a mask (pixels with mask value > 0.5):
//! RMSE and PSNR on linear radiance (peak: the reference's largest luminance) and on
//! display-encoded values (peak 1); SSIM (Wang et al. 2004: 11×11 Gaussian window, σ = 1.5,
//! K1 = 0.01, K2 = 0.03, on display luminance); and FLIP (LDR-FLIP of Andersson et al. 2020
//! through the `nv-flip` crate, NVIDIA's reference implementation, at 67 pixels per degree).

use crate::image::{Image, Mask, quantize8};
use crate::math::luminance;
use serde::Serialize;

/// The `prob` quantile of `sorted` (ascending) by linear interpolation between order
/// statistics — R's `quantile(type = 7)`, the rule of `mrstudy_analysis::task::quantile_type7`;
/// 0 for an empty slice.
pub fn quantile(sorted: &[f64], prob: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let index = (sorted.len() - 1) as f64 * prob.clamp(0.0, 1.0);
    let lo = index.floor();
    let low_value = sorted[lo as usize];
    let high_value = sorted[(index.ceil() as usize).min(sorted.len() - 1)];
    if index > lo && high_value != low_value {
        let h = index - lo;
        (1.0 - h) * low_value + h * high_value
    } else {
        low_value
    }
}

/// Errors of a test image against a reference.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct ImageErrors {
    pub rmse_linear: f64,
    pub psnr_linear: f64,
    pub rmse_display: f64,
    pub psnr_display: f64,
    pub ssim: f64,
    pub flip: f64,
    /// Pixels the errors were taken over.
    pub pixels: usize,
}

fn selected(mask: Option<&Mask>, i: usize) -> bool {
    mask.is_none_or(|m| m.values[i] > 0.5)
}

/// Root-mean-square error over all channels of the selected pixels (0 when none are selected).
pub fn rmse(reference: &Image, test: &Image, mask: Option<&Mask>) -> f64 {
    let mut s = 0.0f64;
    let mut n = 0usize;
    for (i, (a, b)) in reference.pixels.iter().zip(&test.pixels).enumerate() {
        if selected(mask, i) {
            let d = (*a - *b).as_dvec3();
            s += d.length_squared();
            n += 3;
        }
    }
    if n == 0 { 0.0 } else { (s / n as f64).sqrt() }
}

/// PSNR in dB; capped at 200 dB for identical images so that it is always finite.
pub fn psnr(rmse: f64, peak: f64) -> f64 {
    (20.0 * (peak / rmse.max(1e-10)).log10()).min(200.0)
}

fn gaussian_blur(values: &[f64], w: usize, h: usize) -> Vec<f64> {
    let sigma = 1.5f64;
    let kernel: Vec<f64> = (-5..=5).map(|i: i32| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp()).collect();
    let ksum: f64 = kernel.iter().sum();
    let pass = |src: &[f64], horizontal: bool| -> Vec<f64> {
        let mut out = vec![0.0; src.len()];
        for y in 0..h {
            for x in 0..w {
                let mut s = 0.0;
                for (k, kv) in kernel.iter().enumerate() {
                    let o = k as i64 - 5;
                    let (sx, sy) = if horizontal {
                        ((x as i64 + o).clamp(0, w as i64 - 1) as usize, y)
                    } else {
                        (x, (y as i64 + o).clamp(0, h as i64 - 1) as usize)
                    };
                    s += kv * src[sy * w + sx];
                }
                out[y * w + x] = s / ksum;
            }
        }
        out
    };
    pass(&pass(values, true), false)
}

/// The SSIM map on display luminance (values expected in [0, 1]).
pub fn ssim_map(reference: &Image, test: &Image) -> Vec<f64> {
    let (w, h) = (reference.width as usize, reference.height as usize);
    let x: Vec<f64> = reference.pixels.iter().map(|p| luminance(*p) as f64).collect();
    let y: Vec<f64> = test.pixels.iter().map(|p| luminance(*p) as f64).collect();
    let xx: Vec<f64> = x.iter().map(|v| v * v).collect();
    let yy: Vec<f64> = y.iter().map(|v| v * v).collect();
    let xy: Vec<f64> = x.iter().zip(&y).map(|(a, b)| a * b).collect();
    let (mx, my) = (gaussian_blur(&x, w, h), gaussian_blur(&y, w, h));
    let (sxx, syy, sxy) = (gaussian_blur(&xx, w, h), gaussian_blur(&yy, w, h), gaussian_blur(&xy, w, h));
    let c1 = (0.01f64).powi(2);
    let c2 = (0.03f64).powi(2);
    (0..w * h)
        .map(|i| {
            let vx = (sxx[i] - mx[i] * mx[i]).max(0.0);
            let vy = (syy[i] - my[i] * my[i]).max(0.0);
            let cov = sxy[i] - mx[i] * my[i];
            ((2.0 * mx[i] * my[i] + c1) * (2.0 * cov + c2)) / ((mx[i] * mx[i] + my[i] * my[i] + c1) * (vx + vy + c2))
        })
        .collect()
}

fn masked_mean(values: &[f64], mask: Option<&Mask>) -> f64 {
    let mut s = 0.0;
    let mut n = 0usize;
    for (i, v) in values.iter().enumerate() {
        if selected(mask, i) {
            s += v;
            n += 1;
        }
    }
    if n == 0 { 0.0 } else { s / n as f64 }
}

/// Mean SSIM over the selected pixels (1 = identical).
pub fn ssim(reference: &Image, test: &Image, mask: Option<&Mask>) -> f64 {
    masked_mean(&ssim_map(reference, test), mask)
}

/// The LDR-FLIP error map of two display-encoded images (0 = identical, 1 = maximal).
pub fn flip_map(reference: &Image, test: &Image) -> Mask {
    let r = nv_flip::FlipImageRgb8::with_data(reference.width, reference.height, &reference.to_rgb8());
    let t = nv_flip::FlipImageRgb8::with_data(test.width, test.height, &test.to_rgb8());
    let map = nv_flip::flip(r, t, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    Mask { width: reference.width, height: reference.height, values: map.to_vec() }
}

/// Mean FLIP over the selected pixels.
pub fn flip(reference: &Image, test: &Image, mask: Option<&Mask>) -> f64 {
    let m = flip_map(reference, test);
    let v: Vec<f64> = m.values.iter().map(|&x| x as f64).collect();
    masked_mean(&v, mask)
}

/// Every metric at once. `*_linear` are radiance buffers, `*_display` camera outputs.
pub fn compare(
    reference_linear: &Image,
    test_linear: &Image,
    reference_display: &Image,
    test_display: &Image,
    mask: Option<&Mask>,
) -> ImageErrors {
    let peak = reference_linear.pixels.iter().map(|p| luminance(*p) as f64).fold(1e-6, f64::max);
    let rl = rmse(reference_linear, test_linear, mask);
    let rd = rmse(reference_display, test_display, mask);
    let pixels = (0..reference_linear.pixels.len()).filter(|&i| selected(mask, i)).count();
    ImageErrors {
        rmse_linear: rl,
        psnr_linear: psnr(rl, peak),
        rmse_display: rd,
        psnr_display: psnr(rd, 1.0),
        ssim: ssim(reference_display, test_display, mask),
        flip: flip(reference_display, test_display, mask),
        pixels,
    }
}

/// 8-bit round trip, for comparing what a viewer sees.
pub fn quantized(img: &Image) -> Image {
    img.map(|p| glam::Vec3::new(quantize8(p.x) as f32, quantize8(p.y) as f32, quantize8(p.z) as f32) / 255.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn quantile_matches_r_type_7() {
        // R 4.2.2: quantile(c(1, 2, 4, 7, 11), .25) = 2; quantile(c(1, 2, 4, 7), c(.25, .75)) =
        // 1.75, 4.75; quantile(1:20, .95) = 19.05 (the values of analysis's quantile_type7 test)
        assert_eq!(quantile(&[1.0, 2.0, 4.0, 7.0, 11.0], 0.25), 2.0);
        assert_eq!(quantile(&[1.0, 2.0, 4.0, 7.0], 0.25), 1.75);
        assert_eq!(quantile(&[1.0, 2.0, 4.0, 7.0], 0.75), 4.75);
        let twenty: Vec<f64> = (1..=20).map(f64::from).collect();
        assert!((quantile(&twenty, 0.95) - 19.05).abs() < 1e-12);
        assert_eq!(quantile(&[], 0.95), 0.0);
    }

    fn gradient() -> Image {
        let mut img = Image::new(32, 24);
        for y in 0..24 {
            for x in 0..32 {
                img.set(x, y, Vec3::new(x as f32 / 32.0, y as f32 / 24.0, 0.5));
            }
        }
        img
    }

    #[test]
    fn identical_images_have_no_error() {
        let a = gradient();
        let e = compare(&a, &a, &a, &a, None);
        assert_eq!(e.rmse_linear, 0.0);
        assert_eq!(e.psnr_display, 200.0);
        assert!((e.ssim - 1.0).abs() < 1e-9);
        assert!(e.flip < 1e-6, "flip {}", e.flip);
    }

    #[test]
    fn rmse_and_psnr_of_a_constant_offset() {
        // every channel off by 0.1: RMSE 0.1, PSNR 20 dB at peak 1
        let a = gradient();
        let b = a.map(|p| p + Vec3::splat(0.1));
        assert!((rmse(&a, &b, None) - 0.1).abs() < 1e-6);
        assert!((psnr(0.1, 1.0) - 20.0).abs() < 1e-9);
        // SSIM is below 1 and FLIP above 0 for a visible change
        assert!(ssim(&a, &b, None) < 0.999);
        assert!(flip(&a, &b, None) > 0.01);
    }

    #[test]
    fn masks_restrict_the_region() {
        let a = gradient();
        let mut b = a.clone();
        b.set(3, 3, Vec3::ONE);
        let mut m = Mask::new(32, 24);
        m.values[0] = 1.0;
        assert_eq!(rmse(&a, &b, Some(&m)), 0.0);
        m.values[3 * 32 + 3] = 1.0;
        assert!(rmse(&a, &b, Some(&m)) > 0.0);
        let empty = Mask::new(32, 24);
        assert_eq!(rmse(&a, &b, Some(&empty)), 0.0);
    }
}
