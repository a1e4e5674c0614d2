//! Compute passes' bind groups kept from frame to frame ([`GpuContext::record_dispatch`]): a
//! dispatch whose pipeline binds the same buffers (at the same offsets and sizes) and texture
//! views as one of the last frames' gets that frame's bind group again instead of a new one
//! (making one costs the host 5–10 µs on lavapipe, and a live frame at the thesis setting
//! dispatches about 40). The pool ([`super::pool`]) hands a frame's passes the same buffers
//! frame after frame while the sizes stay, their uniforms included ([`GpuContext::upload`]
//! writes new contents into the same buffer), and the views of textures are kept with them
//! ([`super::pool::Views`]), so a steady frame makes none.
//!
//! The key holds clones of the pipeline, buffers and views it names: while a group is kept no
//! handle it names can be dropped and its address given to another resource, so equal keys
//! always mean the same resources. Groups no dispatch asked for in the last [`KEPT_FRAMES`]
//! frames are dropped when a frame begins ([`KeptGroups::begin_frame`]).
//!
//! [`GpuContext::record_dispatch`]: super::context::GpuContext::record_dispatch
//! [`GpuContext::upload`]: super::context::GpuContext::upload

use std::collections::HashMap;
use std::sync::Mutex;

/// Frames a kept bind group stays without being asked for.
const KEPT_FRAMES: u64 = 2;

/// Kept groups at most outside frames (work that never begins one: tests of single passes).
const MAX_KEPT: usize = 4096;

/// A resource bound, by identity: a buffer range or a texture view.
#[derive(PartialEq, Eq, Hash)]
enum Bound {
    Buffer(wgpu::Buffer, u64, Option<wgpu::BufferSize>),
    View(wgpu::TextureView),
}

/// A compute pipeline's bind group 0 by what it binds where.
#[derive(PartialEq, Eq, Hash)]
struct Key {
    pipeline: wgpu::ComputePipeline,
    entries: Vec<(u32, Bound)>,
}

/// The kept bind groups and the frame each was last asked for in.
#[derive(Default)]
pub(super) struct KeptGroups {
    inner: Mutex<Inner>,
}

#[derive(Default)]
struct Inner {
    frame: u64,
    groups: HashMap<Key, (wgpu::BindGroup, u64)>,
}

impl KeptGroups {
    /// Counts a frame and drops the groups no dispatch asked for in the last [`KEPT_FRAMES`].
    pub(super) fn begin_frame(&self) {
        let mut inner = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        inner.frame += 1;
        let frame = inner.frame;
        inner.groups.retain(|_, (_, last)| frame - *last <= KEPT_FRAMES);
    }

    /// The bind group 0 of `pipeline` with `entries`: the kept one, or the one `make` makes (kept
    /// when every entry is a buffer range or a texture view; else made each time).
    pub(super) fn get(
        &self,
        pipeline: &wgpu::ComputePipeline,
        entries: &[wgpu::BindGroupEntry],
        make: impl FnOnce() -> wgpu::BindGroup,
    ) -> wgpu::BindGroup {
        let bound: Option<Vec<(u32, Bound)>> = entries
            .iter()
            .map(|entry| match &entry.resource {
                wgpu::BindingResource::Buffer(b) => {
                    Some((entry.binding, Bound::Buffer(b.buffer.clone(), b.offset, b.size)))
                }
                wgpu::BindingResource::TextureView(view) => Some((entry.binding, Bound::View((*view).clone()))),
                _ => None,
            })
            .collect();
        let Some(entries) = bound else { return make() };
        let key = Key { pipeline: pipeline.clone(), entries };
        let mut inner = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        let frame = inner.frame;
        if let Some((group, last)) = inner.groups.get_mut(&key) {
            *last = frame;
            return group.clone();
        }
        if inner.groups.len() >= MAX_KEPT {
            inner.groups.clear();
        }
        let group = make();
        inner.groups.insert(key, (group.clone(), frame));
        group
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;

    /// A group is made once for the same pipeline, buffers, offsets and sizes, again for any other
    /// buffer or range, and again once no frame asked for it in [`KEPT_FRAMES`] frames.
    #[test]
    fn a_group_is_kept_for_the_same_resources_only() {
        let Some(r) = crate::test_support::renderer_or_skip() else { return };
        let ctx = &r.ctx;
        let source = "@group(0) @binding(0) var<storage, read_write> a: array<u32>;
            @compute @workgroup_size(1) fn main() { a[0] = 1u; }";
        let [pipeline] = ctx.compute_pipelines("bind_groups test", source, ["main"]);
        let buffer = |label| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 512,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        let (a, b) = (buffer("kept a"), buffer("kept b"));
        let made = Cell::new(0);
        let kept = KeptGroups::default();
        let get = |binding: wgpu::BindingResource| {
            let entries = [wgpu::BindGroupEntry { binding: 0, resource: binding }];
            kept.get(&pipeline, &entries, || {
                made.set(made.get() + 1);
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: None,
                    layout: &pipeline.get_bind_group_layout(0),
                    entries: &entries,
                })
            })
        };
        let first = get(a.as_entire_binding());
        assert_eq!(get(a.as_entire_binding()), first, "the same buffer's group is kept");
        assert_eq!(made.get(), 1);
        get(b.as_entire_binding());
        assert_eq!(made.get(), 2, "another buffer gets a group of its own");
        let part = wgpu::BufferBinding { buffer: &a, offset: 256, size: wgpu::BufferSize::new(256) };
        get(wgpu::BindingResource::Buffer(part));
        assert_eq!(made.get(), 3, "another range of the same buffer gets a group of its own");
        kept.begin_frame();
        assert_eq!(get(a.as_entire_binding()), first, "kept into the next frame");
        for _ in 0..=KEPT_FRAMES {
            kept.begin_frame();
        }
        get(a.as_entire_binding());
        assert_eq!(made.get(), 4, "dropped after {KEPT_FRAMES} frames without a dispatch asking for it");
    }
}
