//! The frame's VPL passes ([`super::PASSES`] 3–5): RSMs and the VPLs drawn from them, the
//! further bounces and the budget split by flux, and the VPLs' imperfect shadow maps. A stimulus
//! frame's VPLs come to the host (the reference steps, recorded byte for byte); a live frame's
//! stay on the GPU, where the ISMs and the shading read them ([`super::super::bounce_chain`]).

use super::*;

impl DirRenderer {
    /// Step 2: RSMs and VPLs (gi only): every RSM rendered first, then all read at once — by the
    /// GPU's VPL sampler, or read back for the CPU's reference (one wait, not four per map) —
    /// with the reflected and refracted VPLs where the caustics land (Figure 5.23).
    pub(super) fn pass_vpls(&self, f: &mut FrameTargets) -> Result<()> {
        let ctx = &self.ctx;
        let params = f.params;
        if params.condition == GiLevel::Gi && f.n_lights > 0 && params.vpls > 0 {
            let rsm_size = params.rsm_size.max(4);
            let env = *ran(&f.env_view, "environment view");
            let (buffers, has_virtual) = (&f.buffers, f.has_virtual);
            // (their targets from the pool: each RSM pass clears them); timed pass by pass, or
            // else all recorded into one encoder after the loop below (the same commands in the
            // same order)
            let one_encoder = !ctx.pass_waits();
            let queued = std::cell::RefCell::new(Vec::new());
            let render_rsm = |passes: &mut Vec<PassTime>, view: &ViewUniform, name: &str, subset: Subset| {
                let targets = SurfaceTargets::new(ctx, rsm_size, rsm_size, "rsm");
                let distance = raster::texture_2d(ctx, rsm_size, rsm_size, raster::DISTANCE_FORMAT, "rsm distance");
                let label = if subset == Subset::Real { "real" } else { "virtual" };
                if one_encoder {
                    let kept = SurfaceTargets {
                        position: targets.position.clone(),
                        normal: targets.normal.clone(),
                        albedo: targets.albedo.clone(),
                    };
                    queued.borrow_mut().push((*view, subset, distance.clone(), kept));
                } else {
                    timed(ctx, passes, format!("RSM {name} {label}"), || {
                        self.raster.rsm(ctx, buffers, view, subset, &ctx.views.of(&distance), &targets)
                    });
                }
                (targets, distance)
            };
            let render_pair = |passes: &mut Vec<PassTime>, view: &ViewUniform, name: &str| {
                let real = render_rsm(passes, view, name, Subset::Real);
                let virt = has_virtual.then(|| render_rsm(passes, view, name, Subset::Virtual));
                (real, virt)
            };
            let mut rendered = Vec::new();
            for (spot, (view, tan_half)) in f.scene.spots.iter().zip(&f.spot_views) {
                rendered.push((vpl::RsmLight::Spot(spot), *tan_half, render_pair(&mut f.passes, view, &spot.name)));
            }
            // the environment's light bounces too: orthographic RSMs along a subset of its
            // directions (evenly spread over the importance-sampled ones), each standing for
            // n / k of them
            let k = (params.env_vpl_directions as usize).min(f.env_dirs.len());
            for j in 0..k {
                let (forward, irradiance) = f.env_dirs[j * f.env_dirs.len() / k];
                let (matrix, eye) = directional_view(forward, env.centre, env.radius, env.depth);
                let view = ViewUniform::orthographic(matrix, eye, forward);
                let light = vpl::RsmLight::Directional {
                    irradiance: irradiance * (f.env_dirs.len() as f32 / k as f32),
                    texel_area: (2.0 * env.radius / rsm_size as f32).powi(2),
                };
                rendered.push((light, 0.0, render_pair(&mut f.passes, &view, &format!("environment {}", j + 1))));
            }
            let queued = queued.into_inner();
            if !queued.is_empty() {
                let draws: Vec<raster::RsmDraw> = queued
                    .iter()
                    .map(|(view, subset, distance, targets)| raster::RsmDraw {
                        view: *view,
                        subset: *subset,
                        distance,
                        targets,
                    })
                    .collect();
                timed(ctx, &mut f.passes, format!("RSMs ({}, one encoder)", draws.len()), || {
                    self.raster.rsms(ctx, buffers, &draws)
                });
            }
            let maps: Vec<vpl::RsmMaps> = rendered
                .iter()
                .map(|(light, tan_half_fov, (real, virt))| {
                    fn textures((t, d): &(SurfaceTargets, Arc<wgpu::Texture>)) -> [&Arc<wgpu::Texture>; 4] {
                        [&t.position, &t.normal, &t.albedo, d]
                    }
                    vpl::RsmMaps {
                        light: *light,
                        tan_half_fov: *tan_half_fov,
                        size: rsm_size,
                        real: textures(real),
                        virt: virt.as_ref().map(textures),
                    }
                })
                .collect();
            let caustics =
                f.photon_maps.as_ref().map_or_else(|_| Vec::new(), |maps| self.specular.caustic_sources(maps));
            let slots = vpl::VplSampler::slots(0, &caustics, &maps);
            let candidates =
                if !self.cpu_vpls.load(std::sync::atomic::Ordering::Relaxed) && vpl::VplSampler::fits(ctx, slots) {
                    let label = format!(
                        "VPL candidates and their CDF ({slots} slots: {} RSMs, {} caustic maps; GPU)",
                        rendered.iter().map(|(_, _, (_, virt))| 1 + virt.is_some() as usize).sum::<usize>(),
                        caustics.len()
                    );
                    FirstBounce::Gpu(timed(ctx, &mut f.passes, label, || {
                        self.vpl_sampler.candidates(ctx, &[], &caustics, &maps)
                    }))
                } else {
                    let caustic_candidates = match &f.photon_maps {
                        Ok(maps) => timed(ctx, &mut f.passes, "caustic VPL candidates (read back)".into(), || {
                            self.specular.caustic_vpls(ctx, maps)
                        }),
                        Err(_) => Vec::new(),
                    };
                    FirstBounce::Cpu(self.cpu_candidates(ctx, &mut f.passes, &rendered, rsm_size, &caustic_candidates))
                };
            drop(maps);
            // the RSM targets go back to the pool for the next frame (the passes reading them are
            // submitted, so the next frame's RSM passes are queued after those)
            drop(rendered);
            // a live frame's VPLs stay on the GPU, where the bounces, the ISMs and the shading
            // read them (a stimulus's come to the host: the reference steps, and its output)
            let resident = f.mode != Frame::Stimulus && f.given_vpls.is_none();
            f.vpls = match &candidates {
                FirstBounce::Gpu(gpu) if resident => {
                    f.gpu_vpls = Some(timed(ctx, &mut f.passes, "VPLs drawn (GPU, kept there)".into(), || {
                        self.vpl_sampler.draw_resident(ctx, gpu, params.vpls)
                    }));
                    f.vpl_slots = params.vpls;
                    Vec::new()
                }
                // a GPU pass: reported only while passes are timed
                FirstBounce::Gpu(_) => timed(ctx, &mut f.passes, "VPLs drawn (GPU, read back)".into(), || {
                    candidates.draw(self, params.vpls)
                }),
                FirstBounce::Cpu(_) => {
                    let start = Instant::now();
                    let drawn = candidates.draw(self, params.vpls);
                    f.passes.push(PassTime::new("VPLs drawn (CPU)", start.elapsed().as_secs_f64() * 1e3));
                    drawn
                }
            };
            f.first_bounce = Some(candidates);
        }
        if let Some(given) = f.given_vpls {
            f.vpls = given.to_vec();
        }
        Ok(())
    }

    /// Step 2a: The multiple-bounce light source (5.2.7), once per further bounce: a pilot over the
    /// whole budget measures the bounce's flux; the budget is then split by flux over the
    /// primary lights and the bounces (the third distribution mode) — the thesis takes those
    /// fluxes from the previous frame, a single stimulus frame measures them first.
    pub(super) fn pass_bounces(&self, f: &mut FrameTargets) -> Result<()> {
        let ctx = &self.ctx;
        let params = f.params;
        if params.condition != GiLevel::Gi || params.bounces <= 1 || f.vpl_count() == 0 {
            return Ok(());
        }
        let made = self.bounce_scenes.get(&f.mesh, |mesh| bounce::BounceScene::new(ctx, mesh));
        let Some(bounce_scene) = made else { return Ok(()) };
        if let (Some(first), Some(FirstBounce::Gpu(candidates))) = (&f.gpu_vpls, &f.first_bounce) {
            let bounces = params.bounces.min(MAX_BOUNCES);
            let inputs = bounce_chain::ChainInputs {
                candidates,
                first,
                scene: &bounce_scene,
                buffers: &f.buffers,
                budget: f.vpl_slots,
                bounces,
                candidates_per_slot: params.bounce_candidates,
                cone_degrees: params.bounce_cone_degrees,
                scene_radius: f.mesh.bounds_radius,
            };
            let label = format!(
                "bounces 2–{bounces} and the budget split by flux ({} slots, {} candidates each, cone {}°; GPU)",
                f.vpl_slots, params.bounce_candidates, params.bounce_cone_degrees
            );
            let chain = timed(ctx, &mut f.passes, label, || {
                self.bounce_chain.run(ctx, &self.bounce, &self.vpl_sampler, &inputs)
            });
            f.gpu_vpls = Some(chain.vpls.clone());
            f.chain = Some(chain);
            return Ok(());
        }
        let budget = params.vpls.max(1);
        let mut pilots: Vec<Vec<vpl::GpuVpl>> = Vec::new();
        let mut sources = f.vpls.clone();
        for b in 2..=params.bounces.min(MAX_BOUNCES) {
            let search = bounce::BounceSearch {
                candidates: params.bounce_candidates,
                cone_degrees: params.bounce_cone_degrees,
                seed: b.wrapping_mul(0x9e37_79b9),
            };
            let label = format!(
                "bounce {b} ({budget} slots, {} candidates each, cone {}°)",
                search.candidates, search.cone_degrees
            );
            let at = bounce::BounceInputs {
                scene: &bounce_scene,
                mesh: &f.mesh,
                materials: &f.scene.materials,
                scene_radius: f.mesh.bounds_radius,
            };
            let (next, found, real_only) =
                timed(ctx, &mut f.passes, label, || self.bounce.spawn(ctx, &at, &sources, budget, &search));
            f.bounce_reports.push(bounce::BounceReport {
                bounce: b,
                slots: budget,
                found,
                real_only,
                flux: vpl::luminance_flux(&next) as f32,
                vpls: 0,
            });
            if next.is_empty() {
                break;
            }
            pilots.push(next.clone());
            sources = next;
        }
        let start = Instant::now();
        let mut fluxes = vec![vpl::luminance_flux(&f.vpls)];
        fluxes.extend(pilots.iter().map(|p| vpl::luminance_flux(p)));
        let counts = vpl::split_budget(budget, &fluxes);
        if f.given_vpls.is_none() {
            // no first-bounce candidates: no RSMs were drawn, so there is nothing to draw from
            f.vpls = f.first_bounce.as_ref().map_or_else(Vec::new, |candidates| candidates.draw(self, counts[0]));
        }
        for (k, pilot) in pilots.iter().enumerate() {
            let drawn = vpl::resample(pilot, counts[k + 1]);
            f.bounce_reports[k].vpls = drawn.len();
            f.vpls.extend(drawn);
        }
        let drawn_where = match &f.first_bounce {
            Some(FirstBounce::Gpu(_)) => "; the first bounce's share drawn on the GPU",
            _ => "",
        };
        f.passes.push(PassTime::new(
            format!("VPL budget split by flux over {} sources (CPU{drawn_where})", fluxes.len()),
            start.elapsed().as_secs_f64() * 1e3,
        ));
        Ok(())
    }

    /// Step 2b: Imperfect shadow maps: VPL visibility from the real and the virtual point clouds.
    pub(super) fn pass_isms(&self, f: &mut FrameTargets) -> Result<()> {
        let params = f.params;
        if f.vpl_count() == 0 || params.ism_size == 0 || params.ism_points == 0 {
            return Ok(());
        }
        let ctx = &self.ctx;
        let settings = ism::IsmSettings {
            points_per_vpl: params.ism_points,
            tile_size: params.ism_size,
            max_distance: 2.0 * f.mesh.bounds_radius * 1.01,
            splatting: params.ism_splatting,
        };
        let label = format!(
            "ISMs ({} VPLs, {}² each, {} points per cloud, {} splatting)",
            f.vpl_count(),
            params.ism_size,
            params.ism_points,
            params.ism_splatting.name()
        );
        let (vpls, slots) = (&f.vpls, f.vpl_slots);
        let clouds = &self.ism_clouds.get(&f.mesh, |mesh| ism::IsmClouds::new(ctx, mesh));
        let atlas = match &f.gpu_vpls {
            Some(gpu) => timed(ctx, &mut f.passes, label, || self.ism.render_gpu(ctx, clouds, (gpu, slots), &settings)),
            None => timed(ctx, &mut f.passes, label, || self.ism.render(ctx, clouds, vpls, &settings)),
        };
        f.ism_atlas = Some(atlas);
        Ok(())
    }
}
