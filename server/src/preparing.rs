//! The studies `serve` is still preparing. `serve` listens at once; the stimuli that are not in
//! the store yet render in the background afterwards ([`crate::serve::prepare_pending`]), one
//! study after another. Until a study's stimuli are complete its participant routes answer
//! [`crate::error::OPENS_SOON`] (503 with `Retry-After`; the participant page shows it) and the
//! admin page shows its progress: counts, a bar and an estimate of the time left. The lab's task
//! studies are listed here too while the lab starts (its renderer, scenes and frame times).
//!
//! Invariant: this module only tracks what is still to come, and uses no module but
//! [`crate::stimuli`] (no import cycle through the error type); a study is served only once
//! [`crate::PreparedStudy::prepare`] has found every one of its stimuli in the store
//! ([`crate::AppState::install`]), and then it is no longer here.

use std::sync::Mutex;
use std::time::{Duration, Instant};

use crate::stimuli::Progress;

/// Where a study being prepared stands.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Stage {
    /// Its stimuli render after those of the studies before it.
    Waiting,
    /// Its stimuli are being rendered.
    Rendering,
    /// They could not be rendered (the sentence says why): the study is not served.
    Failed(String),
}

/// The progress of one study being prepared.
#[derive(Debug, Clone)]
pub struct StudyProgress {
    pub slug: String,
    pub title: String,
    pub stage: Stage,
    /// Reference renders (the photograph and, where synthesised, the ground truth of one scene
    /// configuration) done, of `references`.
    pub references_done: usize,
    pub references: usize,
    /// Stimuli done (rendered, or found in the store), of `stimuli`.
    pub stimuli_done: usize,
    pub stimuli: usize,
    /// Samples per pixel of the reference render under way: done, total.
    pub samples: (u32, u32),
    timing: Timing,
}

/// How long the parts took so far, for the estimate.
#[derive(Debug, Clone, Default)]
struct Timing {
    /// When the part under way (a reference render or a stimulus) began.
    part_started: Option<Instant>,
    in_reference: bool,
    reference_seconds: Vec<f64>,
    stimulus_seconds: f64,
    stimuli_timed: usize,
}

impl StudyProgress {
    fn new(slug: String, title: String, stimuli: usize) -> StudyProgress {
        StudyProgress {
            slug,
            title,
            stage: Stage::Waiting,
            references_done: 0,
            references: 0,
            stimuli_done: 0,
            stimuli,
            samples: (0, 0),
            timing: Timing::default(),
        }
    }

    /// Done, from 0 to 1: stimuli count one each, a reference render as many as the stimuli of
    /// its scene configuration (the two take comparable time on lavapipe).
    pub fn fraction(&self) -> f64 {
        if self.references == 0 || self.stimuli == 0 {
            return 0.0;
        }
        let per_reference = self.stimuli as f64 / self.references as f64;
        let running = if self.timing.in_reference && self.samples.1 > 0 {
            f64::from(self.samples.0) / f64::from(self.samples.1)
        } else {
            0.0
        };
        let done = (self.references_done as f64 + running) * per_reference + self.stimuli_done as f64;
        (done / (2.0 * self.stimuli as f64)).clamp(0.0, 1.0)
    }

    /// The time left, from what the parts done so far took; `None` before one reference render
    /// and one stimulus have been timed (or while the study is not rendering).
    pub fn estimate(&self, now: Instant) -> Option<Duration> {
        if self.stage != Stage::Rendering {
            return None;
        }
        let timing = &self.timing;
        let in_part = timing.part_started.map_or(0.0, |started| now.duration_since(started).as_secs_f64());
        let (done, total) = self.samples;
        // the reference under way, extrapolated from its samples so far
        let running_reference = (timing.in_reference && done > 0).then(|| in_part * f64::from(total) / f64::from(done));
        let per_reference = match timing.reference_seconds.as_slice() {
            [] => running_reference?,
            seconds => seconds.iter().sum::<f64>() / seconds.len() as f64,
        };
        if timing.stimuli_timed == 0 {
            return None;
        }
        let per_stimulus = timing.stimulus_seconds / timing.stimuli_timed as f64;
        let current = match running_reference {
            Some(whole) => (whole - in_part).max(0.0),
            None => 0.0,
        };
        let references_left = self.references.saturating_sub(self.references_done + usize::from(timing.in_reference));
        let stimuli_left = self.stimuli.saturating_sub(self.stimuli_done);
        let seconds = current + references_left as f64 * per_reference + stimuli_left as f64 * per_stimulus;
        Some(Duration::from_secs_f64(seconds.max(0.0)))
    }

    /// One line of counts and the estimate, as the admin page shows it.
    pub fn summary(&self, now: Instant) -> String {
        match &self.stage {
            Stage::Waiting => format!("waiting to render its {} stimuli", self.stimuli),
            Stage::Failed(reason) => format!("not served: {reason}"),
            Stage::Rendering => {
                let mut line = format!(
                    "{} of {} stimuli, {} of {} reference renders",
                    self.stimuli_done, self.stimuli, self.references_done, self.references
                );
                if self.timing.in_reference && self.samples.1 > 0 {
                    line += &format!(" (one under way: {} of {} samples per pixel)", self.samples.0, self.samples.1);
                }
                match self.estimate(now) {
                    Some(left) => line += &format!("; about {} left", minutes(left)),
                    None => line += "; estimating the time left",
                }
                line
            }
        }
    }

    fn record(&mut self, step: &Progress, now: Instant) {
        match step {
            Progress::Start { photos, stimuli } => {
                self.stage = Stage::Rendering;
                self.references = *photos;
                self.stimuli = *stimuli;
                self.timing.part_started = Some(now);
            }
            Progress::Photo { done, total, .. } => {
                self.samples = (*done, *total);
                self.timing.in_reference = true;
                if done >= total {
                    self.end_reference(now);
                }
            }
            Progress::Stimulus { ms, .. } => {
                if self.timing.in_reference {
                    self.end_reference(now);
                }
                self.stimuli_done += 1;
                // a stimulus found in the store took no time (ms 0): not timed
                if *ms > 0.0
                    && let Some(started) = self.timing.part_started
                {
                    self.timing.stimulus_seconds += now.duration_since(started).as_secs_f64();
                    self.timing.stimuli_timed += 1;
                }
                self.timing.part_started = Some(now);
            }
        }
    }

    fn end_reference(&mut self, now: Instant) {
        if let Some(started) = self.timing.part_started {
            self.timing.reference_seconds.push(now.duration_since(started).as_secs_f64());
        }
        self.references_done += 1;
        self.timing.in_reference = false;
        self.timing.part_started = Some(now);
    }
}

/// A duration as people read it: "40 s", "3 min".
pub fn minutes(duration: Duration) -> String {
    let seconds = duration.as_secs();
    if seconds < 60 { format!("{seconds} s") } else { format!("{} min", seconds.div_ceil(60)) }
}

/// The studies being prepared, shared by the handlers and the task that renders.
#[derive(Debug, Default)]
pub struct Preparation {
    inner: Mutex<Inner>,
}

#[derive(Debug, Default)]
struct Inner {
    studies: Vec<StudyProgress>,
    /// Task studies whose lab is starting: slug, title.
    lab: Vec<(String, String)>,
}

impl Preparation {
    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Adds a study whose `stimuli` are still to render.
    pub fn add(&self, slug: &str, title: &str, stimuli: usize) {
        self.lock().studies.push(StudyProgress::new(slug.to_string(), title.to_string(), stimuli));
    }

    /// Records a step of rendering `slug`'s stimuli.
    pub fn record(&self, slug: &str, step: &Progress) {
        let now = Instant::now();
        if let Some(study) = self.lock().studies.iter_mut().find(|study| study.slug == slug) {
            study.record(step, now);
        }
    }

    /// Marks `slug` as failed: it will not be served.
    pub fn fail(&self, slug: &str, reason: String) {
        if let Some(study) = self.lock().studies.iter_mut().find(|study| study.slug == slug) {
            study.stage = Stage::Failed(reason);
        }
    }

    /// Forgets `slug`: it is served now.
    pub fn remove(&self, slug: &str) {
        self.lock().studies.retain(|study| study.slug != slug);
    }

    /// The study `slug` if it is still being prepared (not failed).
    pub fn pending(&self, slug: &str) -> Option<StudyProgress> {
        self.lock().studies.iter().find(|study| study.slug == slug && !matches!(study.stage, Stage::Failed(_))).cloned()
    }

    /// Every study being prepared, or that failed to be, in the order they render.
    pub fn studies(&self) -> Vec<StudyProgress> {
        self.lock().studies.clone()
    }

    /// Notes that the lab is starting for these task studies, (slug, title) each; none once it
    /// has started.
    pub fn set_lab_starting(&self, studies: Vec<(String, String)>) {
        self.lock().lab = studies;
    }

    /// The title of `slug` if it is a task study whose lab is still starting.
    pub fn lab_starting(&self, slug: &str) -> Option<String> {
        self.lock().lab.iter().find(|(starting, _)| starting == slug).map(|(_, title)| title.clone())
    }

    /// Every task study whose lab is still starting: (slug, title).
    pub fn lab(&self) -> Vec<(String, String)> {
        self.lock().lab.clone()
    }

    /// Seconds a participant of `slug` should wait before trying again: the estimate, between
    /// 10 s and 2 min (1 min when there is none yet).
    pub fn retry_after(&self, slug: &str) -> u64 {
        self.pending(slug)
            .and_then(|study| study.estimate(Instant::now()))
            .map_or(60, |left| left.as_secs().clamp(10, 120))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn photo(done: u32) -> Progress {
        Progress::Photo { scene: "a".into(), done, total: 8 }
    }

    fn stimulus(ms: f64) -> Progress {
        Progress::Stimulus { scene: "a".into(), condition: "c".into(), ms, warning: None }
    }

    /// Two scene configurations of two stimuli: a reference of 8 s and stimuli of 2 s each
    /// leave 8 + 2 × 2 s after the first scene configuration.
    #[test]
    fn the_estimate_extrapolates_the_parts_timed_so_far() {
        let start = Instant::now();
        let at = |seconds: u64| start + Duration::from_secs(seconds);
        let mut study = StudyProgress::new("s".into(), "S".into(), 4);
        assert_eq!(study.estimate(at(0)), None, "waiting");
        study.record(&Progress::Start { photos: 2, stimuli: 4 }, at(0));
        study.record(&photo(4), at(4));
        assert_eq!(study.estimate(at(4)), None, "no stimulus timed yet");
        assert!((study.fraction() - 0.125).abs() < 1e-9, "{}", study.fraction());
        study.record(&photo(8), at(8));
        study.record(&stimulus(5.0), at(10));
        study.record(&stimulus(5.0), at(12));
        assert_eq!(study.estimate(at(12)), Some(Duration::from_secs(12)));
        assert!((study.fraction() - 0.5).abs() < 1e-9);
        // half-way through the second reference: 4 s of it left
        study.record(&photo(4), at(16));
        assert_eq!(study.estimate(at(16)), Some(Duration::from_secs(8)));
        assert!(study.summary(at(16)).starts_with("2 of 4 stimuli, 1 of 2 reference renders (one under way: 4 of 8"));
        assert!(study.summary(at(16)).ends_with("about 8 s left"), "{}", study.summary(at(16)));
    }

    /// Stimuli found in the store are counted as done but not timed.
    #[test]
    fn stored_stimuli_count_but_take_no_time() {
        let start = Instant::now();
        let mut study = StudyProgress::new("s".into(), "S".into(), 2);
        study.record(&Progress::Start { photos: 1, stimuli: 2 }, start);
        study.record(&photo(8), start + Duration::from_secs(3));
        study.record(&stimulus(0.0), start + Duration::from_secs(3));
        assert_eq!(study.stimuli_done, 1);
        assert_eq!(study.estimate(start + Duration::from_secs(3)), None);
        study.record(&stimulus(1.0), start + Duration::from_secs(5));
        assert_eq!(study.estimate(start + Duration::from_secs(5)), Some(Duration::ZERO));
    }

    #[test]
    fn a_failed_study_is_not_pending_and_a_removed_one_is_gone() {
        let preparation = Preparation::default();
        preparation.add("a", "A", 3);
        preparation.add("b", "B", 3);
        assert!(preparation.pending("a").is_some());
        assert_eq!(preparation.retry_after("a"), 60);
        preparation.fail("a", "no adapter".into());
        assert!(preparation.pending("a").is_none());
        preparation.remove("b");
        assert!(preparation.pending("b").is_none());
        assert_eq!(preparation.studies().len(), 1);
    }
}
