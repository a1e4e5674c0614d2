//! Geometry: rays, bounding boxes, the two primitive kinds the tracer intersects (triangles and
//! analytic spheres), transforms, and tessellation of the scene-file shapes (box, plane, quad,
//! cylinder, cone frustum, swept tube) into triangles.

use glam::{Mat3, Mat4, Vec2, Vec3};
use std::f32::consts::PI;

#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
}

#[derive(Clone, Copy, Debug)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb { min: Vec3::splat(f32::INFINITY), max: Vec3::splat(f32::NEG_INFINITY) };
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb { min: self.min.min(o.min), max: self.max.max(o.max) }
    }
    pub fn centroid(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }
    pub fn area(&self) -> f32 {
        let d = (self.max - self.min).max(Vec3::ZERO);
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }
    /// Slab test; returns the entry distance if the ray hits within (0, t_max).
    #[inline]
    pub fn hit(&self, origin: Vec3, inv_dir: Vec3, t_max: f32) -> Option<f32> {
        let t0 = (self.min - origin) * inv_dir;
        let t1 = (self.max - origin) * inv_dir;
        let tmin = t0.min(t1).max_element().max(0.0);
        let tmax = t0.max(t1).min_element().min(t_max);
        if tmin <= tmax { Some(tmin) } else { None }
    }
}

/// A triangle with optional per-vertex shading normals and texture coordinates.
#[derive(Clone, Debug)]
pub struct Triangle {
    pub p: [Vec3; 3],
    pub n: Option<[Vec3; 3]>,
    pub uv: [Vec2; 3],
}

impl Triangle {
    pub fn area(&self) -> f32 {
        0.5 * (self.p[1] - self.p[0]).cross(self.p[2] - self.p[0]).length()
    }
    pub fn geometric_normal(&self) -> Vec3 {
        (self.p[1] - self.p[0]).cross(self.p[2] - self.p[0]).normalize_or_zero()
    }
}

/// What the tracer intersects.
#[derive(Clone, Debug)]
pub enum Primitive {
    Triangle(Triangle),
    Sphere { center: Vec3, radius: f32 },
}

/// A ray–primitive intersection with its local surface description.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    pub t: f32,
    pub point: Vec3,
    /// Geometric normal (as oriented by the primitive: outward for spheres, winding for triangles).
    pub geometric_normal: Vec3,
    pub shading_normal: Vec3,
    pub uv: Vec2,
}

impl Primitive {
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        match self {
            Primitive::Triangle(t) => {
                for p in t.p {
                    b.grow(p);
                }
            }
            Primitive::Sphere { center, radius } => {
                b.grow(*center - Vec3::splat(*radius));
                b.grow(*center + Vec3::splat(*radius));
            }
        }
        b
    }

    /// Distance to the nearest intersection in (t_min, t_max), without surface details.
    #[inline]
    pub fn intersect_t(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<(f32, f32, f32)> {
        match self {
            Primitive::Triangle(tri) => {
                // Möller–Trumbore
                let e1 = tri.p[1] - tri.p[0];
                let e2 = tri.p[2] - tri.p[0];
                let pvec = ray.dir.cross(e2);
                let det = e1.dot(pvec);
                if det.abs() < 1e-12 {
                    return None;
                }
                let inv = 1.0 / det;
                let tvec = ray.origin - tri.p[0];
                let u = tvec.dot(pvec) * inv;
                if !(0.0..=1.0).contains(&u) {
                    return None;
                }
                let qvec = tvec.cross(e1);
                let v = ray.dir.dot(qvec) * inv;
                if v < 0.0 || u + v > 1.0 {
                    return None;
                }
                let t = e2.dot(qvec) * inv;
                if t > t_min && t < t_max { Some((t, u, v)) } else { None }
            }
            Primitive::Sphere { center, radius } => {
                let oc = ray.origin - *center;
                let a = ray.dir.length_squared();
                let half_b = oc.dot(ray.dir);
                let c = oc.length_squared() - radius * radius;
                let disc = half_b * half_b - a * c;
                if disc < 0.0 {
                    return None;
                }
                let sq = disc.sqrt();
                let t0 = (-half_b - sq) / a;
                if t0 > t_min && t0 < t_max {
                    return Some((t0, 0.0, 0.0));
                }
                let t1 = (-half_b + sq) / a;
                if t1 > t_min && t1 < t_max { Some((t1, 0.0, 0.0)) } else { None }
            }
        }
    }

    /// Completes an intersection found by [`Primitive::intersect_t`].
    pub fn surface(&self, ray: &Ray, t: f32, u: f32, v: f32) -> SurfaceHit {
        self.surface_with(ray, t, u, v, true)
    }

    /// [`Primitive::surface`], with a sphere's texture coordinates (an arc tangent and an arc
    /// cosine) computed only when `uv` asks for them (a textured material); otherwise zero.
    #[inline(always)]
    pub fn surface_with(&self, ray: &Ray, t: f32, u: f32, v: f32, uv: bool) -> SurfaceHit {
        self.surface_with_normal(ray, t, u, v, uv, self.flat_normal())
    }

    /// A triangle's geometric normal ([`Triangle::geometric_normal`]); zero for a sphere, whose
    /// normal depends on the point.
    #[inline(always)]
    pub fn flat_normal(&self) -> Vec3 {
        match self {
            Primitive::Triangle(tri) => tri.geometric_normal(),
            Primitive::Sphere { .. } => Vec3::ZERO,
        }
    }

    /// [`Primitive::surface_with`] with a triangle's geometric normal given (precomputed, as
    /// [`Triangle::geometric_normal`] gives it; unused for a sphere).
    #[inline(always)]
    pub fn surface_with_normal(&self, ray: &Ray, t: f32, u: f32, v: f32, uv: bool, normal: Vec3) -> SurfaceHit {
        let point = ray.origin + ray.dir * t;
        match self {
            Primitive::Triangle(tri) => {
                let w = 1.0 - u - v;
                let ng = normal;
                let ns = match tri.n {
                    Some(n) => (n[0] * w + n[1] * u + n[2] * v).normalize_or(ng),
                    None => ng,
                };
                let uv = tri.uv[0] * w + tri.uv[1] * u + tri.uv[2] * v;
                SurfaceHit { t, point, geometric_normal: ng, shading_normal: ns, uv }
            }
            Primitive::Sphere { center, radius } => {
                let n = ((point - *center) / *radius).normalize();
                let uv = match uv {
                    true => Vec2::new(0.5 + n.z.atan2(n.x) / (2.0 * PI), n.y.clamp(-1.0, 1.0).acos() / PI),
                    false => Vec2::ZERO,
                };
                SurfaceHit { t, point, geometric_normal: n, shading_normal: n, uv }
            }
        }
    }
}

/// Builds the object-to-world matrix from translation, Euler rotation (degrees, applied X then Y
/// then Z) and per-axis scale.
pub fn transform_matrix(translate: Vec3, rotate_deg: Vec3, scale: Vec3) -> Mat4 {
    let r = glam::Quat::from_euler(
        glam::EulerRot::ZYX,
        rotate_deg.z.to_radians(),
        rotate_deg.y.to_radians(),
        rotate_deg.x.to_radians(),
    );
    Mat4::from_scale_rotation_translation(scale, r, translate)
}

/// Transforms triangles to world space (normals by the inverse transpose); drops triangles of
/// zero area and returns how many were dropped.
pub fn transform_triangles(tris: Vec<Triangle>, m: &Mat4) -> (Vec<Triangle>, usize) {
    let nm = Mat3::from_mat4(*m).inverse().transpose();
    let mut out = Vec::with_capacity(tris.len());
    let mut degenerate = 0;
    for t in tris {
        let p = t.p.map(|p| m.transform_point3(p));
        let n = t.n.map(|n| n.map(|n| (nm * n).normalize_or_zero()));
        let tri = Triangle { p, n, uv: t.uv };
        let a = tri.area();
        if !(a > 1e-14) || !a.is_finite() {
            degenerate += 1;
            continue;
        }
        out.push(tri);
    }
    (out, degenerate)
}

fn quad_tris(c: Vec3, u: Vec3, v: Vec3, uv_scale: Vec2) -> [Triangle; 2] {
    // corners c, c+u, c+u+v, c+v ; normal = u × v
    let p0 = c;
    let p1 = c + u;
    let p2 = c + u + v;
    let p3 = c + v;
    let t0 = Vec2::new(0.0, 0.0) * uv_scale;
    let t1 = Vec2::new(1.0, 0.0) * uv_scale;
    let t2 = Vec2::new(1.0, 1.0) * uv_scale;
    let t3 = Vec2::new(0.0, 1.0) * uv_scale;
    [Triangle { p: [p0, p1, p2], n: None, uv: [t0, t1, t2] }, Triangle { p: [p0, p2, p3], n: None, uv: [t0, t2, t3] }]
}

/// A unit quad in the XZ plane centred at the origin, facing +Y, scaled to `size` (x, z).
pub fn quad(size: Vec2, uv_scale: Vec2) -> Vec<Triangle> {
    let c = Vec3::new(-size.x / 2.0, 0.0, size.y / 2.0);
    quad_tris(c, Vec3::new(size.x, 0.0, 0.0), Vec3::new(0.0, 0.0, -size.y), uv_scale).to_vec()
}

/// An axis-aligned box centred at the origin, outward-facing.
pub fn cuboid(size: Vec3, uv_scale: Vec2) -> Vec<Triangle> {
    let h = size / 2.0;
    let mut out = Vec::with_capacity(12);
    let faces = [
        (Vec3::new(-h.x, -h.y, h.z), Vec3::new(size.x, 0.0, 0.0), Vec3::new(0.0, size.y, 0.0)), // +z
        (Vec3::new(h.x, -h.y, -h.z), Vec3::new(-size.x, 0.0, 0.0), Vec3::new(0.0, size.y, 0.0)), // -z
        (Vec3::new(h.x, -h.y, h.z), Vec3::new(0.0, 0.0, -size.z), Vec3::new(0.0, size.y, 0.0)), // +x
        (Vec3::new(-h.x, -h.y, -h.z), Vec3::new(0.0, 0.0, size.z), Vec3::new(0.0, size.y, 0.0)), // -x
        (Vec3::new(-h.x, h.y, h.z), Vec3::new(size.x, 0.0, 0.0), Vec3::new(0.0, 0.0, -size.z)), // +y
        (Vec3::new(-h.x, -h.y, -h.z), Vec3::new(size.x, 0.0, 0.0), Vec3::new(0.0, 0.0, size.z)), // -y
    ];
    for (c, u, v) in faces {
        out.extend(quad_tris(c, u, v, uv_scale));
    }
    out
}

/// A surface of revolution about +Y: radius `r0` at y = -h/2 to `r1` at y = +h/2, with optional
/// caps. `r0 == r1` is a cylinder; different radii give a cone frustum (a lamp shade).
pub fn frustum(r0: f32, r1: f32, height: f32, segments: u32, caps: bool) -> Vec<Triangle> {
    let n = segments.max(3);
    let y0 = -height / 2.0;
    let y1 = height / 2.0;
    let slope = (r0 - r1) / height.max(1e-9);
    let mut out = Vec::new();
    for i in 0..n {
        let a0 = 2.0 * PI * i as f32 / n as f32;
        let a1 = 2.0 * PI * (i + 1) as f32 / n as f32;
        let d0 = Vec3::new(a0.cos(), 0.0, -a0.sin());
        let d1 = Vec3::new(a1.cos(), 0.0, -a1.sin());
        let n0 = (d0 + Vec3::Y * slope).normalize();
        let n1 = (d1 + Vec3::Y * slope).normalize();
        let b0 = d0 * r0 + Vec3::Y * y0;
        let b1 = d1 * r0 + Vec3::Y * y0;
        let t0 = d0 * r1 + Vec3::Y * y1;
        let t1 = d1 * r1 + Vec3::Y * y1;
        let u0 = i as f32 / n as f32;
        let u1 = (i + 1) as f32 / n as f32;
        out.push(Triangle {
            p: [b0, b1, t1],
            n: Some([n0, n1, n1]),
            uv: [Vec2::new(u0, 0.0), Vec2::new(u1, 0.0), Vec2::new(u1, 1.0)],
        });
        out.push(Triangle {
            p: [b0, t1, t0],
            n: Some([n0, n1, n0]),
            uv: [Vec2::new(u0, 0.0), Vec2::new(u1, 1.0), Vec2::new(u0, 1.0)],
        });
        if caps {
            if r1 > 0.0 {
                let c = Vec3::Y * y1;
                out.push(Triangle { p: [c, t0, t1], n: None, uv: [Vec2::splat(0.5); 3] });
            }
            if r0 > 0.0 {
                let c = Vec3::Y * y0;
                out.push(Triangle { p: [c, b1, b0], n: None, uv: [Vec2::splat(0.5); 3] });
            }
        }
    }
    out
}

/// A tube swept along a polyline `path` with per-point radii (closed at both ends), with smooth
/// normals: used for the banana.
/// A closed solid of revolution about +Y: `profile` holds `[radius, height]` from the bottom
/// up; an end of radius 0 is a pole, any other end gets a flat cap. Normals are smooth, from
/// the profile's slope (averaged over the two segments at each ring), so that glass and
/// mirrors see the turned surface, not its facets.
pub fn lathe(profile: &[[f32; 2]], segments: u32) -> Vec<Triangle> {
    let n = segments.max(3) as usize;
    let m = profile.len();
    // the outward normal of each profile segment in the (r, y) plane
    let segment_normal = |i: usize| {
        let (dr, dy) = (profile[i + 1][0] - profile[i][0], profile[i + 1][1] - profile[i][1]);
        Vec2::new(dy, -dr).normalize_or_zero()
    };
    let ring_normal: Vec<Vec2> = (0..m)
        .map(|i| {
            let before = if i > 0 { segment_normal(i - 1) } else { Vec2::ZERO };
            let after = if i + 1 < m { segment_normal(i) } else { Vec2::ZERO };
            let n = (before + after).normalize_or_zero();
            if n == Vec2::ZERO { Vec2::Y } else { n }
        })
        .collect();
    let at = |i: usize, k: usize| {
        let a = 2.0 * PI * k as f32 / n as f32;
        let (c, s) = (a.cos(), a.sin());
        let [r, y] = profile[i];
        let nr = ring_normal[i];
        (Vec3::new(r * c, y, r * s), Vec3::new(nr.x * c, nr.y, nr.x * s).normalize())
    };
    let mut out = Vec::new();
    let uv = [Vec2::ZERO; 3];
    for i in 0..m - 1 {
        for k in 0..n {
            let k1 = (k + 1) % n;
            let (a, na) = at(i, k);
            let (b, nb) = at(i, k1);
            let (c, nc) = at(i + 1, k1);
            let (d, nd) = at(i + 1, k);
            // outward winding: counter-clockwise seen from outside
            for tri in [
                Triangle { p: [a, c, b], n: Some([na, nc, nb]), uv },
                Triangle { p: [a, d, c], n: Some([na, nd, nc]), uv },
            ] {
                if tri.geometric_normal().length_squared() > 0.0 {
                    out.push(tri);
                }
            }
        }
    }
    for (i, down) in [(0usize, true), (m - 1, false)] {
        let [r, y] = profile[i];
        if r <= 0.0 {
            continue;
        }
        let centre = Vec3::new(0.0, y, 0.0);
        let normal = if down { -Vec3::Y } else { Vec3::Y };
        for k in 0..n {
            let (a, _) = at(i, k);
            let (b, _) = at(i, (k + 1) % n);
            let mut tri = Triangle { p: [centre, a, b], n: Some([normal; 3]), uv };
            if tri.geometric_normal().dot(normal) < 0.0 {
                tri.p.swap(1, 2);
            }
            out.push(tri);
        }
    }
    out
}

pub fn tube(path: &[Vec3], radii: &[f32], segments: u32) -> Vec<Triangle> {
    let n = segments.max(3) as usize;
    let m = path.len();
    let mut rings: Vec<Vec<(Vec3, Vec3)>> = Vec::with_capacity(m);
    let mut prev_side = Vec3::ZERO;
    for i in 0..m {
        let tangent = if i == 0 {
            path[1] - path[0]
        } else if i == m - 1 {
            path[m - 1] - path[m - 2]
        } else {
            path[i + 1] - path[i - 1]
        }
        .normalize();
        let mut side = if i == 0 { tangent.any_orthonormal_vector() } else { prev_side };
        side = (side - tangent * side.dot(tangent)).normalize();
        prev_side = side;
        let up = tangent.cross(side);
        let ring = (0..n)
            .map(|k| {
                let a = 2.0 * PI * k as f32 / n as f32;
                let d = side * a.cos() + up * a.sin();
                (path[i] + d * radii[i], d)
            })
            .collect();
        rings.push(ring);
    }
    let mut out = Vec::new();
    for i in 0..m - 1 {
        for k in 0..n {
            let k1 = (k + 1) % n;
            let (a, na) = rings[i][k];
            let (b, nb) = rings[i][k1];
            let (c, nc) = rings[i + 1][k1];
            let (d, nd) = rings[i + 1][k];
            let uv = [Vec2::ZERO; 3];
            out.push(Triangle { p: [a, b, c], n: Some([na, nb, nc]), uv });
            out.push(Triangle { p: [a, c, d], n: Some([na, nc, nd]), uv });
        }
    }
    for (i, outward) in [(0usize, path[0] - path[1]), (m - 1, path[m - 1] - path[m - 2])] {
        let c = path[i];
        for k in 0..n {
            let k1 = (k + 1) % n;
            let (a, _) = rings[i][k];
            let (b, _) = rings[i][k1];
            let mut tri = Triangle { p: [c, a, b], n: None, uv: [Vec2::ZERO; 3] };
            if tri.geometric_normal().dot(outward) < 0.0 {
                tri.p.swap(1, 2);
            }
            out.push(tri);
        }
    }
    // make winding consistent with outward normals
    for t in out.iter_mut() {
        if let Some(ns) = t.n {
            let avg = ns[0] + ns[1] + ns[2];
            if t.geometric_normal().dot(avg) < 0.0 {
                t.p.swap(1, 2);
                t.uv.swap(1, 2);
                t.n = Some([ns[0], ns[2], ns[1]]);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Volume by the divergence theorem: positive when every triangle faces outward.
    fn volume(tris: &[Triangle]) -> f32 {
        tris.iter().map(|t| t.p[0].dot(t.p[1].cross(t.p[2])) / 6.0).sum()
    }

    #[test]
    fn a_lathe_is_closed_faces_outward_and_has_the_turned_volume() {
        // a cylinder of radius 0.1 and height 0.2 (capped), and a sphere of radius 0.1 (poles)
        let cylinder = lathe(&[[0.1, 0.0], [0.1, 0.2]], 256);
        let v = volume(&cylinder);
        let exact = std::f32::consts::PI * 0.01 * 0.2;
        assert!((v / exact - 1.0).abs() < 1e-3, "cylinder volume {v} against {exact}");
        let profile: Vec<[f32; 2]> = (0..=200)
            .map(|i| {
                let t = std::f32::consts::PI * i as f32 / 200.0;
                [0.1 * t.sin(), 0.1 - 0.1 * t.cos()]
            })
            .collect();
        let sphere = lathe(&profile, 256);
        let exact = 4.0 / 3.0 * std::f32::consts::PI * 1e-3;
        assert!((volume(&sphere) / exact - 1.0).abs() < 2e-3, "sphere volume {}", volume(&sphere));
        // every edge shared by exactly two triangles (watertight), in opposite directions
        let key = |p: Vec3| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
        let mut edges = std::collections::HashMap::new();
        for t in &cylinder {
            for e in 0..3 {
                *edges.entry((key(t.p[e]), key(t.p[(e + 1) % 3]))).or_insert(0) += 1;
            }
        }
        for ((a, b), count) in &edges {
            assert_eq!(*count, 1, "edge used twice in one direction");
            assert_eq!(edges.get(&(*b, *a)), Some(&1), "an open edge");
        }
        // smooth normals agree with the sphere's radial direction
        for t in &sphere {
            for k in 0..3 {
                let radial = (t.p[k] - Vec3::new(0.0, 0.1, 0.0)).normalize();
                assert!(t.n.unwrap()[k].dot(radial) > 0.999, "{:?}", t.n.unwrap()[k]);
            }
        }
    }
}
