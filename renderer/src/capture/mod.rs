//! Simulated capture of the real environment (Rohmer et al., Sec. 5; issue 18, Deliver 1).
//!
//! An RGB-D device is moved through the real scene: at each capture [`Pose`] its depth sensor
//! measures a sparse set of pixels (a fraction [`DepthSensor::density`] of them, each with
//! Gaussian axial noise growing with the square of the depth, only within the sensor's range,
//! real objects only), and its colour camera (same intrinsics, path traced at the sensor's
//! resolution) sees the scene's radiance. The paper's pipeline then runs on each depth image:
//! every sample's disk (a radius chosen so about [`DepthSensor::neighbours`] × 0.6 disks overlap
//! a pixel) lists it in the pixels it covers, up to `neighbours` per pixel; samples farther in
//! depth than [`DepthSensor::discontinuity`] from the pixel's nearest sample are dropped; a
//! plane is fitted to the rest ([`plane::fit_plane`], Cramer's rule); intersecting it with the
//! pixel's view ray refines the pixel's depth. Each measured sample then becomes an
//! [`hashgrid::EnvironmentSample`] (the refined position, the plane's normal, the colour
//! camera's pixel) offered to the probabilistic [`hashgrid::HashGrid`]; before that, stored
//! samples the new depth image sees through are removed.
//!
//! Done on the CPU (rayon): a capture of four poses at 160×120 takes well under a second, and
//! it runs once per scene; the scene representations built from it (issue 18, Deliver 2) are
//! the GPU's work. Because the scene is simulated, every sample's true surface point, normal
//! and albedo are known, and [`CaptureReport`] gives the capture's error against them.

pub mod hashgrid;
pub mod plane;

use crate::camera::Camera;
use crate::image::Image;
use crate::math::{Rng, hash3};
use crate::pathtracer::{TraceParams, World, render};
use crate::scene::Scene;
use glam::Vec3;
use hashgrid::{EnvironmentSample, HashGrid, Inserted};
use plane::{FitFailure, fit_plane};
use rayon::prelude::*;
use serde::Serialize;
use std::time::Instant;

/// The simulated depth sensor. Defaults after a structured-light sensor of the paper's kind:
/// 160×120 depth pixels, 45° vertical field of view, 0.4–4 m range, axial noise σ = 1.6 mm × z²
/// (z in metres; Khoshelham and Elberink 2012 measured about 4 cm at 5 m for the Kinect), a
/// third of the pixels measured.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct DepthSensor {
    pub width: u32,
    pub height: u32,
    pub fov_y_deg: f32,
    /// Range in metres along the view axis; samples outside are not measured.
    pub near: f32,
    pub far: f32,
    /// Axial noise's standard deviation at 1 m (metres); it grows with z².
    pub noise: f32,
    /// Fraction of the pixels that carry a measurement.
    pub density: f32,
    /// The neighbourhood list's length k.
    pub neighbours: u32,
    /// The depth gap (metres) beyond which a neighbour is on another surface (0.1 m in the paper).
    pub discontinuity: f32,
}

impl Default for DepthSensor {
    fn default() -> Self {
        DepthSensor {
            width: 160,
            height: 120,
            fov_y_deg: 45.0,
            near: 0.4,
            far: 4.0,
            noise: 0.0016,
            density: 0.33,
            neighbours: 16,
            discontinuity: 0.1,
        }
    }
}

impl DepthSensor {
    /// The disk radius in pixels: a conservative 60 % of `neighbours` disks over a pixel on
    /// average, so lists rarely overflow (the paper: "the radius needs to be chosen
    /// conservatively").
    pub fn disk_radius(&self) -> f32 {
        (0.6 * self.neighbours as f32 / (self.density.max(1e-3) * std::f32::consts::PI)).sqrt().max(1.0)
    }

    /// Axial noise σ at depth `z`.
    pub fn sigma(&self, z: f32) -> f32 {
        self.noise * z * z
    }
}

/// Where the device is: its position and the point it looks at (up is +y).
#[derive(Clone, Copy, Debug)]
pub struct Pose {
    pub position: Vec3,
    pub look_at: Vec3,
}

/// Everything a capture needs.
#[derive(Clone, Debug)]
pub struct CaptureParams {
    pub sensor: DepthSensor,
    pub poses: Vec<Pose>,
    /// Samples per pixel of the colour camera's path-traced image.
    pub colour_spp: u32,
    /// Slots of the hash grid (4 M in the paper) and its virtual cell size (0.05 m).
    pub grid_capacity: usize,
    pub cell: f32,
    pub seed: u64,
}

impl CaptureParams {
    /// The default sensor and grid, with [`default_poses`] of `scene` (`count` of them; `real`
    /// is the scene's real world).
    pub fn for_scene(scene: &Scene, real: &World, count: usize) -> CaptureParams {
        CaptureParams {
            sensor: DepthSensor::default(),
            poses: default_poses(scene, real, count),
            colour_spp: 16,
            grid_capacity: 1 << 20,
            cell: 0.05,
            seed: 1,
        }
    }
}

/// Capture poses around the scene's camera: the camera's own pose first, then poses swung about
/// the vertical through the point the camera looks at (the first surface on its central ray),
/// alternately left and right by 20°, 40°, …, at the camera's distance and height.
pub fn default_poses(scene: &Scene, world: &World, count: usize) -> Vec<Pose> {
    let cam = &scene.camera;
    let forward = -cam.rotation.col(2);
    let centre =
        world.first_hit(&cam.ray(cam.cx, cam.cy)).map(|(hit, _)| hit.point).unwrap_or(cam.position + forward * 2.0);
    let offset = cam.position - centre;
    (0..count.max(1))
        .map(|i| {
            let k = i.div_ceil(2) as f32 * if i % 2 == 1 { 1.0 } else { -1.0 };
            let angle = (20.0 * k).to_radians();
            let rotated = glam::Quat::from_rotation_y(angle) * offset;
            Pose { position: centre + rotated, look_at: centre }
        })
        .collect()
}

/// One measured depth pixel.
#[derive(Clone, Copy, Debug)]
struct Measurement {
    pixel: u32,
    /// Measured depth along the view axis, and the world point it puts on the pixel's ray.
    z: f32,
    point: Vec3,
    /// The true surface: point, normal (towards the sensor), albedo.
    truth: (Vec3, Vec3, Vec3),
}

/// Median and 90th percentile of an error.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Spread {
    pub median: f64,
    pub p90: f64,
    pub count: usize,
}

impl Spread {
    pub(crate) fn of(mut values: Vec<f64>) -> Spread {
        values.sort_by(f64::total_cmp);
        Spread {
            median: crate::metrics::quantile(&values, 0.5),
            p90: crate::metrics::quantile(&values, 0.9),
            count: values.len(),
        }
    }
}

/// What a capture made and how far it is from the truth.
#[derive(Clone, Debug, Default, Serialize)]
pub struct CaptureReport {
    pub poses: usize,
    pub depth_pixels: usize,
    /// Depth samples measured (in range, on a real surface, in the sensor's random pattern).
    pub measured: usize,
    /// Depth pixels with a fitted plane, and those without: no sample, two or fewer, or an
    /// ill-conditioned system (the paper's black, dark grey and light grey).
    pub fitted: usize,
    pub empty: usize,
    pub too_few: usize,
    pub ill_conditioned: usize,
    pub disk_radius_px: f32,
    /// Environment samples made (measured samples whose pixel has a plane), and what the hash
    /// grid did with them.
    pub samples: usize,
    pub inserted: usize,
    pub replaced: usize,
    pub dropped: usize,
    /// Stored samples removed because a later depth image saw through them.
    pub removed: usize,
    pub stored: usize,
    /// Distance of each environment sample from the true surface point on its ray (mm), the
    /// raw measurement's distance for comparison, and the angle between the fitted and the true
    /// normal (degrees).
    pub position_error_mm: Spread,
    pub raw_position_error_mm: Spread,
    pub normal_error_deg: Spread,
    /// Milliseconds per stage over all poses.
    pub depth_ms: f64,
    pub fit_ms: f64,
    pub colour_ms: f64,
    pub grid_ms: f64,
}

/// A finished capture: the hash grid of environment samples and the report.
pub struct Capture {
    pub grid: HashGrid,
    pub report: CaptureReport,
}

/// One pose's depth image after the pipeline: per pixel the refined distance along its
/// pixel-centre ray and the fitted normal, where a plane was fitted.
struct DepthImage {
    camera: Camera,
    refined: Vec<Option<(f32, Vec3)>>,
}

/// Captures a scene's real world (`World::new(scene, Subset::RealOnly)`) from every pose
/// (`progress` is told after each).
pub fn capture(real: &World, params: &CaptureParams, progress: impl FnMut(usize, usize)) -> Capture {
    capture_worlds(&vec![real; params.poses.len()], params, progress)
}

/// [`capture`] with the real world as it is at each pose (`worlds[i]` at `params.poses[i]`): a
/// real object that moves between poses leaves samples the later depth images see through.
pub fn capture_worlds(worlds: &[&World], params: &CaptureParams, mut progress: impl FnMut(usize, usize)) -> Capture {
    assert_eq!(worlds.len(), params.poses.len(), "one world per pose");
    let mut grid = HashGrid::new(params.grid_capacity, params.cell);
    let mut report = CaptureReport {
        poses: params.poses.len(),
        disk_radius_px: params.sensor.disk_radius(),
        ..CaptureReport::default()
    };
    let (mut pos_err, mut raw_err, mut normal_err) = (Vec::new(), Vec::new(), Vec::new());
    for (pose_index, pose) in params.poses.iter().enumerate() {
        let s = &params.sensor;
        let camera = Camera::from_fov(s.width, s.height, s.fov_y_deg, pose.position, pose.look_at, Vec3::Y);
        let t0 = Instant::now();
        let world = worlds[pose_index];
        let measurements = measure(world, &camera, s, params.seed, pose_index as u64);
        let t1 = Instant::now();
        let (depth, counts) = fit_depth_image(camera, s, &measurements);
        let t2 = Instant::now();
        let trace = TraceParams { seed: hash3(params.seed, 0xc010, pose_index as u64), ..TraceParams::default() };
        let colour: Image = render(world, &depth.camera, &trace, params.colour_spp.max(1)).image();
        let t3 = Instant::now();
        report.depth_pixels += (s.width * s.height) as usize;
        report.measured += measurements.len();
        report.fitted += counts[0];
        report.empty += counts[1];
        report.too_few += counts[2];
        report.ill_conditioned += counts[3];
        // remove what this depth image sees through, then offer its samples
        report.removed += grid.retain(|sample| !seen_through(&depth, s, sample.position));
        let mut rng = Rng::for_stream(params.seed, 0x6a1d, pose_index as u64);
        for m in &measurements {
            let Some((t, normal)) = depth.refined[m.pixel as usize] else { continue };
            let (x, y) = (m.pixel % s.width, m.pixel / s.width);
            let ray = depth.camera.ray(x as f32 + 0.5, y as f32 + 0.5);
            let position = ray.origin + ray.dir * t;
            let sample = EnvironmentSample { position, normal, colour: colour.get(x, y), pose: pose_index as u32 };
            report.samples += 1;
            match grid.insert(sample, &mut rng) {
                Inserted::New => report.inserted += 1,
                Inserted::Replaced => report.replaced += 1,
                Inserted::Dropped => report.dropped += 1,
            }
            let (true_point, true_normal, _albedo) = m.truth;
            pos_err.push(((position - true_point).length() * 1000.0) as f64);
            raw_err.push(((m.point - true_point).length() * 1000.0) as f64);
            normal_err.push(normal.dot(true_normal).clamp(-1.0, 1.0).acos().to_degrees() as f64);
        }
        let t4 = Instant::now();
        report.depth_ms += (t1 - t0).as_secs_f64() * 1e3;
        report.fit_ms += (t2 - t1).as_secs_f64() * 1e3;
        report.colour_ms += (t3 - t2).as_secs_f64() * 1e3;
        report.grid_ms += (t4 - t3).as_secs_f64() * 1e3;
        progress(pose_index + 1, params.poses.len());
    }
    report.stored = grid.len();
    report.position_error_mm = Spread::of(pos_err);
    report.raw_position_error_mm = Spread::of(raw_err);
    report.normal_error_deg = Spread::of(normal_err);
    Capture { grid, report }
}

/// The sensor's measurements from one pose: each pixel in the random pattern whose centre ray
/// meets a real surface within range, with noisy depth.
fn measure(world: &World, camera: &Camera, s: &DepthSensor, seed: u64, pose: u64) -> Vec<Measurement> {
    let forward = -camera.rotation.col(2);
    (0..s.height)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..s.width).filter_map(move |x| {
                let pixel = y * s.width + x;
                let mut rng = Rng::for_stream(seed, hash3(0xde97, pose, 0), pixel as u64);
                if rng.next_f32() >= s.density {
                    return None;
                }
                let ray = camera.ray(x as f32 + 0.5, y as f32 + 0.5);
                let (hit, albedo) = world.first_hit(&ray)?;
                let z_true = hit.t * ray.dir.dot(forward);
                if !(z_true >= s.near && z_true <= s.far) {
                    return None;
                }
                let z = z_true + s.sigma(z_true) * rng.next_normal();
                let point = ray.origin + ray.dir * (z / ray.dir.dot(forward));
                Some(Measurement { pixel, z, point, truth: (hit.point, hit.shading_normal, albedo) })
            })
        })
        .collect()
}

/// Neighbourhood lists, discontinuity filter, plane fit and depth refinement for every pixel;
/// the counts are [fitted, empty, two or fewer, ill-conditioned].
fn fit_depth_image(camera: Camera, s: &DepthSensor, measurements: &[Measurement]) -> (DepthImage, [usize; 4]) {
    let (w, h) = (s.width as i64, s.height as i64);
    let k = s.neighbours.max(1) as usize;
    let r = s.disk_radius();
    let reach = r.ceil() as i64;
    // rasterise each sample's disk into the lists of the pixels it covers, in sample order
    let mut lists: Vec<Vec<u32>> = vec![Vec::new(); (w * h) as usize];
    for (i, m) in measurements.iter().enumerate() {
        let (mx, my) = ((m.pixel % s.width) as i64, (m.pixel / s.width) as i64);
        for y in (my - reach).max(0)..=(my + reach).min(h - 1) {
            for x in (mx - reach).max(0)..=(mx + reach).min(w - 1) {
                let d2 = ((x - mx) * (x - mx) + (y - my) * (y - my)) as f32;
                let list = &mut lists[(y * w + x) as usize];
                if d2 <= r * r && list.len() < k {
                    list.push(i as u32);
                }
            }
        }
    }
    let results: Vec<Result<(f32, Vec3), Option<FitFailure>>> = lists
        .par_iter()
        .enumerate()
        .map(|(pixel, list)| {
            let (px, py) = ((pixel as i64 % w) as f32, (pixel as i64 / w) as f32);
            let screen = |i: &u32| {
                let p = measurements[*i as usize].pixel;
                let (x, y) = ((p % s.width) as f32, (p / s.width) as f32);
                (x - px).powi(2) + (y - py).powi(2)
            };
            let Some(nearest) = list.iter().min_by(|a, b| screen(a).total_cmp(&screen(b))) else {
                return Err(None);
            };
            let z_ref = measurements[*nearest as usize].z;
            let points: Vec<Vec3> = list
                .iter()
                .map(|i| &measurements[*i as usize])
                .filter(|m| (m.z - z_ref).abs() <= s.discontinuity)
                .map(|m| m.point)
                .collect();
            let plane = fit_plane(&points).map_err(Some)?;
            let ray = camera.ray(px + 0.5, py + 0.5);
            let mut normal = plane.normal;
            if normal.dot(ray.origin - plane.point) < 0.0 {
                normal = -normal;
            }
            let denom = normal.dot(ray.dir);
            if denom.abs() < 1e-3 {
                // the plane is seen edge-on: no depth along this ray
                return Err(Some(FitFailure::IllConditioned));
            }
            let t = normal.dot(plane.point - ray.origin) / denom;
            if !(t > 0.0 && t.is_finite()) {
                return Err(Some(FitFailure::IllConditioned));
            }
            Ok((t, normal))
        })
        .collect();
    let mut counts = [0usize; 4];
    let refined = results
        .into_iter()
        .map(|r| match r {
            Ok(v) => {
                counts[0] += 1;
                Some(v)
            }
            Err(None) => {
                counts[1] += 1;
                None
            }
            Err(Some(FitFailure::TooFew)) => {
                counts[2] += 1;
                None
            }
            Err(Some(FitFailure::IllConditioned)) => {
                counts[3] += 1;
                None
            }
        })
        .collect();
    (DepthImage { camera, refined }, counts)
}

/// Whether the depth image sees through a stored sample: it projects into the image and lies
/// in front of the refined surface of its pixel and of every neighbour with a refined depth (a
/// sample on a silhouette, whose pixel's plane may be the background's, stays) by more than
/// three noise σ plus 2 cm.
fn seen_through(depth: &DepthImage, s: &DepthSensor, p: Vec3) -> bool {
    let cam = &depth.camera;
    let Some((u, v)) = cam.project(p) else { return false };
    if !(u >= 0.0 && v >= 0.0 && u < s.width as f32 && v < s.height as f32) {
        return false;
    }
    let forward = -cam.rotation.col(2);
    let z_sample = (p - cam.position).dot(forward);
    let (cx, cy) = (u as i64, v as i64);
    let mut seen = 0;
    for y in (cy - 1).max(0)..=(cy + 1).min(s.height as i64 - 1) {
        for x in (cx - 1).max(0)..=(cx + 1).min(s.width as i64 - 1) {
            let Some((t, _)) = depth.refined[(y * s.width as i64 + x) as usize] else { continue };
            let z_image = t * cam.ray(x as f32 + 0.5, y as f32 + 0.5).dir.dot(forward);
            if z_sample >= z_image - (3.0 * s.sigma(z_image) + 0.02) {
                return false;
            }
            seen += 1;
        }
    }
    seen > 0
}

#[cfg(test)]
mod tests;
