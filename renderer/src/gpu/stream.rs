//! One command stream per frame (issue 50, Deliver 1): between [`GpuContext::begin_frame`] and
//! the end of the frame (its [`FrameBatch`] dropped), the command buffers a thread's passes
//! submit are held and handed to the queue together, in one `queue.submit`, at the frame's next
//! host wait (a read-back, [`GpuContext::wait`]) or at its end. A live frame that waits once, for
//! its image, so makes one submission; a stimulus frame one per wait (its VPLs and bounces, its
//! colour mapping's sums, its image), and, while passes are timed
//! ([`GpuContext::set_pass_waits`]), one per timed pass.
//!
//! Holding command buffers changes what the host may assume about the order of its own work:
//! - a buffer or texture a pending command uses must not go back to the pool and to another
//!   user before the command is submitted: every resource the pool or the resident buffers hand
//!   out during a batch is held by the batch until its submission (then the queue orders later
//!   users after it, as before);
//! - `queue.write_buffer` runs before the *next* submission's commands, so a write issued after
//!   commands were recorded would land before them: while the thread's batch holds commands,
//!   [`GpuContext::write_buffer`] writes into a fresh staging buffer and records a copy into the
//!   stream in its place (`GpuContext::write_ordered`). Writes into a buffer just taken from
//!   the pool ([`GpuContext::upload`]'s uniforms) need no such order — no pending command can
//!   use such a buffer — so within a frame they are staged on the host and written with one
//!   `queue.write_buffer` when the batch is submitted, and copied into place by the batch's
//!   prelude, whose commands run first (`GpuContext::write_taken`); outside a frame they go
//!   straight to the queue.
//!
//! Frames on other threads (tests share one context) keep batches of their own (`batch`).
//!
//! The passes of a frame also record into one encoder ([`GpuContext::encoder`]): each pass
//! borrows the frame's encoder, records its commands after the commands recorded so far and
//! gives it back ([`GpuContext::submit`]), so a frame finishes one encoder per submission (and
//! its prelude) instead of one per pass (about 38 in a live gi frame at the thesis setting; the
//! one `finish` still encodes every pass: 5–7 µs a pass on lavapipe). The order of
//! the commands is the order of the passes' `submit`s, as with an encoder each. While a pass has
//! the encoder it records only into it: the context's own recording (a pooled buffer cleared,
//! an ordered write, a dispatch or copy of its own) waits until the encoder is given back, except
//! that a buffer just taken from the pool with [`Contents::Zeroed`] is cleared in the batch's
//! prelude, recorded before all its commands (no held command can use such a buffer); debug
//! builds panic where a pass breaks this. While passes are timed with GPU timestamps
//! ([`GpuContext::enable_gpu_timer`]) each pass keeps an encoder of its own, between its
//! timestamps.

use super::context::GpuContext;
use super::pool::Contents;

/// An encoder a pass records into ([`GpuContext::encoder`]): within a frame, the frame's own,
/// lent to the pass until [`GpuContext::submit`] gives it back; else an encoder of its own.
#[must_use = "a pass's commands reach the device when its encoder is submitted"]
pub struct PassEncoder {
    encoder: wgpu::CommandEncoder,
    /// Whether this is the frame's encoder, lent ([`super::batch::Batches::lend`]).
    shared: bool,
}

impl std::ops::Deref for PassEncoder {
    type Target = wgpu::CommandEncoder;
    fn deref(&self) -> &wgpu::CommandEncoder {
        &self.encoder
    }
}

impl std::ops::DerefMut for PassEncoder {
    fn deref_mut(&mut self) -> &mut wgpu::CommandEncoder {
        &mut self.encoder
    }
}

/// The frame's command stream on this thread, submitted when dropped
/// ([`GpuContext::begin_frame`]).
#[must_use = "the frame's commands are submitted when its batch is dropped"]
pub struct FrameBatch<'c> {
    ctx: &'c GpuContext,
}

impl Drop for FrameBatch<'_> {
    fn drop(&mut self) {
        self.ctx.flush();
        self.ctx.batches.end();
    }
}

impl GpuContext {
    /// Starts a frame in the pool ([`super::pool::Pool::begin_frame`]) and its counters
    /// ([`GpuContext::reset_counters`]), and its command stream on this thread: its command
    /// buffers are submitted together at its waits and when the returned batch is dropped.
    pub fn begin_frame(&self) -> FrameBatch<'_> {
        self.release_uploads();
        self.pool.begin_frame();
        self.kept_groups.begin_frame();
        self.reset_counters();
        self.batches.begin();
        FrameBatch { ctx: self }
    }

    /// An encoder for a pass's commands, to be handed to [`GpuContext::submit`]: within a frame
    /// on this thread, the frame's one encoder (see the module documentation), unless passes
    /// are timed with GPU timestamps; else a new one.
    pub fn encoder(&self) -> PassEncoder {
        let make = || self.device.create_command_encoder(&Default::default());
        if !self.timestamps_passes()
            && let Some(encoder) = self.batches.lend(make)
        {
            return PassEncoder { encoder, shared: true };
        }
        PassEncoder { encoder: make(), shared: false }
    }

    /// Submits a pass's commands: the frame's encoder given back to the frame (its commands
    /// run at the frame's next submission); an encoder of its own finished and submitted, or
    /// held in this thread's frame batch. While passes are timed
    /// ([`GpuContext::set_pass_waits`]) with the GPU timer on ([`GpuContext::enable_gpu_timer`]),
    /// timestamps are written just before and just after it (tiny command buffers in the same
    /// submission), for [`GpuContext::take_gpu_ms`].
    pub fn submit(&self, encoder: PassEncoder) {
        if encoder.shared {
            self.batches.give_back(encoder.encoder);
        } else {
            self.submit_timed(encoder.encoder);
        }
    }

    /// Submits `commands` now, or holds them in this thread's frame batch (after the commands
    /// its encoder recorded so far, finished first).
    pub(super) fn enqueue(&self, commands: Vec<wgpu::CommandBuffer>) {
        let mut all: Vec<wgpu::CommandBuffer> =
            self.batches.take_open().map(|open| self.finish(open)).into_iter().collect();
        all.extend(commands);
        if let Some(commands) = self.batches.push(all) {
            self.queue_submit(commands);
        }
    }

    /// Submits what this thread's batch holds, in one submission (its prelude, its command
    /// buffers, its encoder), then lets its resources go (later users are ordered after these
    /// commands).
    pub(super) fn flush(&self) {
        let taken = self.batches.take();
        let prelude = self.copy_staged(taken.staged, taken.prelude);
        let mut commands: Vec<wgpu::CommandBuffer> = prelude.map(|p| self.finish(p)).into_iter().collect();
        commands.extend(taken.commands);
        commands.extend(taken.open.map(|open| self.finish(open)));
        if !commands.is_empty() {
            self.queue_submit(commands);
        }
        drop(taken.held);
    }

    /// `contents` (zero-padded to `size` bytes) written into `buffer`, just taken from the pool
    /// (no held command uses it): within a frame, staged with the batch's other uploads and
    /// copied into place at the start of its submission (one `queue.write_buffer` for all of
    /// them: each costs the host 5–8 µs on lavapipe, and a live frame makes about 50); else
    /// written at once (it runs before the next submission).
    pub(super) fn write_taken(&self, buffer: &std::sync::Arc<wgpu::Buffer>, contents: &[u8], size: u64) {
        if self.batches.stage(buffer, contents, size) {
            self.count_upload(contents.len() as u64);
        } else if contents.len() as u64 == size {
            self.write_direct(buffer, 0, contents);
        } else {
            let mut padded = contents.to_vec();
            padded.resize(size as usize, 0);
            self.write_direct(buffer, 0, &padded);
        }
    }

    /// The batch's staged uploads ([`GpuContext::write_taken`]) written into one staging buffer
    /// from the pool and copied from it by `prelude` (made when there is none), whose commands
    /// run first in the submission.
    fn copy_staged(
        &self,
        staged: super::batch::Staged,
        prelude: Option<wgpu::CommandEncoder>,
    ) -> Option<wgpu::CommandEncoder> {
        if staged.copies.is_empty() {
            return prelude;
        }
        // a size that recurs from frame to frame, so the pool hands the same buffer back
        let size = (staged.bytes.len() as u64).next_power_of_two().max(256);
        let staging = self.buffer("uploads", size, wgpu::BufferUsages::COPY_SRC, Contents::Overwritten);
        // counted when staged
        self.queue.write_buffer(&staging, 0, &staged.bytes);
        let mut prelude = prelude.unwrap_or_else(|| self.device.create_command_encoder(&Default::default()));
        for (buffer, at, size) in &staged.copies {
            prelude.copy_buffer_to_buffer(&staging, *at, buffer, 0, *size);
        }
        Some(prelude)
    }

    /// A buffer just taken from the pool cleared to zeros, in the order of the stream; while a
    /// pass has the frame's encoder, in the batch's prelude (no held command can use the buffer).
    pub(super) fn clear_taken(&self, buffer: &wgpu::Buffer) {
        let make = || self.device.create_command_encoder(&Default::default());
        if self.batches.lent() && self.batches.prelude(make, |e| e.clear_buffer(buffer, 0, None)) {
            return;
        }
        let mut encoder = self.encoder();
        encoder.clear_buffer(buffer, 0, None);
        if encoder.shared {
            self.submit(encoder);
        } else {
            // no pass's work: not between timestamps
            let commands = self.finish(encoder.encoder);
            self.enqueue(vec![commands]);
        }
    }

    /// `data` written into `buffer` at `offset` in the order of the stream: into a staging
    /// buffer taken now (its write runs before the batch's commands; nothing else uses it),
    /// then copied by a command recorded after the batch's commands so far.
    pub(super) fn write_ordered(&self, buffer: &wgpu::Buffer, offset: u64, data: &[u8]) {
        let size = data.len() as u64;
        let staging = self.buffer("ordered write", size.max(4), wgpu::BufferUsages::COPY_SRC, Contents::Overwritten);
        self.write_direct(&staging, 0, data);
        let mut encoder = self.encoder();
        encoder.copy_buffer_to_buffer(&staging, 0, buffer, offset, size);
        self.submit(encoder);
    }
}
