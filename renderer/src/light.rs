//! Lights: spot and point lights (delta lights, sampled by next-event estimation only), the
//! environment (an equirectangular radiance map, importance-sampled by luminance × sin θ), and
//! helpers that make environment maps: a procedural sky with a window, fish-eye conversion, and
//! repair of invalid pixels. Area lights are emissive triangles; see [`crate::pathtracer`].
//!
//! Direction convention of environment maps: world +Y is up; u = 0.5 looks down −Z (the default
//! camera direction), u increases towards +X; v = 0 is the zenith.

use crate::image::Image;
use crate::math::{Distribution1D, luminance};
use glam::Vec3;
use std::f32::consts::PI;

/// A spot light: radiant intensity `intensity` (W/sr per channel) on the axis, constant inside
/// the inner cone and falling off smoothly (smoothstep in cos θ) to zero at the outer cone.
/// A point light is a spot light with both cones at 180°.
#[derive(Clone, Debug)]
pub struct SpotLight {
    pub name: String,
    pub position: Vec3,
    pub direction: Vec3,
    pub cos_inner: f32,
    pub cos_outer: f32,
    pub intensity: Vec3,
    pub real: bool,
}

impl SpotLight {
    /// Radiant intensity towards the unit direction `dir` (from the light).
    pub fn intensity_towards(&self, dir: Vec3) -> Vec3 {
        let c = dir.dot(self.direction);
        if c >= self.cos_inner {
            return self.intensity;
        }
        if c <= self.cos_outer {
            return Vec3::ZERO;
        }
        let t = (c - self.cos_outer) / (self.cos_inner - self.cos_outer);
        self.intensity * (t * t * (3.0 - 2.0 * t))
    }
}

/// An importance-sampled equirectangular environment.
#[derive(Clone, Debug)]
pub struct Environment {
    pub map: Image,
    /// Rotation about +Y, as a fraction of a turn.
    pub rotation: f32,
    rows: Distribution1D,
    cols: Vec<Distribution1D>,
}

impl Environment {
    pub fn new(map: Image, rotation_deg: f32) -> Self {
        let (w, h) = (map.width as usize, map.height as usize);
        let mut row_weights = Vec::with_capacity(h);
        let mut cols = Vec::with_capacity(h);
        for j in 0..h {
            let sin_t = (PI * (j as f32 + 0.5) / h as f32).sin();
            let weights: Vec<f32> = (0..w).map(|i| luminance(map.pixels[j * w + i]).max(0.0) * sin_t).collect();
            let d = Distribution1D::new(&weights);
            row_weights.push(d.total);
            cols.push(d);
        }
        let rows = Distribution1D::new(&row_weights);
        Environment { map, rotation: rotation_deg / 360.0, rows, cols }
    }
    /// A constant environment (the white furnace).
    pub fn uniform(radiance: Vec3) -> Self {
        Environment::new(Image::filled(8, 4, radiance), 0.0)
    }

    fn dir_to_uv(&self, d: Vec3) -> (f32, f32) {
        let theta = d.y.clamp(-1.0, 1.0).acos();
        let phi = d.x.atan2(-d.z);
        let u = ((phi + PI) / (2.0 * PI) + self.rotation).rem_euclid(1.0);
        (u, theta / PI)
    }
    fn uv_to_dir(&self, u: f32, v: f32) -> Vec3 {
        equirect_dir(u - self.rotation, v)
    }
    /// Radiance arriving from direction `d` (pointing away from the scene), nearest texel.
    pub fn eval(&self, d: Vec3) -> Vec3 {
        let (u, v) = self.dir_to_uv(d);
        let i = ((u * self.map.width as f32) as u32).min(self.map.width - 1);
        let j = ((v * self.map.height as f32) as u32).min(self.map.height - 1);
        self.map.get(i, j)
    }
    /// Solid-angle pdf of [`Environment::sample`] producing `d`.
    pub fn pdf(&self, d: Vec3) -> f32 {
        let (u, v) = self.dir_to_uv(d);
        let (w, h) = (self.map.width as usize, self.map.height as usize);
        let i = ((u * w as f32) as usize).min(w - 1);
        let j = ((v * h as f32) as usize).min(h - 1);
        // (u, v) is uniform within a texel, so the solid-angle density uses the exact sin θ.
        let sin_t = (PI * v).sin();
        if sin_t <= 0.0 {
            return 0.0;
        }
        let p = self.rows.prob(j) * self.cols[j].prob(i);
        p * (w * h) as f32 / (2.0 * PI * PI * sin_t)
    }
    /// Samples a direction: (direction, radiance, solid-angle pdf).
    pub fn sample(&self, u1: f32, u2: f32) -> Option<(Vec3, Vec3, f32)> {
        let (w, h) = (self.map.width as usize, self.map.height as usize);
        let (j, pj, du_row) = self.rows.sample(u1);
        let (i, pi, du_col) = self.cols[j].sample(u2);
        let p = pj * pi;
        if p <= 0.0 {
            return None;
        }
        let u = (i as f32 + du_col) / w as f32;
        // uniform in (u, v) within the texel: the solid-angle density then has the exact sin θ
        let v = (j as f32 + du_row) / h as f32;
        let d = self.uv_to_dir(u, v);
        let sin_t = (PI * v).sin();
        if sin_t <= 1e-6 {
            return None;
        }
        let pdf = p * (w * h) as f32 / (2.0 * PI * PI * sin_t);
        Some((d, self.map.pixels[j * w + i], pdf))
    }
}

/// The direction of equirectangular map coordinates (`u`, `v`) in [0, 1)² of an unrotated map
/// (+y up, u = ½ looking down −z): the layout of every [`Environment`], and of the light probes
/// made for one.
pub fn equirect_dir(u: f32, v: f32) -> Vec3 {
    let phi = 2.0 * PI * u - PI;
    let theta = PI * v;
    Vec3::new(theta.sin() * phi.sin(), theta.cos(), -theta.sin() * phi.cos())
}

/// A procedural indoor "sky": a vertical gradient from `ground` through `horizon` to `zenith`,
/// with a rectangular window of radiance `window` centred on `window_dir`, `window_size_deg`
/// (width, height) wide. Returned as an equirectangular map of `width × width/2`.
pub fn procedural_sky(
    width: u32,
    zenith: Vec3,
    horizon: Vec3,
    ground: Vec3,
    window: Option<(Vec3, [f32; 2], Vec3)>,
) -> Image {
    let height = width / 2;
    let env = Environment { map: Image::new(1, 1), rotation: 0.0, rows: Distribution1D::new(&[1.0]), cols: vec![] };
    let mut img = Image::new(width, height);
    for j in 0..height {
        for i in 0..width {
            let d = env.uv_to_dir((i as f32 + 0.5) / width as f32, (j as f32 + 0.5) / height as f32);
            let mut c =
                if d.y >= 0.0 { horizon.lerp(zenith, d.y.powf(0.7)) } else { horizon.lerp(ground, (-d.y).powf(0.4)) };
            if let Some((wd, size, radiance)) = window {
                let wd = wd.normalize();
                let right = Vec3::Y.cross(-wd).normalize_or(Vec3::X);
                let up = (-wd).cross(right);
                let fwd = d.dot(wd);
                if fwd > 0.0 {
                    let x = (d.dot(right) / fwd).atan().to_degrees();
                    let y = (d.dot(up) / fwd).atan().to_degrees();
                    if x.abs() < size[0] / 2.0 && y.abs() < size[1] / 2.0 {
                        c = radiance;
                    }
                }
            }
            img.set(i, j, c);
        }
    }
    img
}

/// Converts an angular ("equidistant") fish-eye image looking straight up (+Y), covering
/// `fov_deg` in its inscribed circle, to an equirectangular map of `width × width/2`. Image right
/// is world +X and image down is world +Z. Directions outside the fish-eye's field are black.
pub fn fisheye_to_equirect(fish: &Image, fov_deg: f32, width: u32) -> Image {
    let height = width / 2;
    let env = Environment { map: Image::new(1, 1), rotation: 0.0, rows: Distribution1D::new(&[1.0]), cols: vec![] };
    let mut img = Image::new(width, height);
    let half = (fov_deg / 2.0).to_radians();
    let r_px = fish.width.min(fish.height) as f32 / 2.0;
    for j in 0..height {
        for i in 0..width {
            let d = env.uv_to_dir((i as f32 + 0.5) / width as f32, (j as f32 + 0.5) / height as f32);
            let alpha = d.y.clamp(-1.0, 1.0).acos();
            if alpha > half {
                continue;
            }
            let r = alpha / half * r_px;
            let az = d.z.atan2(d.x);
            let px = fish.width as f32 / 2.0 + r * az.cos();
            let py = fish.height as f32 / 2.0 + r * az.sin();
            img.set(i, j, fish.sample_bilinear(px, py));
        }
    }
    img
}

/// Replaces NaN, infinite and negative values by 0 (negative, NaN) or the largest finite value
/// of the map (+∞). Returns a warning naming what was repaired, or None when the map was clean.
pub fn repair_environment(map: &mut Image, source: &str) -> Option<String> {
    let (nan, inf, neg) = map.count_invalid();
    if nan + inf + neg == 0 {
        return None;
    }
    let max_finite = map.pixels.iter().flat_map(|p| p.to_array()).filter(|c| c.is_finite()).fold(0.0f32, f32::max);
    let mut first = None;
    for (k, p) in map.pixels.iter_mut().enumerate() {
        let mut a = p.to_array();
        let mut bad = false;
        for c in a.iter_mut() {
            if c.is_nan() || *c < 0.0 && c.is_finite() || *c == f32::NEG_INFINITY {
                *c = 0.0;
                bad = true;
            } else if *c == f32::INFINITY {
                *c = max_finite;
                bad = true;
            }
        }
        if bad && first.is_none() {
            first = Some(k);
        }
        *p = Vec3::from_array(a);
    }
    let k = first.unwrap_or(0);
    Some(format!(
        "environment map {source}: repaired {nan} NaN, {inf} infinite and {neg} negative channel values (NaN and negative set to 0, +inf to the largest finite value {max_finite}); first at pixel ({}, {})",
        k as u32 % map.width,
        k as u32 / map.width
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rng;

    #[test]
    fn environment_pdf_integrates_to_one_and_matches_sampling() {
        let sky = procedural_sky(
            64,
            Vec3::new(0.3, 0.4, 0.6),
            Vec3::splat(0.8),
            Vec3::splat(0.1),
            Some((Vec3::new(1.0, 0.5, -1.0), [30.0, 20.0], Vec3::splat(20.0))),
        );
        let env = Environment::new(sky, 30.0);
        let mut rng = Rng::new(1);
        // ∫ pdf dω over the sphere by uniform sampling
        let n = 200_000;
        let mut s = 0.0f64;
        for _ in 0..n {
            let d = crate::math::sample_uniform_sphere(rng.next_f32(), rng.next_f32());
            s += env.pdf(d) as f64 * 4.0 * std::f64::consts::PI;
        }
        assert!((s / n as f64 - 1.0).abs() < 0.02, "∫pdf = {}", s / n as f64);
        // sampled pdf equals pdf(dir), radiance equals eval(dir)
        for _ in 0..1000 {
            let (d, l, pdf) = env.sample(rng.next_f32(), rng.next_f32()).unwrap();
            assert!((env.pdf(d) - pdf).abs() <= 1e-3 * pdf.max(1.0), "{} vs {}", env.pdf(d), pdf);
            assert!((env.eval(d) - l).abs().max_element() < 1e-4);
        }
    }

    #[test]
    fn repair_names_what_it_fixed() {
        let mut m = Image::filled(4, 2, Vec3::ONE);
        m.pixels[1].x = f32::NAN;
        m.pixels[2].y = f32::INFINITY;
        m.pixels[3].z = -2.0;
        let w = repair_environment(&mut m, "test.hdr").unwrap();
        assert!(w.contains("1 NaN") && w.contains("1 infinite") && w.contains("1 negative"), "{w}");
        assert_eq!(m.count_invalid(), (0, 0, 0));
        assert!(repair_environment(&mut m, "x").is_none());
    }
}
