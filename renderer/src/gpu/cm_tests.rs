//! The GPU colour mapping and composition against the CPU reference ([`crate::cm`]) on the
//! GPU's own L_rv, L_r and flags, at 96×72 on lavapipe: every method, both compositions,
//! composites agreeing to 10⁻³; the passes in the frame report; no differential, no change.

use super::*;
use crate::cm::colour::gamma_encode;
use crate::cm::{CmInput, CmMethod, cpu_frame};
use crate::scene::Role;
use crate::test_support::{TestScene, assert_images_match, renderer_or_skip};

fn params(method: CmMethod, composition: Composition) -> DirParams {
    DirParams {
        condition: GiLevel::Shadows,
        env_lights: 8,
        shadow_map_size: 256,
        cm: CmParams { method, min_pairs: 50, ..CmParams::default() },
        composition,
        ..DirParams::default()
    }
}

/// A built-in scene at 96×72 and a photograph made from its own L_r through a known camera
/// (a colour matrix, an exposure, gamma 2.2), a gradient where nothing is modelled, and a few
/// saturated pixels.
fn scene_and_photo(r: &DirRenderer) -> (Scene, Image) {
    let scene = colourful_scene();
    let first = r
        .render(&scene, &Image::filled(96, 72, Vec3::splat(0.5)), &params(CmMethod::Off, Composition::Additive))
        .unwrap();
    let m = glam::Mat3::from_cols_array_2d(&[[0.7, 0.05, 0.02], [0.06, 0.65, 0.05], [0.02, 0.04, 0.55]]);
    let mut photo = Image::new(96, 72);
    for i in 0..photo.pixels.len() {
        photo.pixels[i] = match first.flags[i] {
            1 => gamma_encode(m * first.l_r.pixels[i] * 3.0),
            _ => Vec3::new((i % 96) as f32 / 95.0, (i / 96) as f32 / 71.0, 0.3),
        };
    }
    (scene, photo)
}

/// A warm floor, a red and a blue real box, a green-white virtual box, a spot light.
fn colourful_scene() -> Scene {
    TestScene::new("cm-test")
        .size(96, 72)
        .materials(&[
            ("floor", "[0.6, 0.5, 0.3]"),
            ("red", "[0.8, 0.1, 0.08]"),
            ("blue", "[0.1, 0.2, 0.7]"),
            ("mint", "[0.5, 0.8, 0.6]"),
        ])
        .objects(
            r#"[[objects]]
name = "red-box"
role = "real"
shape = "box"
size = [0.25, 0.2, 0.25]
translate = [-0.3, 0.1, -0.1]
material = "red"
[[objects]]
name = "blue-box"
role = "real"
shape = "box"
size = [0.25, 0.2, 0.25]
translate = [0.3, 0.1, -0.1]
material = "blue"
[[objects]]
name = "virtual-box"
role = "virtual"
shape = "box"
size = [0.15, 0.15, 0.15]
translate = [0.0, 0.075, 0.1]
material = "mint"
"#,
        )
        .spot_cone(50, 60)
        .build()
}

#[test]
fn every_cm_method_on_the_gpu_agrees_with_the_cpu_reference() {
    let Some(r) = renderer_or_skip() else { return };
    let (scene, photo) = scene_and_photo(r);
    for method in CmMethod::ALL {
        for composition in [Composition::Additive, Composition::Scaled] {
            let p = params(method, composition);
            let gpu = r.render(&scene, &photo, &p).unwrap();
            let input = CmInput {
                width: 96,
                height: 72,
                l_rv: &gpu.l_rv.pixels,
                l_r: &gpu.l_r.pixels,
                flags: &gpu.flags,
                photo: &photo.pixels,
            };
            let cpu = cpu_frame(&input, &p.cm, p.exposure, composition, &mut CmState::default());
            assert_eq!(
                cpu.report.fallback.is_some(),
                gpu.report.cm.fallback.is_some(),
                "{method:?}: CPU {:?} GPU {:?}",
                cpu.report,
                gpu.report.cm
            );
            let warned = |w: &Option<crate::cm::statistics::RatioWarning>| {
                w.as_ref().map(|w| w.channels.iter().map(|c| c.channel).collect::<Vec<_>>())
            };
            assert_eq!(warned(&cpu.report.warning), warned(&gpu.report.cm.warning), "{method:?}: the ratio warnings");
            let cpu_composite = Image { width: 96, height: 72, pixels: cpu.composite.clone() };
            eprintln!(
                "{method:?} {composition:?}: mapping CPU {:?} GPU {:?}",
                cpu.report.mapping, gpu.report.cm.mapping
            );
            assert_images_match(
                &format!("cm-{}-{composition:?}-gpu-against-cpu", method.name()),
                &gpu.composite,
                &cpu_composite,
                1e-3,
                0.0,
            );
            assert!(gpu.composite.pixels.iter().all(|v| v.is_finite()));
            let names: Vec<&str> = gpu.report.passes.iter().map(|p| p.pass.as_str()).collect();
            assert!(
                names.contains(&"composition") && names.iter().any(|n| n.starts_with(&format!("cm {}", method.name()))),
                "{names:?}"
            );
            if method != CmMethod::Off {
                assert!(gpu.report.cm.pairs > 0, "{method:?}: {:?}", gpu.report.cm);
            }
        }
    }
}

#[test]
fn rohmer_on_the_gpu_recovers_the_known_camera_matrix() {
    let Some(r) = renderer_or_skip() else { return };
    let (scene, photo) = scene_and_photo(r);
    let gpu = r.render(&scene, &photo, &params(CmMethod::Rohmer, Composition::Additive)).unwrap();
    let crate::cm::Mapping::Linear { rows } = gpu.report.cm.mapping else { panic!("{:?}", gpu.report.cm) };
    let want = [[2.1, 0.18, 0.06], [0.15, 1.95, 0.12], [0.06, 0.15, 1.65]];
    for k in 0..3 {
        for j in 0..3 {
            assert!(
                (rows[k][j] - want[k][j]).abs() < 0.1,
                "C⁻¹ = {rows:?} against {want:?} ({:?}, {} pairs)",
                gpu.report.cm.fallback,
                gpu.report.cm.pairs
            );
        }
    }
}

#[test]
fn without_virtual_objects_every_method_leaves_the_photograph_exact() {
    let Some(r) = renderer_or_skip() else { return };
    let (mut scene, photo) = scene_and_photo(r);
    scene.objects.retain(|o| o.role == Role::Real);
    for method in CmMethod::ALL {
        for composition in [Composition::Additive, Composition::Scaled] {
            let out = r.render(&scene, &photo, &params(method, composition)).unwrap();
            let name = format!("cm-{}-{composition:?}-without-virtual-objects", method.name());
            assert_images_match(&name, &out.composite, &photo, 0.0, 0.0);
        }
    }
}

#[test]
fn the_sample_state_carries_across_frames_on_the_gpu() {
    let Some(r) = renderer_or_skip() else { return };
    let (scene, photo) = scene_and_photo(r);
    let p = params(CmMethod::Samples, Composition::Additive);
    let mut state = LiveState::default();
    let first = r.render_with_state(&scene, &photo, &p, &mut state).unwrap();
    let darker = Image { pixels: photo.pixels.iter().map(|c| *c * 0.6).collect(), ..photo.clone() };
    let alone = r.render(&scene, &darker, &p).unwrap();
    let second = r.render_with_state(&scene, &darker, &p, &mut state).unwrap();
    let rows = |g: &GpuRender| match g.report.cm.mapping {
        crate::cm::Mapping::Affine { rows } => rows,
        ref m => panic!("{m:?}"),
    };
    let (a, b, c) = (rows(&first), rows(&alone), rows(&second));
    for k in 0..3 {
        for j in 0..4 {
            assert!((c[k][j] - (0.3 * b[k][j] + 0.7 * a[k][j])).abs() < 1e-5, "{c:?}");
        }
    }
    assert_eq!(state.cm.frames, 2);
}

/// Issue 17's colour-mapping defect: on every built-in survey scene, the virtual objects' mean
/// luminance under each cm method against the ground truth's, through the scene's own camera
/// (64×48, the stimulus's gi condition). `samples` rendered them at 0.16–0.73 of the ground
/// truth and `statistics` at 0.42–0.70 while the composition subtracted τ(L_r = 0) — the
/// mapping's offset — from every virtual pixel. Stated factors: no method below 0.45 (`off`,
/// the plain Reinhard curve, is at 0.52–0.64 here), and the two methods that fit the camera,
/// `statistics` and `samples`, not below 0.55 (here 0.62–1.19; survey-3's 0.62 is a mapping
/// with a slope of 1.1 and no offset, faithful to the camera, not this defect).
#[test]
fn no_cm_method_darkens_the_virtual_objects_of_a_survey_scene() {
    use crate::reference::{ReferenceParams, render_reference};
    use crate::stimulus::{Factors, RenderKnobs, render_condition};
    let Some(r) = renderer_or_skip() else { return };
    let knobs = |cm| RenderKnobs {
        vpls: 64,
        ism_size: 64,
        ism_points: 512,
        ism_splatting: crate::gpu::ism::IsmSplatting::default(),
        bounces: 1,
        bounce_candidates: 1024,
        composition: Composition::Additive,
        cm: Some(cm),
        ca_source: crate::ca::ParamSource::Scene,
        caustic_map_size: 256,
    };
    let factors = Factors { gi: GiLevel::Gi, coherent: None, cm: false, ca: false, caustics: true };
    let linear_luminance = |image: &Image, mask: &[f32]| {
        let linear = image.srgb_to_linear();
        let (sum, count) = linear
            .pixels
            .iter()
            .zip(mask)
            .filter(|(_, m)| **m > 0.5)
            .fold((0.0f64, 0usize), |(s, n), (c, _)| (s + crate::math::luminance(*c) as f64, n + 1));
        sum / count.max(1) as f64
    };
    let mut failures = Vec::new();
    for name in crate::builtin::names().filter(|name| name.starts_with("survey-")) {
        let scene = crate::scene::load(name).unwrap().with_size(64, 48);
        let truth =
            render_reference(&scene, &ReferenceParams { spp: 8, ..ReferenceParams::default() }, &|_, _| {}).unwrap();
        let mask = &truth.virtual_mask.values;
        assert!(mask.iter().any(|m| *m > 0.5), "{name} shows no virtual object at 64×48");
        let truth_luminance = linear_luminance(&truth.ground_truth, mask);
        let mut line = format!("{name}:");
        for method in CmMethod::ALL {
            let frame = render_condition(r, &scene, &truth.photo, &factors, &knobs(method)).unwrap().frame;
            let ratio = linear_luminance(&frame.composite, mask) / truth_luminance;
            line += &format!(" {} {ratio:.2}", method.name());
            let floor = if matches!(method, CmMethod::Statistics | CmMethod::Samples) { 0.55 } else { 0.45 };
            if !(ratio >= floor) {
                failures.push(format!("{name} {}: {ratio:.2} of the ground truth (floor {floor})", method.name()));
            }
        }
        eprintln!("{line}");
    }
    assert!(failures.is_empty(), "virtual objects darkened: {failures:?}");
}
