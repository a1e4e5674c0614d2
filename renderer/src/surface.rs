//! What the camera sees at a pixel: the G-buffer's surface flag, as the GPU frame reports it
//! ([`crate::gpu::GpuRender::flags`]) and the colour mapping reads it ([`crate::cm::CmInput`]).
//! The shaders write the same numbers (`raster.wgsl`, read back by `cm.wgsl`).

/// No modelled surface (the photograph alone).
pub const NOTHING: u32 = 0;
/// A real surface (its proxy).
pub const REAL: u32 = 1;
/// A virtual surface.
pub const VIRTUAL: u32 = 2;
