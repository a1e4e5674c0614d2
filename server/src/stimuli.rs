//! Rendered stimuli: the scene configurations of a study that name a scene for the renderer
//! (`render = "survey-1"` or a scene file) are rendered under every condition's factor levels
//! and kept in the content-addressed stimulus store, so `serve` renders only what is missing.
//!
//! Each stimulus is found through an index entry `<store>/rendered/<key>` whose content is the
//! stored file's name; the key is the SHA-256 of the renderer's fingerprint of the stimulus
//! (scene as TOML, size, samples, seed, VPLs, factor levels, renderer version — see
//! [`mrstudy_renderer::stimulus`]). Entries are written after their image, each by a rename, so
//! an interrupted run leaves no entry pointing at a partial file; the next start renders what is
//! still missing.
//!
//! Beside each image the store keeps its ground truth: a scene configuration the path tracer
//! synthesises (no background photograph) gets its ground-truth composite rendered once, in the
//! same reference render as the photograph the stimuli are composed over, stored like a stimulus
//! (`rendered/<ground-truth key>`), and every stimulus of it a [`StimulusRecord`] — its errors
//! against that ground truth per region, its render time and settings — stored as
//! `<sha256>.json` under the entry `rendered/<key>.metrics`. [`metrics_csv`] writes them as
//! docs/design.md's stimulus metrics CSV.
//!
//! Sensor-noise realisations (a detection design's `realisations` > 1): realisation k > 0 of a
//! scene configuration is its scene with the simulated camera's noise seed replaced
//! ([`realisation_seed`]), so it has its own fingerprints, its own ground truth and its own
//! stimuli, each rendered over its own photograph. The path tracer's radiance does not depend on
//! the noise seed, so [`render_missing`] path-traces a scene configuration once and passes the
//! same radiance through the camera once per realisation ([`mrstudy_renderer::sensor::apply`]):
//! a realisation costs one GPU frame per condition, not a reference render.
//!
//! Sharding ([`Shard`], `mrstudy stimuli --shard K/N`): the unit of work is a scene
//! configuration (its reference render is shared by all its conditions); the renderable scene
//! configurations, in the study's order, are dealt round-robin to N shards, so shard K renders a
//! deterministic, disjoint share whatever its store already holds. Stores merge by copying
//! their files into one (content-addressed names, index entries that name them; every writer
//! renames a uniquely named partial file into place), and a merged store holds the same images,
//! ground truths and index entries as one rendered on a single machine.

pub mod command;
pub mod lines;
pub mod warnings;

use std::path::{Path, PathBuf};

use mrstudy_analysis::stimulus_metrics::{StimulusMetrics, parse_stimulus_metrics};
use mrstudy_renderer::gpu::DirRenderer;
use mrstudy_renderer::metrics::{StimulusErrors, quantized, stimulus_errors};
use mrstudy_renderer::stimulus::{Factors, StimulusSettings};
use mrstudy_renderer::{Image, ReferenceOutput, RenderError};
use serde::{Deserialize, Serialize};

use crate::study::{StimulusSource, Study, sha256_hex};

/// Why the stimuli of a study could not be rendered.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StimuliError {
    /// A condition's factor levels are not something the renderer can render.
    #[error("study \"{slug}\" ({file}): condition \"{condition}\": {reason}")]
    Factors { slug: String, file: PathBuf, condition: String, reason: String },
    /// The scene could not be loaded or rendered (the renderer's own sentence).
    #[error("study \"{slug}\" ({file}): scene configuration \"{scene}\": {source}")]
    Render { slug: String, file: PathBuf, scene: String, source: RenderError },
    /// No GPU adapter could be opened (the stimuli need the GPU renderer).
    #[error(
        "study \"{slug}\" ({file}) needs its stimuli rendered on the GPU, and no adapter could be opened: {source}"
    )]
    NoGpu { slug: String, file: PathBuf, source: RenderError },
    #[error("cannot write {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    /// A stored stimulus or record could not be read back.
    #[error("the stimulus store entry {path} cannot be read: {reason}")]
    Store { path: PathBuf, reason: String },
}

/// One stimulus a study needs from the renderer.
#[derive(Debug, Clone)]
pub struct PlannedStimulus {
    pub scene_index: usize,
    pub condition_index: usize,
    /// Scene configuration and condition names, for messages and file names.
    pub scene: String,
    pub condition: String,
    pub factors: Factors,
    /// SHA-256 of the fingerprint: the index entry's name.
    pub key: String,
    /// The sensor-noise realisation (0: the scene's own noise seed).
    pub realisation: usize,
    /// A threshold study's level: the knob value the stimulus is rendered with
    /// ([`crate::study::Condition::knob`]).
    pub knob: Option<mrstudy_renderer::knob::KnobSetting>,
}

impl PlannedStimulus {
    /// The render settings of this stimulus: the plan's, with its knob set.
    pub fn settings(&self, plan: &StimulusPlan) -> StimulusSettings {
        plan.settings.with_knob(self.knob)
    }
}

impl PlannedStimulus {
    /// The name of the index entry of the stimulus's [`StimulusRecord`].
    pub fn record_key(&self) -> String {
        format!("{}.metrics", self.key)
    }
}

/// One scene configuration's part of a [`StimulusPlan`]: the renderer's scene, loaded once at
/// the study's stimulus size, the key of its ground truth and a stimulus per condition.
#[derive(Debug, Clone)]
pub struct PlannedScene {
    pub scene: mrstudy_renderer::Scene,
    /// SHA-256 of the ground truth's fingerprint; `None` for a scene with a background
    /// photograph, which has no ground truth.
    pub ground_truth_key: Option<String>,
    pub stimuli: Vec<PlannedStimulus>,
    /// Realisations 1, 2, … of a detection design with `realisations` > 1 (realisation 0 is
    /// the fields above).
    pub realisations: Vec<PlannedRealisation>,
}

/// One further sensor-noise realisation of a scene configuration: its scene (the noise seed
/// replaced), its ground truth's key and a stimulus per condition.
#[derive(Debug, Clone)]
pub struct PlannedRealisation {
    pub scene: mrstudy_renderer::Scene,
    pub ground_truth_key: String,
    pub stimuli: Vec<PlannedStimulus>,
}

/// The noise seed of realisation `realisation` of a scene whose camera has noise seed `base`:
/// `base` itself for realisation 0 (the stimuli other studies of the scene share), else a
/// SplitMix64 step of the two.
pub fn realisation_seed(base: u64, realisation: usize) -> u64 {
    if realisation == 0 { base } else { crate::schedule::derived_seed(base, realisation as u64) }
}

/// `scene` with its camera's noise seed that of realisation `realisation` (in the resolved
/// parameters and in the description, so fingerprints tell realisations apart).
pub fn realised(mut scene: mrstudy_renderer::Scene, realisation: usize) -> mrstudy_renderer::Scene {
    if realisation > 0 {
        let seed = realisation_seed(scene.sensor.seed, realisation);
        scene.sensor.seed = seed;
        scene.desc.camera.sensor.seed = Some(seed);
    }
    scene
}

impl PlannedScene {
    /// The ground-truth key and stimuli of realisation `realisation`, if planned.
    pub fn realisation(&self, realisation: usize) -> Option<(Option<&String>, &[PlannedStimulus])> {
        match realisation {
            0 => Some((self.ground_truth_key.as_ref(), &self.stimuli)),
            k => self.realisations.get(k - 1).map(|r| (Some(&r.ground_truth_key), r.stimuli.as_slice())),
        }
    }

    /// Every planned stimulus of the scene configuration, realisation by realisation.
    pub fn all_stimuli(&self) -> impl Iterator<Item = &PlannedStimulus> {
        self.stimuli.iter().chain(self.realisations.iter().flat_map(|r| &r.stimuli))
    }

    /// True when something of the scene configuration is not in `store`: a stimulus, its
    /// ground truth, or a stimulus's record.
    fn incomplete(&self, store: &Path) -> bool {
        let realisation_incomplete = |r: &PlannedRealisation| {
            lookup(store, &r.ground_truth_key).is_none()
                || r.stimuli.iter().any(|s| lookup(store, &s.key).is_none() || lookup_record(store, s).is_none())
        };
        if self.realisations.iter().any(realisation_incomplete) {
            return true;
        }
        match &self.ground_truth_key {
            Some(key) => {
                lookup(store, key).is_none()
                    || self.stimuli.iter().any(|s| lookup(store, &s.key).is_none() || lookup_record(store, s).is_none())
            }
            None => self.stimuli.iter().any(|s| lookup(store, &s.key).is_none()),
        }
    }
}

/// What the store keeps about a rendered stimulus beside its image: its errors against the
/// ground truth of its scene configuration, the render's time and settings. Names of scene
/// configurations and conditions are not in it (the store is shared by studies); the study's
/// plan adds them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StimulusRecord {
    /// The stimulus's file name in the store.
    pub stimulus: String,
    /// The ground truth's file name in the store.
    pub ground_truth: String,
    /// The factors switched on (`gi+cm`, `none`, …).
    pub factors: String,
    pub settings: StimulusSettings,
    /// The GPU frame's time (the frame this record was made with).
    pub render_ms: f64,
    pub adapter: String,
    /// The reference render of the photograph and the ground truth, shared by the scene
    /// configuration's stimuli.
    pub reference_seconds: f64,
    pub errors: StimulusErrors,
    /// What the render found that a researcher should know (the statistics colour mapping's
    /// channel ratios outside [0.5, 2]), one sentence each naming the scene; absent when none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// Every stimulus a study needs from the renderer, with its cache key: made once per study (each
/// scene file loaded once) and used to render what is missing ([`render_missing`]), to find the
/// stimuli to serve ([`crate::PreparedStudy::prepare`]) and to write copies ([`write_copies`]).
#[derive(Debug, Clone)]
pub struct StimulusPlan {
    pub settings: StimulusSettings,
    /// `[scene configuration]`; `None` where the scene configuration has image files.
    pub scenes: Vec<Option<PlannedScene>>,
}

impl StimulusPlan {
    /// The plan of `study`: its render settings, each rendered scene configuration's scene and
    /// one stimulus per condition, keyed by the renderer's fingerprint.
    pub fn of(study: &Study) -> Result<StimulusPlan, StimuliError> {
        let settings = settings(study);
        let mut scenes = Vec::new();
        for (scene_index, scene) in study.scenes.iter().enumerate() {
            let StimulusSource::Render(render) = &scene.source else {
                scenes.push(None);
                continue;
            };
            let loaded = mrstudy_renderer::scene::load(render).map_err(|source| StimuliError::Render {
                slug: study.slug.clone(),
                file: study.file.clone(),
                scene: scene.name.clone(),
                source,
            })?;
            let loaded = settings.sized(loaded);
            if study.design.reference.is_some() && loaded.background.is_some() {
                return Err(StimuliError::Render {
                    slug: study.slug.clone(),
                    file: study.file.clone(),
                    scene: scene.name.clone(),
                    source: RenderError::Unsupported(format!(
                        "the scene `{render}` has a background photograph, so it has no ground truth for reference = \"ground-truth\""
                    )),
                });
            }
            let ground_truth_key =
                loaded.background.is_none().then(|| sha256_hex(settings.ground_truth_fingerprint(&loaded).as_bytes()));
            let stimuli_of = |loaded: &mrstudy_renderer::Scene, realisation: usize| {
                let mut stimuli = Vec::new();
                for (condition_index, condition) in study.conditions.iter().enumerate() {
                    let factors = condition.factors.clone().map_err(|reason| StimuliError::Factors {
                        slug: study.slug.clone(),
                        file: study.file.clone(),
                        condition: condition.name.clone(),
                        reason,
                    })?;
                    stimuli.push(PlannedStimulus {
                        scene_index,
                        condition_index,
                        scene: scene.name.clone(),
                        condition: condition.name.clone(),
                        factors,
                        key: sha256_hex(settings.with_knob(condition.knob).fingerprint(loaded, &factors).as_bytes()),
                        realisation,
                        knob: condition.knob,
                    });
                }
                Ok::<_, StimuliError>(stimuli)
            };
            let stimuli = stimuli_of(&loaded, 0)?;
            let mut realisations = Vec::new();
            if ground_truth_key.is_some() {
                for realisation in 1..study.design.realisations.max(1) as usize {
                    let scene = realised(loaded.clone(), realisation);
                    realisations.push(PlannedRealisation {
                        ground_truth_key: sha256_hex(settings.ground_truth_fingerprint(&scene).as_bytes()),
                        stimuli: stimuli_of(&scene, realisation)?,
                        scene,
                    });
                }
            }
            scenes.push(Some(PlannedScene { scene: loaded, ground_truth_key, stimuli, realisations }));
        }
        Ok(StimulusPlan { settings, scenes })
    }

    /// Every planned stimulus, scene configuration by scene configuration (each with its
    /// realisations).
    pub fn stimuli(&self) -> impl Iterator<Item = &PlannedStimulus> {
        self.scenes.iter().flatten().flat_map(|scene| scene.all_stimuli())
    }

    /// The planned stimuli not yet in `store` (their images: what serving needs).
    pub fn missing(&self, store: &Path) -> Vec<&PlannedStimulus> {
        self.stimuli().filter(|stimulus| lookup(store, &stimulus.key).is_none()).collect()
    }

    /// The scene configurations (indices) with something not yet in `store`: a stimulus, its
    /// ground truth or a stimulus's record ([`render_missing`] makes them).
    pub fn incomplete(&self, store: &Path) -> Vec<usize> {
        self.scenes
            .iter()
            .enumerate()
            .filter(|(_, planned)| planned.as_ref().is_some_and(|planned| planned.incomplete(store)))
            .map(|(index, _)| index)
            .collect()
    }
}

/// Why a `--shard K/N` was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ShardError {
    #[error("`{text}` is not K/N (e.g. 3/8: the third of eight shares)")]
    NotKOfN { text: String },
    #[error("`{part}` in `{text}` is not a whole number")]
    NotANumber { part: String, text: String },
    #[error("`{text}`: K must be 1 to N and N at least 1")]
    OutOfRange { text: String },
}

/// A share of a study's rendering: the `index`-th (1-based) of `count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    /// Parses `K/N` with 1 ≤ K ≤ N; says what is wrong otherwise.
    pub fn parse(text: &str) -> Result<Shard, ShardError> {
        let (index, count) = text.split_once('/').ok_or_else(|| ShardError::NotKOfN { text: text.to_string() })?;
        let number = |part: &str| {
            part.trim()
                .parse::<usize>()
                .map_err(|_| ShardError::NotANumber { part: part.to_string(), text: text.to_string() })
        };
        let (index, count) = (number(index)?, number(count)?);
        if count == 0 || index == 0 || index > count {
            return Err(ShardError::OutOfRange { text: text.to_string() });
        }
        Ok(Shard { index, count })
    }

    /// Whether this shard renders the scene configuration at `position` among the renderable
    /// ones (0-based, in the study's order).
    pub fn owns(&self, position: usize) -> bool {
        position % self.count == self.index - 1
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl StimulusPlan {
    /// How many stimuli the scene configurations `scenes` (indices) have.
    pub fn stimuli_in(&self, scenes: &[usize]) -> usize {
        scenes.iter().filter_map(|&index| self.scenes[index].as_ref()).map(|scene| scene.all_stimuli().count()).sum()
    }

    /// One line naming the scene configurations `shard` renders of `study`.
    pub fn shard_line(&self, study: &Study, shard: Shard) -> String {
        let names: Vec<&str> =
            self.shard_scenes(shard).into_iter().map(|index| study.scenes[index].name.as_str()).collect();
        format!(
            "shard {shard}: {} of the study's {} rendered scene configurations{}",
            names.len(),
            self.scenes.iter().flatten().count(),
            if names.is_empty() {
                " (nothing to do: more shards than scene configurations)".to_string()
            } else {
                format!(": {}", names.join(", "))
            }
        )
    }

    /// The summary line of `mrstudy stimuli`: what `rendered` made of the study's (or the
    /// shard's) stimuli in `store`, and what was there already.
    pub fn rendered_line(&self, study: &Study, rendered: &Rendered, store: &Path, shard: Option<Shard>) -> String {
        let total = match shard {
            Some(shard) => self.stimuli_in(&self.shard_scenes(shard)),
            None => self.stimuli().count(),
        };
        format!(
            "study \"{}\": rendered {} stimuli, {} were already in {} ({total} rendered stimuli in all); {} ground truths and {} stimulus records made",
            study.slug,
            rendered.stimuli,
            total.saturating_sub(rendered.stimuli),
            store.display(),
            rendered.ground_truths,
            rendered.records
        )
    }

    /// The scene configurations (indices) `shard` renders, incomplete in `store` or not.
    pub fn shard_scenes(&self, shard: Shard) -> Vec<usize> {
        self.scenes
            .iter()
            .enumerate()
            .filter(|(_, planned)| planned.is_some())
            .enumerate()
            .filter(|(position, _)| shard.owns(*position))
            .map(|(_, (index, _))| index)
            .collect()
    }
}

/// What [`render_missing`] made.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Rendered {
    /// Stimulus images rendered and stored.
    pub stimuli: usize,
    /// Ground-truth composites rendered and stored.
    pub ground_truths: usize,
    /// Stimulus records (errors against the ground truth) made, for new stimuli and for
    /// stimuli stored before records existed.
    pub records: usize,
}

/// What the progress callback is told.
#[derive(Debug, Clone)]
pub enum Progress {
    /// Rendering starts: `photos` reference renders (each the photograph and, where the scene
    /// is synthesised, its ground truth) and `stimuli` GPU frames to make.
    Start { photos: usize, stimuli: usize },
    /// A reference render's samples: `done` of `total` samples per pixel (the photograph's, then
    /// the ground truth's).
    Photo { scene: String, done: u32, total: u32 },
    /// A stimulus was rendered and stored; `warning`, what its render found that a researcher
    /// should know (the statistics colour mapping's ratios outside [0.5, 2]), one sentence.
    Stimulus { scene: String, condition: String, ms: f64, warning: Option<String> },
}

/// The render settings of a study (its `[render]` table; defaults of the renderer otherwise).
pub fn settings(study: &Study) -> StimulusSettings {
    let defaults = StimulusSettings::default();
    match &study.render {
        Some(render) => StimulusSettings {
            width: render.size[0],
            height: render.size[1],
            spp: render.spp.unwrap_or(defaults.spp),
            seed: render.seed.unwrap_or(defaults.seed),
            vpls: render.vpls.unwrap_or(defaults.vpls),
            knob: None,
        },
        None => defaults,
    }
}

fn index_path(store: &Path, key: &str) -> PathBuf {
    store.join("rendered").join(key)
}

/// The stored file name of a rendered stimulus, if it is in the store.
pub fn lookup(store: &Path, key: &str) -> Option<String> {
    let name = std::fs::read_to_string(index_path(store, key)).ok()?;
    let name = name.trim().to_string();
    store.join(&name).is_file().then_some(name)
}

/// Writes `bytes` into the store as `<sha256>.<extension>` (if not there) and returns the name.
pub fn store_bytes(bytes: &[u8], extension: &str, store: &Path) -> Result<String, std::io::Error> {
    let name = format!("{}.{extension}", sha256_hex(bytes));
    let target = store.join(&name);
    if !target.exists() {
        std::fs::create_dir_all(store)?;
        write_atomically(&partial(&store.join(format!(".{name}"))), &target, bytes)?;
    }
    Ok(name)
}

/// A partial file's name beside `path`, unique to this process and call: several renderers
/// (shards, servers) may write the same entry of a shared store at once.
fn partial(path: &Path) -> PathBuf {
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let mut name = path.as_os_str().to_owned();
    name.push(format!(".{}-{n}.partial", std::process::id()));
    PathBuf::from(name)
}

fn write_atomically(temporary: &Path, target: &Path, bytes: &[u8]) -> Result<(), std::io::Error> {
    use std::io::Write;
    let mut file = std::fs::File::create(temporary)?;
    file.write_all(bytes)?;
    file.sync_all()?;
    std::fs::rename(temporary, target)
}

/// The stored record of `stimulus`, if it is in the store.
pub fn lookup_record(store: &Path, stimulus: &PlannedStimulus) -> Option<StimulusRecord> {
    let name = lookup(store, &stimulus.record_key())?;
    serde_json::from_slice(&std::fs::read(store.join(name)).ok()?).ok()
}

fn write_entry(store: &Path, key: &str, name: &str) -> Result<(), StimuliError> {
    let entry = index_path(store, key);
    write_atomically(&partial(&entry), &entry, name.as_bytes())
        .map_err(|source| StimuliError::Io { path: entry, source })
}

/// Renders what the study's `plan` needs and `store` lacks: for each incomplete scene
/// configuration one reference render (the photograph, and the ground truth where the scene is
/// synthesised), then each missing stimulus on the GPU over the photograph, and each stimulus's
/// [`StimulusRecord`] (a stimulus stored before records existed is rendered again for its
/// time, and measured as stored). [`write_copies`] writes named copies of every stimulus
/// afterwards.
pub fn render_missing(
    study: &Study,
    plan: &StimulusPlan,
    store: &Path,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<Rendered, StimuliError> {
    render_missing_shard(study, plan, store, None, progress)
}

/// [`render_missing`] for the scene configurations of one `shard` only (all with `None`).
pub fn render_missing_shard(
    study: &Study,
    plan: &StimulusPlan,
    store: &Path,
    shard: Option<Shard>,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<Rendered, StimuliError> {
    let mut scenes = plan.incomplete(store);
    if let Some(shard) = shard {
        let owned = plan.shard_scenes(shard);
        scenes.retain(|index| owned.contains(index));
    }
    if scenes.is_empty() {
        return Ok(Rendered::default());
    }
    let renderer = DirRenderer::new().map_err(|source| StimuliError::NoGpu {
        slug: study.slug.clone(),
        file: study.file.clone(),
        source,
    })?;
    render_scenes(&renderer, study, plan, store, scenes, progress)
}

/// [`render_missing`] on a GPU renderer the caller keeps (the server's render queue,
/// [`crate::render_queue`], renders level after level on one).
pub fn render_missing_on(
    renderer: &DirRenderer,
    study: &Study,
    plan: &StimulusPlan,
    store: &Path,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<Rendered, StimuliError> {
    render_scenes(renderer, study, plan, store, plan.incomplete(store), progress)
}

fn render_scenes(
    renderer: &DirRenderer,
    study: &Study,
    plan: &StimulusPlan,
    store: &Path,
    scenes: Vec<usize>,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<Rendered, StimuliError> {
    let mut rendered = Rendered::default();
    if scenes.is_empty() {
        return Ok(rendered);
    }
    let frames = plan.stimuli_in(&scenes);
    progress(Progress::Start { photos: scenes.len(), stimuli: frames });
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| StimuliError::Io { path, source }
    };
    std::fs::create_dir_all(store.join("rendered")).map_err(io(&store.join("rendered")))?;
    for scene_index in scenes {
        let Some(planned) = &plan.scenes[scene_index] else { continue };
        let scene_name = study.scenes[scene_index].name.clone();
        let render_error = |source| StimuliError::Render {
            slug: study.slug.clone(),
            file: study.file.clone(),
            scene: scene_name.clone(),
            source,
        };
        let report = |done, total| progress(Progress::Photo { scene: scene_name.clone(), done, total });
        // the photograph, and the ground truth with its masks where the scene is synthesised
        let (photo, linear, reference) = match &planned.ground_truth_key {
            Some(key) => {
                let reference = match recent_reference(key) {
                    Some(reference) => reference,
                    None => {
                        let reference = std::sync::Arc::new(
                            plan.settings.reference(&planned.scene, &report).map_err(render_error)?,
                        );
                        keep_reference(key, &reference);
                        reference
                    }
                };
                let shown = quantized(&reference.ground_truth);
                let name = store_ground_truth(store, key, &shown, &mut rendered)?;
                (reference.photo.clone(), reference.hdr_real.clone(), Some((reference, shown, name)))
            }
            None => {
                let (linear, photo, _) = plan.settings.photo(&planned.scene, &report).map_err(render_error)?;
                (photo, linear, None)
            }
        };
        let render_realisation = |scene: &mrstudy_renderer::Scene,
                                  stimuli: &[PlannedStimulus],
                                  photo: &Image,
                                  ground_truth: Option<(&ReferenceOutput, &Image, &String)>,
                                  rendered: &mut Rendered|
         -> Result<(), StimuliError> {
            // the simulated capture of the real scene, made by its first coherent stimulus
            let mut captured = None;
            for stimulus in stimuli {
                let stored = lookup(store, &stimulus.key);
                let needs_record = ground_truth.is_some() && lookup_record(store, stimulus).is_none();
                if stored.is_some() && !needs_record {
                    progress(Progress::Stimulus {
                        scene: stimulus.scene.clone(),
                        condition: stimulus.condition.clone(),
                        ms: 0.0,
                        warning: None,
                    });
                    continue;
                }
                let frame = stimulus
                    .settings(plan)
                    .render_stimulus(renderer, scene, photo, &linear, &stimulus.factors, &mut captured)
                    .map_err(render_error)?;
                let warning = frame.cm_warning.as_ref().map(|w| w.sentence(&scene.name));
                let (name, shown) = match stored {
                    Some(name) => {
                        let path = store.join(&name);
                        let image = Image::load(&path, "stimulus")
                            .map_err(|error| StimuliError::Store { path, reason: error.to_string() })?;
                        (name, image)
                    }
                    None => {
                        let name = store_bytes(&frame.composite.encode_png(), "png", store).map_err(io(store))?;
                        write_entry(store, &stimulus.key, &name)?;
                        rendered.stimuli += 1;
                        (name, quantized(&frame.composite))
                    }
                };
                if let Some((reference, ground_truth, ground_truth_name)) = ground_truth {
                    let record = StimulusRecord {
                        stimulus: name,
                        ground_truth: ground_truth_name.clone(),
                        factors: stimulus.factors.label(),
                        settings: stimulus.settings(plan),
                        render_ms: frame.ms,
                        adapter: frame.adapter.clone(),
                        reference_seconds: reference.stats.seconds,
                        errors: stimulus_errors(
                            ground_truth,
                            &shown,
                            &reference.affected_mask,
                            &reference.virtual_mask,
                        ),
                        warnings: warning.iter().cloned().collect(),
                    };
                    let bytes = serde_json::to_vec_pretty(&record).expect("a stimulus record serialises");
                    let record_name = store_bytes(&bytes, "json", store).map_err(io(store))?;
                    write_entry(store, &stimulus.record_key(), &record_name)?;
                    rendered.records += 1;
                }
                progress(Progress::Stimulus {
                    scene: stimulus.scene.clone(),
                    condition: stimulus.condition.clone(),
                    ms: frame.ms,
                    warning,
                });
            }
            Ok(())
        };
        render_realisation(
            &planned.scene,
            &planned.stimuli,
            &photo,
            reference.as_ref().map(|(reference, shown, name)| (&**reference, shown, name)),
            &mut rendered,
        )?;
        // further realisations: the same radiance through the camera with another noise seed
        if let Some((reference, _, _)) = &reference {
            for realisation in &planned.realisations {
                let camera = &realisation.scene.camera;
                let sensor = &realisation.scene.sensor;
                let photo = mrstudy_renderer::sensor::apply(&reference.hdr_real, camera, sensor);
                let shown = quantized(&mrstudy_renderer::sensor::apply(&reference.hdr_full, camera, sensor));
                let name = store_ground_truth(store, &realisation.ground_truth_key, &shown, &mut rendered)?;
                render_realisation(
                    &realisation.scene,
                    &realisation.stimuli,
                    &photo,
                    Some((reference, &shown, &name)),
                    &mut rendered,
                )?;
            }
        }
    }
    Ok(rendered)
}

/// Reference renders kept in memory after [`render_missing`] made them, by the key of their
/// ground truth (realisation 0), the most recent last: when one study's stimuli were rendered
/// and another study needs further realisations of the same scene configuration (the web survey
/// renders first, having fewer stimuli; real-or-rendered's realisations follow), its radiance is
/// not traced again. At most [`KEPT_REFERENCES`] (about 27 MB each at 800 × 600).
static RECENT_REFERENCES: std::sync::Mutex<Vec<(String, std::sync::Arc<ReferenceOutput>)>> =
    std::sync::Mutex::new(Vec::new());

/// How many reference renders [`RECENT_REFERENCES`] keeps: the web survey's scene configurations.
const KEPT_REFERENCES: usize = 6;

pub(crate) fn recent_reference(key: &str) -> Option<std::sync::Arc<ReferenceOutput>> {
    let kept = RECENT_REFERENCES.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    kept.iter().find(|(kept_key, _)| kept_key == key).map(|(_, reference)| reference.clone())
}

pub(crate) fn keep_reference(key: &str, reference: &std::sync::Arc<ReferenceOutput>) {
    let mut kept = RECENT_REFERENCES.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    kept.retain(|(kept_key, _)| kept_key != key);
    if kept.len() >= KEPT_REFERENCES {
        kept.remove(0);
    }
    kept.push((key.to_string(), reference.clone()));
}

/// The stored ground truth under `key`, storing `shown` first where it is not there yet.
fn store_ground_truth(store: &Path, key: &str, shown: &Image, rendered: &mut Rendered) -> Result<String, StimuliError> {
    if let Some(name) = lookup(store, key) {
        return Ok(name);
    }
    let name = store_bytes(&shown.encode_png(), "png", store)
        .map_err(|source| StimuliError::Io { path: store.to_path_buf(), source })?;
    write_entry(store, key, &name)?;
    rendered.ground_truths += 1;
    Ok(name)
}

/// The stimulus metrics of a study's rendered stimuli, read from their records in the store:
/// when the study is prepared, and again for an on-demand threshold study after levels were
/// rendered (`RenderQueue::metrics`).
#[derive(Debug, Clone, Default)]
pub struct StimulusMetricsNow {
    /// The stimulus metrics CSV (docs/design.md); `None` when no stimulus has a ground truth.
    pub csv: Option<String>,
    /// Why a scene configuration has none, or why the records could not be read.
    pub notes: Vec<String>,
    /// The CSV parsed for the analysis.
    pub metrics: Option<StimulusMetrics>,
}

impl StimulusMetricsNow {
    /// The metrics of `plan`'s stimuli (those in `store`).
    pub fn of(study: &Study, plan: &StimulusPlan, store: &Path) -> StimulusMetricsNow {
        let (mut csv, mut notes) = match metrics_csv(study, plan, store) {
            Ok((csv, notes)) => (csv.lines().nth(1).is_some().then_some(csv), notes),
            Err(error) => (None, vec![error.to_string()]),
        };
        let metrics = match csv.as_deref().map(|csv| parse_stimulus_metrics(csv, "stimulus metrics CSV")) {
            Some(Ok(metrics)) => Some(metrics),
            Some(Err(error)) => {
                csv = None;
                notes.push(format!("the stimulus metrics cannot be read: {error}"));
                None
            }
            None => None,
        };
        StimulusMetricsNow { csv, notes, metrics }
    }
}

/// The study's stimulus metrics CSV (docs/design.md): `stimulus,scene,condition,metric,region,value`,
/// one row per stimulus, metric and region, `render_ms` in region `image` (realisation 0 of each
/// scene configuration only: further sensor-noise realisations differ from it in noise alone,
/// and the CSV is joined to trials by scene and condition); and one sentence per
/// scene configuration that has no ground truth (image files, or a background photograph).
/// A rendered stimulus without its record in `store` is an error naming it (render it first).
pub fn metrics_csv(study: &Study, plan: &StimulusPlan, store: &Path) -> Result<(String, Vec<String>), StimuliError> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let csv_error = |error: csv::Error| StimuliError::Store { path: store.to_path_buf(), reason: error.to_string() };
    writer.write_record(["stimulus", "scene", "condition", "metric", "region", "value"]).map_err(csv_error)?;
    let mut notes = Vec::new();
    for (scene, planned) in study.scenes.iter().zip(&plan.scenes) {
        let Some(planned) = planned.as_ref().filter(|planned| planned.ground_truth_key.is_some()) else {
            notes.push(match scene.source {
                StimulusSource::Images(_) => format!(
                    "scene configuration \"{}\" shows image files: no ground truth exists for its stimuli",
                    scene.name
                ),
                StimulusSource::Render(_) => format!(
                    "scene configuration \"{}\" has a background photograph: no ground truth exists for its stimuli",
                    scene.name
                ),
            });
            continue;
        };
        for stimulus in &planned.stimuli {
            let record = lookup_record(store, stimulus).ok_or_else(|| StimuliError::Store {
                path: index_path(store, &stimulus.record_key()),
                reason: format!(
                    "the errors of the stimulus {} / {} are not in the store (run `mrstudy stimuli --study {}` first)",
                    stimulus.scene,
                    stimulus.condition,
                    study.file.display()
                ),
            })?;
            let mut row = |metric: &str, region: &str, value: f64| {
                writer.write_record([
                    record.stimulus.as_str(),
                    stimulus.scene.as_str(),
                    stimulus.condition.as_str(),
                    metric,
                    region,
                    &format!("{value}"),
                ])
            };
            for value in &record.errors.values {
                row(&value.metric, &value.region, value.value).map_err(csv_error)?;
            }
            row("render_ms", "image", record.render_ms).map_err(csv_error)?;
        }
    }
    let bytes = writer
        .into_inner()
        .map_err(|error| StimuliError::Store { path: store.to_path_buf(), reason: error.to_string() })?;
    Ok((String::from_utf8(bytes).expect("the CSV is UTF-8"), notes))
}

/// Writes every stimulus of the study into `dir` as `<scene>__<condition>.<extension>`: the
/// rendered ones from the store (whether rendered now or before) and the image files of scene
/// configurations that have them. Returns how many were written; a rendered stimulus missing
/// from the store is an error naming it (render it first).
pub fn write_copies(study: &Study, plan: &StimulusPlan, store: &Path, dir: &Path) -> Result<usize, StimuliError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| StimuliError::Io { path, source }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let mut written = 0;
    for (scene, planned) in study.scenes.iter().zip(&plan.scenes) {
        match (planned, &scene.source) {
            (Some(planned), _) => {
                for stimulus in planned.all_stimuli() {
                    let name = lookup(store, &stimulus.key).ok_or_else(|| StimuliError::Io {
                        path: store.join("rendered").join(&stimulus.key),
                        source: std::io::Error::new(
                            std::io::ErrorKind::NotFound,
                            format!("the stimulus {} / {} is not in the store", stimulus.scene, stimulus.condition),
                        ),
                    })?;
                    let extension = Path::new(&name).extension().and_then(|e| e.to_str()).unwrap_or("png").to_string();
                    // realisation k > 0 of a detection design: `<scene>__<condition>__r<k>`
                    let realisation =
                        if stimulus.realisation == 0 { String::new() } else { format!("__r{}", stimulus.realisation) };
                    let copy = dir.join(format!(
                        "{}__{}{realisation}.{extension}",
                        file_safe(&stimulus.scene),
                        file_safe(&stimulus.condition)
                    ));
                    std::fs::copy(store.join(&name), &copy).map_err(io(&copy))?;
                    written += 1;
                }
            }
            (None, StimulusSource::Images(images)) => {
                for (condition, image) in study.conditions.iter().zip(images) {
                    let extension = image.extension().and_then(|e| e.to_str()).unwrap_or("png").to_ascii_lowercase();
                    let copy =
                        dir.join(format!("{}__{}.{extension}", file_safe(&scene.name), file_safe(&condition.name)));
                    std::fs::copy(image, &copy).map_err(io(&copy))?;
                    written += 1;
                }
            }
            (None, StimulusSource::Render(_)) => {}
        }
    }
    Ok(written)
}

/// A name usable in a file name: letters, digits, `-`, `_`, `.`; anything else becomes `-`.
fn file_safe(name: &str) -> String {
    name.chars().map(|c| if c.is_ascii_alphanumeric() || "-_.".contains(c) { c } else { '-' }).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_safe_names_keep_plain_characters_only() {
        assert_eq!(file_safe("GI+CA"), "GI-CA");
        assert_eq!(file_safe("survey-1"), "survey-1");
        assert_eq!(file_safe("../x"), "..-x");
    }

    #[test]
    fn stored_bytes_are_named_by_content_and_written_once() {
        let dir = tempfile::tempdir().unwrap();
        let a = store_bytes(b"abc", "png", dir.path()).unwrap();
        assert_eq!(a, format!("{}.png", sha256_hex(b"abc")));
        assert_eq!(store_bytes(b"abc", "png", dir.path()).unwrap(), a);
        assert_eq!(std::fs::read(dir.path().join(&a)).unwrap(), b"abc");
        assert!(crate::prepared::stimulus_content_type(&a).is_some());
    }

    const REALISED: &str = r#"
slug = "realised"
title = "T"
kind = "paired-comparison"
question = "Q?"
[texts]
welcome = "w"
consent = "c"
instructions = "i"
[[factors]]
name = "ca"
[[conditions]]
name = "LQ"
levels = { ca = 0 }
[[conditions]]
name = "CA"
levels = { ca = 1 }
[[scenes]]
name = "a"
render = "survey-1"
[render]
size = [48, 36]
spp = 2
[design]
reference = "ground-truth"
realisations = 2
repetitions = 1
scenes = "same"
"#;

    #[test]
    fn a_realisation_is_the_same_radiance_through_the_camera_with_another_noise_seed() {
        if DirRenderer::new().is_err() {
            eprintln!("skipped: no GPU adapter (not even a software one)");
            return;
        }
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("realised.toml");
        std::fs::write(&file, REALISED).unwrap();
        let study = crate::study::load_study(&file).unwrap();
        let plan = StimulusPlan::of(&study).unwrap();
        let store = dir.path().join("store");
        let rendered = render_missing(&study, &plan, &store, &|_| {}).unwrap();
        assert_eq!(rendered, Rendered { stimuli: 4, ground_truths: 2, records: 4 });
        assert!(plan.incomplete(&store).is_empty());
        let planned = plan.scenes[0].as_ref().unwrap();
        let realisation = &planned.realisations[0];
        let load = |key: &str| Image::load(&store.join(lookup(&store, key).unwrap()), "test").unwrap();
        let (first, second) = (load(planned.ground_truth_key.as_ref().unwrap()), load(&realisation.ground_truth_key));
        // the pass through the camera of the kept radiance equals a whole reference render of
        // the realised scene: the path tracer's radiance does not depend on the noise seed
        let whole = plan.settings.reference(&realisation.scene, &|_, _| {}).unwrap();
        assert_eq!(quantized(&whole.ground_truth).encode_png(), second.encode_png());
        // another noise realisation: different pixels, the same picture on average
        let differing = first.pixels.iter().zip(&second.pixels).filter(|(a, b)| a != b).count();
        assert!(differing * 4 > first.pixels.len(), "{differing} of {} pixels differ", first.pixels.len());
        let mean = |image: &Image| {
            image.pixels.iter().map(|p| f64::from(p.x + p.y + p.z) / 3.0).sum::<f64>() / image.pixels.len() as f64
        };
        assert!((mean(&first) - mean(&second)).abs() < 0.02, "{} vs {}", mean(&first), mean(&second));
        // the stimuli of realisation 1 differ from realisation 0's (rendered over its photograph)
        for (zero, one) in planned.stimuli.iter().zip(&realisation.stimuli) {
            assert_ne!(lookup(&store, &zero.key), lookup(&store, &one.key), "{}", zero.condition);
            assert!(lookup_record(&store, one).is_some_and(|record| record.ground_truth == lookup(&store, &realisation.ground_truth_key).unwrap()));
        }
    }

    #[test]
    fn further_realisations_of_a_scene_rendered_for_another_study_trace_no_radiance_again() {
        if DirRenderer::new().is_err() {
            eprintln!("skipped: no GPU adapter (not even a software one)");
            return;
        }
        let dir = tempfile::tempdir().unwrap();
        let load = |name: &str, text: &str| {
            let file = dir.path().join(name);
            std::fs::write(&file, text).unwrap();
            crate::study::load_study(&file).unwrap()
        };
        // the first study needs realisation 0 only (as the web survey), the second two
        // (as real-or-rendered); a size of its own, so no other test's render is kept
        let sized = REALISED.replace("size = [48, 36]", "size = [40, 30]");
        let first = load("first.toml", &sized.replace("realisations = 2", "realisations = 1"));
        let second = load("second.toml", &sized.replace("slug = \"realised\"", "slug = \"realised-2\""));
        let store = dir.path().join("store");
        let photos = std::sync::atomic::AtomicUsize::new(0);
        let count = |step: Progress| {
            if matches!(step, Progress::Photo { .. }) {
                photos.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            }
        };
        let first_plan = StimulusPlan::of(&first).unwrap();
        assert_eq!(render_missing(&first, &first_plan, &store, &count).unwrap().stimuli, 2);
        assert!(photos.load(std::sync::atomic::Ordering::Relaxed) > 0, "the first study traces its radiance");
        photos.store(0, std::sync::atomic::Ordering::Relaxed);
        let second_plan = StimulusPlan::of(&second).unwrap();
        let rendered = render_missing(&second, &second_plan, &store, &count).unwrap();
        assert_eq!(rendered, Rendered { stimuli: 2, ground_truths: 1, records: 2 });
        assert_eq!(photos.load(std::sync::atomic::Ordering::Relaxed), 0, "the radiance was traced again");
    }
}
