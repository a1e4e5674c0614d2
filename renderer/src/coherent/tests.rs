//! Tests of the coherent renderer: the voxel volume's cones, reflectance estimation (eq. 5)
//! against a known albedo under a known environment, eq. 9's cache against plain eq. 8, no
//! virtual object leaves the photograph exact, and every method brings a scene's composite
//! closer to the ground truth than gi off.

use super::*;
use crate::test_support::scene_from_toml;

/// The photograph of a coherent stimulus: as shown and linear.
fn photograph<'a>(display: &'a Image, linear: &'a Image) -> render::Photograph<'a> {
    render::Photograph { display, linear }
}

/// How a coherent stimulus is shown: its colour mapping and camera artifacts.
fn presented<'a>(cm: &'a crate::cm::CmParams, ca: Option<&'a crate::ca::CaParams>) -> render::Presentation<'a> {
    render::Presentation { cm, ca }
}

/// A real grey floor under a sky with a bright window, a virtual box on it, a real spot light.
const FLOOR: &str = r#"
[camera]
width = 48
height = 36
fov_y_deg = 50.0
position = [0.0, 1.0, 1.8]
look_at = [0.0, 0.15, 0.0]

[materials.floor]
albedo = 0.4

[materials.box]
albedo = [0.8, 0.2, 0.1]

[[objects]]
name = "floor"
role = "real"
shape = "quad"
size = [3.0, 3.0]
material = "floor"

[[objects]]
name = "box"
role = "virtual"
shape = "box"
size = [0.3, 0.3, 0.3]
translate = [0.0, 0.15, 0.0]
material = "box"

[[lights]]
name = "spot"
kind = "spot"
position = [0.6, 1.6, 0.6]
target = [0.0, 0.0, 0.0]
intensity = 3.0

[environment]
kind = "sky"
zenith = [0.5, 0.5, 0.55]
horizon = [0.4, 0.38, 0.35]
ground = [0.1, 0.1, 0.1]
window_direction = [-0.6, 0.8, 0.2]
window_size_deg = [40.0, 30.0]
window_radiance = [4.0, 4.0, 4.2]
"#;

/// The scene, its real world and a capture's samples (cell 0.03 m).
fn captured(text: &str) -> (Scene, World, Vec<EnvironmentSample>) {
    let scene = scene_from_toml(text, "floor");
    let (real, samples) = crate::test_support::captured_samples(&scene, 0.03);
    (scene, real, samples)
}

#[test]
fn a_cone_stops_at_a_wall_of_samples_and_passes_where_there_is_none() {
    // a wall at z = 1 of samples every 2 cm, radiance 2
    let mut samples = Vec::new();
    for i in 0..50 {
        for j in 0..50 {
            samples.push(EnvironmentSample {
                position: Vec3::new(-0.5 + i as f32 * 0.02, -0.5 + j as f32 * 0.02, 1.0),
                normal: Vec3::NEG_Z,
                colour: Vec3::splat(2.0),
                pose: 0,
            });
        }
    }
    let volume = VoxelVolume::build(&samples, 64, 0.02);
    assert!(volume.level_count() == 7 && volume.filled() > 0, "{} levels", volume.level_count());
    let origin = Vec3::new(0.0, 0.0, 0.5);
    let hit = volume.cone(origin, Vec3::Z, 0.01);
    assert!(hit.opacity > 0.9, "{hit:?}");
    assert!((hit.distance - 0.5).abs() < 0.04, "{hit:?}");
    assert!((hit.radiance / hit.opacity - Vec3::splat(2.0)).abs().max_element() < 1e-3, "{hit:?}");
    // away from the wall: nothing
    let away = volume.cone(origin, Vec3::NEG_Z, 0.01);
    assert_eq!(away.opacity, 0.0);
    assert!(away.distance.is_infinite());
    // a wide cone reads coarser levels, where the one-voxel wall is averaged with empty
    // space: it sees the wall partly transparent, with its colour
    let wide = volume.cone(Vec3::new(0.0, 0.0, 0.2), Vec3::Z, 0.3);
    assert!(wide.opacity > 0.01 && wide.opacity < hit.opacity, "{wide:?}");
    assert!((wide.radiance / wide.opacity - Vec3::splat(2.0)).abs().max_element() < 1e-3, "{wide:?}");
    // an empty capture: an empty volume
    let empty = VoxelVolume::build(&[], 8, 0.02);
    assert_eq!(empty.filled(), 0);
    assert_eq!(empty.cone(Vec3::ZERO, Vec3::X, 0.1).opacity, 0.0);
}

#[test]
fn a_surface_of_coarse_samples_fills_one_layer_of_fine_voxels() {
    // a floor at y = 0.003 of samples every 5 cm (the footprint), voxels of 1 cm: each
    // sample's disk fills the voxels its plane passes through, not a ball 5 cm across
    let mut samples = Vec::new();
    for i in 0..=20 {
        for j in 0..=20 {
            samples.push(EnvironmentSample {
                position: Vec3::new(-0.5 + i as f32 * 0.05, 0.003, -0.5 + j as f32 * 0.05),
                normal: Vec3::Y,
                colour: Vec3::splat(0.5),
                pose: 0,
            });
        }
    }
    let volume = VoxelVolume::build(&samples, 110, 0.05);
    assert!((volume.voxel - 0.01).abs() < 1e-4, "voxel {}", volume.voxel);
    // the floor is closed: 1.075 m across (the disks reach 3.75 cm past the outer samples)
    let layer = 107 * 107;
    assert!(volume.filled() > layer * 9 / 10 && volume.filled() < layer * 11 / 10, "{} filled", volume.filled());
    // a thin cone straight down meets it within a voxel of the plane, and one a voxel above
    // it, going up, meets nothing
    for x in [-0.31f32, 0.0, 0.17] {
        let hit = volume.cone(Vec3::new(x, 0.2, 0.05), Vec3::NEG_Y, 0.005);
        // one voxel thick, read trilinearly, it stops most of the cone (measured 0.82)
        assert!(hit.opacity > 0.75 && (hit.distance - 0.197).abs() < 0.015, "{hit:?}");
        assert_eq!(volume.cone(Vec3::new(x, 0.015, 0.05), Vec3::Y, 0.005).opacity, 0.0);
    }
}

#[test]
fn the_light_probe_is_laid_out_as_environment_maps_are() {
    // every texel a different value: a direction through a texel's centre reads that texel
    let (w, h) = (16, 8);
    let mut map = Image::new(w, h);
    for (k, p) in map.pixels.iter_mut().enumerate() {
        *p = Vec3::splat(k as f32);
    }
    let env = Environment::new(map, 0.0);
    for j in 0..h {
        for i in 0..w {
            let dir = crate::light::equirect_dir((i as f32 + 0.5) / w as f32, (j as f32 + 0.5) / h as f32);
            assert_eq!(env.eval(dir).x, (j * w + i) as f32, "texel ({i}, {j})");
        }
    }
}

#[test]
fn reflectance_estimation_recovers_a_known_albedo_under_a_known_environment() {
    let (scene, real, samples) = captured(FLOOR);
    let mut params = CoherentParams::new(Method::Dit, Quality::Med);
    params.settings.material_samples = 4096;
    let (rep, _) = build_representation(&scene, &real, &samples, 0.03, &params, None);
    let renderer = Coherent::new(&scene, &real, &rep, params);
    // a floor point away from the box; its photographed radiance by the path tracer, many paths
    let x = Vec3::new(-0.5, 0.0, 0.4);
    let eye = scene.camera.position;
    let dir = (x - eye).normalize();
    let mut rng = Rng::new(7);
    let trace = TraceParams::default();
    let paths = 8192;
    let (mut sum, mut sum2) = (Vec3::ZERO, Vec3::ZERO);
    for _ in 0..paths {
        let (l, _) = real.radiance(Ray { origin: eye, dir }, &mut rng, &trace);
        sum += l;
        sum2 += l * l;
    }
    let observed = sum / paths as f32;
    let observed_se = ((sum2 / paths as f32 - observed * observed).max(Vec3::ZERO) / paths as f32).powf(0.5);
    let rho = renderer.estimate_albedo(x, Vec3::Y, observed, 11);
    // the estimate's sampling error: its irradiance from 4096 cosine samples (their spread
    // measured here with the same query), and the observed radiance's
    let m = 4096;
    let frame = Frame::from_normal(Vec3::Y);
    let (mut e, mut e2) = (0.0f64, 0.0f64);
    let mut rng = Rng::new(3);
    for _ in 0..m {
        let d = frame.to_world(sample_cosine_hemisphere(rng.next_f32(), rng.next_f32()));
        let l = crate::math::luminance(rep.incident(Query::Dit, x + Vec3::Y * 1e-3, d, 0.0).radiance) as f64;
        e += l;
        e2 += l * l;
    }
    let mean = e / m as f64;
    let cv = ((e2 / m as f64 - mean * mean).max(0.0)).sqrt() / mean / (m as f64).sqrt();
    let rel_observed = (crate::math::luminance(observed_se) / crate::math::luminance(observed)) as f64;
    let rel = (cv * cv + rel_observed * rel_observed).sqrt();
    // plus 2 % for the light probe's resolution (128×64 texels of a window with sharp edges)
    let tolerance = 0.4 * (4.0 * rel + 0.02);
    for c in 0..3 {
        assert!((rho[c] as f64 - 0.4).abs() < tolerance, "albedo {rho} against 0.4 (tolerance {tolerance:.4})");
    }
}

#[test]
fn the_cache_of_eq_9_is_unbiased_against_eq_8_and_less_noisy_at_equal_tracing() {
    let (scene, real, samples) = captured(FLOOR);
    let mut params = CoherentParams::new(Method::Dit, Quality::Med);
    params.settings.background_samples = 64;
    let (rep, _) = build_representation(&scene, &real, &samples, 0.03, &params, None);
    let renderer = Coherent::new(&scene, &real, &rep, params);
    // a floor point beside the box: some directions meet it
    let x = Vec3::new(0.3, 0.0, 0.1);
    let rho = Vec3::splat(0.4);
    let runs = 400;
    let estimate = |cache: u32, big_n: u32, run: u64| {
        let mut rng = Rng::for_stream(run, 5, 0);
        let d = renderer.differential(x, Vec3::Y, rho, big_n, cache, &mut rng);
        (crate::math::luminance(d.value) as f64, d.traced)
    };
    let stats = |values: &[f64]| {
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (values.len() - 1) as f64;
        (mean, var)
    };
    // eq. 9: 64 directions, at most 8 traced; eq. 8: 8 directions, every hit traced (no more
    // rays traced than eq. 9's on average)
    let (cached, traced_cached): (Vec<f64>, Vec<u64>) = (0..runs).map(|r| estimate(8, 64, r)).unzip();
    let (plain, traced_plain): (Vec<f64>, Vec<u64>) = (0..runs).map(|r| estimate(0, 8, r + 10_000)).unzip();
    let (m9, v9) = stats(&cached);
    let (m8, v8) = stats(&plain);
    assert!(m8 < 0.0, "the box must darken the floor beside it: {m8}");
    // the same mean within noise (4 standard errors of the difference)
    let se = (v9 / runs as f64 + v8 / runs as f64).sqrt();
    assert!((m9 - m8).abs() < 4.0 * se, "eq. 9 mean {m9} against eq. 8 mean {m8} (se {se})");
    let t9 = traced_cached.iter().sum::<u64>() as f64 / runs as f64;
    let t8 = traced_plain.iter().sum::<u64>() as f64 / runs as f64;
    assert!(t9 >= t8 && t9 <= 8.0, "traced per estimate: eq. 9 {t9}, eq. 8 {t8}");
    assert!(v9 < 0.5 * v8, "variance: eq. 9 {v9}, eq. 8 {v8}");
}

#[test]
fn with_no_virtual_object_every_method_leaves_the_photograph_exact() {
    let text = FLOOR.replace("role = \"virtual\"", "role = \"real\"");
    let (scene, real, samples) = captured(&text);
    let photo = photo(&scene);
    for method in Method::ALL {
        let p = CoherentParams::new(method, Quality::Low);
        let (rep, _) = build_representation(&scene, &real, &samples, 0.03, &p, None);
        let frame = Coherent::new(&scene, &real, &rep, p).render(&photo, &|_, _| {}).unwrap();
        assert_eq!(frame.composite.pixels, photo.pixels, "{}", method.name());
        assert_eq!(frame.report.object_pixels, 0);
        assert!(frame.report.skipped.iter().any(|s| s.contains("no virtual object")), "{:?}", frame.report.skipped);
        // the GPU's frame too (where an adapter opens)
        if let Some(renderer) = crate::test_support::renderer_or_skip() {
            let frame = Coherent::new(&scene, &real, &rep, p).render_gpu(&photo, renderer).unwrap().unwrap();
            assert_eq!(frame.composite.pixels, photo.pixels, "{} on the GPU", method.name());
        }
    }
}

/// The photograph's linear radiance at the scene's size, few samples.
fn photo(scene: &Scene) -> Image {
    let params = crate::reference::ReferenceParams { spp: 4, ..Default::default() };
    crate::reference::render_photo(scene, &params, &|_, _| {}).unwrap().0
}

#[test]
fn every_method_brings_the_composite_closer_to_the_ground_truth_than_gi_off() {
    let (scene, real, samples) = captured(FLOOR);
    let reference = crate::reference::render_reference(
        &scene,
        &crate::reference::ReferenceParams { spp: 64, ..Default::default() },
        &|_, _| {},
    )
    .unwrap();
    let error = |method: Method| {
        let p = CoherentParams::new(method, Quality::Med);
        let (rep, _) = build_representation(&scene, &real, &samples, 0.03, &p, None);
        let frame = Coherent::new(&scene, &real, &rep, p).render(&reference.hdr_real, &|_, _| {}).unwrap();
        assert!(frame.report.object_pixels > 20, "{:?}", frame.report);
        // linear radiance against the path-traced composite in the affected region
        crate::metrics::rmse(&reference.hdr_full, &frame.composite, Some(&reference.affected_mask))
    };
    let off = error(Method::Off);
    for method in [Method::Em, Method::Dit, Method::Vct] {
        let e = error(method);
        assert!(e < off, "{}: RMSE {e:.4} against gi off {off:.4}", method.name());
    }
}

#[test]
fn on_the_survey_scenes_every_method_beats_gi_off_on_average_and_where_the_lamp_is_virtual() {
    // the whole chain of `mrstudy render --gi-method`: reference, capture, representation
    // (on the GPU where one opens, as studies build it), frame, camera; FLIP in the affected
    // region (display values, as a participant sees them).
    //
    // Until the table lamps lit (issue 44: the spot light sat inside the lamp's stem), every
    // method beat gi off on every survey scene (but DIT on survey-4, within ±0.0035). With the
    // lamps lighting the table, some methods trail gi off where the real lamp lights the table
    // beside the virtual objects (2026-11-28, 16-spp ground truths, FLIP against gi off:
    // survey-3 VCT 0.267/0.258; survey-4 DIT 0.173/0.166, VCT 0.170/0.166; survey-6 EM
    // 0.210/0.205, DIT 0.230/0.205, VCT 0.279/0.205), while all beat it by far where the lamp is
    // virtual (survey-2, survey-5: 0.20–0.24 against 0.44–0.46). So each method must beat gi off
    // on average over the six scenes (EM 0.204, DIT 0.211, VCT 0.248 against 0.324), on both
    // virtual-lamp scenes, and lose on no scene by more than 0.1.
    let gpu = crate::test_support::dir_renderer().ok();
    let methods = [Method::Em, Method::Dit, Method::Vct];
    let (mut off_sum, mut sums) = (0.0, [0.0; 3]);
    for name in ["survey-1", "survey-2", "survey-3", "survey-4", "survey-5", "survey-6"] {
        let scene = crate::scene::load(name).unwrap().with_size(128, 96);
        let reference = crate::reference::ReferenceParams { spp: 16, ..Default::default() };
        let flip = |method: Method| {
            let result =
                render::render_scene(&scene, &CoherentParams::new(method, Quality::Med), &reference, gpu, &|_, _| {})
                    .unwrap();
            result.errors.value("flip_mean", "affected").unwrap()
        };
        let off = flip(Method::Off);
        off_sum += off;
        for (k, method) in methods.into_iter().enumerate() {
            let e = flip(method);
            println!("{name} {}: FLIP {e:.4}, gi off {off:.4}", method.name());
            sums[k] += e;
            let bound = if ["survey-2", "survey-5"].contains(&name) { off } else { off + 0.1 };
            assert!(e < bound, "{name}, {}: FLIP {e:.4} against gi off {off:.4}", method.name());
        }
    }
    for (k, method) in methods.into_iter().enumerate() {
        let (mean, off_mean) = (sums[k] / 6.0, off_sum / 6.0);
        assert!(mean < off_mean, "{}: mean FLIP {mean:.4} against gi off {off_mean:.4}", method.name());
    }
}

#[test]
fn a_coherent_stimulus_is_mapped_and_composed_over_the_photograph_as_a_dir_stimulus_is() {
    let (scene, _, _) = captured(FLOOR);
    let params = crate::reference::ReferenceParams { spp: 4, ..Default::default() };
    let (linear, display, _) = crate::reference::render_photo(&scene, &params, &|_, _| {}).unwrap();
    let p = CoherentParams::new(Method::Dit, Quality::Low);
    let off = crate::cm::CmParams::default();
    let capture = render::CapturedScene::new(&scene, p.seed, &|_, _| {});
    let shown =
        render::render_stimulus(&scene, &capture, photograph(&display, &linear), &p, presented(&off, None), None)
            .unwrap();
    let frame = &shown.frame;
    let (mut object_pixels, mut untouched) = (0, 0);
    for k in 0..display.pixels.len() {
        let c = shown.composite.pixels[k];
        assert!(c.is_finite() && c.min_element() >= 0.0 && c.max_element() <= 1.0, "pixel {k}: {c}");
        if frame.coverage.values[k] == 1.0 {
            // the object as DIR's cm off shows it: sRGB of the simplified Reinhard operator
            let expected = crate::cm::Mapping::Off.apply(frame.object.pixels[k], 1.0).clamp(Vec3::ZERO, Vec3::ONE);
            assert!((c - expected).abs().max_element() < 1e-6, "pixel {k}: {c} against {expected}");
            object_pixels += 1;
        } else if frame.coverage.values[k] == 0.0 && frame.differential.pixels[k] == Vec3::ZERO {
            // no change to the real scene: the photograph bit for bit
            assert_eq!(c, display.pixels[k], "pixel {k}");
            untouched += 1;
        }
    }
    assert!(object_pixels > 20 && untouched > 100, "{object_pixels} object pixels, {untouched} untouched");
    // the shadow darkens the floor beside the box
    let darker = (0..display.pixels.len())
        .filter(|&k| frame.coverage.values[k] == 0.0 && frame.differential.pixels[k].max_element() < -1e-3)
        .filter(|&k| shown.composite.pixels[k].max_element() < display.pixels[k].max_element())
        .count();
    assert!(darker > 20, "{darker} darkened pixels");

    // with no virtual object, cm's colour transfer and ca's camera leave the photograph exact
    let (scene, _, _) = captured(&FLOOR.replace("role = \"virtual\"", "role = \"real\""));
    let (linear, display, _) = crate::reference::render_photo(&scene, &params, &|_, _| {}).unwrap();
    let statistics = crate::cm::CmParams { method: crate::cm::CmMethod::Statistics, ..Default::default() };
    let ca = crate::ca::CaParams::from_sensor(&scene.sensor);
    let capture = render::CapturedScene::new(&scene, p.seed, &|_, _| {});
    let shown = render::render_stimulus(
        &scene,
        &capture,
        photograph(&display, &linear),
        &p,
        presented(&statistics, Some(&ca)),
        None,
    )
    .unwrap();
    assert_eq!(shown.composite.pixels, display.pixels);
}

/// The fraction of `n` items for which `differ` holds.
fn share(n: usize, differ: impl Fn(usize) -> bool) -> f64 {
    (0..n).filter(|&i| differ(i)).count() as f64 / n.max(1) as f64
}

#[test]
fn the_gpu_builds_the_impostors_and_the_voxel_volume_of_a_capture_as_the_cpu_does() {
    let Some(renderer) = crate::test_support::renderer_or_skip() else { return };
    let ctx = &renderer.ctx;
    // survey-6's capture: two virtual objects, so two impostors
    let scene = crate::scene::load("survey-6").unwrap().with_size(80, 60);
    let captured = render::CapturedScene::new(&scene, 1, &|_, _| {});
    let cell = captured.cell();
    let mut samples = captured.samples().to_vec();
    assert!(samples.len() > 500, "{} samples", samples.len());
    // hard cases both builds must skip or clip alike: a NaN position, a NaN radiance, no
    // normal, and radiance far above RADIANCE_MAX (a lamp's core)
    let on_desk = samples[samples.len() / 2].position;
    samples.push(EnvironmentSample { position: Vec3::NAN, normal: Vec3::Y, colour: Vec3::ONE, pose: 0 });
    samples.push(EnvironmentSample { position: on_desk, normal: Vec3::Y, colour: Vec3::NAN, pose: 0 });
    samples.push(EnvironmentSample { position: on_desk + 0.01, normal: Vec3::ZERO, colour: Vec3::ONE, pose: 0 });
    samples.push(EnvironmentSample { position: on_desk - 0.01, normal: Vec3::X, colour: Vec3::splat(1e7), pose: 0 });
    let builder = crate::gpu::representation::RepresentationBuilder::new(ctx);
    let centres: Vec<Vec3> = virtual_object_bounds(&scene).iter().map(|b| b.centroid()).collect();
    assert_eq!(centres.len(), 2);
    for centre in centres {
        // 256² as the pipeline's high quality; up to the spring of this issue the GPU lost
        // splats of disks near the centre there (0.5 % of texels at 128², 1.3 % at 256²)
        for size in [64u32, 128, 256] {
            let cpu = crate::coherent::impostor::DistanceImpostor::build(&samples, centre, size, cell);
            let built = builder
                .impostor(ctx, &samples, centre, size, super::impostor::SPLAT_RADIUS * cell)
                .unwrap()
                .map(DistanceImpostor::from);
            let gpu = &built.value;
            assert!(built.gpu_bytes > 0 && built.gpu_ms.is_finite());
            let ((cr, cd), (gr, gd)) = (cpu.maps(), gpu.maps());
            assert_eq!(cd.len(), 6 * (size * size) as usize);
            assert_eq!(gd.len(), cd.len());
            assert!(cpu.filled() > cd.len() / 3, "{} filled", cpu.filled());
            // identical on lavapipe; float rounding elsewhere may move a disk's edge across
            // a texel's direction, or an equal distance between two samples: a few texels
            let filled_differ = share(cd.len(), |i| cd[i].is_finite() != gd[i].is_finite());
            assert!(filled_differ < 0.002, "{size}²: {filled_differ:.4} of texels filled on one side only");
            let distance_differ =
                share(cd.len(), |i| cd[i].is_finite() && gd[i].is_finite() && (cd[i] - gd[i]).abs() > 1e-4 * cd[i]);
            assert!(distance_differ < 0.005, "{size}²: {distance_differ:.4} of texels at another distance");
            let radiance_differ = share(cd.len(), |i| cd[i].is_finite() && (cr[i] - gr[i]).abs().max_element() > 1e-6);
            assert!(radiance_differ < 0.005, "{radiance_differ:.4} of texels with another radiance");
        }
    }
    let cpu = VoxelVolume::build(&samples, 64, cell);
    let built = builder
        .voxels(ctx, &samples, VoxelVolume::frame(&samples, 64, cell), super::impostor::SPLAT_RADIUS * cell)
        .unwrap()
        .map(VoxelVolume::from);
    let gpu = &built.value;
    assert_eq!((gpu.origin, gpu.voxel, gpu.res), (cpu.origin, cpu.voxel, cpu.res));
    assert_eq!(gpu.level_count(), cpu.level_count());
    assert!(cpu.filled() > 1000, "{} voxels filled", cpu.filled());
    for level in 0..cpu.level_count() {
        let (c, g) = (cpu.level(level), gpu.level(level));
        assert_eq!(c.len(), g.len());
        // fixed point (1/4096) against f32 sums: within 1e-3 of the value, relative
        let differ = share(c.len(), |i| (0..4).any(|k| (c[i][k] - g[i][k]).abs() > 1e-3 * (1.0 + c[i][k].abs())));
        assert!(differ < 0.002, "level {level}: {differ:.4} of voxels differ");
    }
    // the clipped lamp core: no voxel above RADIANCE_MAX on either side
    let brightest = gpu.level(0).iter().map(|v| v[0]).fold(0.0f32, f32::max);
    assert!(brightest > 1000.0 && brightest <= crate::coherent::voxel::RADIANCE_MAX, "{brightest}");
}

#[test]
fn a_live_frame_of_the_unmoved_scene_is_its_stimulus_and_follows_the_object_when_it_moves() {
    let (scene, _, _) = captured(FLOOR);
    let params = crate::reference::ReferenceParams { spp: 4, ..Default::default() };
    let (linear, display, _) = crate::reference::render_photo(&scene, &params, &|_, _| {}).unwrap();
    let off = crate::cm::CmParams::default();
    let live = render::LiveCoherent::new(&scene, display.clone(), linear.clone(), 1).unwrap();
    let mut moved = scene.clone();
    moved.translate_object("box", Vec3::new(0.3, 0.0, 0.0));
    // the mean column of the pixels a frame changes from the photograph
    let changed_column = |image: &Image| {
        let w = image.width as usize;
        let columns: Vec<f64> = (0..image.pixels.len())
            .filter(|&k| (image.pixels[k] - display.pixels[k]).abs().max_element() > 0.02)
            .map(|k| (k % w) as f64)
            .collect();
        assert!(columns.len() > 20, "{} changed pixels", columns.len());
        columns.iter().sum::<f64>() / columns.len() as f64
    };
    for method in [Method::Em, Method::Dit, Method::Vct] {
        let p = CoherentParams::new(method, Quality::Low);
        let capture = render::CapturedScene::new(&scene, p.seed, &|_, _| {});
        let stimulus =
            render::render_stimulus(&scene, &capture, photograph(&display, &linear), &p, presented(&off, None), None)
                .unwrap();
        let frame = live.frame(&scene, &p, &off, &mut crate::cm::CmState::default(), None).unwrap();
        assert_eq!(frame.composite.pixels, stimulus.composite.pixels, "{}", method.name());
        let after = live.frame(&moved, &p, &off, &mut crate::cm::CmState::default(), None).unwrap();
        let (before, now) = (changed_column(&frame.composite), changed_column(&after.composite));
        assert!(now > before + 3.0, "{}: the change's mean column went from {before:.1} to {now:.1}", method.name());
        // the scene voxel volume does not depend on the object: built for the first frame only
        let built = |f: &render::LiveFrame| f.passes.iter().filter(|pass| pass.pass.contains("voxel volume")).count();
        assert_eq!((built(&frame), built(&after)), if method == Method::Vct { (1, 0) } else { (0, 0) });
    }
}

/// FLOOR with the virtual box replaced by `object` (TOML of one `[[objects]]` entry's keys).
fn floor_with(object: &str) -> Scene {
    let start = FLOOR.find("[[objects]]\nname = \"box\"").unwrap();
    let end = start + FLOOR[start..].find("[[lights]]").unwrap();
    let text =
        format!("{}[[objects]]\nname = \"thing\"\nrole = \"virtual\"\n{object}\n\n{}", &FLOOR[..start], &FLOOR[end..]);
    scene_from_toml(&text, "floor")
}

#[test]
fn a_solid_volume_holds_a_sphere_and_a_box_by_their_volume_with_outward_normals() {
    use solid::SolidVolume;
    // a sphere fills π/6 of its box (exact along z, 4 × 4 columns a voxel across)
    let scene = floor_with("shape = \"sphere\"\nradius = 0.1\ntranslate = [0.0, 0.3, 0.0]\nmaterial = \"box\"");
    let object = World::new(&scene, Subset::VirtualOnly);
    let bounds = virtual_object_bounds(&scene)[0];
    let volume = SolidVolume::build(&object, bounds, 32);
    assert_eq!(volume.dims(), glam::UVec3::splat(32));
    assert_eq!(volume.level_count(), 6);
    let filled = volume.filled();
    assert!((filled - PI as f64 / 6.0).abs() < 2e-3, "filled {filled:.5} against {:.5}", PI as f64 / 6.0);
    // each level is the mean of the one below: the fill is kept
    let mean = |level: usize| {
        let n = 32u32 >> level;
        let mut sum = 0.0;
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    sum += volume.tau(level, glam::UVec3::new(x, y, z)) as f64;
                }
            }
        }
        sum / (n * n * n) as f64
    };
    assert!((mean(2) - filled).abs() < 1e-5 && (mean(5) - filled).abs() < 1e-5);
    // rays towards the centre stop at the surface (within a voxel's diagonal); rays passing
    // two voxels beside it do not
    let centre = Vec3::new(0.0, 0.3, 0.0);
    let diagonal = volume.voxel.length();
    let mut rng = Rng::new(3);
    for _ in 0..200 {
        let dir = crate::math::sample_uniform_sphere(rng.next_f32(), rng.next_f32());
        let origin = centre - dir * 0.5;
        let hit = volume.march(origin, dir, 0.0, f32::INFINITY).expect("a ray at the centre stops");
        assert!((hit.t - 0.4).abs() < diagonal, "stopped at {} instead of 0.4", hit.t);
        let outward = (hit.point - centre).normalize();
        assert!(hit.surface.normal.dot(outward) > 0.85, "normal {} at {}", hit.surface.normal, hit.point);
        assert!((hit.surface.albedo - Vec3::new(0.8, 0.2, 0.1)).abs().max_element() < 1e-5);
        let side = Frame::from_normal(dir).to_world(Vec3::X) * (0.1 + 2.0 * diagonal);
        assert!(volume.march(origin + side, dir, 0.0, f32::INFINITY).is_none());
    }
    // closed objects get a volume; a Cornell box's one-sided walls do not bound a solid
    assert!(solid::is_closed(&scene.objects.iter().find(|o| o.name == "thing").unwrap().prims));
    for (name, closed) in [("dir-env-shadow", false), ("glass-figure", true), ("survey-6", true)] {
        let scene = crate::scene::load(name).unwrap();
        let all = scene.objects.iter().filter(|o| o.role == Role::Virtual).all(|o| solid::is_closed(&o.prims));
        assert_eq!(all, closed, "{name}");
    }
    // a box fills its own volume, and moving the volume is building it where the object went
    let scene = floor_with("shape = \"box\"\nsize = [0.3, 0.1, 0.2]\ntranslate = [0.0, 0.05, 0.0]\nmaterial = \"box\"");
    let object = World::new(&scene, Subset::VirtualOnly);
    let volume = SolidVolume::build(&object, virtual_object_bounds(&scene)[0], 32);
    assert_eq!(volume.dims(), glam::UVec3::new(32, 11, 22));
    assert!((volume.filled() - 1.0).abs() < 1e-4, "{}", volume.filled());
    let offset = Vec3::new(0.37, 0.0, -0.21);
    let mut moved_scene = scene.clone();
    moved_scene.translate_object("thing", offset);
    let rebuilt =
        SolidVolume::build(&World::new(&moved_scene, Subset::VirtualOnly), virtual_object_bounds(&moved_scene)[0], 32);
    let moved = volume.moved(offset);
    for _ in 0..200 {
        let dir = crate::math::sample_uniform_sphere(rng.next_f32(), rng.next_f32());
        let origin = offset + Vec3::new(0.0, 0.05, 0.0) - dir * 0.5 + 0.05 * Vec3::new(rng.next_f32(), 0.0, 0.0);
        let (a, b) = (moved.march(origin, dir, 0.0, 2.0), rebuilt.march(origin, dir, 0.0, 2.0));
        assert_eq!(a.is_some(), b.is_some());
        if let (Some(a), Some(b)) = (a, b) {
            assert!((a.t - b.t).abs() < 1e-4 && a.surface.normal.dot(b.surface.normal) > 0.999, "{a:?} {b:?}");
        }
    }
}

#[test]
fn self_shadows_through_the_solid_volume_darken_the_object_as_a_fine_volume_does() {
    // a low box before a tall one: the low box's top sees the tall one's front, and med stops
    // those rays at the tall box's voxels, as intersecting it exactly would
    let scene = floor_with(
        "shape = \"box\"\nsize = [0.2, 0.1, 0.1]\ntranslate = [0.0, 0.05, 0.1]\nmaterial = \"box\"\n\n[[objects]]\nname = \"other\"\nrole = \"virtual\"\nshape = \"box\"\nsize = [0.2, 0.4, 0.1]\ntranslate = [0.0, 0.2, -0.05]\nmaterial = \"box\"",
    );
    let (real, samples) = crate::test_support::captured_samples(&scene, 0.03);
    let photo = photo(&scene);
    let p = CoherentParams::new(Method::Dit, Quality::Med);
    let (rep, passes) = build_representation(&scene, &real, &samples, 0.03, &p, None);
    assert_eq!(rep.solids.len(), 2);
    assert!(passes.iter().any(|pass| pass.pass.starts_with("object solid volumes (32×16×16, 16×32×8")), "{passes:?}");
    let voxel = Coherent::new(&scene, &real, &rep, p).render(&photo, &|_, _| {}).unwrap();
    // the same frame with no self-shadow tests (quality low's rule), and through a fine volume
    let unshadowed = Coherent::new(
        &scene,
        &real,
        &rep,
        CoherentParams { settings: Settings { self_shadow: false, ..p.settings }, ..p },
    )
    .render(&photo, &|_, _| {})
    .unwrap();
    let object_mean = |frame: &CoherentFrame| {
        let pixels: Vec<Vec3> = (0..frame.object.pixels.len())
            .filter(|&k| frame.coverage.values[k] == 1.0)
            .map(|k| frame.object.pixels[k])
            .collect();
        pixels.iter().map(|p| p.element_sum() as f64).sum::<f64>() / pixels.len() as f64
    };
    let exact = {
        let object = World::new(&scene, Subset::VirtualOnly);
        let mut rep = rep.clone();
        // a solid volume so fine that it is the exact object to well within the others' gap
        rep.solids =
            virtual_object_bounds(&scene).iter().map(|&b| solid::SolidVolume::build(&object, b, 256)).collect();
        Coherent::new(&scene, &real, &rep, p).render(&photo, &|_, _| {}).unwrap()
    };
    let (v, u, e) = (object_mean(&voxel), object_mean(&unshadowed), object_mean(&exact));
    eprintln!("object's mean radiance: 32 voxels {v:.4}, 256 voxels {e:.4}, no self-shadow tests {u:.4}");
    assert!(v < 0.97 * u, "self-shadowed {v:.4} against unshadowed {u:.4}");
    assert!((v - e).abs() < 0.25 * (u - e), "32-voxel {v:.4}, 256-voxel {e:.4}, unshadowed {u:.4}");
}

#[test]
fn the_gpu_sweeps_build_the_solid_volumes_as_the_cpu_does() {
    use crate::gpu::representation::SolidSweeps;
    use solid::SolidVolume;
    let Some(renderer) = crate::test_support::renderer_or_skip() else { return };
    let builder = renderer.representation_builder();
    // a sphere; two boxes, one tilted, whose boxes overlap; three patterned objects (stripes,
    // a checkered sphere, wood); the glass figure's turned mesh of 71 424 triangles; the metal
    // bottle's scene (a mirror, a box, a lamp with a sphere bulb)
    let spheres = floor_with("shape = \"sphere\"\nradius = 0.1\ntranslate = [0.0, 0.3, 0.0]\nmaterial = \"box\"");
    let boxes = floor_with(
        "shape = \"box\"\nsize = [0.2, 0.1, 0.1]\ntranslate = [0.0, 0.05, 0.1]\nmaterial = \"box\"\n\n[[objects]]\nname = \"other\"\nrole = \"virtual\"\nshape = \"box\"\nsize = [0.2, 0.4, 0.1]\nrotate_deg = [0.0, 35.0, 0.0]\ntranslate = [0.05, 0.2, 0.02]\nmaterial = \"box\"",
    );
    let patterned = patterned_scene();
    let scenes = [
        spheres,
        boxes,
        patterned.clone(),
        crate::scene::load("glass-figure").unwrap(),
        crate::scene::load("metal-bottle").unwrap(),
    ];
    for scene in &scenes {
        let object = World::new(scene, Subset::VirtualOnly);
        let prims = super::build::solid_primitives(scene).unwrap();
        for bounds in virtual_object_bounds(scene) {
            for longest in [16, 32] {
                let (voxel, dims) = SolidVolume::frame(&bounds, longest);
                let built = builder.solid_sweeps(&renderer.ctx, &prims, bounds, voxel, dims).unwrap();
                let gpu = SolidVolume::from_sweeps(bounds.min, voxel, dims, built.value.clone());
                let cpu = SolidVolume::build(&object, bounds, longest);
                assert_eq!(gpu.dims(), cpu.dims());
                let SolidSweeps { tau, normals, albedos, mips } = built.value;
                assert_eq!(mips.len() + 1, gpu.level_count(), "the GPU made every mip level");
                let n = tau.len();
                assert!(n == normals.len() && n == albedos.len() && n == (dims.x * dims.y * dims.z) as usize);
                // the same crossings, found by the same arithmetic: τ within float rounding in
                // all but a rare column where a ray grazes an edge one side counts and the
                // other does not
                let mut off = 0;
                let mut worst_mean = 0.0f64;
                for level in 0..cpu.level_count() {
                    let (mut a, mut b) = (0.0f64, 0.0f64);
                    let d = (dims.as_vec3() / (1u32 << level) as f32).ceil().as_uvec3().max(glam::UVec3::ONE);
                    for z in 0..d.z {
                        for y in 0..d.y {
                            for x in 0..d.x {
                                let v = glam::UVec3::new(x, y, z);
                                let (g, c) = (gpu.tau(level, v), cpu.tau(level, v));
                                if level == 0 && (g - c).abs() > 1e-4 {
                                    off += 1;
                                }
                                (a, b) = (a + g as f64, b + c as f64);
                            }
                        }
                    }
                    worst_mean = worst_mean.max((a - b).abs() / (d.x * d.y * d.z) as f64);
                }
                assert!(off * 500 <= n, "{}: {off} of {n} voxels' τ differ at {longest}", scene.name);
                assert!(worst_mean < 1e-3, "{}: mean τ differs by {worst_mean} at {longest}", scene.name);
                assert!(gpu.filled() > 0.01, "{}: an empty volume", scene.name);
                // the surfaces: where both saw crossings, the same outward normal and albedo
                let mut agree = 0;
                let mut both = 0;
                for z in 0..dims.z {
                    for y in 0..dims.y {
                        for x in 0..dims.x {
                            let v = glam::UVec3::new(x, y, z);
                            let (g, c) = (gpu.surface(v), cpu.surface(v));
                            if let (Some(g), Some(c)) = (g, c) {
                                both += 1;
                                if g.normal.dot(c.normal) > 0.99
                                    && (g.albedo - c.albedo).abs().max_element() < 1e-4
                                    && g.delta == c.delta
                                {
                                    agree += 1;
                                }
                            }
                        }
                    }
                }
                assert!(both > 0 && agree * 100 >= both * 99, "{}: {agree} of {both} surface voxels agree", scene.name);
                eprintln!(
                    "{} at {longest}: τ of {off} of {n} voxels differ by more than 1e-4, mean τ by at most {worst_mean:.1e}; {agree} of {both} surface voxels agree; GPU {:.1} ms",
                    scene.name, built.gpu_ms
                );
                assert!(built.gpu_bytes > 0 && built.gpu_ms >= 0.0);
            }
        }
    }
    // the representation says where its solid volumes were built, and why not on the GPU
    let p = CoherentParams::new(Method::Dit, Quality::Med);
    let built_by = |scene: &Scene| {
        let sky = Arc::new(crate::light::Environment::uniform(Vec3::splat(0.5)));
        let (_, passes) =
            build_queries(scene, &[], 0.03, &p, Some(renderer), Prebuilt { sky, voxels: None, solids: None });
        passes.into_iter().map(|pass| pass.pass).find(|pass| pass.starts_with("object solid volumes")).unwrap()
    };
    let plain = built_by(&scenes[1]);
    assert!(plain.contains(&renderer.ctx.adapter_name()) && plain.contains("GPU"), "{plain}");
    let mut imaged = patterned.clone();
    let stripes = imaged.materials.iter().position(|m| m.name == "striped").unwrap();
    let image = crate::image::Image { width: 2, height: 2, pixels: vec![Vec3::ONE, Vec3::ZERO, Vec3::ZERO, Vec3::ONE] };
    imaged.materials[stripes].texture = Some(crate::material::Texture::Image(Arc::new(image)));
    let patterned_pass = built_by(&patterned);
    assert!(patterned_pass.contains("GPU"), "{patterned_pass}");
    let named = built_by(&imaged);
    assert!(named.contains("on the CPU") && named.contains("image texture"), "{named}");
}

/// The floor with three virtual objects of procedural patterns: a striped box, a checkered
/// sphere, a wooden box.
fn patterned_scene() -> Scene {
    let text = FLOOR.replace(
        "[materials.box]",
        "[materials.striped]\npattern = { kind = \"stripes\", a = [0.1, 0.2, 0.3], b = [0.7, 0.6, 0.3], scale = 5.0 }\n\n[materials.checkered]\npattern = { kind = \"checker\", a = [0.9, 0.1, 0.1], b = [0.1, 0.1, 0.9], scale = 6.0 }\n\n[materials.wooden]\npattern = { kind = \"wood\", a = [0.55, 0.36, 0.2], b = [0.32, 0.18, 0.08], scale = 9.0 }\n\n[materials.box]",
    );
    let start = text.find("[[objects]]\nname = \"box\"").unwrap();
    let end = start + text[start..].find("[[lights]]").unwrap();
    let objects = "[[objects]]\nname = \"book\"\nrole = \"virtual\"\nshape = \"box\"\nsize = [0.2, 0.05, 0.3]\ntranslate = [-0.2, 0.025, 0.0]\nmaterial = \"striped\"\n\n[[objects]]\nname = \"ball\"\nrole = \"virtual\"\nshape = \"sphere\"\nradius = 0.08\ntranslate = [0.1, 0.08, 0.0]\nmaterial = \"checkered\"\n\n[[objects]]\nname = \"block\"\nrole = \"virtual\"\nshape = \"box\"\nsize = [0.1, 0.2, 0.1]\ntranslate = [0.3, 0.1, -0.1]\nmaterial = \"wooden\"\n\n";
    scene_from_toml(&format!("{}{objects}{}", &text[..start], &text[end..]), "patterned")
}
