//! The render queue without a GPU: a fake render that stores a one-line file per stimulus,
//! held at a gate so that the queue's state can be looked at while a render is under way.

use std::sync::mpsc;

use super::*;

/// An on-demand threshold study (two scene configurations, ten levels) prepared over a store in
/// which only the ground truths and the start-up levels exist (fake files).
fn prepared(store: &Path) -> (Arc<PreparedStudy>, StimulusPlan) {
    let dir = tempfile::tempdir().unwrap();
    let text = crate::study::threshold_tests::THRESHOLD.replace(
        "reference = \"ground-truth\"",
        "reference = \"ground-truth\"\nrender = \"on-demand\"\nrender_ahead = 2",
    );
    let file = dir.path().join("threshold.toml");
    std::fs::write(&file, text).unwrap();
    let study = crate::study::load_study(&file).unwrap();
    let plan = StimulusPlan::of(&study).unwrap();
    let startup = startup_plan(&study, &plan);
    std::fs::create_dir_all(store.join("rendered")).unwrap();
    startup.stimuli().for_each(|stimulus| fake_record(store, stimulus));
    let mut keys: Vec<String> = startup.stimuli().map(|stimulus| stimulus.key.clone()).collect();
    keys.extend(plan.scenes.iter().flatten().filter_map(|scene| scene.ground_truth_key.clone()));
    for key in keys {
        fake(store, &key);
    }
    let prepared = PreparedStudy::prepare(study, &plan, store).unwrap();
    (Arc::new(prepared), plan)
}

fn fake(store: &Path, key: &str) {
    let name = crate::stimuli::store_bytes(key.as_bytes(), "png", store).unwrap();
    std::fs::write(store.join("rendered").join(key), name).unwrap();
}

/// A stimulus record whose render time is the level's index (its errors left empty).
fn fake_record(store: &Path, stimulus: &crate::stimuli::PlannedStimulus) {
    let record = crate::stimuli::StimulusRecord {
        stimulus: format!("{}.png", stimulus.key),
        ground_truth: "truth.png".into(),
        factors: "gi".into(),
        settings: Default::default(),
        render_ms: stimulus.condition_index as f64,
        adapter: "test".into(),
        reference_seconds: 0.0,
        errors: Default::default(),
        warnings: Vec::new(),
    };
    let name = crate::stimuli::store_bytes(&serde_json::to_vec(&record).unwrap(), "json", store).unwrap();
    std::fs::write(store.join("rendered").join(stimulus.record_key()), name).unwrap();
}

/// A queue whose renders each wait for a message on the returned sender, and tell each
/// stimulus rendered on the returned receiver.
fn gated(store: &Path, capacity: usize) -> (RenderQueue, mpsc::Sender<()>, mpsc::Receiver<usize>) {
    let (open, gate) = mpsc::channel::<()>();
    let (told, rendered) = mpsc::channel::<usize>();
    let gate = Arc::new(Mutex::new(gate));
    let make: MakeRender = Arc::new(move || {
        let (gate, told) = (gate.clone(), told.clone());
        Box::new(move |_: &Study, plan: &StimulusPlan, store: &Path| {
            gate.lock().unwrap().recv().map_err(|_| "the test ended".to_string())?;
            let stimuli: Vec<_> = plan.stimuli().collect();
            assert_eq!(stimuli.len(), 1, "one stimulus per render");
            fake(store, &stimuli[0].key);
            fake_record(store, stimuli[0]);
            told.send(stimuli[0].condition_index).unwrap();
            Ok(())
        })
    });
    (RenderQueue::with_render(store.to_path_buf(), capacity, make), open, rendered)
}

#[test]
fn start_up_renders_the_levels_of_the_first_trials_and_every_ground_truth() {
    let store = tempfile::tempdir().unwrap();
    let (prepared, plan) = prepared(store.path());
    let design = prepared.study.threshold.as_ref().unwrap();
    let intensities = design.intensities.clone().unwrap();
    let first = first_levels(design, &intensities, 1).unwrap();
    assert_eq!(first.len(), 1, "no answers: one level");
    let two = first_levels(design, &intensities, 2).unwrap();
    assert!(two.is_superset(&first) && two.len() <= 3, "{two:?}");
    // the prepared study knows the start-up levels' files and leaves the others empty
    for (scene, names) in prepared.stimuli.iter().enumerate() {
        for (level, name) in names.iter().enumerate() {
            assert_eq!(name.is_empty(), !two.contains(&level), "scene {scene} level {level}");
        }
    }
    assert!(prepared.ground_truths.iter().flatten().all(|name| !name.is_empty()));
    assert!(startup_plan(&prepared.study, &plan).stimuli().count() < plan.stimuli().count());
}

#[tokio::test]
async fn a_missing_level_is_rendered_once_for_two_participants_who_need_it() {
    let store = tempfile::tempdir().unwrap();
    let (prepared, plan) = prepared(store.path());
    let missing = prepared.stimuli[0].iter().position(String::is_empty).unwrap();
    let (queue, open, rendered) = gated(store.path(), 4);
    queue.register(prepared.clone(), plan.clone());
    let slug = prepared.study.slug.clone();
    let ask = |queue: RenderQueue, slug: String| async move {
        queue.stimulus(&slug, 0, 0, missing, Duration::from_secs(30)).await
    };
    let first = tokio::spawn(ask(queue.clone(), slug.clone()));
    let second = tokio::spawn(ask(queue.clone(), slug.clone()));
    // both are waiting on one render
    while queue.position(&plan.scenes[0].as_ref().unwrap().stimuli[missing].key).is_none() {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    tokio::time::sleep(Duration::from_millis(50)).await;
    let jobs = {
        let state = queue.lock();
        state.waiting.len() + usize::from(state.current.is_some())
    };
    assert_eq!(jobs, 1, "{}", queue.summary());
    open.send(()).unwrap();
    let (first, second) = (first.await.unwrap().unwrap(), second.await.unwrap().unwrap());
    assert_eq!(first, second);
    assert_eq!(rendered.recv().unwrap(), missing);
    assert!(rendered.try_recv().is_err(), "one render for both");
    assert_eq!(queue.rendered(), 1);
    // now in the store: at once, no render
    assert_eq!(queue.stimulus(&slug, 0, 0, missing, Duration::ZERO).await.unwrap(), first);
    assert_eq!(queue.rendered(), 1);
    assert!(queue.summary().contains("1 rendered"), "{}", queue.summary());
}

#[tokio::test]
async fn a_full_queue_refuses_a_level_and_does_not_grow() {
    let store = tempfile::tempdir().unwrap();
    let (prepared, plan) = prepared(store.path());
    let (queue, open, _rendered) = gated(store.path(), 2);
    queue.register(prepared.clone(), plan);
    let slug = &prepared.study.slug;
    let missing: Vec<(usize, usize)> = (0..2)
        .flat_map(|scene| prepared.stimuli[scene].iter().enumerate().map(move |(level, name)| (scene, level, name)))
        .filter(|(_, _, name)| name.is_empty())
        .map(|(scene, level, _)| (scene, level))
        .collect();
    assert!(missing.len() >= 5, "{missing:?}");
    // the first goes to the worker (held at the gate), two wait: the queue is full
    let mut outcomes = Vec::new();
    for &(scene, level) in &missing[..3] {
        outcomes.push(queue.stimulus(slug, scene, 0, level, Duration::from_millis(20)).await);
        // the worker takes the first before the next is queued
        while queue.lock().current.is_none() {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    }
    assert!(outcomes.iter().all(|outcome| matches!(outcome, Err(Unready::Rendering { .. }))), "{outcomes:?}");
    let (scene, level) = missing[3];
    let refused = queue.stimulus(slug, scene, 0, level, Duration::from_millis(20)).await;
    assert!(matches!(refused, Err(Unready::Full { capacity: 2, .. })), "{refused:?}");
    assert!(refused.unwrap_err().retry_after_seconds().is_some());
    assert_eq!(queue.lock().waiting.len(), 2, "nothing was queued beyond the bound");
    assert_eq!(queue.refused(), 1);
    // asking again for a queued level is no new job
    let (scene, level) = missing[2];
    let again = queue.stimulus(slug, scene, 0, level, Duration::from_millis(20)).await;
    assert!(matches!(again, Err(Unready::Rendering { .. })), "{again:?}");
    assert_eq!(queue.refused(), 1);
    drop(open);
}

/// The levels with a stimulus record in `csv` (its `render_ms` rows, which the fake sets to the
/// level's index), per scene configuration name.
fn levels_in(csv: &str) -> Vec<(String, usize)> {
    csv.lines()
        .skip(1)
        .filter(|line| line.contains(",render_ms,"))
        .map(|line| {
            let fields: Vec<&str> = line.split(',').collect();
            (fields[1].to_string(), fields[5].parse::<f64>().unwrap() as usize)
        })
        .collect()
}

#[tokio::test]
async fn a_participants_request_goes_before_levels_queued_ahead_of_need() {
    let store = tempfile::tempdir().unwrap();
    let (prepared, plan) = prepared(store.path());
    let (queue, open, rendered) = gated(store.path(), 8);
    queue.register(prepared.clone(), plan);
    let slug = &prepared.study.slug;
    let missing: Vec<usize> =
        prepared.stimuli[0].iter().enumerate().filter(|(_, n)| n.is_empty()).map(|(l, _)| l).collect();
    assert!(missing.len() >= 4, "{missing:?}");
    // the first prefetch goes to the worker (held at the gate), two more wait
    assert!(queue.prefetch(slug, 0, 0, missing[0]));
    while queue.lock().current.is_none() {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    assert!(queue.prefetch(slug, 0, 0, missing[1]));
    assert!(queue.prefetch(slug, 0, 0, missing[2]));
    assert!(!queue.prefetch(slug, 0, 0, missing[2]), "a level queued already is not queued again");
    // a participant's level goes before the waiting prefetches; one already prefetched is lifted
    let asked = queue.stimulus(slug, 0, 0, missing[3], Duration::from_millis(10)).await;
    assert!(matches!(asked, Err(Unready::Rendering { position: 1, .. })), "{asked:?}");
    let lifted = queue.stimulus(slug, 0, 0, missing[2], Duration::from_millis(10)).await;
    assert!(matches!(lifted, Err(Unready::Rendering { position: 2, .. })), "{lifted:?}");
    let order: Vec<(usize, bool)> = queue.lock().waiting.iter().map(|job| (job.condition, job.prefetch)).collect();
    assert_eq!(order, [(missing[3], false), (missing[2], false), (missing[1], true)]);
    for _ in 0..4 {
        open.send(()).unwrap();
    }
    let done: Vec<usize> = (0..4).map(|_| rendered.recv().unwrap()).collect();
    assert_eq!(done, [missing[0], missing[3], missing[2], missing[1]]);
    // rendered now: nothing to prefetch
    assert!(!queue.prefetch(slug, 0, 0, missing[1]));
    assert!(queue.summary().contains("3 queued ahead of need"), "{}", queue.summary());
    assert_eq!(queue.refused(), 0);
}

#[tokio::test]
async fn prefetching_leaves_half_the_queue_to_participants() {
    let store = tempfile::tempdir().unwrap();
    let (prepared, plan) = prepared(store.path());
    let (queue, open, _rendered) = gated(store.path(), 4);
    queue.register(prepared.clone(), plan);
    let slug = &prepared.study.slug;
    let missing: Vec<(usize, usize)> = (0..2)
        .flat_map(|scene| prepared.stimuli[scene].iter().enumerate().map(move |(level, name)| (scene, level, name)))
        .filter(|(_, _, name)| name.is_empty())
        .map(|(scene, level, _)| (scene, level))
        .collect();
    let queued: Vec<bool> = missing[..4].iter().map(|&(scene, level)| queue.prefetch(slug, scene, 0, level)).collect();
    // the worker may or may not have taken the first yet: two wait at most
    assert!(queue.lock().waiting.len() <= 2, "{}", queue.summary());
    assert!(!queued[3], "{queued:?}");
    assert_eq!(queue.refused(), 0, "a prefetch is never a refusal");
    drop(open);
}

#[tokio::test]
async fn the_stimulus_metrics_gain_each_level_rendered_on_demand() {
    let store = tempfile::tempdir().unwrap();
    let (prepared, plan) = prepared(store.path());
    let (queue, open, _rendered) = gated(store.path(), 4);
    queue.register(prepared.clone(), plan);
    let slug = &prepared.study.slug;
    let before = levels_in(queue.metrics(slug).unwrap().csv.as_deref().unwrap());
    let expected: Vec<(String, usize)> = prepared
        .stimuli
        .iter()
        .enumerate()
        .flat_map(|(scene, names)| {
            let scene = prepared.study.scenes[scene].name.clone();
            names.iter().enumerate().filter(|(_, name)| !name.is_empty()).map(move |(level, _)| (scene.clone(), level))
        })
        .collect();
    assert_eq!(before, expected, "the levels rendered at start-up");
    let missing = prepared.stimuli[1].iter().position(String::is_empty).unwrap();
    open.send(()).unwrap();
    queue.stimulus(slug, 1, 0, missing, Duration::from_secs(30)).await.unwrap();
    let after = levels_in(queue.metrics(slug).unwrap().csv.as_deref().unwrap());
    assert_eq!(after.len(), before.len() + 1);
    assert!(after.contains(&(prepared.study.scenes[1].name.clone(), missing)), "{after:?}");
    assert!(queue.metrics("no-such-study").is_none());
}
