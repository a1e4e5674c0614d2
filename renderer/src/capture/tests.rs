//! Tests of the simulated capture: a real floor and box captured noise-free and with the
//! sensor's noise, a box that moves away between poses, a sensor that sees nothing.

use super::*;
use crate::test_support::{capture_setup, scene_from_toml};

/// A real floor and a real box under a real spot light, camera 2 m away.
const ROOM: &str = r#"
[camera]
width = 64
height = 48
fov_y_deg = 50.0
position = [0.0, 1.2, 2.2]
look_at = [0.0, 0.3, 0.0]

[materials.floor]
albedo = 0.6

[materials.box]
albedo = [0.7, 0.5, 0.2]

[[objects]]
name = "floor"
role = "real"
shape = "quad"
size = [4.0, 4.0]
material = "floor"

[[objects]]
name = "box"
role = "real"
shape = "box"
size = [0.5, 0.4, 0.5]
translate = [0.0, 0.2, 0.0]
material = "box"

[[lights]]
name = "spot"
kind = "spot"
position = [0.5, 2.5, 1.0]
target = [0.0, 0.0, 0.0]
intensity = 8.0
"#;

/// The scene and its real world.
fn scene(text: &str) -> (Scene, World) {
    let scene = scene_from_toml(text, "room");
    let (real, _) = capture_setup(&scene, 1, 2, 1 << 14);
    (scene, real)
}

fn params((scene, _): &(Scene, World), poses: usize, noise: f32) -> CaptureParams {
    let (_, mut p) = capture_setup(scene, poses, 2, 1 << 14);
    p.sensor.noise = noise;
    p
}

#[test]
fn noise_free_capture_recovers_the_true_geometry() {
    let room = scene(ROOM);
    let cap = capture(&room.1, &params(&room, 3, 0.0), |_, _| {});
    let r = &cap.report;
    assert_eq!(r.poses, 3);
    assert!(r.measured > 3 * 160 * 120 / 6, "{r:?}");
    // nothing moved, so nothing should be seen through; a sample on the box's silhouette whose
    // neighbourhood's planes are all the floor's behind it can be (one in 11 000 here)
    assert!(r.removed * 1000 <= r.samples, "{r:?}");
    assert!(r.fitted > r.depth_pixels / 2, "{r:?}");
    // planes fitted across the box's edges tilt a few pixels' normals; most are exact
    assert!(r.normal_error_deg.median < 0.1, "{:?}", r.normal_error_deg);
    assert!(r.position_error_mm.median < 0.5, "{:?}", r.position_error_mm);
    assert!(r.stored > 100 && r.stored <= r.inserted, "{r:?}");
    // stored samples lie on the floor or the box, with their colour from the camera; a few
    // where the floor meets the box take the other face's plane (both are within the 0.1 m
    // discontinuity threshold of each other at the crease), as in the paper
    let mut off = 0;
    for s in cap.grid.samples() {
        let on_floor = s.position.y.abs() < 0.005;
        let on_box = s.position.y < 0.405 && s.position.x.abs() < 0.255 && s.position.z.abs() < 0.255;
        off += usize::from(!(on_floor || on_box));
        assert!(s.colour.is_finite() && s.colour.min_element() >= 0.0);
    }
    assert!(off * 100 < r.stored, "{off} of {} stored samples off the surfaces", r.stored);
}

#[test]
fn plane_fits_halve_the_sensor_noise_and_the_normals_follow_the_surfaces() {
    let room = scene(ROOM);
    let cap = capture(&room.1, &params(&room, 2, 0.0016), |_, _| {});
    let r = &cap.report;
    // σ = 1.6 mm × z² at about 2.4 m: ~9 mm raw; the fit over ~10 neighbours averages it down
    assert!(r.raw_position_error_mm.median > 4.0, "{:?}", r.raw_position_error_mm);
    assert!(
        r.position_error_mm.median < 0.6 * r.raw_position_error_mm.median,
        "refined {:?} raw {:?}",
        r.position_error_mm,
        r.raw_position_error_mm
    );
    assert!(r.normal_error_deg.median < 8.0, "{:?}", r.normal_error_deg);
}

#[test]
fn a_real_object_that_moves_away_is_removed_from_the_grid() {
    let with_box = scene(ROOM);
    let (_, without) = scene(&ROOM.replace("translate = [0.0, 0.2, 0.0]", "translate = [30.0, 0.2, 0.0]"));
    let (a, b) = (&with_box.1, &without);
    let mut p = params(&with_box, 2, 0.0);
    p.poses[1] = p.poses[0];
    let on_box = |s: &EnvironmentSample| s.position.y > 0.05;
    let before = capture_worlds(&[a], &CaptureParams { poses: vec![p.poses[0]], ..p.clone() }, |_, _| {});
    assert!(before.grid.samples().filter(|s| on_box(s)).count() > 50);
    let after = capture_worlds(&[a, b], &p, |_, _| {});
    assert!(after.report.removed > 50, "{:?}", after.report);
    let left: Vec<Vec3> = after.grid.samples().filter(|s| on_box(s)).map(|s| s.position).collect();
    assert!(left.is_empty(), "{left:?}");
    // and the floor the box hid is there now
    assert!(after.grid.samples().filter(|s| s.position.x.abs() < 0.2 && s.position.z.abs() < 0.2).count() > 5);
}

#[test]
fn a_sensor_that_sees_nothing_makes_an_empty_capture() {
    let room = scene(ROOM);
    let mut p = params(&room, 1, 0.0);
    p.sensor.far = 0.5; // everything is farther
    let cap = capture(&room.1, &p, |_, _| {});
    assert_eq!(cap.report.measured, 0);
    assert_eq!(cap.report.stored, 0);
    assert_eq!(cap.report.empty, cap.report.depth_pixels);
    assert_eq!(cap.report.position_error_mm.count, 0);
    assert_eq!(cap.report.position_error_mm.median, 0.0);
}
