//! The CPU reference path tracer: unidirectional, unbiased, with next-event estimation and
//! multiple importance sampling (power heuristic) for area lights (emissive triangles) and the
//! environment; spot and point lights are delta lights sampled by NEE alone. Russian roulette
//! starts after three bounces and is unbiased; there is no clamping of any kind.
//!
//! Mirrors and glass ([`crate::material::DeltaBsdf`]) are sampled, never reached by NEE. Light
//! from an area light or the environment through them (a caustic) is found by camera paths
//! that hit the emitter after a specular bounce. Light from a spot or point light through them
//! is not: a camera path can neither hit a delta light nor connect to it through glass. Those
//! paths — light, one or more mirror or glass bounces, then a diffuse or glossy surface and
//! whatever follows (L S+ D (D|S)* … with the last non-specular vertex connected to the camera)
//! — are added by **light tracing** ([`World::trace_light_path`]): paths start at the spot
//! lights and are connected to the camera at every diffuse or glossy vertex after the first
//! specular chain. The two estimators count disjoint sets of paths, so their sum is unbiased.
//! Light tracing was chosen over bidirectional path tracing because it adds exactly the missing
//! paths with one more loop over the same BVH (no MIS between strategies to keep right), and
//! over photon mapping because it is unbiased and needs no kernel radius. What neither reaches:
//! a caustic from a delta light seen only through a mirror or glass (L S+ D S+ E), which no
//! unbiased estimator with a pinhole camera and a delta light can sample (Mitsuba's `path` and
//! `ptracer` miss it too). The light-traced part runs only in scenes with a mirror or glass and
//! a spot light ([`World::needs_light_tracing`]).
//!
//! Determinism: sample `s` of pixel `p` draws from its own stream `(seed, p, s)`, and every
//! bounce consumes exactly eight numbers whatever happens, so results do not depend on thread
//! scheduling, and two worlds that differ only where a path never goes (the real-only and the
//! full scene) produce identical samples there — the photograph and the ground truth share
//! their noise realisation.
//!
//! That also lets the reference trace both images at once ([`World::radiance_pair`]): while a
//! path of the full world meets only real objects it is, number for number, the path of the
//! real-only world, so it is traced once and its light counted for both; a shadow ray blocked
//! in the full world is retraced in the real-only one (a virtual object may be what blocks it),
//! and at the first virtual hit the real-only path goes on alone from the same state and the
//! same numbers. Both images are bit for bit those of two passes. It needs the two worlds to
//! sample the same lights ([`World::shares_lights_with`]): with a virtual light the light
//! choice differs from the first bounce, and the reference renders two passes.

mod accumulator;

use crate::bvh::{Bvh, BvhHit};
use crate::camera::Camera;
use crate::geometry::{Primitive, Ray, SurfaceHit, Triangle};
use crate::image::Image;
use crate::light::{Environment, SpotLight};
use crate::material::{Bsdf, DeltaBsdf, Material, Transport};
use crate::math::{Distribution1D, Rng, luminance, power_heuristic, sample_triangle};
use crate::scene::{Role, Scene};
pub use accumulator::{Accumulator, render};
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::sync::Arc;

const RAY_EPSILON: f32 = 1e-4;

/// The random stream of light paths (camera samples use the pixel index as their stream).
const LIGHT_STREAM: u64 = u64::MAX;

/// A ray origin just off the surface point `point`, on the side of `normal`.
fn offset(point: Vec3, normal: Vec3) -> Vec3 {
    point + normal * RAY_EPSILON * (1.0 + point.abs().max_element())
}

/// The surface's outward normal (its shading normal turned to the geometric normal's side).
fn outward_normal(s: &SurfaceHit) -> Vec3 {
    if s.shading_normal.dot(s.geometric_normal) < 0.0 { -s.shading_normal } else { s.shading_normal }
}

/// A diffuse or glossy point a path shades: position `p`, shading normal `ns`, geometric normal
/// `ng`.
#[derive(Clone, Copy, Debug)]
struct ShadingPoint {
    p: Vec3,
    ns: Vec3,
    ng: Vec3,
}

/// How a path arrives at a surface: `wo` the direction back along it, `front` whether it came
/// from outside, `ng` the geometric normal on its side.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Arrival {
    pub wo: Vec3,
    pub front: bool,
    pub ng: Vec3,
}

/// A path's bounce off a mirror or glass hit at distance `t`, arriving as `arrival` says: the
/// Beer–Lambert loss of a segment that ran inside, the sampled direction's weight, and the next
/// ray, started on the side the path leaves to.
pub(crate) fn delta_bounce(
    delta: &DeltaBsdf,
    s: &SurfaceHit,
    t: f32,
    arrival: Arrival,
    u: f32,
    transport: Transport,
    beta: &mut Vec3,
) -> Ray {
    let Arrival { wo, front, ng } = arrival;
    if !front {
        *beta *= delta.inside_transmittance(t);
    }
    let sample = delta.sample(wo, outward_normal(s), front, u, transport);
    *beta *= sample.weight;
    Ray { origin: offset(s.point, if sample.transmitted { -ng } else { ng }), dir: sample.wi }
}

/// The diffuse and Blinn–Phong BSDF of `material` at a hit (`ng`: the geometric normal on the
/// side the path came from), with its shading normal turned to that side and the point to
/// continue from; `None` when the surface reflects nothing.
#[inline(always)]
pub(crate) fn shade(material: &Material, s: &SurfaceHit, ng: Vec3) -> Option<(Vec3, Bsdf, Vec3)> {
    let mut ns = s.shading_normal;
    if ns.dot(ng) < 0.0 {
        ns = -ns;
    }
    let kd = material.albedo_at(s.uv);
    if kd.max_element() <= 0.0 && material.specular.max_element() <= 0.0 {
        return None;
    }
    Some((ns, Bsdf::new(ns, kd, material.specular, material.exponent), offset(s.point, ng)))
}

/// A bounce's eight numbers, two from each of four draws.
#[inline(always)]
fn draw_bounce(rng: &mut Rng) -> [f32; 8] {
    let mut u = [0.0; 8];
    for pair in u.chunks_exact_mut(2) {
        (pair[0], pair[1]) = rng.next_f32_pair();
    }
    u
}

/// Russian roulette from the fourth bounce on (unbiased: a survivor's weight grows by 1/q);
/// false ends the path.
fn survives_roulette(depth: u32, beta: &mut Vec3, u: f32) -> bool {
    if depth >= 3 {
        let q = beta.max_element().min(0.99);
        if q <= 0.0 || u >= q {
            return false;
        }
        *beta /= q;
    }
    true
}

/// Which part of a scene a world holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Subset {
    /// Real objects and real lights only: the photograph.
    RealOnly,
    /// Everything: the ground-truth composite.
    All,
    /// Virtual objects and virtual lights only: what the coherent renderer
    /// ([`crate::coherent`]) traces for the virtual object's self-shadowing and its influence.
    VirtualOnly,
}

#[derive(Clone, Copy, Debug)]
struct PrimInfo {
    object: u32,
    material: u32,
    /// Index into `emitters`, or −1.
    emitter: i32,
}

/// An emitting triangle, or two that make a parallelogram (an area light's quad), sampled
/// uniformly by area: the points `corner + b1 e1 + b2 e2` with b1, b2 ≥ 0 and b1 + b2 ≤ 1 (a
/// triangle) or b1, b2 ≤ 1 (a parallelogram).
#[derive(Clone, Debug)]
struct Emitter {
    corner: Vec3,
    e1: Vec3,
    e2: Vec3,
    parallelogram: bool,
    normal: Vec3,
    area: f32,
    radiance: Vec3,
}

impl Emitter {
    fn triangle(t: &Triangle, radiance: Vec3) -> Emitter {
        Emitter {
            corner: t.p[0],
            e1: t.p[1] - t.p[0],
            e2: t.p[2] - t.p[0],
            parallelogram: false,
            normal: t.geometric_normal(),
            area: t.area(),
            radiance,
        }
    }

    /// This triangle and `t` as one parallelogram, where they share an edge, face the same way
    /// and their other corners lie opposite each other across it.
    fn joined(&self, t: &Triangle) -> Option<Emitter> {
        if self.parallelogram || t.geometric_normal().dot(self.normal) < 1.0 - 1e-5 {
            return None;
        }
        let mine = [self.corner, self.corner + self.e1, self.corner + self.e2];
        // the shared edge's two corners, and each triangle's corner off it
        let shared: Vec<Vec3> = mine.into_iter().filter(|v| t.p.contains(v)).collect();
        let (Some(&p), Some(&q), &[_, _]) =
            (mine.iter().find(|v| !t.p.contains(v)), t.p.iter().find(|v| !mine.contains(v)), &shared[..])
        else {
            return None;
        };
        let scale = mine.iter().chain(&t.p).fold(1.0f32, |m, v| m.max(v.abs().max_element()));
        if (p + q - shared[0] - shared[1]).abs().max_element() > 1e-5 * scale {
            return None;
        }
        Some(Emitter {
            corner: p,
            e1: shared[0] - p,
            e2: shared[1] - p,
            parallelogram: true,
            normal: self.normal,
            area: self.area + t.area(),
            radiance: self.radiance,
        })
    }
}

#[derive(Clone, Copy, Debug)]
enum LightGroup {
    Spot(usize),
    Emitters,
    Environment,
}

/// A scene prepared for tracing: BVH, materials and light-sampling tables.
pub struct World {
    bvh: Bvh<PrimInfo>,
    /// Each BVH primitive's geometric normal (a triangle's, computed once; zero for a sphere).
    normals: Vec<Vec3>,
    materials: Vec<Material>,
    /// Role of each object (indexed by `PrimInfo::object`).
    pub object_roles: Vec<Role>,
    emitters: Vec<Emitter>,
    emitter_dist: Distribution1D,
    spots: Vec<SpotLight>,
    env: Option<Arc<Environment>>,
    groups: Vec<LightGroup>,
    /// Whether an object of this world is a mirror or glass.
    has_delta: bool,
}

/// Tracing parameters.
#[derive(Clone, Copy, Debug)]
pub struct TraceParams {
    pub seed: u64,
    /// A safety bound on path length; with Russian roulette it is practically never reached.
    pub max_depth: u32,
    /// Light tracing for caustics from spot and point lights (in scenes that need it); off
    /// leaves those paths out, as a camera-only path tracer would (for comparisons).
    pub light_tracing: bool,
}

impl Default for TraceParams {
    fn default() -> Self {
        TraceParams { seed: 1, max_depth: 64, light_tracing: true }
    }
}

impl World {
    pub fn new(scene: &Scene, subset: Subset) -> World {
        let include = |role: Role| match subset {
            Subset::All => true,
            Subset::RealOnly => role == Role::Real,
            Subset::VirtualOnly => role == Role::Virtual,
        };
        let mut prims = Vec::new();
        let mut payload = Vec::new();
        let mut emitters: Vec<Emitter> = Vec::new();
        let mut has_delta = false;
        for (oi, o) in scene.objects.iter().enumerate() {
            if !include(o.role) {
                continue;
            }
            let mat = &scene.materials[o.material];
            has_delta |= mat.delta.is_some();
            for p in &o.prims {
                let mut emitter = -1;
                if mat.is_emissive()
                    && let Primitive::Triangle(t) = p
                    && t.area() > 0.0
                {
                    // an object's two triangles of one quad are one emitter
                    let last = payload.last().filter(|l: &&PrimInfo| l.object == oi as u32 && l.emitter >= 0);
                    match last.and_then(|l| emitters[l.emitter as usize].joined(t).map(|j| (l.emitter, j))) {
                        Some((index, joined)) => {
                            emitters[index as usize] = joined;
                            emitter = index;
                        }
                        None => {
                            emitter = emitters.len() as i32;
                            emitters.push(Emitter::triangle(t, mat.emission));
                        }
                    }
                }
                prims.push(p.clone());
                payload.push(PrimInfo { object: oi as u32, material: o.material as u32, emitter });
            }
        }
        let weights: Vec<f32> = emitters.iter().map(|e| luminance(e.radiance) * e.area).collect();
        let emitter_dist = Distribution1D::new(&weights);
        let spots: Vec<SpotLight> =
            scene.spots.iter().filter(|s| include(if s.real { Role::Real } else { Role::Virtual })).cloned().collect();
        let mut groups: Vec<LightGroup> = (0..spots.len()).map(LightGroup::Spot).collect();
        if !emitters.is_empty() {
            groups.push(LightGroup::Emitters);
        }
        if scene.environment.is_some() {
            groups.push(LightGroup::Environment);
        }
        let bvh = Bvh::build(prims, payload);
        let normals = bvh.prims.iter().map(Primitive::flat_normal).collect();
        World {
            bvh,
            normals,
            materials: scene.materials.clone(),
            object_roles: scene.objects.iter().map(|o| o.role).collect(),
            emitters,
            emitter_dist,
            spots,
            env: scene.environment.clone(),
            groups,
            has_delta,
        }
    }

    /// The material of a hit and the surface there (texture coordinates only where the
    /// material is textured).
    #[inline(always)]
    fn surface_at(&self, ray: &Ray, hit: &BvhHit) -> (&Material, SurfaceHit) {
        let mat = &self.materials[self.bvh.payload[hit.prim].material as usize];
        let prim = &self.bvh.prims[hit.prim];
        (mat, prim.surface_with_normal(ray, hit.t, hit.u, hit.v, mat.texture.is_some(), self.normals[hit.prim]))
    }

    /// The nearest surface along `ray` (beyond the tracer's epsilon): the hit with its shading
    /// normal turned towards the ray's origin, and the surface's diffuse albedo there. Used by
    /// the simulated depth sensor ([`crate::capture`]) for the true geometry.
    pub fn first_hit(&self, ray: &Ray) -> Option<(SurfaceHit, Vec3)> {
        let hit = self.bvh.intersect(ray, RAY_EPSILON, f32::INFINITY)?;
        let (mat, mut s) = self.surface_at(ray, &hit);
        if s.shading_normal.dot(ray.dir) > 0.0 {
            s.shading_normal = -s.shading_normal;
        }
        Some((s, mat.albedo_at(s.uv)))
    }

    /// The nearest surface along `ray` closer than `t_max`, with its material; the shading
    /// normal is left as the primitive gives it.
    pub fn hit_with_material(&self, ray: &Ray, t_max: f32) -> Option<(SurfaceHit, &Material)> {
        let hit = self.bvh.intersect(ray, RAY_EPSILON, t_max)?;
        let (mat, s) = self.surface_at(ray, &hit);
        Some((s, mat))
    }

    /// Whether anything lies along `ray` closer than `t_max`.
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        self.bvh.occluded(ray, RAY_EPSILON, t_max)
    }

    /// Whether light tracing is needed: a mirror or glass object and a spot or point light.
    pub fn needs_light_tracing(&self) -> bool {
        self.has_delta && !self.spots.is_empty()
    }

    /// Traces one light path from a spot light (chosen uniformly; its direction uniformly in
    /// its cone) and hands every camera connection to `splat` as (pixel index, value): the
    /// value's mean over all light paths, divided by their number, is the pixel's mean
    /// radiance from the paths the camera tracer cannot sample (see the module doc). Uses the
    /// same eight numbers per bounce as camera paths.
    pub fn trace_light_path(
        &self,
        camera: &Camera,
        rng: &mut Rng,
        params: &TraceParams,
        splat: &mut dyn FnMut(usize, Vec3),
    ) {
        if self.spots.is_empty() {
            return;
        }
        let u: [f32; 3] = std::array::from_fn(|_| rng.next_f32());
        let spot = &self.spots[((u[0] * self.spots.len() as f32) as usize).min(self.spots.len() - 1)];
        // uniform in the cone cos θ ≥ cos_outer (the whole sphere for a point light)
        let cos_max = spot.cos_outer.max(-1.0);
        let cos_theta = 1.0 - u[1] * (1.0 - cos_max);
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let phi = 2.0 * std::f32::consts::PI * u[2];
        let frame = crate::math::Frame::from_normal(spot.direction);
        let dir = frame.to_world(Vec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta));
        // intensity / (pdf of the direction × probability of the light)
        let solid_angle = 2.0 * std::f32::consts::PI * (1.0 - cos_max);
        let mut beta = spot.intensity_towards(dir) * solid_angle * self.spots.len() as f32;
        if beta.max_element() <= 0.0 {
            return;
        }
        let mut ray = Ray { origin: spot.position, dir };
        let mut through_specular = false;
        let forward = -camera.rotation.col(2);
        for depth in 0..params.max_depth {
            let u = draw_bounce(rng);
            let Some(hit) = self.bvh.intersect(&ray, RAY_EPSILON, f32::INFINITY) else { break };
            let (mat, s) = self.surface_at(&ray, &hit);
            let wo = -ray.dir;
            let front = s.geometric_normal.dot(wo) > 0.0;
            let ng = if front { s.geometric_normal } else { -s.geometric_normal };
            if let Some(delta) = &mat.delta {
                ray = delta_bounce(delta, &s, hit.t, Arrival { wo, front, ng }, u[4], Transport::Importance, &mut beta);
                through_specular = true;
            } else {
                // the camera tracer's next-event estimation has every path whose first
                // bounce from the light is diffuse or glossy
                if !through_specular {
                    break;
                }
                let Some((ns, bsdf, p)) = shade(mat, &s, ng) else { break };
                // the connection to the pinhole: W = fx fy / cos³θ per solid angle at the camera
                let to_camera = camera.position - p;
                let dist2 = to_camera.length_squared();
                let dist = dist2.sqrt();
                let wc = to_camera / dist;
                let cos_camera = forward.dot(-wc);
                let cos_surface = ns.dot(wc);
                if cos_camera > 0.0
                    && cos_surface > 0.0
                    && ng.dot(wc) > 0.0
                    && let Some((px, py)) = camera.project(s.point)
                    && px >= 0.0
                    && py >= 0.0
                    && px < camera.width as f32
                    && py < camera.height as f32
                {
                    let f = bsdf.eval(wc, wo);
                    if f.max_element() > 0.0
                        && !self.bvh.occluded(&Ray { origin: p, dir: wc }, RAY_EPSILON, dist * (1.0 - 1e-4))
                    {
                        let importance = camera.fx * camera.fy / (dist2 * cos_camera * cos_camera * cos_camera);
                        let pixel = py as usize * camera.width as usize + px as usize;
                        splat(pixel, beta * f * (cos_surface * importance));
                    }
                }
                let Some(bs) = bsdf.sample(wo, u[4], u[5], u[6]) else { break };
                if bs.wi.dot(ng) <= 0.0 {
                    break;
                }
                beta *= bs.weight;
                ray = Ray { origin: p, dir: bs.wi };
            }
            if !survives_roulette(depth, &mut beta, u[7]) {
                break;
            }
        }
    }

    fn group_prob(&self) -> f32 {
        if self.groups.is_empty() { 0.0 } else { 1.0 / self.groups.len() as f32 }
    }

    /// Solid-angle pdf with which NEE would have chosen the point hit on emitter `e`.
    fn emitter_pdf(&self, e: usize, dir: Vec3, t: f32) -> f32 {
        let em = &self.emitters[e];
        let cos_l = em.normal.dot(-dir);
        if cos_l <= 0.0 {
            return 0.0;
        }
        self.group_prob() * self.emitter_dist.prob(e) / em.area * t * t / cos_l
    }

    fn env_pdf(&self, dir: Vec3) -> f32 {
        match &self.env {
            Some(env) => self.group_prob() * env.pdf(dir),
            None => 0.0,
        }
    }

    /// Radiance along `ray`, and the object the primary ray hit first.
    pub fn radiance(&self, ray: Ray, rng: &mut Rng, params: &TraceParams) -> (Vec3, Option<u32>) {
        let (l, _, first) = self.trace::<false>(self, PathState::start(ray), None, rng, params);
        (l, first)
    }

    /// Whether `real`, the real-only world of the same scene, has this world's lights: then a
    /// path of both worlds is one path until it first meets a virtual object
    /// ([`World::radiance_pair`]). No virtual light and no virtual emitter.
    pub fn shares_lights_with(&self, real: &World) -> bool {
        self.spots.len() == real.spots.len()
            && self.emitters.len() == real.emitters.len()
            && self.groups.len() == real.groups.len()
            && self.env.is_some() == real.env.is_some()
    }

    /// The radiance along `ray` in this world (the full scene) and in `real` (its real-only
    /// world, which must share its lights: [`World::shares_lights_with`]), each bit for bit what
    /// [`World::radiance`] gives from the same stream, and the object hit first in this world.
    /// The two paths are traced once while they are the same path — every hit real, the same
    /// random numbers, the same light sample — and a shadow ray blocked here is retraced in the
    /// real world alone; at the first virtual hit the real path goes on by itself.
    pub fn radiance_pair(
        &self,
        real: &World,
        ray: Ray,
        rng: &mut Rng,
        params: &TraceParams,
    ) -> (Vec3, Vec3, Option<u32>) {
        self.trace::<true>(real, PathState::start(ray), None, rng, params)
    }

    /// The path tracer's loop, from `path` on (`pending`: this bounce's numbers, already drawn).
    /// With `JOINT`, `twin` is the real-only world and the path is traced for both worlds while
    /// it stays real ([`World::radiance_pair`]); returns this world's radiance, the twin's, and
    /// the object hit first.
    #[inline(always)]
    fn trace<const JOINT: bool>(
        &self,
        twin: &World,
        path: PathState,
        pending: Option<[f32; 8]>,
        rng: &mut Rng,
        params: &TraceParams,
    ) -> (Vec3, Vec3, Option<u32>) {
        let PathState { mut ray, mut l, mut beta, mut prev_pdf, mut prev_delta, depth: first_depth } = path;
        let mut l_twin = l;
        let mut shared = JOINT;
        let mut first = None;
        let draw = draw_bounce;
        let mut next = pending.unwrap_or_else(|| draw(rng));
        for depth in first_depth..params.max_depth {
            // this bounce's numbers; the next bounce's are drawn when this one goes on (no
            // other draw comes between, so the stream is used in the same order)
            let u = next;
            let Some(hit) = self.bvh.intersect(&ray, RAY_EPSILON, f32::INFINITY) else {
                if let Some(env) = &self.env {
                    let le = env.eval(ray.dir);
                    let w = if prev_delta { 1.0 } else { power_heuristic(prev_pdf, self.env_pdf(ray.dir)) };
                    let term = beta * le * w;
                    l += term;
                    if shared {
                        l_twin += term;
                    }
                }
                break;
            };
            let info = self.bvh.payload[hit.prim];
            if depth == 0 {
                first = Some(info.object);
            }
            if shared && self.object_roles[info.object as usize] == Role::Virtual {
                // the real path misses this object: it goes on alone, from this bounce's numbers
                let here = PathState { ray, l: l_twin, beta, prev_pdf, prev_delta, depth };
                l_twin = twin.trace::<false>(twin, here, Some(u), &mut rng.clone(), params).0;
                shared = false;
            }
            let (mat, s) = self.surface_at(&ray, &hit);
            let wo = -ray.dir;
            let front = s.geometric_normal.dot(wo) > 0.0;
            if front && mat.is_emissive() {
                let w = if prev_delta || info.emitter < 0 {
                    1.0
                } else {
                    power_heuristic(prev_pdf, self.emitter_pdf(info.emitter as usize, ray.dir, hit.t))
                };
                let term = beta * mat.emission * w;
                l += term;
                if shared {
                    l_twin += term;
                }
            }
            let ng = if front { s.geometric_normal } else { -s.geometric_normal };
            if let Some(delta) = &mat.delta {
                // a mirror or glass: no light reaches it by NEE; the path goes on sampled
                ray = delta_bounce(delta, &s, hit.t, Arrival { wo, front, ng }, u[4], Transport::Radiance, &mut beta);
                prev_delta = true;
                if !survives_roulette(depth, &mut beta, u[7]) {
                    break;
                }
                next = draw(rng);
                continue;
            }
            let Some((ns, bsdf, p)) = shade(mat, &s, ng) else { break };

            // next-event estimation
            if let Some((term, shadow, t_max)) = self.next_event(&bsdf, ShadingPoint { p, ns, ng }, wo, beta, &u) {
                if !self.bvh.occluded(&shadow, RAY_EPSILON, t_max) {
                    l += term;
                    if shared {
                        l_twin += term;
                    }
                } else if shared && !twin.bvh.occluded(&shadow, RAY_EPSILON, t_max) {
                    // blocked by a virtual object only
                    l_twin += term;
                }
            }

            // continue the path by sampling the BRDF
            let Some(bs) = bsdf.sample(wo, u[4], u[5], u[6]) else { break };
            if bs.wi.dot(ng) <= 0.0 {
                break;
            }
            beta *= bs.weight;
            prev_pdf = bs.pdf;
            prev_delta = false;
            ray = Ray { origin: p, dir: bs.wi };
            if !survives_roulette(depth, &mut beta, u[7]) {
                break;
            }
            next = draw(rng);
        }
        (l, l_twin, first)
    }

    /// Next-event estimation at a diffuse or glossy point `at`, its normals on the side of `wo`:
    /// the contribution of one light sample if nothing blocks it, the shadow ray and its length;
    /// `None` when the sample cannot contribute.
    #[inline(always)]
    fn next_event(
        &self,
        bsdf: &Bsdf,
        ShadingPoint { p, ns, ng }: ShadingPoint,
        wo: Vec3,
        beta: Vec3,
        u: &[f32; 8],
    ) -> Option<(Vec3, Ray, f32)> {
        if self.groups.is_empty() {
            return None;
        }
        let gi = ((u[0] * self.groups.len() as f32) as usize).min(self.groups.len() - 1);
        let p_group = self.group_prob();
        match self.groups[gi] {
            LightGroup::Spot(i) => {
                let spot = &self.spots[i];
                let d = spot.position - p;
                let dist2 = d.length_squared();
                let dist = dist2.sqrt();
                let wi = d * (1.0 / dist);
                let intensity = spot.intensity_towards(-wi);
                let cos = ns.dot(wi);
                if intensity.max_element() > 0.0 && cos > 0.0 && ng.dot(wi) > 0.0 {
                    let f = bsdf.eval(wo, wi);
                    if f.max_element() > 0.0 {
                        let term = beta * f * intensity * (cos / (dist2 * p_group));
                        return Some((term, Ray { origin: p, dir: wi }, dist * (1.0 - 1e-4)));
                    }
                }
                None
            }
            LightGroup::Emitters => {
                let (e, pe, _) = self.emitter_dist.sample(u[1]);
                let em = &self.emitters[e];
                let (b1, b2) = if em.parallelogram { (u[2], u[3]) } else { sample_triangle(u[2], u[3]) };
                let q = em.corner + em.e1 * b1 + em.e2 * b2;
                let d = q - p;
                let dist2 = d.length_squared();
                let dist = dist2.sqrt();
                let wi = d * (1.0 / dist);
                let cos_l = em.normal.dot(-wi);
                let cos = ns.dot(wi);
                if cos_l > 0.0 && cos > 0.0 && ng.dot(wi) > 0.0 {
                    let pdf = p_group * pe / em.area * dist2 / cos_l;
                    let (f, bsdf_pdf) = bsdf.eval_pdf(wo, wi);
                    if f.max_element() > 0.0 {
                        let w = power_heuristic(pdf, bsdf_pdf);
                        let term = beta * f * em.radiance * (cos * w / pdf);
                        return Some((term, Ray { origin: p, dir: wi }, dist * (1.0 - 1e-4)));
                    }
                }
                None
            }
            LightGroup::Environment => {
                let (wi, le, pdf_env) = self.env.as_ref().and_then(|env| env.sample(u[1], u[2]))?;
                let cos = ns.dot(wi);
                if cos > 0.0 && ng.dot(wi) > 0.0 && le.max_element() > 0.0 {
                    let pdf = p_group * pdf_env;
                    let (f, bsdf_pdf) = bsdf.eval_pdf(wo, wi);
                    if f.max_element() > 0.0 {
                        let w = power_heuristic(pdf, bsdf_pdf);
                        let term = beta * f * le * (cos * w / pdf);
                        return Some((term, Ray { origin: p, dir: wi }, f32::INFINITY));
                    }
                }
                None
            }
        }
    }
}

/// Where a camera path stands before a bounce: the ray to follow, the radiance gathered so far,
/// the throughput, the last bounce's pdf (and whether it was a mirror or glass), and the depth.
#[derive(Clone, Copy, Debug)]
struct PathState {
    ray: Ray,
    l: Vec3,
    beta: Vec3,
    prev_pdf: f32,
    prev_delta: bool,
    depth: u32,
}

impl PathState {
    fn start(ray: Ray) -> PathState {
        PathState { ray, l: Vec3::ZERO, beta: Vec3::ONE, prev_pdf: 0.0, prev_delta: true, depth: 0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    fn tri(p: [Vec3; 3]) -> Triangle {
        Triangle { p, n: None, uv: [Vec2::ZERO; 3] }
    }

    #[test]
    fn a_quads_two_triangles_are_one_parallelogram_emitter_and_other_pairs_are_not() {
        // a 2 × 1 rectangle at height 1, corners in order
        let [a, b, c, d] = [[0.0, 1.0, 0.0], [2.0, 1.0, 0.0], [2.0, 1.0, 1.0], [0.0, 1.0, 1.0]].map(Vec3::from_array);
        let first = Emitter::triangle(&tri([a, b, c]), Vec3::ONE);
        let quad = first.joined(&tri([a, c, d])).expect("a quad's triangles join");
        assert!(quad.parallelogram);
        assert!((quad.area - 2.0).abs() < 1e-6, "{}", quad.area);
        // its four corners are the quad's
        let corners = [quad.corner, quad.corner + quad.e1, quad.corner + quad.e2, quad.corner + quad.e1 + quad.e2];
        for p in [a, b, c, d] {
            assert!(corners.iter().any(|q| (*q - p).length() < 1e-6), "{p} not a corner of {corners:?}");
        }
        // a kite (the fourth corner off the parallelogram), a triangle facing the other way, one
        // sharing a single corner, and a third triangle on a parallelogram are refused
        assert!(first.joined(&tri([a, c, d + Vec3::X * 0.3])).is_none());
        assert!(first.joined(&tri([a, d, c])).is_none());
        assert!(first.joined(&tri([a, d, d + Vec3::X * 0.5])).is_none());
        assert!(quad.joined(&tri([a, c, d])).is_none());
    }
}
