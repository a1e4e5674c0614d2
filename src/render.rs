//! `mrstudy render`: the flags, then `scene::load_as`, and `reference::render_to_file` (the CPU
//! reference path tracer: `--photo`, `--reference`) or `stimulus::render_condition_to_file`
//! (a condition on the GPU over the path-traced photograph) or `coherent::render::render_to_file`
//! (`--gi-method`: Rohmer et al.'s methods from a simulated capture) with a progress bar;
//! `--contact-sheet`: `contact_sheet::render` over the web survey's conditions or a study's.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use mrstudy_renderer::ca::ParamSource;
use mrstudy_renderer::cm::{CmMethod, Composition};
use mrstudy_renderer::coherent::{CoherentParams, Method, Quality};
use mrstudy_renderer::gpu::GiLevel;
use mrstudy_renderer::gpu::ism::IsmSplatting;
use mrstudy_renderer::reference::{ReferenceParams, Target, render_to_file};
use mrstudy_renderer::sensor::SensorParams;
use mrstudy_renderer::stimulus::{Factors, RenderKnobs, StimulusSettings, render_condition_to_file};
use mrstudy_renderer::{builtin, contact_sheet, scene};

use crate::progress::progress_bar;

flags! {
    RenderArgs {
        /// List the built-in scene names, one per line.
        #[arg(long)] list: bool,
        /// A built-in scene name or a scene file (TOML).
        #[arg(long)] scene: Option<String>,
        /// Render the ground-truth composite (real and virtual objects) with the reference path tracer.
        #[arg(long, conflicts_with_all = ["photo", "condition", "factors", "cm"])] reference: bool,
        /// Render the photograph (real objects only) with the reference path tracer.
        #[arg(long, conflicts_with_all = ["condition", "factors", "cm"])] photo: bool,
        /// A condition by name, on the GPU: `gi` (shadows and indirect light), `shadows`, or `none`.
        #[arg(long, conflicts_with = "factors", value_parser = crate::choice(GiLevel::parse, "gi, shadows, none (for colour mapping add --cm, for camera artifacts use --factors)"))] condition: Option<GiLevel>,
        /// Factors to switch on, on the GPU: `gi` (indirect light and shadows), `cm` (the statistics-based colour mapping), `ca` (camera artifacts); caustics of mirrors and glass come with `gi` and `shadows` (`--caustic-map-size 0` turns them off).
        #[arg(long, value_parser = Factors::parse_list)] factors: Option<Factors>,
        #[command(flatten)] knobs: KnobsFlags,
        /// Render by one of Rohmer et al.'s methods from a simulated capture of the real scene (CPU): `em`, `dit`, `vct`, or `off` (no coherent rendering); prints its errors against the ground truth.
        #[arg(long, conflicts_with_all = ["reference", "photo", "condition", "factors", "cm"], value_parser = crate::choice(Method::parse, "em, dit, vct, off"))] gi_method: Option<Method>,
        /// The paper's quality setting of `--gi-method`: low, med or high.
        #[arg(long, default_value = "med", value_parser = crate::choice(Quality::parse, "low, med, high"))] quality: Quality,
        /// Samples per pixel of the reference path tracer.
        #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..))] spp: u32,
        /// Image size WxH (intrinsics scale with it); default: the scene's.
        #[arg(long, value_parser = scene::parse_size)] size: Option<(u32, u32)>,
        /// Random seed of the path tracer.
        #[arg(long, default_value_t = 1)] seed: u64,
        /// Replace the scene's simulated camera by a preset: webcam, phone or clean.
        #[arg(long, value_parser = crate::choice(SensorParams::preset, "webcam, phone, clean"))] camera: Option<SensorParams>,
        /// Output image: `.png` (camera output) or `.exr` (linear HDR radiance).
        #[arg(long)] out: Option<PathBuf>,
        /// Also write every buffer into this directory: photo.png, ground_truth.png, real.exr, full.exr, virtual_mask.png, affected_mask.png, report.json.
        #[arg(long)] buffers: Option<PathBuf>,
        /// Print the scene as a scene file (TOML) and exit.
        #[arg(long)] print_toml: bool,
        /// Write a contact sheet (PNG): the ground truth, the photograph and the stimulus of each condition side by side, labelled, rendered as a study renders them (default size 200x150).
        #[arg(long, value_name = "FILE.png", conflicts_with_all = ["reference", "photo", "condition", "factors", "gi_method", "out"])] contact_sheet: Option<PathBuf>,
        /// The conditions of the contact sheet: those of this study file (default: the web survey's eight, LQ … HQ).
        #[arg(long, value_name = "FILE", requires = "contact_sheet")] study: Option<PathBuf>,
    }
}

flags! {
    /// [`RenderKnobs`]' flags; their defaults are its `Default` (a test checks).
    KnobsFlags => RenderKnobs {} {
        /// GPU: the VPL budget of the `gi` condition.
        #[arg(long, default_value_t = RenderKnobs::default().vpls)] vpls: u32,
        /// GPU: resolution of each VPL's imperfect shadow map (0: VPLs unshadowed).
        #[arg(long, default_value_t = RenderKnobs::default().ism_size)] ism_size: u32,
        /// GPU: points per cloud (real, virtual) splatted into each VPL's imperfect shadow map.
        #[arg(long, default_value_t = RenderKnobs::default().ism_points)] ism_points: u32,
        /// GPU: how the imperfect shadow maps' splats are drawn: `compute` (a compute pass, atomics) or `raster` (the rasteriser, depth test).
        #[arg(long, default_value = "compute", value_parser = crate::choice(IsmSplatting::parse, "compute, raster"))] ism_splatting: IsmSplatting,
        /// GPU: bounces of indirect light in the `gi` condition (1: the single bounce of the RSM VPLs; more add the multiple-bounce light source of thesis 5.2.7, at most 8).
        #[arg(long, default_value_t = RenderKnobs::default().bounces, value_parser = clap::value_parser!(u32).range(1..=8))] bounces: u32,
        /// GPU: candidate points each multiple-bounce slot searches.
        #[arg(long, default_value_t = RenderKnobs::default().bounce_candidates)] bounce_candidates: u32,
        /// GPU: the composition: additive (default) or scaled (Debevec: α = L'_cam / τ(L_r)).
        #[arg(long, default_value = "additive", value_parser = crate::choice(Composition::parse, "additive, scaled"))] composition: Composition,
        /// GPU: the colour mapping of the GI buffers: off (Reinhard), statistics, samples or rohmer (overrides what the `cm` factor implies).
        #[arg(long, value_parser = crate::choice(CmMethod::parse, "off, statistics, samples, rohmer"))] cm: Option<CmMethod>,
        /// Where the `ca` factor takes its parameters: `scene` (the scene's simulated camera) or `estimate` (noise, blur and JPEG quality measured on the photograph).
        #[arg(long = "ca-params", default_value = "scene", value_parser = crate::choice(ParamSource::parse, "scene, estimate"))] ca_source: ParamSource,
        /// GPU: resolution of each caustic map of a mirror or glass object (0: no caustics).
        #[arg(long, default_value_t = RenderKnobs::default().caustic_map_size)] caustic_map_size: u32,
    }
}

/// `--contact-sheet`: the ground truth and every condition of `--study` (or the web survey's).
fn contact_sheet(args: &RenderArgs, name: &str, out: &std::path::Path) -> Result<()> {
    let conditions: Vec<(String, Factors)> = match &args.study {
        None => contact_sheet::rmc_conditions(),
        Some(file) => match mrstudy_server::study::load_any(file)? {
            mrstudy_server::study::LoadedStudy::Survey(study) => study
                .conditions
                .into_iter()
                .map(|c| c.factors.map(|f| (c.name.clone(), f)).map_err(|why| anyhow::anyhow!("{}: {why}", c.name)))
                .collect::<Result<_>>()?,
            mrstudy_server::study::LoadedStudy::Task(_) => {
                bail!("{} is a task study; name a paired-comparison study", file.display())
            }
        },
    };
    let (width, height) = args.size.unwrap_or((200, 150));
    let settings = StimulusSettings { width, height, spp: args.spp, seed: args.seed, ..StimulusSettings::default() };
    let scene = scene::load_as(name, Some((width, height)), args.camera.clone())?;
    scene.warnings.iter().for_each(|warning| eprintln!("warning: {warning}"));
    let renderer = mrstudy_renderer::gpu::DirRenderer::new()?;
    let bar =
        progress_bar(2 * args.spp as u64 + conditions.len() as u64, &format!("{} contact sheet", scene.name), "steps");
    let sheet =
        contact_sheet::render(&renderer, &scene, &settings, &conditions, &|done, _| bar.set_position(done as u64));
    bar.finish_and_clear();
    sheet?.save_png(out)?;
    eprintln!(
        "wrote {} ({} conditions at {width}x{height}, {} spp, on {})",
        out.display(),
        conditions.len(),
        args.spp,
        renderer.ctx.adapter_name()
    );
    Ok(())
}

pub fn run(args: RenderArgs) -> Result<()> {
    if args.list {
        builtin::names().for_each(|name| println!("{name}"));
        return Ok(());
    }
    let name = args.scene.as_deref().context("--scene NAME|FILE is required (see `mrstudy render --list`)")?;
    if let Some(out) = &args.contact_sheet {
        return contact_sheet(&args, name, out);
    }
    let gpu = args.condition.is_some() || args.factors.is_some() || args.knobs.cm.is_some();
    // conditions render at 1024x768 unless --size says otherwise
    let size = args.size.or(gpu.then_some((1024, 768)));
    let scene = scene::load_as(name, size, args.camera.clone())?;
    if args.print_toml {
        print!("{}", scene.desc.to_toml());
        return Ok(());
    }
    scene.warnings.iter().for_each(|warning| eprintln!("warning: {warning}"));
    let target = args.reference.then_some(Target::GroundTruth).or(args.photo.then_some(Target::Photo));
    if !gpu && target.is_none() && args.gi_method.is_none() {
        bail!(
            "say what to render: --condition gi|shadows|none (GPU), --reference or --photo (CPU reference path tracer), or --gi-method em|dit|vct|off"
        );
    }
    let out = args.out.as_ref().context("--out FILE (.png or .exr) is required")?;
    let params = ReferenceParams { spp: args.spp, seed: args.seed, ..ReferenceParams::default() };
    if let Some(method) = args.gi_method {
        let coherent = CoherentParams { seed: args.seed, ..CoherentParams::new(method, args.quality) };
        // the representation and the frame run on the GPU where one opens (the CPU's otherwise)
        let renderer = match mrstudy_renderer::gpu::DirRenderer::new() {
            Ok(renderer) => Some(renderer),
            Err(e) => {
                eprintln!("note: no GPU ({e}); the representation and the frame run on the CPU");
                None
            }
        };
        let bar = progress_bar(2 * args.spp as u64 + 9, &format!("{} {}", scene.name, method.name()), "steps");
        let lines = mrstudy_renderer::coherent::render::render_to_file(
            &scene,
            &coherent,
            &params,
            out,
            args.buffers.as_deref(),
            renderer.as_ref(),
            &|done, _| bar.set_position(done as u64),
        );
        bar.finish_and_clear();
        lines?.iter().for_each(|line| eprintln!("{line}"));
        return Ok(());
    }
    let label =
        format!("{}{} {}x{}", if gpu { "photo " } else { "" }, scene.name, scene.camera.width, scene.camera.height);
    let Some(target) = target else {
        // `--condition` is the gi level alone; `--cm` alone renders every factor off
        let factors = match args.condition {
            Some(gi) => Factors { gi, coherent: None, cm: false, ca: false, caustics: true },
            None => args.factors.unwrap_or(Factors {
                gi: GiLevel::None,
                coherent: None,
                cm: false,
                ca: false,
                caustics: true,
            }),
        };
        let bar = progress_bar(args.spp as u64, &label, "spp");
        let lines = render_condition_to_file(
            &scene,
            &factors,
            &RenderKnobs::from(args.knobs),
            &params,
            out,
            args.buffers.as_deref(),
            &|done, _| bar.set_position(done as u64),
        );
        bar.finish_and_clear();
        lines?.iter().for_each(|line| eprintln!("{line}"));
        return Ok(());
    };
    let bar = progress_bar(target.progress_total(&params) as u64, &label, "spp");
    let stats =
        render_to_file(&scene, &params, target, out, args.buffers.as_deref(), &|done, _| bar.set_position(done as u64));
    bar.finish_and_clear();
    let stats = stats?;
    stats.warnings.iter().filter(|w| w.contains("firefly")).for_each(|warning| eprintln!("warning: {warning}"));
    eprintln!("wrote {} in {:.1} s ({:.0} samples/s)", out.display(), stats.seconds, stats.samples_per_second);
    eprintln!("light tracing {} ({} light paths)", stats.light_tracing, stats.light_paths);
    Ok(())
}
