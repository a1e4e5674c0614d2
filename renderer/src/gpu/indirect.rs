//! The indirect light's post pass (shader: `indirect.wgsl`): the geometry-aware merge of
//! interleaved sampling, temporal smoothing by equations 5.11–5.15 (thesis 5.2.9), and the sum
//! with the direct light into L_rv and L_r. It runs only when the frame has indirect light (the
//! `gi` condition with VPLs).
//!
//! Temporal smoothing needs the previous frame: [`TemporalState`] keeps its smoothed indirect
//! light, its surface positions and normals and its camera. A frame without a state (stimuli)
//! has confidence 0 everywhere and is exactly the unsmoothed result. Motion is taken from the
//! camera (reprojection); objects that move show through the depth, normal and illumination
//! terms, which lower the confidence where they change — there are no per-object motion vectors.

use super::context::GpuContext;
use super::pool::Contents;
use super::raster::SurfaceTargets;
use glam::{Mat4, Vec3};
use serde::Serialize;
use std::sync::Arc;

pub const SHADER: &str = include_str!("indirect.wgsl");

/// The weights of equations 5.11–5.14. Defaults: the thesis's values for its Cornell box scene
/// (w_p = (10, 10, 10000), w_n = 1, w_i = 0.025), with a base confidence of 0.9.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TemporalParams {
    /// Weights of the screen-space motion (x, y; in units of the image size) and of the depth
    /// change (in units of the scene's bounding radius).
    pub w_p: [f32; 3],
    pub w_n: f32,
    pub w_i: f32,
    /// c_B: the largest share of the previous frame's light.
    pub base_confidence: f32,
}

impl Default for TemporalParams {
    fn default() -> Self {
        TemporalParams { w_p: [10.0, 10.0, 10000.0], w_n: 1.0, w_i: 0.025, base_confidence: 0.9 }
    }
}

/// What temporal smoothing keeps from one frame to the next (on the GPU).
pub struct TemporalState {
    width: u32,
    height: u32,
    view_proj: Mat4,
    indirect: Arc<wgpu::Buffer>,
    surface: Arc<wgpu::Buffer>,
    /// Frames smoothed so far.
    pub frames: u64,
}

/// Matches `Params` in indirect.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct IndirectUniform {
    size: [u32; 4],
    weights: [f32; 4],
    more: [f32; 4],
    camera: [f32; 4],
    prev_view_proj: [[f32; 4]; 4],
}

pub struct IndirectPass {
    pipeline: wgpu::ComputePipeline,
}

/// The frame's inputs to the pass.
pub struct IndirectInputs<'a> {
    pub width: u32,
    pub height: u32,
    /// The interleaved-sampling split n (1: none).
    pub split: u32,
    pub gbuffer: &'a SurfaceTargets,
    /// The shaded indirect light, I_rv then I_r.
    pub raw: &'a wgpu::Buffer,
    /// Direct light in, L_rv then L_r out.
    pub solutions: &'a wgpu::Buffer,
    pub camera: Vec3,
    pub view_proj: Mat4,
    pub scene_radius: f32,
}

impl IndirectPass {
    pub fn new(ctx: &GpuContext) -> Self {
        let [pipeline] = ctx.compute_pipelines("indirect.wgsl", SHADER, ["cs_indirect"]);
        IndirectPass { pipeline }
    }

    /// Runs the pass; with `temporal`, smooths against `state` (if it is of this size) and
    /// leaves this frame in it. Returns the frame's mean confidence-carrying buffer's owner
    /// state only through `state`.
    pub fn run(
        &self,
        ctx: &GpuContext,
        inputs: &IndirectInputs,
        temporal: Option<(&TemporalParams, &mut Option<TemporalState>)>,
    ) {
        let pixels = (inputs.width * inputs.height) as u64;
        let buffer = |label: &str| {
            ctx.buffer(
                label,
                2 * pixels * 16,
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                Contents::Zeroed,
            )
        };
        let (weights, history) = match &temporal {
            Some((weights, state)) => {
                ((*weights).clone(), state.as_ref().filter(|s| s.fits(inputs.width, inputs.height)))
            }
            None => (TemporalParams::default(), None),
        };
        let placeholder;
        let (prev_indirect, prev_surface, prev_view_proj) = match history {
            Some(state) => (&state.indirect, &state.surface, state.view_proj),
            None => {
                placeholder = (buffer("no previous indirect"), buffer("no previous surface"));
                (&placeholder.0, &placeholder.1, Mat4::IDENTITY)
            }
        };
        let next_indirect = buffer("indirect");
        let next_surface = buffer("surface");
        let uniform = IndirectUniform {
            size: [inputs.width, inputs.height, inputs.split.max(1), history.is_some() as u32],
            weights: [weights.w_p[0], weights.w_p[1], weights.w_p[2], weights.w_n],
            more: [weights.w_i, weights.base_confidence.clamp(0.0, 1.0), inputs.scene_radius, 0.0],
            camera: [inputs.camera.x, inputs.camera.y, inputs.camera.z, 0.0],
            prev_view_proj: prev_view_proj.to_cols_array_2d(),
        };
        let uniform = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("indirect params"),
            contents: bytemuck::bytes_of(&uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let gp = ctx.views.of(&inputs.gbuffer.position);
        let gn = ctx.views.of(&inputs.gbuffer.normal);
        ctx.dispatch(
            "indirect",
            &self.pipeline,
            &[
                wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&gp) },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&gn) },
                wgpu::BindGroupEntry { binding: 3, resource: inputs.raw.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: inputs.solutions.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 5, resource: prev_indirect.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 6, resource: prev_surface.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 7, resource: next_indirect.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 8, resource: next_surface.as_entire_binding() },
            ],
            [inputs.width.div_ceil(8), inputs.height.div_ceil(8)],
        );
        if let Some((_, state)) = temporal {
            let frames = state.as_ref().map_or(0, |s| s.frames) + 1;
            *state = Some(TemporalState {
                width: inputs.width,
                height: inputs.height,
                view_proj: inputs.view_proj,
                indirect: next_indirect,
                surface: next_surface,
                frames,
            });
        }
    }
}

impl TemporalState {
    /// Whether this state can smooth a frame of `width` × `height` (a frame of another size
    /// starts afresh).
    pub fn fits(&self, width: u32, height: u32) -> bool {
        self.width == width && self.height == height
    }

    /// The smoothed indirect light of the last frame (I_rv then I_r, w of I_rv: the confidence).
    pub fn read_indirect(&self, ctx: &GpuContext) -> Vec<f32> {
        ctx.read_f32(&self.indirect)
    }
}
