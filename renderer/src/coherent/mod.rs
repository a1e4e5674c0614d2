//! Coherent rendering by sampling (Rohmer, Jendersie and Grosch; issue 18): the virtual object
//! and its influence on the real scene rendered from a captured environment
//! ([`crate::capture`]), every illumination query a ray or cone into a scene representation —
//! environment mapping (EM), distance impostor tracing (DIT) or voxel cone tracing (VCT),
//! [`query`] — and composed in the reference (linear) colour space (Sec. 6.6).
//!
//! The frame is rendered on the CPU, pass by pass as the paper's Table 2 lists them (the
//! representation is built on the GPU where a renderer is given, [`build_representation`]):
//! representation build, the G-buffer with the tests of eq. 9 against the virtual object's
//! bounding box, the virtual object (importance-sampled Blinn–Phong, Sec. 6.3, self-shadowing
//! and on `high` a secondary diffuse bounce), material estimation (eq. 5), the differential
//! background (eq. 8 with the object-aware cache of eq. 9; cones by eq. 6 where the query is
//! VCT) and the composition. Where it departs from the paper, it says so:
//! - the G-buffer is the real scene's true geometry (as differential instant radiosity's is)
//!   rather than the splatted point cloud;
//! - the virtual object's self-shadow rays and secondary bounces march its solid voxel volume
//!   ([`solid`]) as the paper's do, but its primary visibility (the paper rasterises it), the
//!   known lights' shadows on it and the differential background's rays to it intersect it
//!   exactly (its BVH);
//! - what the capture did not reach is answered by a light probe at the virtual object (the
//!   real scene path traced from there, as the thesis's fish-eye capture of the surroundings);
//! - a scene with several virtual objects gets one distance impostor per object, centred in it,
//!   and a query reads the one nearest its origin (the paper has one object);
//! - the scene's point and spot lights, which have no extent a camera could capture, are known
//!   lights: they light the object and the real surfaces with visibility tested through the
//!   representation and the virtual object (the virtual lights of a scene need this too).
//!
//! `Method::Off` is the baseline without coherent rendering: the object lit by the known lights
//! and the light probe with no occlusion at all, and no differential background.

mod build;
pub mod evaluation;
mod gpu_frame;
pub mod impostor;
pub mod query;
pub mod render;
pub mod solid;
pub mod voxel;

#[cfg(test)]
mod gpu_tests;
#[cfg(test)]
mod tests;

pub use build::{
    PROBE_PATHS, PROBE_WIDTH, Prebuilt, build_queries, build_representation, light_probe, virtual_bounds,
    virtual_object_bounds,
};

use crate::capture::hashgrid::EnvironmentSample;
use crate::coherent::impostor::DistanceImpostor;
use crate::coherent::voxel::VoxelVolume;
use crate::error::{RenderError, Result};
use crate::geometry::{Aabb, Ray, SurfaceHit};
use crate::gpu::PassTime;
use crate::image::{Image, Mask};
use crate::light::{Environment, SpotLight, equirect_dir};
use crate::material::{DeltaBsdf, Material, Transport};
use crate::math::{Frame, Rng, sample_cosine_hemisphere};
use crate::pathtracer::{Arrival, Subset, TraceParams, World, delta_bounce, shade};
use crate::scene::{Role, Scene};
use glam::Vec3;
use query::{Query, Representation};
use rayon::prelude::*;
use solid::SolidVolume;
use std::f32::consts::PI;
use std::sync::Arc;
use std::time::Instant;

/// A global-illumination method of Rohmer et al. (or none).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// No coherent rendering: the object lit without occlusion, the photograph untouched.
    Off,
    Em,
    Dit,
    Vct,
}

impl Method {
    pub const ALL: [Method; 4] = [Method::Off, Method::Em, Method::Dit, Method::Vct];

    pub fn parse(text: &str) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.name() == text)
    }

    pub fn name(self) -> &'static str {
        match self {
            Method::Off => "off",
            Method::Em => "em",
            Method::Dit => "dit",
            Method::Vct => "vct",
        }
    }

    /// The query of the object's shading and the differential background.
    fn query(self) -> Query {
        match self {
            Method::Em => Query::Em,
            Method::Vct => Query::Vct,
            Method::Off | Method::Dit => Query::Dit,
        }
    }

    /// The query of material estimation: the paper uses DIT there for EM too (EM cannot
    /// answer from a real surface's position).
    fn material_query(self) -> Query {
        if self == Method::Vct { Query::Vct } else { Query::Dit }
    }
}

/// The paper's quality settings (Sec. 8, Table 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Quality {
    Low,
    Med,
    High,
}

impl Quality {
    pub const ALL: [Quality; 3] = [Quality::Low, Quality::Med, Quality::High];

    pub fn parse(text: &str) -> Option<Quality> {
        Quality::ALL.into_iter().find(|q| q.name() == text)
    }

    pub fn name(self) -> &'static str {
        match self {
            Quality::Low => "low",
            Quality::Med => "med",
            Quality::High => "high",
        }
    }

    /// *Low* and *med*: 16 samples for material estimation, the differential background
    /// (cache 8) and the object; *low* omits self-shadow tests. *High*: 64 (cache 32) and 128
    /// for the object, with a secondary bounce. Representations: the paper's 6×256² impostor
    /// and 256³ volume on *high*, half that per axis below (a CPU's memory and time); the
    /// object's solid volume 32 voxels along its longest axis below *high*, 128 on it.
    pub fn settings(self) -> Settings {
        match self {
            Quality::Low | Quality::Med => Settings {
                object_samples: 16,
                material_samples: 16,
                background_samples: 16,
                cache: 8,
                impostor_size: 128,
                scene_voxels: 128,
                object_voxels: 32,
                self_shadow: self == Quality::Med,
                secondary_bounce: false,
            },
            Quality::High => Settings {
                object_samples: 128,
                material_samples: 64,
                background_samples: 64,
                cache: 32,
                impostor_size: 256,
                scene_voxels: 256,
                object_voxels: 128,
                self_shadow: true,
                secondary_bounce: true,
            },
        }
    }
}

/// Sample counts and representation sizes.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Settings {
    /// BRDF samples per pixel of the virtual object (Sec. 6.3).
    pub object_samples: u32,
    /// Cosine samples per pixel of material estimation (eq. 5).
    pub material_samples: u32,
    /// Cosine directions per pixel tested against the object's box (N of eqs. 8 and 9).
    pub background_samples: u32,
    /// Directions traced of those that meet the box (|H_a| of eq. 9, the cache size); 0 traces
    /// every one (plain eq. 8).
    pub cache: u32,
    /// Texels per face of the distance impostor (EM, DIT).
    pub impostor_size: u32,
    /// Voxels per axis of the scene voxel volume (VCT).
    pub scene_voxels: u32,
    /// Voxels along the longest axis of each virtual object's solid volume (the others in
    /// proportion; the paper's 32³ and 128 × 96 × 96), built when `self_shadow` is on.
    pub object_voxels: u32,
    pub self_shadow: bool,
    pub secondary_bounce: bool,
}

/// Everything a coherent render depends on.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct CoherentParams {
    pub method: Method,
    pub quality: Quality,
    pub settings: Settings,
    pub seed: u64,
}

impl CoherentParams {
    pub fn new(method: Method, quality: Quality) -> CoherentParams {
        CoherentParams { method, quality, settings: quality.settings(), seed: 1 }
    }
}

/// What a coherent render did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct CoherentReport {
    pub method: String,
    pub quality: String,
    pub passes: Vec<PassTime>,
    pub representation_bytes: usize,
    /// Pixels the virtual object covers (in part).
    pub object_pixels: usize,
    /// Real pixels whose differential was computed (some cosine direction met the object's box,
    /// or a known light's path crossed it).
    pub background_pixels: usize,
    /// Real pixels left as photographed: no direction met the box (eq. 9's set F).
    pub background_skipped: usize,
    /// Directions traced for the differential background (H_a) and those eq. 9 accounted for
    /// by scaling instead (H_b).
    pub rays_traced: u64,
    pub rays_scaled: u64,
    /// Pixels whose estimated albedo exceeded 1 in some channel (clamped), and those that
    /// received no light to estimate it from (albedo 0).
    pub albedo_clamped: usize,
    pub albedo_unlit: usize,
    /// Parts of the method a scene did not need, in words.
    pub skipped: Vec<String>,
    /// What the frame asked of the GPU, where it ran there ([`Coherent::render_preferring_gpu`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub counters: Option<crate::gpu::context::FrameCounters>,
}

impl CoherentReport {
    pub fn total_ms(&self) -> f64 {
        self.passes.iter().map(|p| p.ms).sum()
    }
}

/// A coherent render's buffers (linear radiance) and report.
#[derive(Clone, Debug)]
pub struct CoherentFrame {
    /// The photograph with the differential background added and the object over it.
    pub composite: Image,
    /// ΔL of the real pixels (eq. 8 or 9), zero elsewhere.
    pub differential: Image,
    /// Estimated albedo ρ of eq. 5 where the differential was computed.
    pub albedo: Image,
    /// The virtual object's coverage per pixel (2×2 subsamples).
    pub coverage: Mask,
    /// The virtual object's radiance where it covers a pixel (the mean of its covered
    /// subsamples), zero elsewhere.
    pub object: Image,
    /// Per pixel, as the colour mapping reads them: `surface::VIRTUAL` where the object covers
    /// at least half, else `surface::REAL` where a real surface is modelled, else
    /// `surface::NOTHING`.
    pub flags: Vec<u32>,
    pub report: CoherentReport,
}

pub(crate) fn ms_since(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

/// The half-angle of a cone standing for the solid angle `omega`.
fn cone_half_angle(omega: f32) -> f32 {
    let omega = omega.clamp(1e-6, 2.0 * PI * 0.3);
    (1.0 - omega / (2.0 * PI)).clamp(-1.0, 1.0).acos()
}

/// A known light seen from `p`: the unit direction to it, its distance and the irradiance it
/// gives a surface of normal `n` there; None when it lies behind the surface or sends nothing
/// this way.
fn light_towards(spot: &SpotLight, p: Vec3, n: Vec3) -> Option<(Vec3, f32, Vec3)> {
    let d = spot.position - p;
    let dist2 = d.length_squared();
    let dist = dist2.sqrt();
    let wi = d / dist;
    let cos = n.dot(wi);
    let intensity = spot.intensity_towards(-wi);
    (cos > 0.0 && intensity.max_element() > 0.0).then(|| (wi, dist, intensity * (cos / dist2)))
}

/// Eq. 9's directions at `x`: `big_n` cosine samples about `n` drawn from `rng`, those that meet
/// the object's box `bounds` (the set H; the others are F).
fn box_directions<'r>(bounds: Aabb, x: Vec3, n: Vec3, big_n: u32, rng: &'r mut Rng) -> impl Iterator<Item = Vec3> + 'r {
    let frame = Frame::from_normal(n);
    (0..big_n)
        .map(move |_| frame.to_world(sample_cosine_hemisphere(rng.next_f32(), rng.next_f32())))
        .filter(move |dir| bounds.hit(x, dir.recip(), f32::INFINITY).is_some())
}

/// What the render of one pixel's background point needs.
#[derive(Clone, Copy, Debug)]
struct Background {
    point: Vec3,
    normal: Vec3,
    /// Whether the object (its box) or its effect on a known light reaches this point.
    affected: bool,
}

/// The renderer of one frame: the scene, the worlds, the representation.
pub struct Coherent<'a> {
    scene: &'a Scene,
    real: &'a World,
    object: World,
    rep: &'a Representation,
    params: CoherentParams,
    bounds: Option<Aabb>,
}

impl<'a> Coherent<'a> {
    pub fn new(scene: &'a Scene, real: &'a World, rep: &'a Representation, params: CoherentParams) -> Self {
        let object = World::new(scene, Subset::VirtualOnly);
        Coherent { scene, real, object, rep, params, bounds: virtual_bounds(scene) }
    }

    /// The frame's size, refused unless `photo` has it, and its report before any pass: what
    /// the CPU frame and the GPU frame ([`Coherent::render_gpu`]) both start with.
    pub(crate) fn frame_start(&self, photo: &Image) -> Result<(u32, u32, CoherentReport)> {
        let cam = &self.scene.camera;
        let (w, h) = (cam.width, cam.height);
        if photo.width != w || photo.height != h {
            return Err(RenderError::Unsupported(format!(
                "the photograph is {}×{} but the scene's camera is {w}×{h}",
                photo.width, photo.height
            )));
        }
        let report = CoherentReport {
            method: self.params.method.name().into(),
            quality: self.params.quality.name().into(),
            representation_bytes: self.rep.bytes(),
            ..CoherentReport::default()
        };
        Ok((w, h, report))
    }

    /// Renders the frame over `photo` (the photograph's linear radiance: the colour-compensated
    /// camera image of the paper's reference colour space).
    pub fn render(&self, photo: &Image, progress: &(dyn Fn(u32, u32) + Sync)) -> Result<CoherentFrame> {
        let (w, h, mut report) = self.frame_start(photo)?;
        let n = (w * h) as usize;
        let steps = 5;
        progress(0, steps);

        // G-buffer: coverage by 2×2 subsamples, the real point behind, eq. 9's box test
        let start = Instant::now();
        let gbuffer: Vec<(u8, Option<Background>)> = (0..n).into_par_iter().map(|k| self.gbuffer(k)).collect();
        report.passes.push(PassTime::new("G-buffer and box tests (eq. 9)", ms_since(start)));
        progress(1, steps);

        // the virtual object
        let start = Instant::now();
        let object: Vec<Vec3> =
            (0..n).into_par_iter().map(|k| if gbuffer[k].0 > 0 { self.object_pixel(k) } else { Vec3::ZERO }).collect();
        report.passes.push(PassTime::new("virtual object", ms_since(start)));
        report.object_pixels = gbuffer.iter().filter(|g| g.0 > 0).count();
        progress(2, steps);

        // material estimation where the differential is needed
        let start = Instant::now();
        let differential_on = self.params.method != Method::Off;
        let albedo: Vec<Option<Vec3>> = (0..n)
            .into_par_iter()
            .map(|k| match gbuffer[k].1 {
                Some(bg) if bg.affected && differential_on => {
                    Some(self.estimate_albedo(bg.point, bg.normal, photo.pixels[k], k as u64))
                }
                _ => None,
            })
            .collect();
        report.passes.push(PassTime::new("material estimation (eq. 5)", ms_since(start)));
        progress(3, steps);

        // the differential background
        let start = Instant::now();
        let (big_n, cache) = (self.params.settings.background_samples, self.params.settings.cache);
        let deltas: Vec<(Vec3, u64, u64)> = (0..n)
            .into_par_iter()
            .map(|k| match (gbuffer[k].1, albedo[k]) {
                (Some(bg), Some(rho)) => {
                    let mut rng = Rng::for_stream(self.params.seed, 0xd1ff, k as u64);
                    let rho = rho.clamp(Vec3::ZERO, Vec3::ONE);
                    let d = self.differential(bg.point, bg.normal, rho, big_n, cache, &mut rng);
                    (d.value, d.traced, d.scaled)
                }
                _ => (Vec3::ZERO, 0, 0),
            })
            .collect();
        report.passes.push(PassTime::new("differential background (eqs. 8, 9)", ms_since(start)));
        progress(4, steps);

        // composition in the reference colour space
        let start = Instant::now();
        let mut composite = Image::new(w, h);
        let mut differential = Image::new(w, h);
        let mut albedo_image = Image::new(w, h);
        let mut coverage = Mask::new(w, h);
        let mut flags = vec![crate::surface::NOTHING; n];
        for k in 0..n {
            let (covered, bg) = gbuffer[k];
            let c = covered as f32 / 4.0;
            flags[k] = if covered >= 2 {
                crate::surface::VIRTUAL
            } else if bg.is_some() {
                crate::surface::REAL
            } else {
                crate::surface::NOTHING
            };
            let background =
                if bg.is_some() { (photo.pixels[k] + deltas[k].0).max(Vec3::ZERO) } else { photo.pixels[k] };
            composite.pixels[k] = if covered == 0 { background } else { c * object[k] + (1.0 - c) * background };
            differential.pixels[k] = deltas[k].0;
            coverage.values[k] = c;
            if let Some(rho) = albedo[k] {
                albedo_image.pixels[k] = rho.clamp(Vec3::ZERO, Vec3::ONE);
                report.albedo_clamped += usize::from(rho.max_element() > 1.0);
                report.albedo_unlit += usize::from(rho == Vec3::ZERO && photo.pixels[k].max_element() > 0.0);
                report.background_pixels += 1;
            } else if bg.is_some() && covered < 4 {
                report.background_skipped += 1;
            }
            report.rays_traced += deltas[k].1;
            report.rays_scaled += deltas[k].2;
        }
        report.passes.push(PassTime::new("composition", ms_since(start)));
        progress(5, steps);
        if self.bounds.is_none() {
            report.skipped.push("no virtual object: the photograph is returned unchanged".into());
        }
        if !differential_on {
            report.skipped.push("gi off: no material estimation or differential background".into());
        } else if !self.params.settings.self_shadow {
            report.skipped.push("self-shadow tests (quality low)".into());
        }
        if self.scene.spots.is_empty() {
            report.skipped.push("known lights: the scene has no point or spot light".into());
        }
        let object = Image { width: w, height: h, pixels: object };
        Ok(CoherentFrame { composite, differential, albedo: albedo_image, coverage, object, flags, report })
    }

    /// Subsample `s` (0–3) of pixel `k`: its primary ray.
    fn primary(&self, k: usize, s: usize) -> Ray {
        let w = self.scene.camera.width as usize;
        let (x, y) = ((k % w) as f32, (k / w) as f32);
        self.scene.camera.ray(x + 0.25 + 0.5 * (s & 1) as f32, y + 0.25 + 0.5 * (s >> 1) as f32)
    }

    /// The real surface along `ray` and the virtual object's hit if it is nearer.
    fn first_hits(&self, ray: &Ray) -> (Option<SurfaceHit>, Option<(SurfaceHit, &Material)>) {
        let real = self.real.first_hit(ray).map(|(s, _)| s);
        let t_real = real.map_or(f32::INFINITY, |s| s.t);
        let object = if self.bounds.is_some() { self.object.hit_with_material(ray, t_real) } else { None };
        (real, object)
    }

    fn gbuffer(&self, k: usize) -> (u8, Option<Background>) {
        let mut covered = 0u8;
        let mut background = None;
        for s in 0..4 {
            let ray = self.primary(k, s);
            match self.first_hits(&ray) {
                (_, Some(_)) => covered += 1,
                (Some(real), None) if background.is_none() => {
                    background = Some(Background { point: real.point, normal: real.shading_normal, affected: false });
                }
                _ => {}
            }
        }
        if let Some(bg) = &mut background {
            bg.affected = self.affected(bg.point, bg.normal, k as u64);
        }
        (covered, background)
    }

    /// Whether the object can change the light at `x`: one of eq. 9's directions meets its
    /// box, or a known light's path to `x` crosses it, or a virtual light reaches `x`.
    fn affected(&self, x: Vec3, n: Vec3, k: u64) -> bool {
        let Some(bounds) = self.bounds else { return false };
        if self.params.method == Method::Off {
            return false;
        }
        let mut rng = Rng::for_stream(self.params.seed, 0xd1ff, k);
        if box_directions(bounds, x, n, self.params.settings.background_samples, &mut rng).next().is_some() {
            return true;
        }
        self.scene.spots.iter().any(|spot| {
            light_towards(spot, x, n)
                .is_some_and(|(wi, dist, _)| !spot.real || bounds.hit(x, wi.recip(), dist).is_some())
        })
    }

    /// The 2×2 subsamples of pixel `k` that see the object, shaded and averaged over all four.
    fn object_pixel(&self, k: usize) -> Vec3 {
        let mut sum = Vec3::ZERO;
        let mut covered = 0;
        let mut rng = Rng::for_stream(self.params.seed, 0x0b1ec7, k as u64);
        for s in 0..4 {
            let ray = self.primary(k, s);
            if let (_, Some((hit, mat))) = self.first_hits(&ray) {
                sum +=
                    self.shade_object(&hit, mat, -ray.dir, (self.params.settings.object_samples / 4).max(1), &mut rng);
                covered += 1;
            }
        }
        // the composition weights by coverage: the mean over the covered subsamples
        if covered > 0 { sum / covered as f32 } else { Vec3::ZERO }
    }

    /// Direct light of the scene's point and spot lights at `p` (normal `ns`, geometric `ng`)
    /// through `f`; `shadowed` tests the object and the representation.
    fn known_lights(&self, p: Vec3, ns: Vec3, ng: Vec3, shadowed: bool, f: impl Fn(Vec3) -> Vec3) -> Vec3 {
        let mut l = Vec3::ZERO;
        for spot in &self.scene.spots {
            let Some((wi, dist, irradiance)) = light_towards(spot, p, ns) else { continue };
            if ng.dot(wi) <= 0.0 {
                continue;
            }
            if shadowed {
                let ray = Ray { origin: p, dir: wi };
                if self.object.occluded(&ray, dist * (1.0 - 1e-4))
                    || !self.rep.transmits(self.params.method.query(), p, wi, dist)
                {
                    continue;
                }
            }
            l += f(wi) * irradiance;
        }
        l
    }

    /// The virtual object's radiance towards `wo` at `hit` with `samples` BRDF samples (Sec. 6.3).
    fn shade_object(&self, hit: &SurfaceHit, mat: &Material, wo: Vec3, samples: u32, rng: &mut Rng) -> Vec3 {
        let front = hit.geometric_normal.dot(wo) > 0.0;
        let ng = if front { hit.geometric_normal } else { -hit.geometric_normal };
        let mut l = if front { mat.emission } else { Vec3::ZERO };
        let method = self.params.method;
        if let Some(delta) = &mat.delta {
            // a mirror or glass: its one or two directions, sampled
            for _ in 0..samples {
                l += self.through_delta(delta, hit, wo, front, ng, rng) / samples as f32;
            }
            return l;
        }
        let Some((ns, bsdf, p)) = shade(mat, hit, ng) else { return l };
        let occluding = method != Method::Off;
        l += self.known_lights(p, ns, ng, occluding && self.params.settings.self_shadow, |wi| bsdf.eval(wo, wi));
        for _ in 0..samples {
            let u: [f32; 3] = std::array::from_fn(|_| rng.next_f32());
            let Some(bs) = bsdf.sample(wo, u[0], u[1], u[2]) else { continue };
            if bs.wi.dot(ng) <= 0.0 || !(bs.pdf > 0.0) {
                continue;
            }
            let half = cone_half_angle(1.0 / (samples as f32 * bs.pdf));
            let incident = if method == Method::Off {
                self.rep.sky.as_ref().map_or(Vec3::ZERO, |env| env.eval(bs.wi))
            } else {
                self.incident_at_object(p, ng, bs.wi, half, rng)
            };
            l += bs.weight * incident / samples as f32;
        }
        l
    }

    /// Light arriving at the object's surface point `p` from `dir`: stopped by the object
    /// itself (Sec. 6.3: zero on *med*, a secondary diffuse bounce on *high*), as its solid
    /// volume has it, else the query; `ng` is the surface's geometric normal on the side `dir`
    /// leaves by.
    fn incident_at_object(&self, p: Vec3, ng: Vec3, dir: Vec3, half: f32, rng: &mut Rng) -> Vec3 {
        let settings = &self.params.settings;
        if settings.self_shadow && self.rep.exact_self_shadows {
            if let Some(l) = self.exact_self_hit(p, dir, rng) {
                return l;
            }
        } else if settings.self_shadow
            && let Some(hit) = self.rep.solid_hit(p, ng, dir)
        {
            if !settings.secondary_bounce {
                return Vec3::ZERO;
            }
            if hit.surface.delta {
                // a mirror or glass: its exact surface passes its one direction on
                return self.exact_self_hit(p, dir, rng).unwrap_or(Vec3::ZERO);
            }
            return self.voxel_bounce(hit.point, hit.surface.normal, hit.surface.albedo, rng);
        }
        self.rep.incident(self.params.method.query(), p, dir, half).radiance
    }

    /// The object's exact surface along the ray from its point `p`: zero on *med*, its
    /// secondary diffuse bounce on *high*; None where the ray leaves the object.
    fn exact_self_hit(&self, p: Vec3, dir: Vec3, rng: &mut Rng) -> Option<Vec3> {
        let (hit, mat) = self.object.hit_with_material(&Ray { origin: p, dir }, f32::INFINITY)?;
        Some(if self.params.settings.secondary_bounce { self.diffuse_bounce(&hit, mat, -dir, rng) } else { Vec3::ZERO })
    }

    /// A diffuse surface of normal `n` and albedo `albedo` at `p` as the solid volume stores it
    /// (Sec. 6.3's secondary bounce): the known lights and one cosine-sampled query.
    fn voxel_bounce(&self, p: Vec3, n: Vec3, albedo: Vec3, rng: &mut Rng) -> Vec3 {
        if albedo.max_element() <= 0.0 {
            return Vec3::ZERO;
        }
        let query = self.params.method.query();
        let mut l = self.known_lights(p, n, n, true, |_| albedo / PI);
        let dir = Frame::from_normal(n).to_world(sample_cosine_hemisphere(rng.next_f32(), rng.next_f32()));
        l += albedo * self.rep.incident(query, p, dir, cone_half_angle(PI / 4.0)).radiance;
        l
    }

    /// The object's radiance at `hit` towards `wo`, as if it were diffuse (Sec. 6.4, ray 2):
    /// its emission, the known lights and one cosine-sampled query; mirrors and glass pass
    /// their one sampled direction on instead.
    fn diffuse_bounce(&self, hit: &SurfaceHit, mat: &Material, wo: Vec3, rng: &mut Rng) -> Vec3 {
        let front = hit.geometric_normal.dot(wo) > 0.0;
        let ng = if front { hit.geometric_normal } else { -hit.geometric_normal };
        if let Some(delta) = &mat.delta {
            return self.through_delta(delta, hit, wo, front, ng, rng);
        }
        let mut l = if front { mat.emission } else { Vec3::ZERO };
        let Some((ns, bsdf, p)) = shade(mat, hit, ng) else { return l };
        let albedo = bsdf.kd;
        if albedo.max_element() <= 0.0 {
            return l;
        }
        let query = self.params.method.query();
        l += self.known_lights(p, ns, ng, true, |_| albedo / PI);
        let dir = Frame::from_normal(ns).to_world(sample_cosine_hemisphere(rng.next_f32(), rng.next_f32()));
        if dir.dot(ng) > 0.0 {
            l += albedo * self.rep.incident(query, p, dir, cone_half_angle(PI / 4.0)).radiance;
        }
        l
    }

    /// A mirror or glass at `hit` seen from `wo`: its one sampled direction (the path tracer's
    /// [`delta_bounce`], absorption inside glass included) answered by the query, weighted.
    fn through_delta(
        &self,
        delta: &DeltaBsdf,
        hit: &SurfaceHit,
        wo: Vec3,
        front: bool,
        ng: Vec3,
        rng: &mut Rng,
    ) -> Vec3 {
        let mut weight = Vec3::ONE;
        let u = rng.next_f32();
        let ray = delta_bounce(delta, hit, hit.t, Arrival { wo, front, ng }, u, Transport::Radiance, &mut weight);
        weight * self.rep.incident(self.params.method.query(), ray.origin, ray.dir, 0.0).radiance
    }

    /// Eq. 5: the Lambertian albedo that explains the photographed radiance `observed` at `x`
    /// under the represented environment (cosine-sampled) and the known real lights.
    pub fn estimate_albedo(&self, x: Vec3, n: Vec3, observed: Vec3, k: u64) -> Vec3 {
        let m = self.params.settings.material_samples.max(1);
        let mut rng = Rng::for_stream(self.params.seed, 0xa1bed0, k);
        let frame = Frame::from_normal(n);
        let query = self.params.method.material_query();
        let origin = self.rep.surface_origin(query, x, n);
        let half = cone_half_angle(PI / m as f32);
        let mut sum = Vec3::ZERO;
        for _ in 0..m {
            let dir = frame.to_world(sample_cosine_hemisphere(rng.next_f32(), rng.next_f32()));
            sum += self.rep.incident(query, origin, dir, half).radiance;
        }
        // irradiance: π times the mean radiance of cosine samples, plus the real known lights
        let mut irradiance = sum * (PI / m as f32);
        for spot in self.scene.spots.iter().filter(|s| s.real) {
            if let Some((wi, dist, e)) = light_towards(spot, origin, n)
                && self.rep.transmits(query, origin, wi, dist)
            {
                irradiance += e;
            }
        }
        let rho = PI * observed / irradiance;
        Vec3::select(irradiance.cmpgt(Vec3::splat(1e-8)), rho, Vec3::ZERO)
    }

    /// The albedo error of the capture (issue 18, Deliver 1): eq. 5 estimated from up to
    /// `count` environment samples' captured colours (spread evenly over them) against the true
    /// albedo of the surface each lies on; the absolute error of the worst channel, unclamped.
    /// Samples with no real surface within 5 cm behind them are left out.
    pub fn albedo_error(&self, samples: &[EnvironmentSample], count: usize) -> crate::capture::Spread {
        let step = (samples.len() / count.max(1)).max(1);
        let errors: Vec<f64> = samples
            .par_iter()
            .enumerate()
            .filter(|(i, _)| i % step == 0)
            .filter_map(|(i, s)| {
                let n = s.normal.normalize_or_zero();
                let ray = Ray { origin: s.position + n * 0.02, dir: -n };
                let (hit, albedo) = self.real.first_hit(&ray)?;
                (hit.t < 0.07).then(|| {
                    let rho = self.estimate_albedo(s.position, n, s.colour, i as u64);
                    (rho - albedo).abs().max_element() as f64
                })
            })
            .collect();
        if errors.is_empty() { crate::capture::Spread::default() } else { crate::capture::Spread::of(errors) }
    }

    /// Eqs. 8 and 9: ΔL at the real point `x` with albedo `rho`. Of the `big_n` cosine directions,
    /// those that miss the object's box contribute nothing (set F); of those that meet it, at
    /// most `cache` (0: all) chosen at random are traced (H_a) and stand for the rest (H_b).
    /// Plus the change in the known lights' direct light (shadows of real lights, light of
    /// virtual ones).
    fn differential(&self, x: Vec3, n: Vec3, rho: Vec3, big_n: u32, cache: u32, rng: &mut Rng) -> Differential {
        let Some(bounds) = self.bounds else { return Differential::default() };
        let big_n = big_n.max(1);
        // the same directions the G-buffer's test drew
        let mut hits: Vec<Vec3> = box_directions(bounds, x, n, big_n, rng).collect();
        let traced = if cache == 0 { hits.len() } else { hits.len().min(cache as usize) };
        // a uniformly random subset of size `traced` in front (partial Fisher–Yates)
        for i in 0..traced {
            let j = i + ((rng.next_f32() * (hits.len() - i) as f32) as usize).min(hits.len() - i - 1);
            hits.swap(i, j);
        }
        let query = self.params.method.query();
        let origin = self.rep.surface_origin(query, x, n);
        let half = cone_half_angle(PI / big_n as f32);
        let mut sum = Vec3::ZERO;
        for &dir in &hits[..traced] {
            sum += self.differential_radiance(origin, dir, half, rng);
        }
        let scale = if traced > 0 { 1.0 + (hits.len() - traced) as f32 / traced as f32 } else { 0.0 };
        let mut value = rho * sum * (scale / big_n as f32);
        // known lights: a real light the object now blocks, a virtual light that now arrives
        let mut change = Vec3::ZERO;
        for spot in &self.scene.spots {
            let Some((wi, dist, e)) = light_towards(spot, origin, n) else { continue };
            let ray = Ray { origin, dir: wi };
            let blocked =
                bounds.hit(origin, wi.recip(), dist).is_some() && self.object.occluded(&ray, dist * (1.0 - 1e-4));
            if spot.real && !blocked {
                continue;
            }
            if !self.rep.transmits(query, origin, wi, dist) {
                continue;
            }
            if spot.real {
                change -= e;
            } else if !blocked {
                change += e;
            }
        }
        value += rho / PI * change;
        Differential { value, traced: traced as u64, scaled: (hits.len() - traced) as u64 }
    }

    /// ΔL along one direction from a real point (Fig. 7): zero if the object is missed or the
    /// environment is nearer (rays 1 and 3), else the object's radiance (a diffuse bounce)
    /// minus the environment's it hides (ray 2); with a cone (VCT), weighted by the share of
    /// the environment the cone still sees (eq. 6).
    fn differential_radiance(&self, origin: Vec3, dir: Vec3, half: f32, rng: &mut Rng) -> Vec3 {
        let ray = Ray { origin, dir };
        let Some((hit, mat)) = self.object.hit_with_material(&ray, f32::INFINITY) else { return Vec3::ZERO };
        let query = self.params.method.query();
        let env = self.rep.incident(query, origin, dir, half);
        if let (Query::Vct, Some(voxels)) = (query, &self.rep.voxels) {
            // eq. 6: the environment seen up to the object, 1 − α, weights the difference
            let before = voxels.cone_to(origin, dir, half, hit.t);
            return (1.0 - before.opacity) * (self.diffuse_bounce(&hit, mat, -dir, rng) - env.radiance);
        }
        if env.distance < hit.t {
            return Vec3::ZERO;
        }
        self.diffuse_bounce(&hit, mat, -dir, rng) - env.radiance
    }
}

/// One pixel's differential and the directions it traced and scaled.
#[derive(Clone, Copy, Debug, Default)]
struct Differential {
    value: Vec3,
    traced: u64,
    scaled: u64,
}
