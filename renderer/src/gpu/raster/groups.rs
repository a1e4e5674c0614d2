//! The raster passes' bind groups kept from frame to frame ([`super::Raster::bind_group`]): a
//! pass's group binds its view uniform (a buffer [`super::super::context::GpuContext::upload`] takes from the pool,
//! the same buffers again in every frame of a scene) and the scene's materials, so a group made
//! for a pipeline and those two buffers serves every later pass that gets the same two buffers.
//! The buffers are keyed by weak handles: one that went away is never mistaken for a new one
//! at its address (its entry is dropped at the next miss).

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError, Weak};

type Key = (usize, usize, usize);
type Entry = (Weak<wgpu::Buffer>, Weak<wgpu::Buffer>, wgpu::BindGroup);

/// Bind groups by (pipeline, view uniform, materials).
#[derive(Default)]
pub struct KeptGroups {
    groups: Mutex<HashMap<Key, Entry>>,
}

impl KeptGroups {
    /// The group kept for `pipeline` over `uniform` and `materials`, or the one `make` makes
    /// (then kept).
    pub fn get_or_make(
        &self,
        pipeline: &wgpu::RenderPipeline,
        uniform: &Arc<wgpu::Buffer>,
        materials: &Arc<wgpu::Buffer>,
        make: impl FnOnce() -> wgpu::BindGroup,
    ) -> wgpu::BindGroup {
        let key = (pipeline as *const _ as usize, Arc::as_ptr(uniform) as usize, Arc::as_ptr(materials) as usize);
        let mut groups = self.groups.lock().unwrap_or_else(PoisonError::into_inner);
        let alive = |weak: &Weak<wgpu::Buffer>, of: &Arc<wgpu::Buffer>| {
            weak.upgrade().is_some_and(|kept| Arc::ptr_eq(&kept, of))
        };
        if let Some((u, m, group)) = groups.get(&key)
            && alive(u, uniform)
            && alive(m, materials)
        {
            return group.clone();
        }
        groups.retain(|_, (u, m, _)| u.strong_count() > 0 && m.strong_count() > 0);
        let group = make();
        groups.insert(key, (Arc::downgrade(uniform), Arc::downgrade(materials), group.clone()));
        group
    }
}
