//! How closely the virtual regions of a frame match the real camera: the estimators of
//! [`super::estimate`] run on the virtual objects of a frame (ca off, or on with scene or
//! estimated parameters), on the same pixels of the path-traced ground truth (which went through
//! the simulated camera, so it shows what the camera does to the virtual objects), and on the
//! untouched real pixels of the photograph. Used by `mrstudy bench render --ca`.
//!
//! Regions, all in the camera's (distorted) image: the reference's virtual coverage and affected
//! region are warped by the camera's distortion. Noise is measured inside the virtual region
//! eroded by 2 px (no silhouette edges); blur on edges centred inside the virtual region
//! grown by 2 px (its silhouettes included); the real region is everything outside the affected region grown by 4 px.

use super::estimate::{blur, noise};
use crate::camera::Camera;
use crate::image::{Image, Mask};
use crate::sensor::{self, SensorParams};
use serde::Serialize;

/// Noise σ (display units) and blur (disc radius, px) measured on one image region.
#[derive(Clone, Debug, Serialize)]
pub struct RegionStats {
    /// Mean display value (over channels) in the noise region.
    pub mean: f32,
    pub noise_sigma: f32,
    pub noise_samples: usize,
    pub blur_radius_px: Option<f32>,
    pub blur_edges: usize,
}

/// The measurement regions of a frame, in the camera's image.
#[derive(Clone, Debug)]
pub struct Regions {
    pub virtual_inner: Mask,
    pub virtual_edges: Mask,
    pub real: Mask,
}

fn grow(mask: &Mask, radius: i64, erode: bool) -> Mask {
    let (w, h) = (mask.width as i64, mask.height as i64);
    let mut out = Mask::new(mask.width, mask.height);
    for y in 0..h {
        for x in 0..w {
            let mut any = false;
            let mut all = true;
            for dy in -radius..=radius {
                for dx in -radius..=radius {
                    let (xx, yy) = (x + dx, y + dy);
                    let v =
                        if xx < 0 || yy < 0 || xx >= w || yy >= h { 0.0 } else { mask.values[(yy * w + xx) as usize] };
                    any |= v > 0.5;
                    all &= v > 0.5;
                }
            }
            out.values[(y * w + x) as usize] = if (erode && all) || (!erode && any) { 1.0 } else { 0.0 };
        }
    }
    out
}

/// A mask of the ideal (pinhole) image carried into the camera's image by its distortion.
pub fn warp_mask(mask: &Mask, camera: &Camera, s: &SensorParams) -> Mask {
    let mut p = SensorParams::clean();
    p.response = sensor::ToneCurve::Linear;
    p.distortion = s.distortion;
    let warped = sensor::apply(&mask.to_image(), camera, &p);
    Mask {
        width: mask.width,
        height: mask.height,
        values: warped.pixels.iter().map(|c| if c.y > 0.5 { 1.0 } else { 0.0 }).collect(),
    }
}

impl Regions {
    /// From the reference's virtual coverage and affected region (ideal image).
    pub fn new(virtual_mask: &Mask, affected: &Mask, camera: &Camera, s: &SensorParams) -> Regions {
        let v = warp_mask(virtual_mask, camera, s);
        let a = warp_mask(affected, camera, s);
        let mut real = grow(&a, 4, false);
        for r in real.values.iter_mut() {
            *r = 1.0 - *r;
        }
        Regions { virtual_inner: grow(&v, 2, true), virtual_edges: grow(&v, 2, false), real }
    }
}

/// Noise over `noise_region` and blur over `blur_region` of `img`, quantised to 8 bits first
/// (what is shown; the photograph was quantised by the camera).
pub fn measure(img: &Image, noise_region: &Mask, blur_region: &Mask) -> RegionStats {
    let img = super::estimate::quantised(img);
    let n = noise(&img, Some(noise_region));
    let b = blur(&img, Some(blur_region));
    let (mut sum, mut count) = (0.0f64, 0usize);
    for (p, m) in img.pixels.iter().zip(&noise_region.values) {
        if *m > 0.5 {
            sum += ((p.x + p.y + p.z) / 3.0) as f64;
            count += 1;
        }
    }
    let mean = if count > 0 { (sum / count as f64) as f32 } else { 0.0 };
    RegionStats {
        mean,
        noise_sigma: n.sigma,
        noise_samples: n.samples,
        blur_radius_px: b.radius_px,
        blur_edges: b.edges,
    }
}
