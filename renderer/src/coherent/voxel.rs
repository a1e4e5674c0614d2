//! The scene voxel volume of voxel cone tracing (Rohmer et al., Sec. 6.1, after Crassin et al.):
//! a dense cube of voxels holding the captured radiance with opacity 1 where a sample lies, and
//! a mipmap chain of averages for wider cones. Cone tracing marches front to back with a step
//! of half the cone's diameter, reading the level whose voxel matches the diameter.

use crate::capture::hashgrid::EnvironmentSample;
use crate::coherent::impostor::SPLAT_RADIUS;
use crate::geometry::Aabb;
use glam::Vec3;

/// The largest radiance one sample brings into a voxel (the GPU build sums radiance in 32-bit
/// fixed point at 1/4096, and this keeps 64 samples in one voxel from overflowing it); far above
/// what a camera records of a surface, it clips only a captured light source's core.
pub const RADIANCE_MAX: f32 = 16383.0;

/// One level: `res`³ voxels of premultiplied radiance (rgb) and opacity (a).
#[derive(Clone, Debug)]
struct Level {
    res: usize,
    data: Vec<[f32; 4]>,
}

impl Level {
    fn at(&self, x: usize, y: usize, z: usize) -> [f32; 4] {
        self.data[(z * self.res + y) * self.res + x]
    }
}

/// A mip-mapped voxel volume of the captured environment.
#[derive(Clone, Debug)]
pub struct VoxelVolume {
    /// The corner of voxel (0, 0, 0).
    pub origin: Vec3,
    /// Edge of a level-0 voxel in metres.
    pub voxel: f32,
    /// Level-0 voxels per axis.
    pub res: u32,
    levels: Vec<Level>,
}

/// A cone's answer: premultiplied radiance gathered, the opacity met (α of eq. 6 is 1 minus
/// it) and the distance at which the opacity passed one half (infinite when it never did).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConeHit {
    pub radiance: Vec3,
    pub opacity: f32,
    pub distance: f32,
}

impl VoxelVolume {
    /// Fills `res`³ voxels over the samples' bounds (a cube, padded by `footprint`); each
    /// sample is a disk in its tangent plane (radius [`SPLAT_RADIUS`] × `footprint`, the hash
    /// grid's cell, so that a surface sampled every cell is closed) and fills the voxels that
    /// disk passes through: a surface stays one voxel thick. A sample without a usable normal
    /// fills the voxels within its radius. Radiance is averaged per voxel.
    pub fn build<'a>(
        samples: impl IntoIterator<Item = &'a EnvironmentSample> + Clone,
        res: u32,
        footprint: f32,
    ) -> Self {
        let (origin, voxel, res) = VoxelVolume::frame(samples.clone(), res, footprint);
        let res = res as usize;
        let empty = !samples.clone().into_iter().any(|s| s.position.is_finite() && s.colour.is_finite());
        let mut sum = vec![[0.0f32; 4]; res * res * res];
        if !empty {
            let radius = (SPLAT_RADIUS * footprint).max(0.5 * voxel);
            let reach = (radius / voxel).ceil() as i64;
            for s in samples {
                if !(s.position.is_finite() && s.colour.is_finite()) {
                    continue;
                }
                let normal = s.unit_normal();
                // a plane meets a voxel's cube when its centre lies within this of the plane
                let slab = normal.map_or(f32::INFINITY, |n| 0.5 * voxel * (n.x.abs() + n.y.abs() + n.z.abs()));
                let c = (s.position - origin) / voxel;
                let (cx, cy, cz) = (c.x.floor() as i64, c.y.floor() as i64, c.z.floor() as i64);
                for z in cz - reach..=cz + reach {
                    for y in cy - reach..=cy + reach {
                        for x in cx - reach..=cx + reach {
                            if x < 0 || y < 0 || z < 0 || x >= res as i64 || y >= res as i64 || z >= res as i64 {
                                continue;
                            }
                            let centre = origin + (Vec3::new(x as f32, y as f32, z as f32) + 0.5) * voxel;
                            let offset = centre - s.position;
                            let across = normal.map_or(0.0, |n| n.dot(offset));
                            if across.abs() > slab || (offset - normal.unwrap_or(Vec3::ZERO) * across).length() > radius
                            {
                                continue;
                            }
                            let v = &mut sum[((z as usize) * res + y as usize) * res + x as usize];
                            let colour = s.colour.clamp(Vec3::ZERO, Vec3::splat(RADIANCE_MAX));
                            v[0] += colour.x;
                            v[1] += colour.y;
                            v[2] += colour.z;
                            v[3] += 1.0;
                        }
                    }
                }
            }
        }
        // level 0: mean radiance, opacity 1 where any sample landed (premultiplied by it)
        let base: Vec<[f32; 4]> = sum
            .into_iter()
            .map(|v| if v[3] > 0.0 { [v[0] / v[3], v[1] / v[3], v[2] / v[3], 1.0] } else { [0.0; 4] })
            .collect();
        let mut levels = vec![Level { res, data: base }];
        while levels.last().is_some_and(|l| l.res > 1) {
            let fine = levels.last().expect("a level");
            let r = fine.res.div_ceil(2);
            let mut data = vec![[0.0f32; 4]; r * r * r];
            for z in 0..r {
                for y in 0..r {
                    for x in 0..r {
                        let mut acc = [0.0f32; 4];
                        for (dx, dy, dz) in (0..8).map(|k| (k & 1, (k >> 1) & 1, (k >> 2) & 1)) {
                            let (fx, fy, fz) = (2 * x + dx, 2 * y + dy, 2 * z + dz);
                            if fx < fine.res && fy < fine.res && fz < fine.res {
                                let v = fine.at(fx, fy, fz);
                                for c in 0..4 {
                                    acc[c] += v[c] / 8.0;
                                }
                            }
                        }
                        data[(z * r + y) * r + x] = acc;
                    }
                }
            }
            levels.push(Level { res: r, data });
        }
        VoxelVolume { origin, voxel, res: res as u32, levels }
    }

    /// Where a volume of `res`³ voxels over `samples` lies: the corner of voxel (0, 0, 0), the
    /// voxel's edge and the resolution (clamped to 1–512). The cube spans the finite samples'
    /// bounds padded by `footprint`; a unit cube at the origin when there is none.
    pub fn frame<'a>(
        samples: impl IntoIterator<Item = &'a EnvironmentSample>,
        res: u32,
        footprint: f32,
    ) -> (Vec3, f32, u32) {
        let res = res.clamp(1, 512);
        let mut bounds = Aabb::EMPTY;
        for s in samples {
            if s.position.is_finite() && s.colour.is_finite() {
                bounds.grow(s.position);
            }
        }
        let (origin, edge) = if bounds.min.x > bounds.max.x {
            (Vec3::ZERO, 1.0)
        } else {
            let pad = Vec3::splat(footprint.max(1e-3));
            let (lo, hi) = (bounds.min - pad, bounds.max + pad);
            (lo, (hi - lo).max_element())
        };
        (origin, edge / res as f32, res)
    }

    /// A volume from its levels' voxels (premultiplied rgb and opacity; level 0 first, each
    /// level half the previous per axis, rounded up, down to one voxel), as the GPU builds it.
    pub fn from_levels(origin: Vec3, voxel: f32, levels: Vec<Vec<[f32; 4]>>) -> Self {
        let levels: Vec<Level> =
            levels.into_iter().map(|data| Level { res: (data.len() as f64).cbrt().round() as usize, data }).collect();
        let res = levels.first().map_or(1, |l| l.res as u32);
        VoxelVolume { origin, voxel, res, levels }
    }

    /// Level `level`'s voxels (x fastest, then y, then z), for comparisons.
    pub fn level(&self, level: usize) -> &[[f32; 4]] {
        &self.levels[level].data
    }

    /// Bytes held by every level.
    pub fn bytes(&self) -> usize {
        self.levels.iter().map(|l| l.data.len() * 16).sum()
    }

    /// Mip levels (level 0 included).
    pub fn level_count(&self) -> usize {
        self.levels.len()
    }

    /// Level-0 voxels with opacity.
    pub fn filled(&self) -> usize {
        self.levels[0].data.iter().filter(|v| v[3] > 0.0).count()
    }

    /// Trilinear lookup at world point `p` in level `level` (zero outside the volume).
    fn sample_level(&self, p: Vec3, level: usize) -> [f32; 4] {
        let l = &self.levels[level];
        let size = self.voxel * (1 << level) as f32;
        let c = (p - self.origin) / size - 0.5;
        let base = c.floor();
        let f = c - base;
        let mut out = [0.0f32; 4];
        for k in 0..8 {
            let (dx, dy, dz) = (k & 1, (k >> 1) & 1, (k >> 2) & 1);
            let (x, y, z) = (base.x as i64 + dx as i64, base.y as i64 + dy as i64, base.z as i64 + dz as i64);
            if x < 0 || y < 0 || z < 0 || x >= l.res as i64 || y >= l.res as i64 || z >= l.res as i64 {
                continue;
            }
            let w = (if dx == 1 { f.x } else { 1.0 - f.x })
                * (if dy == 1 { f.y } else { 1.0 - f.y })
                * (if dz == 1 { f.z } else { 1.0 - f.z });
            let v = l.at(x as usize, y as usize, z as usize);
            for c in 0..4 {
                out[c] += w * v[c];
            }
        }
        out
    }

    /// Lookup between levels (`level` fractional).
    fn sample(&self, p: Vec3, level: f32) -> [f32; 4] {
        let top = (self.levels.len() - 1) as f32;
        let level = level.clamp(0.0, top);
        let lo = level.floor() as usize;
        let hi = (lo + 1).min(self.levels.len() - 1);
        let t = level - lo as f32;
        let a = self.sample_level(p, lo);
        if t == 0.0 || hi == lo {
            return a;
        }
        let b = self.sample_level(p, hi);
        std::array::from_fn(|c| a[c] + t * (b[c] - a[c]))
    }

    /// Traces a cone of half-angle `half_angle` from `origin` along the unit `dir`, starting
    /// one voxel out (so the surface it leaves does not stop it) and ending where the
    /// opacity reaches 0.95 or the cone leaves the volume.
    pub fn cone(&self, origin: Vec3, dir: Vec3, half_angle: f32) -> ConeHit {
        self.cone_to(origin, dir, half_angle, f32::INFINITY)
    }

    /// [`VoxelVolume::cone`] ending at distance `t_max` (what lies before a point).
    pub fn cone_to(&self, origin: Vec3, dir: Vec3, half_angle: f32, t_max: f32) -> ConeHit {
        let tan = half_angle.clamp(1e-3, 1.4).tan();
        let size = self.voxel * self.res as f32;
        let lo = self.origin;
        let hi = self.origin + Vec3::splat(size);
        // where the ray leaves the cube (the march stops there)
        let inv = dir.recip();
        let t0 = (lo - origin) * inv;
        let t1 = (hi - origin) * inv;
        let t_exit = t0.max(t1).min_element().min(t_max);
        let t_enter = t0.min(t1).max_element().max(0.0);
        let mut hit = ConeHit { radiance: Vec3::ZERO, opacity: 0.0, distance: f32::INFINITY };
        if !(t_exit > t_enter) {
            return hit;
        }
        let mut t = t_enter.max(self.voxel);
        while t < t_exit && hit.opacity < 0.95 {
            let diameter = (2.0 * t * tan).max(self.voxel);
            let level = (diameter / self.voxel).log2();
            let s = self.sample(origin + dir * t, level);
            if s[3] > 1e-6 {
                // opacity corrected for a step of half the diameter
                let a = 1.0 - (1.0 - s[3].min(1.0)).sqrt();
                let colour = Vec3::new(s[0], s[1], s[2]) / s[3];
                hit.radiance += (1.0 - hit.opacity) * a * colour;
                hit.opacity += (1.0 - hit.opacity) * a;
                if hit.distance.is_infinite() && hit.opacity >= 0.5 {
                    hit.distance = t;
                }
            }
            t += 0.5 * diameter;
        }
        hit
    }
}

impl From<crate::gpu::representation::VoxelLevels> for VoxelVolume {
    fn from(levels: crate::gpu::representation::VoxelLevels) -> VoxelVolume {
        VoxelVolume::from_levels(levels.origin, levels.voxel, levels.levels)
    }
}
