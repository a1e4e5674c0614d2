//! The virtual object's solid voxel volume (Rohmer et al., Sec. 6.3): a small volume fitted to
//! each virtual object's box, each voxel holding the probability τ that it lies inside the
//! object (the fraction of its volume inside), with mip levels, and at the voxels the surface
//! passes through the surface's outward normal and diffuse albedo. The paper traces the object's
//! self-shadow rays and secondary bounces in it instead of the triangle mesh, and so does
//! [`super::Coherent`] (`low` omits self-shadows; `med` stops a ray at an opaque voxel; `high`
//! bounces there, lit from the stored normal and albedo).
//!
//! The voxelisation is solid by parity, as the GPU method the paper cites (Eisemann and Décoret
//! 2008) is: along each of `SUB`² sample columns per voxel column (parallel to z) the object's
//! surface crossings are found exactly (its BVH), the intervals between an odd and the next even
//! crossing are inside, and each voxel gets the share of its z extent they cover, averaged over
//! its columns — exact along z, sampled across. The object must be closed; an odd number of
//! crossings in a column closes its last interval at the box's far side. An object that is not
//! closed ([`is_closed`]) gets no volume: the renderer intersects it exactly and says so. Normals
//! and albedos come from crossings along all three axes, so faces parallel to one axis are
//! still seen. The volume is built in the object's place at build time; [`SolidVolume::moved`]
//! follows a translated object without rebuilding (the paper applies rigid transformations to
//! the ray).

use crate::geometry::{Aabb, Primitive, Ray};
use crate::gpu::representation::{SOLID_SUB as SUB, SolidSweeps, mip_dims, sweep_span};
use crate::pathtracer::World;
use glam::{UVec3, Vec3};
use std::sync::Arc;

/// τ from which a voxel stops a ray.
const OPAQUE: f32 = 0.5;

/// The surface a voxel holds: its outward normal and diffuse albedo (means over the crossings
/// in it), and whether a mirror or glass was crossed there.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolidSurface {
    pub normal: Vec3,
    pub albedo: Vec3,
    pub delta: bool,
}

/// One mip level: τ per voxel, x fastest.
#[derive(Clone, Debug)]
struct Level {
    dims: UVec3,
    tau: Vec<f32>,
}

/// A ray's first opaque voxel in a solid volume.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolidHit {
    /// Distance along the ray to the voxel's entry.
    pub t: f32,
    pub point: Vec3,
    pub surface: SolidSurface,
}

/// A virtual object's solid voxel volume; cheap to clone (its voxels are shared).
#[derive(Clone, Debug)]
pub struct SolidVolume {
    /// The corner of voxel (0, 0, 0) where the object now stands.
    pub origin: Vec3,
    /// A voxel's edges.
    pub voxel: Vec3,
    levels: Arc<Vec<Level>>,
    surface: Arc<Vec<Option<SolidSurface>>>,
}

impl SolidVolume {
    /// Voxelises the part of `object` (a world of the virtual objects) inside `bounds` with
    /// `longest` voxels along the box's longest axis and proportionally fewer (at least one)
    /// along the others: the paper's 32³ and 128 × 96 × 96.
    pub fn build(object: &World, bounds: Aabb, longest: u32) -> SolidVolume {
        let (voxel, dims) = SolidVolume::frame(&bounds, longest);
        let origin = bounds.min;
        let count = (dims.x * dims.y * dims.z) as usize;
        let index = |v: UVec3| (v.x + dims.x * (v.y + dims.y * v.z)) as usize;
        let mut sweeps = SolidSweeps {
            tau: vec![0.0; count],
            normals: vec![[0.0; 4]; count],
            albedos: vec![[0.0; 4]; count],
            mips: Vec::new(),
        };
        let samples = (SUB * SUB) as f32;
        for axis in 0..3 {
            // the two axes across the sweep, and the sweep's direction
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut dir = Vec3::ZERO;
            dir[axis] = 1.0;
            let (from, to) = sweep_span(&bounds, axis);
            // τ needs the z sweep's every column; the normals of the other two, every other one
            let stride = if axis == 2 { 1 } else { 2 };
            for j in (0..dims[v] * SUB).step_by(stride) {
                for i in (0..dims[u] * SUB).step_by(stride) {
                    let mut start = origin;
                    start[u] += (i as f32 + 0.5) / SUB as f32 * voxel[u];
                    start[v] += (j as f32 + 0.5) / SUB as f32 * voxel[v];
                    start[axis] = from;
                    let crossings = crossings(object, start, dir, to);
                    let column = |k: u32| {
                        let mut cell = UVec3::ZERO;
                        cell[u] = i / SUB;
                        cell[v] = j / SUB;
                        cell[axis] = k;
                        cell
                    };
                    for (n, c) in crossings.iter().enumerate() {
                        let k = (((c.point[axis] - origin[axis]) / voxel[axis]).floor() as i64)
                            .clamp(0, dims[axis] as i64 - 1) as u32;
                        // entering (even) crossings face against the sweep, leaving ones along it
                        let outward = if (n % 2 == 0) == (c.normal[axis] > 0.0) { -c.normal } else { c.normal };
                        let at = index(column(k));
                        let normal = &mut sweeps.normals[at];
                        *normal =
                            [normal[0] + outward.x, normal[1] + outward.y, normal[2] + outward.z, normal[3] + 1.0];
                        let albedo = &mut sweeps.albedos[at];
                        let delta = if c.delta { 1.0 } else { albedo[3] };
                        *albedo = [albedo[0] + c.albedo.x, albedo[1] + c.albedo.y, albedo[2] + c.albedo.z, delta];
                    }
                    if axis != 2 {
                        continue;
                    }
                    // τ from the z sweep: the inside intervals' share of each voxel's extent
                    let mut inside = crossings.chunks(2).map(|pair| {
                        let enter = pair[0].point[2];
                        let leave = pair.get(1).map_or(bounds.max[2], |c| c.point[2]);
                        (enter, leave)
                    });
                    for (enter, leave) in &mut inside {
                        let first = (((enter - origin[2]) / voxel[2]).floor().max(0.0) as u32).min(dims[2] - 1);
                        let last = (((leave - origin[2]) / voxel[2]).floor().max(0.0) as u32).min(dims[2] - 1);
                        for k in first..=last {
                            let (lo, hi) = (origin[2] + k as f32 * voxel[2], origin[2] + (k + 1) as f32 * voxel[2]);
                            let covered = (leave.min(hi) - enter.max(lo)).max(0.0) / voxel[2];
                            sweeps.tau[index(column(k))] += covered / samples;
                        }
                    }
                }
            }
        }
        SolidVolume::from_sweeps(origin, voxel, dims, sweeps)
    }

    /// A voxel's edges and the voxels per axis of a volume over `bounds` with `longest` voxels
    /// along its longest axis and proportionally fewer (at least one) along the others.
    pub fn frame(bounds: &Aabb, longest: u32) -> (Vec3, UVec3) {
        let extent = (bounds.max - bounds.min).max(Vec3::splat(1e-6));
        let longest = longest.max(1);
        // (a hair under the quotient before rounding up: 0.1 / 0.2 × 32 is 16, not 17)
        let dims = (extent / extent.max_element() * longest as f32 - 1e-3).ceil().max(Vec3::ONE).as_uvec3();
        (extent / dims.as_vec3(), dims)
    }

    /// The volume from its sweeps' sums (the CPU's or the GPU's, [`SolidSweeps`]): τ clamped to
    /// [0, 1] with its mip levels (the sweeps' own, else made here), and at each voxel a
    /// crossing passed the mean outward normal and albedo.
    pub fn from_sweeps(origin: Vec3, voxel: Vec3, dims: UVec3, sweeps: SolidSweeps) -> SolidVolume {
        let SolidSweeps { mut tau, normals, albedos, mips } = sweeps;
        for t in &mut tau {
            *t = t.clamp(0.0, 1.0);
        }
        let surface = normals
            .iter()
            .zip(&albedos)
            .map(|(n, a)| {
                (n[3] > 0.0).then(|| SolidSurface {
                    normal: Vec3::new(n[0], n[1], n[2]).normalize_or_zero(),
                    albedo: Vec3::new(a[0], a[1], a[2]) / n[3],
                    delta: a[3] > 0.0,
                })
            })
            .collect();
        let mut levels = vec![Level { dims, tau }];
        let sizes = mip_dims(dims);
        if mips.len() + 1 == sizes.len() {
            levels.extend(sizes[1..].iter().zip(mips).map(|(&dims, tau)| Level { dims, tau }));
        }
        while levels.last().is_some_and(|l| l.dims.max_element() > 1) {
            levels.push(downsample(levels.last().expect("a level")));
        }
        SolidVolume { origin, voxel, levels: Arc::new(levels), surface: Arc::new(surface) }
    }

    /// Voxels per axis of level 0.
    pub fn dims(&self) -> UVec3 {
        self.levels[0].dims
    }

    /// Mip levels, level 0 included.
    pub fn level_count(&self) -> usize {
        self.levels.len()
    }

    /// τ of voxel `v` at mip `level` (0 outside).
    pub fn tau(&self, level: usize, v: UVec3) -> f32 {
        let l = &self.levels[level.min(self.levels.len() - 1)];
        if v.cmpge(l.dims).any() {
            return 0.0;
        }
        l.tau[(v.x + l.dims.x * (v.y + l.dims.y * v.z)) as usize]
    }

    /// The volume's box.
    pub fn bounds(&self) -> Aabb {
        Aabb { min: self.origin, max: self.origin + self.voxel * self.dims().as_vec3() }
    }

    /// The same volume following its object moved by `offset`.
    pub fn moved(&self, offset: Vec3) -> SolidVolume {
        SolidVolume { origin: self.origin + offset, ..self.clone() }
    }

    /// Bytes held (τ of every level, the surface cells).
    pub fn bytes(&self) -> usize {
        self.levels.iter().map(|l| l.tau.len() * 4).sum::<usize>()
            + self.surface.len() * std::mem::size_of::<Option<SolidSurface>>()
    }

    /// The fraction of the volume's box inside the object: the mean τ of level 0.
    pub fn filled(&self) -> f64 {
        let tau = &self.levels[0].tau;
        tau.iter().map(|&t| t as f64).sum::<f64>() / tau.len().max(1) as f64
    }

    /// The first voxel along the ray from `origin` (unit `dir`) with τ ≥ ½, between `t_min` (a
    /// self-shadow ray's offset past the voxels its own surface fills) and `t_max`; its surface
    /// is the one stored there, or in the nearest voxel around it that has one.
    pub fn march(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Option<SolidHit> {
        let bounds = self.bounds();
        let inv = dir.recip();
        let t0 = (bounds.min - origin) * inv;
        let t1 = (bounds.max - origin) * inv;
        let enter = t0.min(t1).max_element().max(t_min);
        let leave = t0.max(t1).min_element().min(t_max);
        if !(enter <= leave) {
            return None;
        }
        // Amanatides–Woo through level 0 from the entry point
        let dims = self.dims();
        let local = (origin + dir * enter - self.origin) / self.voxel;
        let mut cell = local.floor().clamp(Vec3::ZERO, dims.as_vec3() - 1.0).as_ivec3();
        let step = dir.signum().as_ivec3();
        let next_boundary =
            (cell.as_vec3() + Vec3::select(dir.cmpgt(Vec3::ZERO), Vec3::ONE, Vec3::ZERO)) * self.voxel + self.origin;
        let mut t_next = Vec3::select(dir.cmpeq(Vec3::ZERO), Vec3::INFINITY, (next_boundary - origin) * inv);
        let delta = (self.voxel * inv).abs();
        let mut t = enter;
        loop {
            let v = cell.as_uvec3();
            if self.tau(0, v) >= OPAQUE {
                let point = origin + dir * t;
                return Some(SolidHit { t, point, surface: self.surface_near(v, dir) });
            }
            let axis = if t_next.x < t_next.y && t_next.x < t_next.z {
                0
            } else if t_next.y < t_next.z {
                1
            } else {
                2
            };
            t = t_next[axis];
            if t > leave {
                return None;
            }
            cell[axis] += step[axis];
            if cell[axis] < 0 || cell[axis] >= dims[axis] as i32 {
                return None;
            }
            t_next[axis] += delta[axis];
        }
    }

    /// The surface stored at voxel `v` of level 0, if a crossing passed it.
    pub fn surface(&self, v: UVec3) -> Option<SolidSurface> {
        let dims = self.dims();
        if v.cmpge(dims).any() {
            return None;
        }
        self.surface[(v.x + dims.x * (v.y + dims.y * v.z)) as usize]
    }

    /// The surface stored at voxel `v`, else the mean of its neighbours' within one voxel; else
    /// a grey surface facing the ray.
    fn surface_near(&self, v: UVec3, dir: Vec3) -> SolidSurface {
        let dims = self.dims();
        let at = |c: UVec3| self.surface[(c.x + dims.x * (c.y + dims.y * c.z)) as usize];
        if let Some(s) = at(v) {
            return s;
        }
        let (mut normal, mut albedo, mut n, mut delta) = (Vec3::ZERO, Vec3::ZERO, 0, false);
        for dz in -1..=1i32 {
            for dy in -1..=1i32 {
                for dx in -1..=1i32 {
                    let c = v.as_ivec3() + glam::IVec3::new(dx, dy, dz);
                    if c.cmplt(glam::IVec3::ZERO).any() || c.cmpge(dims.as_ivec3()).any() {
                        continue;
                    }
                    if let Some(s) = at(c.as_uvec3()) {
                        normal += s.normal;
                        albedo += s.albedo;
                        n += 1;
                        delta |= s.delta;
                    }
                }
            }
        }
        if n == 0 {
            return SolidSurface { normal: -dir, albedo: Vec3::splat(0.5), delta: false };
        }
        let normal = if normal.length_squared() > 0.0 { normal.normalize() } else { -dir };
        SolidSurface { normal, albedo: albedo / n as f32, delta }
    }
}

/// Whether `prims` bound a solid, as parity voxelisation needs: spheres do, and triangles do
/// when every edge is shared by exactly two of them (corners compared as stored). A Cornell box
/// of five one-sided walls does not.
pub fn is_closed(prims: &[Primitive]) -> bool {
    let mut edges: std::collections::HashMap<([u32; 3], [u32; 3]), u32> = std::collections::HashMap::new();
    for prim in prims {
        if let Primitive::Triangle(t) = prim {
            for k in 0..3 {
                let (a, b) = (t.p[k].to_array().map(f32::to_bits), t.p[(k + 1) % 3].to_array().map(f32::to_bits));
                *edges.entry(if a < b { (a, b) } else { (b, a) }).or_default() += 1;
            }
        }
    }
    edges.values().all(|&n| n == 2)
}

/// A crossing of the object's surface along a sweep.
struct Crossing {
    point: Vec3,
    normal: Vec3,
    albedo: Vec3,
    delta: bool,
}

/// Every crossing of `object`'s surfaces along the ray from `start` in the axis direction `dir`,
/// up to the coordinate `end` along it, in order.
fn crossings(object: &World, start: Vec3, dir: Vec3, end: f32) -> Vec<Crossing> {
    let axis = dir.abs().max_position();
    let mut found = Vec::new();
    let mut origin = start;
    while found.len() < 256 {
        let remaining = end - origin[axis];
        if remaining <= 0.0 {
            break;
        }
        let Some((hit, material)) = object.hit_with_material(&Ray { origin, dir }, remaining) else { break };
        found.push(Crossing {
            point: hit.point,
            normal: hit.geometric_normal,
            albedo: material.albedo_at(hit.uv),
            delta: material.delta.is_some(),
        });
        origin = hit.point;
    }
    found
}

/// The next mip level: τ averaged over each 2×2×2 block (a block cut by the edge averages the
/// voxels it has).
fn downsample(level: &Level) -> Level {
    let dims = (level.dims + UVec3::ONE) / 2;
    let mut tau = vec![0.0; (dims.x * dims.y * dims.z) as usize];
    for z in 0..dims.z {
        for y in 0..dims.y {
            for x in 0..dims.x {
                let (mut sum, mut n) = (0.0, 0);
                for c in 0..8u32 {
                    let v = UVec3::new(2 * x + (c & 1), 2 * y + ((c >> 1) & 1), 2 * z + (c >> 2));
                    if v.cmplt(level.dims).all() {
                        sum += level.tau[(v.x + level.dims.x * (v.y + level.dims.y * v.z)) as usize];
                        n += 1;
                    }
                }
                tau[(x + dims.x * (y + dims.y * z)) as usize] = sum / n as f32;
            }
        }
    }
    Level { dims, tau }
}
