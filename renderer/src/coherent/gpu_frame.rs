//! The coherent frame on the GPU (issue 50, item 2): [`Coherent::render_preferring_gpu`].
//!
//! What runs where. On the CPU, as [`Coherent::render`] does them: the G-buffer with eq. 9's box
//! tests, every ray's geometry against the virtual object's exact surface (the object's
//! primary hits, its BRDF samples, the known lights' shadow rays through the object, the
//! differential background's rays to the object), and every random number, in the CPU's order.
//! That is recorded as plain data ([`crate::gpu::coherent`]): a list of queries and, per
//! pixel, terms. On the GPU: every query into the representation — EM lookups, DIT traces, VCT
//! cones (also eq. 6's cone up to the object), the object's self-shadow test in its solid
//! volumes, the light probe — and the shading that combines them: the object's radiance, eq.
//! 5's albedo, the differential background of eqs. 8–9 and the composite.
//!
//! One place where the CPU's random numbers depend on a query's answer: a ray of the
//! differential background (Fig. 7) whose environment is nearer than the object stops before
//! its bounce draws its direction, so the next ray's bounce draws the numbers this one would
//! have. The recording makes each ray's bounce once per count of numbers the rays before it
//! may have drawn, and the GPU keeps the count and reads the one that applies.
//!
//! *High* (the secondary bounce, whose random numbers depend on where the solid volume stops a
//! ray) is rendered on the CPU; so is a frame the GPU refuses ([`crate::gpu::coherent::FrameRefused`]).

use super::*;
use crate::gpu::DirRenderer;
use crate::gpu::coherent::{
    self as g, BOUNCE, CHANGE, ESTIMATED, FrameInput, IRRADIANCE, LIGHTS, OBJECT, PixelRecord, QueryRecord,
    REAL_SURFACE, SUM, TermRecord,
};

/// A frame's recording: its queries, terms and pixels, and eq. 9's directions traced and scaled.
#[derive(Default)]
pub(super) struct Recorded {
    pub queries: Vec<QueryRecord>,
    pub terms: Vec<TermRecord>,
    pub pixels: Vec<PixelRecord>,
    pub traced: u64,
    pub scaled: u64,
}

/// One pixel's recording: its queries (indices local to it) and terms.
#[derive(Default)]
struct Recording {
    queries: Vec<QueryRecord>,
    terms: Vec<TermRecord>,
    pixel: PixelRecord,
    traced: u64,
    scaled: u64,
}

impl Recording {
    fn query(&mut self, q: QueryRecord) -> u32 {
        self.queries.push(q);
        (self.queries.len() - 1) as u32
    }

    fn term(&mut self, op: u32, reg: u32, query: u32, aux: u32, weight: Vec3, scalar: f32) {
        self.terms.push(TermRecord { code: [op, reg, query, aux], weight: weight.extend(scalar).to_array() });
    }

    fn constant(&mut self, reg: u32, weight: Vec3) {
        self.term(g::CONST, reg, 0, g::NONE, weight, 0.0);
    }

    fn incident(&mut self, reg: u32, weight: Vec3, q: QueryRecord, divisor: f32) {
        let q = self.query(q);
        self.term(g::INCIDENT, reg, q, g::NONE, weight, divisor);
    }

    /// An incident term that counts only when the differential's random numbers drawn so far
    /// are `offset` (see the module's documentation).
    fn incident_at(&mut self, reg: u32, weight: Vec3, q: QueryRecord, offset: u32) {
        let q = self.query(q);
        self.term(g::INCIDENT, reg, q, offset, weight, 1.0);
    }

    fn transmits(&mut self, reg: u32, weight: Vec3, q: QueryRecord, distance: f32) {
        let q = self.query(q);
        self.term(g::TRANSMITS, reg, q, g::NONE, weight, distance);
    }
}

/// Counts of random numbers the rays before one may have drawn.
fn reachable(draws: &[u32], every_ray_bounces: bool) -> Vec<u32> {
    if every_ray_bounces {
        return vec![draws.iter().sum()];
    }
    let mut reach = vec![0u32];
    for &d in draws {
        let more: Vec<u32> = reach.iter().map(|r| r + d).collect();
        reach.extend(more);
        reach.sort_unstable();
        reach.dedup();
    }
    reach
}

impl Coherent<'_> {
    /// The frame on `gpu` where it can run there (see the module's documentation), else
    /// [`Coherent::render`] on the CPU with the reason among the report's `skipped`. Without a
    /// GPU, the CPU's frame.
    pub fn render_preferring_gpu(
        &self,
        photo: &Image,
        gpu: Option<&DirRenderer>,
        progress: &(dyn Fn(u32, u32) + Sync),
    ) -> Result<CoherentFrame> {
        let Some(gpu) = gpu else { return self.render(photo, progress) };
        if self.params.settings.secondary_bounce {
            let mut frame = self.render(photo, progress)?;
            frame.report.skipped.push("the GPU frame: quality high's secondary bounce runs on the CPU".into());
            return Ok(frame);
        }
        match self.render_gpu(photo, gpu)? {
            Ok(frame) => Ok(frame),
            Err(refused) => {
                let mut frame = self.render(photo, progress)?;
                frame.report.skipped.push(format!("the GPU frame, rendered on the CPU instead: {refused}"));
                Ok(frame)
            }
        }
    }

    /// The frame recorded here and run on `gpu` (*low* and *med*); the GPU's refusal in words.
    pub fn render_gpu(
        &self,
        photo: &Image,
        gpu: &DirRenderer,
    ) -> Result<std::result::Result<CoherentFrame, g::FrameRefused>> {
        let (w, h, mut report) = self.frame_start(photo)?;
        let n = (w * h) as usize;
        let start = Instant::now();
        let gbuffer: Vec<(u8, Option<Background>)> = (0..n).into_par_iter().map(|k| self.gbuffer(k)).collect();
        report.passes.push(PassTime::new("G-buffer and box tests (eq. 9)", ms_since(start)));
        let start = Instant::now();
        let recorded = self.record(&gbuffer);
        report.rays_traced = recorded.traced;
        report.rays_scaled = recorded.scaled;
        report.passes.push(PassTime::new(
            format!(
                "rays and terms recorded (CPU): {} queries, {} terms",
                recorded.queries.len(),
                recorded.terms.len()
            ),
            ms_since(start),
        ));
        let start = Instant::now();
        let maps: Vec<_> = self.rep.impostors.iter().map(|m| (m.centre, m.size, m.maps())).collect();
        let input = self.input(&recorded, &maps, photo);
        let pixels = &recorded.pixels;
        let out = match gpu.coherent_passes().run(&gpu.ctx, &input) {
            Ok(out) => out,
            Err(refused) => return Ok(Err(refused)),
        };
        report.passes.push(PassTime::new(
            "queries, object shading, material estimation (eq. 5) and differential background (eqs. 8, 9) on the GPU, read back",
            ms_since(start),
        ));
        report.counters = Some(out.counters);

        let start = Instant::now();
        let mut differential = Image::new(w, h);
        let mut albedo_image = Image::new(w, h);
        let mut coverage = Mask::new(w, h);
        let mut flags = vec![crate::surface::NOTHING; n];
        for k in 0..n {
            let (covered, bg) = gbuffer[k];
            flags[k] = if covered >= 2 {
                crate::surface::VIRTUAL
            } else if bg.is_some() {
                crate::surface::REAL
            } else {
                crate::surface::NOTHING
            };
            differential.pixels[k] = out.differential[k];
            coverage.values[k] = covered as f32 / 4.0;
            if pixels[k].terms[3] & ESTIMATED != 0 {
                let rho = out.rho[k];
                albedo_image.pixels[k] = rho.clamp(Vec3::ZERO, Vec3::ONE);
                report.albedo_clamped += usize::from(rho.max_element() > 1.0);
                report.albedo_unlit += usize::from(rho == Vec3::ZERO && photo.pixels[k].max_element() > 0.0);
                report.background_pixels += 1;
            } else if bg.is_some() && covered < 4 {
                report.background_skipped += 1;
            }
        }
        report.object_pixels = gbuffer.iter().filter(|g| g.0 > 0).count();
        let composite = Image { width: w, height: h, pixels: out.composite };
        let object = Image { width: w, height: h, pixels: out.object };
        report.passes.push(PassTime::new("composition", ms_since(start)));
        if self.bounds.is_none() {
            report.skipped.push("no virtual object: the photograph is returned unchanged".into());
        }
        if self.params.method == Method::Off {
            report.skipped.push("gi off: no material estimation or differential background".into());
        } else if !self.params.settings.self_shadow {
            report.skipped.push("self-shadow tests (quality low)".into());
        }
        if self.scene.spots.is_empty() {
            report.skipped.push("known lights: the scene has no point or spot light".into());
        }
        Ok(Ok(CoherentFrame { composite, differential, albedo: albedo_image, coverage, object, flags, report }))
    }

    /// Every pixel's queries and terms, in one list each (a term's queries numbered in it).
    pub(super) fn record(&self, gbuffer: &[(u8, Option<Background>)]) -> Recorded {
        let recordings: Vec<Recording> =
            gbuffer.par_iter().enumerate().map(|(k, g)| self.record_pixel(k, *g)).collect();
        let mut out = Recorded::default();
        out.pixels.reserve(gbuffer.len());
        for r in &recordings {
            let base = out.queries.len() as u32;
            let mut pixel = r.pixel;
            pixel.terms[0] = out.terms.len() as u32;
            pixel.terms[1] = r.terms.len() as u32;
            out.pixels.push(pixel);
            out.queries.extend_from_slice(&r.queries);
            out.terms.extend(r.terms.iter().map(|t| {
                let mut t = *t;
                if t.code[0] != g::CONST {
                    t.code[2] += base;
                }
                // a RAY_END's second query is a query; an INCIDENT's is an offset
                if t.code[0] == g::RAY_END && t.code[3] != g::NONE {
                    t.code[3] += base;
                }
                t
            }));
            out.traced += r.traced;
            out.scaled += r.scaled;
        }
        out
    }

    /// What the GPU's passes read: `recorded`, the representation (`maps`: each impostor's
    /// centre, size and maps) and the photograph.
    pub(super) fn input<'a>(
        &'a self,
        recorded: &'a Recorded,
        maps: &'a [(Vec3, u32, (&'a [Vec3], &'a [f32]))],
        photo: &'a Image,
    ) -> FrameInput<'a> {
        FrameInput {
            queries: &recorded.queries,
            terms: &recorded.terms,
            pixels: &recorded.pixels,
            photo: &photo.pixels,
            impostors: maps
                .iter()
                .map(|(centre, size, (radiance, distance))| g::ImpostorData {
                    centre: *centre,
                    size: *size,
                    radiance,
                    distance,
                })
                .collect(),
            voxels: self.rep.voxels.as_ref().map(|v| g::VoxelData {
                origin: v.origin,
                voxel: v.voxel,
                res: v.res,
                levels: (0..v.level_count()).map(|l| v.level(l)).collect(),
            }),
            solids: self.rep.solids.iter().map(solid_data).collect(),
            sky: self.rep.sky.as_ref().map(|s| g::SkyData {
                width: s.map.width,
                height: s.map.height,
                rotation: s.rotation,
                pixels: &s.map.pixels,
            }),
            pi_over_m: PI / self.params.settings.material_samples.max(1) as f32,
            read_queries: false,
            chunk_bytes: None,
        }
    }

    /// Pixel `k`'s queries and terms: the object (as [`Coherent::render`]'s `object_pixel`),
    /// eq. 5 and the differential background where it is affected.
    fn record_pixel(&self, k: usize, (covered, bg): (u8, Option<Background>)) -> Recording {
        let mut rec = Recording::default();
        if covered > 0 {
            let mut rng = Rng::for_stream(self.params.seed, 0x0b1ec7, k as u64);
            let mut hits = 0u32;
            for s in 0..4 {
                let ray = self.primary(k, s);
                if let (_, Some((hit, mat))) = self.first_hits(&ray) {
                    let samples = (self.params.settings.object_samples / 4).max(1);
                    self.record_object(&mut rec, &hit, mat, -ray.dir, samples, &mut rng);
                    hits += 1;
                }
            }
            rec.pixel.terms[2] = hits;
            rec.pixel.scale[1] = covered as f32 / 4.0;
        }
        if let Some(bg) = bg {
            rec.pixel.terms[3] |= REAL_SURFACE;
            if bg.affected && self.params.method != Method::Off {
                rec.pixel.terms[3] |= ESTIMATED;
                self.record_albedo(&mut rec, bg.point, bg.normal, k as u64);
                let mut rng = Rng::for_stream(self.params.seed, 0xd1ff, k as u64);
                let (big_n, cache) = (self.params.settings.background_samples, self.params.settings.cache);
                self.record_differential(&mut rec, bg.point, bg.normal, (big_n, cache), &mut rng);
            }
        }
        rec
    }

    /// The query [`Representation::incident`] would answer: its kind and impostor.
    fn incident_query(&self, query: Query, origin: Vec3, dir: Vec3, half: f32) -> QueryRecord {
        let near = self
            .rep
            .impostors
            .iter()
            .enumerate()
            .min_by(|(_, a), (_, b)| {
                let (da, db) = ((a.centre - origin).length_squared(), (b.centre - origin).length_squared());
                da.total_cmp(&db)
            })
            .map(|(i, _)| i as u32);
        let kind = match (query, near, &self.rep.voxels) {
            (Query::Vct, _, Some(_)) => g::CONE,
            (Query::Em, Some(_), _) => g::LOOKUP,
            (_, Some(_), _) => g::TRACE,
            _ => g::SKY,
        };
        QueryRecord::new(kind, near.unwrap_or(0), origin, dir, half)
    }

    /// [`Coherent::known_lights`] into `reg`: each light's weight, tested through the
    /// representation on the GPU where `shadowed` (the object's exact surface here).
    fn record_known_lights(
        &self,
        rec: &mut Recording,
        reg: u32,
        (p, ns, ng): (Vec3, Vec3, Vec3),
        shadowed: bool,
        f: impl Fn(Vec3) -> Vec3,
    ) {
        for spot in &self.scene.spots {
            let Some((wi, dist, irradiance)) = light_towards(spot, p, ns) else { continue };
            if ng.dot(wi) <= 0.0 {
                continue;
            }
            if shadowed {
                let ray = Ray { origin: p, dir: wi };
                if self.object.occluded(&ray, dist * (1.0 - 1e-4)) {
                    continue;
                }
                let q = self.incident_query(self.params.method.query(), p, wi, 0.0);
                rec.transmits(reg, f(wi) * irradiance, q, dist);
            } else {
                rec.constant(reg, f(wi) * irradiance);
            }
        }
    }

    /// [`Coherent::shade_object`] (*low*, *med*) into the object's register.
    fn record_object(
        &self,
        rec: &mut Recording,
        hit: &SurfaceHit,
        mat: &Material,
        wo: Vec3,
        samples: u32,
        rng: &mut Rng,
    ) {
        let front = hit.geometric_normal.dot(wo) > 0.0;
        let ng = if front { hit.geometric_normal } else { -hit.geometric_normal };
        rec.constant(OBJECT, if front { mat.emission } else { Vec3::ZERO });
        let method = self.params.method;
        if let Some(delta) = &mat.delta {
            for _ in 0..samples {
                let (weight, q) = self.delta_query(delta, hit, wo, (front, ng), rng);
                rec.incident(OBJECT, weight, q, samples as f32);
            }
            return;
        }
        let Some((ns, bsdf, p)) = shade(mat, hit, ng) else { return };
        let occluding = method != Method::Off;
        let shadowed = occluding && self.params.settings.self_shadow;
        self.record_known_lights(rec, OBJECT, (p, ns, ng), shadowed, |wi| bsdf.eval(wo, wi));
        for _ in 0..samples {
            let u: [f32; 3] = std::array::from_fn(|_| rng.next_f32());
            let Some(bs) = bsdf.sample(wo, u[0], u[1], u[2]) else { continue };
            if bs.wi.dot(ng) <= 0.0 || !(bs.pdf > 0.0) {
                continue;
            }
            let half = cone_half_angle(1.0 / (samples as f32 * bs.pdf));
            let q = if method == Method::Off {
                QueryRecord::new(g::SKY, 0, p, bs.wi, half)
            } else {
                // incident_at_object: stopped by the object itself (zero on med), else the query
                let settings = &self.params.settings;
                if settings.self_shadow && self.rep.exact_self_shadows {
                    if self.object.hit_with_material(&Ray { origin: p, dir: bs.wi }, f32::INFINITY).is_some() {
                        continue;
                    }
                    self.incident_query(method.query(), p, bs.wi, half)
                } else if settings.self_shadow {
                    self.incident_query(method.query(), p, bs.wi, half).self_shadowed(ng)
                } else {
                    self.incident_query(method.query(), p, bs.wi, half)
                }
            };
            rec.incident(OBJECT, bs.weight, q, samples as f32);
        }
    }

    /// [`Coherent::through_delta`]: the sampled direction's weight and query.
    fn delta_query(
        &self,
        delta: &DeltaBsdf,
        hit: &SurfaceHit,
        wo: Vec3,
        (front, ng): (bool, Vec3),
        rng: &mut Rng,
    ) -> (Vec3, QueryRecord) {
        let mut weight = Vec3::ONE;
        let u = rng.next_f32();
        let ray = delta_bounce(delta, hit, hit.t, Arrival { wo, front, ng }, u, Transport::Radiance, &mut weight);
        (weight, self.incident_query(self.params.method.query(), ray.origin, ray.dir, 0.0))
    }

    /// [`Coherent::estimate_albedo`]'s queries: the irradiance's cosine samples and the real
    /// known lights.
    fn record_albedo(&self, rec: &mut Recording, x: Vec3, n: Vec3, k: u64) {
        let m = self.params.settings.material_samples.max(1);
        let mut rng = Rng::for_stream(self.params.seed, 0xa1bed0, k);
        let frame = Frame::from_normal(n);
        let query = self.params.method.material_query();
        let origin = self.rep.surface_origin(query, x, n);
        let half = cone_half_angle(PI / m as f32);
        for _ in 0..m {
            let dir = frame.to_world(sample_cosine_hemisphere(rng.next_f32(), rng.next_f32()));
            rec.incident(IRRADIANCE, Vec3::ONE, self.incident_query(query, origin, dir, half), 1.0);
        }
        for spot in self.scene.spots.iter().filter(|s| s.real) {
            if let Some((wi, dist, e)) = light_towards(spot, origin, n) {
                rec.transmits(LIGHTS, e, self.incident_query(query, origin, wi, 0.0), dist);
            }
        }
    }

    /// [`Coherent::differential`]'s rays and known lights.
    fn record_differential(&self, rec: &mut Recording, x: Vec3, n: Vec3, (big_n, cache): (u32, u32), rng: &mut Rng) {
        let Some(bounds) = self.bounds else { return };
        let big_n = big_n.max(1);
        let mut hits: Vec<Vec3> = box_directions(bounds, x, n, big_n, rng).collect();
        let traced = if cache == 0 { hits.len() } else { hits.len().min(cache as usize) };
        for i in 0..traced {
            let j = i + ((rng.next_f32() * (hits.len() - i) as f32) as usize).min(hits.len() - i - 1);
            hits.swap(i, j);
        }
        let query = self.params.method.query();
        let origin = self.rep.surface_origin(query, x, n);
        let half = cone_half_angle(PI / big_n as f32);
        let cones = query == Query::Vct && self.rep.voxels.is_some();
        // the random numbers each ray's bounce draws (zero where the ray misses the object)
        let mut draws: Vec<u32> = Vec::with_capacity(traced);
        for &dir in &hits[..traced] {
            let ray = Ray { origin, dir };
            let Some((hit, mat)) = self.object.hit_with_material(&ray, f32::INFINITY) else {
                draws.push(0);
                continue;
            };
            let env = rec.query(self.incident_query(query, origin, dir, half));
            let before = if cones {
                rec.query(self.incident_query(query, origin, dir, half).kind(g::CONE_TO).ending_at(hit.t))
            } else {
                g::NONE
            };
            // the bounce once per count of numbers drawn before it (a cone's ray always bounces)
            let drawn = self.record_bounce(rec, &hit, mat, -dir, rng, &reachable(&draws, cones));
            rec.term(g::RAY_END, SUM, env, before, Vec3::new(drawn as f32, 0.0, 0.0), hit.t);
            draws.push(drawn);
        }
        let scale = if traced > 0 { 1.0 + (hits.len() - traced) as f32 / traced as f32 } else { 0.0 };
        rec.pixel.scale[0] = scale / big_n as f32;
        rec.traced = traced as u64;
        rec.scaled = (hits.len() - traced) as u64;
        for spot in &self.scene.spots {
            let Some((wi, dist, e)) = light_towards(spot, origin, n) else { continue };
            let ray = Ray { origin, dir: wi };
            let blocked =
                bounds.hit(origin, wi.recip(), dist).is_some() && self.object.occluded(&ray, dist * (1.0 - 1e-4));
            if spot.real && !blocked {
                continue;
            }
            let q = self.incident_query(query, origin, wi, 0.0);
            if spot.real {
                rec.transmits(CHANGE, -e, q, dist);
            } else if !blocked {
                rec.transmits(CHANGE, e, q, dist);
            }
        }
    }

    /// [`Coherent::diffuse_bounce`] into the bounce register, its random direction once per
    /// count in `offsets` of numbers drawn before it (`rng` as it stands with none); returns
    /// how many numbers it draws.
    fn record_bounce(
        &self,
        rec: &mut Recording,
        hit: &SurfaceHit,
        mat: &Material,
        wo: Vec3,
        rng: &Rng,
        offsets: &[u32],
    ) -> u32 {
        let front = hit.geometric_normal.dot(wo) > 0.0;
        let ng = if front { hit.geometric_normal } else { -hit.geometric_normal };
        let advanced = |offset: u32| {
            let mut r = rng.clone();
            for _ in 0..offset {
                r.next_f32();
            }
            r
        };
        if let Some(delta) = &mat.delta {
            for &offset in offsets {
                let (weight, q) = self.delta_query(delta, hit, wo, (front, ng), &mut advanced(offset));
                rec.incident_at(BOUNCE, weight, q, offset);
            }
            return 1;
        }
        rec.constant(BOUNCE, if front { mat.emission } else { Vec3::ZERO });
        let Some((ns, bsdf, p)) = shade(mat, hit, ng) else { return 0 };
        let albedo = bsdf.kd;
        if albedo.max_element() <= 0.0 {
            return 0;
        }
        let query = self.params.method.query();
        self.record_known_lights(rec, BOUNCE, (p, ns, ng), true, |_| albedo / PI);
        let frame = Frame::from_normal(ns);
        for &offset in offsets {
            let mut r = advanced(offset);
            let dir = frame.to_world(sample_cosine_hemisphere(r.next_f32(), r.next_f32()));
            if dir.dot(ng) > 0.0 {
                rec.incident_at(BOUNCE, albedo, self.incident_query(query, p, dir, cone_half_angle(PI / 4.0)), offset);
            }
        }
        2
    }
}

/// A solid volume's level-0 τ as the GPU reads it.
fn solid_data(v: &SolidVolume) -> g::SolidData {
    let dims = v.dims();
    let mut tau = Vec::with_capacity((dims.x * dims.y * dims.z) as usize);
    for z in 0..dims.z {
        for y in 0..dims.y {
            for x in 0..dims.x {
                tau.push(v.tau(0, glam::UVec3::new(x, y, z)));
            }
        }
    }
    g::SolidData { origin: v.origin, voxel: v.voxel, dims, tau }
}
