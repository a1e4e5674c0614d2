//! What the CLI's commands say, on the terminal: [`Console`] prints their lines and notes and
//! draws their progress as a bar (indicatif); [`stimulus_bars`], the two bars of stimulus
//! rendering (plain lines when stderr is not a terminal, e.g. a service's log: [`ProgressLines`]).

use std::sync::{Arc, Mutex};
use std::time::Instant;

use crate::stimuli::Progress;
use crate::stimuli::lines::ProgressLines;
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use mrstudy_renderer::command::Said;

/// A bar counting `total` `unit`s under `label`.
fn progress_bar(total: u64, label: &str, unit: &str) -> ProgressBar {
    let template = format!("{{msg}} [{{bar:30}}] {{pos}}/{{len}} {unit} {{elapsed_precise}} (eta {{eta}})");
    let style = ProgressStyle::with_template(&template).unwrap_or_else(|_| ProgressStyle::default_bar());
    ProgressBar::new(total).with_style(style.progress_chars("=> ")).with_message(label.to_string())
}

/// Prints what a command says: [`Said::Out`] to stdout, notes to stderr (after clearing the bar),
/// progress as one bar, cleared when its work is done or the console is dropped.
#[derive(Default)]
pub struct Console {
    bar: Mutex<Option<(String, ProgressBar)>>,
}

impl Console {
    pub fn say(&self, said: Said) {
        let mut bar = self.bar.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        if let Said::Progress { label, unit, done, total } = said
            && (done < total || total == 0)
        {
            if bar.as_ref().is_none_or(|(shown, _)| shown != unit) {
                *bar = Some((unit.to_string(), progress_bar(total, label, unit)));
            }
            let (_, bar) = bar.as_ref().expect("a bar was just made");
            bar.set_length(total);
            bar.set_message(label.to_string());
            return bar.set_position(done);
        }
        clear(&mut bar);
        match said {
            Said::Out(text) => print!("{text}"),
            Said::Note(text) => eprintln!("{text}"),
            _ => {}
        }
    }
}

impl Drop for Console {
    fn drop(&mut self) {
        clear(&mut self.bar.lock().unwrap_or_else(|poisoned| poisoned.into_inner()));
    }
}

fn clear(bar: &mut Option<(String, ProgressBar)>) {
    if let Some((_, bar)) = bar.take() {
        bar.finish_and_clear();
    }
}

/// Bars for rendering a study's stimuli: one for the photograph being path-traced, one for
/// the stimuli; when stderr is not a terminal (where indicatif draws nothing), plain lines
/// instead.
pub fn stimulus_bars() -> Arc<dyn Fn(&str, &Progress) + Send + Sync> {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        let lines = Mutex::new(ProgressLines::default());
        return Arc::new(move |slug: &str, step: &Progress| {
            if let Progress::Stimulus { warning: Some(warning), .. } = step {
                eprintln!("warning: {warning}");
            }
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
            Progress::Stimulus { scene, condition, warning, .. } => {
                if let Some(warning) = warning {
                    let _ = bars.println(format!("warning: {warning}"));
                }
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
