//! Small numeric helpers: hashes (SplitMix64, PCG, the latter as in the shaders), a counter-based random number generator (deterministic per seed,
//! pixel and sample, independent of thread scheduling), orthonormal frames, sampling routines.

use glam::Vec3;
use std::f32::consts::PI;

/// SplitMix64 finaliser: a good 64-bit mixing function.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Hash of several words; used to derive independent streams.
#[inline]
pub fn hash3(a: u64, b: u64, c: u64) -> u64 {
    mix64(mix64(mix64(a ^ 0x9e37_79b9_7f4a_7c15).wrapping_add(b)).wrapping_add(c))
}

/// The PCG hash (O'Neill; the "pcg" of Jarzynski and Olano, JCGT 9(3), 2020), in u32 as in WGSL.
#[inline]
pub fn pcg_hash(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// A SplitMix64 stream. Cheap, statistically sound for Monte Carlo, and seeded by hashing
/// (seed, pixel, sample) so that results do not depend on which thread renders what.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
}

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng { state: mix64(seed) }
    }
    pub fn for_stream(seed: u64, stream: u64, index: u64) -> Self {
        Rng { state: hash3(seed, stream, index) }
    }
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix64(self.state)
    }
    /// Uniform in [0, 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }
    /// Two numbers uniform in [0, 1) from one draw: the 64-bit output's top 24 bits and the 24
    /// below them (SplitMix64's output bits are all equally good).
    #[inline]
    pub fn next_f32_pair(&mut self) -> (f32, f32) {
        let word = self.next_u64();
        let scale = 1.0 / (1u64 << 24) as f32;
        ((word >> 40) as f32 * scale, ((word >> 16) & 0xff_ffff) as f32 * scale)
    }
    /// Standard normal (Box–Muller).
    pub fn next_normal(&mut self) -> f32 {
        let u1 = (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
        let u2 = (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
        let r = (-2.0 * (1.0 - u1).ln()).sqrt();
        (r * (2.0 * std::f64::consts::PI * u2).cos()) as f32
    }
}

/// Rec. 709 / sRGB-primaries luminance of linear RGB.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// An orthonormal frame around a unit normal (Duff et al. 2017, branchless).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub t: Vec3,
    pub b: Vec3,
    pub n: Vec3,
}

impl Frame {
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let t = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let bb = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { t, b: bb, n }
    }
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.t * v.x + self.b * v.y + self.n * v.z
    }
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }
}

/// Cosine-weighted direction on the local hemisphere (+z); pdf = cos θ / π.
#[inline]
pub fn sample_cosine_hemisphere(u1: f32, u2: f32) -> Vec3 {
    let r = u1.sqrt();
    let phi = 2.0 * PI * u2;
    Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt())
}

/// Uniform direction on the sphere; pdf = 1 / 4π.
#[inline]
pub fn sample_uniform_sphere(u1: f32, u2: f32) -> Vec3 {
    let z = 1.0 - 2.0 * u1;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u2;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Uniform point on a triangle, as barycentrics (b1, b2).
#[inline]
pub fn sample_triangle(u1: f32, u2: f32) -> (f32, f32) {
    let s = u1.sqrt();
    (1.0 - s, u2 * s)
}

/// Veach's power heuristic with β = 2.
#[inline]
pub fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    if a + b <= 0.0 { 0.0 } else { a / (a + b) }
}

/// A piecewise-constant 1-D distribution for importance sampling.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    pub cdf: Vec<f32>,
    pub total: f32,
}

impl Distribution1D {
    /// `weights` must be non-negative; an all-zero input becomes uniform.
    pub fn new(weights: &[f32]) -> Self {
        let n = weights.len().max(1);
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0f32);
        let mut acc = 0.0f64;
        for &w in weights {
            acc += w.max(0.0) as f64;
            cdf.push(acc as f32);
        }
        let total = acc as f32;
        if total > 0.0 {
            for c in cdf.iter_mut() {
                *c /= total;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32 / n as f32;
            }
        }
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        Distribution1D { cdf, total }
    }
    pub fn len(&self) -> usize {
        self.cdf.len() - 1
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Probability of bucket `i`.
    #[inline]
    pub fn prob(&self, i: usize) -> f32 {
        self.cdf[i + 1] - self.cdf[i]
    }
    /// Samples a bucket; returns (index, probability, u remapped to [0,1) within the bucket).
    pub fn sample(&self, u: f32) -> (usize, f32, f32) {
        let n = self.len();
        // first index with cdf[i+1] > u
        let mut lo = 0usize;
        let mut hi = n;
        while lo < hi {
            let mid = (lo + hi) / 2;
            if self.cdf[mid + 1] <= u { lo = mid + 1 } else { hi = mid }
        }
        let i = lo.min(n - 1);
        let p = self.prob(i);
        let du = if p > 0.0 { ((u - self.cdf[i]) / p).clamp(0.0, 0.999_999) } else { 0.5 };
        (i, p, du)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bucket [`Distribution1D::sample`] must pick, by its definition: the first with
    /// cdf[i+1] > u, the last where none is.
    fn first_above(d: &Distribution1D, u: f32) -> usize {
        (0..d.len()).find(|&i| d.cdf[i + 1] > u).unwrap_or(d.len() - 1)
    }

    #[test]
    fn sampling_picks_the_first_bucket_above_u_with_empty_buckets_and_at_every_edge() {
        let mut rng = Rng::new(11);
        // sizes around powers of two, zero weights (flat stretches of the cdf) at the ends and
        // inside, one bucket, and all zero (uniform)
        let shapes: Vec<Vec<f32>> = vec![
            vec![1.0],
            vec![0.0, 0.0, 0.0],
            vec![0.0, 2.0, 0.0, 0.0, 1.0, 0.0],
            vec![3.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            (0..17).map(|i| (i % 3) as f32).collect(),
            (0..64).map(|_| if rng.next_f32() < 0.3 { 0.0 } else { rng.next_f32() }).collect(),
            (0..1000).map(|_| rng.next_f32().powi(4)).collect(),
        ];
        for weights in shapes {
            let d = Distribution1D::new(&weights);
            // every cdf value exactly, just below and above it, and random points
            let mut us: Vec<f32> = d.cdf.iter().flat_map(|&c| [c, c.next_down(), c.next_up()]).collect();
            us.extend((0..2000).map(|_| rng.next_f32()));
            for u in us.into_iter().filter(|u| (0.0..1.0).contains(u)) {
                let (i, p, du) = d.sample(u);
                assert_eq!(i, first_above(&d, u), "u = {u} over weights {weights:?}");
                assert!(p > 0.0, "an empty bucket {i} was picked at u = {u}");
                assert!((0.0..1.0).contains(&du), "{du}");
            }
        }
    }
}
