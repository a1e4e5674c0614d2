//! Imperfect shadow maps (shader: `ism.wgsl`): the visibility of every VPL, from two point
//! clouds — one on the real surfaces, one on the virtual ones (thesis 5.2.4: VPLs sit on real
//! and virtual objects, so two ISMs are needed, as two shadow maps are for a primary light). The
//! shading pass takes V_r from the real atlas layer and V_v from the virtual one, and weighs a
//! VPL's light by min(V_r, V_v) in L_rv and by V_r in L_r, as equation 5.3 does for direct light.
//!
//! Each VPL gets `points_per_vpl` points drawn on the GPU in proportion to surface area (a
//! per-subset CDF over triangles is built here), splatted as geometry-aligned quads (5.2.8) into
//! its `tile_size`² tile of a square atlas (paraboloid mapping of the VPL's hemisphere). A quad
//! is two indexed triangles on four vertices, so the vertex shader — which draws the point —
//! runs four times per splat, not six.

use super::context::GpuContext;
use super::mesh::GpuMesh;
use super::vpl::GpuVpl;
use wgpu::util::DeviceExt;

pub const SHADER: &str = concat!(include_str!("common.wgsl"), include_str!("ism.wgsl"));
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Splats per indexed draw: the index buffer holds this many (24 MB), larger clouds take
/// several draws.
const SPLATS_PER_DRAW: u32 = 1 << 20;
/// The most splats one layer draws (four vertices each, numbered by an i32 base vertex); the
/// points per VPL are cut to fit.
const MAX_SPLATS: u64 = (i32::MAX as u64) / 4;

/// Matches `IsmParams` in ism.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct IsmUniform {
    counts: [u32; 4],
    subset: [u32; 4],
    scale: [f32; 4],
}

/// The two ISM atlases (layer 0 real points, layer 1 virtual points) and how to read them.
pub struct IsmAtlas {
    pub texture: std::sync::Arc<wgpu::Texture>,
    pub tiles_per_row: u32,
    pub tile_size: u32,
    /// 1 / the distance that maps to depth 1.
    pub inv_max_distance: f32,
    /// Splat (disc) radius in metres per cloud (real, virtual): discs of about twice the area
    /// each point stands for, so a cloud's splats close over its surfaces.
    pub splat_radius: [f32; 2],
    /// Points drawn per VPL and subset (0 where the subset has no surface).
    pub points: [u32; 2],
}

pub struct Ism {
    pipeline: wgpu::RenderPipeline,
    /// The splats' index buffer (4s, 4s+1, 4s+2, 4s+2, 4s+1, 4s+3 for splat s: two triangles
    /// sharing their diagonal's vertices) and how many splats it holds, kept from frame to frame
    /// and made anew only when a frame needs more.
    indices: std::sync::Mutex<Option<(u32, wgpu::Buffer)>>,
    /// Splats per indexed draw ([`SPLATS_PER_DRAW`]; tests draw in smaller pieces).
    splats_per_draw: u32,
}

/// The cumulative area distribution over `triangles` (each three positions), ending at 1, and
/// the total area; `None` when the area is zero.
pub fn area_cdf(positions: &[[f32; 4]], triangles: std::ops::Range<usize>) -> Option<(Vec<f32>, f64)> {
    let mut cdf = Vec::with_capacity(triangles.len());
    let mut total = 0.0f64;
    for t in triangles {
        let p = |k: usize| glam::Vec3::from_slice(&positions[3 * t + k][..3]);
        let area = 0.5 * (p(1) - p(0)).cross(p(2) - p(0)).length() as f64;
        total += if area.is_finite() { area } else { 0.0 };
        cdf.push(total);
    }
    if total <= 0.0 {
        return None;
    }
    let cdf: Vec<f32> = cdf.into_iter().map(|c| (c / total) as f32).collect();
    Some((cdf, total))
}

impl Ism {
    pub fn new(ctx: &GpuContext) -> Self {
        let module = ctx.device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("ism.wgsl"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let pipeline = ctx.device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("ism splats"),
            layout: None,
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_splat"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_splat"),
                compilation_options: Default::default(),
                targets: &[],
            }),
            multiview_mask: None,
            cache: None,
        });
        Ism { pipeline, indices: std::sync::Mutex::new(None), splats_per_draw: SPLATS_PER_DRAW }
    }

    /// An index buffer for at least `splats` splats.
    fn indices(&self, ctx: &GpuContext, splats: u32) -> wgpu::Buffer {
        let mut cache = self.indices.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some((held, buffer)) = cache.as_ref()
            && *held >= splats
        {
            return buffer.clone();
        }
        let indices: Vec<u32> = (0..splats).flat_map(|s| [0, 1, 2, 2, 1, 3].map(|k| 4 * s + k)).collect();
        let buffer = ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("ism splat indices"),
            contents: bytemuck::cast_slice(&indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        *cache = Some((splats, buffer.clone()));
        buffer
    }

    /// Renders both atlases for `vpls`. `max_distance` bounds every VPL-to-surface distance.
    pub fn render(
        &self,
        ctx: &GpuContext,
        mesh: &GpuMesh,
        vpls: &[GpuVpl],
        points_per_vpl: u32,
        tile_size: u32,
        max_distance: f32,
    ) -> IsmAtlas {
        let device = &ctx.device;
        let n_vpls = vpls.len().max(1) as u32;
        let max_texture = device.limits().max_texture_dimension_2d;
        let mut tiles_per_row = (n_vpls as f64).sqrt().ceil() as u32;
        tiles_per_row = tiles_per_row.max(1);
        // the atlas must fit the device: shrink the tiles if it would not
        let tile_size = tile_size.max(4).min((max_texture / tiles_per_row).max(4));
        let atlas = tiles_per_row * tile_size;
        // from the pool: both layers are rendered with a clear below
        let texture = ctx.texture(&wgpu::TextureDescriptor {
            label: Some("ism atlas"),
            size: wgpu::Extent3d { width: atlas, height: atlas, depth_or_array_layers: 2 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let positions = mesh.positions_with_role();
        let n_triangles = mesh.vertices.len() / 3;
        let real_triangles = mesh.real_count as usize / 3;
        let subsets = [0..real_triangles, real_triangles..n_triangles];
        // every splat's four vertices are numbered in one draw's vertex_index (a base vertex is
        // an i32): at most MAX_SPLATS splats in all
        let points_per_vpl = points_per_vpl.clamp(1, (MAX_SPLATS / n_vpls as u64).max(1) as u32);
        let mut splat_radius = [0.0f32; 2];
        let position_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("ism positions"),
            contents: bytemuck::cast_slice(if positions.is_empty() { &[[0.0f32; 4]][..] } else { &positions }),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let vpl_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("ism vpls"),
            contents: bytemuck::cast_slice(if vpls.is_empty() {
                &[GpuVpl { position: [0.0; 4], normal: [0.0, 1.0, 0.0, 0.0], flux: [0.0; 4] }][..]
            } else {
                vpls
            }),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let inv_max_distance = 1.0 / max_distance.max(1e-6);
        let mut points = [0u32; 2];
        let splats = vpls.len() as u32 * points_per_vpl;
        let splats_per_draw = self.splats_per_draw.max(1);
        let indices = (splats > 0).then(|| self.indices(ctx, splats.min(splats_per_draw)));
        let mut encoder = device.create_command_encoder(&Default::default());
        for (layer, range) in subsets.iter().enumerate() {
            let view = texture.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2),
                base_array_layer: layer as u32,
                array_layer_count: Some(1),
                ..Default::default()
            });
            let cdf = area_cdf(&positions, range.clone());
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("ism"),
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &view,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                ..Default::default()
            });
            let Some((cdf, area)) = cdf else { continue };
            if vpls.is_empty() {
                continue;
            }
            points[layer] = points_per_vpl;
            // splats cover the cloud's surfaces about twice over
            splat_radius[layer] = (2.0 * area / (points_per_vpl as f64 * std::f64::consts::PI)).sqrt() as f32;
            let uniform = IsmUniform {
                counts: [points_per_vpl, tiles_per_row, tile_size, atlas],
                subset: [range.start as u32, range.len() as u32, vpls.len() as u32, 0],
                scale: [inv_max_distance, splat_radius[layer], 0.0, 0.0],
            };
            let uniform_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("ism params"),
                contents: bytemuck::bytes_of(&uniform),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let cdf_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("ism cdf"),
                contents: bytemuck::cast_slice(&cdf),
                usage: wgpu::BufferUsages::STORAGE,
            });
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("ism"),
                layout: &self.pipeline.get_bind_group_layout(0),
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: uniform_buffer.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: position_buffer.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: cdf_buffer.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 3, resource: vpl_buffer.as_entire_binding() },
                ],
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            // one vertex shader invocation per corner, not per triangle's corner; in draws of at
            // most `splats_per_draw` splats (what the index buffer holds), in order
            if let Some(indices) = &indices {
                pass.set_index_buffer(indices.slice(..), wgpu::IndexFormat::Uint32);
                for first in (0..splats).step_by(splats_per_draw as usize) {
                    let count = (splats - first).min(splats_per_draw);
                    pass.draw_indexed(0..6 * count, 4 * first as i32, 0..1);
                }
            }
        }
        ctx.submit(encoder);
        IsmAtlas { texture, tiles_per_row, tile_size, inv_max_distance, splat_radius, points }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cloud drawn in several indexed draws (each a base vertex further, the last one partial)
    /// makes the same ISMs bit for bit as in one draw: 7 VPLs of dir-lamp-box's first bounce ×
    /// 100 points in draws of 64 splats against the renderer's one draw.
    #[test]
    fn a_cloud_drawn_in_several_draws_makes_the_same_isms_as_in_one() {
        let Some(r) = crate::test_support::renderer_or_skip() else { return };
        let scene = crate::scene::load("dir-lamp-box").unwrap();
        let mesh = crate::gpu::mesh::build(&scene);
        // VPLs on the scene's surfaces: each triangle's centroid, facing its normal
        let vpls: Vec<GpuVpl> = mesh
            .positions_with_role()
            .chunks_exact(3)
            .step_by(5)
            .take(7)
            .map(|t| {
                let p = |k: usize| glam::Vec3::from_slice(&t[k][..3]);
                let (c, n) = ((p(0) + p(1) + p(2)) / 3.0, (p(1) - p(0)).cross(p(2) - p(0)).normalize());
                GpuVpl { position: [c.x, c.y, c.z, 1.0], normal: [n.x, n.y, n.z, 0.0], flux: [1.0; 4] }
            })
            .collect();
        assert_eq!(vpls.len(), 7);
        let read = |atlas: &IsmAtlas| r.ctx.read_textures(&[(&atlas.texture, 4)]).remove(0);
        let one = read(&r.ism.render(&r.ctx, &mesh, &vpls, 100, 32, 20.0));
        let in_pieces = Ism { splats_per_draw: 64, ..Ism::new(&r.ctx) };
        let several = read(&in_pieces.render(&r.ctx, &mesh, &vpls, 100, 32, 20.0));
        let cleared = one.chunks_exact(4).filter(|t| f32::from_le_bytes([t[0], t[1], t[2], t[3]]) == 1.0).count();
        assert!(cleared < one.len() / 4, "the splats must cover some texels for this test to tell anything");
        assert!(one == several, "the ISMs drawn in draws of 64 splats differ from one draw's");
    }

    #[test]
    fn the_area_cdf_weights_triangles_by_area_and_ends_at_one() {
        let tri = |s: f32| [[0.0, 0.0, 0.0, 0.0], [s, 0.0, 0.0, 0.0], [0.0, s, 0.0, 0.0]];
        let positions: Vec<[f32; 4]> = [tri(1.0), tri(3.0f32.sqrt()), tri(0.0)].concat();
        let (cdf, total) = area_cdf(&positions, 0..3).unwrap();
        assert!((total - 2.0).abs() < 1e-6, "{total}");
        assert!((cdf[0] - 0.25).abs() < 1e-6 && (cdf[1] - 1.0).abs() < 1e-6 && cdf[2] == 1.0, "{cdf:?}");
        assert!(area_cdf(&positions, 2..3).is_none(), "a zero-area subset has no distribution");
        assert!(area_cdf(&positions, 0..0).is_none());
    }
}
