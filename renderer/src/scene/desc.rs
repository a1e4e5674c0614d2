//! The scene file's schema: [`SceneDesc`] and its parts, as TOML reads and writes them
//! (documented in `renderer/scenes/README.md`). Plain data; [`super`] resolves it into a
//! world-space scene, [`super::builtin`] writes the named scenes in it.

use crate::error::{RenderError, Result};
use crate::sensor::SensorDesc;
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Whether something exists in the real world (and so in the photograph) or only virtually.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    Real,
    Virtual,
}

/// A colour given as one grey value or as `[r, g, b]`.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum Rgb {
    Grey(f32),
    Rgb([f32; 3]),
}

impl Rgb {
    pub fn vec(self) -> Vec3 {
        match self {
            Rgb::Grey(g) => Vec3::splat(g),
            Rgb::Rgb(c) => Vec3::from_array(c),
        }
    }
}

/// The whole scene file.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    #[serde(default)]
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub camera: CameraDesc,
    #[serde(default)]
    pub materials: BTreeMap<String, MaterialDesc>,
    #[serde(default)]
    pub objects: Vec<ObjectDesc>,
    #[serde(default)]
    pub lights: Vec<LightDesc>,
    pub environment: Option<EnvironmentDesc>,
    pub background: Option<BackgroundDesc>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    pub width: u32,
    pub height: u32,
    /// Vertical field of view in degrees (or give `k`).
    pub fov_y_deg: Option<f32>,
    /// Intrinsics `[fx, fy, cx, cy]` in pixels.
    pub k: Option<[f32; 4]>,
    pub position: [f32; 3],
    pub look_at: [f32; 3],
    pub up: Option<[f32; 3]>,
    #[serde(default)]
    pub sensor: SensorDesc,
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialDesc {
    /// `glossy` (default: diffuse kd plus Blinn–Phong ks), `mirror` or `glass`.
    pub kind: Option<String>,
    /// mirror: the fraction reflected (default 1).
    pub reflectance: Option<Rgb>,
    /// glass: index of refraction inside (default 1.5; 1 outside).
    pub ior: Option<f32>,
    /// glass: the fraction of light kept after `transmittance_depth` scene units inside
    /// (Beer–Lambert; default 1: clear).
    pub transmittance: Option<Rgb>,
    /// glass: the depth at which `transmittance` holds (default 1 scene unit).
    pub transmittance_depth: Option<f32>,
    /// Diffuse albedo kd (default 0.8); multiplies the texture or pattern.
    pub albedo: Option<Rgb>,
    /// Albedo texture image (relative to the scene file); sRGB-encoded 8-bit or linear HDR.
    pub texture: Option<String>,
    pub pattern: Option<PatternDesc>,
    /// Blinn–Phong specular intensity ks (default 0); kd + ks must not exceed 1.
    pub specular: Option<Rgb>,
    /// Blinn–Phong exponent n (default 20).
    pub exponent: Option<f32>,
    /// Emitted radiance (default 0).
    pub emission: Option<Rgb>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PatternDesc {
    /// `wood`, `checker` or `stripes`.
    pub kind: String,
    pub a: Rgb,
    pub b: Rgb,
    /// Rings, squares or stripes per unit of texture coordinate.
    pub scale: f32,
}

/// A material by name (a key of `[materials]`) or inline.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(untagged)]
pub enum MaterialRef {
    Named(String),
    Inline(MaterialDesc),
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectDesc {
    #[serde(default)]
    pub name: String,
    /// `real` or `virtual` (required for objects; a proxy inherits its object's).
    pub role: Option<Role>,
    /// `box`, `sphere`, `plane`, `quad`, `cylinder`, `cone`, `tube`, `lathe` or `mesh`.
    pub shape: String,
    /// box: `[x, y, z]`; plane and quad: `[x, z]`.
    pub size: Option<Vec<f32>>,
    pub radius: Option<f32>,
    /// cone: radius at the top (the bottom is `radius`).
    pub radius_top: Option<f32>,
    pub height: Option<f32>,
    pub segments: Option<u32>,
    /// tube: the centre line and the radius at each point.
    pub points: Option<Vec<[f32; 3]>>,
    pub radii: Option<Vec<f32>>,
    /// lathe: `[radius, height]` pairs from the bottom up, turned about +Y.
    pub profile: Option<Vec<[f32; 2]>>,
    /// mesh: a `.gltf`, `.glb` or `.obj` file relative to the scene file.
    pub path: Option<String>,
    pub uv_scale: Option<[f32; 2]>,
    pub material: Option<MaterialRef>,
    pub translate: Option<[f32; 3]>,
    /// Euler angles in degrees, applied X, then Y, then Z.
    pub rotate_deg: Option<[f32; 3]>,
    pub scale: Option<Rgb>,
    /// The proxy model of a real object, when it differs from the true object.
    pub proxy: Option<Box<ObjectDesc>>,
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightDesc {
    #[serde(default)]
    pub name: String,
    /// `spot`, `point` or `area`.
    pub kind: String,
    /// Default `real`.
    pub role: Option<Role>,
    pub position: [f32; 3],
    pub direction: Option<[f32; 3]>,
    pub target: Option<[f32; 3]>,
    /// spot: half-angles from the axis, in degrees.
    pub inner_deg: Option<f32>,
    pub outer_deg: Option<f32>,
    /// spot and point: radiant intensity on the axis (W/sr); area: radiance (W/m²/sr).
    pub intensity: f32,
    pub color: Option<Rgb>,
    /// area: `[width, height]` in metres.
    pub size: Option<[f32; 2]>,
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentDesc {
    /// `map`, `sky` or `uniform`.
    pub kind: String,
    /// map: `.hdr` or `.exr` file relative to the scene file.
    pub path: Option<String>,
    /// map: `equirect` (default) or `fisheye` (angular, looking up).
    pub mapping: Option<String>,
    /// fisheye field of view in degrees (default 180).
    pub fov_deg: Option<f32>,
    /// Radiance scale (default 1).
    pub intensity: Option<f32>,
    pub rotation_deg: Option<f32>,
    pub zenith: Option<Rgb>,
    pub horizon: Option<Rgb>,
    pub ground: Option<Rgb>,
    pub window_direction: Option<[f32; 3]>,
    pub window_size_deg: Option<[f32; 2]>,
    pub window_radiance: Option<Rgb>,
    /// uniform: the radiance from every direction.
    pub radiance: Option<Rgb>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BackgroundDesc {
    /// A photograph of the real scene (relative to the scene file), used instead of synthesising one.
    pub photo: String,
}

impl SceneDesc {
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_default()
    }
    pub fn from_toml(text: &str, file: &str) -> Result<SceneDesc> {
        toml::from_str(text)
            .map_err(|e| RenderError::Parse { file: file.to_string(), message: one_line(&e.to_string()) })
    }
}

fn one_line(s: &str) -> String {
    // toml errors are multi-line with a source excerpt; keep the location and the message.
    let lines: Vec<&str> = s.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
    let head = lines.first().copied().unwrap_or("");
    let msg = lines.last().copied().unwrap_or("");
    if head == msg { head.to_string() } else { format!("{head} {}", msg.trim_start_matches('|').trim()) }
}
