//! Per thread, the frame being recorded ([`super::stream`]): its command buffers in order, not
//! yet submitted, the encoder its passes record into, and the pooled and resident resources it
//! took, held until they are.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::ThreadId;

/// A thread's frame being recorded: its command buffers in order, the encoder recording after
/// them, and the resources it took.
#[derive(Default)]
struct Batch {
    commands: Vec<wgpu::CommandBuffer>,
    /// The frame's encoder: the commands recorded after `commands`, lent to one pass at a time
    /// ([`Batches::lend`]).
    open: Option<wgpu::CommandEncoder>,
    /// Whether `open` is lent to a pass now.
    lent: bool,
    /// Clears of buffers just taken from the pool while the encoder was lent (no held command
    /// uses such a buffer, so they may run first in the submission: [`Batches::prelude`]).
    prelude: Option<wgpu::CommandEncoder>,
    /// Uploads into buffers just taken from the pool ([`Batches::stage`]): their bytes one
    /// after another, and where each goes.
    staged: Staged,
    held: Held,
    /// Frames begun on this thread and not yet ended (a frame inside another ends with it).
    depth: u32,
}

/// Uploads staged in a batch: their bytes one after another, and per upload its buffer, where
/// its bytes start and how many there are.
#[derive(Default)]
pub(super) struct Staged {
    pub(super) bytes: Vec<u8>,
    pub(super) copies: Vec<(Arc<wgpu::Buffer>, u64, u64)>,
}

/// A batch's commands and resources taken out of it to be submitted ([`Batches::take`]).
#[derive(Default)]
pub(super) struct Taken {
    pub(super) staged: Staged,
    pub(super) prelude: Option<wgpu::CommandEncoder>,
    pub(super) commands: Vec<wgpu::CommandBuffer>,
    pub(super) open: Option<wgpu::CommandEncoder>,
    pub(super) held: Held,
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

    /// This thread's held commands, in the order they run (the prelude, the command buffers,
    /// the open encoder), and its resources, taken out of its batch (none outside a frame).
    pub(super) fn take(&self) -> Taken {
        match self.lock().get_mut(&std::thread::current().id()) {
            Some(batch) => {
                debug_assert!(!batch.lent, "the frame's commands submitted while a pass records into its encoder");
                Taken {
                    staged: std::mem::take(&mut batch.staged),
                    prelude: batch.prelude.take(),
                    commands: std::mem::take(&mut batch.commands),
                    open: batch.open.take(),
                    held: std::mem::take(&mut batch.held),
                }
            }
            None => Taken::default(),
        }
    }

    /// This thread's open encoder, taken out of its batch to be finished before command buffers
    /// recorded after it are held (none outside a frame, or when none is open).
    pub(super) fn take_open(&self) -> Option<wgpu::CommandEncoder> {
        let mut threads = self.lock();
        let batch = threads.get_mut(&std::thread::current().id())?;
        debug_assert!(!batch.lent, "a command buffer held while a pass records into the frame's encoder");
        batch.open.take()
    }

    /// Lends this thread's frame encoder (the open one, or one `make` makes) to a pass, which
    /// gives it back ([`Batches::give_back`]) when it has recorded its commands. `None` outside a
    /// frame, and when it is lent already (a pass recording while another records: their
    /// commands could not keep the order of their submissions; debug builds panic).
    pub(super) fn lend(&self, make: impl FnOnce() -> wgpu::CommandEncoder) -> Option<wgpu::CommandEncoder> {
        let mut threads = self.lock();
        let batch = threads.get_mut(&std::thread::current().id())?;
        debug_assert!(!batch.lent, "a pass records into the frame's encoder while another pass has it");
        if batch.lent {
            return None;
        }
        batch.lent = true;
        Some(batch.open.take().unwrap_or_else(make))
    }

    /// The frame's encoder back from the pass it was lent to ([`Batches::lend`]).
    pub(super) fn give_back(&self, encoder: wgpu::CommandEncoder) {
        if let Some(batch) = self.lock().get_mut(&std::thread::current().id()) {
            batch.open = Some(encoder);
            batch.lent = false;
        }
    }

    /// Stages `contents`, zero-padded to `size` bytes (a multiple of 4), for `buffer` (just taken
    /// from the pool: no held command uses it), to be copied into it at the start of the batch's
    /// submission; false outside a frame.
    pub(super) fn stage(&self, buffer: &Arc<wgpu::Buffer>, contents: &[u8], size: u64) -> bool {
        let mut threads = self.lock();
        let Some(batch) = threads.get_mut(&std::thread::current().id()) else { return false };
        let staged = &mut batch.staged;
        let at = staged.bytes.len();
        staged.bytes.extend_from_slice(contents);
        staged.bytes.resize(at + size as usize, 0);
        staged.copies.push((buffer.clone(), at as u64, size));
        true
    }

    /// Whether this thread's frame encoder is lent to a pass now.
    pub(super) fn lent(&self) -> bool {
        self.lock().get(&std::thread::current().id()).is_some_and(|b| b.lent)
    }

    /// Records `record` into this thread's prelude (made by `make` when there is none), whose
    /// commands run first in the batch's submission; false outside a frame.
    pub(super) fn prelude(
        &self,
        make: impl FnOnce() -> wgpu::CommandEncoder,
        record: impl FnOnce(&mut wgpu::CommandEncoder),
    ) -> bool {
        let mut threads = self.lock();
        let Some(batch) = threads.get_mut(&std::thread::current().id()) else { return false };
        record(batch.prelude.get_or_insert_with(make));
        true
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
        self.lock().get(&std::thread::current().id()).is_some_and(|b| {
            !b.commands.is_empty() || b.open.is_some() || b.lent || b.prelude.is_some() || !b.staged.copies.is_empty()
        })
    }
}
