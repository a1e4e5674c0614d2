//! Tests of task study files: defaults, refusals naming the key, the shipped lab study.

use super::*;
use crate::lab_study_fixture::LabStudy;

/// The test lab study with its required keys only (`[design]` and `[render]` at their defaults),
/// a distance and a placement task.
fn minimal() -> String {
    LabStudy { min_response_ms: None, tasks: &["kind = \"distance\"", "kind = \"placement\""], ..LabStudy::default() }
        .required_toml()
}

fn load(text: &str) -> Result<TaskStudy, StudyError> {
    parse(text, Path::new("studies/lab.toml"), Path::new("studies"), "00".into())
}

#[test]
fn defaults_are_the_thesis_design() {
    let study = load(&minimal()).unwrap();
    assert_eq!(
        study.conditions,
        vec![Condition::Dir(GiLevel::None), Condition::Dir(GiLevel::Shadows), Condition::Dir(GiLevel::Gi)]
    );
    assert_eq!(study.counterbalance, Counterbalance::Williams);
    assert_eq!(study.scene, "lab-task");
    assert_eq!(study.tasks.len(), 2);
    assert_eq!(study.trial_count(), 2 * (1 + 3 * 3));
}

#[test]
fn a_condition_may_name_a_coherent_method_and_a_wrong_one_is_refused_with_its_key() {
    use mrstudy_renderer::coherent::{Method, Quality};
    let with = |conditions: &str| {
        load(&minimal().replace("[[tasks]]\nkind = \"placement\"", &format!("[design]\nconditions = {conditions}")))
    };
    let study = with(r#"["off", "dit", "vct-high", "em-low"]"#).unwrap();
    let coherent = |method, quality| Condition::Coherent(CoherentLevel { method, quality });
    assert_eq!(
        study.conditions,
        vec![
            Condition::Dir(GiLevel::None),
            coherent(Method::Dit, Quality::Med),
            coherent(Method::Vct, Quality::High),
            coherent(Method::Em, Quality::Low),
        ]
    );
    let names: Vec<String> = study.conditions.iter().map(Condition::name).collect();
    assert_eq!(names, ["none", "dit", "vct-high", "em-low"]);
    assert_eq!(serde_json::to_value(study.conditions[2]).unwrap(), "vct-high");
    for (conditions, key) in [
        (r#"["gi", "dit-best"]"#, "design.conditions[1]"),
        (r#"["off-high", "gi"]"#, "design.conditions[0]"),
        (r#"["dit", "dit-med"]"#, "design.conditions[1]"),
    ] {
        let error = with(conditions).unwrap_err();
        assert_eq!(error.key, key, "{conditions}: {error}");
    }
    assert!(with(r#"["dit", "dit-med"]"#).unwrap_err().expected.contains("\"dit\" appears twice"));
}

#[test]
fn bad_values_name_the_key() {
    let error =
        load(&minimal().replace("[[tasks]]\nkind = \"placement\"", "[design]\nconditions = [\"none\", \"HQ\"]"))
            .unwrap_err();
    assert_eq!(error.key, "design.conditions[1]");
    assert!(error.expected.contains("none, shadows, gi"), "{error}");
    let error =
        load(&minimal().replace("kind = \"placement\"", "kind = \"placement\"\nanswer_max_cm = 50")).unwrap_err();
    assert_eq!(error.key, "tasks[1].answer_max_cm");
    let error = load(&minimal().replace("kind = \"placement\"", "kind = \"distance\"")).unwrap_err();
    assert_eq!(error.key, "tasks[1].name");
    let error = load(&minimal().replace("kind = \"placement\"", "kind = \"juggling\"")).unwrap_err();
    assert!(error.to_string().contains("juggling"), "{error}");
    let error = load(&minimal().replace("kind = \"placement\"", "kind = \"placement\"\nmax_cm = 80")).unwrap_err();
    assert_eq!(error.key, "tasks[1].min_cm");
    // a held arrow key's steps per second: 1 to 60, for key tasks only, 10 by default
    let study = load(&minimal()).unwrap();
    assert!(study.tasks.iter().all(|task| task.held_steps_per_second == DEFAULT_HELD_STEPS_PER_SECOND));
    let error = load(&minimal().replace("kind = \"placement\"", "kind = \"placement\"\nheld_steps_per_second = 0"))
        .unwrap_err();
    assert_eq!(error.key, "tasks[1].held_steps_per_second");
    let error =
        load(&minimal().replace("kind = \"distance\"", "kind = \"distance\"\nheld_steps_per_second = 5")).unwrap_err();
    assert_eq!(error.key, "tasks[0].held_steps_per_second");
    let fast = load(&minimal().replace("kind = \"placement\"", "kind = \"placement\"\nheld_steps_per_second = 20"));
    assert_eq!(fast.unwrap().tasks[1].held_steps_per_second, 20.0);
}

#[test]
fn participation_and_pace_keys_have_defaults_and_name_the_key_when_bad() {
    let study = load(&minimal()).unwrap();
    assert_eq!((study.min_response_ms, study.abandon_after_minutes, study.render.pace), (300, 30.0, Pace::None));
    let top = minimal().replace(
        "kind = \"task\"",
        "kind = \"task\"\npace = \"equal\"\nmin_response_ms = 0\nabandon_after_minutes = 0.01",
    );
    let study = load(&top).unwrap();
    assert_eq!((study.min_response_ms, study.abandon_after_minutes, study.render.pace), (0, 0.01, Pace::Equal));
    let under = minimal()
        .replace("[[tasks]]\nkind = \"distance\"", "[render]\npace = \"equal\"\n[[tasks]]\nkind = \"distance\"");
    assert_eq!(load(&under).unwrap().render.pace, Pace::Equal);
    let both =
        top.replace("[[tasks]]\nkind = \"distance\"", "[render]\npace = \"none\"\n[[tasks]]\nkind = \"distance\"");
    assert_eq!(load(&both).unwrap_err().key, "render.pace");
    let error = load(&minimal().replace("kind = \"task\"", "kind = \"task\"\nmin_response_ms = -5")).unwrap_err();
    assert_eq!(error.key, "min_response_ms");
    let error = load(&minimal().replace("kind = \"task\"", "kind = \"task\"\nabandon_after_minutes = 0")).unwrap_err();
    assert_eq!(error.key, "abandon_after_minutes");
    let error = load(&minimal().replace("kind = \"task\"", "kind = \"task\"\npace = \"fast\"")).unwrap_err();
    assert!(error.to_string().contains("fast"), "{error}");
}

#[test]
fn the_shipped_lab_study_loads_as_a_task_study() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../studies");
    let studies = crate::study::load_studies(&dir).unwrap();
    let task = studies
        .iter()
        .find_map(|study| match study {
            crate::study::LoadedStudy::Task(task) => Some(task),
            _ => None,
        })
        .expect("studies/lab-task.toml is a task study");
    assert_eq!(task.slug, "lab-task");
    assert_eq!(
        task.tasks.iter().map(|t| t.kind).collect::<Vec<_>>(),
        vec![TaskKind::Distance, TaskKind::Placement, TaskKind::Contact]
    );
    assert_eq!(task.trial_count(), 30);
    let error = crate::study::load_study(&dir.join("lab-task.toml")).unwrap_err();
    assert_eq!(error.key, "kind");
}
