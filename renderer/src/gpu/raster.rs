//! Rasterisation passes (shader: `raster.wgsl`): the camera's G-buffer, a light's shadow map
//! (distance to the light only) and its reflective shadow map (distance, position, normal,
//! albedo). Every pass draws the scene's triangle list, or its real or virtual subset.

use super::context::GpuContext;
use super::mesh::{GpuMaterial, GpuMesh, GpuVertex};
use glam::{Mat4, Vec3};
use std::sync::Arc;

mod groups;

/// G-buffer and RSM attachments: position+flag, normal+exponent, albedo+ks.
pub const SURFACE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// Shadow maps store the distance to the light (spot) or along the light (directional).
pub const DISTANCE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// A viewpoint: matches `View` in raster.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ViewUniform {
    pub view_proj: [[f32; 4]; 4],
    pub eye: [f32; 4],
    pub forward: [f32; 4],
}

impl ViewUniform {
    pub fn perspective(view_proj: Mat4, eye: Vec3, forward: Vec3) -> Self {
        ViewUniform {
            view_proj: view_proj.to_cols_array_2d(),
            eye: [eye.x, eye.y, eye.z, 0.0],
            forward: [forward.x, forward.y, forward.z, 0.0],
        }
    }
    pub fn orthographic(view_proj: Mat4, origin: Vec3, forward: Vec3) -> Self {
        ViewUniform {
            view_proj: view_proj.to_cols_array_2d(),
            eye: [origin.x, origin.y, origin.z, 1.0],
            forward: [forward.x, forward.y, forward.z, 0.0],
        }
    }
}

/// Which triangles a pass draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Subset {
    All,
    Real,
    Virtual,
}

/// The scene's geometry and materials on the GPU.
#[derive(Clone)]
pub struct SceneBuffers {
    pub vertices: std::sync::Arc<wgpu::Buffer>,
    pub materials: std::sync::Arc<wgpu::Buffer>,
    pub real_count: u32,
    pub total_count: u32,
}

impl SceneBuffers {
    pub fn new(ctx: &GpuContext, mesh: &GpuMesh) -> Self {
        // uploaded from the mesh itself (no copy); one zeroed element where a list is empty,
        // as a binding must not be
        let zero_vertex: [GpuVertex; 1] = [bytemuck::Zeroable::zeroed()];
        let zero_material: [GpuMaterial; 1] = [bytemuck::Zeroable::zeroed()];
        let vertices = if mesh.vertices.is_empty() { &zero_vertex[..] } else { &mesh.vertices[..] };
        let materials = if mesh.materials.is_empty() { &zero_material[..] } else { &mesh.materials[..] };
        // kept from frame to frame while the scene is the same ([`GpuContext::resident`])
        SceneBuffers {
            vertices: ctx.resident(
                "vertices",
                bytemuck::cast_slice(vertices),
                // (storage too: a live frame's bounces read the hit triangles' attributes)
                wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::STORAGE,
            ),
            materials: ctx.resident("materials", bytemuck::cast_slice(materials), wgpu::BufferUsages::STORAGE),
            real_count: mesh.real_count,
            total_count: mesh.vertices.len() as u32,
        }
    }

    fn range(&self, subset: Subset) -> std::ops::Range<u32> {
        match subset {
            Subset::All => 0..self.total_count,
            Subset::Real => 0..self.real_count,
            Subset::Virtual => self.real_count..self.total_count,
        }
    }
}

/// The three surface attachments (G-buffer or RSM).
pub struct SurfaceTargets {
    pub position: Arc<wgpu::Texture>,
    pub normal: Arc<wgpu::Texture>,
    pub albedo: Arc<wgpu::Texture>,
}

impl SurfaceTargets {
    /// Targets from the pool ([`texture_2d`]): the caller renders them with a clear first.
    pub fn new(ctx: &GpuContext, width: u32, height: u32, label: &str) -> Self {
        let make = |what: &str| texture_2d(ctx, width, height, SURFACE_FORMAT, &format!("{label} {what}"));
        SurfaceTargets { position: make("position"), normal: make("normal"), albedo: make("albedo") }
    }

    /// Targets of one texel, zero, never rendered (not from the pool, where another user could
    /// leave something in them): bound where a pass reads no surface.
    pub fn placeholder(ctx: &GpuContext, label: &str) -> Self {
        let make =
            |what: &str| Arc::new(ctx.create_texture(&target_2d(1, 1, SURFACE_FORMAT, &format!("{label} {what}"))));
        SurfaceTargets { position: make("position"), normal: make("normal"), albedo: make("albedo") }
    }
}

/// The description of a 2D render target that can also be sampled and copied.
fn target_2d(width: u32, height: u32, format: wgpu::TextureFormat, label: &str) -> wgpu::TextureDescriptor<'_> {
    wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC
            | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    }
}

/// A 2D render target from the pool ([`GpuContext::texture`]): as its last user left it, so
/// whoever reads it renders it with a clear (or copies every texel into it) first.
pub fn texture_2d(
    ctx: &GpuContext,
    width: u32,
    height: u32,
    format: wgpu::TextureFormat,
    label: &str,
) -> Arc<wgpu::Texture> {
    ctx.texture(&target_2d(width, height, format, label))
}

/// The three raster pipelines, built from one shader module.
pub struct Raster {
    gbuffer: wgpu::RenderPipeline,
    /// The G-buffer of the farthest surfaces (depth test `Greater`): the back faces of glass
    /// objects for two-sided refraction (Wyman 2005).
    gbuffer_back: wgpu::RenderPipeline,
    shadow: wgpu::RenderPipeline,
    rsm: wgpu::RenderPipeline,
    /// Depth attachments by size, made once and reused by every pass of that size (each pass
    /// clears its depth on load and discards it on store, and the queue runs passes in order);
    /// making a new one per pass cost each of a frame's 60-odd passes a texture allocation.
    depth_cache: std::sync::Mutex<Vec<((u32, u32), wgpu::TextureView)>>,
    /// The shadow maps' bind groups (one per map, each over its part of the views buffer),
    /// kept while the views buffer [`Raster::shadow_maps`] uploads into is the same one from the
    /// pool (a frame of the same scene gets it again): a weak handle to it, its stride, the groups.
    shadow_groups: std::sync::Mutex<Option<(std::sync::Weak<wgpu::Buffer>, u64, Vec<wgpu::BindGroup>)>>,
    /// A view of each layer of the shadow maps' texture ([`Raster::layer_views`]), kept while
    /// the pool hands the frame the same texture: a weak handle to it (one that went away is
    /// never mistaken for a new one), the views.
    layer_views: std::sync::Mutex<Option<LayerViews>>,
    /// The passes' bind groups kept while their view uniform and materials buffers are the
    /// same ([`groups::KeptGroups`]).
    kept_groups: groups::KeptGroups,
}

type LayerViews = (std::sync::Weak<wgpu::Texture>, Arc<Vec<wgpu::TextureView>>);

pub const SHADER: &str = concat!(include_str!("material.wgsl"), include_str!("raster.wgsl"));

/// What one pass of [`Raster::draw`] draws and into what: the objects of `subset`, at `size`,
/// into `targets` (each a view and the value it is cleared to).
#[derive(Clone, Copy)]
struct Pass<'a> {
    subset: Subset,
    size: (u32, u32),
    targets: &'a [(&'a wgpu::TextureView, f64)],
}

impl Raster {
    pub fn new(ctx: &GpuContext) -> Self {
        let module = ctx.device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("raster.wgsl"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let attributes =
            wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2, 3 => Uint32, 4 => Uint32];
        let layout = wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<GpuVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &attributes,
        };
        let surface =
            Some(wgpu::ColorTargetState { format: SURFACE_FORMAT, blend: None, write_mask: wgpu::ColorWrites::ALL });
        let distance =
            Some(wgpu::ColorTargetState { format: DISTANCE_FORMAT, blend: None, write_mask: wgpu::ColorWrites::ALL });
        let pipeline = |label: &str,
                        entry: &str,
                        targets: &[Option<wgpu::ColorTargetState>],
                        depth_compare: wgpu::CompareFunction| {
            ctx.device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: None,
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs_main"),
                    compilation_options: Default::default(),
                    buffers: &[Some(layout.clone())],
                },
                primitive: wgpu::PrimitiveState { cull_mode: None, ..Default::default() },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(true),
                    depth_compare: Some(depth_compare),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    targets,
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let less = wgpu::CompareFunction::Less;
        let surfaces = [surface.clone(), surface.clone(), surface.clone()];
        Raster {
            gbuffer: pipeline("g-buffer", "fs_gbuffer", &surfaces, less),
            gbuffer_back: pipeline("g-buffer of back faces", "fs_gbuffer", &surfaces, wgpu::CompareFunction::Greater),
            shadow: pipeline("shadow map", "fs_shadow", std::slice::from_ref(&distance), less),
            rsm: pipeline(
                "reflective shadow map",
                "fs_rsm",
                &[distance, surface.clone(), surface.clone(), surface],
                less,
            ),
            depth_cache: std::sync::Mutex::new(Vec::new()),
            shadow_groups: std::sync::Mutex::new(None),
            layer_views: std::sync::Mutex::new(None),
            kept_groups: groups::KeptGroups::default(),
        }
    }

    fn bind_group(
        &self,
        ctx: &GpuContext,
        pipeline: &wgpu::RenderPipeline,
        scene: &SceneBuffers,
        view: &ViewUniform,
    ) -> wgpu::BindGroup {
        let uniform = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("view"),
            contents: bytemuck::bytes_of(view),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        // the uniform's buffer from the pool, written above: a group over it made in an
        // earlier frame binds the same bytes
        self.kept_groups.get_or_make(pipeline, &uniform, &scene.materials, || {
            self.bind_group_with(ctx, pipeline, scene, uniform.as_entire_binding())
        })
    }

    /// The bind group of a pass whose view uniform is `view` (a whole buffer or a part of one).
    fn bind_group_with(
        &self,
        ctx: &GpuContext,
        pipeline: &wgpu::RenderPipeline,
        scene: &SceneBuffers,
        view: wgpu::BindingResource<'_>,
    ) -> wgpu::BindGroup {
        let layout = pipeline.get_bind_group_layout(0);
        // fs_shadow does not read the materials, so its derived layout has no binding 1
        let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: view }];
        if !std::ptr::eq(pipeline, &self.shadow) {
            entries.push(wgpu::BindGroupEntry { binding: 1, resource: scene.materials.as_entire_binding() });
        }
        ctx.bind_group(&wgpu::BindGroupDescriptor { label: None, layout: &layout, entries: &entries })
    }

    fn depth(&self, ctx: &GpuContext, width: u32, height: u32) -> wgpu::TextureView {
        let mut cache = self.depth_cache.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some((_, view)) = cache.iter().find(|(size, _)| *size == (width, height)) {
            return view.clone();
        }
        let view = ctx
            .create_texture(&wgpu::TextureDescriptor {
                label: Some("depth"),
                size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: DEPTH_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                view_formats: &[],
            })
            .create_view(&Default::default());
        cache.push(((width, height), view.clone()));
        view
    }

    fn draw(
        &self,
        ctx: &GpuContext,
        pipeline: &wgpu::RenderPipeline,
        scene: &SceneBuffers,
        view: &ViewUniform,
        pass: Pass,
    ) {
        let bind_group = self.bind_group(ctx, pipeline, scene, view);
        let mut encoder = ctx.encoder();
        self.record(ctx, &mut encoder, pipeline, &bind_group, scene, pass);
        ctx.submit(encoder);
    }

    /// Records one pass of [`Raster::draw`] into `encoder`.
    fn record(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::RenderPipeline,
        bind_group: &wgpu::BindGroup,
        scene: &SceneBuffers,
        pass: Pass,
    ) {
        let Pass { subset, size, targets } = pass;
        let depth = self.depth(ctx, size.0, size.1);
        let attachments: Vec<Option<wgpu::RenderPassColorAttachment>> = targets
            .iter()
            .map(|(view, clear)| {
                Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color { r: *clear, g: *clear, b: *clear, a: *clear }),
                        store: wgpu::StoreOp::Store,
                    },
                })
            })
            .collect();
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: None,
                color_attachments: &attachments,
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Discard }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            let range = scene.range(subset);
            if !range.is_empty() {
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, bind_group, &[]);
                pass.set_vertex_buffer(0, scene.vertices.slice(..));
                pass.draw(range, 0..1);
            }
        }
    }

    /// The camera's G-buffer (all geometry); position.w is 0 where nothing was drawn.
    pub fn gbuffer(&self, ctx: &GpuContext, scene: &SceneBuffers, view: &ViewUniform, targets: &SurfaceTargets) {
        let size = (targets.position.width(), targets.position.height());
        let views = [&targets.position, &targets.normal, &targets.albedo].map(|t| ctx.views.of(t));
        let targets = [(&*views[0], 0.0), (&*views[1], 0.0), (&*views[2], 0.0)];
        self.draw(ctx, &self.gbuffer, scene, view, Pass { subset: Subset::All, size, targets: &targets });
    }

    /// A shadow map of `subset` into `distance` (a layer view); empty texels hold 1e30.
    pub fn shadow_map(
        &self,
        ctx: &GpuContext,
        scene: &SceneBuffers,
        view: &ViewUniform,
        subset: Subset,
        distance: &wgpu::TextureView,
        size: u32,
    ) {
        self.draw(ctx, &self.shadow, scene, view, Pass { subset, size: (size, size), targets: &[(distance, 1e30)] });
    }

    /// A 2D view of each layer of `texture` (the shadow maps' targets), made when the texture is
    /// not the one the last frame's were made of (64 views a frame at the thesis setting).
    pub fn layer_views(&self, texture: &Arc<wgpu::Texture>) -> Arc<Vec<wgpu::TextureView>> {
        let mut kept = self.layer_views.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some((of, views)) = kept.as_ref()
            && of.upgrade().is_some_and(|of| Arc::ptr_eq(&of, texture))
        {
            return views.clone();
        }
        let view = |layer: u32| {
            texture.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2),
                base_array_layer: layer,
                array_layer_count: Some(1),
                ..Default::default()
            })
        };
        let views = Arc::new((0..texture.depth_or_array_layers()).map(view).collect::<Vec<_>>());
        *kept = Some((Arc::downgrade(texture), views.clone()));
        views
    }

    /// Several shadow maps of one size (each a view, a subset and a target), recorded into one
    /// command buffer and submitted once, their views in one uniform buffer — as
    /// [`Raster::shadow_map`] one by one, without a buffer and a submission per map.
    pub fn shadow_maps(
        &self,
        ctx: &GpuContext,
        scene: &SceneBuffers,
        maps: &[(ViewUniform, Subset, &wgpu::TextureView)],
        size: u32,
    ) {
        if maps.is_empty() {
            return;
        }
        let stride = (std::mem::size_of::<ViewUniform>() as u64)
            .next_multiple_of(ctx.device.limits().min_uniform_buffer_offset_alignment as u64);
        let mut contents = vec![0u8; stride as usize * maps.len()];
        for (k, (view, _, _)) in maps.iter().enumerate() {
            let at = k * stride as usize;
            contents[at..at + std::mem::size_of::<ViewUniform>()].copy_from_slice(bytemuck::bytes_of(view));
        }
        let views = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("views"),
            contents: &contents,
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let mut groups = self.shadow_groups.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let kept = groups.as_ref().is_some_and(|(buffer, kept_stride, kept)| {
            buffer.upgrade().is_some_and(|b| Arc::ptr_eq(&b, &views))
                && *kept_stride == stride
                && kept.len() == maps.len()
        });
        if !kept {
            let group = |k: usize| {
                let binding = wgpu::BufferBinding {
                    buffer: &views,
                    offset: k as u64 * stride,
                    size: std::num::NonZeroU64::new(std::mem::size_of::<ViewUniform>() as u64),
                };
                self.bind_group_with(ctx, &self.shadow, scene, wgpu::BindingResource::Buffer(binding))
            };
            *groups = Some((Arc::downgrade(&views), stride, (0..maps.len()).map(group).collect()));
        }
        let bind_groups = &groups.as_ref().expect("made above").2;
        let mut encoder = ctx.encoder();
        for ((_, subset, distance), bind_group) in maps.iter().zip(bind_groups) {
            let pass = Pass { subset: *subset, size: (size, size), targets: &[(*distance, 1e30)] };
            self.record(ctx, &mut encoder, &self.shadow, bind_group, scene, pass);
        }
        drop(groups);
        ctx.submit(encoder);
    }

    /// A reflective shadow map: distance plus the surfaces the light sees (its own resolution,
    /// separate from the shadow map used for visibility).
    pub fn rsm(
        &self,
        ctx: &GpuContext,
        scene: &SceneBuffers,
        view: &ViewUniform,
        subset: Subset,
        distance: &wgpu::TextureView,
        targets: &SurfaceTargets,
    ) {
        let size = (targets.position.width(), targets.position.height());
        let views = [&targets.position, &targets.normal, &targets.albedo].map(|t| ctx.views.of(t));
        let targets = [(distance, 1e30), (&*views[0], 0.0), (&*views[1], 0.0), (&*views[2], 0.0)];
        self.draw(ctx, &self.rsm, scene, view, Pass { subset, size, targets: &targets });
    }

    /// Several reflective shadow maps ([`Raster::rsm`] each) recorded into one encoder: one
    /// `finish` for all of them instead of one a map.
    pub fn rsms(&self, ctx: &GpuContext, scene: &SceneBuffers, maps: &[RsmDraw<'_>]) {
        if maps.is_empty() {
            return;
        }
        let mut encoder = ctx.encoder();
        for map in maps {
            let size = (map.targets.position.width(), map.targets.position.height());
            let views = [map.distance, &map.targets.position, &map.targets.normal, &map.targets.albedo]
                .map(|t| ctx.views.of(t));
            let targets = [(&*views[0], 1e30), (&*views[1], 0.0), (&*views[2], 0.0), (&*views[3], 0.0)];
            let bind_group = self.bind_group(ctx, &self.rsm, scene, &map.view);
            self.record(
                ctx,
                &mut encoder,
                &self.rsm,
                &bind_group,
                scene,
                Pass { subset: map.subset, size, targets: &targets },
            );
        }
        ctx.submit(encoder);
    }

    /// G-buffer draws into parts of one set of targets, in one render pass: each draw its own
    /// view, viewport `[x, y, width, height]` and vertex ranges. With `farthest` the depth test
    /// keeps the farthest surface (back faces of closed objects) instead of the nearest.
    /// Used for the impostors of mirrors and glass (six cube faces side by side, without the
    /// object itself) and for the back faces of glass ([`super::specular`]).
    pub fn gbuffer_draws(
        &self,
        ctx: &GpuContext,
        scene: &SceneBuffers,
        targets: &SurfaceTargets,
        draws: &[GbufferDraw<'_>],
        farthest: bool,
    ) {
        let pipeline = if farthest { &self.gbuffer_back } else { &self.gbuffer };
        let (width, height) = (targets.position.width(), targets.position.height());
        let views = [&targets.position, &targets.normal, &targets.albedo].map(|t| ctx.views.of(t));
        let bind_groups: Vec<wgpu::BindGroup> =
            draws.iter().map(|draw| self.bind_group(ctx, pipeline, scene, &draw.view)).collect();
        let depth = self.depth(ctx, width, height);
        let attachments: Vec<Option<wgpu::RenderPassColorAttachment>> = views
            .iter()
            .map(|view| {
                Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })
            })
            .collect();
        let mut encoder = ctx.encoder();
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("g-buffer draws"),
                color_attachments: &attachments,
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(if farthest { 0.0 } else { 1.0 }),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_vertex_buffer(0, scene.vertices.slice(..));
            for (draw, bind_group) in draws.iter().zip(&bind_groups) {
                let [x, y, w, h] = draw.viewport;
                pass.set_viewport(x as f32, y as f32, w as f32, h as f32, 0.0, 1.0);
                pass.set_scissor_rect(x, y, w, h);
                pass.set_bind_group(0, bind_group, &[]);
                for range in draw.ranges.iter().filter(|range| !range.is_empty()) {
                    pass.draw(range.clone(), 0..1);
                }
            }
        }
        ctx.submit(encoder);
    }
}

/// One map of [`Raster::rsms`]: its view, the objects it draws, its targets.
pub struct RsmDraw<'a> {
    pub view: ViewUniform,
    pub subset: Subset,
    pub distance: &'a Arc<wgpu::Texture>,
    pub targets: &'a SurfaceTargets,
}

/// One draw of [`Raster::gbuffer_draws`].
pub struct GbufferDraw<'a> {
    pub view: ViewUniform,
    pub viewport: [u32; 4],
    pub ranges: &'a [std::ops::Range<u32>],
}
