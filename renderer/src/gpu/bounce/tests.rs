//! Tests of the multiple-bounce light source: slot linking on the CPU, and on the GPU (lavapipe
//! on machines without a GPU) the cone search, the carried flux and the path flags of eqs.
//! 5.9–5.10.

use super::*;

fn vpl(flux: f32, normal: Vec3) -> GpuVpl {
    GpuVpl {
        position: [0.0, 0.0, 0.0, 1.0],
        normal: [normal.x, normal.y, normal.z, 0.0],
        flux: [flux, flux, flux, 0.0],
    }
}

#[test]
fn slots_follow_the_sources_flux_and_directions_the_cosine_lobe() {
    let sources = [vpl(1.0, Vec3::Y), vpl(3.0, Vec3::X), vpl(0.0, Vec3::Z)];
    let linked = link_slots(&sources, 4000, 5);
    assert_eq!(linked.len(), 4000);
    let count = |i: usize| linked.iter().filter(|s| s.source == i).count();
    assert_eq!((count(0), count(1), count(2)), (1000, 3000, 0));
    // a cosine lobe around the normal: E[cos θ] = 2/3, E[cos² θ] = 1/2, nothing below
    for (i, n) in [(0, Vec3::Y), (1, Vec3::X)] {
        let cos: Vec<f64> = linked.iter().filter(|s| s.source == i).map(|s| s.direction.dot(n) as f64).collect();
        assert!(cos.iter().all(|c| *c >= 0.0));
        let mean = cos.iter().sum::<f64>() / cos.len() as f64;
        let mean2 = cos.iter().map(|c| c * c).sum::<f64>() / cos.len() as f64;
        assert!((mean - 2.0 / 3.0).abs() < 0.01 && (mean2 - 0.5).abs() < 0.01, "{mean} {mean2}");
        // and spread around it: the mean tangential component vanishes
        let mean_dir: Vec3 =
            linked.iter().filter(|s| s.source == i).map(|s| s.direction).sum::<Vec3>() / cos.len() as f32;
        assert!((mean_dir - n * mean_dir.dot(n)).length() < 0.02, "{mean_dir}");
    }
    assert!(link_slots(&[vpl(0.0, Vec3::Y)], 16, 1).is_empty(), "no flux, no slots");
    assert!(link_slots(&[vpl(f32::NAN, Vec3::Y)], 16, 1).is_empty(), "NaN flux is no flux");
}

/// The bounce passes on the GPU, against closed-form distances and fluxes.
mod on_gpu {
    use super::*;
    use crate::gpu::mesh;
    use crate::test_support::{box_object, renderer_or_skip, scene_with};

    /// A closed virtual box of 0.6 m (albedo 0.8) standing on the real floor of the test scene.
    fn room() -> String {
        box_object("room", "virtual", [0.6, 0.6, 0.6], [0.0, 0.3, 0.0], "white")
    }

    fn source(at: Vec3, normal: Vec3, path_real: bool, ir: bool) -> GpuVpl {
        GpuVpl {
            position: [at.x, at.y, at.z, path_real as u8 as f32],
            normal: [normal.x, normal.y, normal.z, ir as u8 as f32],
            flux: [1.0, 1.0, 1.0, 0.0],
        }
    }

    fn search(candidates: u32) -> BounceSearch {
        BounceSearch { candidates, cone_degrees: 5.0, seed: 3 }
    }

    /// Inside the closed box every direction hits a wall at a distance known in closed form; the
    /// nearest candidate in the 5° cone must be found in almost every slot (measured 97 % with
    /// 16384 candidates), close to that distance (the analytic ray cast is the reference).
    #[test]
    fn the_nearest_point_in_the_cone_is_where_a_ray_would_hit() {
        let Some(r) = renderer_or_skip() else { return };
        let scene = scene_with(&room());
        let mesh = mesh::build(&scene);
        let bounce_scene = BounceScene::new(&r.ctx, &mesh).unwrap();
        let origin = Vec3::new(0.05, 0.3, -0.1);
        let sources = [source(origin, Vec3::Y, false, false)];
        let linked = link_slots(&sources, 512, 9);
        let slots: Vec<SlotGpu> = linked
            .iter()
            .map(|s| SlotGpu {
                origin: [origin.x, origin.y, origin.z, 0.0],
                normal: [0.0, 1.0, 0.0, 0.0],
                direction: [s.direction.x, s.direction.y, s.direction.z, 0.0],
            })
            .collect();
        let hits = r.bounce.nearest(&r.ctx, &bounce_scene, &slots, &search(16384), mesh.bounds_radius);
        let mut errors = Vec::new();
        for (j, s) in linked.iter().enumerate() {
            let d = s.direction;
            // the ray from the origin to the box's walls: x, z in ±0.3, y in [0, 0.6]
            let t = |o: f32, d: f32, lo: f32, hi: f32| {
                if d > 0.0 {
                    (hi - o) / d
                } else if d < 0.0 {
                    (lo - o) / d
                } else {
                    f32::INFINITY
                }
            };
            let ray = t(origin.x, d.x, -0.3, 0.3).min(t(origin.y, d.y, 0.0, 0.6)).min(t(origin.z, d.z, -0.3, 0.3));
            let found = hits[8 * j];
            if found >= 0.0 {
                errors.push(((found - ray) / ray).abs());
                assert!(
                    (hits[8 * j + 1] as u32) >= mesh.real_count / 3,
                    "slot {j}: the box is virtual, the hit is not"
                );
                assert!(hits[8 * j + 4] < 0.0 || hits[8 * j + 4] > found, "the real hit (floor) lies beyond the box");
            }
        }
        let found = errors.len() as f64 / linked.len() as f64;
        errors.sort_by(f32::total_cmp);
        let (median, p95) = (errors[errors.len() / 2], errors[errors.len() * 95 / 100]);
        eprintln!("found {found:.3}; relative distance error median {median:.4}, p95 {p95:.4}");
        assert!(found > 0.95, "{found}");
        // the nearest point of a 5° cone lies a little short of the ray's hit on an oblique wall:
        // measured median 3 %, p95 8.5 % (tan 5° = 8.7 %)
        assert!(median < 0.05 && p95 < 0.12, "median {median} p95 {p95}");
    }

    /// All the light of a VPL inside the closed box reaches its walls: the next bounce carries
    /// albedo · Φ (0.8), less the slots that found no candidate.
    #[test]
    fn in_a_closed_box_the_bounce_carries_albedo_times_the_flux() {
        let Some(r) = renderer_or_skip() else { return };
        let scene = scene_with(&room());
        let mesh = mesh::build(&scene);
        let bounce_scene = BounceScene::new(&r.ctx, &mesh).unwrap();
        let sources = [
            source(Vec3::new(0.0, 0.3, 0.0), Vec3::Y, false, false),
            source(Vec3::new(0.1, 0.4, 0.0), Vec3::NEG_X, false, false),
        ];
        let (vpls, found, real_only) = r.bounce.spawn(
            &r.ctx,
            &BounceInputs {
                scene: &bounce_scene,
                mesh: &mesh,
                materials: &scene.materials,
                scene_radius: mesh.bounds_radius,
            },
            &sources,
            512,
            &search(16384),
        );
        let flux = crate::gpu::vpl::luminance_flux(&vpls);
        eprintln!("found {found} of 512, flux {flux:.4} of 1.6");
        assert!(found as f64 / 512.0 > 0.95 && real_only == 0);
        assert!((flux / (0.8 * 2.0 * found as f64 / 512.0) - 1.0).abs() < 0.02, "{flux}");
        assert!(vpls.iter().all(|v| v.position[3] == 0.0 && v.normal[3] == 0.0), "a virtual path stays virtual");
        // every new VPL faces into the room (towards its source)
        assert!(vpls.iter().all(|v| {
            let p = Vec3::from_slice(&v.position[..3]);
            let n = Vec3::from_slice(&v.normal[..3]);
            n.dot(Vec3::new(0.0, 0.3, 0.0) - p) > 0.0
        }));
    }

    /// Eqs. 5.9–5.10 and the real-only continuation: a real path (x̄ = 1) from the real floor
    /// that meets a virtual box turns virtual (x̄ = 0) and also continues, for L_r only (ir = 1),
    /// to the real ceiling behind it; a path that meets the ceiling directly stays real; an
    /// ir = 1 source spawns only on real surfaces.
    #[test]
    fn path_flags_follow_equations_5_9_and_5_10() {
        let Some(r) = renderer_or_skip() else { return };
        let objects = box_object("ceiling", "real", [3.0, 0.02, 3.0], [0.0, 1.0, 0.0], "white")
            + &box_object("blocker", "virtual", [0.4, 0.05, 0.4], [0.0, 0.5, 0.0], "red");
        let scene = scene_with(&objects);
        let mesh = mesh::build(&scene);
        let bounce_scene = BounceScene::new(&r.ctx, &mesh).unwrap();
        let real_source = [source(Vec3::ZERO, Vec3::Y, true, false)];
        let (vpls, found, real_only) = r.bounce.spawn(
            &r.ctx,
            &BounceInputs {
                scene: &bounce_scene,
                mesh: &mesh,
                materials: &scene.materials,
                scene_radius: mesh.bounds_radius,
            },
            &real_source,
            512,
            &search(16384),
        );
        let y = |v: &GpuVpl| v.position[1];
        let on_blocker = vpls.iter().filter(|v| (0.45..0.55).contains(&y(v))).count();
        eprintln!(
            "found {found}, {} VPLs, {on_blocker} on the blocker, {real_only} real-only continuations",
            vpls.len()
        );
        // the 3 m ceiling 1 m up subtends about 70 % of the cosine lobe: the rest escapes
        assert!(found > 300 && on_blocker > 50, "{found} {on_blocker}");
        for v in &vpls {
            if (0.45..0.55).contains(&y(v)) {
                assert_eq!(
                    (v.position[3], v.normal[3]),
                    (0.0, 0.0),
                    "on the virtual blocker: virtual path, lights L_rv"
                );
            } else {
                // the slab's far face may win where its near face had no candidate in the cone:
                // no visibility test, as in the thesis
                assert!((0.98..1.02).contains(&y(v)), "on the ceiling: {v:?}");
                assert_eq!(v.position[3], 1.0, "on the real ceiling: a real path");
            }
        }
        let continuations = vpls.iter().filter(|v| v.normal[3] == 1.0).count();
        assert_eq!(continuations, real_only as usize);
        assert!(real_only as f64 > 0.9 * on_blocker as f64, "{real_only} {on_blocker}");
        // the red blocker reflects red; the white ceiling white
        assert!(vpls.iter().filter(|v| v.position[3] == 0.0).all(|v| v.flux[0] > 10.0 * v.flux[1]));
        // an ir = 1 source (a real surface behind a virtual one) only reaches real surfaces
        let (vpls, _, _) = r.bounce.spawn(
            &r.ctx,
            &BounceInputs {
                scene: &bounce_scene,
                mesh: &mesh,
                materials: &scene.materials,
                scene_radius: mesh.bounds_radius,
            },
            &[source(Vec3::ZERO, Vec3::Y, true, true)],
            256,
            &search(16384),
        );
        assert!(
            !vpls.is_empty() && vpls.iter().all(|v| v.position[3] == 1.0 && v.normal[3] == 1.0 && y(v) > 0.9),
            "{vpls:?}"
        );
    }

    /// Light leaving the scene makes no VPL.
    #[test]
    fn light_that_leaves_the_scene_spawns_nothing() {
        let Some(r) = renderer_or_skip() else { return };
        let scene = scene_with("");
        let mesh = mesh::build(&scene);
        let bounce_scene = BounceScene::new(&r.ctx, &mesh).unwrap();
        let (vpls, found, _) = r.bounce.spawn(
            &r.ctx,
            &BounceInputs {
                scene: &bounce_scene,
                mesh: &mesh,
                materials: &scene.materials,
                scene_radius: mesh.bounds_radius,
            },
            &[source(Vec3::new(0.0, 0.01, 0.0), Vec3::Y, true, false)],
            128,
            &search(4096),
        );
        assert_eq!((vpls.len(), found), (0, 0));
    }
}
