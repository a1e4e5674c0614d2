//! Progress bars (indicatif) for the long commands: one bar with a unit, the two bars of
//! stimulus rendering (plain lines when stderr is not a terminal, e.g. a service's log:
//! `mrstudy_server::stimuli::lines`), and the benchmarks' printer.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use mrstudy_renderer::bench::Observer;
use mrstudy_server::stimuli::Progress;
use mrstudy_server::stimuli::lines::ProgressLines;

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
        let lines = Mutex::new(ProgressLines::default());
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
