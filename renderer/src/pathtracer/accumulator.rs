//! The progressive render of the path tracer: per-pixel sums of camera samples (and of the
//! light-traced paths) over rows in parallel, each sample from its own random stream, and what
//! a finished render reports — the image, per-pixel standard errors, the virtual objects'
//! coverage and the firefly pixels.

use super::*;

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
    /// Light tracing's sums per pixel (only in a world that needs it), and its number of paths:
    /// one per pixel and camera sample.
    light_sum: Vec<DVec3>,
    pub light_paths: u64,
}

/// One pixel's sums over a batch of samples: radiance, samples whose primary ray hit a virtual
/// object, the brightest sample's luminance, the sum of squared luminances, invalid samples.
#[derive(Clone, Copy, Debug, Default)]
struct PixelSums {
    acc: DVec3,
    virtual_hits: u32,
    max_l: f32,
    lum2: f64,
    invalid: u64,
}

/// A row of [`PixelSums`] and its invalid samples.
#[derive(Clone, Debug, Default)]
struct RowSums {
    pixels: Vec<PixelSums>,
    invalid: u64,
}

/// Rows of `K` images' sums, one list of rows per image.
fn unzip_rows<const K: usize>(rows: Vec<[RowSums; K]>) -> [Vec<RowSums>; K] {
    let mut out: [Vec<RowSums>; K] = std::array::from_fn(|_| Vec::with_capacity(rows.len()));
    for row in rows {
        for (o, r) in out.iter_mut().zip(row) {
            o.push(r);
        }
    }
    out
}

/// Light paths traced per parallel task (their splats are summed in task order, so the image
/// does not depend on the thread count).
const LIGHT_CHUNK: u64 = 1 << 13;

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
            light_sum: Vec::new(),
            light_paths: 0,
        }
    }

    /// Adds samples `self.spp .. self.spp + n` to every pixel (rayon over rows).
    pub fn add_samples(&mut self, world: &World, camera: &Camera, params: &TraceParams, n: u32) {
        let start = self.spp;
        let rows = self.trace_rows(camera, params, n, |ray, rng| {
            let (l, first) = world.radiance(ray, rng, params);
            [(l, first.is_some_and(|o| world.object_roles[o as usize] == Role::Virtual))]
        });
        let [rows] = unzip_rows(rows);
        self.add_rows(rows);
        self.finish_samples(world, camera, params, start, n);
    }

    /// [`Accumulator::add_samples`] for the full scene's world (into `self`) and its real-only
    /// world (into `real`) at once, tracing each path once while it is the same in both
    /// ([`World::radiance_pair`]); the sums are bit for bit those of two separate calls. The
    /// worlds must share their lights ([`World::shares_lights_with`]).
    pub fn add_samples_pair(
        &mut self,
        real: &mut Accumulator,
        full_world: &World,
        real_world: &World,
        camera: &Camera,
        params: &TraceParams,
        n: u32,
    ) {
        assert!(full_world.shares_lights_with(real_world), "a paired render needs worlds with the same lights");
        assert_eq!(self.spp, real.spp, "paired accumulators must hold the same samples");
        let start = self.spp;
        let rows = self.trace_rows(camera, params, n, |ray, rng| {
            let (l, l_real, first) = full_world.radiance_pair(real_world, ray, rng, params);
            [(l, first.is_some_and(|o| full_world.object_roles[o as usize] == Role::Virtual)), (l_real, false)]
        });
        let [full_rows, real_rows] = unzip_rows(rows);
        self.add_rows(full_rows);
        real.add_rows(real_rows);
        self.finish_samples(full_world, camera, params, start, n);
        real.finish_samples(real_world, camera, params, start, n);
    }

    /// Samples `self.spp .. self.spp + n` of every pixel, `K` radiance values per sample (with
    /// whether the primary ray hit a virtual object), summed per pixel: rows of per-pixel sums.
    fn trace_rows<const K: usize>(
        &self,
        camera: &Camera,
        params: &TraceParams,
        n: u32,
        sample: impl Fn(Ray, &mut Rng) -> [(Vec3, bool); K] + Sync,
    ) -> Vec<[RowSums; K]> {
        let w = self.width as usize;
        let start = self.spp;
        (0..self.height)
            .into_par_iter()
            .map(|y| {
                let mut rows: [RowSums; K] = std::array::from_fn(|_| RowSums::default());
                for x in 0..self.width {
                    let pixel = (y as u64) * w as u64 + x as u64;
                    let mut sums = [PixelSums::default(); K];
                    for s in start..start + n {
                        let mut rng = Rng::for_stream(params.seed, pixel, s as u64);
                        let (jx, jy) = rng.next_f32_pair();
                        let ray = camera.ray(x as f32 + jx, y as f32 + jy);
                        for (sum, (l, virtual_first)) in sums.iter_mut().zip(sample(ray, &mut rng)) {
                            if !l.is_finite() {
                                sum.invalid += 1;
                                continue;
                            }
                            sum.acc += l.as_dvec3();
                            sum.max_l = sum.max_l.max(luminance(l));
                            sum.lum2 += (luminance(l) as f64).powi(2);
                            sum.virtual_hits += virtual_first as u32;
                        }
                    }
                    for (row, sum) in rows.iter_mut().zip(sums) {
                        row.invalid += sum.invalid;
                        row.pixels.push(sum);
                    }
                }
                rows
            })
            .collect()
    }

    /// Adds per-pixel sums (rows in order) to the image's.
    fn add_rows(&mut self, rows: Vec<RowSums>) {
        let w = self.width as usize;
        for (y, row) in rows.into_iter().enumerate() {
            self.invalid_samples += row.invalid;
            for (x, p) in row.pixels.into_iter().enumerate() {
                let i = y * w + x;
                self.sum_lum2[i] += p.lum2;
                self.sum[i] += p.acc;
                self.virtual_hits[i] += p.virtual_hits;
                self.max_sample[i] = self.max_sample[i].max(p.max_l);
            }
        }
    }

    /// After camera samples `start .. start + n`: the light paths of the same samples (where
    /// the world needs them), and the new sample count.
    fn finish_samples(&mut self, world: &World, camera: &Camera, params: &TraceParams, start: u32, n: u32) {
        let pixels = self.width as u64 * self.height as u64;
        if params.light_tracing && world.needs_light_tracing() {
            self.add_light_paths(world, camera, params, start as u64 * pixels, n as u64 * pixels);
        }
        self.spp += n;
    }

    /// Traces light paths `first .. first + count` (each from its own stream) and adds their
    /// camera connections.
    fn add_light_paths(&mut self, world: &World, camera: &Camera, params: &TraceParams, first: u64, count: u64) {
        if self.light_sum.is_empty() {
            self.light_sum = vec![DVec3::ZERO; self.sum.len()];
        }
        let chunks = count.div_ceil(LIGHT_CHUNK);
        // a few chunks per thread at a time keeps the splat lists small
        let batch = (rayon::current_num_threads() as u64 * 4).max(1);
        let mut invalid = 0u64;
        for batch_start in (0..chunks).step_by(batch as usize) {
            let splats: Vec<Vec<(u32, Vec3)>> = (batch_start..(batch_start + batch).min(chunks))
                .into_par_iter()
                .map(|chunk| {
                    let mut splats = Vec::new();
                    let end = ((chunk + 1) * LIGHT_CHUNK).min(count);
                    for path in chunk * LIGHT_CHUNK..end {
                        let mut rng = Rng::for_stream(params.seed, LIGHT_STREAM, first + path);
                        world.trace_light_path(camera, &mut rng, params, &mut |pixel, value| {
                            splats.push((pixel as u32, value))
                        });
                    }
                    splats
                })
                .collect();
            for (pixel, value) in splats.into_iter().flatten() {
                if value.is_finite() {
                    self.light_sum[pixel as usize] += value.as_dvec3();
                } else {
                    invalid += 1;
                }
            }
        }
        self.invalid_samples += invalid;
        self.light_paths += count;
    }

    /// The mean radiance per pixel (camera paths, plus light paths where the world needs them).
    pub fn image(&self) -> Image {
        let inv = 1.0 / self.spp.max(1) as f64;
        let light_inv = 1.0 / self.light_paths.max(1) as f64;
        let pixels = match self.light_sum.is_empty() {
            true => self.sum.iter().map(|s| (*s * inv).as_vec3()).collect(),
            false => self.sum.iter().zip(&self.light_sum).map(|(s, l)| (*s * inv + *l * light_inv).as_vec3()).collect(),
        };
        Image { width: self.width, height: self.height, pixels }
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
