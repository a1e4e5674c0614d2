//! Progress bars (indicatif) for the long commands: one bar with a unit, the two bars of
//! stimulus rendering (plain lines when stderr is not a terminal, e.g. a service's log), and
//! the benchmarks' printer.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use mrstudy_renderer::bench::Observer;
use mrstudy_server::stimuli::Progress;

/// A bar counting `total` `unit`s under `label`.
pub fn progress_bar(total: u64, label: &str, unit: &str) -> ProgressBar {
    let template = format!("{{msg}} [{{bar:30}}] {{pos}}/{{len}} {unit} {{elapsed_precise}} (eta {{eta}})");
    let style = ProgressStyle::with_template(&template).unwrap_or_else(|_| ProgressStyle::default_bar());
    ProgressBar::new(total).with_style(style.progress_chars("=> ")).with_message(label.to_string())
}

/// Bars for rendering a study's stimuli: one for the photograph being path-traced, one for
/// the stimuli; when stderr is not a terminal (where indicatif draws nothing), plain lines
/// instead.
pub fn stimulus_bars() -> Arc<dyn Fn(&str, &Progress) + Send + Sync> {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        let lines = Mutex::new(Lines::default());
        return Arc::new(move |slug: &str, step: &Progress| {
            let line = lines.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).step(slug, step, Instant::now());
            if let Some(line) = line {
                eprintln!("{line}");
            }
        });
    }
    let bars = MultiProgress::new();
    let state: Mutex<Option<(ProgressBar, ProgressBar)>> = Mutex::new(None);
    Arc::new(move |slug: &str, step: &Progress| {
        let mut state = state.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        match step {
            Progress::Start { photos, stimuli } => {
                let photo = bars.add(progress_bar(1, "photograph", "spp"));
                let label = format!("{slug}: {stimuli} stimuli ({photos} photographs first)");
                *state = Some((photo, bars.add(progress_bar(*stimuli as u64, &label, "stimuli"))));
            }
            Progress::Photo { scene, done, total } => {
                if let Some((photo, _)) = state.as_ref() {
                    photo.set_length(*total as u64);
                    photo.set_position(*done as u64);
                    photo.set_message(format!("photograph {scene}"));
                }
            }
            Progress::Stimulus { scene, condition, .. } => {
                if let Some((photo, frames)) = state.as_ref() {
                    frames.inc(1);
                    frames.set_message(format!("{slug}: {scene} {condition}"));
                    if frames.position() == frames.length().unwrap_or(0) {
                        photo.finish_and_clear();
                        frames.finish_and_clear();
                    }
                }
            }
        }
    })
}

/// A plain line at most every [`LINE_EVERY`] and at each further 5 % of a study's stimuli.
const LINE_EVERY: Duration = Duration::from_secs(10);

/// Where the rendering of one study's stimuli stands, for the plain lines of [`stimulus_bars`].
#[derive(Default)]
struct Lines {
    slug: String,
    stimuli: usize,
    done: usize,
    /// The reference render under way: scene configuration, samples done and total.
    photo: Option<(String, u32, u32)>,
    /// When the last line was printed and the 5 % step it was at.
    last: Option<(Instant, usize)>,
}

impl Lines {
    /// The line to print for this step, if one is due: always at the start and the end, at each
    /// further 5 % of the stimuli, and at least every 10 s while anything moves.
    fn step(&mut self, slug: &str, step: &Progress, now: Instant) -> Option<String> {
        match step {
            Progress::Start { photos, stimuli } => {
                *self = Lines { slug: slug.to_string(), stimuli: *stimuli, ..Lines::default() };
                self.last = Some((now, 0));
                return Some(format!(
                    "{slug}: rendering {stimuli} stimuli ({photos} reference renders of the photograph and ground truth first)"
                ));
            }
            Progress::Photo { scene, done, total } => self.photo = Some((scene.clone(), *done, *total)),
            Progress::Stimulus { .. } => {
                self.photo = None;
                self.done += 1;
            }
        }
        let step_now = (self.done * 20).checked_div(self.stimuli).unwrap_or(0);
        let (at, step_then) = self.last.unwrap_or((now, 0));
        let finished = self.stimuli > 0 && self.done == self.stimuli;
        if !(finished || step_now > step_then || now.duration_since(at) >= LINE_EVERY) {
            return None;
        }
        self.last = Some((now, step_now));
        let percent = (self.done * 100).checked_div(self.stimuli).unwrap_or(0);
        let mut line = format!("{}: {} of {} stimuli rendered ({percent} %)", self.slug, self.done, self.stimuli);
        if let Some((scene, done, total)) = &self.photo {
            line += &format!("; reference render of {scene}: {done} of {total} samples per pixel");
        }
        Some(line)
    }
}

/// Prints a renderer benchmark's table to stdout, its notes to stderr, and a progress bar for
/// each reference render.
#[derive(Default)]
pub struct Printer {
    bar: Mutex<Option<ProgressBar>>,
}

impl Observer for Printer {
    fn line(&self, text: &str) {
        println!("{text}");
    }
    fn note(&self, text: &str) {
        eprintln!("{text}");
    }
    fn progress(&self, label: &str, done: u32, total: u32) {
        let mut bar = self.bar.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        if done >= total {
            if let Some(bar) = bar.take() {
                bar.finish_and_clear();
            }
        } else {
            bar.get_or_insert_with(|| progress_bar(total as u64, label, "spp")).set_position(done as u64);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stimulus() -> Progress {
        Progress::Stimulus { scene: "a".into(), condition: "c".into(), ms: 1.0 }
    }

    /// 40 stimuli: a line at the start, at every second stimulus (5 %) and none in between,
    /// and one after 10 s of a reference render without a stimulus.
    #[test]
    fn plain_lines_come_every_five_per_cent_or_ten_seconds() {
        let start = Instant::now();
        let mut lines = Lines::default();
        let first = lines.step("s", &Progress::Start { photos: 2, stimuli: 40 }, start).unwrap();
        assert!(first.starts_with("s: rendering 40 stimuli"), "{first}");
        let photo = |done| Progress::Photo { scene: "box".into(), done, total: 64 };
        assert_eq!(lines.step("s", &photo(8), start + Duration::from_secs(5)), None);
        assert_eq!(
            lines.step("s", &photo(16), start + Duration::from_secs(10)).as_deref(),
            Some("s: 0 of 40 stimuli rendered (0 %); reference render of box: 16 of 64 samples per pixel")
        );
        let at = start + Duration::from_secs(11);
        assert_eq!(lines.step("s", &stimulus(), at), None);
        assert_eq!(lines.step("s", &stimulus(), at).as_deref(), Some("s: 2 of 40 stimuli rendered (5 %)"));
        let printed = (0..38).filter_map(|_| lines.step("s", &stimulus(), at)).collect::<Vec<_>>();
        assert_eq!(printed.len(), 19, "{printed:?}");
        assert_eq!(printed.last().unwrap(), "s: 40 of 40 stimuli rendered (100 %)");
    }
}
