//! `mrstudy-renderer`: scenes, the simulated camera, the CPU reference path tracer and image
//! metrics, and the GPU differential-rendering pipeline ([`gpu`]: differential instant radiosity
//! on wgpu, with the colour mapping of [`cm`] and the camera-artifact factor [`ca`]).
//!
//! Invariant: the renderer knows nothing of studies, participants or HTTP. It turns a scene into
//! images, masks, timings and errors.
//!
//! Code map:
//! - `bench` (feature `bench`): the benchmarks behind `mrstudy bench render` (GPU frame time and error, the
//!   path tracer's convergence, ca and cm accuracy), each a typed report.
//! - [`scene`]: the scene file (TOML) schema and its resolution into world-space [`scene::Scene`];
//!   [`scene::desc`] is the schema, [`builtin`] (`scene::builtin`) the built-in scenes (survey set, DIR test scenes, lab task scene).
//! - [`geometry`], [`bvh`], [`mesh`]: primitives, a binned-SAH BVH, glTF/OBJ loading.
//! - [`material`]: Lambert plus energy-conserving Blinn–Phong, textures, emission.
//! - [`light`]: spot, point, area (emissive triangles) and environment lights (HDR/EXR maps,
//!   equirectangular or fish-eye, or a procedural sky with a window).
//! - [`camera`]: pinhole intrinsics (field of view or K) and pose.
//! - [`pathtracer`]: the unbiased CPU reference path tracer (NEE + MIS, rayon, progressive,
//!   deterministic per seed).
//! - [`reference`](mod@reference): the photograph, the ground-truth composite, HDR buffers and masks.
//! - [`sensor`]: the simulated camera (exposure … JPEG) with presets `webcam`, `phone`, `clean`.
//! - [`ca`]: the `ca` factor — Klein & Murray's camera chain on the virtual layers (CPU reference;
//!   the GPU pass is [`gpu::ca`]) and single-image estimators of noise, blur and JPEG
//!   quality ([`ca::estimate`]).
//! - [`metrics`]: RMSE/PSNR (linear and display), SSIM and FLIP, over the image or a mask.
//! - [`image`]: linear RGB float images, masks, PNG/EXR input and output.
//! - [`stimulus`]: a scene configuration under a study's factor levels (gi, shadows, cm, ca):
//!   the path-traced photograph, then the GPU frame; a fingerprint for caching.
//! - [`contact_sheet`]: a scene's ground truth, photograph and stimuli side by side, labelled.
//! - [`command`]: `mrstudy render` as a function over a plain request, and what a command says.
//! - [`surface`]: the G-buffer's per-pixel surface flag (nothing, real, virtual).
//! - [`cm`]: the `cm` factor's CPU reference — Reinhard, statistics-based (Lab E), sample-based
//!   and Rohmer et al.'s colour mapping, the composition (additive or Debevec's scaled), Lab,
//!   HSV and CIEDE2000.
//! - [`gpu`]: adapter choice, G-buffer, shadow maps, RSMs and VPLs, imperfect shadow maps, the
//!   shading pass writing L_rv and L_r, interleaved-sampling merge and temporal smoothing, the cm
//!   passes, differential composition (WGSL beside the Rust that drives it).

// The renderer's benchmark experiments (`mrstudy bench render`), behind the `bench` feature so
// they are not part of the library's default API; `mrstudy-bench` turns it on.
#[cfg(feature = "bench")]
pub mod bench;
pub mod bvh;
pub mod ca;
pub mod camera;
pub mod capture;
pub mod cm;
pub mod coherent;
pub mod command;
pub mod contact_sheet;
pub mod error;
pub mod geometry;
pub mod gpu;
pub mod image;
pub mod knob;
pub mod light;
pub mod material;
pub mod math;
pub mod mesh;
pub mod metrics;
pub mod pathtracer;
pub mod reference;
pub mod scene;
pub mod sensor;
pub mod stimulus;
pub mod surface;
#[cfg(test)]
pub(crate) mod test_support;

pub use error::RenderError;
pub use image::{Image, Mask};
pub use reference::{ReferenceOutput, ReferenceParams, render_reference};
pub use scene::{Scene, SceneDesc, builtin};
