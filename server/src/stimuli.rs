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

use std::path::{Path, PathBuf};

use mrstudy_renderer::RenderError;
use mrstudy_renderer::gpu::DirRenderer;
use mrstudy_renderer::stimulus::{Factors, StimulusSettings};

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
}

/// One scene configuration's part of a [`StimulusPlan`]: the renderer's scene, loaded once at
/// the study's stimulus size, and a stimulus per condition.
#[derive(Debug, Clone)]
pub struct PlannedScene {
    pub scene: mrstudy_renderer::Scene,
    pub stimuli: Vec<PlannedStimulus>,
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
                    key: sha256_hex(settings.fingerprint(&loaded, &factors).as_bytes()),
                });
            }
            scenes.push(Some(PlannedScene { scene: loaded, stimuli }));
        }
        Ok(StimulusPlan { settings, scenes })
    }

    /// Every planned stimulus, scene configuration by scene configuration.
    pub fn stimuli(&self) -> impl Iterator<Item = &PlannedStimulus> {
        self.scenes.iter().flatten().flat_map(|scene| &scene.stimuli)
    }

    /// The planned stimuli not yet in `store`.
    pub fn missing(&self, store: &Path) -> Vec<&PlannedStimulus> {
        self.stimuli().filter(|stimulus| lookup(store, &stimulus.key).is_none()).collect()
    }
}

/// What the progress callback is told.
#[derive(Debug, Clone)]
pub enum Progress {
    /// Rendering starts: `photos` photographs and `stimuli` GPU frames to make.
    Start { photos: usize, stimuli: usize },
    /// A photograph's samples: `done` of `total` samples per pixel.
    Photo { scene: String, done: u32, total: u32 },
    /// A stimulus was rendered and stored.
    Stimulus { scene: String, condition: String, ms: f64 },
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
        write_atomically(&store.join(format!(".{name}.partial")), &target, bytes)?;
    }
    Ok(name)
}

fn write_atomically(temporary: &Path, target: &Path, bytes: &[u8]) -> Result<(), std::io::Error> {
    use std::io::Write;
    let mut file = std::fs::File::create(temporary)?;
    file.write_all(bytes)?;
    file.sync_all()?;
    std::fs::rename(temporary, target)
}

/// Renders the study's missing stimuli (by its `plan`) into `store` and returns how many were
/// rendered ([`write_copies`] writes named copies of every stimulus afterwards).
pub fn render_missing(
    study: &Study,
    plan: &StimulusPlan,
    store: &Path,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<usize, StimuliError> {
    let missing = plan.missing(store);
    if missing.is_empty() {
        return Ok(0);
    }
    let renderer = DirRenderer::new().map_err(|source| StimuliError::NoGpu {
        slug: study.slug.clone(),
        file: study.file.clone(),
        source,
    })?;
    let mut scenes: Vec<usize> = missing.iter().map(|stimulus| stimulus.scene_index).collect();
    scenes.dedup();
    progress(Progress::Start { photos: scenes.len(), stimuli: missing.len() });
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
        let (photo, _) = plan
            .settings
            .photo(&planned.scene, &|done, total| progress(Progress::Photo { scene: scene_name.clone(), done, total }))
            .map_err(render_error)?;
        for stimulus in missing.iter().filter(|stimulus| stimulus.scene_index == scene_index) {
            let frame =
                plan.settings.render(&renderer, &planned.scene, &photo, &stimulus.factors).map_err(render_error)?;
            let bytes = frame.composite.encode_png();
            let name = store_bytes(&bytes, "png", store).map_err(io(store))?;
            let entry = index_path(store, &stimulus.key);
            write_atomically(&entry.with_extension("partial"), &entry, name.as_bytes()).map_err(io(&entry))?;
            progress(Progress::Stimulus {
                scene: stimulus.scene.clone(),
                condition: stimulus.condition.clone(),
                ms: frame.report.ms,
            });
        }
    }
    Ok(missing.len())
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
                for stimulus in &planned.stimuli {
                    let name = lookup(store, &stimulus.key).ok_or_else(|| StimuliError::Io {
                        path: store.join("rendered").join(&stimulus.key),
                        source: std::io::Error::new(
                            std::io::ErrorKind::NotFound,
                            format!("the stimulus {} / {} is not in the store", stimulus.scene, stimulus.condition),
                        ),
                    })?;
                    let extension = Path::new(&name).extension().and_then(|e| e.to_str()).unwrap_or("png").to_string();
                    let copy = dir.join(format!(
                        "{}__{}.{extension}",
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
}
