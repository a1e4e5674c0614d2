//! Mirrors, glass and caustics in the reference path tracer (issue 17) against Mitsuba 3: the
//! scenes `tests/reference/specular/{spot,area}.toml` (a glass sphere and a mirror on a diffuse
//! floor under a spot light and under an area light), rendered here with independent seeds, and
//! each region's mean radiance compared with Mitsuba 3.9.1's (`scalar_rgb`; `ptracer` for the
//! floor under the spot light, `path` elsewhere), which `tests/reference/mitsuba_specular.py`
//! wrote into `tests/reference/mitsuba_specular.json` (this test needs no Mitsuba). Equal means
//! within noise: the difference must stay within four standard errors of the two estimates
//! together (each from the spread of independent renders), plus 0.01 % for single-precision
//! arithmetic. The seeds are fixed, so the outcome is too. Under the spot light the caustic
//! regions are lit only by light tracing: without it they would be black (checked as well).

use mrstudy_renderer::pathtracer::{Subset, TraceParams, World, render};
use mrstudy_renderer::scene::Scene;
use std::path::Path;

/// Independent renders per scene (their spread gives the standard error), and their samples.
const SEEDS: u64 = 8;
const SPP: u32 = 256;

fn reference_dir() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/reference"))
}

fn region_mean(image: &mrstudy_renderer::Image, box_: &[usize]) -> f64 {
    let (x0, y0, x1, y1) = (box_[0], box_[1], box_[2], box_[3]);
    let mut sum = 0.0f64;
    for y in y0..y1 {
        for x in x0..x1 {
            let p = image.pixels[y * image.width as usize + x];
            sum += (p.x + p.y + p.z) as f64 / 3.0;
        }
    }
    sum / ((x1 - x0) * (y1 - y0)) as f64
}

fn compare(name: &str) {
    let reference: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(reference_dir().join("mitsuba_specular.json")).unwrap()).unwrap();
    let scene = Scene::load(&reference_dir().join("specular").join(format!("{name}.toml"))).unwrap();
    let world = World::new(&scene, Subset::All);
    assert_eq!(world.needs_light_tracing(), name == "spot", "light tracing only where a spot light meets glass");
    let images: Vec<_> = (0..SEEDS)
        .map(|seed| {
            render(&world, &scene.camera, &TraceParams { seed: 1000 + seed, ..Default::default() }, SPP).image()
        })
        .collect();
    let mut failures = Vec::new();
    for (region, expected) in reference["scenes"][name].as_object().unwrap() {
        let box_: Vec<usize> =
            reference["regions"][region].as_array().unwrap().iter().map(|v| v.as_u64().unwrap() as usize).collect();
        let means: Vec<f64> = images.iter().map(|image| region_mean(image, &box_)).collect();
        let mean = means.iter().sum::<f64>() / SEEDS as f64;
        let variance = means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (SEEDS - 1) as f64;
        let ours_se = (variance / SEEDS as f64).sqrt();
        let theirs = expected["mean"].as_f64().unwrap();
        let theirs_se = expected["standard_error"].as_f64().unwrap();
        let tolerance = 4.0 * (ours_se.powi(2) + theirs_se.powi(2)).sqrt() + 1e-4 * theirs.abs();
        let line = format!(
            "{name} {region}: mrstudy {mean:.5} ± {ours_se:.5}, Mitsuba ({}) {theirs:.5} ± {theirs_se:.5}, tolerance {tolerance:.5}",
            expected["integrator"].as_str().unwrap()
        );
        eprintln!("{line}");
        if (mean - theirs).abs() > tolerance {
            failures.push(line);
        }
    }
    assert!(failures.is_empty(), "region means differ beyond noise:\n{}", failures.join("\n"));
}

#[test]
fn glass_and_mirror_caustics_under_a_spot_light_match_mitsuba_ptracer() {
    compare("spot");
}

#[test]
fn without_light_tracing_the_spot_lights_caustics_are_missing() {
    let scene = Scene::load(&reference_dir().join("specular/spot.toml")).unwrap();
    let world = World::new(&scene, Subset::All);
    let params = |light_tracing| TraceParams { seed: 7, light_tracing, ..Default::default() };
    let with = render(&world, &scene.camera, &params(true), 16).image();
    let without = render(&world, &scene.camera, &params(false), 16).image();
    let caustic = [53, 52, 59, 57];
    // the focus of the glass sphere: over 2 with light tracing, nearly black without it
    assert!(region_mean(&with, &caustic) > 1.5, "{}", region_mean(&with, &caustic));
    assert!(region_mean(&without, &caustic) < 0.01, "{}", region_mean(&without, &caustic));
    // a scene without mirror or glass needs none
    let plain = Scene::load(&reference_dir().join("specular/spot.toml")).unwrap();
    let mut plain = plain;
    let glossy: Vec<usize> = (0..plain.materials.len()).filter(|&m| plain.materials[m].delta.is_none()).collect();
    for object in &mut plain.objects {
        object.material = glossy[0];
    }
    assert!(!World::new(&plain, Subset::All).needs_light_tracing());
}

#[test]
fn glass_and_mirror_under_an_area_light_match_mitsuba_path() {
    compare("area");
}

#[test]
fn a_material_of_one_kind_with_the_keys_of_another_is_refused_naming_the_key() {
    let scene = |material: &str| {
        let text = format!(
            "[camera]\nwidth = 8\nheight = 8\nfov_y_deg = 40\nposition = [0.0, 1.0, 2.0]\nlook_at = [0.0, 0.0, 0.0]\n\
             [materials.m]\n{material}\n\
             [[objects]]\nname = \"ball\"\nrole = \"virtual\"\nshape = \"sphere\"\nradius = 0.3\nmaterial = \"m\"\n"
        );
        let desc = mrstudy_renderer::scene::SceneDesc::from_toml(&text, "bad.toml")?;
        Scene::from_desc(desc, Path::new("."), "bad.toml")
    };
    for (material, key, expected) in [
        ("kind = \"glass\"\nalbedo = 0.5", "materials.m.albedo", "kind = \"glass\""),
        ("kind = \"mirror\"\nior = 1.5", "materials.m.ior", "kind = \"mirror\""),
        ("ior = 1.5", "materials.m.ior", "kind = \"glossy\""),
        ("kind = \"metal\"", "materials.m.kind", "\"glossy\", \"mirror\" or \"glass\""),
        ("kind = \"glass\"\nior = 0.5", "materials.m.ior", "from 1 to 4"),
        ("kind = \"glass\"\ntransmittance = 0.0", "materials.m.transmittance", "(0, 1]"),
        ("kind = \"glass\"\ntransmittance_depth = -1.0", "materials.m.transmittance_depth", "> 0"),
        ("kind = \"mirror\"\nreflectance = 1.5", "materials.m.reflectance", "[0, 1]"),
    ] {
        let message = scene(material).err().unwrap_or_else(|| panic!("accepted: {material}")).to_string();
        assert!(
            message.contains("bad.toml") && message.contains(key) && message.contains(expected),
            "{material}: {message}"
        );
    }
    // what the keys make
    let glass =
        scene("kind = \"glass\"\nior = 1.33\ntransmittance = [0.5, 1.0, 1.0]\ntransmittance_depth = 0.1").unwrap();
    match glass.materials[glass.objects[0].material].delta {
        Some(mrstudy_renderer::material::DeltaBsdf::Dielectric { ior, absorption }) => {
            assert_eq!(ior, 1.33);
            // exp(−σ · 0.1) = 0.5
            assert!((absorption.x - 2f32.ln() / 0.1).abs() < 1e-4 && absorption.y == 0.0, "{absorption}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn light_tracing_gives_the_same_image_on_any_number_of_threads() {
    let scene = Scene::load(&reference_dir().join("specular/spot.toml")).unwrap();
    let world = World::new(&scene, Subset::All);
    let params = TraceParams { seed: 3, ..Default::default() };
    let on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| render(&world, &scene.camera, &params, 3).image())
    };
    let (one, three) = (on(1), on(3));
    assert!(
        one.pixels
            .iter()
            .zip(&three.pixels)
            .all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits))
    );
}
