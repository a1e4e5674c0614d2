//! Trial schedules: which pair, which side, which scene configurations, in which order.
//!
//! A schedule is a pure function of the study definition and one 64-bit participant seed, so
//! storing the seed (the server also stores the whole schedule) is enough to reproduce it. The
//! random stream is ChaCha8 seeded with `seed_from_u64` (its output is fixed by the rand_chacha
//! crate's reproducibility guarantee), and the shuffles and draws below are written out here
//! rather than taken from `rand`, whose algorithms may change between versions.
//!
//! - every condition pair is shown `repetitions` times; within each pair the two conditions
//!   are on the left equally often (for an odd count the extra one goes to a random side);
//! - scene configurations are drawn uniformly per trial, two different ones for
//!   `scenes = "different"` (so the two images are never directly comparable), one for `same`;
//! - catch trials are balanced left/right the same way;
//! - the order of all trials is a uniform random permutation.
//!
//! A detection design (`reference = "ground-truth"`, "real or rendered?") is scheduled so that
//! remembering pictures cannot tell the answer ([`plan_detection`], schedule version 2): the
//! ground truth is on the left in half of the participant's trials; each scene configuration
//! is shown equally often (the counts differ by at most one); each scene configuration's
//! trials take its sensor-noise realisations ([`crate::study::Design::realisations`]) in a
//! random order, each once before any twice, so with at least as many realisations as trials
//! per scene configuration no ground-truth picture is ever shown twice; and no scene
//! configuration comes twice in a row (where the counts allow it), so neither does a
//! ground-truth picture. Catch trials are inserted at random places afterwards.
//! [`plan_detection_v1`] keeps version 1 (scene configurations drawn per trial, any order),
//! so stored version-1 schedules can be reproduced and the two designs compared
//! (`crate::simulate::familiarity`).
//!
//! An active design (`pairs = "active"`) plans its warm-up and catch trials this way at join;
//! the rest come in batches from [`active_batch`], chosen from every judgment so far.

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};

use crate::study::{SceneDraw, Study};
// Where the schedule's trials are defined; named here too, as the schedule's output, for the
// designs built on it (simulate, threshold).
pub use crate::trial::{PlannedKind, PlannedTrial};

pub use mrstudy_analysis::active::{ActiveError, Posterior, SideBalance};

/// Version of the scheduling algorithm, stored with each participant. Version 2 changed the
/// detection designs only ([`plan_detection`]); other designs are scheduled as in version 1.
pub const SCHEDULE_VERSION: i64 = 2;

/// The schedules' random stream: ChaCha8 from one seed, with the draws written out here.
pub(crate) struct Stream(ChaCha8Rng);

impl Stream {
    /// The stream of `seed` (`crate::rating` plans its trials from it too).
    pub(crate) fn seeded(seed: u64) -> Stream {
        Stream(ChaCha8Rng::seed_from_u64(seed))
    }

    pub(crate) fn below(&mut self, bound: usize) -> usize {
        // Lemire's nearly divisionless method, with rejection: uniform on 0..bound.
        let bound = bound as u64;
        assert!(bound > 0);
        loop {
            let product = (self.0.next_u64() as u128) * (bound as u128);
            let low = product as u64;
            if low >= bound.wrapping_neg() % bound {
                return (product >> 64) as usize;
            }
        }
    }

    fn coin(&mut self) -> bool {
        self.0.next_u64() >> 63 == 1
    }

    pub(crate) fn shuffle<T>(&mut self, items: &mut [T]) {
        for index in (1..items.len()).rev() {
            let other = self.below(index + 1);
            items.swap(index, other);
        }
    }

    /// `count` booleans, half of them true (the odd one to a random side), in random order.
    fn balanced_sides(&mut self, count: usize) -> Vec<bool> {
        let mut first_left = count / 2;
        if count % 2 == 1 && self.coin() {
            first_left += 1;
        }
        let mut sides: Vec<bool> = (0..count).map(|index| index < first_left).collect();
        self.shuffle(&mut sides);
        sides
    }

    fn scenes(&mut self, draw: SceneDraw, scene_count: usize) -> (usize, usize) {
        match draw {
            SceneDraw::Same => {
                let scene = self.below(scene_count);
                (scene, scene)
            }
            SceneDraw::Different => {
                let left = self.below(scene_count);
                let mut right = self.below(scene_count - 1);
                if right >= left {
                    right += 1;
                }
                (left, right)
            }
        }
    }
}

/// The schedule of one participant.
pub fn plan(study: &Study, seed: u64) -> Vec<PlannedTrial> {
    if study.threshold.is_some() {
        // a threshold study plans nothing at join: each trial is chosen when it is reached
        // (`crate::threshold`)
        return Vec::new();
    }
    if study.design.reference.is_some() {
        return plan_detection(study, seed);
    }
    let mut stream = Stream(ChaCha8Rng::seed_from_u64(seed));
    let repetitions = study.design.repetitions as usize;
    let mut trials = Vec::with_capacity(study.trial_count());
    for &(first, second) in &study.design.pairs {
        for first_left in stream.balanced_sides(repetitions) {
            trials.push(pair_trial(study, &mut stream, (first, second), first_left));
        }
    }
    push_catch_trials(study, &mut stream, &mut trials);
    stream.shuffle(&mut trials);
    trials
}

/// A trial of the condition pair `(first, second)`, `first` on the left when `first_left`, its
/// scene configurations drawn from `stream` (realisation 0).
fn pair_trial(study: &Study, stream: &mut Stream, (first, second): (usize, usize), first_left: bool) -> PlannedTrial {
    let (left, right) = if first_left { (first, second) } else { (second, first) };
    let (left_scene, right_scene) = stream.scenes(study.design.scenes, study.scenes.len());
    PlannedTrial { kind: PlannedKind::Pair { left, right }, left_scene, right_scene, realisation: 0 }
}

fn push_catch_trials(study: &Study, stream: &mut Stream, trials: &mut Vec<PlannedTrial>) {
    for (index, catch) in study.catch.iter().enumerate() {
        for better_left in stream.balanced_sides(catch.repetitions as usize) {
            trials.push(PlannedTrial {
                kind: PlannedKind::Catch { index, better_left },
                left_scene: 0,
                right_scene: 0,
                realisation: 0,
            });
        }
    }
}

/// The schedule of one participant of a detection design, version 2 (see the module header):
/// sides balanced over all the participant's trials, scene configurations balanced (each
/// `n / S` or one more times), realisations of each scene configuration each used once before
/// any is used again, no scene configuration twice in a row where the counts allow it, catch
/// trials inserted at random places.
pub fn plan_detection(study: &Study, seed: u64) -> Vec<PlannedTrial> {
    let mut stream = Stream(ChaCha8Rng::seed_from_u64(seed));
    let scene_count = study.scenes.len().max(1);
    let realisations = (study.design.realisations as usize).max(1);
    let repetitions = study.design.repetitions as usize;
    let count = study.design.pairs.len() * repetitions;
    let mut sides = stream.balanced_sides(count).into_iter();
    let mut trials = Vec::with_capacity(study.trial_count());
    for &(condition, truth) in &study.design.pairs {
        for truth_left in sides.by_ref().take(repetitions) {
            let (left, right) = if truth_left { (truth, condition) } else { (condition, truth) };
            trials.push(PlannedTrial {
                kind: PlannedKind::Pair { left, right },
                left_scene: 0,
                right_scene: 0,
                realisation: 0,
            });
        }
    }
    // scene configurations: whole rounds of every scene configuration in random order, the last
    // round cut short, dealt to the trials in random order
    stream.shuffle(&mut trials);
    let mut scenes = Vec::with_capacity(count);
    while scenes.len() < count {
        let mut round: Vec<usize> = (0..scene_count).collect();
        stream.shuffle(&mut round);
        scenes.extend(round.into_iter().take(count - scenes.len()));
    }
    // realisations: per scene configuration, rounds of every realisation in random order
    let mut rounds: Vec<Vec<usize>> = vec![Vec::new(); scene_count];
    for (trial, &scene) in trials.iter_mut().zip(&scenes) {
        if rounds[scene].is_empty() {
            let mut round: Vec<usize> = (0..realisations).collect();
            stream.shuffle(&mut round);
            round.reverse(); // popped from the back
            rounds[scene] = round;
        }
        trial.left_scene = scene;
        trial.right_scene = scene;
        trial.realisation = rounds[scene].pop().expect("a round is never empty");
    }
    let mut ordered = order_without_repeats(&mut stream, trials, scene_count);
    let mut catch = Vec::new();
    push_catch_trials(study, &mut stream, &mut catch);
    for trial in catch {
        let at = stream.below(ordered.len() + 1);
        ordered.insert(at, trial);
    }
    ordered
}

/// `trials` in a random order in which no two neighbours show the same scene configuration:
/// each next trial is drawn uniformly from those whose scene configuration differs from the
/// previous one's and leaves the rest arrangeable (no scene configuration holding more than
/// half, rounded up, of what is left). Where no arrangement exists (one scene configuration
/// has more than half the trials) a repeat is allowed when nothing else is left.
fn order_without_repeats(stream: &mut Stream, mut trials: Vec<PlannedTrial>, scene_count: usize) -> Vec<PlannedTrial> {
    let mut counts = vec![0usize; scene_count];
    for trial in &trials {
        counts[trial.left_scene] += 1;
    }
    // Whether `counts` (after taking one of `taken`) can be ordered with no neighbours equal
    // and its first element not `taken`.
    let arrangeable = |counts: &[usize], taken: usize| {
        let total: usize = counts.iter().sum();
        let most = counts.iter().copied().max().unwrap_or(0);
        most <= total.div_ceil(2) && !(total % 2 == 1 && counts[taken] == total.div_ceil(2))
    };
    let mut ordered = Vec::with_capacity(trials.len());
    let mut previous: Option<usize> = None;
    while !trials.is_empty() {
        let candidates: Vec<usize> = (0..trials.len())
            .filter(|&index| {
                let scene = trials[index].left_scene;
                if Some(scene) == previous {
                    return false;
                }
                counts[scene] -= 1;
                let fits = arrangeable(&counts, scene);
                counts[scene] += 1;
                fits
            })
            .collect();
        let index = if candidates.is_empty() {
            // no order without a repeat exists: take one that differs if any, else any
            let differing: Vec<usize> =
                (0..trials.len()).filter(|&index| Some(trials[index].left_scene) != previous).collect();
            if differing.is_empty() { stream.below(trials.len()) } else { differing[stream.below(differing.len())] }
        } else {
            candidates[stream.below(candidates.len())]
        };
        let trial = trials.swap_remove(index);
        counts[trial.left_scene] -= 1;
        previous = Some(trial.left_scene);
        ordered.push(trial);
    }
    ordered
}

/// The schedule of a detection design as schedule version 1 made it: the ground truth on the
/// left in half of the trials, each trial's scene configuration drawn uniformly and
/// independently, realisation 0 only, the order a uniform random permutation. Kept to
/// reproduce version-1 schedules and as the baseline of `crate::simulate::familiarity`.
pub fn plan_detection_v1(study: &Study, seed: u64) -> Vec<PlannedTrial> {
    let mut stream = Stream(ChaCha8Rng::seed_from_u64(seed));
    let repetitions = study.design.repetitions as usize;
    let mut trials = Vec::with_capacity(study.trial_count());
    let count = study.design.pairs.len() * repetitions;
    let mut sides = stream.balanced_sides(count).into_iter();
    for &(condition, truth) in &study.design.pairs {
        for truth_left in sides.by_ref().take(repetitions) {
            trials.push(pair_trial(study, &mut stream, (truth, condition), truth_left));
        }
    }
    push_catch_trials(study, &mut stream, &mut trials);
    stream.shuffle(&mut trials);
    trials
}

/// A fresh posterior for the study's active design (`None` for a fixed design). With
/// `prior = "spread"` (target worths only) it scores its batches under the hierarchical prior on
/// the log-worths' spread by the plain EIG ([`Posterior::with_spread_prior`] with ρ = 1; the
/// study's `prior_sd` is the spread's prior mean) for the first [`SPREAD_SWITCH`] trials per
/// condition, then as the fixed prior's design ([`Posterior::with_spread_switch`]): the hybrid
/// measured in docs/simulate/README.md.
///
/// [`SPREAD_SWITCH`]: mrstudy_analysis::active::SPREAD_SWITCH
pub fn active_posterior(study: &Study) -> Option<Result<Posterior, ActiveError>> {
    let active = study.design.active.as_ref()?;
    let target = crate::study::active_target(active, &study.conditions);
    let posterior = Posterior::new(&target, mrstudy_analysis::active::Link::Logit, active.prior_sd);
    Some(match active.prior {
        crate::study::ActivePrior::Fixed => posterior,
        crate::study::ActivePrior::Spread => posterior
            .and_then(|p| p.with_mean_weight(1.0))
            .and_then(Posterior::with_spread_prior)
            .and_then(|p| p.with_spread_switch(mrstudy_analysis::active::SPREAD_SWITCH)),
    })
}

/// What one participant has been shown so far, as an active batch needs it: the last pair
/// (never repeated back to back), the left − right count of each condition, and how many
/// batches were chosen for them before.
#[derive(Debug, Clone)]
pub struct ActiveHistory {
    pub previous: Option<(usize, usize)>,
    pub sides: SideBalance,
    pub batches: u64,
}

impl ActiveHistory {
    /// The history of a participant shown `pairs` (left, right) so far, of which `batches`
    /// batches were chosen actively.
    pub fn of(conditions: usize, pairs: &[(usize, usize)], batches: u64) -> ActiveHistory {
        let mut sides = SideBalance::new(conditions);
        for &(left, right) in pairs {
            sides.record(left, right);
        }
        let previous = pairs.last().map(|&(left, right)| (left.min(right), left.max(right)));
        ActiveHistory { previous, sides, batches }
    }
}

/// The next `count` trials of a participant of an active design, chosen by `posterior` (every
/// judgment so far): pairs by [`Posterior::best_pairs`] with ties broken by the stream of
/// (participant seed, posterior state, batch number), sides balanced per participant, scene
/// configurations drawn by the study's rule from a stream of (participant seed, batch number).
/// The server and `mrstudy simulate` both schedule through here; the same posterior state,
/// seed and history give the same trials.
pub fn active_batch(
    study: &Study,
    posterior: &Posterior,
    seed: u64,
    history: &mut ActiveHistory,
    count: usize,
) -> Result<Vec<PlannedTrial>, ActiveError> {
    let mut ties = mrstudy_analysis::active::tie_stream(seed, posterior.state_id(), history.batches);
    let pairs = posterior.best_pairs(count, history.previous, &mut ties)?;
    let mut stream = Stream(ChaCha8Rng::seed_from_u64(derived_seed(seed, history.batches + 1)));
    history.batches += 1;
    let mut trials = Vec::with_capacity(pairs.len());
    for pair in pairs {
        let (left, right) = history.sides.assign(pair, &mut ties);
        let (left_scene, right_scene) = stream.scenes(study.design.scenes, study.scenes.len());
        trials.push(PlannedTrial { kind: PlannedKind::Pair { left, right }, left_scene, right_scene, realisation: 0 });
        history.previous = Some(pair);
    }
    Ok(trials)
}

/// The next `count` trials of an active design's participant when its posterior cannot be
/// used: pairs drawn uniformly from the fixed part of the design (its warm-up's pairs, or every
/// pair without one), never the previous pair back to back, sides balanced as in
/// [`active_batch`], scenes by the study's rule.
pub fn fallback_batch(study: &Study, seed: u64, history: &mut ActiveHistory, count: usize) -> Vec<PlannedTrial> {
    let n = study.conditions.len();
    let pairs: Vec<(usize, usize)> = if study.design.pairs.is_empty() {
        crate::study::survey::all_pairs(n)
    } else {
        study.design.pairs.iter().map(|&(a, b)| (a.min(b), a.max(b))).collect()
    };
    let key = derived_seed(seed ^ 0xFA11_BAC4, history.batches + 1);
    let mut stream = Stream(ChaCha8Rng::seed_from_u64(key));
    let mut sides = ChaCha8Rng::seed_from_u64(derived_seed(key, 1));
    history.batches += 1;
    let mut trials = Vec::with_capacity(count);
    for _ in 0..count {
        let mut pair = pairs[stream.below(pairs.len())];
        if pairs.len() > 1 {
            while Some(pair) == history.previous {
                pair = pairs[stream.below(pairs.len())];
            }
        }
        let (left, right) = history.sides.assign(pair, &mut sides);
        let (left_scene, right_scene) = stream.scenes(study.design.scenes, study.scenes.len());
        trials.push(PlannedTrial { kind: PlannedKind::Pair { left, right }, left_scene, right_scene, realisation: 0 });
        history.previous = Some(pair);
    }
    trials
}

/// The seed of participant number `ordinal` (0-based) of a study with a study seed: a
/// SplitMix64 step of their combination, so consecutive participants get unrelated streams.
pub fn derived_seed(study_seed: u64, ordinal: u64) -> u64 {
    let mut z = study_seed ^ ordinal.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::load_study;
    use std::collections::HashMap;

    fn thesis_study() -> Study {
        let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../studies/web-survey.toml");
        load_study(&file).unwrap()
    }

    #[test]
    fn a_detection_design_shows_each_condition_beside_its_own_scenes_ground_truth_sides_balanced() {
        let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../studies/real-or-rendered.toml");
        let study = load_study(&file).unwrap();
        let truth = study.conditions.len();
        for seed in 0..50 {
            let trials = plan(&study, seed);
            assert_eq!(trials.len(), 24);
            let mut shown = vec![0; truth];
            let mut truth_left = 0;
            for trial in &trials {
                let PlannedKind::Pair { left, right } = trial.kind else { panic!() };
                assert_eq!(trial.left_scene, trial.right_scene);
                assert!((left == truth) != (right == truth), "{left} {right}");
                truth_left += usize::from(left == truth);
                shown[left.min(right)] += 1;
            }
            assert_eq!(truth_left, 12, "the ground truth left in half of the trials");
            assert!(shown.iter().all(|&count| count == 3), "{shown:?}");
        }
    }

    fn real_or_rendered() -> Study {
        let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../studies/real-or-rendered.toml");
        load_study(&file).unwrap()
    }

    /// Per scene configuration, how often a participant's trials show it.
    fn scene_counts(study: &Study, trials: &[PlannedTrial]) -> Vec<usize> {
        let mut counts = vec![0; study.scenes.len()];
        for trial in trials.iter().filter(|trial| matches!(trial.kind, PlannedKind::Pair { .. })) {
            counts[trial.left_scene] += 1;
        }
        counts
    }

    #[test]
    fn a_detection_design_shows_every_scene_configuration_equally_often() {
        // version 1 drew scene configurations per trial: one participant saw survey-5 in 8 of 24
        let study = real_or_rendered();
        for seed in 0..500 {
            let counts = scene_counts(&study, &plan(&study, seed));
            assert!(counts.iter().all(|&count| count == 4), "seed {seed}: {counts:?}");
        }
        // 3 conditions x 3 over 6 scene configurations: counts 1 or 2 (within one)
        let mut fewer = study.clone();
        fewer.design.pairs.truncate(3);
        for seed in 0..200 {
            let counts = scene_counts(&fewer, &plan(&fewer, seed));
            let (low, high) = (counts.iter().min().unwrap(), counts.iter().max().unwrap());
            assert!(high - low <= 1 && counts.iter().sum::<usize>() == 9, "seed {seed}: {counts:?}");
        }
    }

    #[test]
    fn a_detection_design_never_shows_a_ground_truth_picture_twice_or_a_scene_twice_in_a_row() {
        let study = real_or_rendered();
        assert_eq!(study.design.realisations, 4);
        for seed in 0..500 {
            let trials = plan(&study, seed);
            let pictures: std::collections::BTreeSet<(usize, usize)> =
                trials.iter().map(|trial| (trial.left_scene, trial.realisation)).collect();
            assert_eq!(pictures.len(), 24, "seed {seed}: a ground-truth picture shown twice");
            assert!(trials.iter().all(|trial| trial.realisation < 4));
            assert!(
                trials.windows(2).all(|pair| pair[0].left_scene != pair[1].right_scene),
                "seed {seed}: a scene configuration twice in a row"
            );
        }
        // with fewer realisations than showings, each realisation is used once before any twice
        let mut two = study.clone();
        two.design.realisations = 2;
        for seed in 0..100 {
            let trials = plan(&two, seed);
            for scene in 0..6 {
                let used: Vec<usize> = trials.iter().filter(|t| t.left_scene == scene).map(|t| t.realisation).collect();
                assert_eq!(used.iter().filter(|&&r| r == 0).count(), 2, "seed {seed}: {used:?}");
            }
        }
    }

    #[test]
    fn a_detection_design_with_one_scene_configuration_still_gets_every_trial() {
        let mut study = real_or_rendered();
        study.scenes.truncate(1);
        let trials = plan(&study, 5);
        assert_eq!(trials.len(), 24);
        assert!(trials.iter().all(|trial| trial.left_scene == 0 && trial.right_scene == 0));
    }

    #[test]
    fn version_1_of_a_detection_schedule_is_kept() {
        // Pinned output of plan_detection_v1 for seed 1 (what version-1 participants were shown):
        // left | right (8: the ground truth) | scene configuration
        let mut study = real_or_rendered();
        study.design.realisations = 1;
        let first: Vec<String> = plan_detection_v1(&study, 1)
            .iter()
            .take(3)
            .map(|trial| match trial.kind {
                PlannedKind::Pair { left, right } => format!("{left}|{right}|{}", trial.left_scene),
                PlannedKind::Catch { .. } => "catch".into(),
            })
            .collect();
        assert_eq!(first, ["8|4|1", "8|7|2", "8|1|3"]);
    }

    #[test]
    fn thesis_design_has_13_pairs_times_5() {
        let study = thesis_study();
        assert_eq!(study.design.pairs.len(), 13);
        let trials = plan(&study, 42);
        assert_eq!(trials.len(), 65);
        let mut per_pair: HashMap<(usize, usize), (usize, usize)> = HashMap::new();
        for trial in &trials {
            let PlannedKind::Pair { left, right } = trial.kind else { panic!() };
            assert_ne!(trial.left_scene, trial.right_scene, "scenes = different");
            let key = (left.min(right), left.max(right));
            let entry = per_pair.entry(key).or_default();
            if left < right { entry.0 += 1 } else { entry.1 += 1 }
        }
        assert_eq!(per_pair.len(), 13);
        for (lower_left, higher_left) in per_pair.values() {
            assert_eq!(lower_left + higher_left, 5);
            assert!(lower_left.abs_diff(*higher_left) == 1, "left/right balanced within a pair");
        }
    }

    #[test]
    fn the_fallback_of_an_active_design_draws_its_fixed_pairs_without_back_to_back_repeats() {
        let study = thesis_study(); // its 13 anchored pairs stand in for an active design's warm-up
        let mut history = ActiveHistory::of(study.conditions.len(), &[], 0);
        let mut trials = Vec::new();
        for _ in 0..20 {
            trials.extend(fallback_batch(&study, 99, &mut history, 5));
        }
        assert_eq!((trials.len(), history.batches), (100, 20));
        let pairs: Vec<(usize, usize)> = trials
            .iter()
            .map(|trial| match trial.kind {
                PlannedKind::Pair { left, right } => (left.min(right), left.max(right)),
                PlannedKind::Catch { .. } => panic!("the fallback draws pairs only"),
            })
            .collect();
        assert!(pairs.iter().all(|pair| study.design.pairs.iter().any(|&(a, b)| (a.min(b), a.max(b)) == *pair)));
        assert!(pairs.windows(2).all(|window| window[0] != window[1]), "a pair twice in a row");
        assert!(history.sides.left_minus_right.iter().all(|count| count.abs() <= 3), "{:?}", history.sides);
        // the same seed and history give the same trials
        let mut again = ActiveHistory::of(study.conditions.len(), &[], 0);
        let first: Vec<PlannedTrial> = (0..20).flat_map(|_| fallback_batch(&study, 99, &mut again, 5)).collect();
        assert_eq!(first, trials);
    }

    #[test]
    fn same_seed_same_schedule_other_seed_other_order() {
        let study = thesis_study();
        assert_eq!(plan(&study, 7), plan(&study, 7));
        assert_ne!(plan(&study, 7), plan(&study, 8));
    }

    #[test]
    fn schedule_of_a_seed_is_stable_across_versions() {
        // Pinned output of SCHEDULE_VERSION 1 for seed 1: if this changes, stored seeds no
        // longer reproduce stored schedules; bump SCHEDULE_VERSION and keep the old algorithm.
        let study = thesis_study();
        let first: Vec<String> = plan(&study, 1)
            .iter()
            .take(3)
            .map(|trial| match trial.kind {
                PlannedKind::Pair { left, right } => format!(
                    "{}|{}|{}|{}",
                    study.conditions[left].name, study.conditions[right].name, trial.left_scene, trial.right_scene
                ),
                PlannedKind::Catch { .. } => "catch".into(),
            })
            .collect();
        assert_eq!(first, PINNED_SEED_1);
    }

    const PINNED_SEED_1: [&str; 3] = ["LQ|CA|4|2", "HQ|GI+CM|3|2", "LQ|GI+CM|1|3"];
}
