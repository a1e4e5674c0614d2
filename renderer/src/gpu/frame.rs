//! One GPU frame as an explicit, ordered list of passes ([`PASSES`]), each a function over the
//! frame's resources ([`FrameTargets`]): what a pass makes it leaves in the targets for the
//! passes after it. A pass records and submits its GPU work and returns (its command buffers
//! held with the frame's others and handed to the queue together at the frame's next wait:
//! [`super::stream`]); it waits for the device only where it needs data on the host (a stimulus's VPLs and bounces, which the host's
//! reference steps make; a colour mapping's sums; the final read-back, which brings the report's
//! counts along), and, while the context times passes ([`GpuContext::set_pass_waits`]), after
//! itself to be timed. A live frame's VPLs are made and consumed on the GPU
//! ([`bounce_chain`]), so a live frame waits once, for its image, and makes one submission.
//!
//! The order is the thesis's (Figure 5.3; the module documentation of [`super`] says what each
//! pass computes): [`FrameTargets::new`] builds the scene's mesh and uploads it, then
//! shadow maps, the mirrors' and glass's impostors and caustic maps, RSMs and VPLs, further
//! bounces, ISMs, the camera's G-buffer, the specular rays and caustic splats, shading, the
//! indirect light, caustics into L_rv and L_r, the photograph, the specular hits, colour
//! mapping, composition, read-back and camera artifacts.

use super::*;
use crate::ca::CaReport;

mod vpls;

/// A pass of the frame: reads what the passes before it left in the targets, adds its own.
type Pass = fn(&DirRenderer, &mut FrameTargets) -> Result<()>;

/// The frame's passes, in order ([`DirRenderer::render_frame`] runs them all; each decides from
/// the scene and the parameters whether it has anything to do).
/// The photograph a frame is given: borrowed, or shared by its caller (a live frame that is only
/// shown: [`DirRenderer::render_display`]), whose `Arc` the photograph's kept buffer holds.
#[derive(Clone, Copy)]
pub(super) enum PhotoRef<'a> {
    Image(&'a Image),
    Shared(&'a Arc<Image>),
}

impl PhotoRef<'_> {
    pub(super) fn image(&self) -> &Image {
        match self {
            PhotoRef::Image(image) => image,
            PhotoRef::Shared(shared) => shared,
        }
    }

    /// Whether the photograph `kept` with the resident buffer ([`GpuContext::resident_for`]) has
    /// this one's bits in every pixel, so that the shaders would see exactly the bytes they saw.
    /// The same `Arc` proves it without a look: the kept clone holds it, so it cannot have been
    /// changed in place since (`Arc::make_mut` copies a shared image); else the pixels are
    /// compared (a 1024×768 photograph is 9.4 MB a side: 0.73–0.80 ms pixel by pixel in one
    /// thread at the thesis setting), bit for bit, in blocks on all threads, each block without
    /// an early exit so that it vectorises — and a shared photograph with the same bits is
    /// kept in place of the one kept, so that the next frame given it needs no look.
    fn stands_for(kept: &mut Arc<Image>, photo: &PhotoRef<'_>) -> bool {
        use rayon::prelude::*;
        if let PhotoRef::Shared(shared) = photo
            && Arc::ptr_eq(kept, shared)
        {
            return true;
        }
        let (a, b) = (&**kept, photo.image());
        let differ = |(p, q): (&[Vec3], &[Vec3])| {
            let bits = |v: &Vec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
            p.iter().zip(q).fold(0u32, |acc, (p, q)| {
                let (p, q) = (bits(p), bits(q));
                acc | (p[0] ^ q[0]) | (p[1] ^ q[1]) | (p[2] ^ q[2])
            }) != 0
        };
        let same = a.width == b.width
            && a.height == b.height
            && a.pixels.len() == b.pixels.len()
            && !a.pixels.par_chunks(PHOTO_BLOCK).zip(b.pixels.par_chunks(PHOTO_BLOCK)).any(differ);
        if same && let PhotoRef::Shared(shared) = photo {
            *kept = Arc::clone(shared);
        }
        same
    }
}

/// Pixels per block of the photograph's comparison with the one kept (`pass_photo`): 192 KB a
/// side.
const PHOTO_BLOCK: usize = 16 * 1024;

pub(super) const PASSES: [(&str, Pass); 16] = [
    ("shadow maps", DirRenderer::pass_shadow_maps),
    ("impostors and caustic maps", DirRenderer::pass_specular_maps),
    ("RSMs and VPLs", DirRenderer::pass_vpls),
    ("further bounces", DirRenderer::pass_bounces),
    ("imperfect shadow maps", DirRenderer::pass_isms),
    ("g-buffer", DirRenderer::pass_gbuffer),
    ("specular rays and caustic splats", DirRenderer::pass_specular_rays),
    ("shading", DirRenderer::pass_shading),
    ("indirect light", DirRenderer::pass_indirect),
    ("caustics into L_rv and L_r", DirRenderer::pass_caustics),
    ("photograph", DirRenderer::pass_photo),
    ("specular hits", DirRenderer::pass_specular_hits),
    ("colour mapping", DirRenderer::pass_colour_mapping),
    ("composition", DirRenderer::pass_composition),
    ("read-back", DirRenderer::pass_readback),
    ("camera artifacts", DirRenderer::pass_camera_artifacts),
];

/// The environment's orthographic views: centre, radius across and depth along the light.
#[derive(Clone, Copy)]
pub(super) struct EnvView {
    centre: Vec3,
    radius: f32,
    depth: f32,
}

/// The frame's images on the host, after the read-back.
pub(super) struct FrameImages {
    pub composite: Image,
    pub l_rv: Image,
    pub l_r: Image,
    pub virtual_mask: Mask,
    pub flags: Vec<u32>,
    /// A frame only shown: the composite as read back in 8 bits (then `composite` is empty).
    pub display: Option<crate::image::Rgba8>,
}

/// Everything a frame's passes read and write, filled in pass by pass ([`PASSES`]).
pub(super) struct FrameTargets<'a> {
    pub scene: &'a Scene,
    pub photo: &'a Image,
    /// The photograph as the caller shares it (a live frame that is only shown): kept with its
    /// buffer, so that the next frame with the same `Arc` skips the comparison (`pass_photo`).
    pub shared_photo: Option<&'a Arc<Image>>,
    pub params: &'a DirParams,
    /// VPLs given instead of made (tests of eqs. 5.6–5.7).
    pub given_vpls: Option<&'a [vpl::GpuVpl]>,
    pub state: &'a mut LiveState,
    pub mode: Frame,
    pub width: u32,
    pub height: u32,
    pub passes: Vec<PassTime>,
    pub mesh: Arc<mesh::GpuMesh>,
    pub buffers: SceneBuffers,
    pub has_virtual: bool,
    /// Whether virtual objects cast shadows (the condition shows them and there are some).
    pub virtual_maps: bool,
    /// Shadow maps: their size, the environment's directions (towards the light, irradiance),
    /// the lights (spot lights, then the environment's), each spot's view.
    pub shadow_size: u32,
    pub env_dirs: Vec<(Vec3, Vec3)>,
    pub n_lights: u32,
    pub shadow_maps: Option<Arc<wgpu::Texture>>,
    pub lights: Vec<GpuLight>,
    pub spot_views: Vec<(ViewUniform, f32)>,
    pub env_view: Option<EnvView>,
    pub impostors: Option<specular::Impostors>,
    pub photon_maps: std::result::Result<specular::PhotonMaps, &'static str>,
    pub vpls: Vec<vpl::GpuVpl>,
    /// A live frame's VPLs, left on the GPU ([`bounce_chain`]): `vpl_slots` slots, zero where
    /// none (then `vpls` stays empty).
    pub gpu_vpls: Option<Arc<wgpu::Buffer>>,
    pub vpl_slots: u32,
    /// A live frame's further bounces and budget split, whose plan and counts come back with the
    /// image for the report.
    pub chain: Option<bounce_chain::ChainOutput>,
    /// The VPLs the chain made in all, once read back.
    pub chain_vpls: Option<usize>,
    pub first_bounce: Option<FirstBounce>,
    pub bounce_reports: Vec<bounce::BounceReport>,
    pub ism_atlas: Option<ism::IsmAtlas>,
    pub gbuffer: Option<SurfaceTargets>,
    pub camera_view_proj: Mat4,
    pub camera_view: Option<ViewUniform>,
    pub traced: Option<specular::Traced>,
    pub caustic_buffer: Option<Arc<wgpu::Buffer>>,
    /// The caustic splats' counts, read back with the images into the specular report.
    pub caustic_counts: Option<Arc<wgpu::Buffer>>,
    pub shade_params: Option<ShadeParams>,
    pub output: Option<shade::ShadeOutput>,
    pub smoothed: bool,
    pub photo_buffer: Option<Arc<wgpu::Buffer>>,
    pub specular_base: Option<Arc<wgpu::Buffer>>,
    pub mapped: Option<Arc<wgpu::Buffer>>,
    pub cm_report: Option<CmReport>,
    pub composite_buffer: Option<Arc<wgpu::Buffer>>,
    pub images: Option<FrameImages>,
    pub ca_report: Option<CaReport>,
}

/// The VPLs as the shading pass takes them: a live frame's on the GPU, or the host's.
fn shade_vpls<'t>(gpu: &'t Option<Arc<wgpu::Buffer>>, host: &'t [vpl::GpuVpl]) -> shade::ShadeVpls<'t> {
    match gpu {
        Some(buffer) => shade::ShadeVpls::Gpu(buffer),
        None => shade::ShadeVpls::Host(host),
    }
}

/// What a pass needs from an earlier one (the order of [`PASSES`] guarantees it).
fn ran<'t, T>(value: &'t Option<T>, what: &str) -> &'t T {
    value.as_ref().unwrap_or_else(|| panic!("the frame's passes are out of order: no {what} yet"))
}

impl<'a> FrameTargets<'a> {
    /// Starts a frame: the scene's mesh (CPU; kept in `meshes` while the scene's geometry stays)
    /// and its buffers (kept with it: `scene_buffers`), before the first pass.
    pub fn new(
        r: &DirRenderer,
        scene: &'a Scene,
        photo: &'a Image,
        params: &'a DirParams,
        state: &'a mut LiveState,
        mode: Frame,
    ) -> FrameTargets<'a> {
        let ctx = &r.ctx;
        let mut passes = Vec::new();
        let start = Instant::now();
        let mesh = r.meshes.get(scene);
        passes.push(PassTime::new("scene mesh (CPU)", start.elapsed().as_secs_f64() * 1e3));
        let buffers = timed(ctx, &mut passes, "upload scene".into(), || {
            r.scene_buffers.get(&mesh, |mesh| SceneBuffers::new(ctx, mesh))
        });
        let has_virtual = mesh.virtual_count() > 0;
        FrameTargets {
            scene,
            photo,
            shared_photo: None,
            params,
            given_vpls: None,
            state,
            mode,
            width: scene.camera.width,
            height: scene.camera.height,
            passes,
            virtual_maps: params.condition != GiLevel::None && has_virtual,
            has_virtual,
            mesh,
            buffers,
            shadow_size: params.shadow_map_size.max(16),
            env_dirs: Vec::new(),
            n_lights: 0,
            shadow_maps: None,
            lights: Vec::new(),
            spot_views: Vec::new(),
            env_view: None,
            impostors: None,
            photon_maps: Err("no mirror or glass"),
            vpls: Vec::new(),
            gpu_vpls: None,
            vpl_slots: 0,
            chain: None,
            chain_vpls: None,
            first_bounce: None,
            bounce_reports: Vec::new(),
            ism_atlas: None,
            gbuffer: None,
            camera_view_proj: Mat4::IDENTITY,
            camera_view: None,
            traced: None,
            caustic_buffer: None,
            caustic_counts: None,
            shade_params: None,
            output: None,
            smoothed: false,
            photo_buffer: None,
            specular_base: None,
            mapped: None,
            cm_report: None,
            composite_buffer: None,
            images: None,
            ca_report: None,
        }
    }

    /// The specular passes' counts, read back with the images (the buffers `pass_readback`
    /// staged, in its order: the combine pass's five, then the caustic splats' two), into
    /// their reports; and a live frame's VPL chain's plan and counts into the bounces' reports.
    fn take_counts(&mut self, words: &[u32], chain: Option<&[u32]>) {
        if let (Some(out), Some(chain)) = (&self.chain, chain) {
            let (reports, vpls) = out.report(chain);
            self.bounce_reports = reports;
            self.chain_vpls = Some(vpls);
        }
        let mut words = words.iter().copied();
        let mut next = || words.next().unwrap_or(0);
        if let Some(traced) = self.traced.as_mut() {
            if traced.counts.is_some() {
                let report = &mut traced.report;
                (report.pixels, report.rays, report.back_projected, report.rendered, report.missed) =
                    (next(), next(), next(), next(), next());
                // the buffer holds eight words
                for _ in 5..8 {
                    next();
                }
            }
            if self.caustic_counts.is_some()
                && let Some(caustics) = traced.report.caustics.as_mut()
            {
                (caustics.photons, caustics.splatted) = (next(), next());
            }
        }
    }

    /// The VPLs the ISMs and the shading go through: the host's, or a live frame's slots on the GPU.
    pub(super) fn vpl_count(&self) -> u32 {
        if self.gpu_vpls.is_some() { self.vpl_slots } else { self.vpls.len() as u32 }
    }

    /// Records a pass's time under `name` (see [`timed`]).
    fn timed<T>(&mut self, ctx: &GpuContext, name: String, f: impl FnOnce() -> T) -> T {
        timed(ctx, &mut self.passes, name, f)
    }
}

impl DirRenderer {
    /// Step 1: Shadow maps: per spot light a real-only and (with virtual shadows) a virtual-only map,
    /// layers 2i and 2i+1; the environment as directional lights (Hammersley points through the
    /// map's importance sampler, each carrying E = L / (N · pdf); they are real, r(pl) = 1),
    /// each with its orthographic maps, all in one submission.
    fn pass_shadow_maps(&self, f: &mut FrameTargets) -> Result<()> {
        let ctx = &self.ctx;
        let (scene, params, size) = (f.scene, f.params, f.shadow_size);
        if let Some(env) = scene.environment.as_ref().filter(|_| params.env_lights > 0) {
            let n = params.env_lights;
            for k in 0..n {
                if let Some((dir, radiance, pdf)) = env.sample((k as f32 + 0.5) / n as f32, radical_inverse(k))
                    && pdf > 0.0
                    && radiance.max_element() > 0.0
                {
                    f.env_dirs.push((-dir, radiance / (n as f32 * pdf)));
                }
            }
        }
        f.n_lights = (scene.spots.len() + f.env_dirs.len()) as u32;
        // from the pool: every layer the shaders read is rendered with a clear below (the
        // virtual layers are read only where they are drawn: `virtual_maps`)
        let shadow_maps = ctx.texture(&wgpu::TextureDescriptor {
            label: Some("shadow maps"),
            size: wgpu::Extent3d { width: size, height: size, depth_or_array_layers: (2 * f.n_lights).max(2) },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: raster::DISTANCE_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        // kept from frame to frame while the pool hands out the same texture
        let layer_views = self.raster.layer_views(&shadow_maps);
        let layer_view = |layer: u32| &layer_views[layer as usize];
        let (mesh, buffers, virtual_maps) = (&f.mesh, &f.buffers, f.virtual_maps);
        for (i, spot) in scene.spots.iter().enumerate() {
            let (matrix, tan_half) =
                spot_view(spot.position, spot.direction, spot.cos_outer, mesh.bounds_centre, mesh.bounds_radius);
            let view = ViewUniform::perspective(matrix, spot.position, spot.direction);
            let layer = 2 * i as u32;
            timed(ctx, &mut f.passes, format!("shadow map {} real", spot.name), || {
                self.raster.shadow_map(ctx, buffers, &view, Subset::Real, layer_view(layer), size)
            });
            if virtual_maps {
                timed(ctx, &mut f.passes, format!("shadow map {} virtual", spot.name), || {
                    self.raster.shadow_map(ctx, buffers, &view, Subset::Virtual, layer_view(layer + 1), size)
                });
            }
            f.lights.push(GpuLight {
                view_proj: matrix.to_cols_array_2d(),
                position: [spot.position.x, spot.position.y, spot.position.z, if spot.real { 1.0 } else { 0.0 }],
                direction: [spot.direction.x, spot.direction.y, spot.direction.z, spot.cos_outer],
                intensity: [spot.intensity.x, spot.intensity.y, spot.intensity.z, spot.cos_inner],
                info: [0.0, layer as f32, 2.0 * tan_half / size as f32, 0.0],
            });
            f.spot_views.push((view, tan_half));
        }
        // the environment's maps cover where virtual objects can change anything: around them (3×
        // their bounding radius, where their shadows fall), or everything without them
        let (centre, radius) = match mesh.virtual_bounds {
            Some((c, r)) => (c, (3.0 * r).min(mesh.bounds_radius)),
            None => (mesh.bounds_centre, mesh.bounds_radius),
        };
        let depth = (mesh.bounds_centre - centre).length() + mesh.bounds_radius + 1e-3;
        f.env_view = Some(EnvView { centre, radius, depth });
        if !f.env_dirs.is_empty() {
            let first = f.lights.len() as u32;
            let (env_dirs, lights) = (&f.env_dirs, &mut f.lights);
            timed(
                ctx,
                &mut f.passes,
                format!(
                    "shadow maps environment ({} directions{})",
                    env_dirs.len(),
                    if virtual_maps { ", real and virtual" } else { ", real" }
                ),
                || {
                    // every direction's maps in one submission
                    let mut maps = Vec::new();
                    for (k, (forward, irradiance)) in env_dirs.iter().enumerate() {
                        let (matrix, eye) = directional_view(*forward, centre, radius, depth);
                        let view = ViewUniform::orthographic(matrix, eye, *forward);
                        let layer = 2 * (first + k as u32);
                        maps.push((view, Subset::Real, layer_view(layer)));
                        if virtual_maps {
                            maps.push((view, Subset::Virtual, layer_view(layer + 1)));
                        }
                        lights.push(GpuLight {
                            view_proj: matrix.to_cols_array_2d(),
                            position: [eye.x, eye.y, eye.z, 1.0],
                            direction: [forward.x, forward.y, forward.z, 0.0],
                            intensity: [irradiance.x, irradiance.y, irradiance.z, 0.0],
                            info: [1.0, layer as f32, 2.0 * radius / size as f32, 0.0],
                        });
                    }
                    self.raster.shadow_maps(ctx, buffers, &maps, size);
                },
            );
        }
        f.shadow_maps = Some(shadow_maps);
        Ok(())
    }

    /// Step 1c: Mirrors and glass (5.3): their impostors, and the photons of their caustic maps
    /// (with the conditions that show virtual objects' shadows).
    fn pass_specular_maps(&self, f: &mut FrameTargets) -> Result<()> {
        let ctx = &self.ctx;
        let at = specular::FrameScene { scene: f.scene, mesh: &f.mesh, buffers: &f.buffers };
        let params = f.params;
        f.impostors = (!f.mesh.specular.is_empty())
            .then(|| self.specular.impostors(ctx, &self.raster, &mut f.passes, at, &params.specular));
        f.photon_maps = match &f.impostors {
            None => Err("no mirror or glass"),
            Some(_) if params.condition == GiLevel::None => {
                Err("the none condition: virtual objects cast neither shadows nor caustics")
            }
            Some(_) if params.specular.caustic_map_size == 0 => Err("caustic_map_size is 0 (caustics off)"),
            Some(_) if f.scene.spots.is_empty() => Err("no spot or point light (caustic maps are made from those)"),
            Some(impostors) => {
                Ok(self.specular.photon_maps(ctx, &self.raster, &mut f.passes, at, impostors, &params.specular))
            }
        };
        Ok(())
    }

    /// Step 3: The camera's G-buffer.
    fn pass_gbuffer(&self, f: &mut FrameTargets) -> Result<()> {
        let ctx = &self.ctx;
        let (scene, mesh) = (f.scene, &f.mesh);
        let gbuffer = SurfaceTargets::new(ctx, f.width, f.height, "g-buffer");
        let far = (scene.camera.position - mesh.bounds_centre).length() + 2.0 * mesh.bounds_radius;
        f.camera_view_proj = camera_matrix(&scene.camera, (far * 1e-5).max(1e-4), far);
        let camera_view =
            ViewUniform::perspective(f.camera_view_proj, scene.camera.position, -scene.camera.rotation.z_axis);
        let buffers = &f.buffers;
        timed(ctx, &mut f.passes, "g-buffer".into(), || self.raster.gbuffer(ctx, buffers, &camera_view, &gbuffer));
        f.gbuffer = Some(gbuffer);
        f.camera_view = Some(camera_view);
        Ok(())
    }

    /// Step 3a: Mirrors and glass (5.3): back faces, reflected and refracted rays; 3b. the caustics'
    /// photons splatted into the camera's pixels.
    fn pass_specular_rays(&self, f: &mut FrameTargets) -> Result<()> {
        let Some(impostors) = &f.impostors else { return Ok(()) };
        let ctx = &self.ctx;
        let gbuffer = ran(&f.gbuffer, "g-buffer");
        let at = specular::FrameScene { scene: f.scene, mesh: &f.mesh, buffers: &f.buffers };
        let rays = specular::RayInputs {
            impostors,
            gbuffer,
            view: ran(&f.camera_view, "camera view"),
            view_proj: f.camera_view_proj,
        };
        let mut traced = self.specular.trace(ctx, &self.raster, &mut f.passes, at, &rays, &f.params.specular);
        match &f.photon_maps {
            Ok(maps) => {
                let (buffer, mut report, counts) = timed(ctx, &mut f.passes, "caustic splats".into(), || {
                    self.specular.splat(ctx, maps, f.scene, gbuffer, f.camera_view_proj)
                });
                f.caustic_counts = Some(counts);
                // (a live frame's VPLs stay on the GPU: not counted)
                report.vpls = f.vpls.iter().filter(|v| v.flux[3] > 0.5).count();
                f.caustic_buffer = Some(buffer);
                traced.report.caustics = Some(report);
            }
            Err(reason) => traced.report.caustics_skipped = Some(reason.to_string()),
        }
        f.traced = Some(traced);
        Ok(())
    }

    /// Step 4: Shading: L_rv and L_r by equations 5.1–5.8.
    fn pass_shading(&self, f: &mut FrameTargets) -> Result<()> {
        let ctx = &self.ctx;
        let (scene, params) = (f.scene, f.params);
        let condition_code = match params.condition {
            GiLevel::None => 0,
            GiLevel::Shadows => 1,
            GiLevel::Gi => 2,
        };
        let ism_atlas = f.ism_atlas.as_ref();
        let shade_params = ShadeParams {
            camera: [scene.camera.position.x, scene.camera.position.y, scene.camera.position.z, 0.0],
            size: [f.width, f.height, f.n_lights, f.vpl_count()],
            mode: [
                if f.virtual_maps { condition_code } else { 0 },
                f.shadow_size,
                ism_atlas.map_or(0, |a| a.tile_size),
                ism_atlas.map_or(1, |a| a.tiles_per_row),
            ],
            tone: [
                params.interleave.max(1) as f32,
                params.vpl_clamp_distance * params.vpl_clamp_distance,
                ism_atlas.map_or(0.0, |a| a.inv_max_distance),
                0.0,
            ],
        };
        let label = if params.interleave > 1 && f.vpl_count() > 0 {
            format!("shading (VPLs interleaved {0}×{0})", params.interleave)
        } else {
            "shading".to_string()
        };
        let inputs = shade::ShadeInputs {
            gbuffer: ran(&f.gbuffer, "g-buffer"),
            shadow_maps: f.shadow_maps.as_deref().expect("the shadow maps ran"),
            lights: &f.lights,
            vpls: shade_vpls(&f.gpu_vpls, &f.vpls),
            scene: &f.buffers,
            ism: ism_atlas.map(|a| &*a.buffer),
        };
        let output = timed(ctx, &mut f.passes, label, || self.shade.run(ctx, &shade_params, &inputs));
        f.shade_params = Some(shade_params);
        f.output = Some(output);
        Ok(())
    }

    /// Step 4b: The indirect light: merge of the interleaved classes, temporal smoothing (live
    /// frames), sum with the direct light.
    fn pass_indirect(&self, f: &mut FrameTargets) -> Result<()> {
        let ctx = &self.ctx;
        let output = ran(&f.output, "shading");
        let Some(raw) = &output.indirect else { return Ok(()) };
        let params = f.params;
        let temporal = f.mode != Frame::Stimulus;
        let split = params.interleave.max(1);
        let inputs = indirect::IndirectInputs {
            width: f.width,
            height: f.height,
            split,
            gbuffer: ran(&f.gbuffer, "g-buffer"),
            raw,
            solutions: &output.solutions,
            camera: f.scene.camera.position,
            view_proj: f.camera_view_proj,
            scene_radius: f.mesh.bounds_radius,
        };
        let mut steps = Vec::new();
        if split > 1 {
            steps.push(format!("merge {split}×{split}"));
        }
        if temporal {
            // the history is used only at this frame's size (`IndirectPass::run`)
            f.smoothed = f.state.temporal.as_ref().is_some_and(|t| t.fits(f.width, f.height));
            steps.push(if f.smoothed {
                "temporal smoothing".to_string()
            } else {
                "temporal smoothing (first frame)".to_string()
            });
        }
        steps.push("sum".into());
        let label = format!("indirect light ({})", steps.join(", "));
        let state = &mut f.state.temporal;
        timed(ctx, &mut f.passes, label, || {
            self.indirect.run(ctx, &inputs, temporal.then_some((&params.temporal, state)))
        });
        Ok(())
    }

    /// Step 4c: The caustics into L_rv and L_r.
    fn pass_caustics(&self, f: &mut FrameTargets) -> Result<()> {
        let Some(caustic) = &f.caustic_buffer else { return Ok(()) };
        let ctx = &self.ctx;
        let (gbuffer, output) = (ran(&f.gbuffer, "g-buffer"), ran(&f.output, "shading"));
        let (width, height) = (f.width, f.height);
        timed(ctx, &mut f.passes, "caustics into L_rv and L_r".into(), || {
            self.specular.apply_caustics(ctx, caustic, gbuffer, &output.solutions, width, height)
        });
        Ok(())
    }

    /// The photograph uploaded for the specular passes, the colour mapping and the composition.
    fn pass_photo(&self, f: &mut FrameTargets) -> Result<()> {
        let ctx = &self.ctx;
        // kept from frame to frame: its texels made and uploaded only when it changed (the
        // same bits in every pixel: the shaders see exactly the bytes they saw)
        let photo = match f.shared_photo {
            Some(shared) => PhotoRef::Shared(shared),
            None => PhotoRef::Image(f.photo),
        };
        f.photo_buffer = Some(f.timed(ctx, "upload photograph".into(), || {
            ctx.resident_for("photo", &photo, PhotoRef::stands_for, wgpu::BufferUsages::STORAGE, |photo| {
                let image = photo.image();
                let texels: Vec<[f32; 4]> = image.pixels.iter().map(|p| [p.x, p.y, p.z, 1.0]).collect();
                let kept = match photo {
                    PhotoRef::Shared(shared) => Arc::clone(shared),
                    PhotoRef::Image(image) => Arc::new((*image).clone()),
                };
                (bytemuck::cast_slice(&texels).to_vec(), kept)
            })
        }));
        Ok(())
    }

    /// Step 4d: The hit G-buffers of mirrors and glass shaded by every light and VPL, then L'_rv,
    /// L'_r and the photograph's part CI_std.
    fn pass_specular_hits(&self, f: &mut FrameTargets) -> Result<()> {
        let Some(mut traced) = f.traced.take() else { return Ok(()) };
        let ctx = &self.ctx;
        let hit_params = ShadeParams { camera: traced.eye.extend(0.0).to_array(), ..*ran(&f.shade_params, "shading") };
        let mut shaded = Vec::new();
        for (name, targets) in [("reflected", &traced.refl), ("refracted", &traced.refr)] {
            let inputs = shade::ShadeInputs {
                gbuffer: targets,
                shadow_maps: f.shadow_maps.as_deref().expect("the shadow maps ran"),
                lights: &f.lights,
                vpls: shade_vpls(&f.gpu_vpls, &f.vpls),
                scene: &f.buffers,
                ism: f.ism_atlas.as_ref().map(|a| &*a.buffer),
            };
            let hit = timed(ctx, &mut f.passes, format!("shading the {name} hits"), || {
                self.shade.run(ctx, &hit_params, &inputs)
            });
            if let Some(raw) = &hit.indirect {
                let inputs = indirect::IndirectInputs {
                    width: f.width,
                    height: f.height,
                    split: f.params.interleave.max(1),
                    gbuffer: targets,
                    raw,
                    solutions: &hit.solutions,
                    camera: traced.eye,
                    view_proj: f.camera_view_proj,
                    scene_radius: f.mesh.bounds_radius,
                };
                timed(ctx, &mut f.passes, format!("indirect light of the {name} hits"), || {
                    self.indirect.run(ctx, &inputs, None)
                });
            }
            shaded.push(hit.solutions);
        }
        let inputs = specular::CombineInputs {
            gbuffer: ran(&f.gbuffer, "g-buffer"),
            solutions: &ran(&f.output, "shading").solutions,
            reflected: &shaded[0],
            refracted: &shaded[1],
            photo: f.photo_buffer.as_deref().expect("the photograph ran"),
            width: f.width,
            height: f.height,
        };
        let label = "mirrors and glass: L'_rv, L'_r and the photograph's part".into();
        f.specular_base = Some(timed(ctx, &mut f.passes, label, || self.specular.combine(ctx, &mut traced, &inputs)));
        f.traced = Some(traced);
        Ok(())
    }

    /// Step 5: Colour mapping of both buffers (the cm factor).
    fn pass_colour_mapping(&self, f: &mut FrameTargets) -> Result<()> {
        let cm_buffers = cm::CmBuffers {
            width: f.width,
            height: f.height,
            solutions: &ran(&f.output, "shading").solutions,
            photo: f.photo_buffer.as_deref().expect("the photograph ran"),
        };
        let (mapped, report) = self.cm.run(
            &self.ctx,
            &mut f.passes,
            &cm_buffers,
            &f.photo.pixels,
            &cm::CmSettings { params: &f.params.cm, exposure: f.params.exposure },
            &mut f.state.cm,
        );
        f.mapped = Some(mapped);
        f.cm_report = Some(report);
        Ok(())
    }

    /// Step 6: Composition over the photograph.
    fn pass_composition(&self, f: &mut FrameTargets) -> Result<()> {
        let ctx = &self.ctx;
        let inputs = compose::ComposeInputs {
            width: f.width,
            height: f.height,
            linear_domain: ran(&f.cm_report, "colour mapping").mapping.linear_domain(),
            composition: f.params.composition,
            mapped: f.mapped.as_deref().expect("the colour mapping ran"),
            photo: f.photo_buffer.as_deref().expect("the photograph ran"),
            specular_base: f.specular_base.as_deref(),
        };
        f.composite_buffer = Some(timed(ctx, &mut f.passes, "composition".into(), || self.compose.run(ctx, &inputs)));
        Ok(())
    }

    /// The read-back, in two timed steps: the GPU's copies into staging buffers, then the
    /// host's map and copy. A frame only shown (without the ca factor, which needs the
    /// radiance buffers for the virtual objects' mask and works on the composite in floats)
    /// reads back only the composite packed to 8-bit RGBA: one wait, 4 bytes a pixel, handed
    /// on as they are ([`crate::image::Rgba8`]).
    fn pass_readback(&self, f: &mut FrameTargets) -> Result<()> {
        let ctx = &self.ctx;
        let (width, height) = (f.width, f.height);
        let composite = ran(&f.composite_buffer, "composition");
        // the report's counts (specular passes) come back with the images, in the same wait
        let counts: Vec<&wgpu::Buffer> =
            [f.traced.as_ref().and_then(|t| t.counts.as_deref()), f.caustic_counts.as_deref()]
                .into_iter()
                .flatten()
                .collect();
        // and a live frame's VPL plan and bounce counts
        let chain = f.chain.as_ref().map(|c| ctx.stage_all(&[&c.plan, &c.stats]));
        if f.mode == Frame::Display && f.params.camera_artifacts.is_none() {
            let staged =
                timed(ctx, &mut f.passes, "readback: packed to 8 bits, copied to staging (GPU)".into(), || {
                    let mut staged = vec![ctx.stage(&self.compose.pack(ctx, composite, width, height))];
                    staged.extend((!counts.is_empty()).then(|| ctx.stage_all(&counts)));
                    staged.extend(chain);
                    staged
                });
            // the bytes copied once from the mapped memory, as they are (no image of floats)
            let pixels = (width * height) as usize * 4;
            let to_bytes = |bytes: &[u8]| readback::copy_blocks::<u8>(&bytes[..pixels.min(bytes.len())]);
            let (bytes, words) = timed(ctx, &mut f.passes, "readback: mapped and copied to the host".into(), || {
                ctx.read_staged_with(&staged[0], &staged[1..].iter().map(|s| &**s).collect::<Vec<_>>(), to_bytes)
            });
            let at = !counts.is_empty() as usize;
            f.take_counts(if at == 1 { &words[0] } else { &[] }, words.get(at).map(|w| w.as_slice()));
            let bytes = bytes.filter(|b| b.len() == pixels).unwrap_or_else(|| vec![0; pixels]);
            let empty = Image::filled(0, 0, Vec3::ZERO);
            let virtual_mask = Mask { width, height, values: Vec::new() };
            f.images = Some(FrameImages {
                composite: empty.clone(),
                l_rv: empty.clone(),
                l_r: empty,
                virtual_mask,
                flags: Vec::new(),
                display: Some(crate::image::Rgba8 { width, height, bytes }),
            });
            return Ok(());
        }
        let radiance = f.mode != Frame::Display || f.params.camera_artifacts.is_some();
        let output = ran(&f.output, "shading");
        let staged = timed(ctx, &mut f.passes, "readback: copies to staging (GPU)".into(), || {
            let mut staged = vec![ctx.stage(composite)];
            staged.extend(radiance.then(|| ctx.stage(&output.solutions)));
            staged.extend((!counts.is_empty()).then(|| ctx.stage_all(&counts)));
            staged.extend(chain);
            staged
        });
        let words = timed(ctx, &mut f.passes, "readback: mapped and copied to the host".into(), || {
            ctx.read_staged(&staged.iter().map(|s| &**s).collect::<Vec<_>>())
        });
        let at = 1 + radiance as usize;
        let (counts_words, chain_words) = match counts.is_empty() {
            true => (&[][..], words.get(at)),
            false => (words[at].as_slice(), words.get(at + 1)),
        };
        f.take_counts(counts_words, chain_words.map(|w| w.as_slice()));
        let composite: &[f32] = bytemuck::cast_slice(&words[0]);
        let solutions: &[f32] = if radiance { bytemuck::cast_slice(&words[1]) } else { &[] };
        let start = Instant::now();
        let half = solutions.len() / 2;
        let composite = to_image(width, height, composite);
        let virtual_mask = Mask {
            width,
            height,
            values: solutions[..half].chunks_exact(4).map(|c| if c[3] > 1.5 { 1.0 } else { 0.0 }).collect(),
        };
        let (l_rv, l_r, flags) = if f.mode == Frame::Display {
            (Image::filled(0, 0, Vec3::ZERO), Image::filled(0, 0, Vec3::ZERO), Vec::new())
        } else {
            use rayon::prelude::*;
            (
                to_image(width, height, &solutions[..half]),
                to_image(width, height, &solutions[half..]),
                solutions[..half].par_chunks_exact(4).map(|c| (c[3] + 0.5) as u32).collect(),
            )
        };
        f.passes.push(PassTime::new("images from the read-back buffers (CPU)", start.elapsed().as_secs_f64() * 1e3));
        f.images = Some(FrameImages { composite, l_rv, l_r, virtual_mask, flags, display: None });
        Ok(())
    }

    /// Step 7: Camera artifacts (the ca factor) on the virtual layers of the composite.
    fn pass_camera_artifacts(&self, f: &mut FrameTargets) -> Result<()> {
        let Some(ca) = &f.params.camera_artifacts else { return Ok(()) };
        let ctx = &self.ctx;
        let images = f.images.as_mut().expect("the read-back ran");
        let (out, report) = timed(ctx, &mut f.passes, "camera artifacts (ca)".into(), || {
            self.artifacts.run(ctx, &images.composite, f.photo, &images.virtual_mask, &f.scene.camera, ca)
        })?;
        images.composite = out;
        f.ca_report = Some(report);
        Ok(())
    }

    /// [`DirRenderer::render`], with the VPLs given instead of created (tests of eqs. 5.6–5.7),
    /// temporal smoothing against `state` in live frames, and the read-back `mode` asks for:
    /// [`FrameTargets::new`], then every pass of [`PASSES`] in order.
    pub(super) fn render_frame(
        &self,
        scene: &Scene,
        photo: &Image,
        params: &DirParams,
        given_vpls: Option<&[vpl::GpuVpl]>,
        state: &mut LiveState,
        mode: Frame,
    ) -> Result<GpuRender> {
        Ok(self.render_frame_shown(scene, PhotoRef::Image(photo), params, given_vpls, state, mode)?.0)
    }

    /// [`DirRenderer::render_frame`], with a frame only shown's 8-bit composite as read back
    /// (None for other frames, and where the ca factor made the composite on the host).
    pub(super) fn render_frame_shown(
        &self,
        scene: &Scene,
        shared: PhotoRef<'_>,
        params: &DirParams,
        given_vpls: Option<&[vpl::GpuVpl]>,
        state: &mut LiveState,
        mode: Frame,
    ) -> Result<(GpuRender, Option<crate::image::Rgba8>)> {
        let ctx = &self.ctx;
        let photo = shared.image();
        let (width, height) = (scene.camera.width, scene.camera.height);
        if photo.width != width || photo.height != height {
            return Err(RenderError::SizeMismatch {
                a_width: width,
                a_height: height,
                b_width: photo.width,
                b_height: photo.height,
            });
        }
        let frame_start = Instant::now();
        let _frame = ctx.begin_frame();
        let mut f = FrameTargets::new(self, scene, photo, params, state, mode);
        f.given_vpls = given_vpls;
        f.shared_photo = match shared {
            PhotoRef::Shared(shared) => Some(shared),
            PhotoRef::Image(_) => None,
        };
        for (_, pass) in PASSES {
            pass(self, &mut f)?;
        }
        let images = f.images.take().expect("the read-back ran");
        let ms = f.passes.iter().map(|p| p.ms).sum();
        let render = GpuRender {
            composite: images.composite,
            l_rv: images.l_rv,
            l_r: images.l_r,
            virtual_mask: images.virtual_mask,
            flags: images.flags,
            report: GpuReport {
                adapter: ctx.adapter_name(),
                scene: scene.name.clone(),
                condition: params.condition,
                width,
                height,
                vpls: match (&f.gpu_vpls, f.chain_vpls) {
                    (Some(_), Some(made)) => made,
                    (Some(_), None) => f.vpl_slots as usize,
                    (None, _) => f.vpls.len(),
                },
                params: params.clone(),
                passes: std::mem::take(&mut f.passes),
                ms,
                cm: f.cm_report.take().expect("the colour mapping ran"),
                camera_artifacts: f.ca_report.take(),
                bounces: std::mem::take(&mut f.bounce_reports),
                temporal_smoothing: f.smoothed,
                memory: ctx.pool_stats(),
                counters: ctx.counters().with_cpu_ms(frame_start.elapsed().as_secs_f64() * 1e3),
                specular: f.traced.take().map(|traced| traced.report),
            },
            vpls: std::mem::take(&mut f.vpls),
        };
        Ok((render, images.display))
    }
}
