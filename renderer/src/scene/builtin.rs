//! Built-in scenes, addressable by name (`mrstudy render --list`):
//!
//! - `survey-1` … `survey-6`: the web-survey set after the thesis (Section 6.4.1, Figure 6.13):
//!   a wooden table before a white wall with boxes, a banana, a red or a blue table lamp, a book
//!   and a Cornell box; six arrangements and camera poses within 30° of the scene centre at
//!   about 51 cm, each saying which objects are virtual.
//! - `dir-env-shadow`, `dir-lamp-cornell`, `dir-lamp-box`, `dir-double-shadow`: the DIR test
//!   scenes of Figures 5.12–5.17 (a virtual Cornell box, a real white box, a real pocket lamp,
//!   an environment light; the double-shadow case with a real spot, a real box and a virtual box
//!   behind it).
//! - `lab-task`: the lab task scene of Section 6.3 (a table, a real cube, a virtual cube).
//! - `glass-figure`, `metal-bottle`: mirrors and glass after Figures 5.24–5.26 — a green glass
//!   figure (a closed turned mesh of 71 424 triangles, in place of the thesis's 69 680-triangle
//!   Stanford bunny) before a real white box and a sheet of paper under a real spot light that
//!   throws its caustic onto them; a virtual metal bottle beside a virtual yellow box, lit by a
//!   real and a virtual pocket lamp.
//!
//! Units are metres; +Y is up; the table top is the plane y = 0 and the wall is at z = −0.45.
//! Each scene is an ordinary [`SceneDesc`], so `mrstudy render --scene NAME --print-toml` (or
//! [`SceneDesc::to_toml`]) shows it as a scene file.

use super::desc::{
    CameraDesc, EnvironmentDesc, LightDesc, MaterialDesc, MaterialRef, ObjectDesc, PatternDesc, Rgb, Role, SceneDesc,
};
use crate::sensor::SensorDesc;
use std::collections::BTreeMap;

/// Names and one-line descriptions of the built-in scenes.
pub const SCENES: [(&str, &str); 13] = [
    ("survey-1", "survey: centre view; Cornell box and banana virtual; red lamp real"),
    ("survey-2", "survey: from the left; red lamp (and its light) and Cornell box virtual"),
    ("survey-3", "survey: from the right; banana and white box virtual; blue lamp real"),
    ("survey-4", "survey: far left, low; book and blue box virtual; red lamp real"),
    ("survey-5", "survey: high view; Cornell box and blue lamp (and its light) virtual"),
    ("survey-6", "survey: far right; white box and book virtual; red lamp real"),
    ("dir-env-shadow", "DIR Fig. 5.12: a virtual Cornell box shadows a real white box under environment light"),
    (
        "dir-lamp-cornell",
        "DIR Fig. 5.13: a real pocket lamp lights the virtual Cornell box, which bleeds red onto the real desk and box",
    ),
    ("dir-lamp-box", "DIR Fig. 5.14: the real pocket lamp lights the real box, which lights the virtual Cornell box"),
    ("dir-double-shadow", "DIR Figs. 5.15-5.17: a real spot, a real box, and a virtual box in the real box's shadow"),
    ("lab-task", "lab task (Sec. 6.3): a table, a real green cube and a virtual green cube"),
    (
        "glass-figure",
        "Figs. 5.24-5.25: a virtual green glass figure throws its caustic onto a real box and paper under a real spot",
    ),
    (
        "metal-bottle",
        "Fig. 5.26: a virtual metal bottle beside a virtual yellow box, lit by a real and a virtual pocket lamp",
    ),
];

pub fn names() -> impl Iterator<Item = &'static str> {
    SCENES.iter().map(|s| s.0)
}

/// The description of a built-in scene, or None.
pub fn get(name: &str) -> Option<SceneDesc> {
    let mut d = match name {
        "survey-1" | "survey-2" | "survey-3" | "survey-4" | "survey-5" | "survey-6" => survey(name[7..].parse().ok()?),
        "dir-env-shadow" => dir_scene(DirCase::EnvShadow),
        "dir-lamp-cornell" => dir_scene(DirCase::LampCornell),
        "dir-lamp-box" => dir_scene(DirCase::LampBox),
        "dir-double-shadow" => dir_scene(DirCase::DoubleShadow),
        "lab-task" => lab_task(),
        "glass-figure" => glass_figure(),
        "metal-bottle" => metal_bottle(),
        _ => return None,
    };
    d.name = name.to_string();
    d.description = SCENES.iter().find(|s| s.0 == name).map(|s| s.1.to_string()).unwrap_or_default();
    Some(d)
}

fn rgb(r: f32, g: f32, b: f32) -> Rgb {
    Rgb::Rgb([r, g, b])
}

fn mat(albedo: Rgb, specular: f32, exponent: f32) -> MaterialDesc {
    MaterialDesc {
        albedo: Some(albedo),
        specular: (specular > 0.0).then_some(Rgb::Grey(specular)),
        exponent: Some(exponent),
        ..Default::default()
    }
}

fn obj(name: &str, role: Role, shape: &str, material: &str, translate: [f32; 3]) -> ObjectDesc {
    ObjectDesc {
        name: name.into(),
        role: Some(role),
        shape: shape.into(),
        material: Some(MaterialRef::Named(material.into())),
        translate: Some(translate),
        ..Default::default()
    }
}

fn boxed(name: &str, role: Role, material: &str, size: [f32; 3], at: [f32; 2], yaw: f32) -> ObjectDesc {
    ObjectDesc {
        size: Some(size.to_vec()),
        rotate_deg: Some([0.0, yaw, 0.0]),
        ..obj(name, role, "box", material, [at[0], size[1] / 2.0, at[1]])
    }
}

fn common_materials() -> BTreeMap<String, MaterialDesc> {
    let mut m = BTreeMap::new();
    m.insert(
        "wood".into(),
        MaterialDesc {
            albedo: Some(Rgb::Grey(0.95)),
            pattern: Some(PatternDesc {
                kind: "wood".into(),
                a: rgb(0.55, 0.36, 0.2),
                b: rgb(0.32, 0.18, 0.08),
                scale: 9.0,
            }),
            specular: Some(Rgb::Grey(0.04)),
            exponent: Some(30.0),
            ..Default::default()
        },
    );
    m.insert("wall".into(), mat(rgb(0.78, 0.77, 0.74), 0.0, 1.0));
    m.insert("white".into(), mat(rgb(0.75, 0.75, 0.73), 0.0, 1.0));
    m.insert("cornell-white".into(), mat(rgb(0.73, 0.73, 0.7), 0.0, 1.0));
    m.insert("cornell-red".into(), mat(rgb(0.63, 0.06, 0.05), 0.0, 1.0));
    m.insert("cornell-green".into(), mat(rgb(0.12, 0.45, 0.09), 0.0, 1.0));
    m.insert("blue-box".into(), mat(rgb(0.08, 0.16, 0.5), 0.1, 25.0));
    m.insert("green-box".into(), mat(rgb(0.12, 0.42, 0.12), 0.05, 20.0));
    m.insert("banana".into(), mat(rgb(0.78, 0.6, 0.08), 0.08, 15.0));
    m.insert("lamp-red".into(), mat(rgb(0.62, 0.05, 0.04), 0.25, 60.0));
    m.insert("lamp-blue".into(), mat(rgb(0.05, 0.12, 0.55), 0.25, 60.0));
    m.insert("metal".into(), mat(rgb(0.25, 0.25, 0.25), 0.5, 80.0));
    m.insert(
        "bulb".into(),
        MaterialDesc { albedo: Some(Rgb::Grey(0.8)), emission: Some(rgb(8.0, 7.0, 5.5)), ..Default::default() },
    );
    m.insert(
        "book".into(),
        MaterialDesc {
            albedo: Some(Rgb::Grey(0.95)),
            pattern: Some(PatternDesc {
                kind: "stripes".into(),
                a: rgb(0.1, 0.18, 0.35),
                b: rgb(0.7, 0.62, 0.3),
                scale: 5.0,
            }),
            specular: Some(Rgb::Grey(0.05)),
            exponent: Some(20.0),
            ..Default::default()
        },
    );
    m
}

fn table_and_wall(objects: &mut Vec<ObjectDesc>) {
    objects.push(ObjectDesc {
        size: Some(vec![1.4, 0.04, 0.9]),
        uv_scale: Some([1.0, 1.0]),
        ..obj("table", Role::Real, "box", "wood", [0.0, -0.02, 0.0])
    });
    objects.push(ObjectDesc {
        size: Some(vec![3.0, 2.0]),
        rotate_deg: Some([90.0, 0.0, 0.0]),
        ..obj("wall", Role::Real, "plane", "wall", [0.0, 0.6, -0.45])
    });
}

/// The room: an indoor sky with a window behind the camera's left, and a ceiling light.
fn room_lighting(lights: &mut Vec<LightDesc>) -> EnvironmentDesc {
    lights.push(LightDesc {
        name: "ceiling".into(),
        kind: "area".into(),
        role: Some(Role::Real),
        position: [0.1, 1.3, 0.3],
        direction: Some([0.0, -1.0, 0.0]),
        intensity: 7.0,
        color: Some(rgb(1.0, 0.95, 0.88)),
        size: Some([0.5, 0.5]),
        ..Default::default()
    });
    EnvironmentDesc {
        kind: "sky".into(),
        zenith: Some(rgb(0.42, 0.42, 0.42)),
        horizon: Some(rgb(0.38, 0.36, 0.33)),
        ground: Some(rgb(0.12, 0.1, 0.09)),
        window_direction: Some([-0.8, 0.7, 1.0]),
        window_size_deg: Some([50.0, 40.0]),
        window_radiance: Some(rgb(3.2, 3.4, 3.8)),
        ..Default::default()
    }
}

/// A table lamp: base, stem, conical shade, bulb and a spot light pointing down-forward.
fn table_lamp(objects: &mut Vec<ObjectDesc>, lights: &mut Vec<LightDesc>, colour: &str, role: Role, at: [f32; 2]) {
    let [x, z] = at;
    let shade = if colour == "red" { "lamp-red" } else { "lamp-blue" };
    let name = format!("{colour}-lamp");
    objects.push(ObjectDesc {
        radius: Some(0.05),
        height: Some(0.015),
        ..obj(&format!("{name}-base"), role, "cylinder", shade, [x, 0.0075, z])
    });
    objects.push(ObjectDesc {
        radius: Some(0.006),
        height: Some(0.22),
        ..obj(&format!("{name}-stem"), role, "cylinder", "metal", [x, 0.125, z])
    });
    objects.push(ObjectDesc {
        radius: Some(0.075),
        radius_top: Some(0.03),
        height: Some(0.08),
        ..obj(&format!("{name}-shade"), role, "cone", shade, [x, 0.245, z])
    });
    objects
        .push(ObjectDesc { radius: Some(0.014), ..obj(&format!("{name}-bulb"), role, "sphere", "bulb", [x, 0.25, z]) });
    // The light hangs 1 cm below the bulb, inside the shade, 16 mm off the stem's axis towards
    // where it points: clear of the stem (radius 6 mm, up to the bulb's socket at y = 0.235)
    // and of the bulb (radius 14 mm about y = 0.25). On the axis it sat on the stem's top cap
    // and every ray of its cone started inside the stem: the lamp lit nothing.
    let direction: [f32; 3] = [0.15, -1.0, 0.2];
    let off = 0.016 / (direction[0] * direction[0] + direction[2] * direction[2]).sqrt();
    lights.push(LightDesc {
        name: format!("{name}-light"),
        kind: "spot".into(),
        role: Some(role),
        position: [x + direction[0] * off, 0.226, z + direction[2] * off],
        direction: Some(direction),
        inner_deg: Some(35.0),
        outer_deg: Some(55.0),
        intensity: 0.35,
        color: Some(rgb(1.0, 0.85, 0.6)),
        ..Default::default()
    });
}

/// A Cornell box model (white floor, ceiling and back, red left, green right, open front, with
/// a small white block inside), `size` wide, centred at `at` on the table, turned by `yaw`.
fn cornell_box(objects: &mut Vec<ObjectDesc>, role: Role, at: [f32; 2], size: f32, yaw: f32) {
    let s = size;
    let (c, sn) = (yaw.to_radians().cos(), yaw.to_radians().sin());
    // local (x, z) → world, rotating about Y by yaw
    let place = |lx: f32, ly: f32, lz: f32| [at[0] + c * lx + sn * lz, ly, at[1] - sn * lx + c * lz];
    let wall = |name: &str, m: &str, centre: [f32; 3], rot: [f32; 3]| ObjectDesc {
        size: Some(vec![s, s]),
        rotate_deg: Some([rot[0], rot[1] + yaw, rot[2]]),
        ..obj(name, role, "plane", m, place(centre[0], centre[1], centre[2]))
    };
    let t = 0.004; // floor plate above the table to avoid coplanar faces
    objects.push(wall("cornell-floor", "cornell-white", [0.0, t, 0.0], [0.0, 0.0, 0.0]));
    objects.push(wall("cornell-ceiling", "cornell-white", [0.0, s + t, 0.0], [180.0, 0.0, 0.0]));
    objects.push(wall("cornell-back", "cornell-white", [0.0, s / 2.0 + t, -s / 2.0], [90.0, 0.0, 0.0]));
    objects.push(wall("cornell-left", "cornell-red", [-s / 2.0, s / 2.0 + t, 0.0], [0.0, 0.0, -90.0]));
    objects.push(wall("cornell-right", "cornell-green", [s / 2.0, s / 2.0 + t, 0.0], [0.0, 0.0, 90.0]));
    let b = s * 0.3;
    objects.push(ObjectDesc {
        size: Some(vec![b, b * 1.6, b]),
        rotate_deg: Some([0.0, 20.0 + yaw, 0.0]),
        ..obj("cornell-block", role, "box", "cornell-white", place(-s * 0.15, t + b * 0.8, -s * 0.1))
    });
}

fn banana(objects: &mut Vec<ObjectDesc>, role: Role, at: [f32; 2], yaw: f32) {
    let n = 9;
    let points: Vec<[f32; 3]> = (0..n)
        .map(|i| {
            let t = i as f32 / (n - 1) as f32 - 0.5; // −0.5 … 0.5
            let a = t * 1.6; // arc angle
            [0.1 * a.sin(), 0.018 + 0.05 * (1.0 - a.cos()), 0.0]
        })
        .collect();
    let radii: Vec<f32> = (0..n)
        .map(|i| {
            let t = i as f32 / (n - 1) as f32;
            0.004 + 0.014 * (std::f32::consts::PI * t).sin().max(0.0).powf(0.6)
        })
        .collect();
    objects.push(ObjectDesc {
        points: Some(points),
        radii: Some(radii),
        segments: Some(16),
        rotate_deg: Some([0.0, yaw, 0.0]),
        ..obj("banana", role, "tube", "banana", [at[0], 0.0, at[1]])
    });
}

fn camera_at(azimuth_deg: f32, elevation_deg: f32, distance: f32, centre: [f32; 3], preset: &str) -> CameraDesc {
    let (a, e) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
    let position = [
        centre[0] + distance * e.cos() * a.sin(),
        centre[1] + distance * e.sin(),
        centre[2] + distance * e.cos() * a.cos(),
    ];
    CameraDesc {
        width: 640,
        height: 480,
        fov_y_deg: Some(45.0),
        k: None,
        position,
        look_at: centre,
        up: None,
        sensor: SensorDesc { preset: Some(preset.into()), seed: Some(7), ..Default::default() },
    }
}

use Role::{Real, Virtual};

fn survey(config: u32) -> SceneDesc {
    let centre = [0.0, 0.06, 0.0];
    // (azimuth, elevation) per configuration: all within 30° of the frontal view, 51 cm away
    let (az, el) =
        [(0.0, 30.0), (-20.0, 26.0), (22.0, 34.0), (-30.0, 22.0), (8.0, 40.0), (30.0, 28.0)][(config - 1) as usize];
    let mut objects = Vec::new();
    let mut lights = Vec::new();
    table_and_wall(&mut objects);
    let env = room_lighting(&mut lights);
    let role = |virtual_in: &[u32]| if virtual_in.contains(&config) { Virtual } else { Real };
    // lamp: red in 1, 2, 4, 6; blue in 3, 5
    let (lamp_colour, lamp_at) = match config {
        1 => ("red", [-0.2, -0.2]),
        2 => ("red", [0.18, -0.22]),
        3 => ("blue", [-0.18, -0.25]),
        4 => ("red", [0.05, -0.28]),
        5 => ("blue", [0.2, -0.18]),
        _ => ("red", [-0.22, -0.12]),
    };
    table_lamp(&mut objects, &mut lights, lamp_colour, role(&[2, 5]), lamp_at);
    let cb_at = match config {
        1 => [0.07, -0.12],
        2 => [-0.12, -0.14],
        3 => [0.12, -0.18],
        4 => [-0.2, -0.2],
        5 => [-0.08, -0.15],
        _ => [0.14, -0.2],
    };
    cornell_box(
        &mut objects,
        role(&[1, 2, 5]),
        cb_at,
        0.14,
        [-10.0, 15.0, -5.0, 20.0, 0.0, -20.0][(config - 1) as usize],
    );
    let banana_at =
        [[-0.08, 0.08], [0.05, 0.06], [0.02, 0.05], [0.14, 0.04], [0.1, 0.06], [-0.05, 0.1]][(config - 1) as usize];
    banana(&mut objects, role(&[1, 3]), banana_at, [20.0, -30.0, 60.0, 10.0, -50.0, 35.0][(config - 1) as usize]);
    let wb =
        [[0.16, 0.06], [-0.17, 0.02], [-0.1, -0.02], [0.22, -0.1], [0.2, 0.06], [-0.03, -0.06]][(config - 1) as usize];
    objects.push(boxed("white-box", role(&[3, 6]), "white", [0.08, 0.08, 0.08], wb, 15.0 * config as f32));
    let bb =
        [[-0.2, 0.02], [0.24, 0.04], [0.22, 0.0], [-0.06, 0.08], [-0.2, 0.05], [0.18, 0.08]][(config - 1) as usize];
    objects.push(boxed("blue-box", role(&[4]), "blue-box", [0.05, 0.1, 0.05], bb, -25.0 + 10.0 * config as f32));
    let bk =
        [[0.02, 0.14], [-0.05, 0.15], [-0.2, 0.12], [-0.15, 0.0], [0.0, 0.14], [0.05, 0.12]][(config - 1) as usize];
    objects.push(boxed("book", role(&[4, 6]), "book", [0.12, 0.025, 0.17], bk, 70.0 + 17.0 * config as f32));
    SceneDesc {
        name: String::new(),
        description: String::new(),
        camera: camera_at(az, el, 0.51, centre, "webcam"),
        materials: common_materials(),
        objects,
        lights,
        environment: Some(env),
        background: None,
    }
}

enum DirCase {
    EnvShadow,
    LampCornell,
    LampBox,
    DoubleShadow,
}

fn dir_scene(case: DirCase) -> SceneDesc {
    let mut objects = Vec::new();
    let mut lights = Vec::new();
    let mut materials = common_materials();
    materials.insert("desk".into(), mat(rgb(0.42, 0.4, 0.37), 0.05, 15.0));
    objects
        .push(ObjectDesc { size: Some(vec![1.4, 0.04, 0.9]), ..obj("desk", Real, "box", "desk", [0.0, -0.02, 0.0]) });
    // the captured environment (Figure 5.12: a fish-eye capture of an office): a brighter sky
    let env = EnvironmentDesc {
        kind: "sky".into(),
        zenith: Some(rgb(0.7, 0.72, 0.75)),
        horizon: Some(rgb(0.5, 0.48, 0.45)),
        ground: Some(rgb(0.15, 0.13, 0.12)),
        window_direction: Some([1.0, 1.2, -0.4]),
        window_size_deg: Some([40.0, 30.0]),
        window_radiance: Some(rgb(6.0, 6.0, 6.5)),
        ..Default::default()
    };
    let pocket_lamp = |objects: &mut Vec<ObjectDesc>, lights: &mut Vec<LightDesc>, pos: [f32; 3], target: [f32; 3]| {
        let d = [target[0] - pos[0], target[1] - pos[1], target[2] - pos[2]];
        let yaw = d[0].atan2(d[2]).to_degrees();
        let pitch = -(d[1] / (d[0] * d[0] + d[2] * d[2]).sqrt()).atan().to_degrees();
        // the body sits behind the light, along the beam axis
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let back = [pos[0] - d[0] / len * 0.056, pos[1] - d[1] / len * 0.056, pos[2] - d[2] / len * 0.056];
        objects.push(ObjectDesc {
            radius: Some(0.012),
            height: Some(0.1),
            rotate_deg: Some([90.0 + pitch, yaw, 0.0]),
            ..obj("pocket-lamp", Real, "cylinder", "metal", back)
        });
        lights.push(LightDesc {
            name: "pocket-lamp-light".into(),
            kind: "spot".into(),
            role: Some(Real),
            position: pos,
            target: Some(target),
            inner_deg: Some(8.0),
            outer_deg: Some(14.0),
            intensity: 4.0,
            color: Some(rgb(1.0, 0.95, 0.85)),
            ..Default::default()
        });
    };
    let centre;
    let mut azimuth = 10.0;
    match case {
        DirCase::EnvShadow | DirCase::LampCornell | DirCase::LampBox => {
            cornell_box(&mut objects, Virtual, [-0.08, -0.05], 0.16, 15.0);
            objects.push(boxed("white-box", Real, "white", [0.09, 0.09, 0.09], [0.12, 0.02], -20.0));
            centre = [0.02, 0.06, 0.0];
            match case {
                DirCase::LampCornell => {
                    pocket_lamp(&mut objects, &mut lights, [-0.05, 0.09, 0.35], [-0.08, 0.06, -0.05])
                }
                DirCase::LampBox => pocket_lamp(&mut objects, &mut lights, [0.3, 0.1, 0.3], [0.12, 0.05, 0.02]),
                _ => {}
            }
        }
        DirCase::DoubleShadow => {
            materials.insert("green-wall".into(), mat(rgb(0.15, 0.5, 0.15), 0.0, 1.0));
            objects.push(boxed("real-box", Real, "green-wall", [0.08, 0.1, 0.08], [0.0, 0.0], 10.0));
            objects.push(boxed("virtual-box", Virtual, "white", [0.07, 0.07, 0.07], [-0.02, -0.17], -15.0));
            lights.push(LightDesc {
                name: "real-spot".into(),
                kind: "spot".into(),
                role: Some(Real),
                position: [0.1, 0.35, 0.35],
                target: Some([0.0, 0.0, -0.05]),
                inner_deg: Some(20.0),
                outer_deg: Some(30.0),
                intensity: 1.2,
                color: Some(rgb(1.0, 0.95, 0.85)),
                ..Default::default()
            });
            centre = [0.0, 0.04, -0.05];
            azimuth = 60.0;
        }
    }
    SceneDesc {
        name: String::new(),
        description: String::new(),
        camera: camera_at(azimuth, 28.0, 0.6, centre, "webcam"),
        materials,
        objects,
        lights,
        environment: Some(EnvironmentDesc {
            intensity: Some(if matches!(case, DirCase::EnvShadow) { 1.0 } else { 0.5 }),
            ..env
        }),
        background: None,
    }
}

fn lab_task() -> SceneDesc {
    let mut objects = Vec::new();
    let mut lights = Vec::new();
    let mut materials = common_materials();
    materials.insert("table-plate".into(), mat(rgb(0.6, 0.6, 0.58), 0.02, 10.0));
    objects.push(ObjectDesc {
        size: Some(vec![1.2, 0.02, 0.8]),
        ..obj("table", Real, "box", "table-plate", [0.0, -0.01, 0.0])
    });
    objects.push(boxed("real-cube", Real, "green-box", [0.05, 0.05, 0.05], [0.0, 0.0], 0.0));
    objects.push(boxed("virtual-cube", Virtual, "green-box", [0.05, 0.05, 0.05], [0.16, -0.1], 30.0));
    let env = room_lighting(&mut lights);
    SceneDesc {
        name: String::new(),
        description: String::new(),
        camera: camera_at(0.0, 45.0, 0.6, [0.05, 0.0, -0.02], "webcam"),
        materials,
        objects,
        lights,
        environment: Some(env),
        background: None,
    }
}

/// A desk under a dim room, for the scenes of mirrors and glass.
fn specular_desk(objects: &mut Vec<ObjectDesc>, materials: &mut BTreeMap<String, MaterialDesc>) -> EnvironmentDesc {
    materials.insert("desk".into(), mat(rgb(0.42, 0.4, 0.37), 0.05, 15.0));
    objects
        .push(ObjectDesc { size: Some(vec![1.2, 0.04, 0.8]), ..obj("desk", Real, "box", "desk", [0.0, -0.02, 0.0]) });
    EnvironmentDesc {
        kind: "sky".into(),
        intensity: Some(0.25),
        zenith: Some(rgb(0.7, 0.72, 0.75)),
        horizon: Some(rgb(0.5, 0.48, 0.45)),
        ground: Some(rgb(0.15, 0.13, 0.12)),
        ..Default::default()
    }
}

fn glass_figure() -> SceneDesc {
    let mut objects = Vec::new();
    let mut materials = common_materials();
    let env = specular_desk(&mut objects, &mut materials);
    materials.insert("paper".into(), mat(rgb(0.85, 0.85, 0.83), 0.0, 1.0));
    materials.insert(
        "green-glass".into(),
        MaterialDesc {
            kind: Some("glass".into()),
            ior: Some(1.5),
            transmittance: Some(rgb(0.35, 0.85, 0.45)),
            transmittance_depth: Some(0.1),
            ..Default::default()
        },
    );
    objects.push(boxed("white-box", Real, "white", [0.24, 0.16, 0.1], [0.0, -0.16], 0.0));
    objects.push(ObjectDesc {
        size: Some(vec![0.21, 0.002, 0.297]),
        rotate_deg: Some([0.0, 75.0, 0.0]),
        ..obj("paper", Real, "box", "paper", [0.1, 0.001, -0.05])
    });
    // a figure of two lobes (a body and a head), turned: 280 profile points × 128 segments
    let (body, head) = ((0.038, 0.045), (0.028, 0.112));
    let radius_at = |y: f32| {
        let lobe = |(r, c): (f32, f32)| (r * r - (y - c) * (y - c)).max(0.0).sqrt();
        (lobe(body).powi(4) + lobe(head).powi(4)).powf(0.25)
    };
    let (bottom, top) = (body.1 - body.0, head.1 + head.0);
    let profile: Vec<[f32; 2]> = (0..280)
        .map(|i| {
            let t = std::f32::consts::PI * i as f32 / 279.0;
            let y = bottom + (top - bottom) * (1.0 - t.cos()) / 2.0;
            let r = if i == 0 || i == 279 { 0.0 } else { radius_at(y) };
            [r, y - bottom]
        })
        .collect();
    objects.push(ObjectDesc {
        profile: Some(profile),
        segments: Some(128),
        ..obj("glass-figure", Virtual, "lathe", "green-glass", [-0.01, 0.0, -0.02])
    });
    let lights = vec![LightDesc {
        name: "spot".into(),
        kind: "spot".into(),
        role: Some(Real),
        position: [0.22, 0.3, 0.3],
        target: Some([-0.03, 0.04, -0.1]),
        inner_deg: Some(14.0),
        outer_deg: Some(20.0),
        intensity: 1.0,
        color: Some(rgb(1.0, 0.96, 0.9)),
        ..Default::default()
    }];
    SceneDesc {
        name: String::new(),
        description: String::new(),
        camera: camera_at(-20.0, 22.0, 0.55, [0.0, 0.06, -0.06], "webcam"),
        materials,
        objects,
        lights,
        environment: Some(env),
        background: None,
    }
}

fn metal_bottle() -> SceneDesc {
    let mut objects = Vec::new();
    let mut materials = common_materials();
    let env = specular_desk(&mut objects, &mut materials);
    materials.insert("yellow".into(), mat(rgb(0.8, 0.65, 0.08), 0.05, 20.0));
    materials.insert(
        "bottle-metal".into(),
        MaterialDesc { kind: Some("mirror".into()), reflectance: Some(rgb(0.85, 0.85, 0.88)), ..Default::default() },
    );
    objects.push(boxed("yellow-box", Virtual, "yellow", [0.07, 0.07, 0.07], [-0.09, 0.01], 20.0));
    // body, rounded shoulder, neck and cap
    let mut profile = vec![[0.03, 0.0], [0.032, 0.004], [0.032, 0.1]];
    for k in 1..=8 {
        let a = std::f32::consts::FRAC_PI_2 * k as f32 / 8.0;
        profile.push([0.011 + 0.021 * a.cos(), 0.1 + 0.03 * a.sin()]);
    }
    profile.extend([[0.011, 0.15], [0.013, 0.15], [0.013, 0.168], [0.0, 0.168]]);
    objects.push(ObjectDesc {
        profile: Some(profile),
        segments: Some(64),
        ..obj("metal-bottle", Virtual, "lathe", "bottle-metal", [0.04, 0.0, 0.0])
    });
    let lamp = |name: &str, role: Role, position: [f32; 3]| LightDesc {
        name: name.into(),
        kind: "spot".into(),
        role: Some(role),
        position,
        target: Some([0.04, 0.07, 0.0]),
        inner_deg: Some(8.0),
        outer_deg: Some(14.0),
        intensity: 3.0,
        color: Some(rgb(1.0, 0.95, 0.85)),
        ..Default::default()
    };
    let lights = vec![
        lamp("real-pocket-lamp", Real, [0.32, 0.1, 0.08]),
        lamp("virtual-pocket-lamp", Virtual, [0.1, 0.12, 0.32]),
    ];
    SceneDesc {
        name: String::new(),
        description: String::new(),
        camera: camera_at(-15.0, 24.0, 0.5, [-0.02, 0.05, 0.0], "webcam"),
        materials,
        objects,
        lights,
        environment: Some(env),
        background: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;
    use std::path::Path;

    #[test]
    fn every_builtin_resolves_and_round_trips_through_toml() {
        for name in names() {
            let desc = get(name).unwrap();
            let toml = desc.to_toml();
            let back = SceneDesc::from_toml(&toml, name).unwrap_or_else(|e| panic!("{name}: {e}\n{toml}"));
            let scene = Scene::from_desc(back, Path::new("."), name).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(scene.has_virtual(), "{name} has no virtual object");
            assert!(scene.warnings.is_empty(), "{name}: {:?}", scene.warnings);
            assert!(scene.object_containing_camera().is_none());
        }
    }

    #[test]
    fn survey_cameras_are_51_cm_away_within_30_degrees() {
        for k in 1..=6 {
            let d = get(&format!("survey-{k}")).unwrap();
            let p = glam::Vec3::from_array(d.camera.position);
            let c = glam::Vec3::from_array(d.camera.look_at);
            assert!(((p - c).length() - 0.51).abs() < 1e-3);
            let front = glam::Vec3::new(0.0, (p - c).y, (p - c).length_squared().sqrt()).normalize();
            let azimuth = (p - c).x.atan2((p - c).z).to_degrees();
            assert!(azimuth.abs() <= 30.0 + 1e-3, "azimuth {azimuth}");
            let _ = front;
        }
    }
}
