//! `mrstudy render`: a thin wrapper over `mrstudy-renderer`. `render --reference` writes the
//! ground-truth composite, `--photo` the photograph of the real scene, both by the CPU
//! reference path tracer through the scene's simulated camera; `--buffers DIR` also writes the
//! HDR buffers, both camera images, the masks and a JSON report. Conditions
//! (`--condition gi|shadows|none`, `--factors gi,cm,ca`, read by `stimulus::Factors`) render on
//! the GPU (differential instant radiosity, `mrstudy_renderer::gpu`) over the path-traced
//! photograph, at 1024x768 unless `--size` says otherwise, with a stimulus's parameters
//! (`StimulusSettings::params`) and the knobs below; `--cm` picks any colour mapping,
//! `--composition` the composition, `--ca-params scene|estimate` where the `ca` factor's
//! camera comes from.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use mrstudy_renderer::ca::ParamSource;
use mrstudy_renderer::cm::{CmMethod, Composition};
use mrstudy_renderer::gpu::{DirRenderer, GiLevel};
use mrstudy_renderer::image::save_by_extension;
use mrstudy_renderer::reference::{ReferenceParams, render_photo, render_reference, write_photo_buffers};
use mrstudy_renderer::sensor::SensorParams;
use mrstudy_renderer::stimulus::{ConditionRender, Factors, RenderKnobs, render_condition};
use mrstudy_renderer::{builtin, scene};
use serde_json::json;

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
    #[arg(long, conflicts_with = "factors", value_parser = crate::choice(GiLevel::parse, "gi, shadows, none (for colour mapping add --cm, for camera artifacts use --factors)"))]
    condition: Option<GiLevel>,
    /// Factors to switch on, on the GPU: `gi` (indirect light and shadows), `cm` (the
    /// statistics-based colour mapping), `ca` (camera artifacts).
    #[arg(long, value_parser = Factors::parse_list)]
    factors: Option<Factors>,
    /// Where the `ca` factor takes its parameters: `scene` (the scene's simulated camera) or
    /// `estimate` (noise, blur and JPEG quality measured on the photograph).
    #[arg(long, default_value = "scene", value_parser = crate::choice(ParamSource::parse, "scene, estimate"))]
    ca_params: ParamSource,
    /// GPU: the colour mapping of the GI buffers: off (Reinhard), statistics, samples or rohmer
    /// (overrides what --factors implies).
    #[arg(long, value_parser = crate::choice(CmMethod::parse, "off, statistics, samples, rohmer"))]
    cm: Option<CmMethod>,
    /// GPU: the composition: additive (default) or scaled (Debevec: α = L'_cam / τ(L_r)).
    #[arg(long, default_value = "additive", value_parser = crate::choice(Composition::parse, "additive, scaled"))]
    composition: Composition,
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
        scene.sensor = SensorParams::preset(preset)
            .with_context(|| format!("--camera `{preset}` is not one of webcam, phone, clean"))?;
        scene.sensor.seed = seed;
    }
    Ok(scene)
}

pub fn progress_bar(total: u64, label: &str) -> ProgressBar {
    let bar = ProgressBar::new(total);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} spp {elapsed_precise} (eta {eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
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
        return run_condition(&args, name);
    }
    if !(args.reference || args.photo) {
        bail!(
            "say what to render: --condition gi|shadows|none (GPU), or --reference or --photo (CPU reference path tracer)"
        );
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
            write_photo_buffers(dir, &scene.name, &hdr, &photo, &stats)?;
        }
        report(&stats.warnings, stats.seconds, stats.samples_per_second, out);
    } else {
        let bar = progress_bar(2 * args.spp as u64, &label);
        let result = render_reference(&scene, &params, &|done, _| bar.set_position(done as u64))?;
        bar.finish_and_clear();
        save_by_extension(out, &result.hdr_full, &result.ground_truth)?;
        if let Some(dir) = &args.buffers {
            result.write_buffers(dir, &scene.name)?;
        }
        report(&result.stats.warnings, result.stats.seconds, result.stats.samples_per_second, out);
    }
    Ok(())
}

/// `render --condition …`: the photograph by the path tracer, then the GPU frame over it.
fn run_condition(args: &RenderArgs, name: &str) -> Result<()> {
    // `--condition` is the gi level alone; `--cm` alone renders every factor off
    let factors = match args.condition {
        Some(gi) => Factors { gi, cm: false, ca: false },
        None => args.factors.map_or_else(|| Factors::parse_list(""), Ok).map_err(|e| anyhow!("--factors: {e}"))?,
    };
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
    let knobs = RenderKnobs {
        vpls: args.vpls,
        ism_size: args.ism_size,
        ism_points: args.ism_points,
        bounces: args.bounces,
        bounce_candidates: args.bounce_candidates,
        composition: args.composition,
        cm: args.cm,
        ca_source: args.ca_params,
    };
    let ConditionRender { frame, params, ca_estimates } =
        render_condition(&renderer, &scene, &photo, &factors, &knobs)?;
    if let Some(estimates) = &ca_estimates {
        eprintln!("ca estimates from the photograph: {estimates}");
    }
    save_by_extension(out, &frame.composite.srgb_to_linear(), &frame.composite)?;
    if let Some(dir) = &args.buffers {
        let extra = json!({ "photo_seconds": photo_stats.seconds, "ca_estimates": ca_estimates });
        frame.write_buffers(dir, &photo, extra)?;
    }
    for pass in &frame.report.passes {
        eprintln!("  {:<40} {:>9.2} ms", pass.pass, pass.ms);
    }
    let method = params.cm.method;
    if let Some(why) = &frame.report.cm.fallback {
        eprintln!("warning: colour mapping {}: {why}", method.name());
    }
    eprintln!(
        "wrote {} ({} condition, cm {}{}, {} VPLs): photo {:.1} s on the CPU, GPU frame {:.1} ms on {}",
        out.display(),
        factors.gi.name(),
        method.name(),
        if factors.ca {
            format!(
                ", ca from the {}",
                if args.ca_params == ParamSource::Scene { "scene's camera" } else { "photograph" }
            )
        } else {
            String::new()
        },
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
