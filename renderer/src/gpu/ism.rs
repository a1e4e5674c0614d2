//! Imperfect shadow maps (shader: `ism.wgsl`): the visibility of every VPL, from two point
//! clouds — one on the real surfaces, one on the virtual ones (thesis 5.2.4: VPLs sit on real
//! and virtual objects, so two ISMs are needed, as two shadow maps are for a primary light). The
//! shading pass takes V_r from the real atlas layer and V_v from the virtual one, and weighs a
//! VPL's light by min(V_r, V_v) in L_rv and by V_r in L_r, as equation 5.3 does for direct light.
//!
//! Each VPL gets `points_per_vpl` points drawn on the GPU in proportion to surface area (a
//! per-subset CDF over triangles is built here), splatted as geometry-aligned quads (5.2.8) into
//! its `tile_size`² tile of a square atlas (paraboloid mapping of the VPL's hemisphere).
//!
//! Two ways to splat ([`IsmSplatting`]), into one atlas buffer the shading pass reads:
//! - **compute** (default): one invocation per splat walks the texels its quad covers and keeps
//!   the nearest depth by an atomic maximum. It needs no rasteriser, so it runs on every shader
//!   core, where a GPU built for compute (NVIDIA's H100 and H200, which lack most of the raster
//!   hardware of a graphics card) would otherwise splat on a few units;
//! - **raster**: the quads are rasterised with a depth test into a depth texture (two indexed
//!   triangles on four vertices, so the vertex shader — which draws the point — runs four times
//!   per splat), then copied into the buffer.
//!
//! They share the splat, the per-texel test and the clipping of a quad at the far plane where
//! it crosses its VPL's horizon; they differ only in texels on a quad's edge (the rasteriser
//! snaps vertices to a sub-texel grid).

use super::context::GpuContext;
use super::mesh::GpuMesh;
use super::pool::Contents;
use super::vpl::GpuVpl;
use serde::Serialize;

pub const SHADER: &str = concat!(include_str!("common.wgsl"), include_str!("cdf.wgsl"), include_str!("ism.wgsl"));
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Splats per indexed draw: the index buffer holds this many (24 MB), larger clouds take
/// several draws.
const SPLATS_PER_DRAW: u32 = 1 << 20;
/// The most splats one layer draws (four vertices each, numbered by an i32 base vertex); the
/// points per VPL are cut to fit.
const MAX_SPLATS: u64 = (i32::MAX as u64) / 4;
/// Invocations per workgroup of `cs_splat`.
const SPLAT_GROUP: u32 = 64;

/// How the splats are drawn into the atlas.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum IsmSplatting {
    /// A compute pass, one invocation per splat, atomics into the atlas buffer.
    #[default]
    Compute,
    /// The rasteriser with a depth test, then copied into the atlas buffer.
    Raster,
}

impl IsmSplatting {
    pub const ALL: [IsmSplatting; 2] = [IsmSplatting::Compute, IsmSplatting::Raster];

    pub fn name(self) -> &'static str {
        match self {
            IsmSplatting::Compute => "compute",
            IsmSplatting::Raster => "raster",
        }
    }

    pub fn parse(text: &str) -> Option<IsmSplatting> {
        Self::ALL.into_iter().find(|s| s.name() == text)
    }
}

/// Matches `IsmParams` in ism.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct IsmUniform {
    counts: [u32; 4],
    subset: [u32; 4],
    scale: [f32; 4],
    layer: [u32; 4],
}

/// The two ISM atlases (layer 0 real points, layer 1 virtual points) and how to read them.
pub struct IsmAtlas {
    /// Per texel (layer, row, column) a `u32`: the bits of 1.0 minus the bits of the stored
    /// depth (distance × `inv_max_distance`, in [0, 1]); 0 where nothing is nearer than the far
    /// plane (`ism_encode` in common.wgsl).
    pub buffer: std::sync::Arc<wgpu::Buffer>,
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

impl IsmAtlas {
    /// Texels per atlas row (and rows).
    pub fn width(&self) -> u32 {
        self.tiles_per_row * self.tile_size
    }
}

/// How a frame's ISMs are made: points per cloud, each VPL's tile size, the largest
/// VPL-to-surface distance, and how the splats are drawn.
#[derive(Clone, Copy, Debug)]
pub struct IsmSettings {
    pub points_per_vpl: u32,
    pub tile_size: u32,
    pub max_distance: f32,
    pub splatting: IsmSplatting,
}

/// What the raster splatting draws: the atlas `buffer` it fills (`atlas` texels across), each
/// layer's (cloud, its CDF and uniform), the point positions and the VPLs, `splats` quads.
#[derive(Clone, Copy)]
struct RasterSplats<'a> {
    buffer: &'a wgpu::Buffer,
    atlas: u32,
    layers: &'a [(usize, std::sync::Arc<wgpu::Buffer>, std::sync::Arc<wgpu::Buffer>)],
    position_buffer: &'a wgpu::Buffer,
    vpl_buffer: &'a wgpu::Buffer,
    splats: u32,
}

pub struct Ism {
    pipeline: wgpu::RenderPipeline,
    splat: wgpu::ComputePipeline,
    from_depth: wgpu::ComputePipeline,
    /// The splats' index buffer (4s, 4s+1, 4s+2, 4s+2, 4s+1, 4s+3 for splat s: two triangles
    /// sharing their diagonal's vertices) and how many splats it holds, kept from frame to frame
    /// and made anew only when a frame needs more.
    indices: std::sync::Mutex<Option<(u32, wgpu::Buffer)>>,
    /// Splats per indexed draw ([`SPLATS_PER_DRAW`]; tests draw in smaller pieces).
    splats_per_draw: u32,
    /// Workgroups per row of the compute splatting's dispatch (the device's limit per
    /// dimension; tests use shorter rows).
    groups_per_row: u32,
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

/// The scene's point clouds as the splats read them, uploaded once per mesh (kept with it in a
/// frame: `mesh::PerMesh`): the triangles' positions with their role and, per layer
/// (real, virtual) with a surface, its triangles, area CDF and area.
#[derive(Clone)]
pub struct IsmClouds {
    positions: std::sync::Arc<wgpu::Buffer>,
    layers: [Option<(std::ops::Range<usize>, std::sync::Arc<wgpu::Buffer>, f64)>; 2],
}

impl IsmClouds {
    pub fn new(ctx: &GpuContext, mesh: &GpuMesh) -> IsmClouds {
        let positions = mesh.positions_with_role();
        let n_triangles = mesh.vertices.len() / 3;
        let real_triangles = mesh.real_count as usize / 3;
        let subsets = [0..real_triangles, real_triangles..n_triangles];
        // the scene's points and their distributions: kept while the scene is the same
        let points = if positions.is_empty() { &[[0.0f32; 4]][..] } else { &positions };
        let position_buffer = ctx.resident("ism positions", bytemuck::cast_slice(points), wgpu::BufferUsages::STORAGE);
        let layers = [0, 1].map(|layer: usize| {
            let range = subsets[layer].clone();
            let (cdf, area) = area_cdf(&positions, range.clone())?;
            let key = format!("ism cdf {layer}");
            Some((range, ctx.resident(&key, bytemuck::cast_slice(&cdf), wgpu::BufferUsages::STORAGE), area))
        });
        IsmClouds { positions: position_buffer, layers }
    }
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
        let [splat, from_depth] = ctx.compute_pipelines("ism.wgsl", SHADER, ["cs_splat", "cs_from_depth"]);
        Ism {
            pipeline,
            splat,
            from_depth,
            indices: std::sync::Mutex::new(None),
            splats_per_draw: SPLATS_PER_DRAW,
            groups_per_row: ctx.device.limits().max_compute_workgroups_per_dimension,
        }
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
        // made once and kept (not from the pool)
        let buffer = ctx.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("ism splat indices"),
            contents: bytemuck::cast_slice(&indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        *cache = Some((splats, buffer.clone()));
        buffer
    }

    /// Renders both atlases for `vpls` by `splatting` over the scene's `clouds`. `max_distance`
    /// bounds every VPL-to-surface distance.
    pub fn render(&self, ctx: &GpuContext, clouds: &IsmClouds, vpls: &[GpuVpl], settings: &IsmSettings) -> IsmAtlas {
        let vpl_buffer = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("ism vpls"),
            contents: bytemuck::cast_slice(if vpls.is_empty() {
                &[GpuVpl { position: [0.0; 4], normal: [0.0, 1.0, 0.0, 0.0], flux: [0.0; 4] }][..]
            } else {
                vpls
            }),
            usage: wgpu::BufferUsages::STORAGE,
        });
        self.render_gpu(ctx, clouds, (&vpl_buffer, vpls.len() as u32), settings)
    }

    /// [`Ism::render`] for `vpls.1` VPLs already on the GPU in `vpls.0` (a live frame's: slots
    /// without flux make no splat).
    pub fn render_gpu(
        &self,
        ctx: &GpuContext,
        clouds: &IsmClouds,
        (vpl_buffer, vpl_count): (&wgpu::Buffer, u32),
        settings: &IsmSettings,
    ) -> IsmAtlas {
        let IsmSettings { points_per_vpl, tile_size, max_distance, splatting } = *settings;
        let device = &ctx.device;
        let limits = device.limits();
        let n_vpls = vpl_count.max(1);
        let tiles_per_row = ((n_vpls as f64).sqrt().ceil() as u32).max(1);
        // the atlas must fit the device, as a texture and as the buffer of both layers: shrink
        // the tiles if it would not
        let max_bytes = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        let max_width = ((max_bytes / 8) as f64).sqrt() as u32;
        let max_width = max_width.min(limits.max_texture_dimension_2d);
        let tile_size = tile_size.max(4).min((max_width / tiles_per_row).max(4));
        let atlas = tiles_per_row * tile_size;
        let buffer = ctx.buffer(
            "ism atlas",
            2 * (atlas as u64) * (atlas as u64) * 4,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            // the compute splats keep maxima over zeros; the raster copy writes every texel
            match splatting {
                IsmSplatting::Compute => Contents::Zeroed,
                IsmSplatting::Raster => Contents::Overwritten,
            },
        );
        // every splat's four vertices are numbered in one draw's vertex_index (a base vertex is
        // an i32): at most MAX_SPLATS splats in all
        let points_per_vpl = points_per_vpl.clamp(1, (MAX_SPLATS / n_vpls as u64).max(1) as u32);
        let position_buffer = &clouds.positions;
        let inv_max_distance = 1.0 / max_distance.max(1e-6);
        let splats = vpl_count * points_per_vpl;
        // per layer with a surface and VPLs: its uniform and its area CDF
        let mut points = [0u32; 2];
        let mut splat_radius = [0.0f32; 2];
        let mut layers = Vec::with_capacity(2);
        for (layer, cloud) in clouds.layers.iter().enumerate() {
            let Some((range, cdf_buffer, area)) = cloud else { continue };
            if vpl_count == 0 {
                continue;
            }
            points[layer] = points_per_vpl;
            // splats cover the cloud's surfaces about twice over
            splat_radius[layer] = (2.0 * area / (points_per_vpl as f64 * std::f64::consts::PI)).sqrt() as f32;
            let uniform = IsmUniform {
                counts: [points_per_vpl, tiles_per_row, tile_size, atlas],
                subset: [range.start as u32, range.len() as u32, vpl_count, splats],
                scale: [inv_max_distance, splat_radius[layer], 0.0, 0.0],
                layer: [layer as u32, 0, 0, 0],
            };
            let uniform_buffer = ctx.upload(&wgpu::util::BufferInitDescriptor {
                label: Some("ism params"),
                contents: bytemuck::bytes_of(&uniform),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            layers.push((layer, uniform_buffer, cdf_buffer.clone()));
        }
        let mut encoder = ctx.encoder();
        match splatting {
            IsmSplatting::Compute => {
                // 64 splats per group, in rows of at most 65 535 groups
                let groups = splats.div_ceil(SPLAT_GROUP);
                let row = groups.clamp(1, self.groups_per_row.max(1));
                for (_, uniform, cdf) in &layers {
                    ctx.record_dispatch(
                        &mut encoder,
                        "ism splats",
                        &self.splat,
                        &[
                            wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                            wgpu::BindGroupEntry { binding: 1, resource: position_buffer.as_entire_binding() },
                            wgpu::BindGroupEntry { binding: 2, resource: cdf.as_entire_binding() },
                            wgpu::BindGroupEntry { binding: 3, resource: vpl_buffer.as_entire_binding() },
                            wgpu::BindGroupEntry { binding: 4, resource: buffer.as_entire_binding() },
                        ],
                        [row, groups.div_ceil(row)],
                    );
                }
            }
            IsmSplatting::Raster => {
                let inputs =
                    RasterSplats { buffer: &buffer, atlas, layers: &layers, position_buffer, vpl_buffer, splats };
                self.rasterise(ctx, &mut encoder, &inputs)
            }
        }
        ctx.submit(encoder);
        IsmAtlas { buffer, tiles_per_row, tile_size, inv_max_distance, splat_radius, points }
    }

    /// The raster splatting: both layers' quads into a depth texture (cleared to the far plane),
    /// then copied into `buffer`.
    fn rasterise(&self, ctx: &GpuContext, encoder: &mut wgpu::CommandEncoder, inputs: &RasterSplats) {
        let RasterSplats { buffer, atlas, layers, position_buffer, vpl_buffer, splats } = *inputs;
        // from the pool: both layers are rendered with a clear below
        let texture = ctx.texture(&wgpu::TextureDescriptor {
            label: Some("ism atlas"),
            size: wgpu::Extent3d { width: atlas, height: atlas, depth_or_array_layers: 2 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let splats_per_draw = self.splats_per_draw.max(1);
        let indices = (splats > 0).then(|| self.indices(ctx, splats.min(splats_per_draw)));
        for layer in 0..2 {
            let view = texture.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2),
                base_array_layer: layer as u32,
                array_layer_count: Some(1),
                ..Default::default()
            });
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
            let Some((_, uniform, cdf)) = layers.iter().find(|(l, _, _)| *l == layer) else { continue };
            let bind_group = ctx.bind_group(&wgpu::BindGroupDescriptor {
                label: Some("ism"),
                layout: &self.pipeline.get_bind_group_layout(0),
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: position_buffer.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: cdf.as_entire_binding() },
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
        // the copy reads only the atlas size from its uniform
        let uniform = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("ism params"),
            contents: bytemuck::bytes_of(&IsmUniform {
                counts: [0, 0, 0, atlas],
                subset: [0; 4],
                scale: [0.0; 4],
                layer: [0; 4],
            }),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        ctx.record_dispatch(
            encoder,
            "ism depth into the atlas buffer",
            &self.from_depth,
            &[
                wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 5, resource: wgpu::BindingResource::TextureView(&view) },
            ],
            [atlas.div_ceil(8), atlas.div_ceil(8)],
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(points_per_vpl: u32, tile_size: u32, max_distance: f32, splatting: IsmSplatting) -> IsmSettings {
        IsmSettings { points_per_vpl, tile_size, max_distance, splatting }
    }

    /// VPLs on dir-lamp-box's surfaces: every fifth triangle's centroid, facing its normal.
    fn surface_vpls(mesh: &GpuMesh, count: usize) -> Vec<GpuVpl> {
        mesh.positions_with_role()
            .chunks_exact(3)
            .step_by(5)
            .take(count)
            .map(|t| {
                let p = |k: usize| glam::Vec3::from_slice(&t[k][..3]);
                let (c, n) = ((p(0) + p(1) + p(2)) / 3.0, (p(1) - p(0)).cross(p(2) - p(0)).normalize());
                GpuVpl { position: [c.x, c.y, c.z, 1.0], normal: [n.x, n.y, n.z, 0.0], flux: [1.0; 4] }
            })
            .collect()
    }

    fn read_atlas(ctx: &GpuContext, atlas: &IsmAtlas) -> Vec<u32> {
        bytemuck::cast_slice::<u8, u32>(&ctx.read_storage(&atlas.buffer)).to_vec()
    }

    /// dir-lamp-box's atlases of 7 VPLs × 100 points in 32² tiles, splatted by the renderer's
    /// `Ism` and by `variant` (the same passes cut into other pieces).
    fn atlases_of_the_renderer_and(variant: impl FnOnce(Ism) -> Ism, splatting: IsmSplatting) -> (Vec<u32>, Vec<u32>) {
        let r = crate::test_support::renderer_or_skip().expect("checked by the caller");
        let scene = crate::scene::load("dir-lamp-box").unwrap();
        let mesh = crate::gpu::mesh::build(&scene);
        let vpls = surface_vpls(&mesh, 7);
        assert_eq!(vpls.len(), 7);
        let one = read_atlas(
            &r.ctx,
            &r.ism.render(&r.ctx, &IsmClouds::new(&r.ctx, &mesh), &vpls, &settings(100, 32, 20.0, splatting)),
        );
        let pieces = variant(Ism::new(&r.ctx));
        let other = read_atlas(
            &r.ctx,
            &pieces.render(&r.ctx, &IsmClouds::new(&r.ctx, &mesh), &vpls, &settings(100, 32, 20.0, splatting)),
        );
        (one, other)
    }

    /// A cloud drawn in several indexed draws (each a base vertex further, the last one partial)
    /// makes the same ISMs bit for bit as in one draw: 7 VPLs of dir-lamp-box's first bounce ×
    /// 100 points in draws of 64 splats against the renderer's one draw.
    #[test]
    fn a_cloud_drawn_in_several_draws_makes_the_same_isms_as_in_one() {
        if crate::test_support::renderer_or_skip().is_none() {
            return;
        }
        let (one, several) =
            atlases_of_the_renderer_and(|ism| Ism { splats_per_draw: 64, ..ism }, IsmSplatting::Raster);
        let covered = one.iter().filter(|&&t| t != 0).count();
        assert!(covered > 0, "the splats must cover some texels for this test to tell anything");
        assert!(one == several, "the ISMs drawn in draws of 64 splats differ from one draw's");
    }

    /// The compute splatting's dispatch in rows (a cloud of more splats than one row of
    /// workgroups holds, 4 194 240 on most devices) covers every splat once: rows of 3 groups
    /// (7 × 100 splats in 11 groups of 64, the last row partial) make the same atlas bit for
    /// bit as one row.
    #[test]
    fn compute_splats_dispatched_in_rows_make_the_same_isms() {
        if crate::test_support::renderer_or_skip().is_none() {
            return;
        }
        let (one, rows) = atlases_of_the_renderer_and(|ism| Ism { groups_per_row: 3, ..ism }, IsmSplatting::Compute);
        assert!(one.iter().any(|&t| t != 0), "the splats must cover some texels for this test to tell anything");
        assert!(one == rows, "the ISMs splatted in rows of 3 workgroups differ from one row's");
    }

    /// A VPL at NaN or at infinity (a degenerate source upstream) leaves its own tile empty and
    /// every other tile as without it, in both splattings: its splats' bounds are clamped to
    /// its tile, so the compute pass neither runs away nor writes elsewhere.
    #[test]
    fn a_vpl_at_nan_or_infinity_touches_no_other_tile() {
        let Some(r) = crate::test_support::renderer_or_skip() else { return };
        let scene = crate::scene::load("dir-lamp-box").unwrap();
        let mesh = crate::gpu::mesh::build(&scene);
        let good = surface_vpls(&mesh, 4);
        for bad in [f32::NAN, f32::INFINITY] {
            let mut vpls = good.clone();
            vpls[1].position = [bad, 0.0, bad, 1.0];
            for splatting in IsmSplatting::ALL {
                let atlas =
                    r.ism.render(&r.ctx, &IsmClouds::new(&r.ctx, &mesh), &vpls, &settings(100, 16, 20.0, splatting));
                let reference =
                    r.ism.render(&r.ctx, &IsmClouds::new(&r.ctx, &mesh), &good, &settings(100, 16, 20.0, splatting));
                let (with_bad, without) = (read_atlas(&r.ctx, &atlas), read_atlas(&r.ctx, &reference));
                let width = atlas.width() as usize;
                let tile_of = |i: usize| {
                    let (x, y) = ((i % (width * width)) % width, (i % (width * width)) / width);
                    (y / 16) * atlas.tiles_per_row as usize + x / 16
                };
                for (i, (a, b)) in with_bad.iter().zip(&without).enumerate() {
                    match tile_of(i) {
                        1 => assert_eq!(*a, 0, "{splatting:?}, {bad}: the bad VPL's tile has a splat at {i}"),
                        _ => assert_eq!(a, b, "{splatting:?}, {bad}: texel {i} changed"),
                    }
                }
            }
        }
    }

    /// The compute splatting makes the rasteriser's ISMs: on 64 VPLs of dir-lamp-box and of
    /// the glass figure (real and virtual clouds, 1024 points, 64² tiles), at most 0.1 % of
    /// the covered texels differ (texel centres within the rasteriser's sub-texel snapping of a
    /// quad's edge; on lavapipe 6 of 53 898 and 24 of 153 277), every other one bit for bit.
    /// The rasteriser is the established implementation of which texels a quad covers (and of
    /// its clipping at the far plane, which the compute pass mirrors); the depth is the shared
    /// per-texel test's.
    #[test]
    fn compute_splats_make_the_rasterisers_isms() {
        let Some(r) = crate::test_support::renderer_or_skip() else { return };
        for name in ["dir-lamp-box", "glass-figure"] {
            let scene = crate::scene::load(name).unwrap();
            let mesh = crate::gpu::mesh::build(&scene);
            let vpls = surface_vpls(&mesh, 64);
            let render = |splatting| {
                r.ism.render(
                    &r.ctx,
                    &IsmClouds::new(&r.ctx, &mesh),
                    &vpls,
                    &settings(1024, 64, 2.0 * mesh.bounds_radius * 1.01, splatting),
                )
            };
            let (compute, raster) = (render(IsmSplatting::Compute), render(IsmSplatting::Raster));
            assert_eq!((compute.tile_size, compute.tiles_per_row), (raster.tile_size, raster.tiles_per_row));
            let (c, g) = (read_atlas(&r.ctx, &compute), read_atlas(&r.ctx, &raster));
            assert_eq!(c.len(), g.len());
            let covered = c.iter().zip(&g).filter(|(a, b)| **a != 0 || **b != 0).count();
            let differ = c.iter().zip(&g).filter(|(a, b)| a != b).count();
            eprintln!("{name}: {differ} of {covered} covered texels differ");
            assert!(covered > c.len() / 20, "{name}: the splats must cover the atlas for this test to tell anything");
            assert!(
                (differ as f64) <= 0.001 * covered as f64,
                "{name}: {differ} of {covered} covered texels differ between compute and raster splatting"
            );
        }
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
