//! Rohmer et al.'s frame on the GPU (issue 50, item 2; shader: `coherent.wgsl`): the queries
//! of a coherent frame — environment mapping (EM: the impostor read in the query's direction),
//! distance impostor tracing (DIT: 24 linear steps and 6 secant steps), voxel cone tracing (VCT:
//! the cone marched through the mip-mapped scene volume), each optionally stopped first by the
//! virtual objects' solid volumes (the object's self-shadow on *med*) — answered by one compute
//! pass, one invocation per query; then a second pass combines each pixel's terms into the
//! object's radiance, eq. 5's albedo, the differential background of eqs. 8–9 and the composite.
//!
//! What the passes read is plain data ([`FrameInput`]): `coherent::gpu_frame` records it from
//! the CPU reference's own frame (the G-buffer, the object's and the real surfaces' rays, every
//! random number, the known lights' tests against the object's exact geometry), so this module
//! names none of `coherent`'s types (no module cycle). A query is a record of origin, direction,
//! cone half-angle, kind and impostor; a term adds to one of a pixel's registers a constant, a
//! weighted query's radiance, a weight where a query transmits up to a distance, or closes one
//! ray of the differential background (Fig. 7: the object's bounce minus the environment it
//! hides, zero where the environment is nearer; with a cone, weighted by eq. 6).
//!
//! llvmpipe stops an invocation's loops after about 2¹⁴ iterations in all (silently): one
//! invocation per query keeps each march short (a cone through 128³ voxels takes at most about
//! 450 steps, its trilinear lookups written out corner by corner).

use super::context::{FrameCounters, GpuContext};
use super::pool::Contents;
use glam::{UVec3, Vec3};
use std::time::Instant;

pub const SHADER: &str = include_str!("coherent.wgsl");

/// Threads per workgroup of both entry points.
const GROUP: u32 = 64;
/// Impostors, solid volumes and voxel levels the uniform holds.
const MAX_IMPOSTORS: usize = 8;
const MAX_SOLIDS: usize = 8;
const MAX_LEVELS: usize = 16;

/// Query kinds (`Query.normal.w`'s low byte).
pub const SKY: u32 = 0;
pub const LOOKUP: u32 = 1;
pub const TRACE: u32 = 2;
pub const CONE: u32 = 3;
pub const CONE_TO: u32 = 4;

/// Term operations (`Term.code.x`).
pub const CONST: u32 = 0;
pub const INCIDENT: u32 = 1;
pub const TRANSMITS: u32 = 2;
pub const RAY_END: u32 = 3;

/// A pixel's registers (`Term.code.y`).
pub const OBJECT: u32 = 0;
pub const IRRADIANCE: u32 = 1;
pub const LIGHTS: u32 = 2;
pub const SUM: u32 = 3;
pub const CHANGE: u32 = 4;
pub const BOUNCE: u32 = 5;

/// No second query (a `RAY_END` without eq. 6's cone).
pub const NONE: u32 = u32::MAX;

/// Pixel flags: a real surface is behind it; its albedo was estimated (it is affected).
pub const REAL_SURFACE: u32 = 1;
pub const ESTIMATED: u32 = 2;

/// One query: origin and cone half-angle, direction and (for [`CONE_TO`]) the cone's end, the
/// object surface's normal (for the self-shadow test) and the bits of kind | impostor << 8 |
/// self-shadow test << 16.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct QueryRecord {
    pub origin: [f32; 4],
    pub dir: [f32; 4],
    pub normal: [f32; 4],
}

impl QueryRecord {
    /// A query of `kind` (reading impostor `impostor`) from `origin` along `dir`; `solid`: the
    /// objects' solid volumes are tested first from the surface of geometric normal `normal`.
    pub fn new(kind: u32, impostor: u32, origin: Vec3, dir: Vec3, half: f32) -> QueryRecord {
        QueryRecord {
            origin: origin.extend(half).to_array(),
            dir: dir.extend(0.0).to_array(),
            normal: [0.0, 0.0, 0.0, f32::from_bits(kind | (impostor << 8))],
        }
    }

    /// This query, stopped by the solid volumes first (the object's self-shadow).
    pub fn self_shadowed(mut self, normal: Vec3) -> QueryRecord {
        let bits = self.normal[3].to_bits() | (1 << 16);
        self.normal = normal.extend(f32::from_bits(bits)).to_array();
        self
    }

    /// This query as a cone ending at `t_max` ([`CONE_TO`]).
    pub fn ending_at(mut self, t_max: f32) -> QueryRecord {
        self.dir[3] = t_max;
        self
    }

    /// This query with another kind.
    pub fn kind(mut self, kind: u32) -> QueryRecord {
        let bits = (self.normal[3].to_bits() & !0xff) | kind;
        self.normal[3] = f32::from_bits(bits);
        self
    }
}

/// One term of a pixel: operation, register, query, second query; weight and scalar.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct TermRecord {
    pub code: [u32; 4],
    pub weight: [f32; 4],
}

/// One pixel: its first term and term count, covered subsamples, flags; eq. 9's scale over N
/// and the coverage.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PixelRecord {
    pub terms: [u32; 4],
    pub scale: [f32; 4],
}

/// A distance impostor's maps (six faces of `size`² texels; infinite distance where empty).
pub struct ImpostorData<'a> {
    pub centre: Vec3,
    pub size: u32,
    pub radiance: &'a [Vec3],
    pub distance: &'a [f32],
}

/// The scene voxel volume: level 0's corner and voxel edge, its levels (premultiplied rgb, α).
pub struct VoxelData<'a> {
    pub origin: Vec3,
    pub voxel: f32,
    pub res: u32,
    pub levels: Vec<&'a [[f32; 4]]>,
}

/// A virtual object's solid volume: τ of level 0, x fastest.
pub struct SolidData {
    pub origin: Vec3,
    pub voxel: Vec3,
    pub dims: UVec3,
    pub tau: Vec<f32>,
}

/// The light probe: an equirectangular map, rows top down, and its rotation (a turn's fraction).
pub struct SkyData<'a> {
    pub width: u32,
    pub height: u32,
    pub rotation: f32,
    pub pixels: &'a [Vec3],
}

/// Everything the two passes read.
pub struct FrameInput<'a> {
    pub queries: &'a [QueryRecord],
    pub terms: &'a [TermRecord],
    pub pixels: &'a [PixelRecord],
    /// The photograph's linear radiance, one per pixel.
    pub photo: &'a [Vec3],
    pub impostors: Vec<ImpostorData<'a>>,
    pub voxels: Option<VoxelData<'a>>,
    pub solids: Vec<SolidData>,
    pub sky: Option<SkyData<'a>>,
    /// π over eq. 5's sample count.
    pub pi_over_m: f32,
    /// Read every query's answer back too ([`FrameOutput::answers`]; for tests).
    pub read_queries: bool,
    /// Bytes a piece of the frame may bind at most (None: what the adapter binds); the frame
    /// runs in as many pieces as that takes, one submission each (tests make it small).
    pub chunk_bytes: Option<u64>,
}

/// The frame's buffers as the passes left them, with what the frame asked of the device.
pub struct FrameOutput {
    pub composite: Vec<Vec3>,
    pub differential: Vec<Vec3>,
    /// Eq. 5's ρ, unclamped (zero where not estimated).
    pub rho: Vec<Vec3>,
    pub object: Vec<Vec3>,
    /// Each query's answer (radiance and distance; a [`CONE_TO`]'s opacity first) where
    /// [`FrameInput::read_queries`] asked for them.
    pub answers: Vec<[f32; 4]>,
    pub counters: FrameCounters,
}

/// Why a frame cannot run on this GPU (the CPU renders it then); each one sentence.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FrameRefused {
    #[error("{what}: {count}, more than the {limit} the GPU frame holds")]
    TooMany { what: &'static str, count: usize, limit: usize },
    #[error("the frame's {what} need a {needed_mb:.0} MB buffer, more than the {limit_mb:.0} MB the adapter binds")]
    TooLarge { what: &'static str, needed_mb: f64, limit_mb: f64 },
}

/// The two compute pipelines.
pub struct CoherentPasses {
    queries: wgpu::ComputePipeline,
    combine: wgpu::ComputePipeline,
}

fn groups(n: u32) -> [u32; 2] {
    let total = n.div_ceil(GROUP).max(1);
    let x = total.min(65_535);
    [x, total.div_ceil(x)]
}

fn vec4s(values: impl Iterator<Item = [f32; 4]>) -> Vec<[f32; 4]> {
    let mut out: Vec<[f32; 4]> = values.collect();
    if out.is_empty() {
        out.push([0.0; 4]);
    }
    out
}

impl CoherentPasses {
    pub fn new(ctx: &GpuContext) -> Self {
        let [queries, combine] = ctx.compute_pipelines("coherent.wgsl", SHADER, ["cs_queries", "cs_combine"]);
        CoherentPasses { queries, combine }
    }

    /// Runs the frame `input` describes: both passes in one submission, one wait, the four
    /// buffers read back (per piece, where the frame's lists exceed what the adapter binds).
    pub fn run(&self, ctx: &GpuContext, input: &FrameInput) -> Result<FrameOutput, FrameRefused> {
        let start = Instant::now();
        let _frame = ctx.begin_frame();
        let too_many = |what, count: usize, limit| {
            if count > limit { Err(FrameRefused::TooMany { what, count, limit }) } else { Ok(()) }
        };
        too_many("impostors", input.impostors.len(), MAX_IMPOSTORS)?;
        too_many("solid volumes", input.solids.len(), MAX_SOLIDS)?;
        too_many("voxel levels", input.voxels.as_ref().map_or(0, |v| v.levels.len()), MAX_LEVELS)?;
        let n = input.pixels.len();
        // the data, each a storage buffer
        let impostor = vec4s(input.impostors.iter().flat_map(|m| {
            m.radiance.iter().zip(m.distance).map(|(r, &d)| r.extend(if d.is_finite() { d } else { -1.0 }).to_array())
        }));
        let voxels = vec4s(input.voxels.iter().flat_map(|v| v.levels.iter().flat_map(|l| l.iter().copied())));
        let mut tau: Vec<f32> = input.solids.iter().flat_map(|s| s.tau.iter().copied()).collect();
        if tau.is_empty() {
            tau.push(0.0);
        }
        let sky = vec4s(input.sky.iter().flat_map(|s| s.pixels.iter().map(|p| p.extend(0.0).to_array())));
        let limit = ctx.device.limits().max_storage_buffer_binding_size;
        for (what, bytes) in [("impostor texels", impostor.len() * 16), ("voxels", voxels.len() * 16)] {
            if bytes as u64 > limit {
                return Err(FrameRefused::TooLarge {
                    what,
                    needed_mb: bytes as f64 / 1e6,
                    limit_mb: limit as f64 / 1e6,
                });
            }
        }
        let impostor = storage(ctx, "coherent impostors", bytemuck::cast_slice(&impostor));
        let voxels = storage(ctx, "coherent voxels", bytemuck::cast_slice(&voxels));
        let tau = storage(ctx, "coherent solids", bytemuck::cast_slice(&tau));
        let sky = storage(ctx, "coherent probe", bytemuck::cast_slice(&sky));
        let representation = [&*impostor, &*voxels, &*tau, &*sky];
        let mut out = FrameOutput {
            composite: Vec::with_capacity(n),
            differential: Vec::with_capacity(n),
            rho: Vec::with_capacity(n),
            object: Vec::with_capacity(n),
            answers: Vec::new(),
            counters: FrameCounters::default(),
        };
        // the frame in as few pieces as the adapter binds (one at the sizes measured so far)
        for chunk in chunks(input, input.chunk_bytes.unwrap_or(limit).min(limit)) {
            self.run_chunk(ctx, input, &chunk, representation, &mut out);
        }
        out.counters = ctx.counters();
        out.counters.cpu_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(out)
    }

    /// One piece of the frame: its pixels, their terms and queries; both passes in one
    /// submission, one wait, its buffers appended to `out`.
    fn run_chunk(
        &self,
        ctx: &GpuContext,
        input: &FrameInput,
        chunk: &Chunk,
        [impostor, voxels, tau, sky]: [&wgpu::Buffer; 4],
        out: &mut FrameOutput,
    ) {
        let n = chunk.pixels.len();
        let queries = &input.queries[chunk.queries.clone()];
        let pixels: Vec<PixelRecord> = input.pixels[chunk.pixels.clone()]
            .iter()
            .map(|p| PixelRecord {
                terms: [p.terms[0] - chunk.terms.start as u32, p.terms[1], p.terms[2], p.terms[3]],
                ..*p
            })
            .collect();
        let photo = vec4s(input.photo[chunk.pixels.clone()].iter().map(|p| p.extend(0.0).to_array()));
        let counts = [queries.len() as u32, n as u32, chunk.queries.start as u32];
        let uniform = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("coherent params"),
            contents: &params(input, counts),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let queries_buffer = storage(ctx, "coherent queries", bytemuck::cast_slice(queries));
        let terms = storage(ctx, "coherent terms", bytemuck::cast_slice(&input.terms[chunk.terms.clone()]));
        let pixels = storage(ctx, "coherent pixels", bytemuck::cast_slice(&pixels));
        let photo = storage(ctx, "coherent photo", bytemuck::cast_slice(&photo));
        let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
        // every query and every pixel writes its own: nothing to clear
        let results = ctx.buffer("coherent results", (queries.len().max(1) * 16) as u64, usage, Contents::Overwritten);
        let frame = ctx.buffer("coherent frame", (n.max(1) * 64) as u64, usage, Contents::Overwritten);
        let mut encoder = ctx.encoder();
        let query_entries = [
            entry(0, &uniform),
            entry(1, &queries_buffer),
            entry(2, &results),
            entry(3, impostor),
            entry(4, voxels),
            entry(5, tau),
            entry(6, sky),
        ];
        ctx.record_dispatch(
            &mut encoder,
            "coherent queries",
            &self.queries,
            &query_entries,
            groups(queries.len() as u32),
        );
        let combine_entries = [
            entry(0, &uniform),
            entry(2, &results),
            entry(7, &terms),
            entry(8, &pixels),
            entry(9, &photo),
            entry(10, &frame),
        ];
        ctx.record_dispatch(&mut encoder, "coherent combine", &self.combine, &combine_entries, groups(n as u32));
        // the read-back's copy in the same submission: one submit, one wait
        let staging =
            ctx.buffer("coherent readback", frame.size(), wgpu::BufferUsages::MAP_READ, Contents::Overwritten);
        encoder.copy_buffer_to_buffer(&frame, 0, &staging, 0, frame.size());
        ctx.submit(encoder);
        let values = ctx.read_staged_f32(&staging);
        if input.read_queries {
            out.answers
                .extend(ctx.read_f32(&results).chunks_exact(4).take(queries.len()).map(|c| [c[0], c[1], c[2], c[3]]));
        }
        let at = |k: usize, which: usize| Vec3::from_slice(&values[(4 * k + which) * 4..(4 * k + which) * 4 + 3]);
        for k in 0..n {
            out.composite.push(at(k, 0));
            out.differential.push(at(k, 1));
            out.rho.push(at(k, 2));
            out.object.push(at(k, 3));
        }
    }
}

/// A piece of the frame: pixels, and the terms and queries they read (ranges into the frame's).
struct Chunk {
    pixels: std::ops::Range<usize>,
    terms: std::ops::Range<usize>,
    queries: std::ops::Range<usize>,
}

/// The frame's pixels cut into pieces whose queries, terms and buffers each fit in `limit`
/// bytes (a pixel's queries are its own and follow the previous pixel's).
fn chunks(input: &FrameInput, limit: u64) -> Vec<Chunk> {
    let query_span = |p: &PixelRecord| -> Option<(usize, usize)> {
        let terms = &input.terms[p.terms[0] as usize..(p.terms[0] + p.terms[1]) as usize];
        let mut span: Option<(usize, usize)> = None;
        for t in terms.iter().filter(|t| t.code[0] != CONST) {
            for q in [Some(t.code[2]), (t.code[0] == RAY_END && t.code[3] != NONE).then_some(t.code[3])]
                .into_iter()
                .flatten()
            {
                let q = q as usize;
                span = Some(span.map_or((q, q + 1), |(a, b)| (a.min(q), b.max(q + 1))));
            }
        }
        span
    };
    let fits = |queries: usize, terms: usize, pixels: usize| {
        (queries * 48) as u64 <= limit && (terms * 32) as u64 <= limit && (pixels * 64) as u64 <= limit
    };
    let mut out: Vec<Chunk> = Vec::new();
    let mut current = Chunk { pixels: 0..0, terms: 0..0, queries: 0..0 };
    for (k, p) in input.pixels.iter().enumerate() {
        let terms_end = (p.terms[0] + p.terms[1]) as usize;
        let span = query_span(p);
        let queries = match (span, current.queries.is_empty()) {
            (Some((a, b)), true) => a..b,
            (Some((_, b)), false) => current.queries.start..b,
            (None, _) => current.queries.clone(),
        };
        let grown = (k + 1 - current.pixels.start, terms_end - current.terms.start, queries.len());
        if !current.pixels.is_empty() && !fits(grown.2, grown.1, grown.0) {
            let next = k;
            let done = std::mem::replace(
                &mut current,
                Chunk { pixels: next..next, terms: p.terms[0] as usize..p.terms[0] as usize, queries: 0..0 },
            );
            out.push(done);
            current.queries = span.map_or(0..0, |(a, b)| a..b);
        } else {
            current.queries = queries;
        }
        current.pixels.end = k + 1;
        current.terms.end = terms_end;
    }
    if !current.pixels.is_empty() {
        out.push(current);
    }
    out
}

fn storage(ctx: &GpuContext, label: &str, bytes: &[u8]) -> std::sync::Arc<wgpu::Buffer> {
    let padded;
    // an empty list binds one zeroed element (the largest, a query, is 48 bytes)
    let contents = if bytes.is_empty() {
        padded = [0u8; 48];
        &padded[..]
    } else {
        bytes
    };
    ctx.upload(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage: wgpu::BufferUsages::STORAGE })
}

fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
}

/// The `Params` uniform (see `coherent.wgsl`).
fn params(input: &FrameInput, [queries, pixels, first]: [u32; 3]) -> Vec<u8> {
    let mut words: Vec<u32> = Vec::with_capacity(240);
    let f = |x: f32| x.to_bits();
    let levels = input.voxels.as_ref().map_or(0, |v| v.levels.len());
    words.extend([queries, input.impostors.len() as u32, input.solids.len() as u32, levels as u32]);
    match &input.voxels {
        Some(v) => words.extend([f(v.origin.x), f(v.origin.y), f(v.origin.z), f(v.voxel)]),
        None => words.extend([0; 4]),
    }
    match &input.sky {
        Some(s) => words.extend([s.width, s.height, f(s.rotation), f(input.pi_over_m)]),
        None => words.extend([0, 0, 0, f(input.pi_over_m)]),
    }
    words.extend([pixels, first, input.voxels.as_ref().map_or(0, |v| v.res), 0]);
    let mut first = 0u32;
    for k in 0..MAX_IMPOSTORS {
        match input.impostors.get(k) {
            Some(m) => {
                let far = m.distance.iter().copied().filter(|d| d.is_finite()).fold(0.0f32, f32::max);
                words.extend([f(m.centre.x), f(m.centre.y), f(m.centre.z), f(far), m.size, first, 0, 0]);
                first += m.distance.len() as u32;
            }
            None => words.extend([0; 8]),
        }
    }
    let mut first = 0u32;
    for k in 0..MAX_SOLIDS {
        match input.solids.get(k) {
            Some(s) => {
                words.extend([f(s.origin.x), f(s.origin.y), f(s.origin.z), 0]);
                words.extend([f(s.voxel.x), f(s.voxel.y), f(s.voxel.z), 0]);
                words.extend([s.dims.x, s.dims.y, s.dims.z, first]);
                first += s.tau.len() as u32;
            }
            None => words.extend([0; 12]),
        }
    }
    let mut first = 0u32;
    for k in 0..MAX_LEVELS {
        match input.voxels.as_ref().and_then(|v| v.levels.get(k)) {
            Some(l) => {
                let res = (l.len() as f64).cbrt().round() as u32;
                words.extend([res, first, 0, 0]);
                first += l.len() as u32;
            }
            None => words.extend([0; 4]),
        }
    }
    bytemuck::cast_slice(&words).to_vec()
}
