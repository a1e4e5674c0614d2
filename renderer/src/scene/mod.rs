//! Scene files: the TOML schema ([`SceneDesc`] and its parts, documented in
//! `renderer/scenes/README.md`) and its resolution into a world-space [`Scene`] that the tracers
//! use. Every object and light is marked real or virtual. A real object may carry a `proxy`: the
//! model a renderer believes in, which may differ from the "true" object that synthesises the
//! photograph (to study estimation error). The reference path tracer always uses the true objects.
//!
//! [`desc`] holds the schema, [`builtin`] the named scenes written in it; this module resolves
//! either (through [`load`]) and imports both, neither of them imports it.

use crate::camera::Camera;
use crate::error::{RenderError, Result};
use crate::geometry::{self, Primitive, Ray, Triangle};
use crate::image::Image;
use crate::light::{self, Environment, SpotLight};
use crate::material::{DeltaBsdf, Material, Texture};
use crate::mesh;
use crate::sensor::SensorParams;
use glam::{Vec2, Vec3};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub mod builtin;
pub mod desc;
pub mod light_check;

#[cfg(test)]
mod intent_tests;

pub use desc::*;

/// One resolved object: world-space primitives and a material.
#[derive(Clone, Debug)]
pub struct SceneObject {
    pub name: String,
    pub role: Role,
    pub material: usize,
    pub prims: Vec<Primitive>,
    /// Proxy geometry and material (real objects only); `None` when the proxy is the object.
    pub proxy: Option<(Vec<Primitive>, usize)>,
    /// Whether the shape is closed (a camera can be "inside" it).
    pub closed: bool,
}

/// A resolved scene, ready to render.
#[derive(Clone, Debug)]
pub struct Scene {
    pub name: String,
    pub description: String,
    pub camera: Camera,
    pub sensor: SensorParams,
    pub materials: Vec<Material>,
    pub objects: Vec<SceneObject>,
    pub spots: Vec<SpotLight>,
    pub environment: Option<Arc<Environment>>,
    pub background: Option<Image>,
    /// Things repaired or dropped while loading, one sentence each.
    pub warnings: Vec<String>,
    pub desc: SceneDesc,
}

/// Loads a built-in scene by name or a scene file by path.
pub fn load(name_or_path: &str) -> Result<Scene> {
    if let Some(desc) = builtin::get(name_or_path) {
        return Scene::from_desc(desc, Path::new("."), name_or_path);
    }
    let path = Path::new(name_or_path);
    if path.exists() {
        return Scene::load(path);
    }
    Err(RenderError::UnknownScene { name: name_or_path.to_string() })
}

/// Loads a scene by name or path (as [`load`]) at another image size (the intrinsics scale
/// with it) and with another simulated camera (its noise seed kept): `mrstudy render`'s
/// `--size` and `--camera`.
pub fn load_as(name_or_path: &str, size: Option<(u32, u32)>, sensor: Option<SensorParams>) -> Result<Scene> {
    let mut scene = load(name_or_path)?;
    if let Some((width, height)) = size {
        scene = scene.with_size(width, height);
    }
    if let Some(sensor) = sensor {
        scene.sensor = SensorParams { seed: scene.sensor.seed, ..sensor };
    }
    Ok(scene)
}

/// An image size `WxH` (or `WXH`), from 1x1 to 16384x16384; the refusal is one sentence
/// about `text`.
pub fn parse_size(text: &str) -> std::result::Result<(u32, u32), SizeError> {
    let text_of = || text.to_string();
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(|| SizeError::NotWxH(text_of()))?;
    let w: u32 = w.trim().parse().map_err(|_| SizeError::Width(text_of()))?;
    let h: u32 = h.trim().parse().map_err(|_| SizeError::Height(text_of()))?;
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        return Err(SizeError::OutOfRange(text_of()));
    }
    Ok((w, h))
}

/// An image size [`parse_size`] refused, with the text it was given.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum SizeError {
    #[error("`{0}` is not of the form WxH")]
    NotWxH(String),
    #[error("`{0}`: the width is not a whole number")]
    Width(String),
    #[error("`{0}`: the height is not a whole number")]
    Height(String),
    #[error("`{0}` must be between 1x1 and 16384x16384")]
    OutOfRange(String),
}

struct Ctx<'a> {
    base: &'a Path,
    file: &'a str,
    warnings: Vec<String>,
}

impl Ctx<'_> {
    fn invalid(&self, key: impl Into<String>, expected: impl Into<String>) -> RenderError {
        RenderError::Invalid { file: self.file.to_string(), key: key.into(), expected: expected.into() }
    }
    fn path(&self, p: &str) -> PathBuf {
        let p = Path::new(p);
        if p.is_absolute() { p.to_owned() } else { self.base.join(p) }
    }
}

fn finite3(ctx: &Ctx, key: &str, v: [f32; 3]) -> Result<Vec3> {
    if v.iter().all(|c| c.is_finite()) {
        Ok(Vec3::from_array(v))
    } else {
        Err(ctx.invalid(key, "three finite numbers"))
    }
}

impl Scene {
    /// The first object that is a mirror or glass, if any.
    pub fn specular_object(&self) -> Option<&SceneObject> {
        self.objects.iter().find(|o| self.materials[o.material].delta.is_some())
    }

    pub fn load(path: &Path) -> Result<Scene> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| RenderError::MissingFile {
            what: "scene file",
            path: path.to_owned(),
            reason: e.to_string(),
        })?;
        let desc = SceneDesc::from_toml(&text, &file)?;
        let base = path.parent().unwrap_or(Path::new("."));
        Scene::from_desc(desc, base, &file)
    }

    /// Resolves a description; relative paths are taken from `base`; `file` names the source in
    /// error messages.
    pub fn from_desc(desc: SceneDesc, base: &Path, file: &str) -> Result<Scene> {
        let mut ctx = Ctx { base, file, warnings: Vec::new() };
        let camera = resolve_camera(&ctx, &desc.camera)?;
        let sensor = desc
            .camera
            .sensor
            .resolve()
            .map_err(|(key, expected)| ctx.invalid(format!("camera.sensor.{key}"), expected))?;

        let mut materials = Vec::new();
        let mut material_index = BTreeMap::new();
        for (name, m) in &desc.materials {
            let mat = resolve_material(&ctx, name, m, &format!("materials.{name}"))?;
            material_index.insert(name.clone(), materials.len());
            materials.push(mat);
        }
        let mut objects = Vec::new();
        for (i, o) in desc.objects.iter().enumerate() {
            let key = format!("objects[{i}]");
            let role = o.role.ok_or_else(|| ctx.invalid(format!("{key}.role"), "\"real\" or \"virtual\""))?;
            let (prims, material, closed) = resolve_object(&mut ctx, o, &key, &mut materials, &material_index)?;
            let proxy = match &o.proxy {
                Some(p) => {
                    if role == Role::Virtual {
                        return Err(ctx.invalid(format!("{key}.proxy"), "a proxy only on a real object"));
                    }
                    let (pp, pm, _) =
                        resolve_object(&mut ctx, p, &format!("{key}.proxy"), &mut materials, &material_index)?;
                    Some((pp, pm))
                }
                None => None,
            };
            let name = if o.name.is_empty() { format!("object{i}") } else { o.name.clone() };
            objects.push(SceneObject { name, role, material, prims, proxy, closed });
        }

        let mut spots = Vec::new();
        // the objects that are area lights' emitters
        let mut area_lights = Vec::new();
        for (i, l) in desc.lights.iter().enumerate() {
            let key = format!("lights[{i}]");
            let role = l.role.unwrap_or(Role::Real);
            let position = finite3(&ctx, &format!("{key}.position"), l.position)?;
            let color = l.color.map(Rgb::vec).unwrap_or(Vec3::ONE);
            if !(l.intensity.is_finite() && l.intensity >= 0.0) {
                return Err(ctx.invalid(format!("{key}.intensity"), "a finite number ≥ 0"));
            }
            let name = if l.name.is_empty() { format!("light{i}") } else { l.name.clone() };
            let direction = || -> Result<Vec3> {
                let d = match (l.direction, l.target) {
                    (Some(d), _) => Vec3::from_array(d),
                    (None, Some(t)) => Vec3::from_array(t) - position,
                    (None, None) => return Err(ctx.invalid(format!("{key}.direction"), "a direction or a target")),
                };
                if d.length_squared() > 0.0 && d.is_finite() {
                    Ok(d.normalize())
                } else {
                    Err(ctx.invalid(format!("{key}.direction"), "a non-zero direction"))
                }
            };
            match l.kind.as_str() {
                "spot" => {
                    let inner = l.inner_deg.unwrap_or(20.0);
                    let outer = l.outer_deg.unwrap_or(30.0);
                    if !(0.0..=180.0).contains(&outer) || !(0.0..=outer).contains(&inner) {
                        return Err(ctx.invalid(format!("{key}.outer_deg"), "0 ≤ inner_deg ≤ outer_deg ≤ 180"));
                    }
                    spots.push(SpotLight {
                        name,
                        position,
                        direction: direction()?,
                        cos_inner: inner.to_radians().cos(),
                        cos_outer: outer.to_radians().cos().min(inner.to_radians().cos() - 1e-6),
                        intensity: color * l.intensity,
                        real: role == Role::Real,
                    });
                }
                "point" => spots.push(SpotLight {
                    name,
                    position,
                    direction: Vec3::Y,
                    cos_inner: -1.0,
                    cos_outer: -1.0 - 1e-6,
                    intensity: color * l.intensity,
                    real: role == Role::Real,
                }),
                "area" => {
                    let size = l.size.ok_or_else(|| ctx.invalid(format!("{key}.size"), "[width, height] in metres"))?;
                    let n = direction()?;
                    if size[0] <= 0.0 || size[1] <= 0.0 {
                        ctx.warnings
                            .push(format!("{file}: {key} (`{name}`) has zero area and emits nothing; it was skipped"));
                        continue;
                    }
                    let frame = crate::math::Frame::from_normal(n);
                    let c = position - frame.t * size[0] / 2.0 - frame.b * size[1] / 2.0;
                    let u = frame.t * size[0];
                    let v = frame.b * size[1];
                    let tris = vec![
                        Triangle { p: [c, c + u, c + u + v], n: None, uv: [Vec2::ZERO; 3] },
                        Triangle { p: [c, c + u + v, c + v], n: None, uv: [Vec2::ZERO; 3] },
                    ];
                    let mut mat = Material::diffuse(&format!("{name}-emitter"), Vec3::ZERO);
                    mat.emission = color * l.intensity;
                    materials.push(mat);
                    area_lights.push(objects.len());
                    objects.push(SceneObject {
                        name,
                        role,
                        material: materials.len() - 1,
                        prims: tris.into_iter().map(Primitive::Triangle).collect(),
                        proxy: None,
                        closed: false,
                    });
                }
                other => {
                    return Err(
                        ctx.invalid(format!("{key}.kind"), format!("\"spot\", \"point\" or \"area\", not \"{other}\""))
                    );
                }
            }
        }

        let environment = match &desc.environment {
            Some(e) => Some(Arc::new(resolve_environment(&mut ctx, e)?)),
            None => None,
        };
        let background = match &desc.background {
            Some(b) => {
                let p = ctx.path(&b.photo);
                let img = Image::load(&p, "background photograph")?;
                let img = if Image::is_hdr_path(&p) { img } else { img.srgb_to_linear() };
                Some(img.resized(camera.width, camera.height))
            }
            None => None,
        };

        let mut scene = Scene {
            name: if desc.name.is_empty() { file.to_string() } else { desc.name.clone() },
            description: desc.description.clone(),
            camera,
            sensor,
            materials,
            objects,
            spots,
            environment,
            background,
            warnings: ctx.warnings,
            desc,
        };
        let enclosure = scene.object_containing_camera();
        scene.warnings.extend(light_check::warnings(&scene.objects, &scene.spots, &area_lights, enclosure.as_deref()));
        if let Some(inside) = enclosure {
            scene.warnings.push(format!(
                "the camera is inside object `{inside}`; its view is blocked by that object's inner faces"
            ));
        }
        Ok(scene)
    }

    /// The name of a closed object whose interior contains the camera, if any (ray parity test).
    pub fn object_containing_camera(&self) -> Option<String> {
        let dirs = [Vec3::new(0.123, 0.981, 0.147).normalize(), Vec3::new(-0.71, 0.09, 0.69).normalize()];
        for o in self.objects.iter().filter(|o| o.closed) {
            let inside = dirs.iter().all(|&dir| {
                let ray = Ray { origin: self.camera.position, dir };
                let mut t_min = 0.0;
                let mut count = 0;
                // count crossings along the ray
                loop {
                    let next = o
                        .prims
                        .iter()
                        .filter_map(|p| p.intersect_t(&ray, t_min, f32::INFINITY))
                        .map(|h| h.0)
                        .fold(f32::INFINITY, f32::min);
                    if !next.is_finite() || count > 64 {
                        break;
                    }
                    count += 1;
                    t_min = next + 1e-5;
                }
                count % 2 == 1
            });
            if inside {
                return Some(o.name.clone());
            }
        }
        None
    }

    /// Renders at another resolution: the intrinsics scale with the image.
    pub fn with_size(mut self, width: u32, height: u32) -> Scene {
        self.camera = self.camera.resized(width, height);
        self
    }

    /// The centre of the axis-aligned bounds of object `name`'s primitives, or None when there
    /// is no such object (or it has no primitives).
    pub fn object_centre(&self, name: &str) -> Option<Vec3> {
        let object = self.objects.iter().find(|o| o.name == name)?;
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for prim in &object.prims {
            let b = prim.bounds();
            lo = lo.min(b.min);
            hi = hi.max(b.max);
        }
        (lo.is_finite() && hi.is_finite()).then(|| (lo + hi) * 0.5)
    }

    /// Moves object `name` (and its proxy) rigidly by `offset` metres, and its description with
    /// it; false when there is no such object or the offset is not finite. Lights are not moved.
    /// (For interactive tasks: a frame per input without resolving the whole scene again.)
    pub fn translate_object(&mut self, name: &str, offset: Vec3) -> bool {
        if !offset.is_finite() {
            return false;
        }
        let Some(object) = self.objects.iter_mut().find(|o| o.name == name) else { return false };
        let shift = |prims: &mut Vec<Primitive>| {
            for prim in prims.iter_mut() {
                match prim {
                    Primitive::Triangle(tri) => tri.p.iter_mut().for_each(|p| *p += offset),
                    Primitive::Sphere { center, .. } => *center += offset,
                }
            }
        };
        shift(&mut object.prims);
        if let Some((proxy, _)) = object.proxy.as_mut() {
            shift(proxy);
        }
        if let Some(desc) = self.desc.objects.iter_mut().find(|o| o.name == name) {
            let t = desc.translate.unwrap_or([0.0; 3]);
            desc.translate = Some([t[0] + offset.x, t[1] + offset.y, t[2] + offset.z]);
        }
        true
    }

    /// Whether the scene has anything virtual (objects or lights).
    pub fn has_virtual(&self) -> bool {
        self.objects.iter().any(|o| o.role == Role::Virtual) || self.spots.iter().any(|s| !s.real)
    }
}

fn resolve_camera(ctx: &Ctx, c: &CameraDesc) -> Result<Camera> {
    if c.width == 0 || c.height == 0 || c.width > 16384 || c.height > 16384 {
        return Err(ctx.invalid("camera.width", "a resolution between 1x1 and 16384x16384"));
    }
    let position = finite3(ctx, "camera.position", c.position)?;
    let look_at = finite3(ctx, "camera.look_at", c.look_at)?;
    if (position - look_at).length() <= 0.0 {
        return Err(ctx.invalid("camera.look_at", "a point different from camera.position"));
    }
    let up = c.up.map(Vec3::from_array).unwrap_or(Vec3::Y);
    if up.cross(position - look_at).length() < 1e-6 {
        return Err(ctx.invalid("camera.up", "a direction not parallel to the viewing direction"));
    }
    match (c.fov_y_deg, c.k) {
        (Some(_), Some(_)) => Err(ctx.invalid("camera.k", "either fov_y_deg or k, not both")),
        (Some(f), None) if f > 0.0 && f < 180.0 => Ok(Camera::from_fov(c.width, c.height, f, position, look_at, up)),
        (Some(_), None) => Err(ctx.invalid("camera.fov_y_deg", "an angle between 0 and 180 degrees")),
        (None, Some(k)) if k[0] > 0.0 && k[1] > 0.0 => Ok(Camera::from_k(c.width, c.height, k, position, look_at, up)),
        (None, Some(_)) => Err(ctx.invalid("camera.k", "[fx, fy, cx, cy] with positive focal lengths")),
        (None, None) => Err(ctx.invalid("camera.fov_y_deg", "a field of view (or a K matrix in camera.k)")),
    }
}

fn resolve_material(ctx: &Ctx, name: &str, m: &MaterialDesc, key: &str) -> Result<Material> {
    let delta_keys = [
        ("reflectance", m.reflectance.is_some()),
        ("ior", m.ior.is_some()),
        ("transmittance", m.transmittance.is_some()),
        ("transmittance_depth", m.transmittance_depth.is_some()),
    ];
    let glossy_keys = [
        ("albedo", m.albedo.is_some()),
        ("texture", m.texture.is_some()),
        ("pattern", m.pattern.is_some()),
        ("specular", m.specular.is_some()),
        ("exponent", m.exponent.is_some()),
        ("emission", m.emission.is_some()),
    ];
    let refuse_keys = |kind: &str, keys: &[(&str, bool)]| -> Result<()> {
        match keys.iter().find(|(_, given)| *given) {
            Some((field, _)) => {
                Err(ctx.invalid(format!("{key}.{field}"), format!("no `{field}` with kind = \"{kind}\"")))
            }
            None => Ok(()),
        }
    };
    match m.kind.as_deref() {
        None | Some("glossy") => refuse_keys("glossy", &delta_keys)?,
        Some("mirror") => {
            refuse_keys("mirror", &glossy_keys)?;
            refuse_keys("mirror", &delta_keys[1..])?;
            let reflectance = m.reflectance.map(Rgb::vec).unwrap_or(Vec3::ONE);
            if !(reflectance.min_element() >= 0.0 && reflectance.max_element() <= 1.0) {
                return Err(ctx.invalid(format!("{key}.reflectance"), "values in [0, 1]"));
            }
            return Ok(Material::delta(name, DeltaBsdf::Mirror { reflectance }));
        }
        Some("glass") => {
            refuse_keys("glass", &glossy_keys)?;
            refuse_keys("glass", &delta_keys[..1])?;
            let ior = m.ior.unwrap_or(1.5);
            if !(ior.is_finite() && (1.0..=4.0).contains(&ior)) {
                return Err(ctx.invalid(format!("{key}.ior"), "an index of refraction from 1 to 4"));
            }
            let transmittance = m.transmittance.map(Rgb::vec).unwrap_or(Vec3::ONE);
            if !(transmittance.min_element() > 0.0 && transmittance.max_element() <= 1.0) {
                return Err(ctx.invalid(format!("{key}.transmittance"), "values in (0, 1]"));
            }
            let depth = m.transmittance_depth.unwrap_or(1.0);
            if !(depth.is_finite() && depth > 0.0) {
                return Err(ctx.invalid(format!("{key}.transmittance_depth"), "a distance > 0"));
            }
            let absorption = -Vec3::new(transmittance.x.ln(), transmittance.y.ln(), transmittance.z.ln()) / depth;
            return Ok(Material::delta(name, DeltaBsdf::Dielectric { ior, absorption }));
        }
        Some(other) => {
            return Err(
                ctx.invalid(format!("{key}.kind"), format!("\"glossy\", \"mirror\" or \"glass\", not \"{other}\""))
            );
        }
    }
    let albedo = m.albedo.map(Rgb::vec).unwrap_or(Vec3::splat(0.8));
    let specular = m.specular.map(Rgb::vec).unwrap_or(Vec3::ZERO);
    let exponent = m.exponent.unwrap_or(20.0);
    let emission = m.emission.map(Rgb::vec).unwrap_or(Vec3::ZERO);
    if albedo.min_element() < 0.0 || !albedo.is_finite() {
        return Err(ctx.invalid(format!("{key}.albedo"), "values in [0, 1]"));
    }
    if specular.min_element() < 0.0 || (albedo + specular).max_element() > 1.0 + 1e-6 {
        return Err(
            ctx.invalid(format!("{key}.specular"), "albedo + specular ≤ 1 in every channel (energy conservation)")
        );
    }
    if !(exponent >= 0.0 && exponent.is_finite()) {
        return Err(ctx.invalid(format!("{key}.exponent"), "a finite number ≥ 0"));
    }
    if emission.min_element() < 0.0 || !emission.is_finite() {
        return Err(ctx.invalid(format!("{key}.emission"), "finite values ≥ 0"));
    }
    let texture = match (&m.texture, &m.pattern) {
        (Some(_), Some(_)) => {
            return Err(ctx.invalid(format!("{key}.pattern"), "either a texture or a pattern, not both"));
        }
        (Some(t), None) => {
            let p = ctx.path(t);
            let img = Image::load(&p, "texture")?;
            let img = if Image::is_hdr_path(&p) { img } else { img.srgb_to_linear() };
            Some(Texture::Image(Arc::new(img)))
        }
        (None, Some(p)) => {
            let (a, b) = (p.a.vec(), p.b.vec());
            Some(match p.kind.as_str() {
                "wood" => Texture::Wood { light: a, dark: b, rings: p.scale },
                "checker" => Texture::Checker { a, b, squares: p.scale },
                "stripes" => Texture::Stripes { a, b, count: p.scale },
                other => {
                    return Err(ctx.invalid(
                        format!("{key}.pattern.kind"),
                        format!("\"wood\", \"checker\" or \"stripes\", not \"{other}\""),
                    ));
                }
            })
        }
        (None, None) => None,
    };
    Ok(Material { name: name.to_string(), albedo, texture, specular, exponent, emission, delta: None })
}

fn resolve_object(
    ctx: &mut Ctx,
    o: &ObjectDesc,
    key: &str,
    materials: &mut Vec<Material>,
    material_index: &BTreeMap<String, usize>,
) -> Result<(Vec<Primitive>, usize, bool)> {
    let material = match &o.material {
        Some(MaterialRef::Named(n)) => *material_index.get(n).ok_or_else(|| {
            ctx.invalid(format!("{key}.material"), format!("the name of a material in [materials]; `{n}` is not one"))
        })?,
        Some(MaterialRef::Inline(m)) => {
            let mat = resolve_material(ctx, &format!("{}-material", o.name), m, &format!("{key}.material"))?;
            materials.push(mat);
            materials.len() - 1
        }
        None => {
            materials.push(Material::diffuse("default", Vec3::splat(0.8)));
            materials.len() - 1
        }
    };
    let translate = finite3(ctx, &format!("{key}.translate"), o.translate.unwrap_or([0.0; 3]))?;
    let rotate = finite3(ctx, &format!("{key}.rotate_deg"), o.rotate_deg.unwrap_or([0.0; 3]))?;
    let scale = o.scale.map(Rgb::vec).unwrap_or(Vec3::ONE);
    if scale.min_element() <= 0.0 || !scale.is_finite() {
        return Err(ctx.invalid(format!("{key}.scale"), "positive finite scale factors"));
    }
    let uv_scale = o.uv_scale.map(Vec2::from_array).unwrap_or(Vec2::ONE);
    let m = geometry::transform_matrix(translate, rotate, scale);
    let positive = |v: Option<f32>, field: &str| -> Result<f32> {
        match v {
            Some(x) if x > 0.0 && x.is_finite() => Ok(x),
            _ => Err(ctx.invalid(format!("{key}.{field}"), format!("a positive number for shape \"{}\"", o.shape))),
        }
    };
    let size_n = |n: usize| -> Result<Vec<f32>> {
        match &o.size {
            Some(s) if s.len() == n && s.iter().all(|x| *x > 0.0 && x.is_finite()) => Ok(s.clone()),
            _ => Err(ctx.invalid(format!("{key}.size"), format!("{n} positive numbers for shape \"{}\"", o.shape))),
        }
    };
    let segments = o.segments.unwrap_or(48).clamp(3, 4096);
    let (tris, closed) = match o.shape.as_str() {
        "sphere" => {
            let r = positive(o.radius, "radius")?;
            let s = scale.max_element();
            if (scale.min_element() - s).abs() > 1e-6 {
                return Err(ctx.invalid(format!("{key}.scale"), "a uniform scale for a sphere"));
            }
            return Ok((vec![Primitive::Sphere { center: translate, radius: r * s }], material, true));
        }
        "box" => {
            let s = size_n(3)?;
            (geometry::cuboid(Vec3::new(s[0], s[1], s[2]), uv_scale), true)
        }
        "plane" | "quad" => {
            let s = size_n(2)?;
            (geometry::quad(Vec2::new(s[0], s[1]), uv_scale), false)
        }
        "cylinder" => (
            geometry::frustum(
                positive(o.radius, "radius")?,
                positive(o.radius, "radius")?,
                positive(o.height, "height")?,
                segments,
                true,
            ),
            true,
        ),
        "cone" => {
            let r0 = positive(o.radius, "radius")?;
            let r1 = o.radius_top.unwrap_or(0.0);
            if !(r1 >= 0.0) {
                return Err(ctx.invalid(format!("{key}.radius_top"), "a number ≥ 0"));
            }
            // a lamp shade: open at both ends
            (geometry::frustum(r0, r1, positive(o.height, "height")?, segments, false), false)
        }
        "tube" => {
            let pts = o.points.clone().unwrap_or_default();
            let radii = o.radii.clone().unwrap_or_default();
            if pts.len() < 2 || radii.len() != pts.len() || radii.iter().any(|r| !(*r > 0.0)) {
                return Err(ctx.invalid(
                    format!("{key}.points"),
                    "at least two points and one positive radius per point (`radii`)",
                ));
            }
            let pts: Vec<Vec3> = pts.into_iter().map(Vec3::from_array).collect();
            (geometry::tube(&pts, &radii, segments.min(64)), true)
        }
        "lathe" => {
            let profile = o.profile.clone().unwrap_or_default();
            let valid = profile.len() >= 2
                && profile.iter().all(|[r, y]| *r >= 0.0 && r.is_finite() && y.is_finite())
                && profile.windows(2).all(|w| w[1][1] >= w[0][1] && (w[1][1] > w[0][1] || w[1][0] != w[0][0]))
                && profile.iter().any(|[r, _]| *r > 0.0);
            if !valid {
                return Err(ctx.invalid(
                    format!("{key}.profile"),
                    "at least two [radius, height] pairs, radii ≥ 0 (not all 0), heights rising from the bottom up",
                ));
            }
            (geometry::lathe(&profile, segments), true)
        }
        "mesh" => {
            let p = o
                .path
                .as_ref()
                .ok_or_else(|| ctx.invalid(format!("{key}.path"), "the path of a .gltf, .glb or .obj file"))?;
            let full = ctx.path(p);
            (mesh::load(&full)?, false)
        }
        other => {
            return Err(ctx.invalid(
                format!("{key}.shape"),
                format!("one of \"box\", \"sphere\", \"plane\", \"quad\", \"cylinder\", \"cone\", \"tube\", \"lathe\", \"mesh\"; not \"{other}\""),
            ));
        }
    };
    let (world, degenerate) = geometry::transform_triangles(tris, &m);
    if degenerate > 0 {
        ctx.warnings
            .push(format!("{}: {key} (`{}`): dropped {degenerate} degenerate (zero-area) triangles", ctx.file, o.name));
    }
    if world.is_empty() {
        return Err(ctx.invalid(format!("{key}.shape"), "geometry with at least one non-degenerate triangle"));
    }
    Ok((world.into_iter().map(Primitive::Triangle).collect(), material, closed))
}

fn resolve_environment(ctx: &mut Ctx, e: &EnvironmentDesc) -> Result<Environment> {
    let scale = e.intensity.unwrap_or(1.0);
    if !(scale >= 0.0 && scale.is_finite()) {
        return Err(ctx.invalid("environment.intensity", "a finite number ≥ 0"));
    }
    let rotation = e.rotation_deg.unwrap_or(0.0);
    let mut map = match e.kind.as_str() {
        "uniform" => Image::filled(8, 4, e.radiance.map(Rgb::vec).unwrap_or(Vec3::ONE)),
        "sky" => light::procedural_sky(
            256,
            e.zenith.map(Rgb::vec).unwrap_or(Vec3::new(0.55, 0.6, 0.7)),
            e.horizon.map(Rgb::vec).unwrap_or(Vec3::new(0.6, 0.58, 0.55)),
            e.ground.map(Rgb::vec).unwrap_or(Vec3::new(0.25, 0.22, 0.2)),
            e.window_radiance.map(|r| {
                (
                    e.window_direction.map(Vec3::from_array).unwrap_or(Vec3::new(-1.0, 0.6, 0.5)),
                    e.window_size_deg.unwrap_or([40.0, 30.0]),
                    r.vec(),
                )
            }),
        ),
        "map" => {
            let p = e
                .path
                .as_ref()
                .ok_or_else(|| ctx.invalid("environment.path", "an .hdr or .exr file for kind \"map\""))?;
            let full = ctx.path(p);
            if !Image::is_hdr_path(&full) {
                return Err(ctx.invalid("environment.path", "an .hdr or .exr file (linear radiance)"));
            }
            let img = Image::load(&full, "environment map")?;
            match e.mapping.as_deref().unwrap_or("equirect") {
                "equirect" => img,
                "fisheye" => {
                    let mut img = img;
                    if let Some(w) = light::repair_environment(&mut img, p) {
                        ctx.warnings.push(w);
                    }
                    light::fisheye_to_equirect(&img, e.fov_deg.unwrap_or(180.0), 512)
                }
                other => {
                    return Err(
                        ctx.invalid("environment.mapping", format!("\"equirect\" or \"fisheye\", not \"{other}\""))
                    );
                }
            }
        }
        other => {
            return Err(ctx.invalid("environment.kind", format!("\"map\", \"sky\" or \"uniform\", not \"{other}\"")));
        }
    };
    let source = e.path.clone().unwrap_or_else(|| e.kind.clone());
    if let Some(w) = light::repair_environment(&mut map, &source) {
        ctx.warnings.push(w);
    }
    if scale != 1.0 {
        map = map.map(|p| p * scale);
    }
    Ok(Environment::new(map, rotation))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_are_read_and_refused_by_their_text() {
        assert_eq!(parse_size("64x48"), Ok((64, 48)));
        assert_eq!(parse_size(" 64 X 48 "), Ok((64, 48)));
        for bad in ["64", "0x48", "64x", "x48", "-1x2", "16385x2", "axb"] {
            let error = parse_size(bad).unwrap_err().to_string();
            assert!(error.contains(&format!("`{bad}`")), "{bad}: {error}");
        }
    }

    #[test]
    fn load_as_resizes_and_changes_the_camera_but_keeps_its_seed() {
        let plain = load("survey-1").unwrap();
        let scene = load_as("survey-1", Some((32, 24)), SensorParams::preset("clean")).unwrap();
        assert_eq!((scene.camera.width, scene.camera.height), (32, 24));
        assert_eq!(scene.sensor.seed, plain.sensor.seed);
        assert_eq!(scene.sensor.jpeg_quality, SensorParams::clean().jpeg_quality);
    }

    #[test]
    fn the_documented_example_scene_loads() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/example.toml");
        let scene = Scene::load(&path).unwrap();
        assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
        assert_eq!(scene.sensor.jpeg_quality, Some(70));
        assert!(scene.has_virtual());
        let boxed = scene.objects.iter().find(|o| o.name == "box").unwrap();
        assert!(boxed.proxy.is_some());
    }

    #[test]
    fn translating_an_object_moves_its_centre_and_nothing_else() {
        let mut scene = load("lab-task").unwrap();
        let before = scene.object_centre("virtual-cube").unwrap();
        let real = scene.object_centre("real-cube").unwrap();
        assert!((real - Vec3::new(0.0, 0.025, 0.0)).length() < 1e-5, "{real}");
        assert!(scene.translate_object("virtual-cube", Vec3::new(0.01, 0.02, -0.03)));
        let after = scene.object_centre("virtual-cube").unwrap();
        assert!((after - before - Vec3::new(0.01, 0.02, -0.03)).length() < 1e-5);
        assert_eq!(scene.object_centre("real-cube").unwrap(), real);
        assert!(!scene.translate_object("no-such-object", Vec3::X));
        assert!(!scene.translate_object("virtual-cube", Vec3::new(f32::NAN, 0.0, 0.0)));
        assert!(scene.object_centre("no-such-object").is_none());
    }
}
