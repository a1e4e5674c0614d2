//! The GPU context: adapter choice (docs/design.md "GPU": a hardware adapter if there is one, else a
//! software Vulkan one — Mesa's lavapipe — else GL, e.g. llvmpipe; `MRSTUDY_ADAPTER=hardware|
//! software|gl` forces a kind), a headless device, and what the host asks of it, counted
//! (read-backs in `gpu::readback`).

pub use super::counters::FrameCounters;
use super::counters::{CounterCells, add_elapsed};
use super::pool::{BufferKey, Contents, PoolStats};
use crate::error::{RenderError, Result};
use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// The features GPU pass timing needs: timestamp queries written between command buffers.
const TIMESTAMPS: wgpu::Features =
    wgpu::Features::TIMESTAMP_QUERY.union(wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS);

/// Uploads held at most outside frames ([`GpuContext::upload`]).
const MAX_HELD_UPLOADS: usize = 4096;

/// Which kind of adapter to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AdapterKind {
    /// A real GPU (discrete, integrated or virtual), any backend.
    Hardware,
    /// A CPU implementation on Vulkan (lavapipe).
    Software,
    /// The GL backend (llvmpipe or a GL driver).
    Gl,
}

impl AdapterKind {
    pub fn parse(text: &str) -> Option<AdapterKind> {
        match text.trim().to_ascii_lowercase().as_str() {
            "hardware" => Some(AdapterKind::Hardware),
            "software" => Some(AdapterKind::Software),
            "gl" => Some(AdapterKind::Gl),
            _ => None,
        }
    }

    fn of(info: &wgpu::AdapterInfo) -> AdapterKind {
        if info.backend == wgpu::Backend::Gl {
            AdapterKind::Gl
        } else if info.device_type == wgpu::DeviceType::Cpu {
            AdapterKind::Software
        } else {
            AdapterKind::Hardware
        }
    }
}

impl fmt::Display for AdapterKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            AdapterKind::Hardware => "hardware",
            AdapterKind::Software => "software",
            AdapterKind::Gl => "gl",
        })
    }
}

/// A headless device and queue on the chosen adapter.
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub kind: AdapterKind,
    /// Whether a frame waits for the device after every pass to time it (the default; see
    /// [`GpuContext::set_pass_waits`]).
    pass_waits: AtomicBool,
    /// GPU timestamps around every submission while passes are timed ([`GpuContext::submit`],
    /// [`GpuContext::take_gpu_ms`]): on a hardware adapter with timestamp queries, or once
    /// [`GpuContext::enable_gpu_timer`] asks for them.
    timer: Mutex<Option<GpuTimer>>,
    /// Buffers and textures kept from frame to frame ([`GpuContext::buffer`]).
    pub(super) pool: super::pool::Pool,
    /// The pool's textures' default views, kept with them ([`super::pool::Views`]).
    pub(super) views: super::pool::Views,
    /// What the host asked of the device since [`GpuContext::reset_counters`].
    counters: CounterCells,
    /// The buffers [`GpuContext::upload`] handed out since the frame began: held until the
    /// next frame begins, so that no later pass of the same frame gets one of them from the
    /// pool and overwrites it before the commands reading it have run.
    uploads: Mutex<Vec<Arc<wgpu::Buffer>>>,
    /// Buffers of a scene's static data, kept from frame to frame ([`GpuContext::resident`]):
    /// per key, what the contents last written were made from and the buffer holding them.
    resident: Mutex<std::collections::HashMap<String, (Held, Arc<wgpu::Buffer>)>>,
    /// Per thread, the frame being recorded: its command buffers, submitted together
    /// ([`super::stream`]).
    pub(super) batches: super::batch::Batches,
    /// Compute passes' bind groups kept from frame to frame ([`super::bind_groups`]).
    pub(super) kept_groups: super::bind_groups::KeptGroups,
}

/// What a resident buffer's contents were made from ([`GpuContext::resident`],
/// [`GpuContext::resident_for`]): the bytes themselves, or a value they are made of.
enum Held {
    Bytes(Vec<u8>),
    Source(Box<dyn std::any::Any + Send>),
}

/// Timestamp queries written before and after each command buffer submitted since the last
/// [`GpuContext::take_gpu_ms`]: pairs (begin, end) in `queries`.
struct GpuTimer {
    queries: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    written: u32,
    /// Nanoseconds per timestamp tick.
    period_ns: f64,
}

/// Timestamp queries per timed pass (two per submission); submissions beyond them go untimed
/// and the pass reports no GPU time rather than part of it.
const TIMER_QUERIES: u32 = 512;

impl GpuContext {
    /// Opens the adapter chosen by `MRSTUDY_ADAPTER`, or the best one available.
    pub fn new() -> Result<GpuContext> {
        let forced = match std::env::var("MRSTUDY_ADAPTER") {
            Ok(v) if !v.trim().is_empty() => Some(AdapterKind::parse(&v).ok_or_else(|| {
                RenderError::Unsupported(format!("MRSTUDY_ADAPTER is `{v}`; expected hardware, software or gl"))
            })?),
            _ => None,
        };
        GpuContext::with_kind(forced)
    }

    /// Opens an adapter of the given kind, or the best available when `None`.
    pub fn with_kind(forced: Option<AdapterKind>) -> Result<GpuContext> {
        let order = match forced {
            Some(kind) => vec![kind],
            None => vec![AdapterKind::Hardware, AdapterKind::Software, AdapterKind::Gl],
        };
        // Vulkan first; the GL backend is probed only when Vulkan has nothing of a wanted kind
        // (probing GL without a display prints EGL complaints on headless machines)
        let mut adapters = enumerate(wgpu::Backends::VULKAN);
        let pick = |adapters: &[wgpu::Adapter]| {
            order.iter().find_map(|kind| {
                adapters
                    .iter()
                    .find(|a| AdapterKind::of(&a.get_info()) == *kind && renders_float_targets(a))
                    .map(|a| (a.clone(), *kind))
            })
        };
        let mut chosen = pick(&adapters);
        if chosen.is_none() {
            adapters.extend(enumerate(wgpu::Backends::GL));
            chosen = pick(&adapters);
        }
        let found: Vec<String> = adapters
            .iter()
            .map(|a| {
                if renders_float_targets(a) {
                    describe(&a.get_info())
                } else {
                    format!("{} without 32-bit float render targets", describe(&a.get_info()))
                }
            })
            .collect();
        let Some((adapter, kind)) = chosen else {
            let wanted = forced.map(|k| format!("{k} adapter")).unwrap_or_else(|| "GPU adapter".into());
            let seen = if found.is_empty() { "none".to_string() } else { found.join("; ") };
            return Err(RenderError::Unsupported(format!(
                "no {wanted} could be opened (adapters found: {seen}); install Mesa's lavapipe (`apt-get install mesa-vulkan-drivers`) for the software one"
            )));
        };
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("mrstudy"),
            required_features: adapter.features() & TIMESTAMPS,
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| RenderError::Unsupported(format!("the adapter {} refused a device: {e}", describe(&info))))?;
        let ctx = GpuContext {
            device,
            queue,
            info,
            kind,
            pass_waits: AtomicBool::new(true),
            timer: Mutex::new(None),
            pool: Default::default(),
            views: Default::default(),
            counters: Default::default(),
            uploads: Mutex::new(Vec::new()),
            resident: Mutex::new(Default::default()),
            batches: Default::default(),
            kept_groups: Default::default(),
        };
        // lavapipe writes some timestamps without waiting for the compute dispatch before them
        // (the bounce pass's search: 15 ms of wall-clock time at 1024 candidates, 528 ms at
        // 65 536 — 500 ms of it waiting for the device after the dispatch — while its
        // timestamps stayed under 0.06 ms; draws and the shading dispatch are timed right), so
        // a software adapter's GPU times could mislead: they are taken on hardware only,
        // unless asked for
        if kind == AdapterKind::Hardware {
            ctx.enable_gpu_timer();
        }
        Ok(ctx)
    }

    /// Turns GPU timestamps around timed passes' submissions on, where the device has timestamp
    /// queries (on by itself on a hardware adapter; on lavapipe they miss some compute
    /// dispatches); whether they are on.
    pub fn enable_gpu_timer(&self) -> bool {
        if !self.device.features().contains(TIMESTAMPS) {
            return false;
        }
        let mut timer = self.timer.lock().unwrap_or_else(|e| e.into_inner());
        if timer.is_none() {
            *timer = Some(GpuTimer {
                queries: self.device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("pass timestamps"),
                    ty: wgpu::QueryType::Timestamp,
                    count: TIMER_QUERIES,
                }),
                resolve: self.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("pass timestamps resolved"),
                    size: TIMER_QUERIES as u64 * 8,
                    usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                }),
                written: 0,
                period_ns: self.queue.get_timestamp_period() as f64,
            });
        }
        true
    }

    /// Submits one pass's own encoder ([`GpuContext::submit`]), between timestamps while passes
    /// are timed with the GPU timer on. Within a frame the command buffer is held and submitted
    /// with the frame's others at its next wait ([`super::stream`]).
    pub(super) fn submit_timed(&self, encoder: wgpu::CommandEncoder) {
        let commands = self.finish(encoder);
        let mut guard = self.timer.lock().unwrap_or_else(|e| e.into_inner());
        let Some(timer) = guard.as_mut().filter(|_| self.pass_waits()) else {
            drop(guard);
            self.enqueue(vec![commands]);
            return;
        };
        if timer.written + 2 > TIMER_QUERIES {
            // more submissions than queries: the pass's GPU time is not reported
            timer.written = TIMER_QUERIES + 1;
            self.enqueue(vec![commands]);
            return;
        }
        let marker = |index: u32| {
            let mut encoder = self.device.create_command_encoder(&Default::default());
            encoder.write_timestamp(&timer.queries, index);
            self.finish(encoder)
        };
        let (begin, end) = (marker(timer.written), marker(timer.written + 1));
        timer.written += 2;
        self.enqueue(vec![begin, commands, end]);
    }

    /// Whether passes are timed with GPU timestamps around each one's command buffer (then
    /// each pass records into an encoder of its own: [`GpuContext::encoder`]).
    pub(super) fn timestamps_passes(&self) -> bool {
        self.pass_waits() && self.has_gpu_timer()
    }

    /// `encoder.finish()`, counted (`encoders`) and its time counted as recording (`record_ms`).
    pub(super) fn finish(&self, encoder: wgpu::CommandEncoder) -> wgpu::CommandBuffer {
        self.counters.encoders.fetch_add(1, Ordering::Relaxed);
        let start = Instant::now();
        let commands = encoder.finish();
        add_elapsed(&self.counters.record_ns, start);
        commands
    }

    /// `queue.submit`, counted (`submits`) and its time counted (`submit_ms`).
    pub(super) fn queue_submit(&self, commands: Vec<wgpu::CommandBuffer>) {
        self.counters.submits.fetch_add(1, Ordering::Relaxed);
        let start = Instant::now();
        self.queue.submit(commands);
        add_elapsed(&self.counters.submit_ns, start);
    }

    /// A bind group made anew, its time counted as recording (`record_ms`).
    pub fn bind_group(&self, desc: &wgpu::BindGroupDescriptor) -> wgpu::BindGroup {
        let start = Instant::now();
        let bind_group = self.device.create_bind_group(desc);
        add_elapsed(&self.counters.record_ns, start);
        bind_group
    }

    /// The GPU's time in milliseconds over the command buffers [`GpuContext::submit`]ted since
    /// the last call (the sum of each one's end minus begin timestamp), then forgets them.
    /// `None` with the timer off, when nothing was submitted, or when a pass submitted more
    /// command buffers than the queries hold. Waits for the device.
    pub fn take_gpu_ms(&self) -> Option<f64> {
        let mut guard = self.timer.lock().unwrap_or_else(|e| e.into_inner());
        let timer = guard.as_mut()?;
        let written = std::mem::take(&mut timer.written);
        if written == 0 || written > TIMER_QUERIES {
            return None;
        }
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("pass timestamps read back"),
            size: written as u64 * 8,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.resolve_query_set(&timer.queries, 0..written, &timer.resolve, 0);
        encoder.copy_buffer_to_buffer(&timer.resolve, 0, &staging, 0, written as u64 * 8);
        // not through `submit`: this copy is no pass's work (and the timer is locked)
        self.enqueue(vec![self.finish(encoder)]);
        let ticks: Vec<u64> = self.mapped(&staging, |bytes| {
            bytes.chunks_exact(8).map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes"))).collect()
        })?;
        let total: u64 = ticks.chunks_exact(2).map(|pair| pair[1].saturating_sub(pair[0])).sum();
        Some(total as f64 * timer.period_ns * 1e-6)
    }

    /// Whether this device writes GPU timestamps around timed passes' submissions.
    pub fn has_gpu_timer(&self) -> bool {
        self.timer.lock().unwrap_or_else(|e| e.into_inner()).is_some()
    }

    /// Compiles the WGSL `source` (named `name` in errors) and one compute pipeline per entry
    /// point, each with the bind-group layout the shader implies.
    pub fn compute_pipelines<const N: usize>(
        &self,
        name: &str,
        source: &str,
        entries: [&str; N],
    ) -> [wgpu::ComputePipeline; N] {
        let module = self.device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(name),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
        entries.map(|entry| {
            self.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        })
    }

    /// Runs one compute pass ([`GpuContext::record_dispatch`]), submitted alone.
    pub fn dispatch(
        &self,
        label: &str,
        pipeline: &wgpu::ComputePipeline,
        entries: &[wgpu::BindGroupEntry],
        groups: [u32; 2],
    ) {
        let mut encoder = self.encoder();
        self.record_dispatch(&mut encoder, label, pipeline, entries, groups);
        self.submit(encoder);
    }

    /// Records one compute pass into `encoder`: `pipeline` over `groups` workgroups (x, y) with
    /// bind group 0 made of `entries` in the pipeline's own layout (kept from frame to frame
    /// while it binds the same resources: `gpu::bind_groups`).
    pub fn record_dispatch(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        label: &str,
        pipeline: &wgpu::ComputePipeline,
        entries: &[wgpu::BindGroupEntry],
        groups: [u32; 2],
    ) {
        let start = Instant::now();
        let bind_group = self.kept_groups.get(pipeline, entries, || {
            self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout: &pipeline.get_bind_group_layout(0),
                entries,
            })
        });
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.dispatch_workgroups(groups[0], groups[1], 1);
        drop(pass);
        add_elapsed(&self.counters.record_ns, start);
    }

    /// The adapter in words, for reports: name, backend and kind.
    pub fn adapter_name(&self) -> String {
        describe(&self.info)
    }

    /// On (the default): every pass of a frame waits for the device and is timed, so a frame's
    /// report says where its time went. Off: passes are only submitted, in order, and the
    /// frame waits where it needs data back (a stimulus's VPLs and bounces, the composite; a
    /// live frame only for its image) — a pipelined frame, whose report lists only its CPU steps. The
    /// images are the same either way (wgpu runs submissions in order); only the timing
    /// differs. `bench render --frame-rate` measures both.
    pub fn set_pass_waits(&self, on: bool) {
        self.pass_waits.store(on, Ordering::Relaxed);
    }

    /// Whether frames wait for the device after every pass ([`GpuContext::set_pass_waits`]).
    pub fn pass_waits(&self) -> bool {
        self.pass_waits.load(Ordering::Relaxed)
    }

    /// Blocks until the GPU has finished all submitted work (counted as a host wait), this
    /// thread's frame batch submitted first.
    pub fn wait(&self) {
        self.flush();
        let start = Instant::now();
        let _ = self.device.poll(wgpu::PollType::wait_indefinitely());
        self.counters.host_waits.fetch_add(1, Ordering::Relaxed);
        self.counters.wait_ns.fetch_add(start.elapsed().as_nanos() as u64, Ordering::Relaxed);
    }

    /// Forgets the counts ([`GpuContext::counters`]); each frame starts with it.
    pub fn reset_counters(&self) {
        let c = &self.counters;
        for cell in [
            &c.submits,
            &c.encoders,
            &c.host_waits,
            &c.readback_bytes,
            &c.upload_bytes,
            &c.allocations,
            &c.wait_ns,
            &c.record_ns,
            &c.submit_ns,
        ] {
            cell.store(0, Ordering::Relaxed);
        }
    }

    /// What the host asked of the device since [`GpuContext::reset_counters`] (`cpu_ms` and
    /// `host_steps_ms` are left 0: the frame fills them in, [`FrameCounters::with_cpu_ms`]).
    pub fn counters(&self) -> FrameCounters {
        let c = &self.counters;
        FrameCounters {
            submits: c.submits.load(Ordering::Relaxed),
            encoders: c.encoders.load(Ordering::Relaxed),
            host_waits: c.host_waits.load(Ordering::Relaxed),
            readback_bytes: c.readback_bytes.load(Ordering::Relaxed),
            upload_bytes: c.upload_bytes.load(Ordering::Relaxed),
            allocations: c.allocations.load(Ordering::Relaxed),
            cpu_ms: 0.0,
            wait_ms: c.wait_ns.load(Ordering::Relaxed) as f64 * 1e-6,
            record_ms: c.record_ns.load(Ordering::Relaxed) as f64 * 1e-6,
            submit_ms: c.submit_ns.load(Ordering::Relaxed) as f64 * 1e-6,
            host_steps_ms: 0.0,
        }
    }

    /// A buffer made anew (counted as an allocation; see [`GpuContext::buffer`] for one from
    /// the pool).
    pub fn create_buffer(&self, desc: &wgpu::BufferDescriptor) -> wgpu::Buffer {
        self.counters.allocations.fetch_add(1, Ordering::Relaxed);
        self.device.create_buffer(desc)
    }

    /// A buffer made anew with `desc.contents` (counted as an allocation and an upload).
    pub fn create_buffer_init(&self, desc: &wgpu::util::BufferInitDescriptor) -> wgpu::Buffer {
        use wgpu::util::DeviceExt;
        self.counters.allocations.fetch_add(1, Ordering::Relaxed);
        self.counters.upload_bytes.fetch_add(desc.contents.len() as u64, Ordering::Relaxed);
        self.device.create_buffer_init(desc)
    }

    /// A buffer holding `desc.contents` (zero-padded to a multiple of 4 bytes, as
    /// `create_buffer_init` pads), taken from the pool and written by `write_buffer` (counted as
    /// an upload; as an allocation only where the pool had none of its size and usage): after a
    /// scene's first frame, uniforms and per-frame data allocate nothing. It is held until the
    /// next [`GpuContext::begin_frame`] (see `uploads`).
    pub fn upload(&self, desc: &wgpu::util::BufferInitDescriptor) -> Arc<wgpu::Buffer> {
        let size =
            (desc.contents.len() as u64).div_ceil(wgpu::COPY_BUFFER_ALIGNMENT).max(1) * wgpu::COPY_BUFFER_ALIGNMENT;
        let buffer = self.buffer(desc.label.unwrap_or("upload"), size, desc.usage, Contents::Overwritten);
        // just taken from the pool: no pending command uses it ([`super::stream`])
        self.write_taken(&buffer, desc.contents, size);
        let mut uploads = self.uploads.lock().unwrap_or_else(|e| e.into_inner());
        if uploads.len() >= MAX_HELD_UPLOADS {
            // work that never begins a frame (tests of single passes): the oldest are long submitted
            uploads.drain(..MAX_HELD_UPLOADS / 2);
        }
        uploads.push(buffer.clone());
        buffer
    }

    /// A buffer holding `contents` (zero-padded to a multiple of 4 bytes) for data that stays
    /// the same from frame to frame — a scene's mesh, its point clouds' distributions, its
    /// environment map, the photograph — kept under `key` (one key per use in a frame): when
    /// the last contents under `key` are these bytes (compared on the host), the same buffer
    /// again, with no upload and no allocation. Otherwise the bytes are written (an upload)
    /// into the kept buffer where it has their size, usage and no other holder (every frame
    /// that used it has submitted its work, which the write is queued after), else into a new
    /// one (an allocation; a frame still recording keeps the old one).
    pub fn resident(&self, key: &str, contents: &[u8], usage: wgpu::BufferUsages) -> Arc<wgpu::Buffer> {
        let unchanged = |held: &mut Held| matches!(held, Held::Bytes(bytes) if bytes.as_slice() == contents);
        self.resident_where(key, usage, unchanged, || {
            (std::borrow::Cow::Borrowed(contents), Held::Bytes(contents.to_vec()))
        })
    }

    /// As [`GpuContext::resident`], for contents made from what the frame has, `probe`: `same`
    /// says whether the value kept under `key` (`S`, what `make` returned with the contents
    /// last written) still stands for `probe` (and may replace it with an equal one that
    /// proves it more cheaply next time), and `make` runs only when it does not — so a
    /// frame whose source did not change neither makes nor compares the bytes (the
    /// photograph's texels: 12.6 MB at 1024×768), and `same` can prove it cheaply (the
    /// photograph: the same `Arc`, kept alive here so that it cannot have changed).
    pub fn resident_for<S: Send + 'static, P: ?Sized>(
        &self,
        key: &str,
        probe: &P,
        same: impl Fn(&mut S, &P) -> bool,
        usage: wgpu::BufferUsages,
        make: impl FnOnce(&P) -> (Vec<u8>, S),
    ) -> Arc<wgpu::Buffer> {
        let unchanged = |held: &mut Held| match held {
            Held::Source(held) => held.downcast_mut::<S>().is_some_and(|held| same(held, probe)),
            Held::Bytes(_) => false,
        };
        self.resident_where(key, usage, unchanged, || {
            let (contents, kept) = make(probe);
            (std::borrow::Cow::Owned(contents), Held::Source(Box::new(kept)))
        })
    }

    /// The buffer kept under `key` when `unchanged` says its contents are still wanted; else
    /// the contents `make` returns written into it or into a new one ([`GpuContext::resident`]).
    fn resident_where<'c>(
        &self,
        key: &str,
        usage: wgpu::BufferUsages,
        unchanged: impl FnOnce(&mut Held) -> bool,
        make: impl FnOnce() -> (std::borrow::Cow<'c, [u8]>, Held),
    ) -> Arc<wgpu::Buffer> {
        let usage = usage | wgpu::BufferUsages::COPY_DST;
        let mut resident = self.resident.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((held, buffer)) = resident.get_mut(key)
            && buffer.usage() == usage
            && unchanged(held)
        {
            self.batches.hold_buffer(buffer);
            return buffer.clone();
        }
        let (contents, held) = make();
        let size = (contents.len() as u64).div_ceil(wgpu::COPY_BUFFER_ALIGNMENT).max(1) * wgpu::COPY_BUFFER_ALIGNMENT;
        if let Some((kept, buffer)) = resident.get_mut(key)
            && buffer.size() == size
            && buffer.usage() == usage
            && Arc::strong_count(buffer) == 1
        {
            self.write_padded(buffer, &contents, size);
            *kept = held;
            self.batches.hold_buffer(buffer);
            return buffer.clone();
        }
        let buffer = Arc::new(self.create_buffer(&wgpu::BufferDescriptor {
            label: Some(key),
            size,
            usage,
            mapped_at_creation: false,
        }));
        self.write_padded(&buffer, &contents, size);
        self.batches.hold_buffer(&buffer);
        resident.insert(key.to_string(), (held, buffer.clone()));
        buffer
    }

    /// `contents` written at the start of `buffer`, zero-padded to `size` bytes.
    fn write_padded(&self, buffer: &wgpu::Buffer, contents: &[u8], size: u64) {
        if contents.len() as u64 == size {
            self.write_buffer(buffer, 0, contents);
        } else {
            let mut padded = contents.to_vec();
            padded.resize(size as usize, 0);
            self.write_buffer(buffer, 0, &padded);
        }
    }

    /// Lets the last frame's uploads go back to the pool ([`GpuContext::upload`]).
    pub(super) fn release_uploads(&self) {
        self.uploads.lock().unwrap_or_else(|e| e.into_inner()).clear();
    }

    /// A texture made anew (counted as an allocation; see [`GpuContext::texture`] for one from
    /// the pool).
    pub fn create_texture(&self, desc: &wgpu::TextureDescriptor) -> wgpu::Texture {
        self.counters.allocations.fetch_add(1, Ordering::Relaxed);
        self.device.create_texture(desc)
    }

    /// `queue.write_buffer`, counted as an upload; while this thread's frame holds commands
    /// not yet submitted, written in the stream's order instead ([`super::stream`]).
    pub fn write_buffer(&self, buffer: &wgpu::Buffer, offset: u64, data: &[u8]) {
        if self.batches.has_pending() {
            self.write_ordered(buffer, offset, data);
        } else {
            self.write_direct(buffer, offset, data);
        }
    }

    /// Counts `bytes` mapped and copied back to the host.
    pub(super) fn count_readback(&self, bytes: u64) {
        self.counters.readback_bytes.fetch_add(bytes, Ordering::Relaxed);
    }

    /// Counts `bytes` uploaded.
    pub(super) fn count_upload(&self, bytes: u64) {
        self.counters.upload_bytes.fetch_add(bytes, Ordering::Relaxed);
    }

    /// `queue.write_buffer`, counted as an upload (it runs before the next submission).
    pub(super) fn write_direct(&self, buffer: &wgpu::Buffer, offset: u64, data: &[u8]) {
        self.count_upload(data.len() as u64);
        self.queue.write_buffer(buffer, offset, data);
    }

    /// `queue.write_texture`, counted as an upload.
    pub fn write_texture(
        &self,
        texture: wgpu::TexelCopyTextureInfo,
        data: &[u8],
        layout: wgpu::TexelCopyBufferLayout,
        size: wgpu::Extent3d,
    ) {
        // it runs before the next submission: after this thread's recorded commands
        self.flush();
        self.counters.upload_bytes.fetch_add(data.len() as u64, Ordering::Relaxed);
        self.queue.write_texture(texture, data, layout, size);
    }

    /// Counts one pooled resource made anew ([`super::pool`]).
    pub(super) fn count_allocation(&self) {
        self.counters.allocations.fetch_add(1, Ordering::Relaxed);
    }
}

/// The G-buffer and shadow maps render to `Rgba32Float` and `R32Float` (GL ES often cannot).
fn renders_float_targets(adapter: &wgpu::Adapter) -> bool {
    [wgpu::TextureFormat::Rgba32Float, wgpu::TextureFormat::R32Float].iter().all(|f| {
        adapter.get_texture_format_features(*f).allowed_usages.contains(wgpu::TextureUsages::RENDER_ATTACHMENT)
    })
}

fn enumerate(backends: wgpu::Backends) -> Vec<wgpu::Adapter> {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = backends;
    let instance = wgpu::Instance::new(desc);
    pollster::block_on(instance.enumerate_adapters(backends))
}

fn describe(info: &wgpu::AdapterInfo) -> String {
    format!("{} ({:?}, {})", info.name, info.backend, AdapterKind::of(info))
}

/// The pool's side of the context ([`super::pool`]): the pool knows nothing of the context.
impl GpuContext {
    /// A buffer of `size` bytes and `usage` from the pool (see the module
    /// documentation): a free one of the same size and usage, or a new one. With
    /// [`Contents::Zeroed`] it reads as zeros. It gets `COPY_DST` besides `usage`, to be cleared.
    pub fn buffer(&self, label: &str, size: u64, usage: wgpu::BufferUsages, contents: Contents) -> Arc<wgpu::Buffer> {
        let usage = usage | wgpu::BufferUsages::COPY_DST;
        let key = BufferKey { size, usage };
        let (buffer, reused) = self.pool.buffer(&self.device, label, key);
        if !reused {
            self.count_allocation();
        }
        if reused {
            match contents {
                Contents::Zeroed => self.clear_taken(&buffer),
                #[cfg(test)]
                Contents::Overwritten if self.pool.poisons() => {
                    // old contents read by mistake show as NaNs (just taken: no pending command
                    // uses it)
                    self.queue.write_buffer(&buffer, 0, &vec![0xffu8; key.size as usize]);
                }
                Contents::Overwritten => {}
            }
        }
        self.batches.hold_buffer(&buffer);
        buffer
    }

    /// A texture of `desc` from the pool (see the module documentation), as its last user left
    /// it: the caller renders every layer it reads with a clear first.
    pub fn texture(&self, desc: &wgpu::TextureDescriptor) -> Arc<wgpu::Texture> {
        let (texture, reused) = self.pool.texture(&self.device, desc);
        if !reused {
            self.count_allocation();
        }
        self.batches.hold_texture(&texture);
        texture
    }

    /// What frames took from the pool since [`GpuContext::begin_frame`].
    pub fn pool_stats(&self) -> PoolStats {
        self.pool.stats()
    }
}
