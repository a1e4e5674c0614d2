//! The scene-load check that every light can shine: a point or spot light inside or on the
//! surface of an object, or an area light facing into one, lights (almost) nothing — as the
//! built-in table lamps did when their spot light sat on the top cap of the lamp's own stem.
//!
//! Each light sends a fixed set of directions (a Fibonacci spiral over its cone, or over the
//! hemisphere in front of each area-light triangle from a grid of points on it), weighted by
//! what it emits that way (the spot's falloff, or the cosine of an area light). A direction is
//! *blocked* when its ray leaves through the inside of a closed object (the first surface it
//! meets faces away from the light: the light is in that object) or meets any surface within
//! [`CONTACT`] of the light. Only objects whose bounds come within [`CONTACT`] of the light can
//! do either, so only those are intersected (a small [`Bvh`] of their primitives): a scene
//! without such objects costs nothing. A light whose blocked share reaches [`WARN_FRACTION`]
//! gets a warning naming the light, the object that blocks most and the share blocked.
//!
//! A shade or a wall a few centimetres away is not "blocking" here: shadows are the scene's
//! business; this check is for lights that are buried in, or pressed against, geometry.

use super::SceneObject;
use crate::bvh::Bvh;
use crate::geometry::{Aabb, Primitive, Ray};
use crate::light::SpotLight;
use crate::math::{Frame, luminance};
use glam::Vec3;

/// A surface this close in front of a light (metres) touches it.
pub const CONTACT: f32 = 1e-3;

/// The share of a light's emission that, blocked, earns a warning.
pub const WARN_FRACTION: f32 = 0.5;

/// Directions per point or spot light, and per point on an area light.
const DIRECTIONS: usize = 512;
/// Points per area-light triangle (a triangular grid of this many rows gives rows·(rows+1)/2).
const AREA_ROWS: usize = 6;

/// What blocks one light.
#[derive(Clone, Debug, PartialEq)]
pub struct Blockage {
    pub light: String,
    /// Whether the light is an area light (it faces into the object) or a point or spot light
    /// (it is inside or on the object).
    pub area: bool,
    /// The object that blocks the largest share.
    pub object: String,
    /// The share of the light's emission (weighted by intensity) that is blocked, by any object.
    pub fraction: f32,
}

impl Blockage {
    /// The warning sentence.
    pub fn warning(&self) -> String {
        let percent = (self.fraction * 100.0).round();
        if self.area {
            format!(
                "area light `{}` faces into object `{}`: {percent:.0} % of its emission is blocked at once; turn it or move it clear of the object",
                self.light, self.object
            )
        } else {
            format!(
                "light `{}` is inside or on the surface of object `{}`: {percent:.0} % of its emission is blocked at once; move it clear of the object",
                self.light, self.object
            )
        }
    }
}

/// The share of each light's emission that is blocked at once, for every light that has any
/// blocked (none: an empty list). `area_lights` are the indices into `objects` of the area
/// lights' emitters (which are not checked against themselves); `enclosure` names an object
/// the camera is inside (a room modelled as a closed box), whose inside a light may light as
/// the camera sees it, so it blocks nothing.
pub fn blockages(
    objects: &[SceneObject],
    spots: &[SpotLight],
    area_lights: &[usize],
    enclosure: Option<&str>,
) -> Vec<Blockage> {
    let bounds: Vec<Aabb> = objects
        .iter()
        .map(|o| if enclosure == Some(o.name.as_str()) { Aabb::EMPTY } else { grown(object_bounds(&o.prims), CONTACT) })
        .collect();
    let mut found = Vec::new();
    for spot in spots {
        let near: Vec<usize> = (0..objects.len()).filter(|&i| contains(&bounds[i], spot.position)).collect();
        if near.is_empty() {
            continue;
        }
        let tracer = Tracer::new(objects, &near);
        let cos_outer = spot.cos_outer.max(-1.0);
        let mut rays = Vec::with_capacity(DIRECTIONS);
        let frame = Frame::from_normal(spot.direction);
        for (local, _) in spiral(DIRECTIONS, cos_outer) {
            let dir = frame.to_world(local);
            let weight = luminance(spot.intensity_towards(dir));
            rays.push((Ray { origin: spot.position, dir }, weight));
        }
        if let Some(b) = tracer.blockage(&spot.name, false, rays) {
            found.push(b);
        }
    }
    for &index in area_lights {
        let light = &objects[index];
        let own = object_bounds(&light.prims);
        let near: Vec<usize> = (0..objects.len()).filter(|&i| i != index && overlaps(&bounds[i], &own)).collect();
        if near.is_empty() {
            continue;
        }
        let tracer = Tracer::new(objects, &near);
        let mut rays = Vec::new();
        for prim in &light.prims {
            let Primitive::Triangle(tri) = prim else { continue };
            let normal = tri.geometric_normal();
            if !normal.is_finite() || normal.length_squared() == 0.0 {
                continue;
            }
            let frame = Frame::from_normal(normal);
            let directions = spiral(DIRECTIONS / 8, 0.0);
            for row in 0..AREA_ROWS {
                for col in 0..=row {
                    // a point of the triangular grid, inside the triangle
                    let b1 = (row - col) as f32 + 1.0 / 3.0;
                    let b2 = col as f32 + 1.0 / 3.0;
                    let (b1, b2) = (b1 / (AREA_ROWS as f32 + 1.0 / 3.0), b2 / (AREA_ROWS as f32 + 1.0 / 3.0));
                    let point = tri.p[0] + (tri.p[1] - tri.p[0]) * b1 + (tri.p[2] - tri.p[0]) * b2;
                    for &(local, cos) in &directions {
                        // uniform in solid angle, weighted by the cosine: emitted power
                        rays.push((Ray { origin: point + normal * 1e-5, dir: frame.to_world(local) }, cos));
                    }
                }
            }
        }
        if let Some(b) = tracer.blockage(&light.name, true, rays) {
            found.push(b);
        }
    }
    found
}

/// The warnings of [`blockages`] whose share reaches [`WARN_FRACTION`].
pub fn warnings(
    objects: &[SceneObject],
    spots: &[SpotLight],
    area_lights: &[usize],
    enclosure: Option<&str>,
) -> Vec<String> {
    blockages(objects, spots, area_lights, enclosure)
        .into_iter()
        .filter(|b| b.fraction >= WARN_FRACTION)
        .map(|b| b.warning())
        .collect()
}

/// `n` directions spread evenly over the cap `cos θ ≥ cos_min` about +Z (a Fibonacci spiral,
/// equal solid angle each), with their cos θ.
fn spiral(n: usize, cos_min: f32) -> Vec<(Vec3, f32)> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|i| {
            let cos = 1.0 - (1.0 - cos_min) * (i as f32 + 0.5) / n as f32;
            let sin = (1.0 - cos * cos).max(0.0).sqrt();
            let phi = golden * i as f32;
            (Vec3::new(sin * phi.cos(), sin * phi.sin(), cos), cos)
        })
        .collect()
}

fn object_bounds(prims: &[Primitive]) -> Aabb {
    prims.iter().fold(Aabb::EMPTY, |b, p| b.union(&p.bounds()))
}

fn grown(b: Aabb, by: f32) -> Aabb {
    Aabb { min: b.min - Vec3::splat(by), max: b.max + Vec3::splat(by) }
}

fn contains(b: &Aabb, p: Vec3) -> bool {
    p.cmpge(b.min).all() && p.cmple(b.max).all()
}

fn overlaps(a: &Aabb, b: &Aabb) -> bool {
    a.min.cmple(b.max).all() && b.min.cmple(a.max).all()
}

/// The primitives of the objects near one light, each knowing its object.
struct Tracer<'a> {
    objects: &'a [SceneObject],
    bvh: Bvh<u32>,
}

impl<'a> Tracer<'a> {
    fn new(objects: &'a [SceneObject], near: &[usize]) -> Tracer<'a> {
        let mut prims = Vec::new();
        let mut payload = Vec::new();
        for &i in near {
            prims.extend(objects[i].prims.iter().cloned());
            payload.extend(std::iter::repeat_n(i as u32, objects[i].prims.len()));
        }
        Tracer { objects, bvh: Bvh::build(prims, payload) }
    }

    /// The object that blocks `ray` at once, if one does: the first surface within
    /// [`CONTACT`], or the inside of a closed object.
    fn blocker(&self, ray: &Ray) -> Option<usize> {
        // beyond a surface the light lies exactly on, which it leaves or enters
        let hit = self.bvh.intersect(ray, 1e-6, f32::INFINITY)?;
        let object = self.bvh.payload[hit.prim] as usize;
        if hit.t <= CONTACT {
            return Some(object);
        }
        let normal = match &self.bvh.prims[hit.prim] {
            Primitive::Triangle(tri) => tri.geometric_normal(),
            Primitive::Sphere { center, .. } => ray.origin + ray.dir * hit.t - *center,
        };
        (self.objects[object].closed && normal.dot(ray.dir) > 0.0).then_some(object)
    }

    fn blockage(&self, light: &str, area: bool, rays: Vec<(Ray, f32)>) -> Option<Blockage> {
        let total: f32 = rays.iter().map(|r| r.1).sum();
        if total <= 0.0 {
            return None;
        }
        let mut by_object = vec![0.0f32; self.objects.len()];
        for (ray, weight) in &rays {
            if *weight > 0.0
                && let Some(object) = self.blocker(ray)
            {
                by_object[object] += weight;
            }
        }
        let blocked: f32 = by_object.iter().sum();
        let (worst, _) = by_object.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
        (blocked > 0.0).then(|| Blockage {
            light: light.to_string(),
            area,
            object: self.objects[worst].name.clone(),
            fraction: blocked / total,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{LightDesc, Scene};
    use crate::test_support::scene_from_toml;

    /// A floor, a closed box of 10 cm at the origin's height 5 cm, an open quad (a wall) at
    /// z = -0.3, and the light given as TOML.
    fn scene(light: &str) -> Scene {
        scene_from_toml(
            &format!(
                r#"
[camera]
width = 8
height = 6
fov_y_deg = 50
position = [0.0, 0.5, 0.8]
look_at = [0.0, 0.0, 0.0]
[[objects]]
name = "floor"
role = "real"
shape = "plane"
size = [2.0, 2.0]
[[objects]]
name = "crate"
role = "virtual"
shape = "box"
size = [0.1, 0.1, 0.1]
translate = [0.0, 0.05, 0.0]
[[objects]]
name = "pole"
role = "real"
shape = "cylinder"
radius = 0.01
height = 0.2
translate = [0.3, 0.1, 0.0]
[[objects]]
name = "wall"
role = "real"
shape = "plane"
size = [2.0, 1.0]
rotate_deg = [90.0, 0.0, 0.0]
translate = [0.0, 0.5, -0.3]
[[lights]]
name = "lamp"
{light}
"#
            ),
            "light-check",
        )
    }

    /// The warnings of `scene` loaded again with its light changed by `change`.
    fn reloaded(scene: &Scene, change: impl FnOnce(&mut LightDesc)) -> Vec<String> {
        let mut desc = scene.desc.clone();
        change(&mut desc.lights[0]);
        Scene::from_desc(desc, std::path::Path::new("."), "light-check").unwrap().warnings
    }

    fn only_warning(scene: &Scene) -> &str {
        assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
        &scene.warnings[0]
    }

    #[test]
    fn a_point_light_inside_a_box_is_named_with_the_box_and_all_of_it_blocked() {
        let scene = scene(
            r#"kind = "point"
position = [0.01, 0.04, 0.02]
intensity = 1.0"#,
        );
        let warning = only_warning(&scene);
        assert!(warning.contains("`lamp`") && warning.contains("`crate`") && warning.contains("100 %"), "{warning}");
    }

    #[test]
    fn a_spot_on_the_top_cap_of_a_pole_pointing_down_is_blocked_as_the_old_table_lamps_were() {
        let scene = scene(
            r#"kind = "spot"
position = [0.3, 0.2, 0.0]
direction = [0.15, -1.0, 0.2]
inner_deg = 35.0
outer_deg = 55.0
intensity = 1.0"#,
        );
        let warning = only_warning(&scene);
        assert!(warning.contains("`pole`") && warning.contains("100 %"), "{warning}");
        // pointing up, off the same cap, it shines freely
        let up = reloaded(&scene, |l| l.direction = Some([0.0, 1.0, 0.0]));
        assert!(up.is_empty(), "{up:?}");
    }

    #[test]
    fn a_spot_on_the_floor_pointing_into_it_is_blocked_and_one_above_it_is_not() {
        let scene = scene(
            r#"kind = "spot"
position = [-0.4, 0.0005, 0.2]
direction = [0.0, -1.0, 0.0]
outer_deg = 40.0
intensity = 1.0"#,
        );
        assert!(only_warning(&scene).contains("`floor`"));
        let lifted = reloaded(&scene, |l| l.position[1] = 0.3);
        assert!(lifted.is_empty(), "{lifted:?}");
    }

    #[test]
    fn a_light_beside_an_object_or_half_covered_is_not_warned_about() {
        // 2 cm from the box's side, every direction free of contact
        let beside = scene(
            r#"kind = "point"
position = [0.07, 0.05, 0.0]
intensity = 1.0"#,
        );
        assert!(beside.warnings.is_empty(), "{:?}", beside.warnings);
        // a point light on the box's top face: the lower half of its emission goes into the box
        let on_top = scene(
            r#"kind = "point"
position = [0.0, 0.1, 0.0]
intensity = 1.0"#,
        );
        let found = blockages(&on_top.objects, &on_top.spots, &[], None);
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!(found[0].object, "crate");
        assert!((found[0].fraction - 0.5).abs() < 0.02, "{found:?}");
    }

    #[test]
    fn an_area_light_facing_into_a_box_is_warned_about_and_facing_away_is_not() {
        // half a millimetre above the box's top, facing down: the cosine-weighted directions
        // within 60° of the normal meet the box within CONTACT (3/4 of the emission)
        let into = scene(
            r#"kind = "area"
position = [0.0, 0.1005, 0.0]
direction = [0.0, -1.0, 0.0]
size = [0.05, 0.05]
intensity = 5.0"#,
        );
        let warning = only_warning(&into);
        assert!(warning.starts_with("area light `lamp` faces into object `crate`"), "{warning}");
        let emitter = into.objects.len() - 1;
        let found = blockages(&into.objects, &into.spots, &[emitter], None);
        assert!((found[0].fraction - 0.75).abs() < 0.03, "{found:?}");
        let away = reloaded(&into, |l| l.direction = Some([0.0, 1.0, 0.0]));
        assert!(away.is_empty(), "{away:?}");
        // inside the box every direction ends on its inside
        let inside = reloaded(&into, |l| l.position[1] = 0.05);
        assert!(inside.len() == 1 && inside[0].contains("100 %"), "{inside:?}");
        // facing the wall from half a millimetre
        let wall = scene(
            r#"kind = "area"
position = [0.0, 0.5, -0.2995]
direction = [0.0, 0.0, -1.0]
size = [0.1, 0.1]
intensity = 5.0"#,
        );
        assert!(only_warning(&wall).contains("`wall`"));
    }

    #[test]
    fn a_light_in_the_room_the_camera_is_in_is_not_warned_about() {
        // a closed box around camera and light is a room: only the camera's own warning
        let mut desc = scene(
            r#"kind = "point"
position = [0.0, 0.6, 0.0]
intensity = 1.0"#,
        )
        .desc;
        desc.objects.push(crate::scene::ObjectDesc {
            name: "room".into(),
            role: Some(crate::scene::Role::Real),
            shape: "box".into(),
            size: Some(vec![3.0, 3.0, 3.0]),
            ..Default::default()
        });
        let room = Scene::from_desc(desc, std::path::Path::new("."), "light-check").unwrap();
        assert_eq!(room.warnings.len(), 1, "{:?}", room.warnings);
        assert!(room.warnings[0].contains("the camera is inside object `room`"), "{:?}", room.warnings);
    }
}
