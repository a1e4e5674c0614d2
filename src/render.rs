//! `mrstudy render` and `mrstudy bench render --reference`: thin wrappers over
//! `mrstudy-renderer`. `render --reference` writes the ground-truth composite, `--photo` the
//! photograph of the real scene, both by the CPU reference path tracer through the scene's
//! simulated camera; `--buffers DIR` also writes the HDR buffers, both camera images, the masks
//! and a JSON report. Conditions (`--condition gi|shadows|none`, `--factors gi`) render on the
//! GPU (differential instant radiosity, `mrstudy_renderer::gpu`) over the path-traced
//! photograph, at 1024x768 unless `--size` says otherwise. The factor `cm` (`--factors gi,cm`)
//! is the thesis's statistics-based colour mapping; `--cm off|statistics|samples|rohmer` picks
//! any method and `--composition additive|scaled` the composition. The factor `ca`
//! (`--factors gi,ca`) adds the camera-artifact chain (`mrstudy_renderer::ca`), its parameters
//! from the scene's camera or estimated from the photograph (`--ca-params scene|estimate`).
//! `bench render --cm` measures each cm method's colour error on the virtual objects against the
//! ground truth through the known camera ([`bench_cm`]), `bench render --ca` the camera
//! artifacts' noise and blur.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use mrstudy_renderer::ca::{CaParams, ParamSource, estimate};
use mrstudy_renderer::cm::{CmMethod, CmParams, Composition};
use mrstudy_renderer::gpu::{Condition, DirParams, DirRenderer};
use mrstudy_renderer::image::save_by_extension;
use mrstudy_renderer::metrics;
use mrstudy_renderer::pathtracer::{Accumulator, Subset, TraceParams, World};
use mrstudy_renderer::reference::{ReferenceParams, render_photo, render_reference};
use mrstudy_renderer::sensor::{self, SensorParams};
use mrstudy_renderer::{Image, Mask, builtin, scene};
use serde_json::{Value, json};

#[derive(Args)]
pub struct RenderArgs {
    /// List the built-in scene names, one per line.
    #[arg(long)]
    list: bool,
    /// A built-in scene name or a scene file (TOML).
    #[arg(long)]
    scene: Option<String>,
    /// Render the ground-truth composite (real and virtual objects) with the reference path tracer.
    #[arg(long, conflicts_with = "photo")]
    reference: bool,
    /// Render the photograph (real objects only) with the reference path tracer.
    #[arg(long)]
    photo: bool,
    /// A condition by name, on the GPU: `gi` (shadows and indirect light), `shadows`, or `none`.
    #[arg(long, conflicts_with = "factors")]
    condition: Option<String>,
    /// Factors to switch on, on the GPU: `gi` (indirect light and shadows), `cm` (the
    /// statistics-based colour mapping), `ca` (camera artifacts).
    #[arg(long)]
    factors: Option<String>,
    /// Where the `ca` factor takes its parameters: `scene` (the scene's simulated camera) or
    /// `estimate` (noise, blur and JPEG quality measured on the photograph).
    #[arg(long, default_value = "scene")]
    ca_params: String,
    /// GPU: the colour mapping of the GI buffers: off (Reinhard), statistics, samples or rohmer
    /// (overrides what --factors implies).
    #[arg(long)]
    cm: Option<String>,
    /// GPU: the composition: additive (default) or scaled (Debevec: α = L'_cam / τ(L_r)).
    #[arg(long, default_value = "additive")]
    composition: String,
    /// GPU: the VPL budget of the `gi` condition.
    #[arg(long, default_value_t = 256)]
    vpls: u32,
    /// GPU: resolution of each VPL's imperfect shadow map (0: VPLs unshadowed).
    #[arg(long, default_value_t = 128)]
    ism_size: u32,
    /// GPU: points per cloud (real, virtual) splatted into each VPL's imperfect shadow map.
    #[arg(long, default_value_t = 1024)]
    ism_points: u32,
    /// GPU: bounces of indirect light in the `gi` condition (1: the single bounce of the RSM
    /// VPLs; more add the multiple-bounce light source of thesis 5.2.7, at most 8).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=8))]
    bounces: u32,
    /// GPU: candidate points each multiple-bounce slot searches.
    #[arg(long, default_value_t = 4096)]
    bounce_candidates: u32,
    /// Samples per pixel of the reference path tracer.
    #[arg(long, default_value_t = 64)]
    spp: u32,
    /// Image size WxH (intrinsics scale with it); default: the scene's.
    #[arg(long)]
    size: Option<String>,
    /// Random seed of the path tracer.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Replace the scene's simulated camera by a preset: webcam, phone or clean.
    #[arg(long)]
    camera: Option<String>,
    /// Output image: `.png` (camera output) or `.exr` (linear HDR radiance).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also write every buffer into this directory: photo.png, ground_truth.png, real.exr,
    /// full.exr, virtual_mask.png, affected_mask.png, report.json.
    #[arg(long)]
    buffers: Option<PathBuf>,
    /// Print the scene as a scene file (TOML) and exit.
    #[arg(long)]
    print_toml: bool,
}

fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s.split_once(['x', 'X']).with_context(|| format!("--size `{s}` is not of the form WxH"))?;
    let w: u32 = w.trim().parse().with_context(|| format!("--size `{s}`: bad width"))?;
    let h: u32 = h.trim().parse().with_context(|| format!("--size `{s}`: bad height"))?;
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        bail!("--size `{s}` must be between 1x1 and 16384x16384");
    }
    Ok((w, h))
}

/// Loads a scene by name or path, applying `--size` and `--camera`.
fn load_scene(name: &str, size: Option<&str>, camera: Option<&str>) -> Result<scene::Scene> {
    let mut scene = scene::load(name)?;
    if let Some(s) = size {
        let (w, h) = parse_size(s)?;
        scene = scene.with_size(w, h);
    }
    if let Some(preset) = camera {
        let seed = scene.sensor.seed;
        scene.sensor = SensorParams::preset(preset).with_context(|| format!("--camera `{preset}` is not one of webcam, phone, clean"))?;
        scene.sensor.seed = seed;
    }
    Ok(scene)
}

fn progress_bar(total: u64, label: &str) -> ProgressBar {
    let bar = ProgressBar::new(total);
    bar.set_style(ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} spp {elapsed_precise} (eta {eta})").unwrap_or_else(|_| ProgressStyle::default_bar()).progress_chars("=> "));
    bar.set_message(label.to_string());
    bar
}

pub fn run(args: RenderArgs) -> Result<()> {
    if args.list {
        for name in builtin::names() {
            println!("{name}");
        }
        return Ok(());
    }
    let name = args.scene.as_deref().context("--scene NAME|FILE is required (see `mrstudy render --list`)")?;
    let scene = load_scene(name, args.size.as_deref(), args.camera.as_deref())?;
    if args.print_toml {
        print!("{}", scene.desc.to_toml());
        return Ok(());
    }
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    if args.condition.is_some() || args.factors.is_some() || args.cm.is_some() {
        return render_condition(&args, name);
    }
    if !(args.reference || args.photo) {
        bail!("say what to render: --condition gi|shadows|none (GPU), or --reference or --photo (CPU reference path tracer)");
    }
    let out = args.out.as_ref().context("--out FILE (.png or .exr) is required")?;
    if args.spp == 0 {
        bail!("--spp must be at least 1");
    }
    let params = ReferenceParams { spp: args.spp, seed: args.seed, ..ReferenceParams::default() };
    let label = format!("{} {}x{}", scene.name, scene.camera.width, scene.camera.height);
    if args.photo {
        let bar = progress_bar(args.spp as u64, &label);
        let (hdr, photo, stats) = render_photo(&scene, &params, &|done, _| bar.set_position(done as u64))?;
        bar.finish_and_clear();
        save_by_extension(out, &hdr, &photo)?;
        if let Some(dir) = &args.buffers {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
            photo.save_png(&dir.join("photo.png"))?;
            hdr.save_exr(&dir.join("real.exr"))?;
            write_json(&dir.join("report.json"), &json!({ "scene": scene.name, "stats": stats }))?;
        }
        report(&stats.warnings, stats.seconds, stats.samples_per_second, out);
    } else {
        let bar = progress_bar(2 * args.spp as u64, &label);
        let result = render_reference(&scene, &params, &|done, _| bar.set_position(done as u64))?;
        bar.finish_and_clear();
        save_by_extension(out, &result.hdr_full, &result.ground_truth)?;
        if let Some(dir) = &args.buffers {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
            result.photo.save_png(&dir.join("photo.png"))?;
            result.ground_truth.save_png(&dir.join("ground_truth.png"))?;
            result.hdr_real.save_exr(&dir.join("real.exr"))?;
            result.hdr_full.save_exr(&dir.join("full.exr"))?;
            result.virtual_mask.save_png(&dir.join("virtual_mask.png"))?;
            result.affected_mask.save_png(&dir.join("affected_mask.png"))?;
            let errors = metrics::compare(&result.hdr_full, &result.hdr_real, &result.ground_truth, &result.photo, Some(&result.affected_mask));
            write_json(
                &dir.join("report.json"),
                &json!({ "scene": scene.name, "stats": result.stats, "photo_vs_ground_truth_in_affected_region": errors }),
            )?;
        }
        report(&result.stats.warnings, result.stats.seconds, result.stats.samples_per_second, out);
    }
    Ok(())
}

/// The `gi` level, the colour mapping and whether `ca` is on, asked for by `--condition` or
/// `--factors`, and `--cm`.
fn condition_of(args: &RenderArgs) -> Result<(Condition, CmMethod, bool)> {
    let mut method = CmMethod::Off;
    let mut ca = false;
    let condition = if let Some(name) = &args.condition {
        Condition::parse(name).with_context(|| format!("--condition `{name}` is not one of gi, shadows, none (for colour mapping add --cm, for camera artifacts use --factors)"))?
    } else {
        let mut condition = Condition::None;
        for factor in args.factors.as_deref().unwrap_or("").split(',').map(str::trim).filter(|f| !f.is_empty()) {
            match factor {
                "gi" => condition = Condition::Gi,
                "cm" => method = CmMethod::Statistics,
                "ca" => ca = true,
                other => bail!("--factors: unknown factor `{other}`; expected gi, cm or ca"),
            }
        }
        condition
    };
    if let Some(name) = &args.cm {
        method = CmMethod::parse(name).with_context(|| format!("--cm `{name}` is not one of off, statistics, samples, rohmer"))?;
    }
    Ok((condition, method, ca))
}

/// `render --condition …`: the photograph by the path tracer, then the GPU frame over it.
fn render_condition(args: &RenderArgs, name: &str) -> Result<()> {
    let (condition, method, ca) = condition_of(args)?;
    let composition = Composition::parse(&args.composition).with_context(|| format!("--composition `{}` is not one of additive, scaled", args.composition))?;
    let ca_source = ParamSource::parse(&args.ca_params).with_context(|| format!("--ca-params `{}` is not one of scene, estimate", args.ca_params))?;
    if args.reference || args.photo {
        bail!("--condition/--factors render on the GPU; leave out --reference and --photo");
    }
    let out = args.out.as_ref().context("--out FILE (.png or .exr) is required")?;
    if args.spp == 0 {
        bail!("--spp must be at least 1");
    }
    let size = args.size.clone().unwrap_or_else(|| "1024x768".to_string());
    let scene = load_scene(name, Some(&size), args.camera.as_deref())?;
    let renderer = DirRenderer::new()?;
    eprintln!("adapter: {}", renderer.ctx.adapter_name());
    let params = ReferenceParams { spp: args.spp, seed: args.seed, ..ReferenceParams::default() };
    let label = format!("photo {} {}x{}", scene.name, scene.camera.width, scene.camera.height);
    let bar = progress_bar(args.spp as u64, &label);
    let (_, photo, photo_stats) = render_photo(&scene, &params, &|done, _| bar.set_position(done as u64))?;
    bar.finish_and_clear();
    let mut ca_estimates = None;
    let camera_artifacts = ca.then(|| match ca_source {
        ParamSource::Scene => CaParams::from_sensor(&scene.sensor),
        ParamSource::Estimate => {
            let (params, estimates) = estimate::params_from_photo(&photo, &scene.sensor);
            ca_estimates = Some(estimates);
            params
        }
    });
    if let Some(e) = &ca_estimates {
        eprintln!(
            "ca estimates from the photograph: noise σ {:.4} (σ² = {:.2e}·d + {:.2e}, {}), blur {}, JPEG quality {}",
            e.noise.sigma,
            e.noise.a,
            e.noise.b,
            e.noise.fit,
            e.blur.radius_px.map(|r| format!("disc radius {r:.2} px ({} edges)", e.blur.edges)).unwrap_or_else(|| "not measurable (no isolated edges)".into()),
            e.jpeg.quality.map(|q| q.to_string()).unwrap_or_else(|| "not detectable (none, or above about 95)".into())
        );
    }
    let dir_params = DirParams { condition, vpls: args.vpls, ism_size: args.ism_size, ism_points: args.ism_points, bounces: args.bounces, bounce_candidates: args.bounce_candidates, cm: CmParams { method, ..CmParams::default() }, composition, camera_artifacts, ..DirParams::default() };
    let frame = renderer.render(&scene, &photo, &dir_params)?;
    save_by_extension(out, &frame.composite.srgb_to_linear(), &frame.composite)?;
    if let Some(dir) = &args.buffers {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        photo.save_png(&dir.join("photo.png"))?;
        frame.composite.save_png(&dir.join("composite.png"))?;
        frame.l_rv.save_exr(&dir.join("l_rv.exr"))?;
        frame.l_r.save_exr(&dir.join("l_r.exr"))?;
        frame.virtual_mask.save_png(&dir.join("virtual_mask.png"))?;
        write_json(&dir.join("report.json"), &json!({ "gpu": frame.report, "photo_seconds": photo_stats.seconds, "ca_estimates": ca_estimates }))?;
    }
    for pass in &frame.report.passes {
        eprintln!("  {:<40} {:>9.2} ms", pass.pass, pass.ms);
    }
    if let Some(why) = &frame.report.cm.fallback {
        eprintln!("warning: colour mapping {}: {why}", method.name());
    }
    eprintln!(
        "wrote {} ({} condition, cm {}{}, {} VPLs): photo {:.1} s on the CPU, GPU frame {:.1} ms on {}",
        out.display(),
        condition.name(),
        method.name(),
        if ca { format!(", ca from the {}", if ca_source == ParamSource::Scene { "scene's camera" } else { "photograph" }) } else { String::new() },
        frame.report.vpls,
        photo_stats.seconds,
        frame.report.ms,
        frame.report.adapter
    );
    Ok(())
}

fn report(warnings: &[String], seconds: f64, samples_per_second: f64, out: &Path) {
    for w in warnings.iter().filter(|w| w.contains("firefly")) {
        eprintln!("warning: {w}");
    }
    eprintln!("wrote {} in {:.1} s ({:.0} samples/s)", out.display(), seconds, samples_per_second);
}

fn write_json(path: &Path, value: &Value) -> Result<()> {
    std::fs::write(path, serde_json::to_string_pretty(value)? + "\n").with_context(|| format!("cannot write {}", path.display()))
}

/// `mrstudy bench render --reference`: samples per second of the reference path tracer, and
/// its error against a high-spp render of the same scene as the sample count grows. Returns
/// (adapter, rows, plots) for `bench`'s table/JSON/plot writer.
pub fn bench_reference(scene_name: Option<&str>, quick: bool) -> Result<(String, Vec<Value>, Vec<(String, String)>)> {
    let name = scene_name.unwrap_or("survey-1");
    let (w, h, max_spp, ref_spp) = if quick { (48, 36, 64, 256) } else { (160, 120, 256, 2048) };
    let scene = load_scene(name, Some(&format!("{w}x{h}")), None)?;
    let threads = rayon::current_num_threads();
    let adapter = format!("cpu reference path tracer ({threads} threads)");
    eprintln!("{name} at {w}x{h}: reference at {ref_spp} spp (seed 1000) …");
    let bar = progress_bar(2 * ref_spp as u64, "reference");
    let reference = render_reference(&scene, &ReferenceParams { spp: ref_spp, seed: 1000, pass_spp: 16, ..ReferenceParams::default() }, &|d, _| bar.set_position(d as u64))?;
    bar.finish_and_clear();
    let affected: &Mask = &reference.affected_mask;
    let world = World::new(&scene, Subset::All);
    let params = TraceParams { seed: 1, ..TraceParams::default() };
    let mut acc = Accumulator::new(w, h);
    let mut rows = Vec::new();
    let mut points_rmse = Vec::new();
    let mut points_flip = Vec::new();
    println!("{:<10} {:>6} {:>10} {:>14} {:>12} {:>12} {:>8}", "scene", "spp", "ms", "samples/s", "rmse(aff)", "rmse(all)", "flip");
    let start = Instant::now();
    let mut spp = 1u32;
    while spp <= max_spp {
        acc.add_samples(&world, &scene.camera, &params, spp - acc.spp);
        let ms = start.elapsed().as_secs_f64() * 1e3;
        let img: Image = acc.image();
        let display = sensor::apply(&img, &scene.camera, &scene.sensor);
        let rmse_aff = metrics::rmse(&reference.hdr_full, &img, Some(affected));
        let rmse_all = metrics::rmse(&reference.hdr_full, &img, None);
        let flip = metrics::flip(&reference.ground_truth, &display, Some(affected));
        let sps = (w * h) as f64 * spp as f64 / (ms / 1e3);
        println!("{:<10} {:>6} {:>10.1} {:>14.0} {:>12.5} {:>12.5} {:>8.4}", name, spp, ms, sps, rmse_aff, rmse_all, flip);
        rows.push(json!({
            "scene": name, "condition": "reference", "spp": spp, "ms": ms, "samples_per_s": sps,
            "rmse": rmse_aff, "rmse_all": rmse_all, "flip": flip,
            "width": w, "height": h, "reference_spp": ref_spp,
        }));
        points_rmse.push((ms, rmse_aff));
        points_flip.push((ms, flip));
        spp *= 2;
    }
    // the 1/√t guide through the first point
    let guide: Vec<(f64, f64)> = points_rmse.first().map(|&(t0, e0)| points_rmse.iter().map(|&(t, _)| (t, e0 * (t0 / t).sqrt())).collect()).unwrap_or_default();
    let plot = mrstudy_analysis::plot::line_plot(&mrstudy_analysis::plot::LinePlot {
        title: format!("Reference path tracer: error against time ({name}, {w}x{h}, {adapter})"),
        x_label: "time (ms)".into(),
        y_label: "error in the affected region".into(),
        x_log: true,
        y_log: true,
        series: vec![
            mrstudy_analysis::plot::LineSeries { name: "RMSE (linear)".into(), points: points_rmse },
            mrstudy_analysis::plot::LineSeries { name: "1/sqrt(t)".into(), points: guide },
            mrstudy_analysis::plot::LineSeries { name: "FLIP".into(), points: points_flip },
        ],
    });
    Ok((adapter, rows, vec![("render_reference.svg".to_string(), plot)]))
}

/// `mrstudy bench render` (GPU): frame time and error against the path-traced ground truth in
/// the affected region, for the conditions none and shadows and for gi over a VPL sweep
/// (16 … 1024), then gi with and without the ca factor through the webcam and phone cameras
/// (the ca pass timed). Each frame is rendered twice and the second timed (the first compiles the
/// shaders on software adapters). Returns (adapter, rows, plots) for `bench`'s writer.
pub fn bench_gpu(scene_name: Option<&str>, quick: bool) -> Result<(String, Vec<Value>, Vec<(String, String)>)> {
    let names: Vec<String> = match scene_name {
        Some(n) => vec![n.to_string()],
        None if quick => vec!["dir-lamp-box".to_string()],
        None => vec!["dir-lamp-box".to_string(), "dir-double-shadow".to_string(), "dir-lamp-cornell".to_string()],
    };
    let (w, h, ref_spp) = if quick { (96, 72, 64) } else { (256, 192, 512) };
    let vpl_counts: &[u32] = if quick { &[16, 64, 256] } else { &[16, 32, 64, 128, 256, 512, 1024] };
    let renderer = DirRenderer::new()?;
    let adapter = renderer.ctx.adapter_name();
    eprintln!("adapter: {adapter}");
    let mut rows = Vec::new();
    let mut plots = Vec::new();
    println!("{:<18} {:<8} {:>6} {:>10} {:>10} {:>8}", "scene", "cond", "vpls", "ms", "rmse(aff)", "flip");
    for name in &names {
        let scene = load_scene(name, Some(&format!("{w}x{h}")), None)?;
        eprintln!("{name} at {w}x{h}: reference at {ref_spp} spp …");
        let bar = progress_bar(2 * ref_spp as u64, "reference");
        let reference = render_reference(&scene, &ReferenceParams { spp: ref_spp, pass_spp: 16, ..ReferenceParams::default() }, &|d, _| bar.set_position(d as u64))?;
        bar.finish_and_clear();
        let affected = &reference.affected_mask;
        // the path tracer's own error against time on this frame: the full scene (real and
        // virtual) path traced at 1, 2, 4, … spp (another seed), through the same camera
        let pt_curve = path_tracer_curve(&scene, &reference, if quick { 64 } else { 256 });
        for point in &pt_curve {
            rows.push(json!({
                "scene": name, "condition": "path tracer", "spp": point.spp, "ms": point.ms, "rmse_linear": point.rmse, "flip_camera": point.flip,
                "width": w, "height": h, "reference_spp": ref_spp,
            }));
        }
        let mut dir_points = Vec::new();
        // one frame rendered twice (the first compiles the shaders on software adapters), the
        // second timed, and its error against the ground truth in the affected region
        let measure = |params: &DirParams| -> Result<(mrstudy_renderer::gpu::GpuRender, f64, f64)> {
            renderer.render(&scene, &reference.photo, params)?;
            let frame = renderer.render(&scene, &reference.photo, params)?;
            let rmse = metrics::rmse(&reference.ground_truth, &frame.composite, Some(affected));
            let flip = metrics::flip(&reference.ground_truth, &frame.composite, Some(affected));
            Ok((frame, rmse, flip))
        };
        let mut settings: Vec<(Condition, u32)> = vec![(Condition::None, 0), (Condition::Shadows, 0)];
        settings.extend(vpl_counts.iter().map(|&n| (Condition::Gi, n)));
        let mut points_rmse = Vec::new();
        let mut points_flip = Vec::new();
        for (condition, vpls) in settings {
            let params = DirParams { condition, vpls, ..DirParams::default() };
            let (frame, rmse, flip) = measure(&params)?;
            let ms = frame.report.ms;
            // the light transport against the path tracer's: DIR's linear composite, its RMSE
            // and its FLIP through the true camera, and the path tracer's time to the same RMSE
            let linear = dir_linear_composite(&frame, &reference.hdr_real);
            let rmse_linear = metrics::rmse(&reference.hdr_full, &linear, Some(affected));
            let flip_camera = metrics::flip(&reference.ground_truth, &sensor::apply(&linear, &scene.camera, &scene.sensor), Some(affected));
            let (pt_ms, bound) = path_tracer_time_to(&pt_curve, rmse_linear, |p| p.rmse);
            let (pt_ms_flip, bound_flip) = path_tracer_time_to(&pt_curve, flip_camera, |p| p.flip);
            let speedup = pt_ms / ms.max(1e-9);
            let speedup_flip = pt_ms_flip / ms.max(1e-9);
            let versus = match bound {
                Bound::Exact => format!("linear RMSE {rmse_linear:.4}: the path tracer needs {pt_ms:.0} ms, {speedup:.2}×"),
                Bound::AtMost => format!("linear RMSE {rmse_linear:.4}: the path tracer at 1 spp ({pt_ms:.0} ms) is as close, ≤ {speedup:.2}×"),
                Bound::AtLeast => format!("linear RMSE {rmse_linear:.4}: the path tracer is not as close in {pt_ms:.0} ms, > {speedup:.2}×"),
            };
            println!("{:<18} {:<8} {:>6} {:>10.2} {:>10.5} {:>8.4}   {versus}", name, condition.name(), frame.report.vpls, ms, rmse, flip);
            if condition == Condition::Gi {
                points_rmse.push((vpls as f64, rmse));
                points_flip.push((vpls as f64, flip));
                dir_points.push((ms, rmse_linear));
            }
            rows.push(json!({
                "scene": name, "condition": condition.name(), "vpls": vpls, "ms": ms, "rmse": rmse, "flip": flip,
                "width": w, "height": h, "reference_spp": ref_spp, "shadow_map_size": params.shadow_map_size, "rsm_size": params.rsm_size,
                "ism_size": params.ism_size, "ism_points": params.ism_points, "bounces": params.bounces,
                "rmse_linear": rmse_linear, "flip_camera": flip_camera,
                "path_tracer_ms_to_same_rmse": pt_ms, "path_tracer_bound": bound.name(), "speedup_over_path_tracer": speedup,
                "path_tracer_ms_to_same_flip": pt_ms_flip, "path_tracer_bound_flip": bound_flip.name(), "speedup_over_path_tracer_flip": speedup_flip,
                "passes": frame.report.passes,
            }));
        }
        plots.push((
            format!("render_gpu_vs_path_tracer_{name}.svg"),
            mrstudy_analysis::plot::line_plot(&mrstudy_analysis::plot::LinePlot {
                title: format!("DIR gi (16–1024 VPLs) vs the path tracer (1–{} spp), {name}, {w}x{h}", pt_curve.last().map_or(0, |p| p.spp)),
                x_label: "time (ms)".into(),
                y_label: "RMSE of radiance in the affected region".into(),
                x_log: true,
                y_log: true,
                series: vec![
                    mrstudy_analysis::plot::LineSeries { name: "path tracer".into(), points: pt_curve.iter().map(|p| (p.ms, p.rmse)).collect() },
                    mrstudy_analysis::plot::LineSeries { name: "DIR gi".into(), points: dir_points },
                ],
            }),
        ));
        // the multiple-bounce light source (5.2.7): bounces and candidates per slot
        let bounce_settings: &[(u32, u32, u32)] = if quick { &[(256, 1, 4096), (256, 3, 4096)] } else { &[(256, 1, 4096), (256, 2, 4096), (256, 3, 1024), (256, 3, 4096), (256, 3, 16384), (1024, 1, 4096), (1024, 3, 4096)] };
        for &(vpls, bounces, bounce_candidates) in bounce_settings {
            let params = DirParams { condition: Condition::Gi, vpls, bounces, bounce_candidates, ..DirParams::default() };
            let (frame, rmse, flip) = measure(&params)?;
            let bounce_ms: f64 = frame.report.passes.iter().filter(|p| p.pass.starts_with("bounce ")).map(|p| p.ms).sum();
            let found: Vec<String> = frame.report.bounces.iter().map(|b| format!("{}/{} found, {} VPLs", b.found, b.slots, b.vpls)).collect();
            println!("{:<18} {:<8} {:>6} {:>10.2} {:>10.5} {:>8.4}   bounces {bounces}, {bounce_candidates} candidates ({bounce_ms:.1} ms; {})", name, "gi", frame.report.vpls, frame.report.ms, rmse, flip, found.join("; "));
            rows.push(json!({
                "scene": name, "condition": "gi", "vpls": vpls, "bounces": bounces, "bounce_candidates": bounce_candidates, "bounce_ms": bounce_ms,
                "ms": frame.report.ms, "rmse": rmse, "flip": flip, "width": w, "height": h, "reference_spp": ref_spp,
                "bounce_report": frame.report.bounces, "passes": frame.report.passes,
            }));
        }
        // ISM resolution at 256 VPLs (0: VPLs unshadowed, no ISMs made)
        let ism_sizes: &[u32] = if quick { &[0, 64] } else { &[0, 32, 64, 128, 256] };
        let mut ism_rmse = Vec::new();
        let mut ism_flip = Vec::new();
        for &ism_size in ism_sizes {
            let params = DirParams { condition: Condition::Gi, vpls: 256, ism_size, ..DirParams::default() };
            let (frame, rmse, flip) = measure(&params)?;
            let ism_ms: f64 = frame.report.passes.iter().filter(|p| p.pass.starts_with("ISMs")).map(|p| p.ms).sum();
            println!("{:<18} {:<8} {:>6} {:>10.2} {:>10.5} {:>8.4}   ISM {}² ({:.1} ms)", name, "gi", frame.report.vpls, frame.report.ms, rmse, flip, ism_size, ism_ms);
            ism_rmse.push((ism_size.max(1) as f64, rmse));
            ism_flip.push((ism_size.max(1) as f64, flip));
            rows.push(json!({
                "scene": name, "condition": "gi", "vpls": 256, "ism_size": ism_size, "ism_points": params.ism_points, "ism_ms": ism_ms,
                "ms": frame.report.ms, "rmse": rmse, "flip": flip, "width": w, "height": h, "reference_spp": ref_spp, "passes": frame.report.passes,
            }));
        }
        plots.push((
            format!("render_gpu_ism_{name}.svg"),
            mrstudy_analysis::plot::line_plot(&mrstudy_analysis::plot::LinePlot {
                title: format!("DIR gi, 256 VPLs: error against ISM size ({name}, {w}x{h}, {adapter}; 1 = no ISMs)"),
                x_label: "ISM size (texels per side)".into(),
                y_label: "error in the affected region (display)".into(),
                x_log: true,
                y_log: false,
                series: vec![mrstudy_analysis::plot::LineSeries { name: "RMSE".into(), points: ism_rmse }, mrstudy_analysis::plot::LineSeries { name: "FLIP".into(), points: ism_flip }],
            }),
        ));
        // the colour mappings at gi: the time of each cm pass and of the composition
        let cm_vpls = if quick { 64 } else { 256 };
        for method in CmMethod::ALL {
            let params = DirParams { condition: Condition::Gi, vpls: cm_vpls, cm: CmParams { method, ..CmParams::default() }, ..DirParams::default() };
            let (frame, rmse, flip) = measure(&params)?;
            let cm_ms: f64 = frame.report.passes.iter().filter(|p| p.pass.starts_with("cm ")).map(|p| p.ms).sum();
            let compose_ms: f64 = frame.report.passes.iter().filter(|p| p.pass == "composition").map(|p| p.ms).sum();
            println!("{:<18} {:<8} {:>6} {:>10.2} {:>10.5} {:>8.4}  cm {:<10} {:>8.2} ms (+ composition {:.2} ms)", name, "gi", frame.report.vpls, frame.report.ms, rmse, flip, method.name(), cm_ms, compose_ms);
            rows.push(json!({
                "scene": name, "condition": "gi", "cm": method.name(), "vpls": cm_vpls, "ms": frame.report.ms, "cm_ms": cm_ms, "composition_ms": compose_ms,
                "rmse": rmse, "flip": flip, "width": w, "height": h, "reference_spp": ref_spp,
                "passes": frame.report.passes, "cm_report": frame.report.cm,
            }));
        }
        // interleaved sampling at 256 VPLs: the tile split n (n × n classes, merge filter)
        let splits: &[u32] = if quick { &[1, 4] } else { &[1, 2, 4] };
        for &interleave in splits {
            let params = DirParams { condition: Condition::Gi, vpls: 256, interleave, ..DirParams::default() };
            let (frame, rmse, flip) = measure(&params)?;
            let shading_ms: f64 = frame.report.passes.iter().filter(|p| p.pass.starts_with("shading") || p.pass.starts_with("indirect light")).map(|p| p.ms).sum();
            println!("{:<18} {:<8} {:>6} {:>10.2} {:>10.5} {:>8.4}   tiles {interleave}×{interleave} (shading + merge {shading_ms:.1} ms)", name, "gi", frame.report.vpls, frame.report.ms, rmse, flip);
            rows.push(json!({
                "scene": name, "condition": "gi", "vpls": 256, "interleave": interleave, "shading_ms": shading_ms,
                "ms": frame.report.ms, "rmse": rmse, "flip": flip, "width": w, "height": h, "reference_spp": ref_spp, "passes": frame.report.passes,
            }));
        }
        // the ca factor on top of gi (scene camera parameters): its pass time and the error
        for preset in ["webcam", "phone"] {
            let mut cam_scene = scene.clone();
            let seed = cam_scene.sensor.seed;
            cam_scene.sensor = SensorParams::preset(preset).context("preset")?;
            cam_scene.sensor.seed = seed;
            let photo = sensor::apply(&reference.hdr_real, &cam_scene.camera, &cam_scene.sensor);
            let truth = sensor::apply(&reference.hdr_full, &cam_scene.camera, &cam_scene.sensor);
            for ca in [false, true] {
                let params = DirParams { condition: Condition::Gi, camera_artifacts: ca.then(|| CaParams::from_sensor(&cam_scene.sensor)), ..DirParams::default() };
                renderer.render(&cam_scene, &photo, &params)?;
                let frame = renderer.render(&cam_scene, &photo, &params)?;
                let rmse = metrics::rmse(&truth, &frame.composite, Some(affected));
                let flip = metrics::flip(&truth, &frame.composite, Some(affected));
                let ca_ms = frame.report.passes.iter().find(|p| p.pass.starts_with("camera artifacts")).map(|p| p.ms);
                let label = if ca { format!("gi+ca/{preset}") } else { format!("gi/{preset}") };
                println!("{:<18} {:<12} {:>6} {:>10.2} {:>10.5} {:>8.4}   ca pass {}", name, label, frame.report.vpls, frame.report.ms, rmse, flip, ca_ms.map(|m| format!("{m:.2} ms")).unwrap_or_else(|| "-".into()));
                rows.push(json!({
                    "scene": name, "condition": if ca { "gi+ca" } else { "gi" }, "camera": preset, "vpls": params.vpls, "ms": frame.report.ms, "ca_ms": ca_ms,
                    "rmse": rmse, "flip": flip, "width": w, "height": h, "reference_spp": ref_spp, "passes": frame.report.passes,
                }));
            }
        }
        plots.push((
            format!("render_gpu_{name}.svg"),
            mrstudy_analysis::plot::line_plot(&mrstudy_analysis::plot::LinePlot {
                title: format!("DIR gi: error against VPL count ({name}, {w}x{h}, {adapter})"),
                x_label: "VPLs".into(),
                y_label: "error in the affected region (display)".into(),
                x_log: true,
                y_log: false,
                series: vec![mrstudy_analysis::plot::LineSeries { name: "RMSE".into(), points: points_rmse }, mrstudy_analysis::plot::LineSeries { name: "FLIP".into(), points: points_flip }],
            }),
        ));
    }
    // the thesis's setting at its resolution: 256 VPLs, 128² ISMs of 1024 points, 4×4 tiles,
    // 1024×768 — frame time only (a path-traced reference at this size is beyond this bench)
    let (tw, th) = if quick { (320, 240) } else { (1024, 768) };
    let scene = load_scene(&names[0], Some(&format!("{tw}x{th}")), None)?;
    let (_, photo, _) = render_photo(&scene, &ReferenceParams { spp: 1, ..ReferenceParams::default() }, &|_, _| {})?;
    for interleave in [1, 4] {
        let params = DirParams { condition: Condition::Gi, vpls: 256, ism_size: 128, ism_points: 1024, interleave, ..DirParams::default() };
        renderer.render(&scene, &photo, &params)?;
        let frame = renderer.render(&scene, &photo, &params)?;
        let fps = 1000.0 / frame.report.ms.max(1e-9);
        println!("{:<18} {:<8} {:>6} {:>10.2}   thesis setting at {tw}x{th}, tiles {interleave}×{interleave}: {fps:.2} fps", names[0], "gi", 256, frame.report.ms);
        rows.push(json!({
            "scene": names[0], "condition": "gi", "vpls": 256, "ism_size": 128, "ism_points": 1024, "interleave": interleave, "setting": "thesis",
            "ms": frame.report.ms, "fps": fps, "width": tw, "height": th, "passes": frame.report.passes,
        }));
    }
    Ok((adapter, rows, plots))
}

/// One point of the path tracer's error curve: RMSE of linear radiance against the ground
/// truth's, FLIP of the camera's output against the ground truth's (affected region).
struct PtPoint {
    spp: u32,
    ms: f64,
    rmse: f64,
    flip: f64,
}

/// The reference path tracer on the whole frame (real and virtual objects, seed 1000 — not the
/// ground truth's), at 1, 2, 4, … `max_spp` samples per pixel: cumulative time and the errors
/// of its image against the ground truth in the affected region.
fn path_tracer_curve(scene: &scene::Scene, reference: &mrstudy_renderer::ReferenceOutput, max_spp: u32) -> Vec<PtPoint> {
    let world = World::new(scene, Subset::All);
    let params = TraceParams { seed: 1000, ..TraceParams::default() };
    let mut acc = Accumulator::new(scene.camera.width, scene.camera.height);
    let mut points = Vec::new();
    let start = Instant::now();
    let mut spp = 1;
    while spp <= max_spp {
        acc.add_samples(&world, &scene.camera, &params, spp - acc.spp);
        let ms = start.elapsed().as_secs_f64() * 1e3;
        let image = acc.image();
        let display = sensor::apply(&image, &scene.camera, &scene.sensor);
        let rmse = metrics::rmse(&reference.hdr_full, &image, Some(&reference.affected_mask));
        let flip = metrics::flip(&reference.ground_truth, &display, Some(&reference.affected_mask));
        points.push(PtPoint { spp, ms, rmse, flip });
        spp *= 2;
    }
    points
}

/// DIR's composite in linear radiance, as the path tracer would see it: the photograph's
/// radiance (the reference's real-only render, which the camera would capture) plus
/// L_rv − L_r, and L_rv where the camera sees a virtual object. Errors of this image measure
/// the light transport alone — the display composite adds the tone mapping's mismatch with the
/// camera (the cm factor's business), which the path tracer, rendered through the true camera,
/// does not have.
fn dir_linear_composite(frame: &mrstudy_renderer::gpu::GpuRender, photo_radiance: &Image) -> Image {
    let mut out = photo_radiance.clone();
    for (i, p) in out.pixels.iter_mut().enumerate() {
        let (rv, r) = (frame.l_rv.pixels[i], frame.l_r.pixels[i]);
        let differential = *p + rv - r;
        *p = if frame.virtual_mask.values[i] > 0.5 { rv } else { differential.max(differential * 0.0) };
    }
    out
}

/// Whether the path tracer's time to an error is measured or only bounded.
#[derive(Clone, Copy, Debug)]
enum Bound {
    Exact,
    /// Already reached at 1 spp: the time is an upper bound.
    AtMost,
    /// Not reached at the curve's largest count: the time is a lower bound.
    AtLeast,
}

impl Bound {
    fn name(self) -> &'static str {
        match self {
            Bound::Exact => "interpolated",
            Bound::AtMost => "at most",
            Bound::AtLeast => "at least",
        }
    }
}

/// The path tracer's time to reach `error` by `metric`: interpolated in log time between the
/// two sample counts that bracket it (the error falls with the samples in expectation; the
/// first crossing is taken).
fn path_tracer_time_to(curve: &[PtPoint], error: f64, metric: impl Fn(&PtPoint) -> f64) -> (f64, Bound) {
    let Some(first) = curve.first() else { return (0.0, Bound::AtLeast) };
    if metric(first) <= error {
        return (first.ms, Bound::AtMost);
    }
    for pair in curve.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        let (ea, eb) = (metric(a), metric(b));
        if eb <= error {
            let f = if ea > eb { (ea - error) / (ea - eb) } else { 1.0 };
            return ((a.ms.ln() + f * (b.ms.ln() - a.ms.ln())).exp(), Bound::Exact);
        }
    }
    (curve.last().map_or(0.0, |p| p.ms), Bound::AtLeast)
}

/// `mrstudy bench render --ca`: how closely noise and blur on the virtual objects match the
/// camera, per scene and camera preset, with the ca factor off, on with the scene's camera
/// parameters and on with parameters estimated from the photograph. The ground truth (path
/// traced, through the simulated camera) shows what the camera does to the virtual objects;
/// the same estimators run on the same pixels of each GPU frame (`mrstudy_renderer::ca::accuracy`),
/// and on the untouched real pixels of the photograph. Also times the ca pass and reports the
/// frame's error against the ground truth in the affected region. Rows with `"layer":
/// "path-traced"` apply the chain (CPU reference) to the path-traced virtual objects through
/// the camera with its artifact stages off, which isolates the chain from the GPU renderer's
/// shading and tone mapping and shares the ground truth's path-tracing noise. Returns
/// (adapter, rows, plots).
pub fn bench_ca(scene_name: Option<&str>, quick: bool) -> Result<(String, Vec<Value>, Vec<(String, String)>)> {
    use mrstudy_renderer::ca::accuracy::{self, Regions};
    let names: Vec<String> = match scene_name {
        Some(n) => vec![n.to_string()],
        None if quick => vec!["dir-double-shadow".to_string()],
        None => ["survey-1", "survey-4", "dir-double-shadow", "dir-lamp-box"].iter().map(|s| s.to_string()).collect(),
    };
    let (w, h, ref_spp) = if quick { (128, 96, 64) } else { (192, 144, 256) };
    let presets = ["webcam", "phone"];
    let renderer = DirRenderer::new()?;
    let adapter = renderer.ctx.adapter_name();
    eprintln!("adapter: {adapter}");
    let mut rows = Vec::new();
    let modes: [(&str, Option<ParamSource>); 3] = [("off", None), ("scene", Some(ParamSource::Scene)), ("estimate", Some(ParamSource::Estimate))];
    let mut noise_series: Vec<Vec<(f64, f64)>> = vec![Vec::new(); modes.len() + 1];
    let mut blur_series: Vec<Vec<(f64, f64)>> = vec![Vec::new(); modes.len() + 1];
    let mut layer_series: Vec<Vec<(f64, f64)>> = vec![Vec::new(); modes.len() + 1];
    let mut layer_blur_series: Vec<Vec<(f64, f64)>> = vec![Vec::new(); modes.len() + 1];
    let mut configuration = 0.0;
    let fmt = |v: Option<f32>| v.map(|v| format!("{v:.2}")).unwrap_or_else(|| "-".into());
    // σ_virt: noise on the frame's virtual objects above the ca-off frame's floor; σ_gt: the
    // camera's noise on the same pixels of the ground truth (above its noise-free floor);
    // σ_real: the photograph's untouched pixels; r: blur as a disc radius (px)
    println!("{:<18} {:<7} {:<9} {:>9} {:>9} {:>9} {:>7} {:>7} {:>7} {:>9} {:>9}", "scene", "camera", "ca", "σ_virt", "σ_gt", "σ_real", "r_virt", "r_gt", "r_real", "ca ms", "rmse(aff)");
    for name in &names {
        let base = load_scene(name, Some(&format!("{w}x{h}")), None)?;
        eprintln!("{name} at {w}x{h}: reference at {ref_spp} spp …");
        let bar = progress_bar(2 * ref_spp as u64, "reference");
        let reference = render_reference(&base, &ReferenceParams { spp: ref_spp, pass_spp: 16, ..ReferenceParams::default() }, &|d, _| bar.set_position(d as u64))?;
        bar.finish_and_clear();
        for preset in presets {
            let mut scene = base.clone();
            let seed = scene.sensor.seed;
            scene.sensor = SensorParams::preset(preset).context("preset")?;
            scene.sensor.seed = seed;
            let photo = sensor::apply(&reference.hdr_real, &scene.camera, &scene.sensor);
            let truth = sensor::apply(&reference.hdr_full, &scene.camera, &scene.sensor);
            // the ground truth without sensor noise: its σ is the path tracer's noise and the
            // shading's residue, which the camera's σ is corrected for (σ_cam² = σ_gt² − σ_floor²)
            let mut quiet = scene.sensor.clone();
            quiet.noise = [0.0, 0.0];
            let truth_quiet = sensor::apply(&reference.hdr_full, &scene.camera, &quiet);
            let regions = Regions::new(&reference.virtual_mask, &reference.affected_mask, &scene.camera, &scene.sensor);
            let affected = accuracy::warp_mask(&reference.affected_mask, &scene.camera, &scene.sensor);
            let real = accuracy::measure(&photo, &regions.real, &regions.real);
            let gt = accuracy::measure(&truth, &regions.virtual_inner, &regions.virtual_edges);
            let floor = accuracy::measure(&truth_quiet, &regions.virtual_inner, &regions.virtual_edges).noise_sigma;
            let camera_sigma = (gt.noise_sigma.powi(2) - floor.powi(2)).max(0.0).sqrt();
            configuration += 1.0;
            noise_series[modes.len()].push((configuration, camera_sigma as f64));
            if let Some(r) = gt.blur_radius_px {
                blur_series[modes.len()].push((configuration, r as f64));
            }
            let mut frame_floor = 0.0f32;
            for (k, (mode, source)) in modes.iter().enumerate() {
                let camera_artifacts = source.map(|s| match s {
                    ParamSource::Scene => CaParams::from_sensor(&scene.sensor),
                    ParamSource::Estimate => estimate::params_from_photo(&photo, &scene.sensor).0,
                });
                let params = DirParams { condition: Condition::Gi, camera_artifacts, ..DirParams::default() };
                renderer.render(&scene, &photo, &params)?;
                let frame = renderer.render(&scene, &photo, &params)?;
                let stats = accuracy::measure(&frame.composite, &regions.virtual_inner, &regions.virtual_edges);
                if k == 0 {
                    frame_floor = stats.noise_sigma;
                }
                let virtual_sigma = (stats.noise_sigma.powi(2) - frame_floor.powi(2)).max(0.0).sqrt();
                let ca_ms = frame.report.passes.iter().find(|p| p.pass.starts_with("camera artifacts")).map(|p| p.ms);
                let rmse = metrics::rmse(&truth, &frame.composite, Some(&affected));
                let flip = metrics::flip(&truth, &frame.composite, Some(&affected));
                println!(
                    "{:<18} {:<7} {:<9} {:>9.5} {:>9.5} {:>9.5} {:>7} {:>7} {:>7} {:>9} {:>9.5}",
                    name,
                    preset,
                    mode,
                    virtual_sigma,
                    camera_sigma,
                    real.noise_sigma,
                    fmt(stats.blur_radius_px),
                    fmt(gt.blur_radius_px),
                    fmt(real.blur_radius_px),
                    ca_ms.map(|m| format!("{m:.2}")).unwrap_or_else(|| "-".into()),
                    rmse
                );
                noise_series[k].push((configuration, virtual_sigma as f64));
                if let Some(r) = stats.blur_radius_px {
                    blur_series[k].push((configuration, r as f64));
                }
                rows.push(json!({
                    "bench": "ca-accuracy", "scene": name, "camera": preset, "ca": mode, "configuration": configuration,
                    "width": w, "height": h, "reference_spp": ref_spp,
                    "virtual": stats, "ground_truth_virtual": gt, "photo_real": real,
                    "virtual_noise_sigma": virtual_sigma, "camera_noise_sigma": camera_sigma,
                    "ground_truth_noise_floor": floor, "frame_noise_floor": frame_floor,
                    "noise_ratio_to_ground_truth": if camera_sigma > 0.0 { Some(virtual_sigma / camera_sigma) } else { None },
                    "blur_difference_to_ground_truth_px": stats.blur_radius_px.zip(gt.blur_radius_px).map(|(a, b)| a - b),
                    "ca_ms": ca_ms, "ms": frame.report.ms, "rmse": rmse, "flip": flip,
                    "ca_params": frame.report.params.camera_artifacts, "layer": "gpu",
                }));
            }
            // the chain alone, without the GPU renderer's shading and tone differences: the
            // virtual layer is the path-traced radiance through the camera with every artifact
            // stage off (the same path-tracing noise as the ground truth), then the ca chain
            let mut clean = scene.sensor.clone();
            clean.distortion = [0.0; 5];
            clean.chromatic_aberration = 0.0;
            clean.defocus_px = 0.0;
            clean.bayer = false;
            clean.noise = [0.0, 0.0];
            clean.sharpen = 0.0;
            clean.jpeg_quality = None;
            clean.vignetting = 0.0;
            let clean_full = sensor::apply(&reference.hdr_full, &scene.camera, &clean);
            let coverage = Mask { width: w, height: h, values: reference.virtual_mask.values.iter().map(|v| if *v > 0.5 { 1.0 } else { 0.0 }).collect() };
            let mut layer = photo.clone();
            for (i, px) in layer.pixels.iter_mut().enumerate() {
                if coverage.values[i] > 0.0 {
                    *px = clean_full.pixels[i];
                }
            }
            for (k, (mode, source)) in modes.iter().enumerate() {
                let mut cpu_ms = 0.0;
                let out = match source {
                    None => layer.clone(),
                    Some(s) => {
                        let p = if *s == ParamSource::Scene { CaParams::from_sensor(&scene.sensor) } else { estimate::params_from_photo(&photo, &scene.sensor).0 };
                        let start = Instant::now();
                        let out = mrstudy_renderer::ca::apply_cpu(&layer, &photo, &coverage, &scene.camera, &p)?.0;
                        cpu_ms = start.elapsed().as_secs_f64() * 1e3;
                        out
                    }
                };
                let rmse = metrics::rmse(&truth, &out, Some(&affected));
                let flip = metrics::flip(&truth, &out, Some(&affected));
                let stats = accuracy::measure(&out, &regions.virtual_inner, &regions.virtual_edges);
                println!(
                    "{:<18} {:<7} {:<9} {:>9.5} {:>9.5} {:>9.5} {:>7} {:>7} {:>7} {:>9} {:>9.5}",
                    name,
                    preset,
                    format!("pt-{mode}"),
                    stats.noise_sigma,
                    gt.noise_sigma,
                    real.noise_sigma,
                    fmt(stats.blur_radius_px),
                    fmt(gt.blur_radius_px),
                    fmt(real.blur_radius_px),
                    format!("{cpu_ms:.0} cpu"),
                    rmse
                );
                layer_series[k].push((configuration, stats.noise_sigma as f64));
                if let Some(r) = stats.blur_radius_px {
                    layer_blur_series[k].push((configuration, r as f64));
                }
                rows.push(json!({
                    "bench": "ca-accuracy", "scene": name, "camera": preset, "ca": mode, "configuration": configuration, "layer": "path-traced",
                    "width": w, "height": h, "reference_spp": ref_spp,
                    "virtual": stats, "ground_truth_virtual": gt, "photo_real": real,
                    "noise_ratio_to_ground_truth": if gt.noise_sigma > 0.0 { Some(stats.noise_sigma / gt.noise_sigma) } else { None },
                    "blur_difference_to_ground_truth_px": stats.blur_radius_px.zip(gt.blur_radius_px).map(|(a, b)| a - b),
                    "ms": cpu_ms, "rmse": rmse, "flip": flip, "timed_on": "cpu (CPU reference implementation)",
                }));
            }
            layer_series[modes.len()].push((configuration, gt.noise_sigma as f64));
            if let Some(r) = gt.blur_radius_px {
                layer_blur_series[modes.len()].push((configuration, r as f64));
            }
        }
    }
    let names_of = ["ca off", "ca scene", "ca estimate", "ground truth"];
    let series = |data: &[Vec<(f64, f64)>]| data.iter().zip(names_of).map(|(p, n)| mrstudy_analysis::plot::LineSeries { name: n.into(), points: p.clone() }).collect();
    let plots = vec![
        (
            "render_ca_noise.svg".to_string(),
            mrstudy_analysis::plot::line_plot(&mrstudy_analysis::plot::LinePlot {
                title: format!("ca: noise σ on the virtual objects ({w}x{h}, {adapter})"),
                x_label: "configuration (scene × camera, see the table)".into(),
                y_label: "camera noise σ above the noise-free floor (Immerkær, display)".into(),
                x_log: false,
                y_log: true,
                series: series(&noise_series),
            }),
        ),
        (
            "render_ca_blur.svg".to_string(),
            mrstudy_analysis::plot::line_plot(&mrstudy_analysis::plot::LinePlot {
                title: format!("ca: blur on the virtual objects' edges ({w}x{h}, {adapter})"),
                x_label: "configuration (scene × camera, see the table)".into(),
                y_label: "equivalent disc radius (px)".into(),
                x_log: false,
                y_log: false,
                series: series(&blur_series),
            }),
        ),
        (
            "render_ca_noise_layer.svg".to_string(),
            mrstudy_analysis::plot::line_plot(&mrstudy_analysis::plot::LinePlot {
                title: format!("ca chain alone on the path-traced virtual layer: noise σ ({w}x{h}, CPU reference)"),
                x_label: "configuration (scene × camera, see the table)".into(),
                y_label: "Immerkær σ on the virtual objects (display)".into(),
                x_log: false,
                y_log: true,
                series: series(&layer_series),
            }),
        ),
        (
            "render_ca_blur_layer.svg".to_string(),
            mrstudy_analysis::plot::line_plot(&mrstudy_analysis::plot::LinePlot {
                title: format!("ca chain alone on the path-traced virtual layer: blur ({w}x{h}, CPU reference)"),
                x_label: "configuration (scene × camera, see the table)".into(),
                y_label: "equivalent disc radius (px)".into(),
                x_log: false,
                y_log: false,
                series: series(&layer_blur_series),
            }),
        ),
    ];
    Ok((adapter, rows, plots))
}

/// The camera settings of the cm accuracy benchmark: Figure 4.16's rows (normal; contrast up and
/// down; saturation up and down) and exposure changes, each relative to the preset.
const CM_SETTINGS: [(&str, fn(&mut SensorParams)); 7] = [
    ("normal", |_| {}),
    ("contrast+", |p| p.contrast *= 1.3),
    ("contrast-", |p| p.contrast *= 0.75),
    ("saturation+", |p| p.saturation *= 1.4),
    ("saturation-", |p| p.saturation *= 0.6),
    ("exposure+1", |p| p.exposure_ev += 1.0),
    ("exposure-1", |p| p.exposure_ev -= 1.0),
];

/// Mean and 95th percentile of a list of errors (0 and 0 when empty).
fn mean_p95(errors: &mut [f64]) -> (f64, f64) {
    if errors.is_empty() {
        return (0.0, 0.0);
    }
    errors.sort_by(f64::total_cmp);
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    let k = ((0.95 * errors.len() as f64).ceil() as usize).clamp(1, errors.len()) - 1;
    (mean, errors[k])
}

/// `mrstudy bench render --cm`: each colour-mapping method's colour error on the virtual
/// objects against the ground-truth composite through the known camera. Per built-in scene the
/// path tracer renders the real-only and full HDR buffers once; per camera preset and setting
/// ([`CM_SETTINGS`]) both go through the simulated camera — with its geometric stages
/// (distortion, chromatic aberration, defocus) off, as they belong to the `ca` factor — and the
/// GPU frame (gi, 128 VPLs) is composed over the photograph with each cm method. Error: CIEDE2000
/// (sRGB → CIELab; the E-scaled Lab of `cm::colour` equals D65 Lab for sRGB input) over the
/// pixels where the G-buffer sees a virtual surface and the path tracer's coverage is full.
pub fn bench_cm(scene_name: Option<&str>, quick: bool) -> Result<(String, Vec<Value>, Vec<(String, String)>)> {
    let names: Vec<String> = match scene_name {
        Some(n) => vec![n.to_string()],
        None if quick => vec!["survey-1".to_string()],
        None => builtin::names().map(str::to_string).collect(),
    };
    let (w, h, spp) = if quick { (80, 60, 16) } else { (160, 120, 64) };
    let presets: Vec<&str> = if quick { vec!["webcam"] } else { SensorParams::PRESETS.to_vec() };
    let renderer = DirRenderer::new()?;
    let adapter = renderer.ctx.adapter_name();
    eprintln!("adapter: {adapter}");
    let mut rows = Vec::new();
    let mut warmed = false;
    // (preset, setting, method) → per-scene (mean, p95)
    let mut summary: std::collections::BTreeMap<(usize, usize, usize), Vec<(f64, f64)>> = Default::default();
    println!("{:<18} {:<7} {:<12} {:<11} {:>8} {:>8} {:>7} {:>8}", "scene", "camera", "setting", "cm", "dE mean", "dE p95", "pixels", "cm ms");
    for name in &names {
        let scene = load_scene(name, Some(&format!("{w}x{h}")), None)?;
        eprintln!("{name} at {w}x{h}: reference at {spp} spp …");
        let bar = progress_bar(2 * spp as u64, "reference");
        let reference = render_reference(&scene, &ReferenceParams { spp, pass_spp: 16, ..ReferenceParams::default() }, &|d, _| bar.set_position(d as u64))?;
        bar.finish_and_clear();
        for (pi, preset) in presets.iter().enumerate() {
            for (si, (setting, alter)) in CM_SETTINGS.iter().enumerate() {
                let mut sensor = SensorParams::preset(preset).with_context(|| format!("no camera preset `{preset}`"))?;
                sensor.seed = scene.sensor.seed;
                sensor.distortion = [0.0; 5];
                sensor.chromatic_aberration = 0.0;
                sensor.defocus_px = 0.0;
                alter(&mut sensor);
                let photo = sensor::apply(&reference.hdr_real, &scene.camera, &sensor);
                let truth = sensor::apply(&reference.hdr_full, &scene.camera, &sensor);
                for (mi, method) in CmMethod::ALL.iter().enumerate() {
                    let params = DirParams { condition: Condition::Gi, vpls: 128, cm: CmParams { method: *method, ..CmParams::default() }, ..DirParams::default() };
                    if !warmed {
                        // the first frame of each method compiles its shaders on software adapters
                        renderer.render(&scene, &photo, &params)?;
                    }
                    let frame = renderer.render(&scene, &photo, &params)?;
                    let mut errors: Vec<f64> = (0..photo.pixels.len())
                        .filter(|&i| frame.flags[i] == 2 && reference.virtual_mask.values[i] >= 0.999)
                        .map(|i| mrstudy_renderer::cm::colour::ciede2000_display(truth.pixels[i], frame.composite.pixels[i]))
                        .collect();
                    let pixels = errors.len();
                    let (mean, p95) = mean_p95(&mut errors);
                    let cm_ms: f64 = frame.report.passes.iter().filter(|p| p.pass.starts_with("cm ")).map(|p| p.ms).sum();
                    println!("{:<18} {:<7} {:<12} {:<11} {:>8.2} {:>8.2} {:>7} {:>8.2}", name, preset, setting, method.name(), mean, p95, pixels, cm_ms);
                    rows.push(json!({
                        "scene": name, "camera": preset, "setting": setting, "cm": method.name(),
                        "de2000_mean": mean, "de2000_p95": p95, "pixels": pixels, "cm_ms": cm_ms, "ms": frame.report.ms,
                        "fallback": frame.report.cm.fallback, "cm_pairs": frame.report.cm.pairs,
                        "width": w, "height": h, "reference_spp": spp, "vpls": 128,
                    }));
                    if pixels > 0 {
                        summary.entry((pi, si, mi)).or_default().push((mean, p95));
                    }
                }
                warmed = true;
            }
        }
    }
    // the averages over scenes: a table and, per camera preset, a plot
    println!("\nmean over scenes of CIEDE2000 on virtual pixels: mean (95th percentile)");
    print!("{:<7} {:<12}", "camera", "setting");
    for m in CmMethod::ALL {
        print!(" {:>16}", m.name());
    }
    println!();
    let mut plots = Vec::new();
    for (pi, preset) in presets.iter().enumerate() {
        let mut series: Vec<Vec<(f64, f64)>> = vec![Vec::new(); CmMethod::ALL.len()];
        for (si, (setting, _)) in CM_SETTINGS.iter().enumerate() {
            print!("{:<7} {:<12}", preset, setting);
            for (mi, method) in CmMethod::ALL.iter().enumerate() {
                let v = summary.get(&(pi, si, mi)).cloned().unwrap_or_default();
                let n = v.len().max(1) as f64;
                let (mean, p95) = (v.iter().map(|x| x.0).sum::<f64>() / n, v.iter().map(|x| x.1).sum::<f64>() / n);
                print!(" {:>7.2} ({:>6.2})", mean, p95);
                series[mi].push(((si + 1) as f64, mean));
                rows.push(json!({ "scene": "mean over scenes", "scenes": v.len(), "camera": preset, "setting": setting, "cm": method.name(), "de2000_mean": mean, "de2000_p95": p95 }));
            }
            println!();
        }
        plots.push((
            format!("render_cm_{preset}.svg"),
            mrstudy_analysis::plot::line_plot(&mrstudy_analysis::plot::LinePlot {
                title: format!("cm accuracy, camera {preset} ({w}x{h}, mean over {} scenes, {adapter})", names.len()),
                x_label: "setting: 1 normal, 2 contrast+, 3 contrast-, 4 saturation+, 5 saturation-, 6 exposure+1, 7 exposure-1".into(),
                y_label: "CIEDE2000 on virtual pixels (mean)".into(),
                x_log: false,
                y_log: false,
                series: CmMethod::ALL.iter().zip(series).map(|(m, points)| mrstudy_analysis::plot::LineSeries { name: m.name().into(), points }).collect(),
            }),
        ));
    }
    Ok((adapter, rows, plots))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_path_tracers_time_to_an_error_is_interpolated_or_bounded() {
        let curve: Vec<PtPoint> = [(1, 10.0, 0.8), (2, 20.0, 0.6), (4, 40.0, 0.4)].iter().map(|&(spp, ms, flip)| PtPoint { spp, ms, rmse: 0.0, flip }).collect();
        let (ms, bound) = path_tracer_time_to(&curve, 0.5, |p| p.flip);
        // halfway between 0.6 and 0.4: halfway in log time between 20 and 40 ms
        assert!(matches!(bound, Bound::Exact) && (ms - 800f64.sqrt()).abs() < 1e-9, "{ms}");
        let (ms, bound) = path_tracer_time_to(&curve, 0.6, |p| p.flip);
        assert!(matches!(bound, Bound::Exact) && (ms - 20.0).abs() < 1e-9, "{ms}");
        assert!(matches!(path_tracer_time_to(&curve, 0.9, |p| p.flip), (10.0, Bound::AtMost)));
        assert!(matches!(path_tracer_time_to(&curve, 0.1, |p| p.flip), (40.0, Bound::AtLeast)));
        assert!(matches!(path_tracer_time_to(&[], 0.1, |p| p.flip), (_, Bound::AtLeast)));
    }
}
