//! Invariants of mirrors and glass in the GPU pipeline (thesis 5.3, [`super::specular`]), on
//! the GPU adapter (lavapipe without a GPU) at small resolution.

use super::*;
use crate::scene::Role;
use crate::test_support::{renderer_or_skip, scene_from_toml};

fn spot_scene() -> Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/reference/specular/spot.toml");
    Scene::load(&path).unwrap()
}

/// A photograph unlike any rendering, in which every pixel tells where it is: red is x / w,
/// green y / h.
fn coordinate_photo(width: u32, height: u32) -> Image {
    let mut photo = Image::new(width, height);
    for (i, p) in photo.pixels.iter_mut().enumerate() {
        let (x, y) = (i as u32 % width, i as u32 / width);
        *p = Vec3::new((x as f32 + 0.5) / width as f32, (y as f32 + 0.5) / height as f32, 0.5);
    }
    photo
}

#[test]
fn a_scene_without_mirrors_or_glass_runs_no_specular_pass() {
    let Some(r) = renderer_or_skip() else { return };
    let mut scene = spot_scene();
    scene.objects.retain(|o| scene.materials[o.material].delta.is_none());
    let photo = crate::test_support::grey_photo(&scene);
    let out = r.render(&scene, &photo, &DirParams { vpls: 16, ism_size: 0, ..Default::default() }).unwrap();
    assert!(out.report.specular.is_none());
    let names: Vec<&str> = out.report.passes.iter().map(|p| p.pass.as_str()).collect();
    assert!(!names.iter().any(|n| n.contains("impostor") || n.contains("hits") || n.contains("glass")), "{names:?}");
}

#[test]
fn a_real_mirror_and_real_glass_without_virtual_objects_leave_the_photograph_exact() {
    let Some(r) = renderer_or_skip() else { return };
    let mut scene = spot_scene();
    for object in &mut scene.objects {
        object.role = Role::Real;
    }
    let photo = coordinate_photo(scene.camera.width, scene.camera.height);
    for condition in [GiLevel::None, GiLevel::Shadows, GiLevel::Gi] {
        let params = DirParams { condition, vpls: 32, ..Default::default() };
        let out = r.render(&scene, &photo, &params).unwrap();
        let report = out.report.specular.as_ref().expect("the specular passes ran");
        assert_eq!(report.objects, ["glass-sphere", "mirror"]);
        assert!(report.pixels > 500 && report.rays > report.pixels, "{report:?}");
        for (k, (a, b)) in out.composite.pixels.iter().zip(&photo.pixels).enumerate() {
            assert_eq!(a, b, "{condition:?}: pixel {k} of the composite differs from the photograph");
        }
    }
}

/// A virtual mirror standing on a real floor reflects the floor in front of it, which the
/// camera sees: each mirror pixel shows the photograph's pixel where the reflected ray meets
/// the floor (back-projection, eq. 5.24), computed here analytically. With reflectance 1 and
/// the `none` condition (no differential light on the floor) nothing is added to it.
#[test]
fn a_virtual_mirror_shows_the_photograph_where_its_reflection_is_seen_by_the_camera() {
    let Some(r) = renderer_or_skip() else { return };
    let toml = r#"
        [camera]
        width = 96
        height = 72
        fov_y_deg = 45
        position = [0.0, 1.2, 2.0]
        look_at = [0.0, 0.3, -0.3]
        [materials.floor]
        albedo = 0.6
        [materials.mirror]
        kind = "mirror"
        [[objects]]
        name = "floor"
        role = "real"
        shape = "quad"
        size = [6.0, 6.0]
        material = "floor"
        [[objects]]
        name = "mirror"
        role = "virtual"
        shape = "quad"
        size = [1.2, 0.8]
        rotate_deg = [120.0, 0.0, 0.0]
        translate = [0.0, 0.45, -0.6]
        material = "mirror"
        [[lights]]
        name = "spot"
        kind = "spot"
        position = [0.0, 2.0, 1.5]
        target = [0.0, 0.0, 0.0]
        inner_deg = 60.0
        outer_deg = 70.0
        intensity = 4.0
    "#;
    let scene = scene_from_toml(toml, "mirror");
    let (width, height) = (scene.camera.width, scene.camera.height);
    let photo = coordinate_photo(width, height);
    let params = DirParams { condition: GiLevel::None, ..Default::default() };
    let out = r.render(&scene, &photo, &params).unwrap();
    let report = out.report.specular.clone().unwrap();
    // the mirror's plane from its mesh
    let mesh = mesh::build(&scene);
    let mirror = &mesh.vertices[mesh.specular[0].range.start as usize..][..3];
    let [a, b, c] = [0, 1, 2].map(|k| Vec3::from_array(mirror[k].position));
    let normal = (b - a).cross(c - a).normalize();
    let (mut checked, mut agree) = (0, 0);
    for y in 0..height {
        for x in 0..width {
            let k = (y * width + x) as usize;
            if out.flags[k] != crate::surface::VIRTUAL {
                continue;
            }
            let ray = scene.camera.ray(x as f32 + 0.5, y as f32 + 0.5);
            let t = (a - ray.origin).dot(normal) / ray.dir.dot(normal);
            let hit = ray.origin + t * ray.dir;
            let reflected = ray.dir - 2.0 * ray.dir.dot(normal) * normal;
            if reflected.y >= -1e-3 {
                continue;
            }
            let floor = hit + reflected * (-hit.y / reflected.y);
            let Some((u, v)) = scene.camera.project(floor) else { continue };
            // well inside the image and away from the mirror itself (hidden there)
            if u < 2.0 || v < 2.0 || u > width as f32 - 2.0 || v > height as f32 - 2.0 {
                continue;
            }
            let q = (v as usize) * width as usize + u as usize;
            if out.flags[q] != crate::surface::REAL {
                continue;
            }
            checked += 1;
            let shown = out.composite.pixels[k];
            let (su, sv) = (shown.x * width as f32, shown.y * height as f32);
            if (su - u).abs() <= 1.5 && (sv - v).abs() <= 1.5 {
                agree += 1;
            }
        }
    }
    eprintln!("{agree} of {checked} mirror pixels agree; {report:?}");
    assert!(checked > 200, "too few mirror pixels see the visible floor: {checked} ({report:?})");
    assert!(
        agree as f32 >= 0.97 * checked as f32,
        "{agree} of {checked} mirror pixels show the photograph where their reflection meets the floor ({report:?})"
    );
    assert!(report.back_projected as f32 >= 0.9 * checked as f32, "{report:?}");
}

/// A virtual glass sphere: its pixels are the reflected and refracted scene (weights by
/// Fresnel, sum below one), every ray weighted and accounted for, and the sphere's own
/// shadow darkens the floor as any virtual object's.
#[test]
fn a_virtual_glass_sphere_is_traced_through_two_interfaces_and_accounts_for_every_ray() {
    let Some(r) = renderer_or_skip() else { return };
    let mut scene = spot_scene();
    scene.objects.retain(|o| o.name != "mirror");
    let photo = coordinate_photo(scene.camera.width, scene.camera.height);
    let out = r.render(&scene, &photo, &DirParams { condition: GiLevel::Shadows, ..Default::default() }).unwrap();
    let report = out.report.specular.clone().unwrap();
    assert_eq!(report.objects, ["glass-sphere"]);
    // glass: a reflected and a refracted ray per pixel
    assert_eq!(report.rays, 2 * report.pixels, "{report:?}");
    assert_eq!(report.rays, report.back_projected + report.rendered + report.missed, "{report:?}");
    assert!(report.rendered > 0 && report.missed > 0, "{report:?}");
    let names: Vec<&str> = out.report.passes.iter().map(|p| p.pass.as_str()).collect();
    assert!(names.iter().any(|n| n.starts_with("back faces of glass")), "{names:?}");
    assert!(out.composite.pixels.iter().all(|p| p.is_finite()));
}

/// A virtual mirror lying on a real floor under a spot light throws the light's mirror image
/// onto a real wall: there the caustic map's irradiance must be the mirrored light's,
/// E = R I cos θ / d² from the light's reflection in the mirror's plane (analytic), inside
/// the reflected patch. The caustic is what L_rv gains over a frame with caustics off.
#[test]
fn a_virtual_mirror_casts_the_irradiance_of_the_mirrored_light() {
    let Some(r) = renderer_or_skip() else { return };
    let scene = mirror_caustic_scene();
    let (width, height) = (scene.camera.width, scene.camera.height);
    let photo = crate::test_support::grey_photo(&scene);
    let render = |caustic_map_size| {
        let specular = specular::SpecularParams { caustic_map_size, ..Default::default() };
        r.render(&scene, &photo, &DirParams { condition: GiLevel::Shadows, specular, ..Default::default() }).unwrap()
    };
    let with = render(256);
    let without = render(0);
    let caustics = with.report.specular.as_ref().and_then(|s| s.caustics.clone()).expect("caustic maps ran");
    assert_eq!(caustics.maps, ["spot → mirror"]);
    assert!(caustics.photons > 10_000 && caustics.splatted > 0, "{caustics:?}");
    let skipped = without.report.specular.as_ref().unwrap().caustics_skipped.clone();
    assert!(skipped.is_some_and(|why| why.contains("caustic_map_size is 0")));
    let spot = &scene.spots[0];
    let reflectance = match scene.materials.iter().find_map(|m| m.delta) {
        Some(crate::material::DeltaBsdf::Mirror { reflectance }) => reflectance.x,
        other => panic!("not a mirror: {other:?}"),
    };
    let mesh = mesh::build(&scene);
    let y_mirror = mesh.vertices[mesh.specular[0].range.start as usize].position[1];
    let mirrored = Vec3::new(spot.position.x, 2.0 * y_mirror - spot.position.y, spot.position.z);
    let (mut checked, mut within, mut ratios) = (0, 0, Vec::new());
    for y in 0..height {
        for x in 0..width {
            let k = (y * width + x) as usize;
            let ray = scene.camera.ray(x as f32 + 0.5, y as f32 + 0.5);
            if ray.dir.z >= 0.0 {
                continue;
            }
            let wall = ray.origin + ray.dir * ((-1.0 - ray.origin.z) / ray.dir.z);
            if wall.y < 0.05 || out_of(wall.x, 1.9) {
                continue;
            }
            // where the mirrored light's ray to this wall point crosses the mirror's plane:
            // well inside the mirror (the splat blurs the patch's edge)
            let to = wall - mirrored;
            let m = mirrored + to * ((y_mirror - mirrored.y) / to.y);
            if out_of(m.x, 0.3 * 0.7) || out_of(m.z, 0.3 * 0.7) {
                continue;
            }
            let d2 = to.length_squared();
            let cos_wall = (-to.normalize()).dot(Vec3::Z).abs();
            let expected = reflectance * spot.intensity.x * cos_wall / d2 * 0.5 / std::f32::consts::PI;
            let got = with.l_rv.pixels[k].x - without.l_rv.pixels[k].x;
            checked += 1;
            ratios.push(got / expected);
            if (got / expected - 1.0).abs() < 0.15 {
                within += 1;
            }
        }
    }
    ratios.sort_by(f32::total_cmp);
    let median = ratios.get(ratios.len() / 2).copied().unwrap_or(f32::NAN);
    eprintln!("{within} of {checked} wall pixels within 15 %; median ratio {median}; {caustics:?}");
    assert!(checked > 150, "too few wall pixels in the reflected patch: {checked}");
    assert!((median - 1.0).abs() < 0.05, "median caustic / analytic irradiance {median}");
    assert!(within as f32 >= 0.9 * checked as f32, "{within} of {checked} within 15 % (median ratio {median})");
}

fn out_of(value: f32, half: f32) -> bool {
    value.abs() > half
}

/// A virtual mirror lying on a real floor, a spot light above that it reflects onto a real wall.
fn mirror_caustic_scene() -> Scene {
    let toml = r#"
        [camera]
        width = 96
        height = 72
        fov_y_deg = 50
        position = [0.0, 0.9, 2.0]
        look_at = [0.0, 0.8, -1.0]
        [materials.white]
        albedo = 0.5
        [materials.mirror]
        kind = "mirror"
        [[objects]]
        name = "floor"
        role = "real"
        shape = "quad"
        size = [4.0, 4.0]
        material = "white"
        [[objects]]
        name = "wall"
        role = "real"
        shape = "quad"
        size = [4.0, 3.0]
        rotate_deg = [90.0, 0.0, 0.0]
        translate = [0.0, 1.5, -1.0]
        material = "white"
        [[objects]]
        name = "mirror"
        role = "virtual"
        shape = "quad"
        size = [0.6, 0.6]
        translate = [0.0, 0.01, 0.0]
        material = "mirror"
        [[lights]]
        name = "spot"
        kind = "spot"
        position = [0.0, 1.0, 1.0]
        target = [0.0, 0.01, 0.0]
        inner_deg = 40.0
        outer_deg = 40.0
        intensity = 4.0
    "#;
    scene_from_toml(toml, "mirror-caustic")
}

/// Reflected VPLs (Figure 5.23): with gi, VPLs are also drawn where the mirror's caustic lands,
/// and together they carry the flux the wall reflects of it, albedo × R × I × the mirror's
/// solid angle seen from the light (integrated here over the mirror).
#[test]
fn the_caustics_reflected_vpls_carry_the_flux_the_wall_reflects() {
    let Some(r) = renderer_or_skip() else { return };
    let scene = mirror_caustic_scene();
    let photo = crate::test_support::grey_photo(&scene);
    let out = r.render(&scene, &photo, &DirParams { vpls: 256, bounces: 1, ..Default::default() }).unwrap();
    let caustic: Vec<_> = out.vpls.iter().filter(|v| v.flux[3] > 0.5).collect();
    let report = out.report.specular.as_ref().and_then(|s| s.caustics.clone()).unwrap();
    assert_eq!(report.vpls, caustic.len());
    assert!(caustic.len() >= 8, "{} reflected VPLs of {}", caustic.len(), out.vpls.len());
    // on the wall (z = -1), not real (the mirror is virtual)
    for v in &caustic {
        assert!((v.position[2] + 1.0).abs() < 0.02 && v.position[3] == 0.0, "{v:?}");
        assert!(v.normal[2] > 0.99, "{v:?}");
    }
    let got: f32 = caustic.iter().map(|v| v.flux[0]).sum();
    let spot = &scene.spots[0];
    let (half, n) = (0.3f32, 200);
    let mut expected = 0.0;
    for i in 0..n {
        for j in 0..n {
            let p = Vec3::new(
                -half + (i as f32 + 0.5) * 2.0 * half / n as f32,
                0.01,
                -half + (j as f32 + 0.5) * 2.0 * half / n as f32,
            );
            let to = p - spot.position;
            let d2 = to.length_squared();
            let cos = (-to.normalize()).dot(Vec3::Y);
            expected += spot.intensity_towards(to.normalize()).x * cos / d2 * (2.0 * half / n as f32).powi(2);
        }
    }
    expected *= 0.5; // the wall's albedo (the mirror's reflectance is 1)
    eprintln!("reflected VPLs: {} carrying {got} W, expected {expected} W", caustic.len());
    assert!((got / expected - 1.0).abs() < 0.1, "reflected VPLs carry {got} W, the wall reflects {expected} W");
}

/// Thesis 5.24's invariant for glass: a virtual glass sphere above a real floor shows, where its
/// refracted ray meets floor the camera sees, the photograph's pixel there (back-projection).
/// The photograph codes each pixel's position (red x / w, green y / h, blue 0.5), the sphere has
/// no absorption and its reflected rays leave a scene without environment, so the composite is
/// k × the photograph's linear colour at the analytic refracted floor point (k the Fresnel
/// transmission, recovered from blue).
#[test]
fn a_virtual_glass_sphere_shows_the_refracted_floor_from_the_photograph() {
    let Some(r) = renderer_or_skip() else { return };
    let toml = r#"
        [camera]
        width = 96
        height = 72
        fov_y_deg = 40
        position = [0.0, 1.2, 1.5]
        look_at = [0.0, 0.5, 0.0]
        [materials.floor]
        albedo = 0.6
        [materials.glass]
        kind = "glass"
        ior = 1.5
        [[objects]]
        name = "floor"
        role = "real"
        shape = "quad"
        size = [6.0, 6.0]
        material = "floor"
        [[objects]]
        name = "ball"
        role = "virtual"
        shape = "sphere"
        radius = 0.15
        translate = [0.0, 0.8, 0.0]
        material = "glass"
        [[lights]]
        name = "spot"
        kind = "spot"
        position = [0.0, 2.0, 0.5]
        target = [0.0, 0.0, 0.0]
        inner_deg = 60.0
        outer_deg = 70.0
        intensity = 2.0
    "#;
    let scene = scene_from_toml(toml, "glass-ball");
    let (width, height) = (scene.camera.width, scene.camera.height);
    let photo = coordinate_photo(width, height);
    let out = r.render(&scene, &photo, &DirParams { condition: GiLevel::None, ..Default::default() }).unwrap();
    let (centre, radius, ior) = (Vec3::new(0.0, 0.8, 0.0), 0.15f32, 1.5f32);
    let sphere_hit = |o: Vec3, d: Vec3, far: bool| {
        let oc = o - centre;
        let b = oc.dot(d);
        let disc = b * b - (oc.length_squared() - radius * radius);
        (disc > 0.0).then(|| o + d * (-b + if far { disc.sqrt() } else { -disc.sqrt() }))
    };
    let refract = |d: Vec3, n: Vec3, eta: f32| {
        let c = -d.dot(n);
        let k = 1.0 - eta * eta * (1.0 - c * c);
        (k >= 0.0).then(|| (eta * d + (eta * c - k.sqrt()) * n).normalize())
    };
    let decode = |c: f32| c.max(0.0).powf(2.2);
    let (mut checked, mut projected, mut agree) = (0, 0, 0);
    for y in 0..height {
        for x in 0..width {
            let k = (y * width + x) as usize;
            let ray = scene.camera.ray(x as f32 + 0.5, y as f32 + 0.5);
            // well inside the silhouette: the tessellated sphere and the analytic one agree there
            // (towards the rim the refraction magnifies a facet's normal error: a tenth of a
            // pixel on the ball moves the floor point by a pixel)
            let oc = ray.origin - centre;
            let b = oc.dot(ray.dir);
            let miss = (oc.length_squared() - b * b).sqrt();
            if miss > 0.55 * radius || out.flags[k] != crate::surface::VIRTUAL {
                continue;
            }
            let Some(p1) = sphere_hit(ray.origin, ray.dir, false) else { continue };
            let n1 = (p1 - centre).normalize();
            let reflected = ray.dir - 2.0 * ray.dir.dot(n1) * n1;
            let Some(t1) = refract(ray.dir, n1, 1.0 / ior) else { continue };
            let Some(p2) = sphere_hit(p1 + t1 * 1e-4, t1, true) else { continue };
            let Some(t2) = refract(t1, -(p2 - centre).normalize(), ior) else { continue };
            // only where the reflected ray leaves the scene and the refracted one meets the floor
            if reflected.y < 0.0 || t2.y >= -1e-3 {
                continue;
            }
            let floor = p2 + t2 * (-p2.y / t2.y);
            let Some((u, v)) = scene.camera.project(floor) else { continue };
            if u < 2.0 || v < 2.0 || u > width as f32 - 2.0 || v > height as f32 - 2.0 {
                continue;
            }
            // visible: the camera's ray to that floor point does not pass through the ball
            let to = floor - scene.camera.position;
            if sphere_hit(scene.camera.position, to.normalize(), false)
                .is_some_and(|h| (h - scene.camera.position).length() < to.length())
            {
                continue;
            }
            checked += 1;
            let shown = out.composite.pixels[k];
            let scale = decode(shown.z) / decode(0.5);
            if !(scale > 0.5) {
                eprintln!("pixel ({x}, {y}): not from the photograph (transmission {scale})");
                continue;
            }
            projected += 1;
            let su = (decode(shown.x) / scale).powf(1.0 / 2.2) * width as f32;
            let sv = (decode(shown.y) / scale).powf(1.0 / 2.2) * height as f32;
            if (su - u).abs() <= 2.0 && (sv - v).abs() <= 2.0 {
                agree += 1;
            } else {
                eprintln!(
                    "pixel ({x}, {y}) miss {:.2}: shows ({su:.1}, {sv:.1}), analytic ({u:.1}, {v:.1})",
                    miss / radius
                );
            }
        }
    }
    let report = out.report.specular.clone().unwrap();
    eprintln!(
        "{agree} of {projected} back-projected ({checked} analytically valid) glass pixels show the refracted floor; {report:?}"
    );
    assert!(checked >= 20, "too few glass pixels see visible floor through the ball: {checked}");
    // Known gap (issue 17's note): about a quarter of these pixels, on the ball's upper cap,
    // lose their refracted ray on the GPU (no hit, black without an environment); the rest
    // must be taken from the photograph at the right place.
    assert!(projected as f32 >= 0.6 * checked as f32, "{projected} of {checked} pixels from the photograph");
    assert!(agree as f32 >= 0.9 * projected as f32, "{agree} of {projected} glass pixels show the refracted floor");
}

/// A pipelined frame (no wait after each pass, [`GpuContext::set_pass_waits`] off) is the same
/// frame: gi with its bounce, caustic maps and their reflected VPLs, bit for bit; its report
/// lists only the CPU steps, and the context times passes again once switched back.
#[test]
fn a_pipelined_frame_equals_the_frame_timed_pass_by_pass() {
    let Some(r) = renderer_or_skip() else { return };
    let scene = mirror_caustic_scene();
    let photo = crate::test_support::grey_photo(&scene);
    let params = DirParams { vpls: 64, bounces: 2, ..Default::default() };
    let timed = r.render(&scene, &photo, &params).unwrap();
    r.ctx.set_pass_waits(false);
    let pipelined = r.render(&scene, &photo, &params);
    r.ctx.set_pass_waits(true);
    let pipelined = pipelined.unwrap();
    assert!(timed.report.specular.as_ref().and_then(|s| s.caustics.as_ref()).is_some(), "caustic maps ran");
    for (name, a, b) in [
        ("composite", &timed.composite, &pipelined.composite),
        ("L_rv", &timed.l_rv, &pipelined.l_rv),
        ("L_r", &timed.l_r, &pipelined.l_r),
    ] {
        assert!(a.pixels == b.pixels, "the pipelined frame's {name} differs");
    }
    assert_eq!(timed.vpls.len(), pipelined.vpls.len());
    assert!(timed.report.passes.len() > 10, "{:?}", timed.report.passes);
    assert!(pipelined.report.passes.iter().all(|p| p.pass.contains("CPU")), "{:?}", pipelined.report.passes);
    let again = r.render(&scene, &photo, &params).unwrap();
    assert_eq!(again.report.passes.len(), timed.report.passes.len());
}

/// Frames take their large buffers and textures from the GPU context's pool (`pool.rs`), as
/// their last frame left them. A frame made after frames of other scenes and conditions (with
/// caustics, two bounces and camera artifacts, so every pass's resources were used before, and
/// read-back staging filled with NaNs on reuse in tests) equals a fresh device's frame bit for
/// bit, and the same frame again makes nothing new. Its own renderer: the pool's counts are
/// per device.
#[test]
fn a_frame_on_reused_buffers_equals_a_fresh_devices_frame() {
    if renderer_or_skip().is_none() {
        return;
    }
    let (fresh, reused) = (DirRenderer::new().unwrap(), DirRenderer::new().unwrap());
    let caustic = mirror_caustic_scene();
    let lamp_box = crate::scene::load("dir-lamp-box").unwrap().with_size(caustic.camera.width, caustic.camera.height);
    let (photo, box_photo) = (crate::test_support::grey_photo(&caustic), crate::test_support::grey_photo(&lamp_box));
    let gi = DirParams { vpls: 64, bounces: 2, ..Default::default() };
    let with_ca = DirParams {
        camera_artifacts: Some(crate::ca::CaParams::from_sensor(&lamp_box.sensor)),
        ..DirParams { condition: GiLevel::Shadows, ..gi.clone() }
    };
    reused.render(&lamp_box, &box_photo, &gi).unwrap();
    reused.render(&caustic, &photo, &DirParams { condition: GiLevel::Shadows, ..gi.clone() }).unwrap();
    reused.render(&lamp_box, &box_photo, &with_ca).unwrap();
    let first = reused.render(&caustic, &photo, &gi).unwrap();
    let expected = fresh.render(&caustic, &photo, &gi).unwrap();
    assert!(first.report.specular.as_ref().and_then(|s| s.caustics.as_ref()).is_some(), "caustic maps ran");
    assert!(first.report.memory.reused_count > 0, "{:?}", first.report.memory);
    for (name, a, b) in [
        ("composite", &first.composite, &expected.composite),
        ("L_rv", &first.l_rv, &expected.l_rv),
        ("L_r", &first.l_r, &expected.l_r),
    ] {
        assert!(a.pixels == b.pixels, "the {name} on reused buffers differs from a fresh device's");
    }
    let again = reused.render(&caustic, &photo, &gi).unwrap();
    assert_eq!(again.report.memory.new_count, 0, "{:?}", again.report.memory);
    assert!(again.composite.pixels == first.composite.pixels);
    let box_again = reused.render(&lamp_box, &box_photo, &with_ca).unwrap();
    let box_fresh = fresh.render(&lamp_box, &box_photo, &with_ca).unwrap();
    assert!(box_again.composite.pixels == box_fresh.composite.pixels, "the ca frame on reused buffers differs");
}
