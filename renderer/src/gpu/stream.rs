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
//!   the pool ([`GpuContext::upload`]'s uniforms) go straight to the queue: no pending command
//!   can use such a buffer.
//!
//! Frames on other threads (tests share one context) keep batches of their own (`batch`).

use super::context::GpuContext;
use super::pool::Contents;

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
        self.reset_counters();
        self.batches.begin();
        FrameBatch { ctx: self }
    }

    /// Submits `commands` now, or holds them in this thread's frame batch.
    pub(super) fn enqueue(&self, commands: Vec<wgpu::CommandBuffer>) {
        if let Some(commands) = self.batches.push(commands) {
            self.queue_submit(commands);
        }
    }

    /// Submits what this thread's batch holds, in one submission, then lets its resources go
    /// (later users are ordered after these commands).
    pub(super) fn flush(&self) {
        let (commands, held) = self.batches.take();
        if !commands.is_empty() {
            self.queue_submit(commands);
        }
        drop(held);
    }

    /// `data` written into `buffer` at `offset` in the order of the stream: into a staging
    /// buffer taken now (its write runs before the batch's commands; nothing else uses it),
    /// then copied by a command recorded after the batch's commands so far.
    pub(super) fn write_ordered(&self, buffer: &wgpu::Buffer, offset: u64, data: &[u8]) {
        let size = data.len() as u64;
        let staging = self.buffer("ordered write", size.max(4), wgpu::BufferUsages::COPY_SRC, Contents::Overwritten);
        self.write_direct(&staging, 0, data);
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&staging, 0, buffer, offset, size);
        self.submit(encoder);
    }
}
