//! GPU buffers and textures kept from frame to frame ([`GpuContext::buffer`](super::context::GpuContext::buffer),
//! [`GpuContext::texture`](super::context::GpuContext::texture)): a frame's large resources — per-pixel buffers, G-buffers, shadow
//! maps, read-back staging — are taken from the pool instead of made anew, and go back to it when
//! the last handle to them is dropped. A frame of 1024×768 with gi makes several hundred MB of
//! them; made and freed every frame, the allocator makes and frees whole memory blocks (128–256
//! MB on Vulkan) with them, each a driver allocation.
//!
//! A resource is free when the pool holds its only handle (an [`Arc`]): whatever keeps one — a
//! frame still using it, the temporal state of the next frame — keeps it out of the pool, so
//! nothing in use is handed out twice. Work already submitted with a resource that goes back may
//! still be running: a later frame's commands using it run after it, because one queue runs
//! submissions in order.
//!
//! A new resource is zero-filled (WebGPU does that); a reused one holds what its last user left.
//! [`Contents::Zeroed`] clears a reused buffer before it is handed out (a `clear_buffer`
//! recorded into the frame's stream, or submitted at once outside a frame), so it reads as a
//! new one; [`Contents::Overwritten`] hands it out as it
//! is, for a buffer the caller writes in full before reading any of it — in this crate's tests
//! such a buffer is first filled with NaNs, so a read of old contents shows. Textures are
//! handed out as they are: every caller renders each layer it reads with a clear first.
//!
//! Each frame ([`GpuContext::begin_frame`](super::context::GpuContext::begin_frame)) drops the free resources no frame took in the last
//! [`KEPT_FRAMES`] frames, so frames of another size or scene do not pile up, and counts what
//! the frame took new and reused ([`PoolStats`], in each frame's report).

use serde::Serialize;
use std::sync::{Arc, Mutex};

/// Frames a free resource stays in the pool without being taken.
pub const KEPT_FRAMES: u64 = 2;

/// What a caller needs of a buffer's contents when it gets it ([`GpuContext::buffer`](super::context::GpuContext::buffer)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Contents {
    /// Zeros, as a new buffer (a reused one is cleared).
    Zeroed,
    /// Anything: the caller writes every byte before it reads one.
    Overwritten,
}

/// What frames took from the pool since [`GpuContext::begin_frame`](super::context::GpuContext::begin_frame): made anew and reused
/// (counts and bytes), and what the pool holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct PoolStats {
    pub new_count: u64,
    pub new_bytes: u64,
    pub reused_count: u64,
    pub reused_bytes: u64,
    /// Bytes of every resource the pool holds, in use or free.
    pub held_bytes: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct BufferKey {
    pub(super) size: u64,
    pub(super) usage: wgpu::BufferUsages,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct TextureKey {
    size: wgpu::Extent3d,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
    dimension: wgpu::TextureDimension,
    mip_level_count: u32,
    sample_count: u32,
}

struct Entry<K, T> {
    key: K,
    item: Arc<T>,
    bytes: u64,
    last_frame: u64,
}

#[derive(Default)]
struct Inner {
    buffers: Vec<Entry<BufferKey, wgpu::Buffer>>,
    textures: Vec<Entry<TextureKey, wgpu::Texture>>,
    frame: u64,
    stats: PoolStats,
}

/// The pool a [`GpuContext`](super::context::GpuContext) keeps.
#[derive(Default)]
pub struct Pool {
    inner: Mutex<Inner>,
    /// Tests only: reused [`Contents::Overwritten`] buffers handed out as they are, as outside
    /// tests, instead of filled with NaNs first ([`Pool::hand_out_as_shipped`]).
    #[cfg(test)]
    as_shipped: std::sync::atomic::AtomicBool,
}

#[cfg(test)]
impl Pool {
    /// Tests only: hands reused [`Contents::Overwritten`] buffers out as they are (`true`), as
    /// outside tests, so that a test measuring a frame's host time measures the frame as it
    /// ships: the NaN fill writes every such buffer from the host (at the thesis setting about
    /// 0.5 ms of a live dir-lamp-box gi frame's 2.1–2.8 ms on lavapipe).
    pub(super) fn hand_out_as_shipped(&self, on: bool) {
        self.as_shipped.store(on, std::sync::atomic::Ordering::Relaxed);
    }

    /// Whether reused [`Contents::Overwritten`] buffers are filled with NaNs first.
    pub(super) fn poisons(&self) -> bool {
        !self.as_shipped.load(std::sync::atomic::Ordering::Relaxed)
    }
}

/// Takes a free entry of `key` (marking it used this frame), if there is one.
fn take<K: PartialEq, T>(entries: &mut [Entry<K, T>], key: &K, frame: u64) -> Option<(Arc<T>, u64)> {
    let entry = entries.iter_mut().find(|e| e.key == *key && Arc::strong_count(&e.item) == 1)?;
    entry.last_frame = frame;
    Some((entry.item.clone(), entry.bytes))
}

fn held<K, T>(entries: &[Entry<K, T>]) -> u64 {
    entries.iter().map(|e| e.bytes).sum()
}

impl Pool {
    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Starts a frame: forgets free resources unused for [`KEPT_FRAMES`] frames and the last
    /// frame's counts.
    pub fn begin_frame(&self) {
        let mut inner = self.lock();
        inner.frame += 1;
        let oldest = inner.frame.saturating_sub(KEPT_FRAMES);
        let keep = |last: u64, in_use: bool| in_use || last >= oldest;
        inner.buffers.retain(|e| keep(e.last_frame, Arc::strong_count(&e.item) > 1));
        inner.textures.retain(|e| keep(e.last_frame, Arc::strong_count(&e.item) > 1));
        inner.stats = PoolStats::default();
    }

    /// What frames took since the last [`Pool::begin_frame`], and what the pool holds.
    pub fn stats(&self) -> PoolStats {
        let inner = self.lock();
        PoolStats { held_bytes: held(&inner.buffers) + held(&inner.textures), ..inner.stats }
    }

    pub(super) fn buffer(&self, device: &wgpu::Device, label: &str, key: BufferKey) -> (Arc<wgpu::Buffer>, bool) {
        let mut inner = self.lock();
        let frame = inner.frame;
        if let Some((buffer, bytes)) = take(&mut inner.buffers, &key, frame) {
            inner.stats.reused_count += 1;
            inner.stats.reused_bytes += bytes;
            return (buffer, true);
        }
        let buffer = Arc::new(device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: key.size,
            usage: key.usage,
            mapped_at_creation: false,
        }));
        inner.stats.new_count += 1;
        inner.stats.new_bytes += key.size;
        inner.buffers.push(Entry { key, item: buffer.clone(), bytes: key.size, last_frame: frame });
        (buffer, false)
    }

    pub(super) fn texture(&self, device: &wgpu::Device, desc: &wgpu::TextureDescriptor) -> (Arc<wgpu::Texture>, bool) {
        let key = TextureKey {
            size: desc.size,
            format: desc.format,
            usage: desc.usage,
            dimension: desc.dimension,
            mip_level_count: desc.mip_level_count,
            sample_count: desc.sample_count,
        };
        let mut inner = self.lock();
        let frame = inner.frame;
        if let Some((texture, bytes)) = take(&mut inner.textures, &key, frame) {
            inner.stats.reused_count += 1;
            inner.stats.reused_bytes += bytes;
            return (texture, true);
        }
        let texture = Arc::new(device.create_texture(desc));
        let texel = desc.format.block_copy_size(None).unwrap_or(4) as u64;
        let bytes = desc.size.width as u64 * desc.size.height as u64 * desc.size.depth_or_array_layers as u64 * texel;
        inner.stats.new_count += 1;
        inner.stats.new_bytes += bytes;
        inner.textures.push(Entry { key, item: texture.clone(), bytes, last_frame: frame });
        (texture, false)
    }
}

/// Each texture's default view ([`Views::of`]), kept while the texture lives: the pool hands a
/// frame the same textures as the last one, so their views are made once, not every frame (a
/// live frame with gi made about a hundred: its RSMs' targets, read by the VPL candidates).
#[derive(Default)]
pub struct Views {
    /// A weak handle to each texture (one that went away is never mistaken for a new one at
    /// the same address: the handle keeps the address taken) and its view.
    kept: Mutex<Vec<(std::sync::Weak<wgpu::Texture>, Arc<wgpu::TextureView>)>>,
}

impl Views {
    /// `texture`'s default view: the one kept for it, or one made now (and the views of
    /// textures that went away dropped).
    pub fn of(&self, texture: &Arc<wgpu::Texture>) -> Arc<wgpu::TextureView> {
        let mut kept = self.kept.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some((_, view)) = kept.iter().find(|(of, _)| std::ptr::eq(of.as_ptr(), Arc::as_ptr(texture))) {
            return view.clone();
        }
        kept.retain(|(of, _)| of.strong_count() > 0);
        let view = Arc::new(texture.create_view(&Default::default()));
        kept.push((Arc::downgrade(texture), view.clone()));
        view
    }
}
