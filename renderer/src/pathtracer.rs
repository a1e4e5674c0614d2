//! The CPU reference path tracer: unidirectional, unbiased, with next-event estimation and
//! multiple importance sampling (power heuristic) for area lights (emissive triangles) and the
//! environment; spot and point lights are delta lights sampled by NEE alone. Russian roulette
//! starts after three bounces and is unbiased; there is no clamping of any kind.
//!
//! Determinism: sample `s` of pixel `p` draws from its own stream `(seed, p, s)`, and every
//! bounce consumes exactly eight numbers whatever happens, so results do not depend on thread
//! scheduling, and two worlds that differ only where a path never goes (the real-only and the
//! full scene) produce identical samples there — the photograph and the ground truth share
//! their noise realisation.

use crate::bvh::Bvh;
use crate::camera::Camera;
use crate::geometry::{Primitive, Ray, Triangle};
use crate::image::Image;
use crate::light::{Environment, SpotLight};
use crate::material::{Bsdf, Material};
use crate::math::{Distribution1D, Rng, luminance, power_heuristic, sample_triangle};
use crate::scene::{Role, Scene};
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::sync::Arc;

const RAY_EPSILON: f32 = 1e-4;

/// Which part of a scene a world holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Subset {
    /// Real objects and real lights only: the photograph.
    RealOnly,
    /// Everything: the ground-truth composite.
    All,
}

#[derive(Clone, Copy, Debug)]
struct PrimInfo {
    object: u32,
    material: u32,
    /// Index into `emitters`, or −1.
    emitter: i32,
}

#[derive(Clone, Debug)]
struct Emitter {
    tri: Triangle,
    normal: Vec3,
    area: f32,
    radiance: Vec3,
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
    materials: Vec<Material>,
    /// Role of each object (indexed by `PrimInfo::object`).
    pub object_roles: Vec<Role>,
    emitters: Vec<Emitter>,
    emitter_dist: Distribution1D,
    spots: Vec<SpotLight>,
    env: Option<Arc<Environment>>,
    groups: Vec<LightGroup>,
}

/// Tracing parameters.
#[derive(Clone, Copy, Debug)]
pub struct TraceParams {
    pub seed: u64,
    /// A safety bound on path length; with Russian roulette it is practically never reached.
    pub max_depth: u32,
}

impl Default for TraceParams {
    fn default() -> Self {
        TraceParams { seed: 1, max_depth: 64 }
    }
}

impl World {
    pub fn new(scene: &Scene, subset: Subset) -> World {
        let include = |role: Role| subset == Subset::All || role == Role::Real;
        let mut prims = Vec::new();
        let mut payload = Vec::new();
        let mut emitters = Vec::new();
        for (oi, o) in scene.objects.iter().enumerate() {
            if !include(o.role) {
                continue;
            }
            let mat = &scene.materials[o.material];
            for p in &o.prims {
                let mut emitter = -1;
                if mat.is_emissive()
                    && let Primitive::Triangle(t) = p
                {
                    let area = t.area();
                    if area > 0.0 {
                        emitter = emitters.len() as i32;
                        emitters.push(Emitter {
                            tri: t.clone(),
                            normal: t.geometric_normal(),
                            area,
                            radiance: mat.emission,
                        });
                    }
                }
                prims.push(p.clone());
                payload.push(PrimInfo { object: oi as u32, material: o.material as u32, emitter });
            }
        }
        let weights: Vec<f32> = emitters.iter().map(|e| luminance(e.radiance) * e.area).collect();
        let emitter_dist = Distribution1D::new(&weights);
        let spots: Vec<SpotLight> = scene.spots.iter().filter(|s| subset == Subset::All || s.real).cloned().collect();
        let mut groups: Vec<LightGroup> = (0..spots.len()).map(LightGroup::Spot).collect();
        if !emitters.is_empty() {
            groups.push(LightGroup::Emitters);
        }
        if scene.environment.is_some() {
            groups.push(LightGroup::Environment);
        }
        World {
            bvh: Bvh::build(prims, payload),
            materials: scene.materials.clone(),
            object_roles: scene.objects.iter().map(|o| o.role).collect(),
            emitters,
            emitter_dist,
            spots,
            env: scene.environment.clone(),
            groups,
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
    pub fn radiance(&self, mut ray: Ray, rng: &mut Rng, params: &TraceParams) -> (Vec3, Option<u32>) {
        let mut l = Vec3::ZERO;
        let mut beta = Vec3::ONE;
        let mut prev_pdf = 0.0f32;
        let mut prev_delta = true;
        let mut first = None;
        for depth in 0..params.max_depth {
            let u: [f32; 8] = std::array::from_fn(|_| rng.next_f32());
            let Some(hit) = self.bvh.intersect(&ray, RAY_EPSILON, f32::INFINITY) else {
                if let Some(env) = &self.env {
                    let le = env.eval(ray.dir);
                    let w = if prev_delta { 1.0 } else { power_heuristic(prev_pdf, self.env_pdf(ray.dir)) };
                    l += beta * le * w;
                }
                break;
            };
            let info = self.bvh.payload[hit.prim];
            if depth == 0 {
                first = Some(info.object);
            }
            let s = self.bvh.prims[hit.prim].surface(&ray, hit.t, hit.u, hit.v);
            let mat = &self.materials[info.material as usize];
            let wo = -ray.dir;
            let front = s.geometric_normal.dot(wo) > 0.0;
            if front && mat.is_emissive() {
                let w = if prev_delta || info.emitter < 0 {
                    1.0
                } else {
                    power_heuristic(prev_pdf, self.emitter_pdf(info.emitter as usize, ray.dir, hit.t))
                };
                l += beta * mat.emission * w;
            }
            let ng = if front { s.geometric_normal } else { -s.geometric_normal };
            let mut ns = s.shading_normal;
            if ns.dot(ng) < 0.0 {
                ns = -ns;
            }
            let kd = mat.albedo_at(s.uv);
            if kd.max_element() <= 0.0 && mat.specular.max_element() <= 0.0 {
                break;
            }
            let bsdf = Bsdf::new(ns, kd, mat.specular, mat.exponent);
            let p = s.point + ng * RAY_EPSILON * (1.0 + s.point.abs().max_element());

            // next-event estimation
            if !self.groups.is_empty() {
                let gi = ((u[0] * self.groups.len() as f32) as usize).min(self.groups.len() - 1);
                let p_group = self.group_prob();
                match self.groups[gi] {
                    LightGroup::Spot(i) => {
                        let spot = &self.spots[i];
                        let d = spot.position - p;
                        let dist2 = d.length_squared();
                        let dist = dist2.sqrt();
                        let wi = d / dist;
                        let intensity = spot.intensity_towards(-wi);
                        let cos = ns.dot(wi);
                        if intensity.max_element() > 0.0 && cos > 0.0 && ng.dot(wi) > 0.0 {
                            let f = bsdf.eval(wo, wi);
                            if f.max_element() > 0.0
                                && !self.bvh.occluded(&Ray { origin: p, dir: wi }, RAY_EPSILON, dist * (1.0 - 1e-4))
                            {
                                l += beta * f * intensity * (cos / (dist2 * p_group));
                            }
                        }
                    }
                    LightGroup::Emitters => {
                        let (e, pe, _) = self.emitter_dist.sample(u[1]);
                        let em = &self.emitters[e];
                        let (b1, b2) = sample_triangle(u[2], u[3]);
                        let q = em.tri.p[0] * (1.0 - b1 - b2) + em.tri.p[1] * b1 + em.tri.p[2] * b2;
                        let d = q - p;
                        let dist2 = d.length_squared();
                        let dist = dist2.sqrt();
                        let wi = d / dist;
                        let cos_l = em.normal.dot(-wi);
                        let cos = ns.dot(wi);
                        if cos_l > 0.0 && cos > 0.0 && ng.dot(wi) > 0.0 {
                            let pdf = p_group * pe / em.area * dist2 / cos_l;
                            let f = bsdf.eval(wo, wi);
                            if f.max_element() > 0.0
                                && !self.bvh.occluded(&Ray { origin: p, dir: wi }, RAY_EPSILON, dist * (1.0 - 1e-4))
                            {
                                let w = power_heuristic(pdf, bsdf.pdf(wo, wi));
                                l += beta * f * em.radiance * (cos * w / pdf);
                            }
                        }
                    }
                    LightGroup::Environment => {
                        if let Some((wi, le, pdf_env)) = self.env.as_ref().and_then(|env| env.sample(u[1], u[2])) {
                            let cos = ns.dot(wi);
                            if cos > 0.0 && ng.dot(wi) > 0.0 && le.max_element() > 0.0 {
                                let pdf = p_group * pdf_env;
                                let f = bsdf.eval(wo, wi);
                                if f.max_element() > 0.0
                                    && !self.bvh.occluded(&Ray { origin: p, dir: wi }, RAY_EPSILON, f32::INFINITY)
                                {
                                    let w = power_heuristic(pdf, bsdf.pdf(wo, wi));
                                    l += beta * f * le * (cos * w / pdf);
                                }
                            }
                        }
                    }
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
            if depth >= 3 {
                let q = beta.max_element().min(0.99);
                if q <= 0.0 || u[7] >= q {
                    break;
                }
                beta /= q;
            }
        }
        (l, first)
    }
}

/// Per-pixel sums of a progressive render.
#[derive(Clone, Debug)]
pub struct Accumulator {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    sum: Vec<DVec3>,
    /// Samples whose primary ray hit a virtual object first.
    virtual_hits: Vec<u32>,
    /// The brightest single sample (luminance) per pixel, for firefly statistics.
    pub max_sample: Vec<f32>,
    /// Sum of squared sample luminances, for the per-pixel standard error.
    sum_lum2: Vec<f64>,
    /// Samples that were NaN or infinite (dropped and counted; an unbiased tracer should have none).
    pub invalid_samples: u64,
}

impl Accumulator {
    pub fn new(width: u32, height: u32) -> Self {
        let n = (width * height) as usize;
        Accumulator {
            width,
            height,
            spp: 0,
            sum: vec![DVec3::ZERO; n],
            virtual_hits: vec![0; n],
            max_sample: vec![0.0; n],
            sum_lum2: vec![0.0; n],
            invalid_samples: 0,
        }
    }

    /// Adds samples `self.spp .. self.spp + n` to every pixel (rayon over rows).
    pub fn add_samples(&mut self, world: &World, camera: &Camera, params: &TraceParams, n: u32) {
        let w = self.width as usize;
        let start = self.spp;
        let rows: Vec<(u64, Vec<(DVec3, u32, f32, f64)>)> = (0..self.height)
            .into_par_iter()
            .map(|y| {
                let mut invalid = 0u64;
                let row = (0..self.width)
                    .map(|x| {
                        let pixel = (y as u64) * w as u64 + x as u64;
                        let mut acc = DVec3::ZERO;
                        let mut vhits = 0u32;
                        let mut max_l = 0.0f32;
                        let mut lum2 = 0.0f64;
                        for s in start..start + n {
                            let mut rng = Rng::for_stream(params.seed, pixel, s as u64);
                            let (jx, jy) = (rng.next_f32(), rng.next_f32());
                            let ray = camera.ray(x as f32 + jx, y as f32 + jy);
                            let (l, first) = world.radiance(ray, &mut rng, params);
                            if !l.is_finite() {
                                invalid += 1;
                                continue;
                            }
                            acc += l.as_dvec3();
                            max_l = max_l.max(luminance(l));
                            lum2 += (luminance(l) as f64).powi(2);
                            if first.is_some_and(|o| world.object_roles[o as usize] == Role::Virtual) {
                                vhits += 1;
                            }
                        }
                        (acc, vhits, max_l, lum2)
                    })
                    .collect();
                (invalid, row)
            })
            .collect();
        for (y, (invalid, row)) in rows.into_iter().enumerate() {
            self.invalid_samples += invalid;
            for (x, (acc, vh, ml, l2)) in row.into_iter().enumerate() {
                let i = y * w + x;
                self.sum_lum2[i] += l2;
                self.sum[i] += acc;
                self.virtual_hits[i] += vh;
                self.max_sample[i] = self.max_sample[i].max(ml);
            }
        }
        self.spp += n;
    }

    /// The mean radiance per pixel.
    pub fn image(&self) -> Image {
        let inv = 1.0 / self.spp.max(1) as f64;
        Image {
            width: self.width,
            height: self.height,
            pixels: self.sum.iter().map(|s| (*s * inv).as_vec3()).collect(),
        }
    }

    /// Standard error of each pixel's mean luminance, from the spread of its samples.
    pub fn luminance_standard_error(&self) -> Vec<f32> {
        let n = self.spp.max(1) as f64;
        self.sum
            .iter()
            .zip(&self.sum_lum2)
            .map(|(s, s2)| {
                let mean = luminance((*s / n).as_vec3()) as f64;
                let var = (s2 / n - mean * mean).max(0.0) * n / (n - 1.0).max(1.0);
                (var / n).sqrt() as f32
            })
            .collect()
    }

    /// Fraction of samples per pixel whose primary ray saw a virtual object.
    pub fn virtual_coverage(&self) -> Vec<f32> {
        let inv = 1.0 / self.spp.max(1) as f32;
        self.virtual_hits.iter().map(|&h| h as f32 * inv).collect()
    }

    /// Pixels where a single sample carries more than `fraction` of the pixel's total and is
    /// brighter than `factor` × the image's mean luminance: fireflies. Counted, never clamped.
    pub fn count_fireflies(&self, factor: f32) -> usize {
        let img = self.image();
        let mean = luminance(img.mean()).max(1e-6);
        let spp = self.spp.max(1) as f32;
        img.pixels
            .iter()
            .zip(&self.max_sample)
            .filter(|(p, m)| **m > factor * mean && **m / spp > 0.5 * luminance(**p).max(1e-9))
            .count()
    }
}

/// Renders `spp` samples per pixel of a world in one go.
pub fn render(world: &World, camera: &Camera, params: &TraceParams, spp: u32) -> Accumulator {
    let mut acc = Accumulator::new(camera.width, camera.height);
    acc.add_samples(world, camera, params, spp);
    acc
}
