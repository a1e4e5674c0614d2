//! The render queue of threshold studies with `[threshold] render = "on-demand"`: a level that
//! is not in the stimulus store yet is rendered when a participant first needs it, so a study
//! may offer a fine grid of levels without rendering all of them at start-up.
//!
//! At start-up `serve` renders only what the first trials can need ([`startup_plan`]): each
//! scene configuration's ground truth and the levels QUEST+ can choose in the first
//! `render_ahead` trials, whatever the answers ([`first_levels`]). When a participant's next
//! level is not in the store, [`RenderQueue::stimulus`] queues its render and waits for it up to
//! [`WAIT`]; the trial is stored only once its stimulus exists, so the level shown is always the
//! level QUEST+ chose (never a neighbour that happens to be rendered), and a participant who
//! reloads gets the same level again (it is replayed from their answers).
//!
//! The queue is bounded ([`CAPACITY`] renders waiting; a request beyond it is refused with a
//! 503 and `Retry-After`, never queued), deduplicated by the stimulus's content address (two
//! participants who need one level wait for one render), and renders one stimulus at a time on
//! one GPU renderer kept by its worker thread for the server's life, with each scene
//! configuration's reference render kept in memory after its first use (about 27 MB at
//! 800 × 600 each), so a level costs one GPU frame and its stimulus record. A failed render is
//! remembered with its sentence: the participants who need that level get it (logged), the admin
//! page shows it, and it is not tried again until a restart. Its state is one line on the admin
//! page ([`RenderQueue::summary`]) and a log line per render.

use std::collections::{BTreeSet, HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use crate::PreparedStudy;
use crate::stimuli::StimulusMetricsNow;
use crate::stimuli::{PlannedScene, StimulusPlan};
use crate::study::Study;
use crate::study::threshold::{RenderWhen, ThresholdDesign};
use crate::threshold::{Answer, next_level};

/// Renders waiting at most; a request beyond them is refused (503 with `Retry-After`).
pub const CAPACITY: usize = 16;

/// How long a participant's `…/next` waits for its level's render before answering 503 with
/// `Retry-After` (the page asks again then; the render goes on).
pub const WAIT: Duration = Duration::from_secs(20);

/// Renders one stimulus: the study and a plan holding only that stimulus (its scene
/// configuration's ground truth beside it), into the store.
pub type Render = Box<dyn FnMut(&Study, &StimulusPlan, &Path) -> Result<(), String> + Send>;

/// Makes the worker's [`Render`] (called once, on the worker thread's start).
pub type MakeRender = Arc<dyn Fn() -> Render + Send + Sync>;

/// One stimulus to render: a level of a scene configuration (and sensor-noise realisation).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Job {
    /// The stimulus's content address (its index entry in the store).
    pub key: String,
    pub slug: String,
    pub scene: usize,
    pub realisation: usize,
    pub condition: usize,
    /// `scene / condition`, for the admin page and the log.
    pub label: String,
    /// Queued ahead of need ([`RenderQueue::prefetch`]): a participant's own request goes
    /// before it.
    pub prefetch: bool,
}

/// Why a level's stimulus is not there for a participant now.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Unready {
    /// Queued or rendering; ask again after `retry_after_seconds`.
    #[error("the level {label} is still being rendered ({position} renders before it)")]
    Rendering { label: String, position: usize, retry_after_seconds: u64 },
    /// The queue is full: nothing was queued.
    #[error("the render queue is full ({capacity} renders waiting): the level {label} was not queued")]
    Full { label: String, capacity: usize, retry_after_seconds: u64 },
    /// Its render failed (the sentence says why).
    #[error("the level {label} could not be rendered: {reason}")]
    Failed { label: String, reason: String },
    /// The study, scene configuration, realisation or level is not one the queue knows.
    #[error(
        "study \"{slug}\" has no on-demand stimulus for scene configuration {scene}, realisation {realisation}, level {condition}"
    )]
    Unknown { slug: String, scene: usize, realisation: usize, condition: usize },
}

impl Unready {
    /// Seconds after which to ask again (`None`: asking again does not help).
    pub fn retry_after_seconds(&self) -> Option<u64> {
        match self {
            Unready::Rendering { retry_after_seconds, .. } | Unready::Full { retry_after_seconds, .. } => {
                Some(*retry_after_seconds)
            }
            _ => None,
        }
    }
}

#[derive(Default)]
struct State {
    waiting: VecDeque<Job>,
    current: Option<(Job, Instant)>,
    /// Content address → the sentence of its failed render.
    failed: HashMap<String, (String, String)>,
    rendered: usize,
    refused: usize,
    render_seconds: f64,
    studies: HashMap<String, Arc<(Arc<PreparedStudy>, StimulusPlan)>>,
    /// Slug → the renders done when its metrics were last read, and those metrics.
    metrics: HashMap<String, (usize, Arc<StimulusMetricsNow>)>,
    prefetched: usize,
    worker: bool,
}

struct Shared {
    state: Mutex<State>,
    /// The worker waits here for a job.
    wake: Condvar,
    /// Waiting requests are woken here after each render.
    done: tokio::sync::Notify,
    store: PathBuf,
    capacity: usize,
    make_render: MakeRender,
}

/// The server's render queue (one per `AppState`); clones share it.
#[derive(Clone)]
pub struct RenderQueue {
    shared: Arc<Shared>,
}

impl std::fmt::Debug for RenderQueue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.summary())
    }
}

impl RenderQueue {
    /// A queue rendering into `store` on the GPU ([`gpu_render`]), at most [`CAPACITY`] waiting.
    pub fn new(store: PathBuf) -> RenderQueue {
        RenderQueue::with_render(store, CAPACITY, Arc::new(gpu_render))
    }

    /// A queue with its own bound and renderer (tests render without a GPU).
    pub fn with_render(store: PathBuf, capacity: usize, make_render: MakeRender) -> RenderQueue {
        RenderQueue {
            shared: Arc::new(Shared {
                state: Mutex::new(State::default()),
                wake: Condvar::new(),
                done: tokio::sync::Notify::new(),
                store,
                capacity,
                make_render,
            }),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.shared.state.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Lets the queue render `prepared`'s levels on demand (its full `plan`); nothing for a
    /// study that renders ahead.
    pub fn register(&self, prepared: Arc<PreparedStudy>, plan: StimulusPlan) {
        if !on_demand(&prepared.study) {
            return;
        }
        let slug = prepared.study.slug.clone();
        self.lock().studies.insert(slug, Arc::new((prepared, plan)));
    }

    /// The render job of level `condition` of scene configuration `scene` (realisation
    /// `realisation`) of study `slug`.
    fn job(&self, slug: &str, scene: usize, realisation: usize, condition: usize) -> Result<Job, Unready> {
        let unknown = || Unready::Unknown { slug: slug.to_string(), scene, realisation, condition };
        let registered = self.lock().studies.get(slug).cloned().ok_or_else(unknown)?;
        let plan = &registered.1;
        let planned = plan.scenes.get(scene).and_then(Option::as_ref).ok_or_else(unknown)?;
        let stimulus = planned.realisation(realisation).and_then(|(_, s)| s.get(condition)).ok_or_else(unknown)?;
        Ok(Job {
            key: stimulus.key.clone(),
            slug: slug.to_string(),
            scene,
            realisation,
            condition,
            label: match realisation {
                0 => format!("{} / {}", stimulus.scene, stimulus.condition),
                r => format!("{} / {} (realisation {r})", stimulus.scene, stimulus.condition),
            },
            prefetch: false,
        })
    }

    /// The stored file name of level `condition` of scene configuration `scene` (realisation
    /// `realisation`) of study `slug`: at once if it is in the store, else after its render
    /// (queued unless it is queued already), waiting at most `wait`.
    pub async fn stimulus(
        &self,
        slug: &str,
        scene: usize,
        realisation: usize,
        condition: usize,
        wait: Duration,
    ) -> Result<String, Unready> {
        let job = self.job(slug, scene, realisation, condition)?;
        if let Some(name) = crate::stimuli::lookup(&self.shared.store, &job.key) {
            return Ok(name);
        }
        self.enqueue(&job)?;
        let deadline = tokio::time::Instant::now() + wait;
        loop {
            let notified = self.shared.done.notified();
            tokio::pin!(notified);
            notified.as_mut().enable();
            if let Some(name) = crate::stimuli::lookup(&self.shared.store, &job.key) {
                return Ok(name);
            }
            if let Some(unready) = self.unready(&job) {
                return Err(unready);
            }
            if tokio::time::timeout_at(deadline, notified).await.is_err() {
                let position = self.position(&job.key).unwrap_or(0);
                return Err(Unready::Rendering {
                    label: job.label,
                    position,
                    retry_after_seconds: self.retry_after(position),
                });
            }
        }
    }

    /// Queues level `condition`'s render ahead of need (a level a participant may be shown
    /// next) when it is missing and the queue is less than half full, behind every request a
    /// participant waits for; never refused, never counted as a refusal. Whether it was queued.
    pub fn prefetch(&self, slug: &str, scene: usize, realisation: usize, condition: usize) -> bool {
        let Ok(job) = self.job(slug, scene, realisation, condition) else { return false };
        if crate::stimuli::lookup(&self.shared.store, &job.key).is_some() {
            return false;
        }
        {
            let state = self.lock();
            if 2 * state.waiting.len() >= self.shared.capacity || self.known(&state, &job.key) {
                return false;
            }
        }
        let queued = self.enqueue(&Job { prefetch: true, ..job }).is_ok();
        if queued {
            self.lock().prefetched += 1;
        }
        queued
    }

    /// Queued, rendering or failed already.
    fn known(&self, state: &State, key: &str) -> bool {
        state.failed.contains_key(key)
            || state.current.as_ref().is_some_and(|(current, _)| current.key == key)
            || state.waiting.iter().any(|waiting| waiting.key == key)
    }

    /// The stimulus metrics of on-demand study `slug` now, with the levels rendered since it was
    /// prepared (read again from the store after each render); `None` for a study the queue does
    /// not render.
    pub fn metrics(&self, slug: &str) -> Option<Arc<StimulusMetricsNow>> {
        let (registered, rendered, cached) = {
            let state = self.lock();
            let registered = state.studies.get(slug).cloned()?;
            (registered, state.rendered, state.metrics.get(slug).cloned())
        };
        if let Some((at, metrics)) = cached
            && at == rendered
        {
            return Some(metrics);
        }
        let (prepared, plan) = &*registered;
        let part = rendered_part(plan, &self.shared.store);
        let metrics = Arc::new(StimulusMetricsNow::of(&prepared.study, &part, &self.shared.store));
        self.lock().metrics.insert(slug.to_string(), (rendered, metrics.clone()));
        Some(metrics)
    }

    /// Queues `job` unless it is queued, rendering or failed already; refuses it when full. A
    /// participant's request goes before the prefetched renders (and lifts a prefetched render
    /// of the same level to its place).
    fn enqueue(&self, job: &Job) -> Result<(), Unready> {
        let mut state = self.lock();
        if !job.prefetch
            && let Some(at) = state.waiting.iter().position(|waiting| waiting.key == job.key && waiting.prefetch)
        {
            let mut lifted = state.waiting.remove(at).expect("the position is in the queue");
            lifted.prefetch = false;
            let first_prefetch =
                state.waiting.iter().position(|waiting| waiting.prefetch).unwrap_or(state.waiting.len());
            state.waiting.insert(first_prefetch, lifted);
            return Ok(());
        }
        if self.known(&state, &job.key) {
            return Ok(());
        }
        if state.waiting.len() >= self.shared.capacity {
            state.refused += 1;
            let retry_after_seconds = seconds_after(mean_seconds(&state), state.waiting.len());
            tracing::warn!(level = %job.label, waiting = state.waiting.len(), "render queue full: a level was refused");
            return Err(Unready::Full {
                label: job.label.clone(),
                capacity: self.shared.capacity,
                retry_after_seconds,
            });
        }
        let at = match job.prefetch {
            true => state.waiting.len(),
            false => state.waiting.iter().position(|waiting| waiting.prefetch).unwrap_or(state.waiting.len()),
        };
        state.waiting.insert(at, job.clone());
        tracing::info!(level = %job.label, study = %job.slug, waiting = state.waiting.len(), prefetch = job.prefetch, "render queued");
        if !state.worker {
            state.worker = true;
            let queue = self.clone();
            std::thread::Builder::new()
                .name("mrstudy-render-queue".into())
                .spawn(move || queue.work())
                .expect("the render queue's thread starts");
        }
        drop(state);
        self.shared.wake.notify_one();
        Ok(())
    }

    /// The failure of `job`, if its render failed.
    fn unready(&self, job: &Job) -> Option<Unready> {
        let state = self.lock();
        let (_, reason) = state.failed.get(&job.key)?;
        Some(Unready::Failed { label: job.label.clone(), reason: reason.clone() })
    }

    /// Renders before `key` (0: it is rendering).
    fn position(&self, key: &str) -> Option<usize> {
        let state = self.lock();
        if state.current.as_ref().is_some_and(|(current, _)| current.key == key) {
            return Some(0);
        }
        state.waiting.iter().position(|job| job.key == key).map(|index| index + usize::from(state.current.is_some()))
    }

    fn retry_after(&self, position: usize) -> u64 {
        seconds_after(mean_seconds(&self.lock()), position)
    }

    /// The worker: one render after another, for the server's life.
    fn work(self) {
        let mut render = (self.shared.make_render)();
        loop {
            let (job, registered) = {
                let mut state = self.lock();
                let job = loop {
                    match state.waiting.pop_front() {
                        Some(job) => break job,
                        None => {
                            state = self.shared.wake.wait(state).unwrap_or_else(|poisoned| poisoned.into_inner());
                        }
                    }
                };
                state.current = Some((job.clone(), Instant::now()));
                let registered = state.studies.get(&job.slug).cloned();
                (job, registered)
            };
            let started = Instant::now();
            let outcome = match &registered {
                Some(registered) => {
                    let (prepared, plan) = &**registered;
                    match single(plan, job.scene, job.realisation, job.condition) {
                        Some(single) => render(&prepared.study, &single, &self.shared.store),
                        None => Err("the level is not in the study's plan".to_string()),
                    }
                }
                None => Err(format!("study \"{}\" is not one the render queue knows", job.slug)),
            };
            let outcome = outcome.and_then(|()| match crate::stimuli::lookup(&self.shared.store, &job.key) {
                Some(_) => Ok(()),
                None => Err("the render ended without storing the stimulus".to_string()),
            });
            let seconds = started.elapsed().as_secs_f64();
            {
                let mut state = self.lock();
                state.current = None;
                match &outcome {
                    Ok(()) => {
                        state.rendered += 1;
                        state.render_seconds += seconds;
                        tracing::info!(level = %job.label, study = %job.slug, seconds, waiting = state.waiting.len(), "level rendered");
                    }
                    Err(reason) => {
                        tracing::error!(level = %job.label, study = %job.slug, %reason, "a level could not be rendered");
                        state.failed.insert(job.key.clone(), (job.label.clone(), reason.clone()));
                    }
                }
            }
            self.shared.done.notify_waiters();
        }
    }

    /// Renders done so far (for tests and the admin page).
    pub fn rendered(&self) -> usize {
        self.lock().rendered
    }

    /// Requests refused because the queue was full.
    pub fn refused(&self) -> usize {
        self.lock().refused
    }

    /// The queue in one line for the admin page; `None` when no study renders on demand.
    pub fn summary_line(&self) -> Option<String> {
        let any = !self.lock().studies.is_empty();
        any.then(|| self.summary())
    }

    /// The queue in one line: what renders, how many wait, done, refused, failed.
    pub fn summary(&self) -> String {
        let state = self.lock();
        let current = match &state.current {
            Some((job, started)) => {
                format!("rendering {} ({}, {:.0} s so far)", job.label, job.slug, started.elapsed().as_secs_f64())
            }
            None => "idle".to_string(),
        };
        let mean = mean_seconds(&state).map(|mean| format!(", {mean:.1} s each")).unwrap_or_default();
        let failed = match state.failed.values().next() {
            Some((label, reason)) => format!("; {} failed (first: {label}: {reason})", state.failed.len()),
            None => String::new(),
        };
        format!(
            "render queue (on-demand levels): {current}; {} waiting of at most {}; {} rendered{mean}; {} queued ahead of need; {} refused as full{failed}",
            state.waiting.len(),
            self.shared.capacity,
            state.rendered,
            state.prefetched,
            state.refused
        )
    }
}

fn mean_seconds(state: &State) -> Option<f64> {
    (state.rendered > 0).then(|| state.render_seconds / state.rendered as f64)
}

/// Seconds until `position` renders are done at `mean` seconds each (5 s each before any),
/// at least 1 and at most 300.
fn seconds_after(mean: Option<f64>, position: usize) -> u64 {
    let each = mean.unwrap_or(5.0);
    (each * (position + 1) as f64).ceil().clamp(1.0, 300.0) as u64
}

/// Whether `study` renders its levels on demand.
pub fn on_demand(study: &Study) -> bool {
    study.threshold.as_ref().is_some_and(|design| design.render == RenderWhen::OnDemand)
}

/// The levels (indices) QUEST+ can choose in the first `trials` trials of a participant,
/// whatever their answers (every sequence of answers replayed).
pub fn first_levels(
    design: &ThresholdDesign,
    intensities: &[f64],
    trials: u32,
) -> Result<BTreeSet<usize>, crate::threshold::NextError> {
    let mut levels = BTreeSet::new();
    let mut sequences: Vec<Vec<Answer>> = vec![Vec::new()];
    for _ in 0..trials.min(design.trials) {
        let mut longer = Vec::with_capacity(sequences.len() * 2);
        for answers in sequences {
            let level = next_level(design, intensities, &answers)?;
            levels.insert(level);
            for correct in [true, false] {
                let mut answers = answers.clone();
                answers.push(Answer { level, correct });
                longer.push(answers);
            }
        }
        sequences = longer;
    }
    Ok(levels)
}

/// What `serve` renders of `study` before it opens: all of `plan`, or for an on-demand study
/// every ground truth and the levels of [`first_levels`] (all levels when they cannot be
/// found, e.g. without intensities).
pub fn startup_plan(study: &Study, plan: &StimulusPlan) -> StimulusPlan {
    let Some(design) = study.threshold.as_ref().filter(|_| on_demand(study)) else { return plan.clone() };
    let levels =
        design.intensities.as_ref().and_then(|intensities| first_levels(design, intensities, design.render_ahead).ok());
    let Some(levels) = levels else { return plan.clone() };
    filtered(plan, |_, _, stimulus| levels.contains(&stimulus.condition_index))
}

/// `plan` without the stimuli not yet in `store` (an on-demand study's metrics and records).
pub fn rendered_part(plan: &StimulusPlan, store: &Path) -> StimulusPlan {
    filtered(plan, |_, _, stimulus| crate::stimuli::lookup(store, &stimulus.key).is_some())
}

/// The plan of one stimulus: level `condition` of scene configuration `scene`, realisation
/// `realisation` (its ground truth beside it); `None` when the plan has no such stimulus.
fn single(plan: &StimulusPlan, scene: usize, realisation: usize, condition: usize) -> Option<StimulusPlan> {
    plan.scenes.get(scene)?.as_ref()?.realisation(realisation)?.1.get(condition)?;
    let mut single = filtered(plan, |index, r, stimulus| {
        index == scene && r == realisation && stimulus.condition_index == condition
    });
    for (index, planned) in single.scenes.iter_mut().enumerate() {
        if index != scene {
            *planned = None;
        } else if let Some(planned) = planned {
            // the other realisations' ground truths are not this render's to make
            planned.realisations = planned
                .realisations
                .drain(..)
                .enumerate()
                .filter(|(k, _)| k + 1 == realisation)
                .map(|(_, kept)| kept)
                .collect();
        }
    }
    Some(single)
}

/// `plan` with only the stimuli `keep(scene, realisation, stimulus)` accepts.
fn filtered(
    plan: &StimulusPlan,
    keep: impl Fn(usize, usize, &crate::stimuli::PlannedStimulus) -> bool,
) -> StimulusPlan {
    let mut plan = plan.clone();
    for (index, planned) in plan.scenes.iter_mut().enumerate() {
        let Some(PlannedScene { stimuli, realisations, .. }) = planned else { continue };
        stimuli.retain(|stimulus| keep(index, 0, stimulus));
        for (k, realisation) in realisations.iter_mut().enumerate() {
            realisation.stimuli.retain(|stimulus| keep(index, k + 1, stimulus));
        }
    }
    plan
}

/// The worker's renderer: one GPU renderer (opened on the first render, kept), and each scene
/// configuration's reference render kept once made (so a level costs one GPU frame).
pub fn gpu_render() -> Render {
    let mut renderer: Option<mrstudy_renderer::gpu::DirRenderer> = None;
    let mut references: HashMap<String, Arc<mrstudy_renderer::ReferenceOutput>> = HashMap::new();
    Box::new(move |study: &Study, plan: &StimulusPlan, store: &Path| {
        let renderer = match &mut renderer {
            Some(renderer) => renderer,
            empty => empty.insert(
                mrstudy_renderer::gpu::DirRenderer::new()
                    .map_err(|error| format!("no GPU adapter could be opened for the render queue: {error}"))?,
            ),
        };
        let keys: Vec<String> =
            plan.scenes.iter().flatten().filter_map(|scene| scene.ground_truth_key.clone()).collect();
        for key in &keys {
            if let Some(reference) = references.get(key) {
                crate::stimuli::keep_reference(key, reference);
            }
        }
        crate::stimuli::render_missing_on(renderer, study, plan, store, &|_| {}).map_err(|error| error.to_string())?;
        for key in keys {
            if let Some(reference) = crate::stimuli::recent_reference(&key) {
                references.insert(key, reference);
            }
        }
        Ok(())
    })
}

#[cfg(test)]
#[path = "render_queue_tests.rs"]
mod tests;
