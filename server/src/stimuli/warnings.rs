//! What a study's stored stimulus records warn of, once per scene configuration: `serve` prints
//! it at start-up for a study whose stimuli are already rendered (a render prints each
//! stimulus's warning as it is made: [`super::Progress::Stimulus`]). Today the one warning is
//! the statistics colour mapping's channel ratio outside [0.5, 2]
//! ([`mrstudy_renderer::cm::statistics::RatioWarning`]).

use std::path::Path;

use super::{StimulusPlan, lookup_record};
use crate::study::Study;

/// One line per scene configuration of `study` whose stimuli's records in `store` carry a
/// warning: the study, the scene configuration, the conditions concerned and the first
/// condition's warning. A stimulus without a record (an image scene, one not rendered yet, a
/// record made before records had warnings) adds nothing.
pub fn stored_warnings(study: &Study, plan: &StimulusPlan, store: &Path) -> Vec<String> {
    let mut lines = Vec::new();
    for planned in plan.scenes.iter().flatten() {
        let mut conditions: Vec<&str> = Vec::new();
        let mut first = None;
        for stimulus in &planned.stimuli {
            let Some(record) = lookup_record(store, stimulus) else { continue };
            if let Some(warning) = record.warnings.into_iter().next() {
                conditions.push(&stimulus.condition);
                first.get_or_insert(warning);
            }
        }
        let (Some(warning), Some(stimulus)) = (first, planned.stimuli.first()) else { continue };
        lines.push(format!(
            "study \"{}\", scene configuration \"{}\" (condition {}): {warning}",
            study.slug,
            stimulus.scene,
            conditions.join(", ")
        ));
    }
    lines
}
