//! Image metrics, over the whole image or over a mask (pixels with mask value > 0.5):
//! RMSE and PSNR on linear radiance (peak: the reference's largest luminance) and on
//! display-encoded values (peak 1); SSIM (Wang et al. 2004: 11×11 Gaussian window, σ = 1.5,
//! K1 = 0.01, K2 = 0.03, on display luminance); and FLIP (LDR-FLIP of Andersson et al. 2020
//! through the `nv-flip` crate, NVIDIA's reference implementation, at 67 pixels per degree).
//!
//! [`stimulus_errors`] measures a stimulus against its ground-truth composite the way docs/design.md's
//! stimulus metrics CSV reports it: every metric in the whole image, the affected region and on
//! the virtual objects, from one FLIP, SSIM and CIEDE2000 map each.

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

/// The metrics of the stimulus metrics CSV (docs/design.md), in its order; `render_ms` is written
/// beside them by the caller that timed the render.
pub const STIMULUS_METRICS: [&str; 7] =
    ["flip_mean", "flip_p95", "rmse_linear", "rmse_display", "ssim", "ciede2000_mean", "ciede2000_p95"];

/// The regions of the stimulus metrics CSV: the whole image, the affected region (where the
/// virtual objects change the real scene, or cover it) and the virtual objects' mask.
pub const STIMULUS_REGIONS: [&str; 3] = ["image", "affected", "virtual"];

/// One value of the stimulus metrics CSV.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct MetricValue {
    pub metric: String,
    pub region: String,
    pub value: f64,
}

/// A stimulus's errors against its ground truth, per region, and the regions that had no
/// pixel (an empty mask: no value is made up for them).
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct StimulusErrors {
    pub values: Vec<MetricValue>,
    /// Regions left out, each with why (e.g. "affected: the mask is empty").
    pub skipped: Vec<String>,
}

impl StimulusErrors {
    /// The value of `metric` in `region`, if that region was measured.
    pub fn value(&self, metric: &str, region: &str) -> Option<f64> {
        self.values.iter().find(|v| v.metric == metric && v.region == region).map(|v| v.value)
    }
}

/// Every metric of [`STIMULUS_METRICS`] of `stimulus` against `ground_truth` (both
/// display-encoded, as a participant sees them) in each region of [`STIMULUS_REGIONS`]:
/// FLIP (mean and 95th percentile, R's type 7), RMSE on the linear values the display
/// encoding stands for and on the display values, mean SSIM, CIEDE2000 (mean and 95th
/// percentile). A region whose mask selects no pixel is skipped and said so.
pub fn stimulus_errors(ground_truth: &Image, stimulus: &Image, affected: &Mask, virtual_mask: &Mask) -> StimulusErrors {
    let n = ground_truth.pixels.len();
    assert_eq!(n, stimulus.pixels.len(), "a stimulus and its ground truth have the same size");
    let flip = flip_map(ground_truth, stimulus).values;
    let ssim = ssim_map(ground_truth, stimulus);
    let (gt_linear, stimulus_linear) = (ground_truth.srgb_to_linear(), stimulus.srgb_to_linear());
    let squared = |a: &Image, b: &Image| -> Vec<f64> {
        a.pixels.iter().zip(&b.pixels).map(|(p, q)| (*p - *q).as_dvec3().length_squared()).collect()
    };
    let squared_linear = squared(&gt_linear, &stimulus_linear);
    let squared_display = squared(ground_truth, stimulus);
    let delta_e: Vec<f64> = ground_truth
        .pixels
        .iter()
        .zip(&stimulus.pixels)
        .map(|(a, b)| crate::cm::colour::ciede2000_display(*a, *b))
        .collect();
    let mut errors = StimulusErrors::default();
    for region in STIMULUS_REGIONS {
        let mask = match region {
            "affected" => Some(affected),
            "virtual" => Some(virtual_mask),
            _ => None,
        };
        let pixels: Vec<usize> = (0..n).filter(|&i| selected(mask, i)).collect();
        if pixels.is_empty() {
            errors.skipped.push(format!("{region}: the mask is empty"));
            continue;
        }
        let mean = |values: &[f64]| pixels.iter().map(|&i| values[i]).sum::<f64>() / pixels.len() as f64;
        let p95 = |values: &[f64]| {
            let mut picked: Vec<f64> = pixels.iter().map(|&i| values[i]).collect();
            picked.sort_by(f64::total_cmp);
            quantile(&picked, 0.95)
        };
        let flip: Vec<f64> = flip.iter().map(|&v| v as f64).collect();
        let values = [
            mean(&flip),
            p95(&flip),
            (mean(&squared_linear) / 3.0).sqrt(),
            (mean(&squared_display) / 3.0).sqrt(),
            mean(&ssim),
            mean(&delta_e),
            p95(&delta_e),
        ];
        for (metric, value) in STIMULUS_METRICS.iter().zip(values) {
            errors.values.push(MetricValue { metric: metric.to_string(), region: region.to_string(), value });
        }
    }
    errors
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

    fn value(errors: &StimulusErrors, metric: &str, region: &str) -> f64 {
        errors.value(metric, region).unwrap()
    }

    #[test]
    fn a_stimulus_equal_to_its_ground_truth_has_zero_error_everywhere() {
        let a = gradient();
        let mut affected = Mask::new(32, 24);
        affected.values[..200].fill(1.0);
        let mut virtual_mask = Mask::new(32, 24);
        virtual_mask.values[50..80].fill(1.0);
        let errors = stimulus_errors(&a, &a, &affected, &virtual_mask);
        assert!(errors.skipped.is_empty());
        assert_eq!(errors.values.len(), STIMULUS_METRICS.len() * STIMULUS_REGIONS.len());
        for v in &errors.values {
            let expected = if v.metric == "ssim" { 1.0 } else { 0.0 };
            assert!((v.value - expected).abs() < 1e-6, "{} {}: {}", v.metric, v.region, v.value);
        }
    }

    #[test]
    fn stimulus_errors_are_taken_per_region_and_empty_regions_are_said() {
        // the stimulus differs from the ground truth only inside the virtual mask: errors there,
        // none outside; the whole image's error is diluted; the empty affected mask is skipped
        let gt = gradient();
        let mut stimulus = gt.clone();
        let mut virtual_mask = Mask::new(32, 24);
        for y in 8..16 {
            for x in 8..16 {
                stimulus.set(x, y, Vec3::new(0.9, 0.1, 0.1));
                virtual_mask.values[(y * 32 + x) as usize] = 1.0;
            }
        }
        let errors = stimulus_errors(&gt, &stimulus, &Mask::new(32, 24), &virtual_mask);
        assert_eq!(errors.skipped, vec!["affected: the mask is empty".to_string()]);
        assert!(errors.values.iter().all(|v| v.region != "affected" && v.value.is_finite()));
        for metric in ["rmse_display", "rmse_linear", "ciede2000_mean", "flip_mean"] {
            let inside = value(&errors, metric, "virtual");
            let whole = value(&errors, metric, "image");
            assert!(inside > 0.0 && whole > 0.0 && whole < inside, "{metric}: {whole} vs {inside}");
        }
        // the RMSE of the region, by hand: mean over the 64 pixels of the squared difference
        let mut sum = 0.0f64;
        for y in 8..16 {
            for x in 8..16 {
                sum += (gt.get(x, y) - stimulus.get(x, y)).as_dvec3().length_squared();
            }
        }
        assert!((value(&errors, "rmse_display", "virtual") - (sum / 192.0).sqrt()).abs() < 1e-9);
        // 64 of 768 pixels changed: the image's p95 of CIEDE2000 is in the changed pixels' range
        assert!(value(&errors, "ciede2000_p95", "image") > 0.0);
        assert!(value(&errors, "ssim", "virtual") < 0.9);
    }
}
