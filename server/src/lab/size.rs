//! The live frame size of a task study (issue 50, item 5).
//!
//! An explicit `render.size` is used as given. Without one, on a hardware adapter the lab
//! renders at [`HARDWARE_SIZE`], and [`display_rate_line`] says after the start-up measurement
//! whether every condition reaches [`DISPLAY_FPS`] there (so `pace = "equal"` costs nothing).
//! On a software adapter (lavapipe, llvmpipe) [`auto_size`] measures at start-up: it renders a
//! few frames of every condition at the smallest size of [`LADDER`] to find the slowest
//! condition, then only that condition at each larger size until it falls below the target
//! (`render.min_fps`, default 10 frames/s), and [`choose`] takes the largest size that kept the
//! target (the smallest when none did). A condition's frame time is its median, or with
//! `pace = "equal"` the pace its frames would be held to (1.5 × the 90th percentile), which is
//! what every condition's participant then sees. The ladder's scenes use a 1-sample photograph, rendered
//! and not cached: their frames cost what the study's frames cost, and the study's own
//! photograph is path-traced (and cached) once, at the chosen size.

use std::path::Path;

use super::live::{self, LabRenderer, LiveError};
use super::timing;
use crate::study::task::{Condition, Pace, TaskStudy};

/// The live size on a hardware adapter when `render.size` is not given.
pub const HARDWARE_SIZE: [u32; 2] = [320, 240];
/// The sizes tried on a software adapter when `render.size` is not given, smallest first (4:3).
pub const LADDER: [[u32; 2]; 6] = [[96, 72], [128, 96], [160, 120], [192, 144], [240, 180], [320, 240]];
/// Frames measured per condition and ladder size (after one warm-up frame): as many as the
/// start-up measurement that follows takes, so that the two agree on a paced frame time (with
/// fewer, the 90th percentile is the slowest frame, the one after a trial's fresh start).
pub const LADDER_FRAMES: usize = super::STARTUP_FRAMES;
/// The display's rate a hardware adapter should reach in every condition.
pub const DISPLAY_FPS: f64 = 60.0;

/// The slowest condition's frame rate at one size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Probe {
    pub size: [u32; 2],
    /// Frame time (render and JPEG encoding), ms: the median, or the pace with `pace = "equal"`.
    pub ms: f64,
}

impl Probe {
    pub fn fps(&self) -> f64 {
        1000.0 / self.ms.max(1e-3)
    }
}

/// The largest size (by pixels) whose probe reaches `target_fps`; the smallest probed size when
/// none does; None when nothing was probed.
pub fn choose(probes: &[Probe], target_fps: f64) -> Option<[u32; 2]> {
    let pixels = |probe: &&Probe| u64::from(probe.size[0]) * u64::from(probe.size[1]);
    probes
        .iter()
        .filter(|probe| probe.fps() >= target_fps)
        .max_by_key(pixels)
        .or_else(|| probes.iter().min_by_key(pixels))
        .map(|probe| probe.size)
}

/// What [`auto_size`] measured and chose.
#[derive(Debug, Clone)]
pub struct AutoSize {
    pub size: [u32; 2],
    /// The slowest condition at the smallest size, which the larger sizes measure.
    pub condition: Condition,
    pub probes: Vec<Probe>,
    pub target_fps: f64,
}

impl AutoSize {
    /// Whether the chosen size reaches the target.
    pub fn reached(&self) -> bool {
        self.probes.iter().any(|probe| probe.size == self.size && probe.fps() >= self.target_fps)
    }

    /// The console line: the adapter, each size's frame rate, the size chosen.
    pub fn line(&self, slug: &str, adapter: &live::AdapterInfo, pace: Pace) -> String {
        let measured = self
            .probes
            .iter()
            .map(|probe| {
                format!("{}×{} {:.1} ms ({:.2} frames/s)", probe.size[0], probe.size[1], probe.ms, probe.fps())
            })
            .collect::<Vec<_>>()
            .join(", ");
        let fps = self.probes.iter().find(|probe| probe.size == self.size).map_or(0.0, Probe::fps);
        let choice = if self.reached() {
            format!(
                "chose {}×{}, the largest size at which the slowest condition keeps {} frames/s (measured {fps:.2} frames/s; measured anew at each start: set render.size = [{}, {}] to keep it)",
                self.size[0], self.size[1], self.target_fps, self.size[0], self.size[1]
            )
        } else {
            format!(
                "chose {}×{}, the smallest size, where the slowest condition reaches only {fps:.2} frames/s (target {} frames/s)",
                self.size[0], self.size[1], self.target_fps
            )
        };
        format!(
            "lab study \"{slug}\": render.size not set; adapter {} ({}), slowest condition {}{}: {measured}; {choice}",
            adapter.adapter,
            adapter.kind,
            self.condition,
            if pace == Pace::Equal { ", paced (pace = \"equal\")" } else { "" }
        )
    }
}

/// Measures `study` (whose `render.size` is not set) at the sizes of `ladder` on `renderer` and
/// chooses its live size (see the module doc). Leaves the last ladder scene registered under
/// the study's slug; the caller registers the study's own scene over it.
pub async fn auto_size(
    renderer: &LabRenderer,
    study: &TaskStudy,
    ladder: &[[u32; 2]],
    frames: usize,
) -> Result<AutoSize, LiveError> {
    let mut probe_study = study.clone();
    probe_study.render.photo_spp = 1;
    let target_fps = study.render.min_fps;
    let mut probes = Vec::new();
    let mut slowest: Option<Condition> = None;
    for &size in ladder {
        let prepared = {
            let probe_study = probe_study.clone();
            tokio::task::spawn_blocking(move || live::prepare_scene(&probe_study, size, None::<&Path>))
                .await
                .map_err(|error| LiveError::Thread { reason: error.to_string() })??
        };
        let real = prepared.layout.real_centre;
        let centre = [real[0] + 0.12, real[1], real[2]];
        renderer.register(prepared)?;
        let mut measured_study = probe_study.clone();
        if let Some(condition) = slowest {
            measured_study.conditions = vec![condition];
        }
        let measured = live::measure(renderer, &measured_study, centre, frames).await?;
        let Some((condition, ms)) = measured
            .into_iter()
            .map(|(condition, times)| (condition, frame_ms(&times, study.render.pace)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
        else {
            break;
        };
        slowest = Some(condition);
        let probe = Probe { size, ms };
        probes.push(probe);
        if probe.fps() < target_fps {
            break;
        }
    }
    let size = choose(&probes, target_fps).unwrap_or(LADDER[0]);
    Ok(AutoSize { size, condition: slowest.unwrap_or(study.conditions[0]), probes, target_fps })
}

/// The frame time a participant sees: the median of `times`, or with `pace = "equal"` the pace
/// these times would set (see [`super::timing`]), so the target holds for paced frames too.
fn frame_ms(times: &[f64], pace: Pace) -> f64 {
    match pace {
        Pace::None => timing::quantile(times, 0.5),
        Pace::Equal => timing::PACE_HEADROOM * timing::quantile(times, timing::PACE_QUANTILE),
    }
}

/// On a hardware adapter: whether every condition reaches [`DISPLAY_FPS`] at the live size,
/// with each condition's frame rate (`medians`: condition name and median frame time, ms).
pub fn display_rate_line(slug: &str, adapter: &live::AdapterInfo, size: [u32; 2], medians: &[(String, f64)]) -> String {
    let fps = |ms: f64| 1000.0 / ms.max(1e-3);
    let per_condition = medians
        .iter()
        .map(|(condition, ms)| format!("{condition} {:.0} frames/s", fps(*ms)))
        .collect::<Vec<_>>()
        .join(", ");
    let slow: Vec<&str> =
        medians.iter().filter(|(_, ms)| fps(*ms) < DISPLAY_FPS).map(|(condition, _)| condition.as_str()).collect();
    let verdict = if slow.is_empty() {
        format!("every condition reaches the display's {DISPLAY_FPS} frames/s, so pace = \"equal\" costs nothing")
    } else {
        format!(
            "below the display's {DISPLAY_FPS} frames/s in condition {} (use a smaller render.size)",
            slow.join(", ")
        )
    };
    format!(
        "lab study \"{slug}\": hardware adapter {} at render.size {}×{}: {per_condition}; {verdict}",
        adapter.adapter, size[0], size[1]
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn probes(fps: &[(u32, f64)]) -> Vec<Probe> {
        fps.iter().map(|&(width, fps)| Probe { size: [width, width * 3 / 4], ms: 1000.0 / fps }).collect()
    }

    #[test]
    fn the_largest_size_that_keeps_the_target_is_chosen() {
        // frame rates fall with size; the ladder stops at the first size below the target
        let measured = probes(&[(96, 40.0), (128, 22.0), (160, 12.5), (192, 9.0)]);
        assert_eq!(choose(&measured, 10.0), Some([160, 120]));
        assert_eq!(choose(&measured, 20.0), Some([128, 96]));
        // exactly the target counts as reaching it
        assert_eq!(choose(&measured, 12.5), Some([160, 120]));
        // an unsorted, non-monotone measurement still gives the largest that passes
        let measured = probes(&[(192, 11.0), (96, 40.0), (160, 9.5)]);
        assert_eq!(choose(&measured, 10.0), Some([192, 144]));
    }

    #[test]
    fn when_no_size_keeps_the_target_the_smallest_is_chosen() {
        assert_eq!(choose(&probes(&[(128, 6.0), (96, 8.0)]), 10.0), Some([96, 72]));
        assert_eq!(choose(&[], 10.0), None);
    }

    #[test]
    fn a_paced_study_is_measured_at_its_pace() {
        let times: Vec<f64> = (1..=10).map(|ms| f64::from(ms) * 10.0).collect();
        assert_eq!(frame_ms(&times, Pace::None), 50.0);
        // 1.5 × the 90th percentile (nearest rank: 90 ms)
        assert_eq!(frame_ms(&times, Pace::Equal), 135.0);
    }

    #[test]
    fn the_display_rate_line_names_each_condition_and_the_slow_ones() {
        let adapter = live::AdapterInfo { adapter: "NVIDIA H200 (Vulkan)".into(), kind: "hardware".into() };
        let fast = display_rate_line("lab", &adapter, [320, 240], &[("none".into(), 2.0), ("gi".into(), 12.5)]);
        assert!(fast.contains("none 500 frames/s, gi 80 frames/s"), "{fast}");
        assert!(fast.contains("costs nothing"), "{fast}");
        let slow = display_rate_line("lab", &adapter, [320, 240], &[("none".into(), 2.0), ("gi".into(), 20.0)]);
        assert!(slow.contains("below the display's 60 frames/s in condition gi"), "{slow}");
    }
}
