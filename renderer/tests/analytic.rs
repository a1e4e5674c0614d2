//! Analytic checks of the reference path tracer and the scene loader: the white furnace, the
//! irradiance of a spot light and of an area light, convergence as 1/√spp, determinism, and the
//! hard cases and bad inputs of the renderer issue. Images are tiny and sample counts small;
//! each tolerance is stated with its statistical reason.

use glam::Vec3;
use mrstudy_renderer::geometry::Ray;
use mrstudy_renderer::math::Rng;
use mrstudy_renderer::pathtracer::{Subset, TraceParams, World, render};
use mrstudy_renderer::reference::{ReferenceParams, render_photo, render_reference};
use mrstudy_renderer::scene::{self, Scene, SceneDesc};
use mrstudy_renderer::{Image, RenderError};
use std::path::{Path, PathBuf};

/// White furnace: the issue asks for albedo × radiance to 0.5 %.
const FURNACE_TOLERANCE: f64 = 0.005;
/// Spot irradiance (inverse-square and cosine law): 1 %.
const SPOT_TOLERANCE: f32 = 0.01;
/// Fitted log–log slope of RMSE against spp must be −0.5 within this.
const SLOPE_TOLERANCE: f64 = 0.1;

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mrstudy-renderer-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn scene_from(toml: &str) -> Scene {
    let desc = SceneDesc::from_toml(toml, "test.toml").unwrap();
    Scene::from_desc(desc, Path::new("."), "test.toml").unwrap()
}

/// A Lambertian floor (albedo 0.5, 20 m square at y = 0) seen from above, lit by `light` (a
/// `[[lights]]` table) and nothing else.
fn floor_under(light: &str) -> Scene {
    scene_from(&format!(
        r#"
        [camera]
        width = 4
        height = 4
        fov_y_deg = 40.0
        position = [0.0, 3.0, 0.01]
        look_at = [0.0, 0.0, 0.0]
        [[objects]]
        name = "floor"
        role = "real"
        shape = "plane"
        size = [20.0, 20.0]
        material = {{ albedo = 0.5 }}
        {light}
        "#
    ))
}

/// The mean of independent samples and its standard error.
fn mean_and_standard_error(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    (mean, (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt())
}

#[test]
fn white_furnace_returns_albedo_times_radiance() {
    // A diffuse sphere (albedo 0.8) filling the whole view inside a uniform environment of
    // radiance 1: every path sees the environment after one bounce (the sphere is convex), so
    // each pixel's expectation is exactly 0.8.
    let scene = scene_from(
        r#"
        [camera]
        width = 32
        height = 32
        fov_y_deg = 10.0
        position = [0.0, 0.0, 2.0]
        look_at = [0.0, 0.0, 0.0]
        [environment]
        kind = "uniform"
        radiance = 1.0
        [[objects]]
        name = "ball"
        role = "real"
        shape = "sphere"
        radius = 0.5
        material = { albedo = 0.8 }
        "#,
    );
    let world = World::new(&scene, Subset::All);
    let acc = render(&world, &scene.camera, &TraceParams::default(), 128);
    // grey albedo and radiance: the channels are equal, so take one (pixels are independent)
    let values: Vec<f64> = acc.image().pixels.iter().map(|p| p.x as f64).collect();
    let (mean, se) = mean_and_standard_error(&values);
    // the test only means something if its own noise is well inside the tolerance
    // (3 σ of the estimate must fit twice inside the tolerance band)
    assert!(6.0 * se < FURNACE_TOLERANCE * 0.8, "standard error {se} too large for the test");
    assert!((mean / 0.8 - 1.0).abs() < FURNACE_TOLERANCE, "furnace mean {mean} (± {se}), expected 0.8");
}

#[test]
fn spot_light_irradiance_follows_inverse_square_and_cosine_laws() {
    // A Lambertian plane (albedo ρ = 0.5) under a spot light of intensity I = 2 W/sr pointing
    // straight down from height h. Outgoing radiance at horizontal offset x: ρ/π · I cos θ / d².
    // Nothing else is in the scene, so the estimate is deterministic.
    for h in [0.5f32, 1.0, 2.0] {
        let scene = floor_under(&format!(
            r#"
            [[lights]]
            kind = "spot"
            position = [0.0, {h}, 0.0]
            direction = [0.0, -1.0, 0.0]
            inner_deg = 70.0
            outer_deg = 80.0
            intensity = 2.0
            "#
        ));
        let world = World::new(&scene, Subset::All);
        for x in [0.0f32, 0.3, 0.7, 1.2] {
            let d2 = h * h + x * x;
            let cos = h / d2.sqrt();
            if cos < 70f32.to_radians().cos() {
                continue;
            }
            let expected = 0.5 / std::f32::consts::PI * 2.0 * cos / d2;
            let ray = Ray { origin: Vec3::new(x, 0.2, 0.0), dir: Vec3::new(0.0, -1.0, 0.0) };
            let (l, _) = world.radiance(ray, &mut Rng::new(1), &TraceParams::default());
            assert!((l.x / expected - 1.0).abs() < SPOT_TOLERANCE, "h={h} x={x}: {} vs {expected}", l.x);
        }
    }
}

/// Irradiance per unit radiance (π × the form factor) at the origin of a plane from a parallel
/// rectangle [x0, x1] × [z0, z1] at height h: the corner-rectangle formula summed with signs.
fn rectangle_irradiance(h: f64, x0: f64, x1: f64, z0: f64, z1: f64) -> f64 {
    let corner = |x: f64, z: f64| {
        let (a, b) = (x.abs() / h, z.abs() / h);
        let (ra, rb) = ((1.0 + a * a).sqrt(), (1.0 + b * b).sqrt());
        let f = (a / ra * (b / ra).atan() + b / rb * (a / rb).atan()) / (2.0 * std::f64::consts::PI);
        x.signum() * z.signum() * f
    };
    std::f64::consts::PI * (corner(x1, z1) - corner(x0, z1) - corner(x1, z0) + corner(x0, z0))
}

#[test]
fn area_light_irradiance_matches_the_rectangles_form_factor() {
    // A Lambertian floor (ρ = 0.5) under a square area light (side 0.5, radiance 3) facing down
    // from height h; the light's own surface is black, so every path's light is direct (next-event
    // estimation and the light hit by BSDF sampling, weighted by MIS). Outgoing radiance at a
    // floor point: ρ/π · L · E, E from the rectangle's form factor (Howell's catalogue, C-11).
    for h in [0.5f64, 1.5] {
        let scene = floor_under(&format!(
            r#"
            [[lights]]
            kind = "area"
            position = [0.0, {h}, 0.0]
            target = [0.0, 0.0, 0.0]
            size = [0.5, 0.5]
            intensity = 3.0
            "#
        ));
        let world = World::new(&scene, Subset::All);
        for x in [0.0f64, 0.15, 0.6] {
            let expected = 0.5 / std::f64::consts::PI * 3.0 * rectangle_irradiance(h, -0.25 - x, 0.25 - x, -0.25, 0.25);
            let n = 100_000;
            let samples: Vec<f64> = (0..n)
                .map(|i| {
                    let ray = Ray { origin: Vec3::new(x as f32, 0.2, 0.0), dir: Vec3::new(0.0, -1.0, 0.0) };
                    world.radiance(ray, &mut Rng::for_stream(7, x.to_bits(), i), &TraceParams::default()).0.x as f64
                })
                .collect();
            let (mean, se) = mean_and_standard_error(&samples);
            // 1 % as for the spot light, and the estimate's own noise well inside it
            assert!(4.0 * se < 0.01 * expected, "h={h} x={x}: standard error {se} too large against {expected}");
            assert!((mean / expected - 1.0).abs() < 0.01, "h={h} x={x}: {mean} (± {se}) vs {expected}");
        }
    }
}

fn convergence_scene() -> Scene {
    scene_from(
        r#"
        [camera]
        width = 12
        height = 12
        fov_y_deg = 40.0
        position = [0.0, 0.6, 1.5]
        look_at = [0.0, 0.2, 0.0]
        [environment]
        kind = "sky"
        [[objects]]
        name = "floor"
        role = "real"
        shape = "plane"
        size = [4.0, 4.0]
        material = { albedo = 0.6 }
        [[objects]]
        name = "ball"
        role = "virtual"
        shape = "sphere"
        radius = 0.25
        translate = [0.0, 0.25, 0.0]
        material = { albedo = [0.7, 0.3, 0.2] }
        "#,
    )
}

#[test]
fn error_falls_as_one_over_sqrt_spp() {
    let scene = convergence_scene();
    let world = World::new(&scene, Subset::All);
    let reference = render(&world, &scene.camera, &TraceParams { seed: 999, ..Default::default() }, 1024).image();
    let spps = [4u32, 16, 64];
    let rmses: Vec<f64> = spps
        .iter()
        .map(|&spp| {
            let img = render(&world, &scene.camera, &TraceParams { seed: 5, ..Default::default() }, spp).image();
            mrstudy_renderer::metrics::rmse(&reference, &img, None)
        })
        .collect();
    // least-squares slope of ln(rmse) against ln(spp); each RMSE is an average over 432 values
    // (relative standard error ≈ 4 %), so the slope's standard error is ≈ 0.03.
    let xs: Vec<f64> = spps.iter().map(|&s| (s as f64).ln()).collect();
    let ys: Vec<f64> = rmses.iter().map(|r| r.ln()).collect();
    let (mx, my) = (xs.iter().sum::<f64>() / 3.0, ys.iter().sum::<f64>() / 3.0);
    let slope = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum::<f64>()
        / xs.iter().map(|x| (x - mx).powi(2)).sum::<f64>();
    assert!((slope + 0.5).abs() < SLOPE_TOLERANCE, "slope {slope}, rmse {rmses:?}");
}

#[test]
fn renders_are_deterministic_per_seed_and_photo_shares_noise_with_ground_truth() {
    let scene = convergence_scene();
    let params = ReferenceParams { spp: 4, seed: 3, ..Default::default() };
    let a = render_reference(&scene, &params, &|_, _| {}).unwrap();
    let b = render_reference(&scene, &params, &|_, _| {}).unwrap();
    assert_eq!(a.hdr_full, b.hdr_full);
    assert_eq!(a.ground_truth, b.ground_truth);
    let c = render_reference(&scene, &ReferenceParams { seed: 4, ..params.clone() }, &|_, _| {}).unwrap();
    assert_ne!(a.hdr_full, c.hdr_full);
    // pixels whose paths never meet the virtual ball are identical in photo and ground truth
    let same = a.hdr_real.pixels.iter().zip(&a.hdr_full.pixels).filter(|(x, y)| x == y).count();
    assert!(same > 0, "no pixel shares its noise realisation");
    // the virtual ball is covered and inside the affected region
    assert!(a.virtual_mask.coverage() > 0.05);
    for (v, m) in a.virtual_mask.values.iter().zip(&a.affected_mask.values) {
        if *v > 0.0 {
            assert_eq!(*m, 1.0);
        }
    }
    // the photograph alone equals the reference's photograph
    let (hdr, photo, _) = render_photo(&scene, &params, &|_, _| {}).unwrap();
    assert_eq!(hdr, a.hdr_real);
    assert_eq!(photo, a.photo);
}

#[test]
fn a_scene_without_virtual_objects_has_identical_photo_and_ground_truth() {
    let mut desc = scene::SceneDesc::from_toml(&convergence_scene().desc.to_toml(), "x").unwrap();
    desc.objects.retain(|o| o.role == Some(scene::Role::Real));
    let scene = Scene::from_desc(desc, Path::new("."), "x").unwrap();
    let out = render_reference(&scene, &ReferenceParams { spp: 2, ..Default::default() }, &|_, _| {}).unwrap();
    assert_eq!(out.hdr_real, out.hdr_full);
    assert_eq!(out.photo, out.ground_truth);
    assert_eq!(out.affected_mask.coverage(), 0.0);
}

#[test]
fn invalid_environment_pixels_are_repaired_with_a_warning() {
    let dir = temp_dir("envmap");
    let mut map = Image::filled(8, 4, Vec3::splat(0.5));
    map.pixels[3] = Vec3::new(f32::NAN, 0.5, 0.5);
    map.pixels[5] = Vec3::new(0.5, f32::INFINITY, 0.5);
    map.pixels[9] = Vec3::new(0.5, 0.5, -1.0);
    map.save_exr(&dir.join("bad.exr")).unwrap();
    let path = dir.join("scene.toml");
    std::fs::write(
        &path,
        r#"
        [camera]
        width = 8
        height = 8
        fov_y_deg = 60.0
        position = [0.0, 0.0, 1.0]
        look_at = [0.0, 0.0, 0.0]
        [environment]
        kind = "map"
        path = "bad.exr"
        [[objects]]
        name = "ball"
        role = "real"
        shape = "sphere"
        radius = 0.3
        "#,
    )
    .unwrap();
    let scene = Scene::load(&path).unwrap();
    let warning = scene.warnings.iter().find(|w| w.contains("bad.exr")).expect("a warning naming the map");
    assert!(warning.contains("1 NaN") && warning.contains("1 infinite") && warning.contains("1 negative"), "{warning}");
    let out = render_reference(&scene, &ReferenceParams { spp: 2, ..Default::default() }, &|_, _| {}).unwrap();
    assert!(out.hdr_full.pixels.iter().all(|p| p.is_finite() && p.min_element() >= 0.0));
    assert_eq!(out.stats.invalid_samples, 0);
}

#[test]
fn degenerate_triangles_zero_area_lights_and_a_camera_inside_an_object_are_reported() {
    let dir = temp_dir("degenerate");
    std::fs::write(dir.join("m.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\n").unwrap();
    let path = dir.join("scene.toml");
    std::fs::write(
        &path,
        r#"
        [camera]
        width = 8
        height = 8
        fov_y_deg = 60.0
        position = [0.0, 0.0, 0.0]
        look_at = [0.0, 0.0, -1.0]
        [[objects]]
        name = "room"
        role = "real"
        shape = "box"
        size = [1.0, 1.0, 1.0]
        [[objects]]
        name = "tri"
        role = "virtual"
        shape = "mesh"
        path = "m.obj"
        translate = [0.0, 0.0, -0.3]
        [[lights]]
        name = "flat"
        kind = "area"
        position = [0.0, 0.4, 0.0]
        direction = [0.0, -1.0, 0.0]
        size = [0.0, 0.2]
        intensity = 5.0
        "#,
    )
    .unwrap();
    let scene = Scene::load(&path).unwrap();
    let all = scene.warnings.join("\n");
    assert!(all.contains("dropped 1 degenerate"), "{all}");
    assert!(all.contains("zero area"), "{all}");
    assert!(all.contains("inside object `room`"), "{all}");
    let out = render_reference(&scene, &ReferenceParams { spp: 1, ..Default::default() }, &|_, _| {}).unwrap();
    assert!(out.hdr_full.pixels.iter().all(|p| p.is_finite()));
}

#[test]
fn fireflies_are_counted_not_clamped() {
    // A tiny, extremely bright emitter that only BRDF sampling can find (an emissive sphere is
    // not in the light list): rare huge samples. They must be reported and kept.
    let scene = scene_from(
        r#"
        [camera]
        width = 16
        height = 16
        fov_y_deg = 50.0
        position = [0.0, 1.0, 1.0]
        look_at = [0.0, 0.0, 0.0]
        [[objects]]
        name = "floor"
        role = "real"
        shape = "plane"
        size = [4.0, 4.0]
        material = { albedo = 0.5 }
        [[objects]]
        name = "sun"
        role = "real"
        shape = "sphere"
        radius = 0.01
        translate = [0.0, 0.5, 0.0]
        material = { albedo = 0.0, emission = 100000.0 }
        "#,
    );
    let (hdr, _, stats) = render_photo(&scene, &ReferenceParams { spp: 4, ..Default::default() }, &|_, _| {}).unwrap();
    assert!(stats.fireflies_photo > 0, "{stats:?}");
    assert!(stats.warnings.iter().any(|w| w.contains("firefly")));
    let brightest = hdr.pixels.iter().map(|p| p.max_element()).fold(0.0, f32::max);
    assert!(brightest > 100.0, "a firefly was clamped: {brightest}");
}

#[test]
fn bad_input_is_named_in_one_sentence() {
    let base = r#"
        [camera]
        width = 8
        height = 8
        fov_y_deg = 60.0
        position = [0.0, 0.0, 1.0]
        look_at = [0.0, 0.0, 0.0]
    "#;
    let dir = temp_dir("bad");
    let check = |body: &str, needles: &[&str]| {
        let path = dir.join("bad.toml");
        std::fs::write(&path, format!("{base}\n{body}")).unwrap();
        let err = Scene::load(&path).unwrap_err().to_string();
        assert!(!err.contains('\n'), "not one line: {err}");
        assert!(err.contains("bad.toml"), "file not named: {err}");
        for n in needles {
            assert!(err.contains(n), "`{n}` missing in: {err}");
        }
    };
    check("[[objects]]\nname = \"a\"\nshape = \"box\"\nsize = [1, 1, 1]", &["objects[0].role", "expected"]);
    check("[[objects]]\nrole = \"real\"\nshape = \"sphere\"", &["objects[0].radius", "positive"]);
    check("[[objects]]\nrole = \"real\"\nshape = \"teapot\"", &["objects[0].shape", "teapot"]);
    check(
        "[[objects]]\nrole = \"real\"\nshape = \"box\"\nsize = [1, 1, 1]\nmaterial = { albedo = 0.8, specular = 0.5 }",
        &["objects[0].material.specular", "≤ 1"],
    );
    check(
        "[[objects]]\nrole = \"real\"\nshape = \"box\"\nsize = [1, 1, 1]\nmaterial = \"nope\"",
        &["objects[0].material", "nope"],
    );
    check("[[objects]]\nrole = \"real\"\nshape = \"box\"\ncolour = 3", &["colour"]);
    check("[[lights]]\nkind = \"spot\"\nposition = [0, 1, 0]\nintensity = 1.0", &["lights[0].direction"]);
    // a missing mesh and a missing texture are named
    for (body, what) in [
        ("[[objects]]\nrole = \"real\"\nshape = \"mesh\"\npath = \"missing.glb\"", "missing.glb"),
        (
            "[[objects]]\nrole = \"real\"\nshape = \"box\"\nsize = [1, 1, 1]\nmaterial = { texture = \"missing.png\" }",
            "missing.png",
        ),
    ] {
        let path = dir.join("bad.toml");
        std::fs::write(&path, format!("{base}\n{body}")).unwrap();
        let err = Scene::load(&path).unwrap_err();
        assert!(matches!(err, RenderError::MissingFile { .. }), "{err}");
        assert!(err.to_string().contains(what), "{err}");
    }
    assert!(matches!(scene::load("no-such-scene"), Err(RenderError::UnknownScene { .. })));
}

#[test]
fn obj_and_gltf_meshes_load() {
    let dir = temp_dir("meshes");
    std::fs::write(
        dir.join("quad.obj"),
        "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvn 0 1 0\nf 1//1 3//1 2//1\nf 1//1 4//1 3//1\n",
    )
    .unwrap();
    // a one-triangle glTF with its buffer beside it
    let positions: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let bytes: Vec<u8> = positions.iter().flat_map(|f| f.to_le_bytes()).collect();
    std::fs::write(dir.join("tri.bin"), &bytes).unwrap();
    std::fs::write(
        dir.join("tri.gltf"),
        r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],
            "nodes":[{"mesh":0,"translation":[0,0,-1]}],
            "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
            "buffers":[{"uri":"tri.bin","byteLength":36}],
            "bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36}],
            "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}]}"#,
    )
    .unwrap();
    let obj = mrstudy_renderer::mesh::load(&dir.join("quad.obj")).unwrap();
    assert_eq!(obj.len(), 2);
    assert!(obj[0].n.is_some());
    let gltf = mrstudy_renderer::mesh::load(&dir.join("tri.gltf")).unwrap();
    assert_eq!(gltf.len(), 1);
    assert!((gltf[0].p[0].z + 1.0).abs() < 1e-6, "node transform not applied");
}

/// The reference's photograph and ground truth traced together (each path once until it meets
/// a virtual object) are bit for bit the two images traced in separate passes, on every built-in
/// scene whose lights are all real — with mirrors, glass, light tracing, environments and
/// area lights among them.
#[test]
fn paths_traced_for_both_images_at_once_give_the_images_of_two_passes() {
    use mrstudy_renderer::pathtracer::Accumulator;
    let params = TraceParams { seed: 5, ..TraceParams::default() };
    let (mut paired, mut apart) = (Vec::new(), Vec::new());
    for name in scene::builtin::names() {
        let scene = scene::load_as(name, Some((40, 30)), None).unwrap();
        let real = World::new(&scene, Subset::RealOnly);
        let full = World::new(&scene, Subset::All);
        if !full.shares_lights_with(&real) {
            apart.push(name);
            continue;
        }
        let (w, h) = (scene.camera.width, scene.camera.height);
        let (mut acc_full, mut acc_real) = (Accumulator::new(w, h), Accumulator::new(w, h));
        // two batches, as a progressive render makes them
        for n in [2, 1] {
            acc_full.add_samples_pair(&mut acc_real, &full, &real, &scene.camera, &params, n);
        }
        let (alone_full, alone_real) =
            (render(&full, &scene.camera, &params, 3), render(&real, &scene.camera, &params, 3));
        let differ = |a: &[Vec3], b: &[Vec3]| a.iter().zip(b).filter(|(x, y)| x != y).count();
        let (gt, photo) = (acc_full.image(), acc_real.image());
        assert_eq!(differ(&gt.pixels, &alone_full.image().pixels), 0, "{name}: ground-truth pixels differ");
        assert_eq!(differ(&photo.pixels, &alone_real.image().pixels), 0, "{name}: photograph pixels differ");
        assert!(acc_full.virtual_coverage() == alone_full.virtual_coverage(), "{name}: virtual coverage");
        assert!(acc_full.max_sample == alone_full.max_sample, "{name}: brightest samples");
        assert!(acc_real.luminance_standard_error() == alone_real.luminance_standard_error(), "{name}: noise");
        assert_eq!(acc_full.light_paths, alone_full.light_paths, "{name}");
        assert!(differ(&gt.pixels, &photo.pixels) > 0, "{name}: the virtual objects change nothing");
        paired.push(name);
    }
    eprintln!("traced together: {paired:?}; in two passes: {apart:?}");
    assert!(paired.len() >= 6, "paired: {paired:?}");
    // a virtual light makes the two images sample different lights: two passes
    assert!(apart.contains(&"survey-2") && apart.contains(&"metal-bottle"), "apart: {apart:?}");
    let scene = scene::load_as("survey-1", Some((40, 30)), None).unwrap();
    let last = std::sync::Mutex::new((0, 0));
    let params = ReferenceParams { spp: 2, pass_spp: 1, ..Default::default() };
    let out = render_reference(&scene, &params, &|done, total| *last.lock().unwrap() = (done, total)).unwrap();
    assert!(out.stats.paths.starts_with("together"), "{}", out.stats.paths);
    // progress counts both images' samples, as two passes do
    assert_eq!(*last.lock().unwrap(), (4, 4));
}
