//! Per thread, the frame being recorded ([`super::stream`]): its command buffers in order, not
//! yet submitted, and the pooled and resident resources it took, held until they are.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::ThreadId;

/// A thread's frame being recorded: its command buffers in order and the resources it took.
#[derive(Default)]
struct Batch {
    commands: Vec<wgpu::CommandBuffer>,
    held: Held,
    /// Frames begun on this thread and not yet ended (a frame inside another ends with it).
    depth: u32,
}

/// Resources a batch holds until its commands are submitted.
#[derive(Default)]
pub(super) struct Held {
    buffers: Vec<Arc<wgpu::Buffer>>,
    textures: Vec<Arc<wgpu::Texture>>,
}

/// Every thread's batch.
#[derive(Default)]
pub(super) struct Batches {
    threads: Mutex<HashMap<ThreadId, Batch>>,
}

impl Batches {
    fn lock(&self) -> MutexGuard<'_, HashMap<ThreadId, Batch>> {
        self.threads.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Starts (or nests) this thread's batch.
    pub(super) fn begin(&self) {
        self.lock().entry(std::thread::current().id()).or_default().depth += 1;
    }

    /// Ends one frame of this thread's batch; the batch goes with its last (its commands already
    /// taken: [`Batches::take`]).
    pub(super) fn end(&self) {
        let mut threads = self.lock();
        let id = std::thread::current().id();
        if let Some(batch) = threads.get_mut(&id) {
            batch.depth = batch.depth.saturating_sub(1);
            if batch.depth == 0 {
                threads.remove(&id);
            }
        }
    }

    /// Holds `commands` in this thread's batch; gives them back where the thread has none.
    pub(super) fn push(&self, commands: Vec<wgpu::CommandBuffer>) -> Option<Vec<wgpu::CommandBuffer>> {
        match self.lock().get_mut(&std::thread::current().id()) {
            Some(batch) => {
                batch.commands.extend(commands);
                None
            }
            None => Some(commands),
        }
    }

    /// This thread's held commands and resources, taken out of its batch (none outside a frame).
    pub(super) fn take(&self) -> (Vec<wgpu::CommandBuffer>, Held) {
        match self.lock().get_mut(&std::thread::current().id()) {
            Some(batch) => (std::mem::take(&mut batch.commands), std::mem::take(&mut batch.held)),
            None => (Vec::new(), Held::default()),
        }
    }

    /// Keeps `buffer` out of the pool until this thread's batch is submitted (nothing outside a
    /// frame).
    pub(super) fn hold_buffer(&self, buffer: &Arc<wgpu::Buffer>) {
        if let Some(batch) = self.lock().get_mut(&std::thread::current().id()) {
            batch.held.buffers.push(buffer.clone());
        }
    }

    /// Keeps `texture` out of the pool until this thread's batch is submitted.
    pub(super) fn hold_texture(&self, texture: &Arc<wgpu::Texture>) {
        if let Some(batch) = self.lock().get_mut(&std::thread::current().id()) {
            batch.held.textures.push(texture.clone());
        }
    }

    /// Whether this thread's batch holds commands not yet submitted.
    pub(super) fn has_pending(&self) -> bool {
        self.lock().get(&std::thread::current().id()).is_some_and(|b| !b.commands.is_empty())
    }
}
