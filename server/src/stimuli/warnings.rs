//! What a study's stored stimulus records warn of, once per scene configuration: `serve` prints
//! it at start-up for a study whose stimuli are already rendered, `mrstudy stimuli` at its end
//! (a render prints each stimulus's warning as it is made: [`super::Progress::Stimulus`]). Today the one warning is
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

#[cfg(test)]
mod tests {
    use super::super::{Progress, StimulusPlan, lookup, lookup_record, render_missing};
    use super::*;

    /// dir-lamp-box (a grey real scene: docs/renderer.md) with and without the statistics
    /// colour mapping, small.
    const GREY: &str = r#"
slug = "grey"
title = "T"
kind = "paired-comparison"
question = "Q?"
[texts]
welcome = "w"
consent = "c"
instructions = "i"
[[factors]]
name = "cm"
[[conditions]]
name = "off"
levels = { cm = 0 }
[[conditions]]
name = "mapped"
levels = { cm = 1 }
[[scenes]]
name = "box"
render = "dir-lamp-box"
[render]
size = [48, 36]
spp = 2
[design]
reference = "ground-truth"
repetitions = 1
scenes = "same"
"#;

    #[test]
    fn the_statistics_mappings_ratio_warning_reaches_the_progress_the_record_and_the_start_up_line() {
        if mrstudy_renderer::gpu::DirRenderer::new().is_err() {
            eprintln!("skipped: no GPU adapter (not even a software one)");
            return;
        }
        let dir = tempfile::tempdir().unwrap();
        let studies = dir.path().join("studies");
        std::fs::create_dir_all(&studies).unwrap();
        let file = studies.join("grey.toml");
        std::fs::write(&file, GREY).unwrap();
        let study = crate::study::load_study(&file).unwrap();
        let plan = StimulusPlan::of(&study).unwrap();
        let store = dir.path().join("store");
        let said = std::sync::Mutex::new(Vec::new());
        render_missing(&study, &plan, &store, &|step| {
            if let Progress::Stimulus { condition, warning, .. } = step {
                said.lock().unwrap().push((condition, warning));
            }
        })
        .unwrap();
        let said = said.into_inner().unwrap();
        let warned = |condition: &str| said.iter().find(|(c, _)| c == condition).and_then(|(_, w)| w.clone());
        assert_eq!(warned("off"), None, "{said:?}");
        let warning = warned("mapped").expect("the mapped condition's render warns");
        for part in ["scene \"dir-lamp-box\"", "σ camera", "chroma multiplied about", "docs/renderer.md"] {
            assert!(warning.contains(part), "{part:?} missing from: {warning}");
        }
        // the records: the mapped stimulus's carries the sentence; the other has no such field
        let planned = plan.scenes[0].as_ref().unwrap();
        let record = |index: usize| lookup_record(&store, &planned.stimuli[index]).unwrap();
        assert_eq!(record(1).warnings, vec![warning.clone()]);
        assert!(record(0).warnings.is_empty());
        let stored = std::fs::read_to_string(store.join(lookup(&store, &planned.stimuli[0].record_key()).unwrap()));
        assert!(!stored.unwrap().contains("warnings"), "an empty list is not written");
        // serve's start-up line: once for the scene configuration, naming study and condition
        let lines = stored_warnings(&study, &plan, &store);
        assert_eq!(lines, vec![format!("study \"grey\", scene configuration \"box\" (condition mapped): {warning}")]);
        // and `serve` loads the rendered study with that line among its warnings
        let data = dir.path().join("data");
        let database = crate::storage::Database::in_data_dir(&data);
        let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
        let prepared = runtime.block_on(crate::serve::load(&database, &data, &studies, Some(&store))).unwrap();
        assert_eq!(prepared.slugs, ["grey"], "{:?}", prepared.skipped);
        assert_eq!(prepared.stimulus_warnings, lines);
    }
}
