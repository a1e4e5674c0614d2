//! `mrstudy render` as a function over a plain [`RenderRequest`] (and `mrstudy capture` over a
//! [`CaptureRequest`]): which renderer the request
//! names (the reference path tracer's photograph or ground truth, a condition on the GPU over the
//! path-traced photograph, one of Rohmer et al.'s methods, a contact sheet), the sizes it
//! defaults to, and what it says: [`Said`] lines for stdout, notes for stderr, progress.

use std::path::{Path, PathBuf};

use crate::coherent::evaluation::{CaptureSettings, CaptureSettingsError, evaluate_capture};
use crate::coherent::{CoherentParams, Method, Quality};
use crate::gpu::{DirRenderer, GiLevel};
use crate::reference::{ReferenceParams, Target, render_to_file};
use crate::sensor::SensorParams;
use crate::stimulus::{Factors, RenderKnobs, StimulusSettings, render_condition_to_file};
use crate::{RenderError, builtin, contact_sheet, scene};

/// What a command says while it runs; the CLI prints and draws it.
#[derive(Clone, Copy, Debug)]
#[non_exhaustive]
pub enum Said<'a> {
    /// Text for stdout, written as it is (its own line ends).
    Out(&'a str),
    /// One line for stderr (a note, a warning, what was written).
    Note(&'a str),
    /// `done` of `total` `unit`s of the work labelled `label`.
    Progress { label: &'a str, unit: &'a str, done: u64, total: u64 },
}

/// `mrstudy render`'s request: the fields of its flags (docs/design.md).
#[derive(Clone, Debug)]
pub struct RenderRequest {
    /// List the built-in scene names instead.
    pub list: bool,
    /// A built-in scene name or a scene file.
    pub scene: Option<String>,
    /// The ground-truth composite by the reference path tracer.
    pub reference: bool,
    /// The photograph by the reference path tracer.
    pub photo: bool,
    /// A condition by its `gi` level alone, on the GPU.
    pub condition: Option<GiLevel>,
    /// The factors of a condition, on the GPU.
    pub factors: Option<Factors>,
    pub knobs: RenderKnobs,
    /// One of Rohmer et al.'s methods from a simulated capture.
    pub gi_method: Option<Method>,
    pub quality: Quality,
    pub spp: u32,
    /// The image size; default: the scene's (1024x768 for a condition, 200x150 for a sheet).
    pub size: Option<(u32, u32)>,
    pub seed: u64,
    /// A simulated camera replacing the scene's.
    pub camera: Option<SensorParams>,
    pub out: Option<PathBuf>,
    pub buffers: Option<PathBuf>,
    /// Print the scene as a scene file instead.
    pub print_toml: bool,
    /// Write a contact sheet here instead.
    pub contact_sheet: Option<PathBuf>,
    /// The contact sheet's conditions (label, factors); none: the web survey's eight
    /// ([`contact_sheet::rmc_conditions`]).
    pub conditions: Option<Vec<(String, Factors)>>,
}

/// Why `mrstudy render` did not render.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RenderCommandError {
    #[error("--scene NAME|FILE is required (see `mrstudy render --list`)")]
    NoScene,
    #[error(
        "say what to render: --condition gi|shadows|none (GPU), --reference or --photo (CPU reference path tracer), or --gi-method em|dit|vct|off"
    )]
    NothingToRender,
    #[error("--out FILE (.png or .exr) is required")]
    NoOut,
    #[error(transparent)]
    Render(#[from] RenderError),
}

/// Runs `request` as `mrstudy render` does, saying what it does through `say`.
pub fn render(request: &RenderRequest, say: &(dyn Fn(Said) + Sync)) -> Result<(), RenderCommandError> {
    if request.list {
        builtin::names().for_each(|name| say(Said::Out(&format!("{name}\n"))));
        return Ok(());
    }
    let name = request.scene.as_deref().ok_or(RenderCommandError::NoScene)?;
    if let Some(out) = &request.contact_sheet {
        return Ok(sheet(request, name, out, say)?);
    }
    let gpu = request.condition.is_some() || request.factors.is_some() || request.knobs.cm.is_some();
    // conditions render at 1024x768 unless --size says otherwise
    let size = request.size.or(gpu.then_some((1024, 768)));
    let scene = scene::load_as(name, size, request.camera.clone())?;
    if request.print_toml {
        say(Said::Out(&scene.desc.to_toml()));
        return Ok(());
    }
    scene.warnings.iter().for_each(|warning| say(Said::Note(&format!("warning: {warning}"))));
    let target = request.reference.then_some(Target::GroundTruth).or(request.photo.then_some(Target::Photo));
    if !gpu && target.is_none() && request.gi_method.is_none() {
        return Err(RenderCommandError::NothingToRender);
    }
    let out = request.out.as_deref().ok_or(RenderCommandError::NoOut)?;
    let buffers = request.buffers.as_deref();
    let params = ReferenceParams { spp: request.spp, seed: request.seed, ..ReferenceParams::default() };
    let progress = |label, unit, total| progress(say, label, unit, total);
    if let Some(method) = request.gi_method {
        let coherent = CoherentParams { seed: request.seed, ..CoherentParams::new(method, request.quality) };
        // the representation and the frame run on the GPU where one opens (the CPU's otherwise)
        let renderer = DirRenderer::new()
            .inspect_err(|e| {
                say(Said::Note(&format!("note: no GPU ({e}); the representation and the frame run on the CPU")))
            })
            .ok();
        let label = format!("{} {}", scene.name, method.name());
        let progress = progress(&label, "steps", 2 * request.spp + 9);
        let lines = crate::coherent::render::render_to_file(
            &scene,
            &coherent,
            &params,
            out,
            buffers,
            renderer.as_ref(),
            &progress,
        )?;
        lines.iter().for_each(|line| say(Said::Note(line)));
        return Ok(());
    }
    let (width, height) = (scene.camera.width, scene.camera.height);
    let label = format!("{}{} {width}x{height}", if gpu { "photo " } else { "" }, scene.name);
    let Some(target) = target else {
        // `--condition` is the gi level alone; `--cm` alone renders every factor off
        let off = Factors { gi: GiLevel::None, coherent: None, cm: false, ca: false, caustics: true };
        let factors = match request.condition {
            Some(gi) => Factors { gi, ..off },
            None => request.factors.unwrap_or(off),
        };
        let progress = progress(&label, "spp", request.spp);
        let lines = render_condition_to_file(&scene, &factors, &request.knobs, &params, out, buffers, &progress)?;
        lines.iter().for_each(|line| say(Said::Note(line)));
        return Ok(());
    };
    let stats = render_to_file(
        &scene,
        &params,
        target,
        out,
        buffers,
        &progress(&label, "spp", target.progress_total(&params)),
    )?;
    let fireflies = stats.warnings.iter().filter(|w| w.contains("firefly"));
    fireflies.for_each(|warning| say(Said::Note(&format!("warning: {warning}"))));
    let rate = stats.samples_per_second;
    say(Said::Note(&format!("wrote {} in {:.1} s ({rate:.0} samples/s)", out.display(), stats.seconds)));
    say(Said::Note(&format!("light tracing {} ({} light paths)", stats.light_tracing, stats.light_paths)));
    Ok(())
}

/// A progress callback saying `done` of `total` `unit`s under `label` (and 0 at once, so that
/// its bar shows from the start).
fn progress<'a>(
    say: &'a (dyn Fn(Said) + Sync),
    label: &'a str,
    unit: &'a str,
    total: u32,
) -> impl Fn(u32, u32) + Sync + 'a {
    say(Said::Progress { label, unit, done: 0, total: total as u64 });
    move |done, _| say(Said::Progress { label, unit, done: done as u64, total: total as u64 })
}

/// `--contact-sheet`: the ground truth and every condition of the request (or the web survey's).
fn sheet(request: &RenderRequest, name: &str, out: &Path, say: &(dyn Fn(Said) + Sync)) -> Result<(), RenderError> {
    let conditions = request.conditions.clone().unwrap_or_else(contact_sheet::rmc_conditions);
    let (width, height) = request.size.unwrap_or((200, 150));
    let settings =
        StimulusSettings { width, height, spp: request.spp, seed: request.seed, ..StimulusSettings::default() };
    let scene = scene::load_as(name, Some((width, height)), request.camera.clone())?;
    scene.warnings.iter().for_each(|warning| say(Said::Note(&format!("warning: {warning}"))));
    let renderer = DirRenderer::new()?;
    let label = format!("{} contact sheet", scene.name);
    let progress = progress(say, &label, "steps", 2 * request.spp + conditions.len() as u32);
    contact_sheet::render(&renderer, &scene, &settings, &conditions, &progress)?.save_png(out)?;
    let adapter = renderer.ctx.adapter_name();
    let count = conditions.len();
    say(Said::Note(&format!(
        "wrote {} ({count} conditions at {width}x{height}, {} spp, on {adapter})",
        out.display(),
        request.spp
    )));
    Ok(())
}

/// `mrstudy capture`'s request: the scene, how its capture is simulated, where its report goes.
#[derive(Clone, Debug)]
pub struct CaptureRequest {
    /// A built-in scene name or a scene file.
    pub scene: String,
    pub settings: CaptureSettings,
    /// Also write the report as JSON here.
    pub json: Option<PathBuf>,
}

/// Why `mrstudy capture` did not report.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CaptureCommandError {
    #[error(transparent)]
    Settings(#[from] CaptureSettingsError),
    #[error("loading scene `{name}`")]
    Scene { name: String, source: RenderError },
    #[error("writing {}", path.display())]
    Write { path: PathBuf, source: std::io::Error },
}

/// Simulates the capture of `request` and says its report ([`evaluate_capture`]).
pub fn capture(request: &CaptureRequest, say: &(dyn Fn(Said) + Sync)) -> Result<(), CaptureCommandError> {
    request.settings.check()?;
    let scene = scene::load(&request.scene)
        .map_err(|source| CaptureCommandError::Scene { name: request.scene.clone(), source })?;
    let progress = progress(say, "capture", "poses", request.settings.poses as u32);
    let evaluation = evaluate_capture(&scene, &request.settings, |done, _| progress(done as u32, 0))?;
    evaluation.lines().iter().for_each(|line| say(Said::Out(&format!("{line}\n"))));
    if let Some(path) = &request.json {
        let json = serde_json::to_string_pretty(&evaluation.json()).expect("a JSON value prints") + "\n";
        std::fs::write(path, json).map_err(|source| CaptureCommandError::Write { path: path.clone(), source })?;
    }
    Ok(())
}
