//! Frame time per condition, so that condition is not confounded with lag: measured for every
//! condition when the lab starts (a few frames each) and kept up to date from every live frame
//! (a window of the most recent [`WINDOW`] frames per condition, shared by the study's sessions).
//!
//! [`FrameTimes::spread`] says how much slower the slowest condition is than the fastest; more
//! than [`PARITY_TOLERANCE`] is reported on `serve`'s output and the admin page. With
//! `pace = "equal"` every frame is held until [`FrameTimes::pace_ms`] has passed since it was
//! requested: [`PACE_HEADROOM`] times the [`PACE_QUANTILE`] of the slowest condition's recent
//! frame times, so that almost every frame of every condition reaches the participant after the
//! same time. A session takes its pace when the participant starts or resumes (see
//! [`super::session`]) and raises it only when frames come late (the slowest condition's
//! recent p90 above the pace), so all
//! conditions of one participant are paced alike even when the machine's load changes.

use std::collections::VecDeque;

use crate::study::task::Condition;

/// Conditions whose frame times differ by more than this fraction are reported.
pub const PARITY_TOLERANCE: f64 = 0.20;
/// Recent frames per condition kept for the running frame time.
pub const WINDOW: usize = 64;
/// The quantile of the slowest condition's recent frame times that frames are paced to.
pub const PACE_QUANTILE: f64 = 0.9;
/// Margin over that quantile: frames of the slowest condition vary from frame to frame (more
/// on a shared machine), live frames run slower than the start-up measurement (measured on
/// lavapipe: gi 24 ms at start-up, 35 ms live), and one that is slower than the pace shows as
/// extra lag. 1.25 left gi's live frames above the pace in 3 of about 15 test runs.
pub const PACE_HEADROOM: f64 = 1.5;

/// One condition's frame times (render + encode, ms).
#[derive(Debug, Clone)]
struct ConditionTimes {
    condition: Condition,
    startup: Vec<f64>,
    recent: VecDeque<f64>,
    frames: u64,
    sum_ms: f64,
}

/// What the admin page and `serve` show for one condition.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ConditionFrameTime {
    pub condition: String,
    /// Median of the frames rendered at start-up.
    pub startup_ms: f64,
    /// Median of the most recent frames (start-up frames until live frames replace them).
    pub current_ms: f64,
    /// Live frames rendered since start-up and their mean (absent before the first).
    pub live_frames: u64,
    pub live_mean_ms: Option<f64>,
}

/// Frame times of a study's conditions (see the module doc).
#[derive(Debug, Clone)]
pub struct FrameTimes {
    conditions: Vec<ConditionTimes>,
}

pub(crate) fn quantile<'a>(values: impl IntoIterator<Item = &'a f64>, q: f64) -> f64 {
    let mut sorted: Vec<f64> = values.into_iter().copied().collect();
    sorted.sort_by(f64::total_cmp);
    mrstudy_analysis::quantile::nearest_rank(&sorted, q)
}

impl FrameTimes {
    /// From the start-up measurement: each condition with its frame times (at least one).
    pub fn new(startup: Vec<(Condition, Vec<f64>)>) -> FrameTimes {
        let conditions = startup
            .into_iter()
            .map(|(condition, times)| ConditionTimes {
                condition,
                recent: times.iter().copied().collect(),
                startup: times,
                frames: 0,
                sum_ms: 0.0,
            })
            .collect();
        FrameTimes { conditions }
    }

    /// Records a live frame's time (non-finite or negative times are ignored).
    pub fn record(&mut self, condition: Condition, ms: f64) {
        if !(ms.is_finite() && ms >= 0.0) {
            return;
        }
        if let Some(times) = self.conditions.iter_mut().find(|times| times.condition == condition) {
            if times.recent.len() == WINDOW {
                times.recent.pop_front();
            }
            times.recent.push_back(ms);
            times.frames += 1;
            times.sum_ms += ms;
        }
    }

    /// Current median frame time of each condition, in the study's order.
    pub fn current(&self) -> Vec<(Condition, f64)> {
        self.conditions.iter().map(|times| (times.condition, quantile(&times.recent, 0.5))).collect()
    }

    /// The slowest condition's current median over the fastest's, minus one (0 when equal).
    pub fn spread(&self) -> f64 {
        let current = self.current();
        let slowest = current.iter().map(|(_, ms)| *ms).fold(0.0, f64::max);
        let fastest = current.iter().map(|(_, ms)| *ms).fold(f64::INFINITY, f64::min);
        if fastest > 0.0 && fastest.is_finite() { slowest / fastest - 1.0 } else { 0.0 }
    }

    /// Whether the conditions differ by more than [`PARITY_TOLERANCE`].
    pub fn unequal(&self) -> bool {
        self.spread() > PARITY_TOLERANCE
    }

    /// The frame time every condition is paced to under `pace = "equal"`, ms.
    pub fn pace_ms(&self) -> f64 {
        PACE_HEADROOM * self.conditions.iter().map(|times| quantile(&times.recent, PACE_QUANTILE)).fold(0.0, f64::max)
    }

    pub fn summary(&self) -> Vec<ConditionFrameTime> {
        self.conditions
            .iter()
            .map(|times| ConditionFrameTime {
                condition: times.condition.name().to_string(),
                startup_ms: quantile(&times.startup, 0.5),
                current_ms: quantile(&times.recent, 0.5),
                live_frames: times.frames,
                live_mean_ms: (times.frames > 0).then(|| times.sum_ms / times.frames as f64),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mrstudy_renderer::gpu::GiLevel;

    #[test]
    fn spread_pace_and_window_follow_the_live_frames() {
        let mut times = FrameTimes::new(vec![
            (Condition::Dir(GiLevel::None), vec![50.0, 60.0, 55.0]),
            (Condition::Dir(GiLevel::Gi), vec![190.0, 200.0, 210.0]),
        ]);
        assert_eq!(times.current(), vec![(Condition::Dir(GiLevel::None), 55.0), (Condition::Dir(GiLevel::Gi), 200.0)]);
        assert!((times.spread() - (200.0 / 55.0 - 1.0)).abs() < 1e-12);
        assert!(times.unequal());
        assert_eq!(times.pace_ms(), PACE_HEADROOM * 210.0);
        // live frames replace the start-up ones in the window
        for _ in 0..WINDOW {
            times.record(Condition::Dir(GiLevel::Gi), 60.0);
        }
        times.record(Condition::Dir(GiLevel::Gi), f64::NAN);
        assert_eq!(times.current()[1], (Condition::Dir(GiLevel::Gi), 60.0));
        assert!(!times.unequal(), "{}", times.spread());
        let summary = times.summary();
        assert_eq!(summary[1].startup_ms, 200.0);
        assert_eq!(summary[1].live_frames, WINDOW as u64);
        assert_eq!(summary[1].live_mean_ms, Some(60.0));
        assert_eq!(summary[0].live_mean_ms, None);
        assert_eq!(times.pace_ms(), PACE_HEADROOM * 60.0);
    }

    #[test]
    fn quantile_is_the_nearest_rank() {
        let values: Vec<f64> = (1..=10).map(f64::from).collect();
        assert_eq!(quantile(&values, 0.9), 9.0);
        assert_eq!(quantile(&values, 0.5), 5.0);
        assert_eq!(quantile(&[], 0.5), 0.0);
    }
}
