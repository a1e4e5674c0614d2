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
