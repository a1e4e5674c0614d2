//! Stimuli: one scene configuration under one combination of factor levels, rendered the way a
//! study shows it — the photograph of the real scene by the CPU path tracer (through the
//! scene's simulated camera), then the GPU frame composing the virtual objects over it.
//!
//! The factors the renderer knows are named here, with the levels it accepts:
//! `gi` (0: virtual objects lit directly, no shadows or indirect light; 1: shadows and indirect
//! light by differential instant radiosity), `shadows` (1 with `gi` 0: shadows only, the middle
//! mode of the thesis's preliminary study), `cm` (adaptive colour mapping: the thesis's
//! statistics-based transfer in CIELab, as in its web survey) and `ca` (camera artifacts:
//! Klein & Murray's chain with the parameters of the scene's simulated camera) and `caustics`
//! (the caustic maps of mirrors and glass, thesis 5.3: they come with `gi` and `shadows`, so a
//! condition that does not name this factor has them; 0 turns them off, and 1 without `gi` or
//! `shadows` is refused, since a caustic is light through a virtual object's shadow). A level
//! outside these, or a factor of another name, is refused with the factor and the level named —
//! a stimulus is never rendered with a factor silently ignored.
//!
//! The `gi` factor also takes its global-illumination *method* by name ([`FactorLevel::Name`]):
//! `"off"` (the same stimulus as 0), `"shadows"` (as `shadows` = 1), `"dir"` (differential
//! instant radiosity, the same stimulus as 1), or one of Rohmer et al.'s coherent methods
//! `"em"`, `"dit"`, `"vct"` ([`crate::coherent`]) at quality *med*, or at another quality with a
//! suffix (`"dit-low"`, `"vct-high"`). A coherent stimulus is rendered on the CPU
//! ([`crate::coherent::render::render_stimulus`]) from a simulated capture of the real scene,
//! then colour-mapped and given camera artifacts by the same `cm` and `ca` as a DIR stimulus
//! (the CPU references of those passes), so that only the method differs between conditions.
//!
//! [`StimulusSettings::fingerprint`] names everything that decides the image (the scene as
//! TOML, size, samples, seed, VPL budget, the factor levels and [`STIMULUS_VERSION`]), so callers
//! can cache rendered stimuli and know when one must be rendered again.

use crate::ca::CaParams;
use crate::cm::{CmMethod, CmParams};
use crate::coherent::render::{CapturedScene, Photograph, Presentation};
use crate::coherent::{CoherentParams, Method, Quality};
use crate::error::{RenderError, Result};
use crate::gpu::{DirParams, DirRenderer, GiLevel, GpuRender};
use crate::image::Image;
use crate::knob::{Knob, KnobSetting};
use crate::reference::{ReferenceOutput, ReferenceParams, RenderStats, render_photo};
use crate::scene::Scene;
use serde::Serialize;

/// Bumped whenever a change to the renderer changes the stimuli it makes, so cached stimuli of
/// an older renderer are rendered again.
pub const STIMULUS_VERSION: u32 = 4;

/// Bumped whenever a change to the GPU passes of mirrors and glass changes their images; it
/// enters the fingerprint of scenes with such an object only, so other cached stimuli stay.
pub const SPECULAR_VERSION: u32 = 2;

/// Bumped whenever a change to the coherent renderer changes its stimuli; it enters the
/// fingerprint of coherent stimuli only.
pub const COHERENT_VERSION: u32 = 1;

/// A factor's level as a study file writes it: a number (`gi = 1`) or a name (`gi = "dit"`).
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[serde(untagged)]
pub enum FactorLevel {
    Number(f64),
    Name(String),
}

impl std::fmt::Display for FactorLevel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FactorLevel::Number(value) => write!(f, "{value}"),
            FactorLevel::Name(name) => write!(f, "\"{name}\""),
        }
    }
}

/// A coherent method and its quality: the `gi` level `"dit"`, `"vct-high"`, ….
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct CoherentLevel {
    pub method: Method,
    pub quality: Quality,
}

impl CoherentLevel {
    /// `dit` (quality med) or `dit-high`: the name a study and a fingerprint use.
    pub fn name(&self) -> String {
        if self.quality == Quality::Med {
            self.method.name().to_string()
        } else {
            format!("{}-{}", self.method.name(), self.quality.name())
        }
    }

    /// The level [`CoherentLevel::name`] gives: `em`, `dit` or `vct`, at quality *med* or with
    /// a suffix `-low`, `-med`, `-high`; None for any other name.
    pub fn parse(name: &str) -> Option<CoherentLevel> {
        let (method, quality) = match name.split_once('-') {
            Some((method, quality)) => (method, Quality::parse(quality)?),
            None => (name, Quality::Med),
        };
        Method::parse(method).filter(|&m| m != Method::Off).map(|method| CoherentLevel { method, quality })
    }
}

/// The names the `gi` factor takes, for messages.
pub const GI_NAMES: &str =
    "\"off\", \"shadows\", \"dir\", \"em\", \"dit\", \"vct\" (a coherent method may end in -low, -med or -high)";

/// The `gi` factor's level named `name`: DIR's mode, or a coherent method.
fn gi_by_name(name: &str) -> std::result::Result<(GiLevel, Option<CoherentLevel>), FactorsError> {
    let dir = match name {
        "off" => Some(GiLevel::None),
        "shadows" => Some(GiLevel::Shadows),
        "dir" => Some(GiLevel::Gi),
        _ => None,
    };
    if let Some(level) = dir {
        return Ok((level, None));
    }
    CoherentLevel::parse(name)
        .map(|level| (GiLevel::Gi, Some(level)))
        .ok_or_else(|| FactorsError::GiName { level: name.to_string() })
}

/// Factor levels the renderer cannot render; each displays as one sentence naming the factor
/// and its level.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FactorsError {
    #[error("factor `gi` has level \"{level}\"; the renderer knows the numbers 0 and 1 and the names {GI_NAMES}")]
    GiName { level: String },
    #[error(
        "factor `{factor}` has level \"{level}\"; the renderer knows the levels 0 (off) and 1 (on) for it (only `gi` takes names)"
    )]
    Name { factor: String, level: String },
    #[error("factor `{factor}` has level {level}; the renderer knows the levels 0 (off) and 1 (on)")]
    Level { factor: String, level: f64 },
    #[error("the renderer knows no factor `{factor}` (it renders gi, shadows, cm, ca and caustics)")]
    Unknown { factor: String },
    #[error(
        "factor `shadows` is 1 while `gi` is \"{gi}\"; shadows alone is a mode of differential instant radiosity (write gi = \"shadows\")"
    )]
    ShadowsWithCoherent { gi: String },
    #[error("factor `caustics` is 1 while `gi` is \"{gi}\"; the coherent methods render no caustics")]
    CausticsWithCoherent { gi: String },
    #[error(
        "factor `caustics` is 1 while `gi` and `shadows` are 0; caustics are light through a virtual object's shadow and come only with gi or shadows"
    )]
    CausticsWithoutGi,
    /// A factor list (`--factors gi,cm`) naming something else.
    #[error("{0}; name them as gi, cm, ca, shadows or caustics")]
    List(Box<FactorsError>),
}

/// The factors a stimulus is rendered under.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Factors {
    /// The gi factor's mode: none, shadows, or shadows and indirect light.
    pub gi: GiLevel,
    /// The gi factor's coherent method, when the level names one (`gi` is then
    /// [`GiLevel::Gi`]: the method renders shadows and indirect light); none: DIR.
    pub coherent: Option<CoherentLevel>,
    /// Adaptive colour mapping on.
    pub cm: bool,
    /// Camera artifacts on.
    pub ca: bool,
    /// Caustics of mirrors and glass with `gi` or `shadows` (on unless a condition sets the
    /// `caustics` factor to 0).
    pub caustics: bool,
}

impl Factors {
    /// The factors named in a comma-separated list (`gi,cm`) switched on, the others off.
    pub fn parse_list(text: &str) -> std::result::Result<Factors, FactorsError> {
        let names = text.split(',').map(str::trim).filter(|name| !name.is_empty());
        Factors::from_levels(names.map(|name| (name, 1.0))).map_err(|reason| FactorsError::List(Box::new(reason)))
    }

    /// Factors from numeric `(name, level)` pairs. Factors not named are off.
    pub fn from_levels<'a>(
        levels: impl IntoIterator<Item = (&'a str, f64)>,
    ) -> std::result::Result<Factors, FactorsError> {
        let levels: Vec<(&str, FactorLevel)> =
            levels.into_iter().map(|(name, level)| (name, FactorLevel::Number(level))).collect();
        Factors::from_study_levels(levels.iter().map(|(name, level)| (*name, level)))
    }

    /// Factors from `(name, level)` pairs as a study's condition lists them, numbers or (for
    /// `gi`) names. Factors not named are off.
    pub fn from_study_levels<'a>(
        levels: impl IntoIterator<Item = (&'a str, &'a FactorLevel)>,
    ) -> std::result::Result<Factors, FactorsError> {
        let (mut gi, mut shadows, mut cm, mut ca) = (false, false, false, false);
        let (mut caustics, mut named_gi) = (None, None);
        for (name, level) in levels {
            let level = match level {
                FactorLevel::Number(value) => *value,
                FactorLevel::Name(text) if name == "gi" => {
                    named_gi = Some(gi_by_name(text)?);
                    continue;
                }
                FactorLevel::Name(text) => {
                    return Err(FactorsError::Name { factor: name.to_string(), level: text.clone() });
                }
            };
            let on = if level == 0.0 {
                false
            } else if level == 1.0 {
                true
            } else {
                return Err(FactorsError::Level { factor: name.to_string(), level });
            };
            match name {
                "gi" => gi = on,
                "shadows" => shadows = on,
                "cm" => cm = on,
                "ca" => ca = on,
                "caustics" => caustics = Some(on),
                other => return Err(FactorsError::Unknown { factor: other.to_string() }),
            }
        }
        let (gi, coherent) = match (named_gi, gi, shadows) {
            (Some((_, Some(coherent))), _, true) => {
                return Err(FactorsError::ShadowsWithCoherent { gi: coherent.name() });
            }
            (Some((level, coherent)), _, shadows) => {
                (if shadows && level == GiLevel::None { GiLevel::Shadows } else { level }, coherent)
            }
            (None, true, _) => (GiLevel::Gi, None),
            (None, false, true) => (GiLevel::Shadows, None),
            (None, false, false) => (GiLevel::None, None),
        };
        if let (Some(coherent), Some(true)) = (coherent, caustics) {
            return Err(FactorsError::CausticsWithCoherent { gi: coherent.name() });
        }
        if caustics == Some(true) && gi == GiLevel::None {
            return Err(FactorsError::CausticsWithoutGi);
        }
        Ok(Factors { gi, coherent, cm, ca, caustics: coherent.is_none() && caustics.unwrap_or(true) })
    }

    /// A short label such as `gi+ca` or `none`.
    pub fn label(&self) -> String {
        let mut parts = Vec::new();
        let coherent = self.coherent.map(|level| level.name());
        match (self.gi, &coherent) {
            (_, Some(name)) => parts.push(name.as_str()),
            (GiLevel::Gi, None) => parts.push("gi"),
            (GiLevel::Shadows, None) => parts.push("shadows"),
            (GiLevel::None, None) => {}
        }
        if self.cm {
            parts.push("cm");
        }
        if self.ca {
            parts.push("ca");
        }
        if !self.caustics && self.gi != GiLevel::None && self.coherent.is_none() {
            parts.push("no-caustics");
        }
        if parts.is_empty() { "none".into() } else { parts.join("+") }
    }
}

/// How stimuli are rendered: size, the path tracer's samples and seed, the VPL budget.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct StimulusSettings {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel of the path-traced photograph.
    pub spp: u32,
    pub seed: u64,
    pub vpls: u32,
    /// A threshold study's level: one knob of the GPU or the path tracer at one value
    /// ([`crate::knob`]); `None` for every other stimulus (and absent from its fingerprint).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub knob: Option<KnobSetting>,
}

impl Default for StimulusSettings {
    fn default() -> Self {
        StimulusSettings { width: 1024, height: 768, spp: 64, seed: 1, vpls: 256, knob: None }
    }
}

impl StimulusSettings {
    /// These settings at one level of a threshold study: the `vpls` knob sets the VPL budget
    /// itself (so the stimulus is the one any study with that budget renders), every other
    /// knob is kept as [`StimulusSettings::knob`]; `None` leaves the settings as they are.
    pub fn with_knob(&self, knob: Option<KnobSetting>) -> StimulusSettings {
        match knob {
            None => self.clone(),
            Some(KnobSetting { knob: Knob::Vpls, value }) => StimulusSettings { vpls: value, ..self.clone() },
            Some(setting) => StimulusSettings { knob: Some(setting), ..self.clone() },
        }
    }

    /// The scene at the stimulus size.
    pub fn sized(&self, scene: Scene) -> Scene {
        if scene.camera.width == self.width && scene.camera.height == self.height {
            scene
        } else {
            scene.with_size(self.width, self.height)
        }
    }

    /// Text naming everything that decides the stimulus of `scene` (already sized) under
    /// `factors`; equal texts give equal images. Hash it for a cache key.
    pub fn fingerprint(&self, scene: &Scene, factors: &Factors) -> String {
        let mut specular = if scene.objects.iter().any(|o| scene.materials[o.material].delta.is_some()) {
            format!("specular v{SPECULAR_VERSION}\n")
        } else {
            String::new()
        };
        if factors.coherent.is_some() {
            specular.push_str(&format!("coherent v{COHERENT_VERSION}\n"));
        }
        // a knob's line only where one is set, so every other stimulus keeps its fingerprint
        let knob = self.knob.map(|setting| format!("knob {} {}\n", setting.knob, setting.value)).unwrap_or_default();
        format!(
            "mrstudy stimulus v{STIMULUS_VERSION}\n{specular}size {}x{}\nspp {}\nseed {}\nvpls {}\nfactors {}\n{knob}{}",
            self.width,
            self.height,
            self.spp,
            self.seed,
            self.vpls,
            factors.label(),
            scene.desc.to_toml()
        )
    }

    /// Text naming everything that decides the ground-truth composite of `scene` (already
    /// sized): the path tracer's settings and the scene, no factors (one ground truth is shared
    /// by every condition of a scene configuration). Hash it for a cache key.
    pub fn ground_truth_fingerprint(&self, scene: &Scene) -> String {
        format!(
            "mrstudy ground truth v{STIMULUS_VERSION}\nsize {}x{}\nspp {}\nseed {}\n{}",
            self.width,
            self.height,
            self.spp,
            self.seed,
            scene.desc.to_toml()
        )
    }

    /// The photograph and the ground-truth composite of `scene` in one reference render (the
    /// same path-tracing random numbers and sensor noise; the photograph is the one
    /// [`StimulusSettings::photo`] makes), with the HDR buffers and the masks the stimulus
    /// metrics are taken in. A scene with a background photograph has no ground truth: an
    /// error saying so.
    pub fn reference(&self, scene: &Scene, progress: &(dyn Fn(u32, u32) + Sync)) -> Result<ReferenceOutput> {
        if self.spp == 0 {
            return Err(RenderError::Unsupported(
                "a stimulus needs at least 1 sample per pixel for its photograph".into(),
            ));
        }
        let params = ReferenceParams { spp: self.spp, seed: self.seed, ..ReferenceParams::default() };
        crate::reference::render_reference(scene, &params, progress)
    }

    /// The photograph of the scene's real part: its linear radiance and the display-encoded
    /// camera output (the CPU path tracer through the scene's camera); `progress(done, total)`
    /// is called as samples complete.
    pub fn photo(&self, scene: &Scene, progress: &(dyn Fn(u32, u32) + Sync)) -> Result<(Image, Image, RenderStats)> {
        if self.spp == 0 {
            return Err(RenderError::Unsupported(
                "a stimulus needs at least 1 sample per pixel for its photograph".into(),
            ));
        }
        let params = ReferenceParams { spp: self.spp, seed: self.seed, ..ReferenceParams::default() };
        render_photo(scene, &params, progress)
    }

    /// The GPU parameters of a stimulus of `scene` under `factors`.
    pub fn params(&self, scene: &Scene, factors: &Factors) -> DirParams {
        let mut params = DirParams { condition: factors.gi, vpls: self.vpls, ..DirParams::default() };
        if factors.cm {
            // the thesis's web-survey cm: statistics-based colour transfer in CIELab (4.30–4.38)
            params.cm = CmParams { method: CmMethod::Statistics, ..CmParams::default() };
        }
        if factors.ca {
            // Klein & Murray's chain with the scene camera's own parameters
            params.camera_artifacts = Some(CaParams::from_sensor(&scene.sensor));
        }
        if !factors.caustics {
            params.specular.caustic_map_size = 0;
        }
        if let Some(knob) = self.knob {
            knob.apply(&mut params);
        }
        params
    }

    /// Renders one DIR stimulus over `photo` (from [`StimulusSettings::photo`] of the same scene).
    pub fn render(&self, renderer: &DirRenderer, scene: &Scene, photo: &Image, factors: &Factors) -> Result<GpuRender> {
        renderer.render(scene, photo, &self.params(scene, factors))
    }

    /// Renders one stimulus by the method its `gi` level names: DIR on the GPU over `photo`
    /// ([`StimulusSettings::render`]), or a coherent method from `linear` (the photograph's
    /// linear radiance) composed over `photo`: its representation built on the GPU, its frame
    /// on the CPU. `captured` is the scene's capture:
    /// the first coherent stimulus of a scene makes it, the others reuse it.
    pub fn render_stimulus(
        &self,
        renderer: &DirRenderer,
        scene: &Scene,
        photo: &Image,
        linear: &Image,
        factors: &Factors,
        captured: &mut Option<CapturedScene>,
    ) -> Result<StimulusFrame> {
        if let Some(KnobSetting { knob: Knob::Spp, value }) = self.knob {
            return self.path_traced_stimulus(scene, value);
        }
        match factors.coherent {
            None => {
                let frame = self.render(renderer, scene, photo, factors)?;
                Ok(StimulusFrame {
                    composite: frame.composite,
                    ms: frame.report.ms,
                    adapter: frame.report.adapter,
                    cm_warning: frame.report.cm.warning,
                })
            }
            Some(level) => {
                let params = CoherentParams { seed: self.seed, ..CoherentParams::new(level.method, level.quality) };
                // the cm and ca of a DIR stimulus under the same factors
                let dir = self.params(scene, factors);
                let captured = captured.get_or_insert_with(|| CapturedScene::new(scene, self.seed, &|_, _| {}));
                let photo = Photograph { display: photo, linear };
                let shown = Presentation { cm: &dir.cm, ca: dir.camera_artifacts.as_ref() };
                let frame =
                    crate::coherent::render::render_stimulus(scene, captured, photo, &params, shown, Some(renderer))?;
                Ok(StimulusFrame {
                    composite: frame.composite,
                    ms: frame.ms,
                    cm_warning: frame.cm.warning,
                    adapter: format!(
                        "{} (coherent rendering: representation on the GPU, frame on the CPU)",
                        renderer.ctx.adapter_name()
                    ),
                })
            }
        }
    }
}

impl StimulusSettings {
    /// The `spp` knob's stimulus: the whole scene (real and virtual objects) path-traced at
    /// `spp` samples per pixel through the same simulated camera as the ground truth (the same
    /// sensor noise), with the path tracer's own random numbers drawn from another seed than
    /// the ground truth's, so that only the sampling noise of fewer samples differs.
    fn path_traced_stimulus(&self, scene: &Scene, spp: u32) -> Result<StimulusFrame> {
        let seed = self.seed ^ 0x9E37_79B9_7F4A_7C15;
        let params = ReferenceParams { spp, seed, ..ReferenceParams::default() };
        let output = crate::reference::render_reference(scene, &params, &|_, _| {})?;
        Ok(StimulusFrame {
            composite: output.ground_truth,
            ms: output.stats.seconds * 1000.0,
            adapter: "CPU path tracer".into(),
            cm_warning: None,
        })
    }
}

/// One stimulus as shown (display-encoded), the time it took and what rendered it.
pub struct StimulusFrame {
    pub composite: Image,
    pub ms: f64,
    pub adapter: String,
    /// The statistics colour mapping's channel ratios outside [0.5, 2], if it found any.
    pub cm_warning: Option<crate::cm::statistics::RatioWarning>,
}

/// What a render of one condition outside a study may change from a stimulus's parameters:
/// `mrstudy render --condition/--factors`'s GPU flags (the binary's clap definitions default to
/// this `Default`).
#[derive(Clone, Debug, PartialEq)]
pub struct RenderKnobs {
    /// The VPL budget of the `gi` condition.
    pub vpls: u32,
    /// Resolution of each VPL's imperfect shadow map (0: VPLs unshadowed).
    pub ism_size: u32,
    /// Points per cloud (real, virtual) splatted into each VPL's imperfect shadow map.
    pub ism_points: u32,
    /// How the imperfect shadow maps' splats are drawn.
    pub ism_splatting: crate::gpu::ism::IsmSplatting,
    /// Bounces of indirect light in the `gi` condition (1..=8).
    pub bounces: u32,
    /// Candidate points each multiple-bounce slot searches.
    pub bounce_candidates: u32,
    /// The composition: additive or scaled (Debevec).
    pub composition: crate::cm::Composition,
    /// The colour mapping of the GI buffers, overriding what the `cm` factor implies.
    pub cm: Option<CmMethod>,
    /// Where the `ca` factor takes its parameters.
    pub ca_source: crate::ca::ParamSource,
    /// Resolution of each caustic map of a mirror or glass object (0: no caustics).
    pub caustic_map_size: u32,
}

impl Default for RenderKnobs {
    fn default() -> RenderKnobs {
        RenderKnobs {
            vpls: 256,
            ism_size: 128,
            ism_points: 1024,
            ism_splatting: crate::gpu::ism::IsmSplatting::Compute,
            bounces: 3,
            bounce_candidates: 4096,
            composition: crate::cm::Composition::Additive,
            cm: None,
            ca_source: crate::ca::ParamSource::Scene,
            caustic_map_size: 256,
        }
    }
}

/// One condition rendered over a photograph, with the parameters it was rendered by and, when
/// the `ca` parameters were estimated on the photograph, the estimates.
pub struct ConditionRender {
    pub frame: GpuRender,
    pub params: DirParams,
    pub ca_estimates: Option<crate::ca::estimate::Estimates>,
}

/// Renders `factors` over `photo` with a stimulus's parameters changed by `knobs`.
pub fn render_condition(
    renderer: &DirRenderer,
    scene: &Scene,
    photo: &Image,
    factors: &Factors,
    knobs: &RenderKnobs,
) -> Result<ConditionRender> {
    let settings = StimulusSettings { vpls: knobs.vpls, ..StimulusSettings::default() };
    let mut params = DirParams {
        ism_size: knobs.ism_size,
        ism_points: knobs.ism_points,
        ism_splatting: knobs.ism_splatting,
        bounces: knobs.bounces,
        bounce_candidates: knobs.bounce_candidates,
        composition: knobs.composition,
        ..settings.params(scene, factors)
    };
    if let Some(method) = knobs.cm {
        params.cm.method = method;
    }
    if factors.caustics {
        params.specular.caustic_map_size = knobs.caustic_map_size;
    }
    let mut ca_estimates = None;
    if factors.ca && knobs.ca_source == crate::ca::ParamSource::Estimate {
        let (ca, estimates) = crate::ca::estimate::params_from_photo(photo, &scene.sensor);
        params.camera_artifacts = Some(ca);
        ca_estimates = Some(estimates);
    }
    let frame = renderer.render(scene, photo, &params)?;
    Ok(ConditionRender { frame, params, ca_estimates })
}

/// `mrstudy render --condition/--factors`: the photograph by the path tracer (`progress` counts
/// its samples per pixel), then `factors` on the GPU over it ([`render_condition`]), saved to
/// `out` (`.png`, or `.exr` linear) with, given `buffers`, every buffer. Returns the lines to
/// show the user: the adapter, the estimates and warnings, each pass's time and a summary.
pub fn render_condition_to_file(
    scene: &Scene,
    factors: &Factors,
    knobs: &RenderKnobs,
    photo_params: &ReferenceParams,
    out: &std::path::Path,
    buffers: Option<&std::path::Path>,
    progress: &(dyn Fn(u32, u32) + Sync),
) -> Result<Vec<String>> {
    let renderer = DirRenderer::new()?;
    let mut lines = vec![format!("adapter: {}", renderer.ctx.adapter_name())];
    let (_, photo, photo_stats) = render_photo(scene, photo_params, progress)?;
    let ConditionRender { frame, params, ca_estimates } = render_condition(&renderer, scene, &photo, factors, knobs)?;
    if let Some(estimates) = &ca_estimates {
        lines.push(format!("ca estimates from the photograph: {estimates}"));
    }
    let method = params.cm.method;
    // what the colour mapping found: a fallback, a channel ratio outside [0.5, 2]
    let mut warnings = Vec::new();
    if let Some(why) = &frame.report.cm.fallback {
        warnings.push(format!("colour mapping {}: {why}", method.name()));
    }
    if let Some(warning) = &frame.report.cm.warning {
        warnings.push(warning.sentence(&scene.name));
    }
    crate::image::save_by_extension(out, &frame.composite.srgb_to_linear(), &frame.composite)?;
    if let Some(dir) = buffers {
        let mut extra = serde_json::json!({ "photo_seconds": photo_stats.seconds, "ca_estimates": ca_estimates });
        if !warnings.is_empty() {
            extra["warnings"] = serde_json::json!(warnings);
        }
        frame.write_buffers(dir, &photo, extra)?;
    }
    lines.extend(frame.report.passes.iter().map(|pass| format!("  {:<40} {:>9.2} ms", pass.pass, pass.ms)));
    lines.extend(warnings.iter().map(|warning| format!("warning: {warning}")));
    let ca = match (factors.ca, knobs.ca_source) {
        (false, _) => "",
        (true, crate::ca::ParamSource::Scene) => ", ca from the scene's camera",
        (true, crate::ca::ParamSource::Estimate) => ", ca from the photograph",
    };
    lines.push(format!(
        "wrote {} ({} condition, cm {}{ca}, {} VPLs): photo {:.1} s on the CPU, GPU frame {:.1} ms on {}",
        out.display(),
        factors.gi.name(),
        method.name(),
        frame.report.vpls,
        photo_stats.seconds,
        frame.report.ms,
        frame.report.adapter
    ));
    Ok(lines)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn levels(pairs: &[(&'static str, f64)]) -> std::result::Result<Factors, String> {
        Factors::from_levels(pairs.iter().copied()).map_err(|error| error.to_string())
    }

    #[test]
    fn factor_levels_map_to_the_three_gi_modes() {
        assert_eq!(
            levels(&[("gi", 0.0), ("cm", 0.0), ("ca", 0.0)]).unwrap(),
            Factors { gi: GiLevel::None, coherent: None, cm: false, ca: false, caustics: true }
        );
        assert_eq!(levels(&[("gi", 1.0)]).unwrap().gi, GiLevel::Gi);
        assert_eq!(levels(&[("gi", 0.0), ("shadows", 1.0)]).unwrap().gi, GiLevel::Shadows);
        assert_eq!(levels(&[("gi", 1.0), ("shadows", 1.0)]).unwrap().gi, GiLevel::Gi);
        assert_eq!(levels(&[("gi", 1.0), ("cm", 1.0), ("ca", 1.0)]).unwrap().label(), "gi+cm+ca");
        assert_eq!(levels(&[]).unwrap().label(), "none");
    }

    #[test]
    fn unknown_factors_and_levels_are_refused_by_name() {
        let error = levels(&[("gi", 2.0)]).unwrap_err();
        assert!(error.contains("`gi`") && error.contains("level 2"), "{error}");
        let error = levels(&[("bloom", 1.0)]).unwrap_err();
        assert!(error.contains("`bloom`"), "{error}");
        assert!(levels(&[("gi", f64::NAN)]).is_err());
    }

    #[test]
    fn caustics_come_with_gi_and_shadows_and_the_factor_turns_them_off() {
        assert!(levels(&[("gi", 1.0)]).unwrap().caustics);
        let off = levels(&[("gi", 1.0), ("caustics", 0.0)]).unwrap();
        assert_eq!(off.label(), "gi+no-caustics");
        assert_ne!(off.label(), levels(&[("gi", 1.0), ("caustics", 1.0)]).unwrap().label());
        let settings = StimulusSettings::default();
        let scene = crate::scene::load("dir-lamp-box").unwrap();
        assert_eq!(settings.params(&scene, &off).specular.caustic_map_size, 0);
        assert!(settings.params(&scene, &levels(&[("shadows", 1.0)]).unwrap()).specular.caustic_map_size > 0);
        // gi off: no shadows, so no caustics either way, and the label says nothing of them
        assert_eq!(levels(&[("caustics", 0.0)]).unwrap().label(), "none");
        let error = levels(&[("gi", 0.0), ("caustics", 1.0)]).unwrap_err();
        assert!(error.contains("`caustics`") && error.contains("gi"), "{error}");
    }

    fn named(pairs: &[(&'static str, &str)]) -> std::result::Result<Factors, String> {
        let levels: Vec<(&str, FactorLevel)> =
            pairs.iter().map(|(name, level)| (*name, FactorLevel::Name(level.to_string()))).collect();
        Factors::from_study_levels(levels.iter().map(|(name, level)| (*name, level))).map_err(|error| error.to_string())
    }

    #[test]
    fn the_gi_factor_names_its_methods_and_the_dir_names_equal_the_numbers() {
        assert_eq!(named(&[("gi", "off")]).unwrap(), levels(&[("gi", 0.0)]).unwrap());
        assert_eq!(named(&[("gi", "dir")]).unwrap(), levels(&[("gi", 1.0)]).unwrap());
        assert_eq!(named(&[("gi", "shadows")]).unwrap(), levels(&[("shadows", 1.0)]).unwrap());
        let dit = named(&[("gi", "dit")]).unwrap();
        assert_eq!(dit.coherent, Some(CoherentLevel { method: Method::Dit, quality: Quality::Med }));
        assert_eq!(dit.label(), "dit");
        assert!(!dit.caustics, "the coherent methods render no caustics");
        let vct = named(&[("gi", "vct-high")]).unwrap();
        assert_eq!(vct.coherent, Some(CoherentLevel { method: Method::Vct, quality: Quality::High }));
        assert_eq!(named(&[("gi", "em-low")]).unwrap().label(), "em-low");
        assert_eq!(named(&[("gi", "dit-med")]).unwrap(), dit);
        for bad in ["pt", "dit-ultra", "off-high", "DIT", ""] {
            let error = named(&[("gi", bad)]).unwrap_err();
            assert!(error.contains(&format!("\"{bad}\"")) && error.contains("\"vct\""), "{error}");
        }
        let error = named(&[("cm", "statistics")]).unwrap_err();
        assert!(error.contains("`cm`") && error.contains("only `gi`"), "{error}");
        let mixed: Vec<(&str, FactorLevel)> =
            vec![("gi", FactorLevel::Name("dit".into())), ("caustics", FactorLevel::Number(1.0))];
        let error = Factors::from_study_levels(mixed.iter().map(|(n, l)| (*n, l))).unwrap_err().to_string();
        assert!(error.contains("no caustics"), "{error}");
        let mixed: Vec<(&str, FactorLevel)> =
            vec![("gi", FactorLevel::Name("vct".into())), ("shadows", FactorLevel::Number(1.0))];
        let error = Factors::from_study_levels(mixed.iter().map(|(n, l)| (*n, l))).unwrap_err().to_string();
        assert!(error.contains("`shadows`") && error.contains("\"vct\""), "{error}");
    }

    #[test]
    fn the_fingerprint_changes_with_every_input() {
        let scene = crate::scene::load("dir-lamp-box").unwrap();
        let settings = StimulusSettings { width: 64, height: 48, ..StimulusSettings::default() };
        let scene = settings.sized(scene);
        let gi = levels(&[("gi", 1.0)]).unwrap();
        let none = levels(&[]).unwrap();
        let base = settings.fingerprint(&scene, &gi);
        assert_eq!(base, settings.fingerprint(&scene, &gi));
        assert_ne!(base, settings.fingerprint(&scene, &none));
        // the method and its quality; off and dir by name are the numbers' stimuli
        let dit = settings.fingerprint(&scene, &named(&[("gi", "dit")]).unwrap());
        assert!(dit.contains("coherent v"), "{dit}");
        assert_ne!(dit, base);
        assert_ne!(dit, settings.fingerprint(&scene, &named(&[("gi", "dit-high")]).unwrap()));
        assert_ne!(dit, settings.fingerprint(&scene, &named(&[("gi", "vct")]).unwrap()));
        assert_eq!(base, settings.fingerprint(&scene, &named(&[("gi", "dir")]).unwrap()));
        assert_ne!(base, StimulusSettings { spp: 2, ..settings.clone() }.fingerprint(&scene, &gi));
        assert_ne!(base, StimulusSettings { seed: 2, ..settings.clone() }.fingerprint(&scene, &gi));
        let other = StimulusSettings { width: 32, height: 24, ..settings.clone() };
        assert_ne!(base, other.fingerprint(&other.sized(crate::scene::load("dir-lamp-box").unwrap()), &gi));
    }

    #[test]
    fn the_reference_render_makes_the_same_photograph_as_photo() {
        // stimuli rendered over `photo` before ground truths existed stay valid: the reference
        // render's photograph is the same image, bit for bit
        let settings = StimulusSettings { width: 32, height: 24, spp: 2, ..StimulusSettings::default() };
        let scene = settings.sized(crate::scene::load("dir-lamp-box").unwrap());
        let (_, photo, _) = settings.photo(&scene, &|_, _| {}).unwrap();
        let reference = settings.reference(&scene, &|_, _| {}).unwrap();
        assert_eq!(photo.pixels, reference.photo.pixels);
        assert_ne!(reference.photo.pixels, reference.ground_truth.pixels);
        assert!(settings.ground_truth_fingerprint(&scene).starts_with("mrstudy ground truth"));
    }
}
