//! A bounding volume hierarchy over [`Primitive`]s, built top-down with a binned surface-area
//! heuristic (16 bins, leaves of at most 4 primitives) and traversed with an explicit stack,
//! near child first. Written here rather than taken from a crate because the tracer needs mixed
//! triangles and analytic spheres with per-primitive payloads, and the `bvh` crate pulls in
//! nalgebra; the structure is small and tested against brute force.

use crate::geometry::{Aabb, Primitive, Ray};

const BINS: usize = 16;
const MAX_LEAF: usize = 4;

#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    /// Leaf: first primitive; interior: index of the second child (the first is next).
    offset: u32,
    /// Leaf: primitive count (> 0); interior: 0.
    count: u32,
}

/// The acceleration structure. Primitives are reordered on build; `payload[i]` travels with
/// primitive `i`.
#[derive(Clone, Debug)]
pub struct Bvh<P: Clone> {
    nodes: Vec<Node>,
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

impl<P: Clone> Bvh<P> {
    pub fn build(prims: Vec<Primitive>, payload: Vec<P>) -> Self {
        assert_eq!(prims.len(), payload.len());
        let n = prims.len();
        let bounds: Vec<Aabb> = prims.iter().map(|p| p.bounds()).collect();
        let centroids: Vec<glam::Vec3> = bounds.iter().map(|b| b.centroid()).collect();
        let mut order: Vec<usize> = (0..n).collect();
        let mut nodes = Vec::with_capacity(2 * n.max(1));
        if n > 0 {
            build_rec(&mut nodes, &mut order, 0, n, &bounds, &centroids);
        }
        let prims_sorted = order.iter().map(|&i| prims[i].clone()).collect();
        let payload_sorted = order.iter().map(|&i| payload[i].clone()).collect();
        Bvh { nodes, prims: prims_sorted, payload: payload_sorted }
    }

    pub fn is_empty(&self) -> bool {
        self.prims.is_empty()
    }

    /// Nearest intersection in (t_min, t_max).
    pub fn intersect(&self, ray: &Ray, t_min: f32, mut t_max: f32) -> Option<BvhHit> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv = ray.dir.recip();
        let mut best: Option<BvhHit> = None;
        let mut stack = [0u32; 64];
        let mut sp = 0usize;
        let mut idx = 0u32;
        self.nodes[0].bounds.hit(ray.origin, inv, t_max)?;
        loop {
            let node = &self.nodes[idx as usize];
            if node.count > 0 {
                for i in node.offset..node.offset + node.count {
                    if let Some((t, u, v)) = self.prims[i as usize].intersect_t(ray, t_min, t_max) {
                        t_max = t;
                        best = Some(BvhHit { prim: i as usize, t, u, v });
                    }
                }
            } else {
                let a = idx + 1;
                let b = node.offset;
                let ha = self.nodes[a as usize].bounds.hit(ray.origin, inv, t_max);
                let hb = self.nodes[b as usize].bounds.hit(ray.origin, inv, t_max);
                match (ha, hb) {
                    (Some(ta), Some(tb)) => {
                        let (near, far) = if ta <= tb { (a, b) } else { (b, a) };
                        stack[sp] = far;
                        sp += 1;
                        idx = near;
                        continue;
                    }
                    (Some(_), None) => {
                        idx = a;
                        continue;
                    }
                    (None, Some(_)) => {
                        idx = b;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // pop the next far child that is still closer than the best hit
            let mut next = None;
            while sp > 0 {
                sp -= 1;
                let candidate = stack[sp];
                if self.nodes[candidate as usize].bounds.hit(ray.origin, inv, t_max).is_some() {
                    next = Some(candidate);
                    break;
                }
            }
            match next {
                Some(n) => idx = n,
                None => break,
            }
        }
        best
    }

    /// Whether anything intersects in (t_min, t_max).
    pub fn occluded(&self, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let inv = ray.dir.recip();
        let mut stack = [0u32; 64];
        let mut sp = 0usize;
        stack[sp] = 0;
        sp += 1;
        while sp > 0 {
            sp -= 1;
            let node = &self.nodes[stack[sp] as usize];
            if node.bounds.hit(ray.origin, inv, t_max).is_none() {
                continue;
            }
            if node.count > 0 {
                for i in node.offset..node.offset + node.count {
                    if self.prims[i as usize].intersect_t(ray, t_min, t_max).is_some() {
                        return true;
                    }
                }
            } else {
                let current = stack[sp];
                stack[sp] = current + 1;
                stack[sp + 1] = node.offset;
                sp += 2;
            }
        }
        false
    }
}

fn build_rec(
    nodes: &mut Vec<Node>,
    order: &mut [usize],
    start: usize,
    end: usize,
    bounds: &[Aabb],
    centroids: &[glam::Vec3],
) -> u32 {
    let node_idx = nodes.len() as u32;
    let mut bb = Aabb::EMPTY;
    let mut cb = Aabb::EMPTY;
    for &i in &order[start..end] {
        bb = bb.union(&bounds[i]);
        cb.grow(centroids[i]);
    }
    nodes.push(Node { bounds: bb, offset: start as u32, count: (end - start) as u32 });
    let n = end - start;
    if n <= MAX_LEAF {
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
    let lo = cb.min[axis];
    let span = extent[axis];
    let mut mid;
    if span <= 1e-12 {
        mid = start + n / 2;
    } else {
        let mut bin_b = [Aabb::EMPTY; BINS];
        let mut bin_n = [0usize; BINS];
        let bin_of = |c: f32| (((c - lo) / span * BINS as f32) as usize).min(BINS - 1);
        for &i in &order[start..end] {
            let b = bin_of(centroids[i][axis]);
            bin_b[b] = bin_b[b].union(&bounds[i]);
            bin_n[b] += 1;
        }
        let mut best_cost = f32::INFINITY;
        let mut best_split = 1;
        for split in 1..BINS {
            let (mut lb, mut rb) = (Aabb::EMPTY, Aabb::EMPTY);
            let (mut ln, mut rn) = (0, 0);
            for b in 0..split {
                lb = lb.union(&bin_b[b]);
                ln += bin_n[b];
            }
            for b in split..BINS {
                rb = rb.union(&bin_b[b]);
                rn += bin_n[b];
            }
            if ln == 0 || rn == 0 {
                continue;
            }
            let cost = lb.area() * ln as f32 + rb.area() * rn as f32;
            if cost < best_cost {
                best_cost = cost;
                best_split = split;
            }
        }
        let leaf_cost = bb.area() * n as f32;
        if best_cost.is_finite() && best_cost >= leaf_cost && n <= 2 * MAX_LEAF {
            return node_idx;
        }
        if !best_cost.is_finite() {
            mid = start + n / 2;
            order[start..end].sort_by(|&a, &b| centroids[a][axis].total_cmp(&centroids[b][axis]));
        } else {
            let slice = &mut order[start..end];
            let mut left = 0;
            for k in 0..slice.len() {
                if bin_of(centroids[slice[k]][axis]) < best_split {
                    slice.swap(left, k);
                    left += 1;
                }
            }
            mid = start + left;
            if mid == start || mid == end {
                mid = start + n / 2;
            }
        }
    }
    if mid == start || mid == end {
        mid = start + n / 2;
    }
    nodes[node_idx as usize].count = 0;
    build_rec(nodes, order, start, mid, bounds, centroids);
    let right = build_rec(nodes, order, mid, end, bounds, centroids);
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
}
