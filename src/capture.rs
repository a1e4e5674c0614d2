//! `mrstudy capture`: the simulated RGB-D capture of a scene's real objects (Rohmer et al.,
//! Sec. 5; `mrstudy_renderer::capture`), with a progress bar, its error against the scene's true
//! geometry printed as a table and optionally written as JSON.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use mrstudy_renderer::capture::impostor::{DistanceImpostor, evaluate};
use mrstudy_renderer::capture::{CaptureParams, capture};
use mrstudy_renderer::coherent::query::Representation;
use mrstudy_renderer::coherent::{Coherent, CoherentParams, Method, PROBE_PATHS, PROBE_WIDTH, Quality, light_probe};
use mrstudy_renderer::pathtracer::{Subset, World};
use mrstudy_renderer::scene;
use mrstudy_renderer::scene::Role;

use crate::progress::progress_bar;

flags! {
    CaptureArgs {
        /// A built-in scene name or a scene file (TOML).
        #[arg(long)] scene: String,
        /// Capture poses: the scene camera's, then swung 20°, 40°, … left and right about the point it looks at.
        #[arg(long, default_value_t = 4)] poses: usize,
        /// Depth image size WxH.
        #[arg(long, value_parser = scene::parse_size, default_value = "160x120")] size: (u32, u32),
        /// Axial depth noise σ at 1 m in metres (it grows with depth squared).
        #[arg(long, default_value_t = 0.0016)] noise: f32,
        /// Fraction of depth pixels measured.
        #[arg(long, default_value_t = 0.33)] density: f32,
        /// Samples per pixel of the colour camera's path-traced image.
        #[arg(long, default_value_t = 16)] spp: u32,
        /// The hash grid's virtual cell in metres (0.05 in the paper, for rooms; a table-top scene keeps more detail with a smaller one).
        #[arg(long, default_value_t = 0.05)] cell: f32,
        /// Texels per cube-map face of the distance impostor built from the capture.
        #[arg(long, default_value_t = 128)] impostor_size: u32,
        /// Random seed of the sensor's pattern and noise.
        #[arg(long, default_value_t = 1)] seed: u64,
        /// Also write the report as JSON here.
        #[arg(long)] json: Option<PathBuf>,
    }
}

pub fn run(args: CaptureArgs) -> Result<()> {
    if args.poses == 0 {
        bail!("--poses must be at least 1");
    }
    if !(args.noise >= 0.0 && args.noise.is_finite()) {
        bail!("--noise must be a finite depth in metres, 0 or more (got {})", args.noise);
    }
    if !(args.density > 0.0 && args.density <= 1.0) {
        bail!("--density must lie in (0, 1] (got {})", args.density);
    }
    if !(args.cell > 0.0 && args.cell.is_finite()) {
        bail!("--cell must be a positive size in metres (got {})", args.cell);
    }
    let scene = scene::load(&args.scene).with_context(|| format!("loading scene `{}`", args.scene))?;
    let real = World::new(&scene, Subset::RealOnly);
    let mut params = CaptureParams::for_scene(&scene, &real, args.poses);
    (params.sensor.width, params.sensor.height) = args.size;
    params.sensor.noise = args.noise;
    params.sensor.density = args.density;
    params.colour_spp = args.spp.max(1);
    params.seed = args.seed;
    params.cell = args.cell;
    let bar = progress_bar(args.poses as u64, "capture", "poses");
    let cap = capture(&real, &params, |done, _| bar.set_position(done as u64));
    bar.finish_and_clear();
    let r = &cap.report;
    println!("capture of `{}`: {} poses of {}×{} depth pixels", scene.name, r.poses, args.size.0, args.size.1);
    println!("  measured samples     {:>9}", r.measured);
    println!(
        "  depth pixels         {:>9} fitted, {} without samples, {} with two or fewer, {} ill-conditioned (disk radius {:.1} px)",
        r.fitted, r.empty, r.too_few, r.ill_conditioned, r.disk_radius_px
    );
    println!(
        "  environment samples  {:>9} made, {} into empty slots, {} replaced, {} dropped, {} removed, {} stored",
        r.samples, r.inserted, r.replaced, r.dropped, r.removed, r.stored
    );
    if r.samples == 0 {
        println!(
            "  no environment samples: the sensor saw no real surface within its range, so there is no error to report"
        );
    } else {
        println!(
            "  position error       median {:.2} mm, 90th percentile {:.2} mm (raw measurement: {:.2} / {:.2} mm)",
            r.position_error_mm.median,
            r.position_error_mm.p90,
            r.raw_position_error_mm.median,
            r.raw_position_error_mm.p90
        );
        println!(
            "  normal error         median {:.2}°, 90th percentile {:.2}°",
            r.normal_error_deg.median, r.normal_error_deg.p90
        );
    }
    println!(
        "  time                 depth {:.0} ms, neighbourhoods and plane fits {:.0} ms, colour camera {:.0} ms, hash grid {:.0} ms",
        r.depth_ms, r.fit_ms, r.colour_ms, r.grid_ms
    );

    // the distance impostor at the virtual objects (or, with none, at the point the camera
    // looks at), and how well EM and DIT answer rays from around it
    let virtual_bounds = scene
        .objects
        .iter()
        .filter(|o| o.role == Role::Virtual)
        .flat_map(|o| o.prims.iter().map(|p| p.bounds()))
        .reduce(|a, b| a.union(&b));
    let (centre, radius) = match virtual_bounds {
        Some(b) => (b.centroid(), 0.5 * (b.max - b.min).length()),
        None => {
            let mut above = params.poses[0].look_at;
            above.y += 0.2;
            (above, 0.2)
        }
    };
    let start = std::time::Instant::now();
    let map = DistanceImpostor::build(cap.grid.samples(), centre, args.impostor_size, params.cell);
    let build_ms = start.elapsed().as_secs_f64() * 1e3;
    let mut imp = evaluate(&map, &real, radius, 20_000, args.seed);
    imp.build_ms = build_ms;
    println!(
        "distance impostor at [{:.2}, {:.2}, {:.2}] ({} the virtual objects), {}² texels per face: {} of {} filled, {:.1} MB, built in {:.0} ms",
        centre.x,
        centre.y,
        centre.z,
        if virtual_bounds.is_some() {
            "the centre of"
        } else {
            "no virtual object; above the point the camera looks at, not"
        },
        imp.size,
        imp.filled_texels,
        imp.texels,
        imp.bytes as f64 / 1e6,
        imp.build_ms
    );
    if imp.rays == 0 {
        println!("  no ray from around the centre meets a real surface: nothing to compare");
    } else {
        println!(
            "  {} rays from within {:.2} m of the centre: EM answers {} (error median {:.3} m, p90 {:.3} m), DIT answers {} (error median {:.3} m, p90 {:.3} m; {:.0} ms per million rays)",
            imp.rays,
            radius,
            imp.em_answered,
            imp.em_error_m.median,
            imp.em_error_m.p90,
            imp.dit_answered,
            imp.dit_error_m.median,
            imp.dit_error_m.p90,
            imp.dit_ms_per_million
        );
    }
    // the albedo of the captured surfaces by eq. 5 (DIT in the impostor above, 64 cosine
    // samples, a light probe at its centre for what the capture missed)
    let mut coherent = CoherentParams { seed: args.seed, ..CoherentParams::new(Method::Dit, Quality::Med) };
    coherent.settings.material_samples = 64;
    let probe = light_probe(&real, centre, PROBE_WIDTH, PROBE_PATHS, args.seed);
    let rep = Representation { impostors: vec![map], sky: Some(Arc::new(probe)), ..Representation::default() };
    let samples: Vec<_> = cap.grid.samples().copied().collect();
    let albedo = Coherent::new(&scene, &real, &rep, coherent).albedo_error(&samples, 4000);
    if albedo.count == 0 {
        println!("albedo error: no environment sample lies on a real surface to compare with");
    } else {
        println!(
            "albedo error (eq. 5 by DIT, 64 samples, worst channel): median {:.3}, 90th percentile {:.3} over {} samples",
            albedo.median, albedo.p90, albedo.count
        );
    }
    if let Some(path) = &args.json {
        let json = serde_json::json!({ "capture": r, "impostor": imp, "albedo_error": albedo });
        std::fs::write(path, serde_json::to_string_pretty(&json)? + "\n")
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
