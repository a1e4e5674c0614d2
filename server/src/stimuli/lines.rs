//! Plain progress lines for rendering a study's stimuli where no progress bar can be drawn
//! (stderr not a terminal, e.g. a service's log): one at the start and the end, one at each
//! further 5 % of the stimuli, and one at least every 10 s while a reference render runs.

use std::time::{Duration, Instant};

use super::Progress;

/// A plain line at most every [`LINE_EVERY`] and at each further 5 % of a study's stimuli.
const LINE_EVERY: Duration = Duration::from_secs(10);

/// Where the rendering of one study's stimuli stands, for its plain progress lines.
#[derive(Debug, Default)]
pub struct ProgressLines {
    slug: String,
    stimuli: usize,
    done: usize,
    /// The reference render under way: scene configuration, samples done and total.
    photo: Option<(String, u32, u32)>,
    /// When the last line was printed and the 5 % step it was at.
    last: Option<(Instant, usize)>,
}

impl ProgressLines {
    /// The line to print for this step, if one is due: always at the start and the end, at each
    /// further 5 % of the stimuli, and at least every 10 s while anything moves.
    pub fn step(&mut self, slug: &str, step: &Progress, now: Instant) -> Option<String> {
        match step {
            Progress::Start { photos, stimuli } => {
                *self = ProgressLines { slug: slug.to_string(), stimuli: *stimuli, ..ProgressLines::default() };
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

#[cfg(test)]
mod tests {
    use super::*;

    fn stimulus() -> Progress {
        Progress::Stimulus { scene: "a".into(), condition: "c".into(), ms: 1.0, warning: None }
    }

    /// 40 stimuli: a line at the start, at every second stimulus (5 %) and none in between,
    /// and one after 10 s of a reference render without a stimulus.
    #[test]
    fn plain_lines_come_every_five_per_cent_or_ten_seconds() {
        let start = Instant::now();
        let mut lines = ProgressLines::default();
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
