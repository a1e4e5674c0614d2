//! `mrstudy render` and `mrstudy bench render --reference`: thin wrappers over
//! `mrstudy-renderer`. `render --reference` writes the ground-truth composite, `--photo` the
//! photograph of the real scene, both by the CPU reference path tracer through the scene's
//! simulated camera; `--buffers DIR` also writes the HDR buffers, both camera images, the masks
//! and a JSON report. Conditions (`--condition gi|shadows|none`, `--factors gi`) render on the
//! GPU (differential instant radiosity, `mrstudy_renderer::gpu`) over the path-traced
//! photograph, at 1024x768 unless `--size` says otherwise. The factor `cm` (`--factors gi,cm`)
//! is the thesis's statistics-based colour mapping; `--cm off|statistics|samples|rohmer` picks
//! any method and `--composition additive|scaled` the composition. The factor `ca` is not
//! built yet and is refused. `bench render --cm` measures each cm method's colour error on the
//! virtual objects against the ground truth through the known camera ([`bench_cm`]).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
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
    /// Factors to switch on, on the GPU: `gi`, `cm` (the statistics-based colour mapping);
    /// `ca` is not built yet.
    #[arg(long)]
    factors: Option<String>,
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

/// The `gi` level and the colour mapping asked for by `--condition`/`--factors` and `--cm`.
fn condition_of(args: &RenderArgs) -> Result<(Condition, CmMethod)> {
    let mut method = CmMethod::Off;
    let condition = if let Some(name) = &args.condition {
        Condition::parse(name).with_context(|| format!("--condition `{name}` is not one of gi, shadows, none (for colour mapping add --cm)"))?
    } else {
        let mut condition = Condition::None;
        for factor in args.factors.as_deref().unwrap_or("").split(',').map(str::trim).filter(|f| !f.is_empty()) {
            match factor {
                "gi" => condition = Condition::Gi,
                "cm" => method = CmMethod::Statistics,
                "ca" => bail!("the factor `ca` (camera artifacts) is not built yet; gi and cm render on the GPU"),
                other => bail!("--factors: unknown factor `{other}`; expected gi or cm (ca is not built yet)"),
            }
        }
        condition
    };
    if let Some(name) = &args.cm {
        method = CmMethod::parse(name).with_context(|| format!("--cm `{name}` is not one of off, statistics, samples, rohmer"))?;
    }
    Ok((condition, method))
}

/// `render --condition …`: the photograph by the path tracer, then the GPU frame over it.
fn render_condition(args: &RenderArgs, name: &str) -> Result<()> {
    let (condition, method) = condition_of(args)?;
    let composition = Composition::parse(&args.composition).with_context(|| format!("--composition `{}` is not one of additive, scaled", args.composition))?;
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
    let dir_params = DirParams { condition, vpls: args.vpls, cm: CmParams { method, ..CmParams::default() }, composition, ..DirParams::default() };
    let frame = renderer.render(&scene, &photo, &dir_params)?;
    save_by_extension(out, &frame.composite.srgb_to_linear(), &frame.composite)?;
    if let Some(dir) = &args.buffers {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        photo.save_png(&dir.join("photo.png"))?;
        frame.composite.save_png(&dir.join("composite.png"))?;
        frame.l_rv.save_exr(&dir.join("l_rv.exr"))?;
        frame.l_r.save_exr(&dir.join("l_r.exr"))?;
        frame.virtual_mask.save_png(&dir.join("virtual_mask.png"))?;
        write_json(&dir.join("report.json"), &json!({ "gpu": frame.report, "photo_seconds": photo_stats.seconds }))?;
    }
    for pass in &frame.report.passes {
        eprintln!("  {:<40} {:>9.2} ms", pass.pass, pass.ms);
    }
    if let Some(why) = &frame.report.cm.fallback {
        eprintln!("warning: colour mapping {}: {why}", method.name());
    }
    eprintln!(
        "wrote {} ({} condition, cm {}, {} VPLs): photo {:.1} s on the CPU, GPU frame {:.1} ms on {}",
        out.display(),
        condition.name(),
        method.name(),
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
/// (16 … 1024). Each frame is rendered twice and the second timed (the first compiles the
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
        let mut settings: Vec<(Condition, u32)> = vec![(Condition::None, 0), (Condition::Shadows, 0)];
        settings.extend(vpl_counts.iter().map(|&n| (Condition::Gi, n)));
        let mut points_rmse = Vec::new();
        let mut points_flip = Vec::new();
        for (condition, vpls) in settings {
            let params = DirParams { condition, vpls, ..DirParams::default() };
            renderer.render(&scene, &reference.photo, &params)?;
            let frame = renderer.render(&scene, &reference.photo, &params)?;
            let rmse = metrics::rmse(&reference.ground_truth, &frame.composite, Some(affected));
            let flip = metrics::flip(&reference.ground_truth, &frame.composite, Some(affected));
            let ms = frame.report.ms;
            println!("{:<18} {:<8} {:>6} {:>10.2} {:>10.5} {:>8.4}", name, condition.name(), frame.report.vpls, ms, rmse, flip);
            if condition == Condition::Gi {
                points_rmse.push((vpls as f64, rmse));
                points_flip.push((vpls as f64, flip));
            }
            rows.push(json!({
                "scene": name, "condition": condition.name(), "vpls": vpls, "ms": ms, "rmse": rmse, "flip": flip,
                "width": w, "height": h, "reference_spp": ref_spp, "shadow_map_size": params.shadow_map_size, "rsm_size": params.rsm_size,
                "passes": frame.report.passes,
            }));
        }
        // the colour mappings at gi: the time of each cm pass and of the composition
        let cm_vpls = if quick { 64 } else { 256 };
        for method in CmMethod::ALL {
            let params = DirParams { condition: Condition::Gi, vpls: cm_vpls, cm: CmParams { method, ..CmParams::default() }, ..DirParams::default() };
            renderer.render(&scene, &reference.photo, &params)?;
            let frame = renderer.render(&scene, &reference.photo, &params)?;
            let rmse = metrics::rmse(&reference.ground_truth, &frame.composite, Some(affected));
            let flip = metrics::flip(&reference.ground_truth, &frame.composite, Some(affected));
            let cm_ms: f64 = frame.report.passes.iter().filter(|p| p.pass.starts_with("cm ")).map(|p| p.ms).sum();
            let compose_ms: f64 = frame.report.passes.iter().filter(|p| p.pass == "composition").map(|p| p.ms).sum();
            println!("{:<18} {:<8} {:>6} {:>10.2} {:>10.5} {:>8.4}  cm {:<10} {:>8.2} ms (+ composition {:.2} ms)", name, "gi", frame.report.vpls, frame.report.ms, rmse, flip, method.name(), cm_ms, compose_ms);
            rows.push(json!({
                "scene": name, "condition": "gi", "cm": method.name(), "vpls": cm_vpls, "ms": frame.report.ms, "cm_ms": cm_ms, "composition_ms": compose_ms,
                "rmse": rmse, "flip": flip, "width": w, "height": h, "reference_spp": ref_spp,
                "passes": frame.report.passes, "cm_report": frame.report.cm,
            }));
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
