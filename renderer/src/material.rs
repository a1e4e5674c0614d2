//! Materials: a Lambertian diffuse lobe plus an energy-conserving Blinn–Phong specular lobe,
//! optional albedo texture (image file or procedural), and emission; or a delta BSDF
//! ([`DeltaBsdf`]): a perfect mirror, or a smooth dielectric (glass) with Fresnel reflection,
//! refraction and Beer–Lambert absorption inside.
//!
//! The BRDF, in the local frame of the shading normal:
//!
//! ```text
//! f(ωi, ωo) = kd / π  +  ks · D(h) / (4 (ωi·h) max(cos θi, cos θo)),
//! D(h)      = (n + 1) / (2π) · cos^n θh              (a normalised Blinn–Phong lobe)
//! ```
//!
//! D is a probability density over half-vector directions, so the specular lobe can be sampled
//! exactly (cos θh = u^(1/(n+1))), and the Ashikhmin–Shirley style denominator bounds its
//! directional albedo by ks for every incidence and exponent. The BRDF is reciprocal, and with
//! kd + ks ≤ 1 per channel (checked when a scene is loaded) it never creates energy. The GPU
//! renderer must use the same formula to be comparable with the reference.

use crate::image::Image;
use crate::math::{Frame, luminance, sample_cosine_hemisphere};
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};
use std::sync::Arc;

/// A texture lookup: an image (linear values, repeat wrap, bilinear) or a procedural pattern.
#[derive(Clone, Debug)]
pub enum Texture {
    Image(Arc<Image>),
    /// Wood-like rings: two colours, ring frequency, seed-free (pure function of uv).
    Wood {
        light: Vec3,
        dark: Vec3,
        rings: f32,
    },
    Checker {
        a: Vec3,
        b: Vec3,
        squares: f32,
    },
    /// Horizontal stripes (book covers, labels).
    Stripes {
        a: Vec3,
        b: Vec3,
        count: f32,
    },
}

impl Texture {
    pub fn eval(&self, uv: Vec2) -> Vec3 {
        match self {
            Texture::Image(img) => {
                let u = uv.x.rem_euclid(1.0);
                let v = uv.y.rem_euclid(1.0);
                img.sample_bilinear(u * img.width as f32, (1.0 - v) * img.height as f32)
            }
            Texture::Wood { light, dark, rings } => {
                let x = uv.x * 1.0;
                let y = uv.y * 7.0;
                let warp = 0.15 * (y * 3.1 + (x * 2.3).sin()).sin() + 0.05 * (y * 17.0).sin();
                let r = ((x + warp) * rings).fract();
                let grain = 0.5 + 0.5 * (r * 2.0 * PI).cos();
                let t = grain.powf(3.0);
                light.lerp(*dark, t * 0.8)
            }
            Texture::Checker { a, b, squares } => {
                let i = (uv.x * squares).floor() as i64 + (uv.y * squares).floor() as i64;
                if i.rem_euclid(2) == 0 { *a } else { *b }
            }
            Texture::Stripes { a, b, count } => {
                if ((uv.y * count).floor() as i64).rem_euclid(2) == 0 {
                    *a
                } else {
                    *b
                }
            }
        }
    }
}

#[derive(Clone, Debug)]
pub struct Material {
    pub name: String,
    /// Diffuse albedo kd (multiplied by the texture, when there is one).
    pub albedo: Vec3,
    pub texture: Option<Texture>,
    /// Specular intensity ks.
    pub specular: Vec3,
    /// Blinn–Phong exponent n.
    pub exponent: f32,
    /// Emitted radiance (front face only).
    pub emission: Vec3,
    /// A mirror or glass: light leaves only in the reflected or refracted direction, and the
    /// lobes above are unused (zero).
    pub delta: Option<DeltaBsdf>,
}

impl Material {
    pub fn diffuse(name: &str, albedo: Vec3) -> Self {
        Material {
            name: name.into(),
            albedo,
            texture: None,
            specular: Vec3::ZERO,
            exponent: 1.0,
            emission: Vec3::ZERO,
            delta: None,
        }
    }

    /// A material that scatters by `delta` alone.
    pub fn delta(name: &str, delta: DeltaBsdf) -> Self {
        Material { albedo: Vec3::ZERO, delta: Some(delta), ..Material::diffuse(name, Vec3::ZERO) }
    }
    pub fn albedo_at(&self, uv: Vec2) -> Vec3 {
        match &self.texture {
            Some(t) => self.albedo * t.eval(uv),
            None => self.albedo,
        }
    }
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}

/// A BSDF that scatters into one direction (or two, for glass): nothing reaches it by
/// next-event estimation, and paths through it are sampled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DeltaBsdf {
    /// A perfect mirror reflecting `reflectance` (per channel) of the incident light.
    Mirror { reflectance: Vec3 },
    /// A smooth dielectric interface: index of refraction `ior` inside (1 outside), unpolarised
    /// Fresnel reflection, refraction by Snell's law, and inside the Beer–Lambert absorption
    /// coefficient `absorption` per scene unit (light travelling a distance d inside keeps
    /// exp(−absorption · d)). The object must be closed with outward normals.
    Dielectric { ior: f32, absorption: Vec3 },
}

/// Which quantity a path carries: radiance from the camera, or importance (flux) from a light.
/// Only refraction tells them apart: radiance is scaled by (η_o / η_t)² across an interface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transport {
    Radiance,
    Importance,
}

/// A sampled direction of a delta BSDF: the new direction, the path weight, and whether the
/// path went through the surface.
#[derive(Clone, Copy, Debug)]
pub struct DeltaSample {
    pub wi: Vec3,
    pub weight: Vec3,
    pub transmitted: bool,
}

/// Unpolarised Fresnel reflectance of a smooth interface for light arriving at cos θ_i
/// (> 0) from a medium of index `eta_i` onto one of index `eta_t`; 1 under total internal
/// reflection.
pub fn fresnel_dielectric(cos_i: f32, eta_i: f32, eta_t: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin_t = eta_i / eta_t * (1.0 - cos_i * cos_i).max(0.0).sqrt();
    if sin_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin_t * sin_t).max(0.0).sqrt();
    let parallel = (eta_t * cos_i - eta_i * cos_t) / (eta_t * cos_i + eta_i * cos_t);
    let perpendicular = (eta_i * cos_i - eta_t * cos_t) / (eta_i * cos_i + eta_t * cos_t);
    0.5 * (parallel * parallel + perpendicular * perpendicular)
}

impl DeltaBsdf {
    /// Samples the direction a path leaving towards `wo` (pointing away from the surface) came
    /// from, with the uniform number `u` choosing between reflection and refraction (by their
    /// Fresnel weights, so the weight is the reflectance or 1 — times the radiance scaling).
    /// `normal` is the surface's outward normal, `front` whether `wo` is on its side.
    pub fn sample(&self, wo: Vec3, normal: Vec3, front: bool, u: f32, transport: Transport) -> DeltaSample {
        let n = if front { normal } else { -normal };
        let cos_o = n.dot(wo).max(0.0);
        let reflected = 2.0 * cos_o * n - wo;
        match *self {
            DeltaBsdf::Mirror { reflectance } => DeltaSample { wi: reflected, weight: reflectance, transmitted: false },
            DeltaBsdf::Dielectric { ior, .. } => {
                let (eta_o, eta_t) = if front { (1.0, ior) } else { (ior, 1.0) };
                let fresnel = fresnel_dielectric(cos_o, eta_o, eta_t);
                if u < fresnel {
                    return DeltaSample { wi: reflected, weight: Vec3::ONE, transmitted: false };
                }
                let eta = eta_o / eta_t;
                let sin2_t = eta * eta * (1.0 - cos_o * cos_o);
                let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
                let wi = (-eta * wo + (eta * cos_o - cos_t) * n).normalize();
                let scale = match transport {
                    Transport::Radiance => eta * eta,
                    Transport::Importance => 1.0,
                };
                DeltaSample { wi, weight: Vec3::splat(scale), transmitted: true }
            }
        }
    }

    /// What a path keeps after travelling `distance` inside the object (glass: Beer–Lambert).
    pub fn inside_transmittance(&self, distance: f32) -> Vec3 {
        match *self {
            DeltaBsdf::Mirror { .. } => Vec3::ONE,
            DeltaBsdf::Dielectric { absorption, .. } => (-absorption * distance).exp(),
        }
    }
}

/// The BRDF at one shading point.
#[derive(Clone, Copy, Debug)]
pub struct Bsdf {
    pub frame: Frame,
    pub kd: Vec3,
    pub ks: Vec3,
    pub exponent: f32,
    /// Probability of sampling the specular lobe.
    p_spec: f32,
}

/// One BSDF sample: direction, weight f·cos/pdf, and pdf.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    pub wi: Vec3,
    pub weight: Vec3,
    pub pdf: f32,
}

impl Bsdf {
    pub fn new(normal: Vec3, kd: Vec3, ks: Vec3, exponent: f32) -> Self {
        let ld = luminance(kd).max(0.0);
        let ls = luminance(ks).max(0.0);
        let p_spec = if ld + ls > 0.0 { ls / (ld + ls) } else { 0.0 };
        Bsdf { frame: Frame::from_normal(normal), kd, ks, exponent: exponent.max(0.0), p_spec }
    }

    #[inline]
    fn d(&self, cos_h: f32) -> f32 {
        (self.exponent + 1.0) / (2.0 * PI) * cos_h.max(0.0).powf(self.exponent)
    }

    /// f(wi, wo) (world directions, both pointing away from the surface).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let lo = self.frame.to_local(wo);
        let li = self.frame.to_local(wi);
        self.eval_local(lo, li)
    }

    fn eval_local(&self, lo: Vec3, li: Vec3) -> Vec3 {
        if lo.z <= 0.0 || li.z <= 0.0 {
            return Vec3::ZERO;
        }
        let mut f = self.kd * FRAC_1_PI;
        if self.ks.max_element() > 0.0 {
            let h = (lo + li).normalize();
            let idoth = li.dot(h).max(1e-8);
            f += self.ks * self.d(h.z) / (4.0 * idoth * lo.z.max(li.z));
        }
        f
    }

    /// f(wi, wo) and the solid-angle pdf of sampling `wi` given `wo`, with one change of frame
    /// (next-event estimation's MIS needs both).
    #[inline(always)]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let lo = self.frame.to_local(wo);
        let li = self.frame.to_local(wi);
        (self.eval_local(lo, li), self.pdf_local(lo, li))
    }

    /// Solid-angle pdf of sampling `wi` given `wo`.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let lo = self.frame.to_local(wo);
        let li = self.frame.to_local(wi);
        self.pdf_local(lo, li)
    }

    fn pdf_local(&self, lo: Vec3, li: Vec3) -> f32 {
        if lo.z <= 0.0 || li.z <= 0.0 {
            return 0.0;
        }
        let mut pdf = (1.0 - self.p_spec) * li.z * FRAC_1_PI;
        if self.p_spec > 0.0 {
            let h = (lo + li).normalize();
            pdf += self.p_spec * self.d(h.z) / (4.0 * lo.dot(h).max(1e-8));
        }
        pdf
    }

    /// Samples an incoming direction with uniform numbers `u_lobe`, `u1`, `u2`.
    #[inline(always)]
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u1: f32, u2: f32) -> Option<BsdfSample> {
        let lo = self.frame.to_local(wo);
        if lo.z <= 0.0 || (self.kd.max_element() <= 0.0 && self.ks.max_element() <= 0.0) {
            return None;
        }
        if self.p_spec <= 0.0 {
            // Lambertian: cosine sampling, whose weight f cos / pdf is the albedo itself
            let li = sample_cosine_hemisphere(u1, u2);
            if li.z <= 0.0 {
                return None;
            }
            return Some(BsdfSample { wi: self.frame.to_world(li), weight: self.kd, pdf: li.z * FRAC_1_PI });
        }
        let li = if u_lobe < self.p_spec {
            let cos_h = u1.powf(1.0 / (self.exponent + 1.0));
            let sin_h = (1.0 - cos_h * cos_h).max(0.0).sqrt();
            let phi = 2.0 * PI * u2;
            let h = Vec3::new(sin_h * phi.cos(), sin_h * phi.sin(), cos_h);
            let li = 2.0 * lo.dot(h) * h - lo;
            if li.z <= 0.0 {
                return None;
            }
            li
        } else {
            sample_cosine_hemisphere(u1, u2)
        };
        let pdf = self.pdf_local(lo, li);
        if pdf <= 0.0 {
            return None;
        }
        let f = self.eval_local(lo, li);
        Some(BsdfSample { wi: self.frame.to_world(li), weight: f * li.z / pdf, pdf })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Rng, sample_uniform_sphere};

    /// Directional albedo by uniform-sphere Monte Carlo: ∫ f cos dωi.
    fn albedo(bsdf: &Bsdf, wo: Vec3, n: usize, rng: &mut Rng) -> (f64, f64) {
        let mut sum = 0.0f64;
        let mut sum2 = 0.0f64;
        for _ in 0..n {
            let wi = sample_uniform_sphere(rng.next_f32(), rng.next_f32());
            let v = (bsdf.eval(wo, wi).x * wi.z.max(0.0) * 4.0 * PI) as f64;
            sum += v;
            sum2 += v * v;
        }
        let mean = sum / n as f64;
        let se = ((sum2 / n as f64 - mean * mean).max(0.0) / n as f64).sqrt();
        (mean, se)
    }

    #[test]
    fn blinn_phong_directional_albedo_never_exceeds_one() {
        let mut rng = Rng::new(3);
        for &exponent in &[1.0f32, 10.0, 100.0] {
            let bsdf = Bsdf::new(Vec3::Z, Vec3::splat(0.0), Vec3::splat(1.0), exponent);
            for &theta in &[0.0f32, 0.6, 1.2, 1.5] {
                let wo = Vec3::new(theta.sin(), 0.0, theta.cos());
                // importance-sampled estimate (the sample weight is f cos / pdf ≤ ks)
                let n = 20_000;
                let mut sum = 0.0f64;
                for _ in 0..n {
                    if let Some(s) = bsdf.sample(wo, 0.0, rng.next_f32(), rng.next_f32()) {
                        assert!(s.weight.x <= 1.0 + 1e-4, "sample weight {} > 1", s.weight.x);
                        sum += s.weight.x as f64;
                    }
                }
                let a = sum / n as f64;
                assert!(a <= 1.0 + 1e-6, "albedo {a} at n={exponent} θ={theta}");
                if exponent >= 100.0 && theta == 0.0 {
                    // a narrow lobe at normal incidence loses almost nothing
                    assert!(a > 0.9, "albedo {a} too low at n={exponent} θ={theta}");
                }
            }
        }
    }

    #[test]
    fn lambert_albedo_equals_kd() {
        let mut rng = Rng::new(5);
        let bsdf = Bsdf::new(Vec3::Z, Vec3::splat(0.7), Vec3::ZERO, 1.0);
        let (mean, se) = albedo(&bsdf, Vec3::new(0.3, 0.0, 0.95).normalize(), 200_000, &mut rng);
        assert!((mean - 0.7).abs() < 4.0 * se + 1e-3, "{mean} ± {se}");
    }

    #[test]
    fn combined_lobes_conserve_energy_and_sampling_matches_eval() {
        // kd + ks = 1: albedo ≤ 1, and the importance-sampled estimate agrees with the
        // uniform-sphere estimate of the same integral (checks pdf and eval consistency).
        let mut rng = Rng::new(11);
        let bsdf = Bsdf::new(Vec3::Z, Vec3::splat(0.6), Vec3::splat(0.4), 20.0);
        let wo = Vec3::new(0.5, 0.0, 0.866).normalize();
        let (uniform, se) = albedo(&bsdf, wo, 400_000, &mut rng);
        let n = 100_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            if let Some(s) = bsdf.sample(wo, rng.next_f32(), rng.next_f32(), rng.next_f32()) {
                sum += s.weight.x as f64;
            }
        }
        let sampled = sum / n as f64;
        assert!(sampled <= 1.0 + 1e-3);
        assert!((sampled - uniform).abs() < 4.0 * se + 0.01, "sampled {sampled} uniform {uniform} ± {se}");
    }

    #[test]
    fn fresnel_matches_the_closed_forms() {
        // normal incidence: ((n1 − n2) / (n1 + n2))²
        assert!((fresnel_dielectric(1.0, 1.0, 1.5) - 0.04).abs() < 1e-6);
        assert!((fresnel_dielectric(1.0, 1.5, 1.0) - 0.04).abs() < 1e-6);
        // Brewster's angle: the parallel part vanishes, the perpendicular one is
        // ((cos θi − n cos θt) / (cos θi + n cos θt))² / 2 with θi + θt = 90°
        let brewster = 1.5f32.atan();
        let (ci, ct) = (brewster.cos(), brewster.sin());
        let perpendicular = ((ci - 1.5 * ct) / (ci + 1.5 * ct)).powi(2);
        assert!((fresnel_dielectric(ci, 1.0, 1.5) - 0.5 * perpendicular).abs() < 1e-6);
        // total internal reflection beyond the critical angle (41.8° for 1.5 → 1)
        assert_eq!(fresnel_dielectric(42.5f32.to_radians().cos(), 1.5, 1.0), 1.0);
        assert!(fresnel_dielectric(41.0f32.to_radians().cos(), 1.5, 1.0) < 1.0);
    }

    #[test]
    fn refraction_obeys_snell_and_scales_radiance_by_the_squared_index_ratio() {
        let glass = DeltaBsdf::Dielectric { ior: 1.5, absorption: Vec3::ZERO };
        let theta = 0.6f32;
        let wo = Vec3::new(theta.sin(), 0.0, theta.cos());
        // u = 1 always refracts (the Fresnel reflectance is below 1)
        let s = glass.sample(wo, Vec3::Z, true, 1.0, Transport::Radiance);
        assert!(s.transmitted && s.wi.z < 0.0);
        let sin_t = (s.wi.x * s.wi.x + s.wi.y * s.wi.y).sqrt();
        assert!((theta.sin() - 1.5 * sin_t).abs() < 1e-5, "Snell: {} vs {}", theta.sin(), 1.5 * sin_t);
        assert!(s.wi.x < 0.0, "the refracted ray goes on across the normal");
        assert!((s.weight.x - 1.0 / 2.25).abs() < 1e-6);
        assert_eq!(glass.sample(wo, Vec3::Z, true, 1.0, Transport::Importance).weight, Vec3::ONE);
        // from inside the scaling is inverted, and u = 0 reflects about the inner normal
        let inside = glass.sample(-wo, Vec3::Z, false, 1.0, Transport::Radiance);
        assert!(inside.transmitted && (inside.weight.x - 2.25).abs() < 1e-5);
        let mirrored = glass.sample(wo, Vec3::Z, true, 0.0, Transport::Radiance);
        assert!(!mirrored.transmitted && (mirrored.wi - Vec3::new(-wo.x, 0.0, wo.z)).length() < 1e-6);
        // Beer–Lambert
        let green = DeltaBsdf::Dielectric { ior: 1.5, absorption: Vec3::new(2.0, 0.1, 2.0) };
        let kept = green.inside_transmittance(0.5);
        assert!((kept - Vec3::new((-1.0f32).exp(), (-0.05f32).exp(), (-1.0f32).exp())).abs().max_element() < 1e-6);
    }

    #[test]
    fn brdf_is_reciprocal() {
        let bsdf = Bsdf::new(Vec3::Z, Vec3::splat(0.3), Vec3::splat(0.5), 30.0);
        let a = Vec3::new(0.2, 0.1, 0.97).normalize();
        let b = Vec3::new(-0.4, 0.3, 0.86).normalize();
        assert!((bsdf.eval(a, b) - bsdf.eval(b, a)).abs().max_element() < 1e-6);
    }
}
