//! Caustics (thesis 5.27–5.29): the caustic maps' photons traced through the impostors, made
//! into reflected and refracted VPL candidates, splatted into the camera's pixels and added to
//! L_rv and L_r.

use super::*;

impl Specular {
    /// Caustic maps (5.27–5.29), first half: for every light and every mirror or glass object
    /// it lights, the object's G-buffer from the light (PGBuf) and its photons traced through
    /// the impostor like the camera's rays. [`Specular::caustic_vpls`] makes VPLs of them,
    /// [`Specular::splat`] the caustic buffer.
    pub fn photon_maps(
        &self,
        ctx: &GpuContext,
        raster: &Raster,
        passes: &mut Vec<crate::gpu::PassTime>,
        at: FrameScene,
        impostors: &Impostors,
        params: &SpecularParams,
    ) -> PhotonMaps {
        let FrameScene { scene, mesh, buffers } = at;
        let map_size = params.caustic_map_size.clamp(8, ctx.device.limits().max_texture_dimension_2d);
        let mut maps = PhotonMaps { map_size, maps: Vec::new(), skipped: Vec::new() };
        let everything = 0..mesh.vertices.len() as u32;
        for light in &scene.spots {
            for (k, object) in mesh.specular.iter().enumerate() {
                let pair = format!("{} → {}", light.name, object.name);
                let Some((matrix, forward, tan_half)) = photon_view(light, object) else {
                    maps.skipped.push(format!("{pair}: the light is inside the object's bounds or its cone misses it"));
                    continue;
                };
                let view = ViewUniform::perspective(matrix, light.position, forward);
                let label = format!("caustic map {pair} ({map_size}²)");
                let (pgbuf, search) = crate::gpu::timed(ctx, passes, label, || {
                    let pgbuf = SurfaceTargets::new(ctx, map_size, map_size, "PGBuf");
                    let draw = GbufferDraw {
                        view,
                        viewport: [0, 0, map_size, map_size],
                        ranges: std::slice::from_ref(&everything),
                    };
                    raster.gbuffer_draws(ctx, buffers, &pgbuf, std::slice::from_ref(&draw), false);
                    let glass: Vec<std::ops::Range<u32>> = match object.delta {
                        DeltaBsdf::Dielectric { .. } => vec![object.range.clone()],
                        DeltaBsdf::Mirror { .. } => Vec::new(),
                    };
                    let back = self.back_faces(ctx, raster, buffers, &glass, &view, (map_size, map_size));
                    let eye =
                        super::rays::Eye { view_proj: matrix, position: light.position, size: (map_size, map_size) };
                    let search = self.search(ctx, impostors, &pgbuf, &back, eye, params);
                    (pgbuf, search)
                });
                maps.maps.push(PhotonMap {
                    pair,
                    light: light.clone(),
                    object: k as u32,
                    object_real: object.real,
                    tan_half,
                    pgbuf,
                    search,
                });
            }
        }
        maps
    }

    /// The caustic maps' photons where they are, for VPL creation on the GPU
    /// ([`crate::gpu::vpl::VplSampler::candidates`], the counterpart of [`Specular::caustic_vpls`]).
    pub fn caustic_sources<'a>(&self, maps: &'a PhotonMaps) -> Vec<crate::gpu::vpl::CausticMap<'a>> {
        maps.maps
            .iter()
            .map(|map| crate::gpu::vpl::CausticMap {
                light: &map.light,
                object: map.object,
                object_real: map.object_real,
                tan_half: map.tan_half,
                size: maps.map_size,
                stride: map.search.stride,
                position: &map.pgbuf.position,
                info: &map.search.info,
                hits: &map.search.hits,
            })
            .collect()
    }

    /// Reflected and refracted VPLs (Figure 5.23): every photon of the caustic maps as a
    /// candidate VPL where it lands, carrying the flux the surface there reflects (albedo ×
    /// the photon's flux); real where light, object and surface are all real. Read back and
    /// made on the CPU: the reference for `vpl.wgsl`'s `cs_caustic_candidates`, which makes the
    /// same candidates on the GPU ([`Specular::caustic_sources`]).
    pub fn caustic_vpls(&self, ctx: &GpuContext, maps: &PhotonMaps) -> Vec<crate::gpu::vpl::GpuVpl> {
        use rayon::prelude::*;
        let mut candidates = Vec::new();
        let n = maps.map_size as usize;
        // every map's buffers copied for reading first, then its positions read with one wait
        // for all (not three waits per map)
        let staged: Vec<(Arc<wgpu::Buffer>, Arc<wgpu::Buffer>)> =
            maps.maps.iter().map(|map| (ctx.stage(&map.search.info), ctx.stage(&map.search.hits))).collect();
        let textures: Vec<(&wgpu::Texture, u32)> = maps.maps.iter().map(|map| (&*map.pgbuf.position, 16)).collect();
        let positions_bytes = ctx.read_textures(&textures);
        for ((map, (info, hits)), positions) in maps.maps.iter().zip(&staged).zip(&positions_bytes) {
            let positions: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(positions);
            let info = ctx.read_staged_f32(info);
            let hits = ctx.read_staged_f32(hits);
            // texel (x, y) of hit plane p (see specular.wgsl's `plane`)
            let plane = |p: usize, x: usize, y: usize| {
                let texel = 4 * ((p * n + y) * map.search.stride as usize + x);
                Vec4::from_slice(&hits[texel..texel + 4])
            };
            // rows on all threads, joined in row order
            let rows: Vec<Vec<crate::gpu::vpl::GpuVpl>> = (0..n)
                .into_par_iter()
                .map(|y| {
                    let mut candidates = Vec::new();
                    for x in 0..n {
                        let pixel = y * n + x;
                        let weights = |q: usize| &info[16 * pixel + 4 * q..16 * pixel + 4 * q + 4];
                        if weights(2)[3] < 0.5 || (weights(3)[3] + 0.5) as u32 != map.object {
                            continue;
                        }
                        let p1 = Vec3::from_slice(&positions[pixel][..3]);
                        let to = p1 - map.light.position;
                        let d_omega = crate::gpu::vpl::texel_solid_angle(x as u32, y as u32, n as u32, map.tan_half);
                        let flux_in = map.light.intensity_towards(to.normalize()) * d_omega;
                        for c in 0..2 {
                            let w = weights(c);
                            if w[3] != 1.0 {
                                continue;
                            }
                            let albedo = plane(3 * c + 2, x, y).truncate();
                            let flux = flux_in * Vec3::new(w[0], w[1], w[2]) * albedo;
                            if luminance(flux) <= 0.0 || !flux.is_finite() {
                                continue;
                            }
                            // position w: role (1 real, 2 virtual) + 4 × material
                            let position = plane(3 * c, x, y);
                            let real = map.light.real && map.object_real && (position.w + 0.5) as u32 % 4 == 1;
                            let position = position.truncate();
                            let normal = plane(3 * c + 1, x, y).truncate().normalize_or_zero();
                            candidates.push(crate::gpu::vpl::GpuVpl {
                                position: position.extend(if real { 1.0 } else { 0.0 }).to_array(),
                                normal: normal.extend(0.0).to_array(),
                                flux: flux.extend(1.0).to_array(),
                            });
                        }
                    }
                    candidates
                })
                .collect();
            candidates.extend(rows.into_iter().flatten());
        }
        candidates
    }

    /// Caustic maps, second half: splats every photon into the caustic buffer in the camera's
    /// pixels. Returns the buffer for [`Specular::apply_caustics`], the report, and the photons'
    /// counts still on the GPU (photons, splatted: two `u32`s), read back with the frame's
    /// images (no wait of their own) into the report's `photons` and `splatted`.
    pub fn splat(
        &self,
        ctx: &GpuContext,
        maps: &PhotonMaps,
        scene: &Scene,
        gbuffer: &SurfaceTargets,
        camera_view_proj: Mat4,
    ) -> (Arc<wgpu::Buffer>, CausticReport, Arc<wgpu::Buffer>) {
        let (width, height) = (scene.camera.width, scene.camera.height);
        let caustic = ctx.buffer(
            "caustic buffer",
            12 * 4 * width as u64 * height as u64,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            Contents::Zeroed,
        );
        let counts = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("photon counts"),
            contents: &[0u8; 16],
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        });
        let cam_position = ctx.views.of(&gbuffer.position);
        let cam_normal = ctx.views.of(&gbuffer.normal);
        for map in &maps.maps {
            let light = &map.light;
            let uniform = PhotonUniform {
                light_position: light.position.extend(if light.real { 1.0 } else { 0.0 }).to_array(),
                light_direction: light.direction.extend(light.cos_outer).to_array(),
                intensity: light.intensity.extend(light.cos_inner).to_array(),
                camera_view_proj: camera_view_proj.to_cols_array_2d(),
                camera: scene.camera.position.extend(0.5 / scene.camera.fy).to_array(),
                map: [map.tan_half, maps.map_size as f32, map.object as f32, if map.object_real { 1.0 } else { 0.0 }],
                size: [width, height, MAX_SPLAT_REACH, 0],
            };
            let uniform = ctx.upload(&wgpu::util::BufferInitDescriptor {
                label: Some("photons"),
                contents: bytemuck::bytes_of(&uniform),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let light_position = ctx.views.of(&map.pgbuf.position);
            let entries = [
                wgpu::BindGroupEntry { binding: 0, resource: map.search.params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&light_position) },
                wgpu::BindGroupEntry { binding: 10, resource: map.search.hits.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 11, resource: map.search.info.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 18, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 19, resource: wgpu::BindingResource::TextureView(&cam_position) },
                wgpu::BindGroupEntry { binding: 20, resource: wgpu::BindingResource::TextureView(&cam_normal) },
                wgpu::BindGroupEntry { binding: 21, resource: caustic.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 22, resource: counts.as_entire_binding() },
            ];
            let groups = maps.map_size.div_ceil(8);
            ctx.dispatch("photons", &self.photons, &entries, [groups, groups]);
        }
        let report = CausticReport {
            map_size: maps.map_size,
            maps: maps.maps.iter().map(|m| m.pair.clone()).collect(),
            skipped: maps.skipped.clone(),
            photons: 0,
            splatted: 0,
            vpls: 0,
        };
        (caustic, report, counts)
    }

    /// Adds the caustic buffer's irradiance, as diffuse radiance rho/pi E, to L_rv and (where
    /// light, object and receiver are real) to L_r.
    pub fn apply_caustics(
        &self,
        ctx: &GpuContext,
        caustic: &wgpu::Buffer,
        gbuffer: &SurfaceTargets,
        solutions: &wgpu::Buffer,
        width: u32,
        height: u32,
    ) {
        let uniform = PhotonUniform { size: [width, height, 0, 0], ..bytemuck::Zeroable::zeroed() };
        let uniform = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("caustics apply"),
            contents: bytemuck::bytes_of(&uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let albedo = ctx.views.of(&gbuffer.albedo);
        let entries = [
            wgpu::BindGroupEntry { binding: 12, resource: solutions.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 18, resource: uniform.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 21, resource: caustic.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 23, resource: wgpu::BindingResource::TextureView(&albedo) },
        ];
        ctx.dispatch("caustics apply", &self.apply, &entries, [width.div_ceil(8), height.div_ceil(8)]);
    }
}

/// The view of `light` onto `object` for its caustic map: aimed at the object's bounding
/// sphere, which it just contains; returns (matrix, forward axis, tan of half the fov), or None
/// where the light is inside the sphere or a spot's cone misses it.
fn photon_view(light: &SpotLight, object: &SpecularObject) -> Option<(Mat4, Vec3, f32)> {
    let to = object.centre - light.position;
    let distance = to.length();
    if distance <= object.radius * 1.001 {
        return None;
    }
    let forward = to / distance;
    let half = ((object.radius / distance).asin() * 1.02).min(80f32.to_radians());
    let off_axis = forward.dot(light.direction).clamp(-1.0, 1.0).acos();
    if light.cos_outer > -1.0 && off_axis - half > light.cos_outer.clamp(-1.0, 1.0).acos() {
        return None;
    }
    let far = distance + object.radius * 1.01;
    let near = ((distance - object.radius) * 0.01).max(1e-4);
    let projection = crate::gpu::perspective(1.0 / half.tan(), near, far);
    Some((projection * crate::gpu::look_at(light.position, forward, crate::gpu::up_hint(forward)), forward, half.tan()))
}
