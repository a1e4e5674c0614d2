//! A study made ready to serve: its stimuli copied into the content-addressed stimulus store
//! (`<data-dir>/stimuli/<sha256>.<ext>`) — image files copied, rendered stimuli looked up in the
//! store's index ([`crate::stimuli`]) — and schedules resolved to the stimulus files shown.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use mrstudy_analysis::stimulus_metrics::StimulusMetrics;

use crate::rating::RatedTrial;
use crate::schedule;
use crate::stimuli::{StimulusMetricsNow, StimulusPlan};
use crate::study::{GROUND_TRUTH, IMAGE_TYPES, StimulusSource, Study};
use crate::trial::{PlannedKind, PlannedTrial, ScheduledTrial, Side};

/// Why a study could not be made ready.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PrepareError {
    /// Stimuli of the study that must be rendered are not in the store yet (`serve` renders
    /// them at start-up; `mrstudy stimuli --study FILE` renders them ahead).
    #[error(
        "study \"{slug}\" ({file}) has {missing} stimuli still to render (scene configuration \"{scene}\" first); `mrstudy serve` renders them at start-up, `mrstudy stimuli --study {file}` ahead of it"
    )]
    NeedsRendering { slug: String, file: PathBuf, scene: String, missing: usize },
    /// The rendered stimuli could not be listed (a scene or condition the renderer refuses).
    #[error(transparent)]
    Stimuli(#[from] crate::stimuli::StimuliError),
    /// The study is a lab task study, which the web survey does not serve.
    #[error(
        "study \"{slug}\" ({file}) is a task study, which runs in the lab against the live renderer, not in the web survey"
    )]
    TaskStudy { slug: String, file: PathBuf },
    /// A threshold study's levels have no usable intensities (`crate::threshold::prepare`).
    #[error("study \"{slug}\": {reason}")]
    Threshold { slug: String, reason: String },
    #[error("cannot copy stimulus {path} into {store}: {source}")]
    Io { path: PathBuf, store: PathBuf, source: std::io::Error },
}

/// A study whose every stimulus is in the stimulus store.
#[derive(Debug)]
pub struct PreparedStudy {
    pub study: Study,
    /// `[scene][condition]` → stimulus file name (realisation 0); empty for a level of an
    /// on-demand threshold study not rendered when the study was prepared
    /// ([`crate::render_queue`] finds it then).
    pub stimuli: Vec<Vec<String>>,
    /// `[scene][realisation − 1][condition]` → stimulus file name of the further sensor-noise
    /// realisations of a detection design (empty otherwise).
    pub realisation_stimuli: Vec<Vec<Vec<String>>>,
    /// `[catch trial]` → (better, worse) stimulus file names.
    pub catch_stimuli: Vec<(String, String)>,
    /// A rating study's `[catch trial]` → (stimulus, reference) file names (`crate::rating`).
    pub rating_catch_stimuli: Vec<(String, Option<String>)>,
    /// `[scene][realisation]` → the ground truth's file name, for a detection design (empty
    /// otherwise).
    pub ground_truths: Vec<Vec<String>>,
    /// The stimulus metrics CSV (docs/design.md) of the rendered stimuli, `None` when no stimulus
    /// has a ground truth; and why a scene configuration has none (or the records could not be
    /// read).
    pub metrics_csv: Option<String>,
    pub metrics_notes: Vec<String>,
    /// `metrics_csv` as the analysis reads it, parsed once here rather than per admin request.
    pub stimulus_metrics: Option<StimulusMetrics>,
}

/// Label of a catch trial's images in the export's `left`/`right`/`chosen` columns.
pub fn catch_label(name: &str, better: bool) -> String {
    format!("catch:{name}:{}", if better { "better" } else { "worse" })
}

impl PreparedStudy {
    /// The study as the `studies` table records it.
    pub fn record(&self) -> crate::storage::StudyRecord<'_> {
        crate::storage::StudyRecord {
            slug: &self.study.slug,
            title: &self.study.title,
            kind: self.study.kind.as_str(),
            open: self.study.open,
            definition: serde_json::to_string(&self.study).expect("study serialises"),
            file_sha256: &self.study.file_sha256,
        }
    }

    /// Finds the study's rendered stimuli in `store` by its `plan` and copies its image files
    /// there (named by content hash).
    pub fn prepare(study: Study, plan: &StimulusPlan, store: &Path) -> Result<PreparedStudy, PrepareError> {
        if study.kind == crate::study::StudyKind::Task {
            return Err(PrepareError::TaskStudy { slug: study.slug, file: study.file });
        }
        // an on-demand threshold study's levels render when first needed (`crate::render_queue`):
        // their names are empty here until then; ground truths and image files are needed now
        let on_demand = crate::render_queue::on_demand(&study);
        let missing = if on_demand { Vec::new() } else { plan.missing(store) };
        if let Some(first) = missing.first() {
            return Err(PrepareError::NeedsRendering {
                slug: study.slug.clone(),
                file: study.file.clone(),
                scene: first.scene.clone(),
                missing: missing.len(),
            });
        }
        let mut stimuli = Vec::new();
        for (scene, planned) in study.scenes.iter().zip(&plan.scenes) {
            match (&scene.source, planned) {
                (StimulusSource::Render(_), planned) => {
                    let names: Option<Vec<String>> = planned.as_ref().and_then(|planned| {
                        planned.stimuli.iter().map(|stimulus| level_name(store, &stimulus.key, on_demand)).collect()
                    });
                    let Some(names) = names else {
                        // not in this study's plan, or gone from the store since it was checked
                        return Err(PrepareError::NeedsRendering {
                            slug: study.slug.clone(),
                            file: study.file.clone(),
                            scene: scene.name.clone(),
                            missing: study.conditions.len(),
                        });
                    };
                    stimuli.push(names);
                }
                (StimulusSource::Images(paths), _) => {
                    stimuli.push(paths.iter().map(|path| store_image(path, store)).collect::<Result<Vec<_>, _>>()?);
                }
            }
        }
        let catch_stimuli = study
            .catch
            .iter()
            .map(|catch| Ok((store_image(&catch.better, store)?, store_image(&catch.worse, store)?)))
            .collect::<Result<Vec<_>, PrepareError>>()?;
        let mut ground_truths = Vec::new();
        let mut realisation_stimuli = Vec::new();
        if study.design.reference.is_some() {
            for (scene, planned) in study.scenes.iter().zip(&plan.scenes) {
                let needs_rendering = |missing: usize| PrepareError::NeedsRendering {
                    slug: study.slug.clone(),
                    file: study.file.clone(),
                    scene: scene.name.clone(),
                    missing,
                };
                let mut names = Vec::new();
                let mut further = Vec::new();
                for realisation in 0..study.design.realisations.max(1) as usize {
                    let Some((key, stimuli)) = planned.as_ref().and_then(|planned| planned.realisation(realisation))
                    else {
                        return Err(needs_rendering(1));
                    };
                    let Some(name) = key.and_then(|key| crate::stimuli::lookup(store, key)) else {
                        return Err(needs_rendering(1));
                    };
                    names.push(name);
                    if realisation > 0 {
                        let stimuli: Option<Vec<String>> =
                            stimuli.iter().map(|stimulus| level_name(store, &stimulus.key, on_demand)).collect();
                        further.push(stimuli.ok_or_else(|| needs_rendering(study.conditions.len()))?);
                    }
                }
                ground_truths.push(names);
                realisation_stimuli.push(further);
            }
        }
        let rendered_part = on_demand.then(|| crate::render_queue::rendered_part(plan, store));
        let StimulusMetricsNow { csv: metrics_csv, notes: metrics_notes, metrics: stimulus_metrics } =
            StimulusMetricsNow::of(&study, rendered_part.as_ref().unwrap_or(plan), store);
        let rating_catch_stimuli = rating_catch_stimuli(&study, &ground_truths, store)?;
        let mut study = study;
        crate::threshold::prepare(&mut study, stimulus_metrics.as_ref())
            .map_err(|reason| PrepareError::Threshold { slug: study.slug.clone(), reason: reason.to_string() })?;
        Ok(PreparedStudy {
            study,
            stimuli,
            realisation_stimuli,
            catch_stimuli,
            rating_catch_stimuli,
            ground_truths,
            metrics_csv,
            metrics_notes,
            stimulus_metrics,
        })
    }

    /// The schedule of the participant with this seed (for an active design: the trials
    /// planned at join, its warm-up and catch trials).
    pub fn schedule(&self, seed: u64) -> Vec<ScheduledTrial> {
        if self.study.rating.is_some() {
            return crate::rating::plan(&self.study, seed).iter().map(|rated| self.rated(rated)).collect();
        }
        schedule::plan(&self.study, seed).iter().map(|planned| self.scheduled(planned)).collect()
    }

    /// A planned rating trial with its condition, scene and stimulus names.
    pub fn rated(&self, rated: &RatedTrial) -> ScheduledTrial {
        rated_trial(self, rated)
    }

    /// A planned trial with its condition, scene and stimulus names.
    pub fn scheduled(&self, planned: &PlannedTrial) -> ScheduledTrial {
        let study = &self.study;
        match planned.kind {
            PlannedKind::Pair { left, right } => {
                // a detection design's index past the conditions is the scene's ground truth, of
                // the trial's sensor-noise realisation
                let realisation = planned.realisation;
                let side = |condition: usize, scene: usize| match study.conditions.get(condition) {
                    Some(condition_of) if realisation == 0 => {
                        (condition_of.name.clone(), self.stimuli[scene][condition].clone())
                    }
                    Some(condition_of) => {
                        (condition_of.name.clone(), self.realisation_stimuli[scene][realisation - 1][condition].clone())
                    }
                    None => (GROUND_TRUTH.to_string(), self.ground_truths[scene][realisation].clone()),
                };
                let (left_condition, left_stimulus) = side(left, planned.left_scene);
                let (right_condition, right_stimulus) = side(right, planned.right_scene);
                ScheduledTrial {
                    left_condition,
                    right_condition,
                    left_scene: study.scenes[planned.left_scene].name.clone(),
                    right_scene: study.scenes[planned.right_scene].name.clone(),
                    left_stimulus,
                    right_stimulus,
                    catch_expected: None,
                    catch_rating: None,
                }
            }
            PlannedKind::Catch { index, better_left } => {
                let catch = &study.catch[index];
                let (better, worse) = &self.catch_stimuli[index];
                let better_label = catch_label(&catch.name, true);
                let worse_label = catch_label(&catch.name, false);
                let (left_condition, right_condition, left_stimulus, right_stimulus) = if better_left {
                    (better_label, worse_label, better.clone(), worse.clone())
                } else {
                    (worse_label, better_label, worse.clone(), better.clone())
                };
                ScheduledTrial {
                    left_condition,
                    right_condition,
                    left_scene: catch.name.clone(),
                    right_scene: catch.name.clone(),
                    left_stimulus,
                    right_stimulus,
                    catch_expected: Some(if better_left { Side::Left } else { Side::Right }),
                    catch_rating: None,
                }
            }
        }
    }
}

/// A rating trial with its condition, scene and stimulus names: the stimulus rated on the left
/// side, the reference (DCR) on the right, empty without one (docs/design.md).
fn rated_trial(prepared: &PreparedStudy, rated: &RatedTrial) -> ScheduledTrial {
    let study = &prepared.study;
    let dcr = study.rating.as_ref().is_some_and(|design| design.method == crate::study::rating::Method::Dcr);
    let truth = |scene: usize| (GROUND_TRUTH.to_string(), prepared.ground_truths[scene][0].clone());
    let ((condition, stimulus), scene, reference, catch_rating) = match *rated {
        RatedTrial::Condition { scene, condition } => (
            (study.conditions[condition].name.clone(), prepared.stimuli[scene][condition].clone()),
            study.scenes[scene].name.clone(),
            dcr.then(|| (truth(scene), study.scenes[scene].name.clone())),
            None,
        ),
        RatedTrial::HiddenReference { scene } => (truth(scene), study.scenes[scene].name.clone(), None, None),
        RatedTrial::Catch { index } => {
            let design = study.rating.as_ref().expect("a rating study");
            let catch = &design.catch[index];
            let (image, reference) = &prepared.rating_catch_stimuli[index];
            let scene = match catch.source {
                crate::study::rating::CatchSource::GroundTruth { scene } => study.scenes[scene].name.clone(),
                crate::study::rating::CatchSource::Image { .. } => catch.name.clone(),
            };
            let label = format!("catch:{}", catch.name);
            let reference = reference.clone().map(|file| ((format!("{label}:reference"), file), scene.clone()));
            ((label, image.clone()), scene, reference, Some(catch.expected))
        }
    };
    let ((right_condition, right_stimulus), right_scene) = reference.unwrap_or_default();
    ScheduledTrial {
        left_condition: condition,
        right_condition,
        left_scene: scene,
        right_scene,
        left_stimulus: stimulus,
        right_stimulus,
        catch_expected: None,
        catch_rating,
    }
}

/// A rating study's catch trials' (stimulus, reference) file names: image files copied into the
/// store, or a scene configuration's ground truth (in DCR its own reference as well).
fn rating_catch_stimuli(
    study: &Study,
    ground_truths: &[Vec<String>],
    store: &Path,
) -> Result<Vec<(String, Option<String>)>, PrepareError> {
    use crate::study::rating::{CatchSource, Method};
    let Some(design) = &study.rating else { return Ok(Vec::new()) };
    let mut stimuli = Vec::with_capacity(design.catch.len());
    for catch in &design.catch {
        stimuli.push(match &catch.source {
            CatchSource::Image { image, reference } => {
                (store_image(image, store)?, reference.as_deref().map(|path| store_image(path, store)).transpose()?)
            }
            CatchSource::GroundTruth { scene } => {
                let truth = ground_truths[*scene][0].clone();
                (truth.clone(), (design.method == Method::Dcr).then_some(truth))
            }
        });
    }
    Ok(stimuli)
}

/// The stored name of the stimulus `key`; for an on-demand study an empty name while it is not
/// rendered yet (`None` only where it must be there).
fn level_name(store: &Path, key: &str, on_demand: bool) -> Option<String> {
    crate::stimuli::lookup(store, key).or_else(|| on_demand.then(String::new))
}

fn store_image(path: &Path, store: &Path) -> Result<String, PrepareError> {
    let io_error = |source| PrepareError::Io { path: path.to_path_buf(), store: store.to_path_buf(), source };
    let bytes = std::fs::read(path).map_err(io_error)?;
    let extension = path.extension().and_then(|ext| ext.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
    let extension = if extension == "jpeg" { "jpg".to_string() } else { extension };
    crate::stimuli::store_bytes(&bytes, &extension, store).map_err(io_error)
}

/// The content type of a stimulus file name, if it is one the store can hold: 64 lower-case
/// hex digits, a dot and a known image extension. Anything else (`..`, slashes, other names)
/// is refused, so stimulus paths cannot be traversed.
pub fn stimulus_content_type(name: &str) -> Option<&'static str> {
    let (hash, extension) = name.split_once('.')?;
    if hash.len() != 64 || !hash.bytes().all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b)) {
        return None;
    }
    IMAGE_TYPES.iter().find(|(ext, _)| *ext == extension && *ext != "jpeg").map(|(_, content_type)| *content_type)
}

/// Studies by slug.
pub type Studies = HashMap<String, std::sync::Arc<PreparedStudy>>;

#[cfg(test)]
mod tests {
    use super::*;

    /// A store in which every planned image of `plan` is a distinct one-line file.
    fn fake_store(plan: &StimulusPlan, store: &Path) {
        std::fs::create_dir_all(store.join("rendered")).unwrap();
        let mut keys: Vec<&String> = plan.stimuli().map(|stimulus| &stimulus.key).collect();
        for planned in plan.scenes.iter().flatten() {
            keys.extend(&planned.ground_truth_key);
            keys.extend(planned.realisations.iter().map(|realisation| &realisation.ground_truth_key));
        }
        for key in keys {
            let name = crate::stimuli::store_bytes(key.as_bytes(), "png", store).unwrap();
            std::fs::write(store.join("rendered").join(key), name).unwrap();
        }
    }

    #[test]
    fn each_trial_of_a_detection_design_shows_its_realisations_ground_truth_and_stimulus() {
        let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../studies/real-or-rendered.toml");
        let study = crate::study::load_study(&file).unwrap();
        let plan = StimulusPlan::of(&study).unwrap();
        assert_eq!(plan.stimuli().count(), 6 * 8 * 4);
        // realisation 0 is the web survey's stimuli: the same keys as without realisations
        let mut single = study.clone();
        single.design.realisations = 1;
        let single_plan = StimulusPlan::of(&single).unwrap();
        let first: Vec<&String> = single_plan.stimuli().map(|stimulus| &stimulus.key).collect();
        let shared: Vec<&String> = plan.stimuli().filter(|s| s.realisation == 0).map(|s| &s.key).collect();
        assert_eq!(first, shared);
        let all: std::collections::BTreeSet<&String> = plan.stimuli().map(|stimulus| &stimulus.key).collect();
        assert_eq!(all.len(), 6 * 8 * 4, "every realisation has its own stimuli");

        let store = tempfile::tempdir().unwrap();
        fake_store(&plan, store.path());
        let prepared = PreparedStudy::prepare(study, &plan, store.path()).unwrap();
        // the file name of each image says which key (scene, realisation, condition) it is for
        let mut keys: Vec<String> = plan.stimuli().map(|stimulus| stimulus.key.clone()).collect();
        for planned in plan.scenes.iter().flatten() {
            keys.extend(planned.ground_truth_key.iter().cloned());
            keys.extend(planned.realisations.iter().map(|realisation| realisation.ground_truth_key.clone()));
        }
        let by_name: HashMap<String, String> =
            keys.into_iter().map(|key| (crate::stimuli::lookup(store.path(), &key).unwrap(), key)).collect();
        let key_of = |name: &str| by_name[name].clone();
        for seed in 0..20 {
            let trials = prepared.schedule(seed);
            let mut truths = std::collections::BTreeSet::new();
            for trial in &trials {
                let (truth, stimulus) = if trial.left_condition == GROUND_TRUTH {
                    (&trial.left_stimulus, &trial.right_stimulus)
                } else {
                    (&trial.right_stimulus, &trial.left_stimulus)
                };
                assert!(truths.insert(truth.clone()), "seed {seed}: a ground-truth picture twice");
                let planned = plan.scenes.iter().flatten().find(|planned| {
                    (0..4).any(|r| planned.realisation(r).unwrap().0.is_some_and(|key| *key == key_of(truth)))
                });
                let planned = planned.unwrap();
                let realisation = (0..4)
                    .find(|&r| planned.realisation(r).unwrap().0.is_some_and(|key| *key == key_of(truth)))
                    .unwrap();
                let stimuli = planned.realisation(realisation).unwrap().1;
                assert!(
                    stimuli.iter().any(|s| s.key == key_of(stimulus) && s.condition != GROUND_TRUTH),
                    "seed {seed}: the stimulus is not of the ground truth's realisation"
                );
            }
            assert_eq!(truths.len(), 24);
        }
    }
}
