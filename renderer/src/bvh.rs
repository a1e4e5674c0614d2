//! A bounding volume hierarchy over [`Primitive`]s for the reference path tracer.
//!
//! Built top-down as a binary tree with a binned surface-area heuristic (16 bins, leaves of at
//! most 4 primitives; a node of 2–4 is split again where its cost in packet and sphere tests
//! says so, so that a floor and the spheres standing on it, or a room's walls, do not share
//! one box that nearly every ray enters), then collapsed into a tree of four-wide nodes (each
//! binary node pulls up its grandchildren, largest surface area first, until it has four
//! children), as Embree and Mitsuba's CPU back end do. A ray tests a node's four child boxes at once and a leaf's
//! triangles four at a time (SIMD lanes through the `wide` crate: SSE on x86-64), with the
//! triangles' edges precomputed; analytic spheres are tested one by one. Every lane does the
//! scalar Möller–Trumbore arithmetic in the scalar order (no fused multiply-add), so a hit's
//! distance and barycentrics are bit-for-bit those of [`Primitive::intersect_t`], and the
//! nearest hit does not depend on the traversal order except between exactly equal distances.
//! Written here rather than taken from a crate because the tracer needs mixed triangles and
//! analytic spheres with per-primitive payloads; tested against brute force.

use crate::geometry::{Aabb, Primitive, Ray};
use glam::Vec3;
use wide::f32x4;

const BINS: usize = 16;
const MAX_LEAF: usize = 4;
/// Triangles per SIMD packet test ([`Tri4`]).
const PACKET: usize = 4;

/// A node of the binary tree the builder makes (and the four-wide tree is collapsed from).
#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    /// Leaf: first primitive; interior: index of the second child (the first is next).
    offset: u32,
    /// Leaf: primitive count (> 0); interior: 0.
    count: u32,
}

/// A child slot of a four-wide node: an inner node's index, or [`LEAF`] | a leaf's index.
const LEAF: u32 = 1 << 31;
/// An unused child slot.
const NONE: u32 = u32::MAX;

/// Four child boxes in structure-of-arrays form.
#[derive(Clone, Copy, Debug)]
struct Node4 {
    lo: [f32x4; 3],
    hi: [f32x4; 3],
    child: [u32; 4],
}

/// A leaf: its triangle packets and spheres (ranges into `Bvh::tris` and `Bvh::spheres`).
#[derive(Clone, Copy, Debug)]
struct Leaf {
    tris: (u32, u32),
    spheres: (u32, u32),
}

/// Up to four triangles: first vertex and the two edges from it, per lane. An unused lane has
/// zero edges, so its determinant is zero and it is never hit.
#[derive(Clone, Copy, Debug)]
struct Tri4 {
    v0: [f32x4; 3],
    e1: [f32x4; 3],
    e2: [f32x4; 3],
    prim: [u32; 4],
}

#[derive(Clone, Copy, Debug)]
struct SphereRec {
    center: Vec3,
    radius: f32,
    prim: u32,
}

/// The acceleration structure. Primitives are reordered on build; `payload[i]` travels with
/// primitive `i`.
#[derive(Clone, Debug)]
pub struct Bvh<P: Clone> {
    nodes: Vec<Node4>,
    leaves: Vec<Leaf>,
    tris: Vec<Tri4>,
    spheres: Vec<SphereRec>,
    /// The deepest traversal stack a ray can need: each level pops one entry and pushes at
    /// most four.
    stack_need: usize,
    pub prims: Vec<Primitive>,
    pub payload: Vec<P>,
}

/// The nearest hit: the primitive index (into `prims`) and ray parameters.
#[derive(Clone, Copy, Debug)]
pub struct BvhHit {
    pub prim: usize,
    pub t: f32,
    pub u: f32,
    pub v: f32,
}

/// A ray splatted across four lanes, with a finite reciprocal direction (a zero component
/// becomes ±1e-30 before the reciprocal, so a box slab the origin lies on gives 0, never NaN).
struct Ray4 {
    o: [f32x4; 3],
    d: [f32x4; 3],
    inv: [f32x4; 3],
}

impl Ray4 {
    #[inline]
    fn new(ray: &Ray) -> Ray4 {
        let inv = |d: f32| {
            let d = if d.abs() < 1e-30 { 1e-30f32.copysign(d) } else { d };
            f32x4::splat(1.0 / d)
        };
        Ray4 {
            o: [f32x4::splat(ray.origin.x), f32x4::splat(ray.origin.y), f32x4::splat(ray.origin.z)],
            d: [f32x4::splat(ray.dir.x), f32x4::splat(ray.dir.y), f32x4::splat(ray.dir.z)],
            inv: [inv(ray.dir.x), inv(ray.dir.y), inv(ray.dir.z)],
        }
    }
}

impl Node4 {
    /// Which of the four boxes the ray enters within [0, t_max] (a bit per lane), and where.
    #[inline(always)]
    fn hit(&self, r: &Ray4, t_max: f32) -> (u32, [f32; 4]) {
        let tx0 = (self.lo[0] - r.o[0]) * r.inv[0];
        let tx1 = (self.hi[0] - r.o[0]) * r.inv[0];
        let ty0 = (self.lo[1] - r.o[1]) * r.inv[1];
        let ty1 = (self.hi[1] - r.o[1]) * r.inv[1];
        let tz0 = (self.lo[2] - r.o[2]) * r.inv[2];
        let tz1 = (self.hi[2] - r.o[2]) * r.inv[2];
        let near = tx0.fast_min(tx1).fast_max(ty0.fast_min(ty1)).fast_max(tz0.fast_min(tz1).fast_max(f32x4::ZERO));
        let far =
            tx0.fast_max(tx1).fast_min(ty0.fast_max(ty1)).fast_min(tz0.fast_max(tz1).fast_min(f32x4::splat(t_max)));
        (near.simd_le(far).to_bitmask(), near.to_array())
    }
}

impl Tri4 {
    /// Möller–Trumbore on four lanes: a bit per lane hit in (t_min, t_max), and t, u, v.
    #[inline(always)]
    fn hit(&self, r: &Ray4, t_min: f32, t_max: f32) -> (u32, [f32; 4], [f32; 4], [f32; 4]) {
        let [dx, dy, dz] = r.d;
        let [e1x, e1y, e1z] = self.e1;
        let [e2x, e2y, e2z] = self.e2;
        // pvec = dir × e2, in glam's order
        let px = dy * e2z - e2y * dz;
        let py = dz * e2x - e2z * dx;
        let pz = dx * e2y - e2x * dy;
        let det = e1x * px + e1y * py + e1z * pz;
        let mut ok = det.abs().simd_ge(f32x4::splat(1e-12));
        let inv = f32x4::ONE / det;
        let tx = r.o[0] - self.v0[0];
        let ty = r.o[1] - self.v0[1];
        let tz = r.o[2] - self.v0[2];
        let u = (tx * px + ty * py + tz * pz) * inv;
        ok &= u.simd_ge(f32x4::ZERO) & u.simd_le(f32x4::ONE);
        // qvec = tvec × e1
        let qx = ty * e1z - e1y * tz;
        let qy = tz * e1x - e1z * tx;
        let qz = tx * e1y - e1x * ty;
        let v = (dx * qx + dy * qy + dz * qz) * inv;
        ok &= v.simd_ge(f32x4::ZERO) & (u + v).simd_le(f32x4::ONE);
        let t = (e2x * qx + e2y * qy + e2z * qz) * inv;
        ok &= t.simd_gt(f32x4::splat(t_min)) & t.simd_lt(f32x4::splat(t_max));
        (ok.to_bitmask(), t.to_array(), u.to_array(), v.to_array())
    }
}

/// The scalar ray–sphere test of [`Primitive::intersect_t`].
#[inline(always)]
fn sphere_hit(s: &SphereRec, ray: &Ray, t_min: f32, t_max: f32) -> Option<f32> {
    let oc = ray.origin - s.center;
    let a = ray.dir.length_squared();
    let half_b = oc.dot(ray.dir);
    let c = oc.length_squared() - s.radius * s.radius;
    let disc = half_b * half_b - a * c;
    if disc < 0.0 {
        return None;
    }
    let sq = disc.sqrt();
    let t0 = (-half_b - sq) / a;
    if t0 > t_min && t0 < t_max {
        return Some(t0);
    }
    let t1 = (-half_b + sq) / a;
    if t1 > t_min && t1 < t_max { Some(t1) } else { None }
}

/// Entries of the traversal stack kept on the call stack; a deeper tree (rare: [`Bvh::stack_need`]
/// says) traverses with a heap stack. Zeroing a fixed 2 KB stack per ray cost 4 % of the path
/// tracer's time, and unsafe code is not allowed here.
const SHORT_STACK: usize = 32;

/// A traversal stack over a slice (bounds-checked: too deep a tree panics, it does not corrupt).
struct Stack<'a, T: Copy> {
    slots: &'a mut [T],
    len: usize,
}

impl<'a, T: Copy> Stack<'a, T> {
    #[inline(always)]
    fn new(slots: &'a mut [T], first: T) -> Self {
        slots[0] = first;
        Stack { slots, len: 1 }
    }
    #[inline(always)]
    fn push(&mut self, value: T) {
        self.slots[self.len] = value;
        self.len += 1;
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        Some(self.slots[self.len])
    }
}

impl<P: Clone> Bvh<P> {
    pub fn build(prims: Vec<Primitive>, payload: Vec<P>) -> Self {
        assert_eq!(prims.len(), payload.len());
        let n = prims.len();
        let bounds: Vec<Aabb> = prims.iter().map(|p| p.bounds()).collect();
        let centroids: Vec<glam::Vec3> = bounds.iter().map(|b| b.centroid()).collect();
        let mut order: Vec<usize> = (0..n).collect();
        let mut binary = Vec::with_capacity(2 * n.max(1));
        if n > 0 {
            let sphere: Vec<bool> = prims.iter().map(|p| matches!(p, Primitive::Sphere { .. })).collect();
            build_rec(&mut binary, &mut order, 0, n, &bounds, &centroids, &sphere);
        }
        let prims: Vec<Primitive> = order.iter().map(|&i| prims[i].clone()).collect();
        let payload = order.iter().map(|&i| payload[i].clone()).collect();
        let mut bvh = Bvh {
            nodes: Vec::new(),
            leaves: Vec::new(),
            tris: Vec::new(),
            spheres: Vec::new(),
            stack_need: 1,
            prims,
            payload,
        };
        if n > 0 {
            bvh.collapse(&binary, 0);
            bvh.stack_need = 1 + 3 * bvh.depth(0);
        }
        bvh
    }

    pub fn is_empty(&self) -> bool {
        self.prims.is_empty()
    }

    /// Levels of four-wide nodes below and including `node`.
    fn depth(&self, node: u32) -> usize {
        1 + self.nodes[node as usize]
            .child
            .iter()
            .filter(|&&c| c != NONE && c & LEAF == 0)
            .map(|&c| self.depth(c))
            .max()
            .unwrap_or(0)
    }

    /// Makes the four-wide node for binary node `idx` (a leaf becomes a node with one child)
    /// and returns its index.
    fn collapse(&mut self, binary: &[Node], idx: u32) -> u32 {
        let mut kids: Vec<u32> = match binary[idx as usize].count {
            0 => vec![idx + 1, binary[idx as usize].offset],
            _ => vec![idx],
        };
        while kids.len() < 4 {
            let widest = kids
                .iter()
                .enumerate()
                .filter(|(_, k)| binary[**k as usize].count == 0)
                .max_by(|a, b| binary[*a.1 as usize].bounds.area().total_cmp(&binary[*b.1 as usize].bounds.area()))
                .map(|(i, _)| i);
            let Some(i) = widest else { break };
            let k = kids[i];
            kids[i] = k + 1;
            kids.insert(i + 1, binary[k as usize].offset);
        }
        let index = self.nodes.len() as u32;
        let inf = f32x4::splat(f32::INFINITY);
        self.nodes.push(Node4 { lo: [inf; 3], hi: [-inf; 3], child: [NONE; 4] });
        let mut lo = [[f32::INFINITY; 4]; 3];
        let mut hi = [[f32::NEG_INFINITY; 4]; 3];
        let mut child = [NONE; 4];
        for (lane, &k) in kids.iter().enumerate() {
            let node = binary[k as usize];
            // padded outward by a relative 2^-20 of the box's largest coordinate: a ray along
            // an axis whose origin lies exactly on a face (a zero direction component, a slab
            // distance of zero) is then inside the slab rather than on its edge, and a box
            // only ever grows (the primitive tests decide hits)
            let scale = node.bounds.min.abs().max(node.bounds.max.abs()).max_element();
            let pad = scale * (1.0 / (1 << 20) as f32) + f32::MIN_POSITIVE;
            for axis in 0..3 {
                lo[axis][lane] = node.bounds.min[axis] - pad;
                hi[axis][lane] = node.bounds.max[axis] + pad;
            }
            child[lane] = match node.count {
                0 => self.collapse(binary, k),
                count => LEAF | self.leaf(node.offset as usize, count as usize),
            };
        }
        self.nodes[index as usize] = Node4 { lo: lo.map(f32x4::from), hi: hi.map(f32x4::from), child };
        index
    }

    /// Packs primitives `first .. first + count` into a leaf and returns its index.
    fn leaf(&mut self, first: usize, count: usize) -> u32 {
        let tris_start = self.tris.len() as u32;
        let spheres_start = self.spheres.len() as u32;
        let mut lanes: Vec<(u32, [Vec3; 3])> = Vec::new();
        for i in first..first + count {
            match &self.prims[i] {
                Primitive::Triangle(t) => lanes.push((i as u32, [t.p[0], t.p[1] - t.p[0], t.p[2] - t.p[0]])),
                Primitive::Sphere { center, radius } => {
                    self.spheres.push(SphereRec { center: *center, radius: *radius, prim: i as u32 })
                }
            }
        }
        for chunk in lanes.chunks(PACKET) {
            let mut v = [[[0.0f32; 4]; 3]; 3];
            let mut prim = [NONE; 4];
            for (lane, (i, vecs)) in chunk.iter().enumerate() {
                prim[lane] = *i;
                for (which, vec) in vecs.iter().enumerate() {
                    for axis in 0..3 {
                        v[which][axis][lane] = vec[axis];
                    }
                }
            }
            let [v0, e1, e2] = v.map(|m| m.map(f32x4::from));
            self.tris.push(Tri4 { v0, e1, e2, prim });
        }
        self.leaves.push(Leaf {
            tris: (tris_start, self.tris.len() as u32),
            spheres: (spheres_start, self.spheres.len() as u32),
        });
        (self.leaves.len() - 1) as u32
    }

    /// Nearest intersection in (t_min, t_max).
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<BvhHit> {
        if self.nodes.is_empty() {
            return None;
        }
        if self.stack_need <= SHORT_STACK {
            self.intersect_with(&mut [(0, 0.0); SHORT_STACK], ray, t_min, t_max)
        } else {
            self.intersect_with(&mut vec![(0, 0.0); self.stack_need], ray, t_min, t_max)
        }
    }

    #[inline(always)]
    fn intersect_with(&self, slots: &mut [(u32, f32)], ray: &Ray, t_min: f32, mut t_max: f32) -> Option<BvhHit> {
        let r = Ray4::new(ray);
        let mut best: Option<BvhHit> = None;
        let mut stack = Stack::new(slots, (0u32, 0f32));
        while let Some((code, near)) = stack.pop() {
            if near > t_max {
                continue;
            }
            if code & LEAF != 0 {
                let leaf = self.leaves[(code & !LEAF) as usize];
                for packet in &self.tris[leaf.tris.0 as usize..leaf.tris.1 as usize] {
                    let (mut mask, t, u, v) = packet.hit(&r, t_min, t_max);
                    while mask != 0 {
                        let lane = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        if t[lane] < t_max {
                            t_max = t[lane];
                            best =
                                Some(BvhHit { prim: packet.prim[lane] as usize, t: t[lane], u: u[lane], v: v[lane] });
                        }
                    }
                }
                for s in &self.spheres[leaf.spheres.0 as usize..leaf.spheres.1 as usize] {
                    if let Some(t) = sphere_hit(s, ray, t_min, t_max) {
                        t_max = t;
                        best = Some(BvhHit { prim: s.prim as usize, t, u: 0.0, v: 0.0 });
                    }
                }
                continue;
            }
            let node = &self.nodes[code as usize];
            let (mut mask, dist) = node.hit(&r, t_max);
            // push the entered children far to near, so the nearest is popped first
            let mut kids = [(0u32, 0f32); 4];
            let mut n = 0;
            while mask != 0 {
                let lane = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if node.child[lane] == NONE {
                    continue;
                }
                let entry = (node.child[lane], dist[lane]);
                let mut j = n;
                while j > 0 && kids[j - 1].1 < entry.1 {
                    kids[j] = kids[j - 1];
                    j -= 1;
                }
                kids[j] = entry;
                n += 1;
            }
            for kid in &kids[..n] {
                stack.push(*kid);
            }
        }
        best
    }

    /// Whether anything intersects in (t_min, t_max).
    pub fn occluded(&self, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        if self.stack_need <= SHORT_STACK {
            self.occluded_with(&mut [0; SHORT_STACK], ray, t_min, t_max)
        } else {
            self.occluded_with(&mut vec![0; self.stack_need], ray, t_min, t_max)
        }
    }

    #[inline(always)]
    fn occluded_with(&self, slots: &mut [u32], ray: &Ray, t_min: f32, t_max: f32) -> bool {
        let r = Ray4::new(ray);
        let mut stack = Stack::new(slots, 0u32);
        while let Some(code) = stack.pop() {
            if code & LEAF != 0 {
                let leaf = self.leaves[(code & !LEAF) as usize];
                for packet in &self.tris[leaf.tris.0 as usize..leaf.tris.1 as usize] {
                    if packet.hit(&r, t_min, t_max).0 != 0 {
                        return true;
                    }
                }
                for s in &self.spheres[leaf.spheres.0 as usize..leaf.spheres.1 as usize] {
                    if sphere_hit(s, ray, t_min, t_max).is_some() {
                        return true;
                    }
                }
                continue;
            }
            let node = &self.nodes[code as usize];
            let mut mask = node.hit(&r, t_max).0;
            while mask != 0 {
                let lane = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if node.child[lane] != NONE {
                    stack.push(node.child[lane]);
                }
            }
        }
        false
    }
}

/// The cost of testing a small leaf, in primitive tests: its triangles four to a packet test,
/// its spheres one test each.
fn packet_cost(triangles: usize, spheres: usize) -> f32 {
    triangles.div_ceil(PACKET) as f32 + spheres as f32
}

/// The cost of a box test in the same units, for splitting a small node: a split becomes one
/// lane of a four-wide node's box test, about half a triangle packet's arithmetic. (The
/// Cornell box's tree is the same for any value from 0 to 1.0 and the old one from 1.1 up;
/// 0.5 keeps clear of that edge.)
const TRAVERSAL_COST: f32 = 0.5;

/// Builds the binary node over `order[start..end]` and below and returns its index: split by
/// a binned surface-area heuristic along the centroids' widest axis, counting primitives,
/// down to at most [`MAX_LEAF`] primitives (a node of up to twice that stays a leaf where no
/// split is cheaper); then a node of two to [`MAX_LEAF`] primitives is split again where its
/// packet tests and box test cost less than its own packet tests — a floor and the spheres
/// on it, a room's walls, which would otherwise share one large box that most rays enter.
fn build_rec(
    nodes: &mut Vec<Node>,
    order: &mut [usize],
    start: usize,
    end: usize,
    bounds: &[Aabb],
    centroids: &[glam::Vec3],
    sphere: &[bool],
) -> u32 {
    let node_idx = nodes.len() as u32;
    let mut bb = Aabb::EMPTY;
    let mut cb = Aabb::EMPTY;
    let mut spheres = 0;
    for &i in &order[start..end] {
        bb = bb.union(&bounds[i]);
        cb.grow(centroids[i]);
        spheres += sphere[i] as usize;
    }
    nodes.push(Node { bounds: bb, offset: start as u32, count: (end - start) as u32 });
    let n = end - start;
    if n == 1 {
        return node_idx;
    }
    let extent = cb.max - cb.min;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let (lo, span) = (cb.min[axis], extent[axis]);
    let bin_of = |c: f32| (((c - lo) / span * BINS as f32) as usize).min(BINS - 1);
    let small = n <= MAX_LEAF;
    // the cheapest split: (cost, first bin on the right)
    let mut best: Option<(f32, usize)> = None;
    if span > 1e-12 {
        let mut bin_b = [Aabb::EMPTY; BINS];
        // triangles and spheres per bin
        let mut bin_n = [(0usize, 0usize); BINS];
        for &i in &order[start..end] {
            let b = bin_of(centroids[i][axis]);
            bin_b[b] = bin_b[b].union(&bounds[i]);
            match sphere[i] {
                true => bin_n[b].1 += 1,
                false => bin_n[b].0 += 1,
            }
        }
        let side = |bins: std::ops::Range<usize>| {
            bins.fold((Aabb::EMPTY, 0, 0), |(b, t, s), k| (b.union(&bin_b[k]), t + bin_n[k].0, s + bin_n[k].1))
        };
        for split in 1..BINS {
            let (lb, lt, ls) = side(0..split);
            let (rb, rt, rs) = side(split..BINS);
            if lt + ls == 0 || rt + rs == 0 {
                continue;
            }
            let cost = match small {
                true => lb.area() * packet_cost(lt, ls) + rb.area() * packet_cost(rt, rs),
                false => lb.area() * (lt + ls) as f32 + rb.area() * (rt + rs) as f32,
            };
            if best.is_none_or(|(c, _)| cost < c) {
                best = Some((cost, split));
            }
        }
    }
    let stays_leaf = match (small, best) {
        (true, None) => true,
        (true, Some((cost, _))) => cost + TRAVERSAL_COST * bb.area() >= bb.area() * packet_cost(n - spheres, spheres),
        (false, Some((cost, _))) => cost >= bb.area() * n as f32 && n <= 2 * MAX_LEAF,
        (false, None) => false,
    };
    if stays_leaf {
        return node_idx;
    }
    let mut mid = match best {
        Some((_, split)) => {
            let slice = &mut order[start..end];
            let mut left = 0;
            for k in 0..slice.len() {
                if bin_of(centroids[slice[k]][axis]) < split {
                    slice.swap(left, k);
                    left += 1;
                }
            }
            start + left
        }
        // every centroid in one plane across the axis (no split has two sides): halves
        None => start + n / 2,
    };
    if mid == start || mid == end {
        mid = start + n / 2;
    }
    nodes[node_idx as usize].count = 0;
    build_rec(nodes, order, start, mid, bounds, centroids, sphere);
    let right = build_rec(nodes, order, mid, end, bounds, centroids, sphere);
    nodes[node_idx as usize].offset = right;
    node_idx
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Triangle;
    use crate::math::{Rng, sample_uniform_sphere};
    use glam::{Vec2, Vec3};

    #[test]
    fn bvh_matches_brute_force() {
        let mut rng = Rng::new(7);
        let mut prims = Vec::new();
        for _ in 0..300 {
            let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0 - 2.0;
            if rng.next_f32() < 0.2 {
                prims.push(Primitive::Sphere { center: c, radius: 0.1 * rng.next_f32() + 0.01 });
            } else {
                let d = |r: &mut Rng| Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) * 0.4 - 0.2;
                let p = [c + d(&mut rng), c + d(&mut rng), c + d(&mut rng)];
                prims.push(Primitive::Triangle(Triangle { p, n: None, uv: [Vec2::ZERO; 3] }));
            }
        }
        let payload: Vec<usize> = (0..prims.len()).collect();
        let bvh = Bvh::build(prims.clone(), payload);
        for _ in 0..2000 {
            let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0 - 3.0;
            let d = sample_uniform_sphere(rng.next_f32(), rng.next_f32());
            let ray = Ray { origin: o, dir: d };
            let brute = prims
                .iter()
                .enumerate()
                .filter_map(|(i, p)| p.intersect_t(&ray, 1e-4, f32::INFINITY).map(|h| (i, h.0)))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let got = bvh.intersect(&ray, 1e-4, f32::INFINITY);
            match (brute, got) {
                (None, None) => {}
                (Some((i, t)), Some(h)) => {
                    assert!((t - h.t).abs() < 1e-5, "t {t} vs {}", h.t);
                    assert_eq!(bvh.payload[h.prim], i);
                }
                (a, b) => panic!("brute {a:?} bvh {b:?}"),
            }
            assert_eq!(bvh.occluded(&ray, 1e-4, f32::INFINITY), brute.is_some());
        }
    }

    /// Brute force over `prims`: the nearest (index, t) in (1e-4, ∞).
    fn brute(prims: &[Primitive], ray: &Ray) -> Option<(usize, f32)> {
        prims
            .iter()
            .enumerate()
            .filter_map(|(i, p)| p.intersect_t(ray, 1e-4, f32::INFINITY).map(|h| (i, h.0)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    fn tri(a: Vec3, b: Vec3, c: Vec3) -> Primitive {
        Primitive::Triangle(Triangle { p: [a, b, c], n: None, uv: [Vec2::ZERO; 3] })
    }

    #[test]
    fn axis_aligned_rays_on_box_planes_hit_what_brute_force_hits() {
        // a grid of unit quads in the planes z = 0, 1, 2, 3 and rays along the axes whose
        // origins lie exactly on slab planes of the boxes (a zero direction component)
        let mut prims = Vec::new();
        for z in 0..4 {
            for x in 0..3 {
                for y in 0..3 {
                    let (x, y, z) = (x as f32, y as f32, z as f32);
                    prims.push(tri(Vec3::new(x, y, z), Vec3::new(x + 1.0, y, z), Vec3::new(x + 1.0, y + 1.0, z)));
                    prims.push(tri(Vec3::new(x, y, z), Vec3::new(x + 1.0, y + 1.0, z), Vec3::new(x, y + 1.0, z)));
                }
            }
        }
        let bvh = Bvh::build(prims.clone(), (0..prims.len()).collect::<Vec<_>>());
        let mut checked = 0;
        for &(ox, oy) in &[(0.5f32, 0.5f32), (1.0, 1.0), (0.0, 0.0), (2.25, 1.0), (3.0, 3.0), (1.5, 0.0)] {
            for &dir in &[Vec3::Z, -Vec3::Z] {
                let origin = Vec3::new(ox, oy, if dir.z > 0.0 { -1.0 } else { 4.0 });
                let ray = Ray { origin, dir };
                let got = bvh.intersect(&ray, 1e-4, f32::INFINITY);
                match (brute(&prims, &ray), got) {
                    (None, None) => {}
                    (Some((_, t)), Some(h)) => {
                        assert_eq!(t, h.t, "ray {ray:?}");
                        checked += 1;
                    }
                    (a, b) => panic!("ray {ray:?}: brute {a:?} bvh {b:?}"),
                }
            }
            // along x inside the plane z = 1 (parallel to every triangle: no hit)
            let ray = Ray { origin: Vec3::new(-1.0, oy, 1.0), dir: Vec3::X };
            assert_eq!(bvh.intersect(&ray, 1e-4, f32::INFINITY).is_some(), brute(&prims, &ray).is_some());
        }
        assert!(checked >= 8, "only {checked} rays hit");
        // no NaN ray ever hits
        let nan = Ray { origin: Vec3::ZERO, dir: Vec3::new(f32::NAN, 0.0, 1.0) };
        assert!(bvh.intersect(&nan, 1e-4, f32::INFINITY).is_none());
        assert!(!bvh.occluded(&nan, 1e-4, f32::INFINITY));
    }

    #[test]
    fn a_deep_tree_traverses_with_a_heap_stack_and_stays_exact() {
        // triangles at positions growing 17-fold (from 1e-12, above the builder's median-split
        // span, below where surface areas overflow): the binned SAH splits one off per level, so
        // the tree is far deeper than the short stack allows
        let x = |i: i32| (1e-12f64 * 17f64.powi(i)) as f32;
        let prims: Vec<Primitive> = (0..38)
            .map(|i| tri(Vec3::new(x(i), -1.0, -1.0), Vec3::new(x(i), 1.0, -1.0), Vec3::new(x(i), 0.0, 1.0)))
            .collect();
        let bvh = Bvh::build(prims.clone(), vec![(); prims.len()]);
        assert!(bvh.stack_need > SHORT_STACK, "stack need {} (the test needs a deep tree)", bvh.stack_need);
        let mut rng = Rng::new(11);
        let mut hits = 0;
        for _ in 0..500 {
            let k = (rng.next_f32() * 37.0) as i32;
            let origin = Vec3::new(x(k) * 4.0, rng.next_f32() * 0.5 - 0.25, rng.next_f32() * 0.5 - 0.25);
            let dir = if rng.next_f32() < 0.5 { Vec3::X } else { -Vec3::X };
            let ray = Ray { origin, dir };
            let got = bvh.intersect(&ray, 0.0, f32::INFINITY);
            let want = bvh
                .prims
                .iter()
                .filter_map(|p| p.intersect_t(&ray, 0.0, f32::INFINITY))
                .map(|h| h.0)
                .min_by(f32::total_cmp);
            assert_eq!(got.map(|h| h.t), want, "ray {ray:?}");
            if let Some(h) = got {
                // several tiny distances can round to the same t; the named one must hit there
                assert_eq!(bvh.prims[h.prim].intersect_t(&ray, 0.0, f32::INFINITY).map(|h| h.0), want);
                hits += 1;
            }
            assert_eq!(bvh.occluded(&ray, 0.0, f32::INFINITY), want.is_some());
        }
        assert!(hits > 200, "only {hits} hits");
    }

    /// Triangles per packet, over all packets.
    fn packet_fill<P: Clone>(bvh: &Bvh<P>) -> f32 {
        let lanes: usize = bvh.tris.iter().map(|t| t.prim.iter().filter(|&&p| p != NONE).count()).sum();
        lanes as f32 / bvh.tris.len() as f32
    }

    #[test]
    fn a_floors_spheres_get_leaves_of_their_own_and_a_dense_mesh_keeps_full_packets() {
        // a 2 × 2 floor and two spheres standing on it: one leaf of four would be a box over the
        // whole floor, entered by every ray that reaches the floor, each paying both spheres' tests
        let (a, b, c, d) = (
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(-1.0, 0.0, 1.0),
        );
        let prims = vec![
            tri(a, b, c),
            tri(a, c, d),
            Primitive::Sphere { center: Vec3::new(-0.4, 0.35, -0.3), radius: 0.35 },
            Primitive::Sphere { center: Vec3::new(0.45, 0.25, 0.2), radius: 0.25 },
        ];
        let bvh = Bvh::build(prims, vec![(); 4]);
        assert!(bvh.leaves.len() >= 2, "one leaf for the floor and its spheres");
        for leaf in &bvh.leaves {
            assert!(
                leaf.tris.0 == leaf.tris.1 || leaf.spheres.0 == leaf.spheres.1,
                "a leaf mixes the floor and a sphere: {leaf:?}"
            );
        }
        // a turned mesh: its leaves stay packets of about four triangles
        let mesh = crate::geometry::lathe(&[[0.0, 0.0], [0.5, 0.1], [0.3, 0.6], [0.45, 1.0], [0.0, 1.1]], 128);
        let prims: Vec<Primitive> = mesh.into_iter().map(Primitive::Triangle).collect();
        let n = prims.len();
        let bvh = Bvh::build(prims, vec![(); n]);
        assert!(packet_fill(&bvh) > 3.0, "{} triangles per packet", packet_fill(&bvh));
    }

    #[test]
    fn a_large_mesh_matches_brute_force_and_an_empty_one_hits_nothing() {
        let mesh = crate::geometry::lathe(&[[0.0, 0.0], [0.5, 0.1], [0.3, 0.6], [0.45, 1.0], [0.0, 1.1]], 128);
        let prims: Vec<Primitive> = mesh.into_iter().map(Primitive::Triangle).collect();
        assert!(prims.len() > 400);
        let bvh = Bvh::build(prims.clone(), (0..prims.len()).collect::<Vec<_>>());
        let mut rng = Rng::new(5);
        let mut hits = 0;
        for _ in 0..1500 {
            let o = Vec3::new(rng.next_f32() * 3.0 - 1.5, rng.next_f32() * 2.0 - 0.5, rng.next_f32() * 3.0 - 1.5);
            let d = sample_uniform_sphere(rng.next_f32(), rng.next_f32());
            let ray = Ray { origin: o, dir: d };
            let got = bvh.intersect(&ray, 1e-4, f32::INFINITY).map(|h| (bvh.payload[h.prim], h.t));
            let want = brute(&prims, &ray);
            match (want, got) {
                (None, None) => {}
                (Some((i, t)), Some((j, u))) => {
                    assert_eq!(t, u, "ray {ray:?}");
                    // equal distances (a shared edge) may name either triangle
                    assert!(i == j || prims[j].intersect_t(&ray, 1e-4, f32::INFINITY).map(|h| h.0) == Some(t));
                    hits += 1;
                }
                (a, b) => panic!("ray {ray:?}: brute {a:?} bvh {b:?}"),
            }
            assert_eq!(bvh.occluded(&ray, 1e-4, f32::INFINITY), want.is_some());
        }
        assert!(hits > 100, "only {hits} hits");
        let empty: Bvh<()> = Bvh::build(Vec::new(), Vec::new());
        assert!(empty.intersect(&Ray { origin: Vec3::ZERO, dir: Vec3::X }, 0.0, f32::INFINITY).is_none());
        assert!(!empty.occluded(&Ray { origin: Vec3::ZERO, dir: Vec3::X }, 0.0, f32::INFINITY));
    }
}
