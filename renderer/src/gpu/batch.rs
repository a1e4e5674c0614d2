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
//!   stream in its place ([`GpuContext::write_ordered`]). Writes into a buffer just taken from
//!   the pool ([`GpuContext::upload`]'s uniforms) go straight to the queue: no pending command
//!   can use such a buffer.
//!
//! Frames on other threads (tests share one context) keep batches of their own.

use super::context::GpuContext;
use super::pool::Contents;
use std::sync::Arc;

/// A thread's frame being recorded: its command buffers in order and the resources it took.
#[derive(Default)]
pub(super) struct Batch {
    commands: Vec<wgpu::CommandBuffer>,
    buffers: Vec<Arc<wgpu::Buffer>>,
    textures: Vec<Arc<wgpu::Texture>>,
    /// Frames begun on this thread and not yet ended (a frame inside another ends with it).
    depth: u32,
}

/// The frame's batch on this thread, ended (its commands submitted) when dropped.
#[must_use = "the frame's commands are submitted when the batch is dropped"]
pub struct FrameBatch<'c> {
    ctx: &'c GpuContext,
}

impl Drop for FrameBatch<'_> {
    fn drop(&mut self) {
        self.ctx.flush();
        let mut batches = self.ctx.batches();
        let id = std::thread::current().id();
        if let Some(batch) = batches.get_mut(&id) {
            batch.depth = batch.depth.saturating_sub(1);
            if batch.depth == 0 {
                batches.remove(&id);
            }
        }
    }
}

impl GpuContext {
    /// Starts holding this thread's command buffers until its next wait or the frame's end.
    pub(super) fn begin_batch(&self) -> FrameBatch<'_> {
        self.batches().entry(std::thread::current().id()).or_default().depth += 1;
        FrameBatch { ctx: self }
    }

    /// Submits `commands` now, or holds them in this thread's frame batch.
    pub(super) fn enqueue(&self, commands: Vec<wgpu::CommandBuffer>) {
        let mut batches = self.batches();
        match batches.get_mut(&std::thread::current().id()) {
            Some(batch) => batch.commands.extend(commands),
            None => {
                drop(batches);
                self.queue_submit(commands);
            }
        }
    }

    /// Submits what this thread's batch holds, in one submission, and lets its resources go.
    pub(super) fn flush(&self) {
        let (commands, buffers, textures) = {
            let mut batches = self.batches();
            let Some(batch) = batches.get_mut(&std::thread::current().id()) else { return };
            (
                std::mem::take(&mut batch.commands),
                std::mem::take(&mut batch.buffers),
                std::mem::take(&mut batch.textures),
            )
        };
        if !commands.is_empty() {
            self.queue_submit(commands);
        }
        // released after the submission: later users are ordered after these commands
        drop((buffers, textures));
    }

    /// Keeps `buffer` out of the pool until this thread's batch is submitted (a no-op outside
    /// a frame).
    pub(super) fn hold_buffer(&self, buffer: &Arc<wgpu::Buffer>) {
        if let Some(batch) = self.batches().get_mut(&std::thread::current().id()) {
            batch.buffers.push(buffer.clone());
        }
    }

    /// Keeps `texture` out of the pool until this thread's batch is submitted.
    pub(super) fn hold_texture(&self, texture: &Arc<wgpu::Texture>) {
        if let Some(batch) = self.batches().get_mut(&std::thread::current().id()) {
            batch.textures.push(texture.clone());
        }
    }

    /// Whether this thread's batch holds commands not yet submitted.
    pub(super) fn has_pending(&self) -> bool {
        self.batches().get(&std::thread::current().id()).is_some_and(|b| !b.commands.is_empty())
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
