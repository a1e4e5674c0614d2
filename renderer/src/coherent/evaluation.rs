//! `mrstudy capture`'s evaluation of a simulated capture as a scene representation for
//! coherent rendering: the capture of a scene's real objects ([`crate::capture`]) and its error
//! against the true geometry, the distance impostor built from it at the virtual objects and how
//! well EM and DIT answer rays from around it ([`impostor::evaluate`]), and the albedo of the
//! captured surfaces by eq. 5 (DIT in that impostor, 64 cosine samples, a light probe at its
//! centre for what the capture missed; [`Coherent::albedo_error`]).

use std::sync::Arc;
use std::time::Instant;

use glam::Vec3;

use super::impostor::{self, DistanceImpostor, ImpostorReport};
use super::query::Representation;
use super::{Coherent, CoherentParams, Method, PROBE_PATHS, PROBE_WIDTH, Quality, light_probe, virtual_bounds};
use crate::capture::{CaptureParams, CaptureReport, Spread, capture};
use crate::pathtracer::{Subset, World};
use crate::scene::Scene;

/// Rays cast from around the impostor's centre to compare EM's and DIT's answers with the truth.
const IMPOSTOR_RAYS: usize = 20_000;
/// Environment samples whose albedo is estimated.
const ALBEDO_SAMPLES: usize = 4000;

/// How a capture is simulated and evaluated: `mrstudy capture`'s flags.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureSettings {
    /// Capture poses: the scene camera's, then swung 20°, 40°, … about the point it looks at.
    pub poses: usize,
    /// Depth image size (width, height).
    pub size: (u32, u32),
    /// Axial depth noise σ at 1 m in metres (it grows with depth squared).
    pub noise: f32,
    /// Fraction of depth pixels measured, in (0, 1].
    pub density: f32,
    /// Samples per pixel of the colour camera's path-traced image.
    pub spp: u32,
    /// The hash grid's virtual cell in metres.
    pub cell: f32,
    /// Texels per cube-map face of the distance impostor built from the capture.
    pub impostor_size: u32,
    /// Random seed of the sensor's pattern and noise (and of the rays and the light probe).
    pub seed: u64,
}

/// A setting of [`CaptureSettings`] out of its range; each displays as one sentence naming the
/// flag and the value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CaptureSettingsError {
    #[error("--poses must be at least 1")]
    NoPoses,
    #[error("--noise must be a finite depth in metres, 0 or more (got {0})")]
    Noise(f32),
    #[error("--density must lie in (0, 1] (got {0})")]
    Density(f32),
    #[error("--cell must be a positive size in metres (got {0})")]
    Cell(f32),
}

impl CaptureSettings {
    /// The first setting out of its range, if any.
    pub fn check(&self) -> Result<(), CaptureSettingsError> {
        if self.poses == 0 {
            return Err(CaptureSettingsError::NoPoses);
        }
        if !(self.noise >= 0.0 && self.noise.is_finite()) {
            return Err(CaptureSettingsError::Noise(self.noise));
        }
        if !(self.density > 0.0 && self.density <= 1.0) {
            return Err(CaptureSettingsError::Density(self.density));
        }
        if !(self.cell > 0.0 && self.cell.is_finite()) {
            return Err(CaptureSettingsError::Cell(self.cell));
        }
        Ok(())
    }
}

/// What [`evaluate_capture`] found.
#[derive(Clone, Debug)]
pub struct CaptureEvaluation {
    pub scene: String,
    pub size: (u32, u32),
    pub capture: CaptureReport,
    /// The impostor's centre: the centre of the virtual objects' bounds, or with none 0.2 m above
    /// the point the first pose looks at.
    pub centre: Vec3,
    /// Whether the scene has virtual objects (and `centre` is theirs).
    pub at_virtual_objects: bool,
    /// The radius around `centre` the impostor's test rays start within.
    pub radius: f32,
    pub impostor: ImpostorReport,
    pub albedo: Spread,
}

/// Captures `scene`'s real objects as `settings` say (`progress` is told after each pose), builds
/// the distance impostor and evaluates it and the albedo estimated through it.
pub fn evaluate_capture(
    scene: &Scene,
    settings: &CaptureSettings,
    progress: impl FnMut(usize, usize),
) -> Result<CaptureEvaluation, CaptureSettingsError> {
    settings.check()?;
    let real = World::new(scene, Subset::RealOnly);
    let mut params = CaptureParams::for_scene(scene, &real, settings.poses);
    (params.sensor.width, params.sensor.height) = settings.size;
    params.sensor.noise = settings.noise;
    params.sensor.density = settings.density;
    params.colour_spp = settings.spp.max(1);
    params.seed = settings.seed;
    params.cell = settings.cell;
    let cap = capture(&real, &params, progress);
    // the distance impostor at the virtual objects (or, with none, above the point the camera
    // looks at), and how well EM and DIT answer rays from around it
    let virtual_objects = virtual_bounds(scene);
    let (centre, radius) = match virtual_objects {
        Some(b) => (b.centroid(), 0.5 * (b.max - b.min).length()),
        None => (params.poses[0].look_at + Vec3::new(0.0, 0.2, 0.0), 0.2),
    };
    let start = Instant::now();
    let map = DistanceImpostor::build(cap.grid.samples(), centre, settings.impostor_size, params.cell);
    let build_ms = start.elapsed().as_secs_f64() * 1e3;
    let mut impostor = impostor::evaluate(&map, &real, radius, IMPOSTOR_RAYS, settings.seed);
    impostor.build_ms = build_ms;
    // the albedo of the captured surfaces by eq. 5
    let mut coherent = CoherentParams { seed: settings.seed, ..CoherentParams::new(Method::Dit, Quality::Med) };
    coherent.settings.material_samples = 64;
    let probe = light_probe(&real, centre, PROBE_WIDTH, PROBE_PATHS, settings.seed);
    let rep = Representation { impostors: vec![map], sky: Some(Arc::new(probe)), ..Representation::default() };
    let samples: Vec<_> = cap.grid.samples().copied().collect();
    let albedo = Coherent::new(scene, &real, &rep, coherent).albedo_error(&samples, ALBEDO_SAMPLES);
    Ok(CaptureEvaluation {
        scene: scene.name.clone(),
        size: settings.size,
        capture: cap.report,
        centre,
        at_virtual_objects: virtual_objects.is_some(),
        radius,
        impostor,
        albedo,
    })
}

impl CaptureEvaluation {
    /// The report as `mrstudy capture` prints it: one line per finding.
    pub fn lines(&self) -> Vec<String> {
        let (r, imp, albedo) = (&self.capture, &self.impostor, &self.albedo);
        let mut lines = vec![
            format!("capture of `{}`: {} poses of {}×{} depth pixels", self.scene, r.poses, self.size.0, self.size.1),
            format!("  measured samples     {:>9}", r.measured),
            format!(
                "  depth pixels         {:>9} fitted, {} without samples, {} with two or fewer, {} ill-conditioned (disk radius {:.1} px)",
                r.fitted, r.empty, r.too_few, r.ill_conditioned, r.disk_radius_px
            ),
            format!(
                "  environment samples  {:>9} made, {} into empty slots, {} replaced, {} dropped, {} removed, {} stored",
                r.samples, r.inserted, r.replaced, r.dropped, r.removed, r.stored
            ),
        ];
        if r.samples == 0 {
            lines.push(
                "  no environment samples: the sensor saw no real surface within its range, so there is no error to report"
                    .into(),
            );
        } else {
            let (position, raw, normal) = (&r.position_error_mm, &r.raw_position_error_mm, &r.normal_error_deg);
            lines.push(format!(
                "  position error       median {:.2} mm, 90th percentile {:.2} mm (raw measurement: {:.2} / {:.2} mm)",
                position.median, position.p90, raw.median, raw.p90
            ));
            lines.push(format!(
                "  normal error         median {:.2}°, 90th percentile {:.2}°",
                normal.median, normal.p90
            ));
        }
        lines.push(format!(
            "  time                 depth {:.0} ms, neighbourhoods and plane fits {:.0} ms, colour camera {:.0} ms, hash grid {:.0} ms",
            r.depth_ms, r.fit_ms, r.colour_ms, r.grid_ms
        ));
        let (c, at) = (self.centre, self.at_virtual_objects);
        let around = if at { "the centre of" } else { "no virtual object; above the point the camera looks at, not" };
        lines.push(format!(
            "distance impostor at [{:.2}, {:.2}, {:.2}] ({around} the virtual objects), {}² texels per face: {} of {} filled, {:.1} MB, built in {:.0} ms",
            c.x,
            c.y,
            c.z,
            imp.size,
            imp.filled_texels,
            imp.texels,
            imp.bytes as f64 / 1e6,
            imp.build_ms
        ));
        if imp.rays == 0 {
            lines.push("  no ray from around the centre meets a real surface: nothing to compare".into());
        } else {
            lines.push(format!(
                "  {} rays from within {:.2} m of the centre: EM answers {} (error median {:.3} m, p90 {:.3} m), DIT answers {} (error median {:.3} m, p90 {:.3} m; {:.0} ms per million rays)",
                imp.rays,
                self.radius,
                imp.em_answered,
                imp.em_error_m.median,
                imp.em_error_m.p90,
                imp.dit_answered,
                imp.dit_error_m.median,
                imp.dit_error_m.p90,
                imp.dit_ms_per_million
            ));
        }
        lines.push(if albedo.count == 0 {
            "albedo error: no environment sample lies on a real surface to compare with".into()
        } else {
            format!(
                "albedo error (eq. 5 by DIT, 64 samples, worst channel): median {:.3}, 90th percentile {:.3} over {} samples",
                albedo.median, albedo.p90, albedo.count
            )
        });
        lines
    }

    /// The report as `mrstudy capture --json` writes it: `capture`, `impostor`, `albedo_error`.
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({ "capture": self.capture, "impostor": self.impostor, "albedo_error": self.albedo })
    }
}
