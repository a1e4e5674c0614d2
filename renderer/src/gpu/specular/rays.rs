//! The camera's reflected and refracted rays (thesis 5.3, steps 2, 3 and 5): the back faces of
//! glass, the ray search through the impostors, and L'_rv, L'_r and CI_std combined from the
//! shaded hits.

use super::*;

/// Where the rays of a search start: the eye's view-projection, its position and the image
/// size (width, height) of the G-buffer seen from it.
#[derive(Clone, Copy, Debug)]
pub(super) struct Eye {
    pub view_proj: Mat4,
    pub position: Vec3,
    pub size: (u32, u32),
}

impl Specular {
    /// The back faces of the glass objects among `ranges` seen from `view` (step 2): the
    /// farthest surfaces, for the exit of two-sided refraction; 1×1 without glass (the shader
    /// reads none, but the binding must exist).
    pub(super) fn back_faces(
        &self,
        ctx: &GpuContext,
        raster: &Raster,
        buffers: &SceneBuffers,
        glass: &[std::ops::Range<u32>],
        view: &ViewUniform,
        (width, height): (u32, u32),
    ) -> SurfaceTargets {
        if glass.is_empty() {
            return SurfaceTargets::placeholder(ctx, "no back faces");
        }
        let back = SurfaceTargets::new(ctx, width, height, "back faces");
        let draw = GbufferDraw { view: *view, viewport: [0, 0, width, height], ranges: glass };
        raster.gbuffer_draws(ctx, buffers, &back, std::slice::from_ref(&draw), true);
        back
    }

    /// The ray search (step 3) for every pixel of `gbuffer` (seen from `eye`) on a mirror or
    /// glass: hits and weights, submitted.
    pub(super) fn search(
        &self,
        ctx: &GpuContext,
        impostors: &Impostors,
        gbuffer: &SurfaceTargets,
        back: &SurfaceTargets,
        eye: Eye,
        params: &SpecularParams,
    ) -> Search {
        let Eye { view_proj, position: eye, size: (width, height) } = eye;
        let stride = row_stride(width);
        let (centre, radius) = impostors.bounds;
        let uniform = Params {
            view_proj: view_proj.to_cols_array_2d(),
            camera: eye.extend(0.0).to_array(),
            size: [width, height, impostors.size, stride],
            search: [params.search_steps.max(1), params.secant_steps, impostors.env_size[0], impostors.env_size[1]],
            env: [impostors.env_rotation, impostors.has_environment as u32 as f32, radius, 0.0],
            scene: centre.extend(0.0).to_array(),
        };
        let params_buffer = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("specular params"),
            contents: bytemuck::bytes_of(&uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let plane_texels = stride as u64 * height as u64;
        let buffer = |label: &str, texels: u64| {
            ctx.buffer(label, texels * 16, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC, Contents::Zeroed)
        };
        let hits = buffer("specular hits", 6 * plane_texels);
        let info = buffer("specular weights", 4 * width as u64 * height as u64);
        let view = |t: &std::sync::Arc<wgpu::Texture>| ctx.views.of(t);
        let texture_views = [
            view(&gbuffer.position),
            view(&gbuffer.normal),
            view(&back.position),
            view(&back.normal),
            view(&impostors.targets.position),
            view(&impostors.targets.normal),
            view(&impostors.targets.albedo),
        ];
        let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: params_buffer.as_entire_binding() }];
        for (k, texture) in texture_views.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: 1 + k as u32,
                resource: wgpu::BindingResource::TextureView(texture),
            });
        }
        entries.push(wgpu::BindGroupEntry { binding: 8, resource: impostors.objects.as_entire_binding() });
        entries.push(wgpu::BindGroupEntry { binding: 9, resource: impostors.environment.as_entire_binding() });
        entries.push(wgpu::BindGroupEntry { binding: 10, resource: hits.as_entire_binding() });
        entries.push(wgpu::BindGroupEntry { binding: 11, resource: info.as_entire_binding() });
        ctx.dispatch("specular trace", &self.trace, &entries, [width.div_ceil(8), height.div_ceil(8)]);
        Search { params: params_buffer, hits, info, stride }
    }

    /// Back faces and the ray search from the camera (steps 2–3); `passes` gets one entry each.
    pub fn trace(
        &self,
        ctx: &GpuContext,
        raster: &Raster,
        passes: &mut Vec<crate::gpu::PassTime>,
        at: FrameScene,
        rays: &RayInputs,
        params: &SpecularParams,
    ) -> Traced {
        let FrameScene { scene, mesh, buffers } = at;
        let RayInputs { impostors, gbuffer, view: camera_view, view_proj: camera_view_proj } = *rays;
        let (width, height) = (scene.camera.width, scene.camera.height);
        let glass: Vec<std::ops::Range<u32>> = mesh
            .specular
            .iter()
            .filter(|o| matches!(o.delta, DeltaBsdf::Dielectric { .. }))
            .map(|o| o.range.clone())
            .collect();
        let back = if glass.is_empty() {
            self.back_faces(ctx, raster, buffers, &glass, camera_view, (width, height))
        } else {
            crate::gpu::timed(ctx, passes, "back faces of glass".into(), || {
                self.back_faces(ctx, raster, buffers, &glass, camera_view, (width, height))
            })
        };
        let label = format!(
            "reflected and refracted rays ({} search + {} secant steps)",
            params.search_steps.max(1),
            params.secant_steps
        );
        let refl = SurfaceTargets::new(ctx, width, height, "GBuf_refl");
        let refr = SurfaceTargets::new(ctx, width, height, "GBuf_refr");
        let search = crate::gpu::timed(ctx, passes, label, || {
            let eye = Eye { view_proj: camera_view_proj, position: scene.camera.position, size: (width, height) };
            let search = self.search(ctx, impostors, gbuffer, &back, eye, params);
            let plane_texels = search.stride as u64 * height as u64;
            let mut encoder = ctx.encoder();
            let targets = [&refl.position, &refl.normal, &refl.albedo, &refr.position, &refr.normal, &refr.albedo];
            for (p, texture) in targets.into_iter().enumerate() {
                encoder.copy_buffer_to_texture(
                    wgpu::TexelCopyBufferInfo {
                        buffer: &search.hits,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset: p as u64 * plane_texels * 16,
                            bytes_per_row: Some(search.stride * 16),
                            rows_per_image: Some(height),
                        },
                    },
                    texture.as_image_copy(),
                    wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                );
            }
            ctx.submit(encoder);
            search
        });
        let report =
            SpecularReport { objects: impostors.names.clone(), impostor_size: impostors.size, ..Default::default() };
        Traced {
            refl,
            refr,
            params: search.params,
            hits: search.hits,
            info: search.info,
            report,
            counts: None,
            eye: mesh.specular[0].centre,
        }
    }

    /// L'_rv, L'_r and CI_std (step 5): rewrites `solutions` at the specular pixels and returns
    /// the base buffer [`crate::gpu::compose`] reads (CI_std, w = 1 at a specular pixel).
    pub fn combine(&self, ctx: &GpuContext, traced: &mut Traced, inputs: &CombineInputs) -> Arc<wgpu::Buffer> {
        let CombineInputs {
            gbuffer,
            solutions,
            reflected: refl_solutions,
            refracted: refr_solutions,
            photo,
            width,
            height,
        } = *inputs;
        let base = ctx.buffer(
            "specular base",
            width as u64 * height as u64 * 16,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            Contents::Zeroed,
        );
        let counts = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("specular counts"),
            contents: &[0u8; 32],
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        });
        let position = ctx.views.of(&gbuffer.position);
        let entries = [
            wgpu::BindGroupEntry { binding: 0, resource: traced.params.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&position) },
            wgpu::BindGroupEntry { binding: 10, resource: traced.hits.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 11, resource: traced.info.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 12, resource: solutions.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 13, resource: refl_solutions.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 14, resource: refr_solutions.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 15, resource: photo.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 16, resource: base.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 17, resource: counts.as_entire_binding() },
        ];
        ctx.dispatch("specular combine", &self.combine, &entries, [width.div_ceil(8), height.div_ceil(8)]);
        traced.counts = Some(counts);
        base
    }
}
