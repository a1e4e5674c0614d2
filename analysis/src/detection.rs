//! Detection: "real or rendered?". In a detection study one side of each paired comparison is
//! the reserved condition [`GROUND_TRUTH`] (the path-traced composite of the same scene
//! configuration) and the other a rendered condition; `chosen` is the image the participant
//! took to be real. A condition's *detection rate* is the fraction of its trials in which the
//! participant chose the ground truth; chance is 0.5.
//!
//! Per condition: the rate with its Clopper–Pearson interval ([`clopper_pearson`]), the exact
//! two-sided binomial test against 0.5 as R's `binom.test` computes it ([`binomial_test`]),
//! d′ for two-alternative forced choice with its delta-method standard error ([`d_prime_2afc`])
//! and the exact power of the test at the condition's own number of trials to detect a true
//! rate of [`ALTERNATIVE_RATE`] ([`binomial_test_power`]). From these a [`Verdict`]: a condition
//! whose test is not significant at [`ALPHA`] although its power is at least [`TARGET_POWER`]
//! is *indistinguishable from the real scene at the study's power*; a significant one is
//! *distinguishable*; any other is *inconclusive*, with its power said.
//!
//! Per scene configuration (where the trials name theirs, `scene_left`/`scene_right`): the rate
//! over all the configuration's detection trials with its interval and test, and its trials
//! and rate per condition ([`SceneDetection`]). A configuration whose rate is far from the others'
//! points at its scene (a lamp that lights nothing, a visible artefact), or at a design in which
//! its ground truth could be learnt; the analysis only reports it.
//!
//! Binomial tails are summed relative to their largest term and carried as logarithms, over
//! the terms that matter (never the whole support for huge counts), so p-values do not
//! underflow and no number is ever NaN or infinite.

use serde::Serialize;
use statrs::distribution::{Continuous, ContinuousCDF, Normal};
use statrs::function::beta::beta_reg;
use statrs::function::factorial::ln_binomial;

pub use crate::data::GROUND_TRUTH;
use crate::data::{Judgment, Judgments, LeftOut, ParsedTrials, TrialScenes};
use crate::pvalue::{P_FLOOR, PValue};

/// Significance level of the binomial test, and of the power computed for it.
pub const ALPHA: f64 = 0.05;
/// The true detection rate the power is computed against: participants who tell the rendering
/// from the real scene three times in four.
pub const ALTERNATIVE_RATE: f64 = 0.75;
/// The power at or above which a non-significant condition counts as indistinguishable.
pub const TARGET_POWER: f64 = 0.8;
/// Confidence level of the Clopper–Pearson interval.
pub const LEVEL: f64 = 0.95;
/// Chance: the rate of an observer who cannot tell the two images apart.
pub const CHANCE: f64 = 0.5;

/// R's tolerance in `binom.test`: outcomes whose probability is at most the observed one's
/// times this count as at least as extreme.
const RELATIVE_ERROR: f64 = 1.0 + 1e-7;

/// Options of [`analyze_detection`]; `Default` gives the documented constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectionOptions {
    /// Significance level of the test ([`ALPHA`]).
    pub alpha: f64,
    /// True rate the power is computed against ([`ALTERNATIVE_RATE`]).
    pub alternative_rate: f64,
    /// Power needed to call a non-significant condition indistinguishable ([`TARGET_POWER`]).
    pub target_power: f64,
    /// Confidence level of the intervals ([`LEVEL`]).
    pub level: f64,
}

impl Default for DetectionOptions {
    fn default() -> Self {
        DetectionOptions { alpha: ALPHA, alternative_rate: ALTERNATIVE_RATE, target_power: TARGET_POWER, level: LEVEL }
    }
}

/// What the test says about a condition.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Verdict {
    /// Not significant, and the test had at least the target power: people could not tell it
    /// from the real scene, at the study's power.
    Indistinguishable,
    /// Significant: the rate differs from chance (in either direction).
    Distinguishable,
    /// Not significant, but the test had too little power to say it is indistinguishable.
    Inconclusive,
}

impl Verdict {
    /// The verdict in words; an inconclusive one with its power, `inconclusive (power 0.42)`.
    pub fn describe(self, power: f64) -> String {
        match self {
            Verdict::Indistinguishable => "indistinguishable".to_string(),
            Verdict::Distinguishable => "distinguishable".to_string(),
            Verdict::Inconclusive => format!("inconclusive (power {:.2})", power.clamp(0.0, 1.0)),
        }
    }
}

/// One rendered condition against the ground truth.
#[derive(Debug, Clone, Serialize)]
pub struct DetectionRate {
    pub condition: String,
    /// Trials of this condition against the ground truth.
    pub trials: u64,
    /// Trials in which the ground truth was chosen as real.
    pub correct: u64,
    /// `correct / trials`.
    pub rate: f64,
    /// Clopper–Pearson interval of the rate at `level`.
    pub ci: [f64; 2],
    /// Exact two-sided binomial test of rate = 0.5 (R's `binom.test`): `p`, `log10_p`.
    #[serde(flatten)]
    pub p: PValue,
    /// d′ = √2·Φ⁻¹(pc) for two-alternative forced choice.
    pub d_prime: f64,
    /// Delta-method standard error of d′: √2·√(pc(1−pc)/n) / φ(Φ⁻¹(pc)).
    pub d_prime_se: f64,
    /// Exact power of the test at `alpha` with this condition's trials against a true rate of
    /// `alternative_rate`.
    pub power: f64,
    pub verdict: Verdict,
    /// Corrections made and readings worth saying (pc of 0 or 1, a rate below chance).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
}

/// The detection analysis of the trials with [`GROUND_TRUTH`] on one side.
#[derive(Debug, Clone, Serialize)]
pub struct Detection {
    pub judgments: u64,
    pub participants: usize,
    /// The chance rate the test is against (0.5).
    pub chance: f64,
    pub alpha: f64,
    pub alternative_rate: f64,
    pub target_power: f64,
    /// Confidence level of the intervals.
    pub level: f64,
    /// One entry per rendered condition, in the order of the data's conditions.
    pub conditions: Vec<DetectionRate>,
    /// One entry per scene configuration, in order of first appearance, where the trials name
    /// their scene configurations; absent otherwise.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub scenes: Vec<SceneDetection>,
    /// The rate by showing: over the trials that showed a participant a scene configuration
    /// for the first, second, … time (in the order of the file's rows, which the export writes
    /// in each participant's trial order). Where no memory helps, the rate does not change with
    /// the showing; a rising rate is learning (of the pictures, or of realism). Present with
    /// `scenes`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub showings: Vec<ShowingDetection>,
    /// Participants left out before the analysis (pilots, excluded), where there is no
    /// preference analysis to carry them; absent when none were.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub left_out: Option<LeftOut>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// The detection trials of one scene configuration.
#[derive(Debug, Clone, Serialize)]
pub struct SceneDetection {
    pub scene: String,
    /// Detection trials of this scene configuration, all conditions together.
    pub trials: u64,
    /// Of them, the trials in which the ground truth was chosen as real.
    pub correct: u64,
    pub rate: f64,
    /// Clopper–Pearson interval of the rate at the analysis's level.
    pub ci: [f64; 2],
    /// Exact two-sided binomial test of rate = 0.5.
    #[serde(flatten)]
    pub p: PValue,
    /// The configuration's trials per rendered condition, in the order of the data's
    /// conditions (conditions it never showed left out).
    pub conditions: Vec<SceneConditionCount>,
}

/// The detection trials that showed their participant a scene configuration for the
/// `showing`-th time.
#[derive(Debug, Clone, Serialize)]
pub struct ShowingDetection {
    /// 1 for a participant's first trial of a scene configuration, 2 for the second, ….
    pub showing: u64,
    pub trials: u64,
    pub correct: u64,
    pub rate: f64,
    pub ci: [f64; 2],
    #[serde(flatten)]
    pub p: PValue,
}

/// One condition's detection trials in one scene configuration.
#[derive(Debug, Clone, Serialize)]
pub struct SceneConditionCount {
    pub condition: String,
    pub trials: u64,
    pub correct: u64,
    pub rate: f64,
}

/// A trials data set split by the reserved condition: preference trials (no side is the ground
/// truth) and detection trials (one side is).
#[derive(Debug, Clone)]
pub struct Split {
    /// The preference trials with their scenes (where read); `None` when every trial is a
    /// detection trial.
    pub preference: Option<(Judgments, Option<TrialScenes>)>,
    /// The detection trials, conditions indexed as in the whole data set; `None` when there
    /// are none.
    pub detection: Option<Judgments>,
    /// The scene configurations of the detection trials (`rows[k]` belongs to the detection
    /// trials' row k), where the trials were read with theirs.
    pub detection_scenes: Option<TrialScenes>,
}

/// Splits parsed trials into preference and detection trials. `n_table_conditions`: the number
/// of conditions of the conditions file the trials were indexed by, if any; the preference
/// trials keep exactly those conditions (the ground truth, indexed after them, goes). Without a
/// conditions file the preference trials keep the conditions they compare.
pub fn split(parsed: ParsedTrials, n_table_conditions: Option<usize>) -> Split {
    let ParsedTrials { judgments, scenes, .. } = parsed;
    let Some(ground_truth) = judgments.conditions.iter().position(|c| c == GROUND_TRUTH) else {
        return Split { preference: Some((judgments, scenes)), detection: None, detection_scenes: None };
    };
    let is_detection = |row: &Judgment| row.left as usize == ground_truth || row.right as usize == ground_truth;
    let detection_rows: Vec<Judgment> = judgments.rows.iter().filter(|row| is_detection(row)).copied().collect();
    if detection_rows.is_empty() {
        return Split { preference: Some((judgments, scenes)), detection: None, detection_scenes: None };
    }
    let detection_scenes = scenes.as_ref().map(|all| TrialScenes {
        names: all.names.clone(),
        rows: judgments.rows.iter().zip(&all.rows).filter(|(row, _)| is_detection(row)).map(|(_, s)| *s).collect(),
    });
    let detection = Some(judgments.subset(detection_rows, |_| true));
    let mut used = vec![false; judgments.conditions.len()];
    let mut preference_rows = Vec::new();
    let mut preference_scenes = scenes.as_ref().map(|s| TrialScenes { names: s.names.clone(), rows: Vec::new() });
    for (k, row) in judgments.rows.iter().enumerate() {
        if is_detection(row) {
            continue;
        }
        used[row.left as usize] = true;
        used[row.right as usize] = true;
        preference_rows.push(*row);
        if let (Some(kept), Some(all)) = (preference_scenes.as_mut(), scenes.as_ref()) {
            kept.rows.push(all.rows[k]);
        }
    }
    if preference_rows.is_empty() {
        return Split { preference: None, detection, detection_scenes };
    }
    let keep = |c: usize| match n_table_conditions {
        Some(n) => c < n,
        None => c != ground_truth && used[c],
    };
    let preference = judgments.subset(preference_rows, keep);
    Split { preference: Some((preference, preference_scenes)), detection, detection_scenes }
}

/// Detection rates, tests, d′ and verdicts per rendered condition, from judgments in which one
/// side of every row is [`GROUND_TRUTH`] (rows without it are ignored).
pub fn analyze_detection(judgments: &Judgments, options: &DetectionOptions) -> crate::Result<Detection> {
    analyze_detection_by_scene(judgments, None, options)
}

/// [`analyze_detection`], and with `scenes` (`rows[k]` the scene configurations of
/// `judgments.rows[k]`) the breakdown per scene configuration ([`Detection::scenes`]). A row whose
/// scene cell is empty counts in the conditions' rates but in no scene configuration's (a warning
/// says how many).
pub fn analyze_detection_by_scene(
    judgments: &Judgments,
    scenes: Option<&TrialScenes>,
    options: &DetectionOptions,
) -> crate::Result<Detection> {
    let mut detection = analyze_conditions(judgments, options)?;
    if let Some(scenes) = scenes.filter(|scenes| scenes.rows.len() == judgments.rows.len()) {
        let (rows, showings, unnamed) = scene_breakdown(judgments, scenes, options);
        detection.scenes = rows;
        detection.showings = showings;
        if unnamed > 0 {
            detection.warnings.push(format!(
                "{} without a scene configuration (empty `scene_left`/`scene_right`) {} in no scene configuration's rate",
                if unnamed == 1 { "1 detection trial".to_string() } else { format!("{unnamed} detection trials") },
                if unnamed == 1 { "counts" } else { "count" }
            ));
        }
    }
    Ok(detection)
}

/// The rows of [`Detection::scenes`] and [`Detection::showings`], and the number of detection
/// trials without a scene.
fn scene_breakdown(
    judgments: &Judgments,
    scenes: &TrialScenes,
    options: &DetectionOptions,
) -> (Vec<SceneDetection>, Vec<ShowingDetection>, u64) {
    let Some(ground_truth) = judgments.conditions.iter().position(|c| c == GROUND_TRUTH) else {
        return (Vec::new(), Vec::new(), 0);
    };
    let n = judgments.conditions.len();
    // [scene][condition] → (trials, correct)
    let mut counts = vec![vec![(0u64, 0u64); n]; scenes.names.len()];
    // (participant, scene) → trials shown so far; [showing − 1] → (trials, correct)
    let mut shown: std::collections::HashMap<(u32, u32), u64> = std::collections::HashMap::new();
    let mut by_showing: Vec<(u64, u64)> = Vec::new();
    let mut unnamed = 0;
    for (row, &[left_scene, right_scene]) in judgments.rows.iter().zip(&scenes.rows) {
        let (left, right) = (row.left as usize, row.right as usize);
        let (rendered, truth_chosen, scene) = if left == ground_truth {
            (right, row.left_chosen, left_scene)
        } else if right == ground_truth {
            (left, !row.left_chosen, right_scene)
        } else {
            continue;
        };
        if scene == TrialScenes::EMPTY || scene as usize >= counts.len() {
            unnamed += row.count;
            continue;
        }
        let cell = &mut counts[scene as usize][rendered];
        cell.0 += row.count;
        if truth_chosen {
            cell.1 += row.count;
        }
        // a row standing for `count` identical trials: showings first + 1 … first + count
        let first = shown.entry((row.participant, scene)).or_default();
        for showing in *first..*first + row.count {
            let showing = showing as usize;
            if by_showing.len() <= showing {
                by_showing.resize(showing + 1, (0, 0));
            }
            by_showing[showing].0 += 1;
            by_showing[showing].1 += u64::from(truth_chosen);
        }
        *first += row.count;
    }
    let showings = by_showing
        .iter()
        .enumerate()
        .map(|(index, &(trials, correct))| ShowingDetection {
            showing: index as u64 + 1,
            trials,
            correct,
            rate: correct as f64 / trials as f64,
            ci: clopper_pearson(correct, trials, options.level),
            p: binomial_test(correct, trials, CHANCE),
        })
        .collect();
    let rows = scenes
        .names
        .iter()
        .zip(&counts)
        .filter_map(|(name, cells)| {
            let trials: u64 = cells.iter().map(|cell| cell.0).sum();
            let correct: u64 = cells.iter().map(|cell| cell.1).sum();
            (trials > 0).then(|| SceneDetection {
                scene: name.clone(),
                trials,
                correct,
                rate: correct as f64 / trials as f64,
                ci: clopper_pearson(correct, trials, options.level),
                p: binomial_test(correct, trials, CHANCE),
                conditions: cells
                    .iter()
                    .enumerate()
                    .filter(|(_, cell)| cell.0 > 0)
                    .map(|(condition, &(trials, correct))| SceneConditionCount {
                        condition: judgments.conditions[condition].clone(),
                        trials,
                        correct,
                        rate: correct as f64 / trials as f64,
                    })
                    .collect(),
            })
        })
        .collect();
    (rows, showings, unnamed)
}

fn analyze_conditions(judgments: &Judgments, options: &DetectionOptions) -> crate::Result<Detection> {
    check_options(options)?;
    let ground_truth = judgments.conditions.iter().position(|c| c == GROUND_TRUTH);
    let n = judgments.conditions.len();
    let (mut trials, mut correct) = (vec![0u64; n], vec![0u64; n]);
    let mut participants = std::collections::BTreeSet::new();
    for row in &judgments.rows {
        let (left, right) = (row.left as usize, row.right as usize);
        let (rendered, ground_truth_chosen) = match ground_truth {
            Some(g) if left == g => (right, row.left_chosen),
            Some(g) if right == g => (left, !row.left_chosen),
            _ => continue,
        };
        participants.insert(row.participant);
        trials[rendered] += row.count;
        if ground_truth_chosen {
            correct[rendered] += row.count;
        }
    }
    let conditions: Vec<DetectionRate> = (0..n)
        .filter(|&c| trials[c] > 0)
        .map(|c| detection_rate(&judgments.conditions[c], correct[c], trials[c], options))
        .collect();
    if conditions.is_empty() {
        return Err(crate::AnalysisError::Empty(format!(
            "there are no detection trials (trials with `{GROUND_TRUTH}` on one side)"
        )));
    }
    Ok(Detection {
        judgments: trials.iter().sum(),
        participants: participants.len(),
        chance: CHANCE,
        alpha: options.alpha,
        alternative_rate: options.alternative_rate,
        target_power: options.target_power,
        level: options.level,
        conditions,
        scenes: Vec::new(),
        showings: Vec::new(),
        left_out: None,
        warnings: Vec::new(),
    })
}

fn check_options(options: &DetectionOptions) -> crate::Result<()> {
    let open_unit = |name: &str, value: f64| {
        if value > 0.0 && value < 1.0 {
            Ok(())
        } else {
            Err(crate::AnalysisError::BadOption {
                option: name.to_string(),
                message: format!("{value} is not between 0 and 1"),
            })
        }
    };
    open_unit("alpha", options.alpha)?;
    open_unit("alternative rate", options.alternative_rate)?;
    open_unit("target power", options.target_power)?;
    open_unit("level", options.level)
}

/// One condition's row: `correct` of `trials` trials chose the ground truth.
pub fn detection_rate(condition: &str, correct: u64, trials: u64, options: &DetectionOptions) -> DetectionRate {
    let rate = correct as f64 / trials as f64;
    let p = binomial_test(correct, trials, CHANCE);
    let power = binomial_test_power(trials, CHANCE, options.alpha, options.alternative_rate);
    let d_prime = d_prime_2afc(correct, trials);
    let mut notes = Vec::new();
    if let Some(corrected) = d_prime.corrected_pc {
        notes.push(format!(
            "{} trials chose the ground truth, so d′ uses pc = {} (the 1/(2n) correction of Macmillan & Kaplan 1985) instead of {}",
            if correct == 0 { "none of the" } else { "all" },
            compact(corrected),
            if correct == 0 { 0 } else { 1 }
        ));
    }
    let significant = p.p <= options.alpha;
    let verdict = if significant {
        Verdict::Distinguishable
    } else if power >= options.target_power {
        Verdict::Indistinguishable
    } else {
        Verdict::Inconclusive
    };
    if significant && rate < CHANCE {
        notes.push("the rendered image was taken for the real one more often than chance".to_string());
    }
    DetectionRate {
        condition: condition.to_string(),
        trials,
        correct,
        rate,
        ci: clopper_pearson(correct, trials, options.level),
        p,
        d_prime: d_prime.d_prime,
        d_prime_se: d_prime.se,
        power,
        verdict,
        notes,
    }
}

/// A probability in a note: up to six significant digits, no trailing zeros.
fn compact(value: f64) -> String {
    let text = format!("{value:.6}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// d′ of a two-alternative forced choice and its standard error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DPrime {
    /// √2·Φ⁻¹(pc).
    pub d_prime: f64,
    /// √2·√(pc(1−pc)/n) / φ(Φ⁻¹(pc)), by the delta method.
    pub se: f64,
    /// The proportion used instead of 0 or 1 (1/(2n), or 1 − 1/(2n)), where one was needed.
    pub corrected_pc: Option<f64>,
}

/// d′ for two-alternative forced choice from `correct` of `trials` (Macmillan & Creelman,
/// *Detection Theory*, eq. 7.3: d′ = √2·z(pc)). A proportion of 0 or 1, whose d′ would be
/// infinite, becomes 1/(2n) or 1 − 1/(2n) (Macmillan & Kaplan 1985), and says so in
/// `corrected_pc`. `trials` must be positive.
pub fn d_prime_2afc(correct: u64, trials: u64) -> DPrime {
    let n = trials.max(1) as f64;
    let (pc, corrected_pc) = if correct == 0 {
        (0.5 / n, Some(0.5 / n))
    } else if correct >= trials {
        (1.0 - 0.5 / n, Some(1.0 - 0.5 / n))
    } else {
        (correct as f64 / n, None)
    };
    let normal = Normal::standard();
    let z = normal.inverse_cdf(pc);
    let d_prime = std::f64::consts::SQRT_2 * z;
    let se = std::f64::consts::SQRT_2 * (pc * (1.0 - pc) / n).sqrt() / normal.pdf(z);
    DPrime { d_prime: d_prime + 0.0, se, corrected_pc }
}

/// The binomial distribution B(n, p), with probabilities in log space.
struct Binomial {
    n: u64,
    p: f64,
    ln_p: f64,
    ln_q: f64,
}

impl Binomial {
    fn new(n: u64, p: f64) -> Binomial {
        Binomial { n, p, ln_p: p.ln(), ln_q: (-p).ln_1p() }
    }

    fn ln_pmf(&self, k: u64) -> f64 {
        if k > self.n {
            return f64::NEG_INFINITY;
        }
        let (k_f, rest) = (k as f64, (self.n - k) as f64);
        // 0·ln 0 = 0 where p is 0 or 1.
        let term = |count: f64, ln: f64| if count == 0.0 { 0.0 } else { count * ln };
        ln_binomial(self.n, k) + term(k_f, self.ln_p) + term(rest, self.ln_q)
    }

    /// ln Σ of the probabilities from `start` on in the direction away from the mean (`down`:
    /// start, start − 1, …): relative to the first, each term is the last times the ratio of
    /// neighbouring probabilities, so the sum needs one logarithm, not one per term. Away from
    /// the mean the terms fall faster than geometrically; the sum stops where a term is below
    /// 10⁻¹⁷ of it.
    fn ln_tail_sum(&self, start: u64, down: bool) -> f64 {
        let ln_first = self.ln_pmf(start);
        if ln_first == f64::NEG_INFINITY {
            return ln_first;
        }
        let odds = self.p / (1.0 - self.p);
        let (n, mut k) = (self.n as f64, start as f64);
        let (mut term, mut sum) = (1.0f64, 1.0f64);
        loop {
            if down {
                if k == 0.0 {
                    break;
                }
                term *= k / ((n - k + 1.0) * odds);
                k -= 1.0;
            } else {
                if k == n {
                    break;
                }
                term *= (n - k) * odds / (k + 1.0);
                k += 1.0;
            }
            sum += term;
            if !(term >= 1e-17 * sum) {
                break;
            }
        }
        ln_first + sum.ln()
    }

    /// ln P(X ≤ a): summed down from `a` where `a` is below the mean, else as the complement of
    /// the upper tail.
    fn ln_cdf(&self, a: i64) -> f64 {
        if a < 0 {
            return f64::NEG_INFINITY;
        }
        let a = a as u64;
        if a >= self.n {
            return 0.0;
        }
        if (a as f64) < self.n as f64 * self.p {
            self.ln_tail_sum(a, true)
        } else {
            ln_one_minus_exp(self.ln_sf(a + 1))
        }
    }

    /// ln P(X ≥ b).
    fn ln_sf(&self, b: u64) -> f64 {
        if b == 0 {
            return 0.0;
        }
        if b > self.n {
            return f64::NEG_INFINITY;
        }
        if (b as f64) > self.n as f64 * self.p {
            self.ln_tail_sum(b, false)
        } else {
            ln_one_minus_exp(self.ln_cdf(b as i64 - 1))
        }
    }

    /// ln of the two-sided p-value of `x` as R's `binom.test`: the probability of every outcome
    /// no more likely than `x` (within R's relative tolerance).
    fn ln_two_sided(&self, x: u64) -> f64 {
        let (n, p) = (self.n, self.p);
        if p == 0.0 {
            return if x == 0 { 0.0 } else { f64::NEG_INFINITY };
        }
        if p == 1.0 {
            return if x == n { 0.0 } else { f64::NEG_INFINITY };
        }
        let m = n as f64 * p;
        let x_f = x as f64;
        if x_f == m {
            return 0.0;
        }
        let threshold = self.ln_pmf(x) + RELATIVE_ERROR.ln();
        let ln_p = if x_f < m {
            // The other tail: from ceil(m) on the probabilities fall; the first at or below the
            // threshold starts it.
            let (mut lo, mut hi) = (m.ceil() as u64, n + 1);
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if self.ln_pmf(mid) <= threshold { hi = mid } else { lo = mid + 1 }
            }
            log_add_exp(self.ln_cdf(x as i64), self.ln_sf(lo))
        } else {
            // Up to floor(m) the probabilities rise; the last at or below the threshold ends the
            // other tail.
            let (mut lo, mut hi) = (0i64, m.floor() as i64 + 1);
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if self.ln_pmf(mid as u64) <= threshold { lo = mid + 1 } else { hi = mid }
            }
            log_add_exp(self.ln_cdf(lo - 1), self.ln_sf(x))
        };
        ln_p.min(0.0)
    }
}

fn log_add_exp(a: f64, b: f64) -> f64 {
    let max = a.max(b);
    if max == f64::NEG_INFINITY { max } else { max + ((a - max).exp() + (b - max).exp()).ln() }
}

/// ln(1 − eᵃ) for a ≤ 0.
fn ln_one_minus_exp(a: f64) -> f64 {
    if a > -std::f64::consts::LN_2 { (-a.exp_m1()).ln() } else { (-a.exp()).ln_1p() }
}

/// The exact two-sided binomial test of `successes` in `trials` against probability `p0`, as R's
/// `binom.test(x, n, p0)$p.value`: the sum of the probabilities of all outcomes whose probability
/// is at most the observed one's × (1 + 10⁻⁷). A p-value below 10⁻³⁰⁰ is a bound with its exact
/// `log10_p`.
pub fn binomial_test(successes: u64, trials: u64, p0: f64) -> PValue {
    if trials == 0 {
        return PValue::new(1.0);
    }
    let ln_p = Binomial::new(trials, p0).ln_two_sided(successes.min(trials));
    if ln_p == f64::NEG_INFINITY {
        // Only where p0 is 0 or 1 and the outcome is impossible under it: p = 0, said as the
        // smallest bound there is.
        return PValue { p: P_FLOOR, log10_p: P_FLOOR.log10(), bound: Some(P_FLOOR) };
    }
    PValue::from_ln(ln_p)
}

/// The exact power of [`binomial_test`] at level `alpha` (reject where p ≤ α) with `trials`
/// trials against `p0`, when the true probability is `true_rate`. The rejection region is the
/// two tails of outcomes whose p-value is at most α (p-values rise towards the mode), found
/// by bisection.
pub fn binomial_test_power(trials: u64, p0: f64, alpha: f64, true_rate: f64) -> f64 {
    if trials == 0 {
        return 0.0;
    }
    let null = Binomial::new(trials, p0);
    let rejects = |x: u64| null.ln_two_sided(x) <= alpha.ln();
    let m = trials as f64 * p0;
    // Lower tail: the largest x ≤ floor(m) that rejects (p rises with x there).
    let (mut lo, mut hi) = (0i64, (m.floor() as i64).min(trials as i64) + 1);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if rejects(mid as u64) { lo = mid + 1 } else { hi = mid }
    }
    let lower_end = lo - 1;
    // Upper tail: the smallest x ≥ ceil(m) that rejects (p falls with x there).
    let (mut lo, mut hi) = ((m.ceil() as u64).min(trials + 1), trials + 1);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if rejects(mid) { hi = mid } else { lo = mid + 1 }
    }
    let upper_start = lo;
    let truth = Binomial::new(trials, true_rate);
    let power = truth.ln_cdf(lower_end).exp() + truth.ln_sf(upper_start).exp();
    power.clamp(0.0, 1.0)
}

/// The Clopper–Pearson ("exact") interval of a binomial proportion at confidence `level`, as R's
/// `binom.test(x, n)$conf.int`: the α/2 quantile of Beta(x, n − x + 1) and the 1 − α/2
/// quantile of Beta(x + 1, n − x), with 0 and 1 where x is 0 or n.
pub fn clopper_pearson(successes: u64, trials: u64, level: f64) -> [f64; 2] {
    if trials == 0 {
        return [0.0, 1.0];
    }
    let x = successes.min(trials) as f64;
    let n = trials as f64;
    let alpha = 1.0 - level;
    let low = if successes == 0 { 0.0 } else { beta_quantile(alpha / 2.0, x, n - x + 1.0) };
    let high = if successes >= trials { 1.0 } else { beta_quantile(1.0 - alpha / 2.0, x + 1.0, n - x) };
    [low, high]
}

/// The `prob` quantile of Beta(a, b), by bisection on the regularised incomplete beta function
/// to the last bit.
fn beta_quantile(prob: f64, a: f64, b: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if beta_reg(a, b, mid) < prob { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// R's rule, term by term, for small n.
    fn brute_force_p(x: u64, n: u64, p0: f64) -> f64 {
        let pmf = |k: u64| (ln_binomial(n, k) + k as f64 * p0.ln() + (n - k) as f64 * (1.0 - p0).ln()).exp();
        let d = pmf(x);
        (0..=n).map(pmf).filter(|&q| q <= d * RELATIVE_ERROR).sum::<f64>().min(1.0)
    }

    #[test]
    fn p_values_equal_the_term_by_term_sum() {
        for n in [1u64, 2, 5, 10, 17, 40] {
            for p0 in [0.5, 0.3, 0.75] {
                for x in 0..=n {
                    let p = binomial_test(x, n, p0).p;
                    let expected = brute_force_p(x, n, p0);
                    assert!(
                        (p - expected).abs() < 1e-12 * expected.max(1e-300) + 1e-15,
                        "{x}/{n} at {p0}: {p} vs {expected}"
                    );
                }
            }
        }
    }

    #[test]
    fn power_equals_the_sum_over_the_rejection_region() {
        for n in [1u64, 5, 6, 20, 33, 100] {
            let pmf = |k: u64| (ln_binomial(n, k) + k as f64 * 0.75f64.ln() + (n - k) as f64 * 0.25f64.ln()).exp();
            let expected: f64 = (0..=n).filter(|&x| brute_force_p(x, n, 0.5) <= 0.05).map(pmf).sum();
            let power = binomial_test_power(n, 0.5, 0.05, 0.75);
            assert!((power - expected).abs() < 1e-12, "n = {n}: {power} vs {expected}");
        }
    }

    #[test]
    fn huge_counts_stay_finite() {
        let p = binomial_test(0, 1_000_000_000, 0.5);
        assert!(p.is_bound() && (p.log10_p - 1e9 * 0.5f64.log10()).abs() < 1.0, "{p:?}");
        let p = binomial_test(500_030_000, 1_000_000_000, 0.5);
        assert!(p.p > 0.0 && p.p < 1.0 && p.log10_p.is_finite(), "{p:?}");
        let power = binomial_test_power(1_000_000_000, 0.5, 0.05, 0.75);
        assert_eq!(power, 1.0);
        let [low, high] = clopper_pearson(0, 1_000_000, 0.95);
        assert!(low == 0.0 && high > 0.0 && high < 1e-5);
    }

    /// Detection trials of two scene configurations: `s1` told apart every time, `s2` never;
    /// one trial with an empty scene, and one preference trial that is not counted.
    const BY_SCENE: &str = "participant,left,right,chosen,scene_left,scene_right\n\
        p1,ground-truth,LQ,ground-truth,s1,s1\np1,HQ,ground-truth,ground-truth,s1,s1\n\
        p1,ground-truth,LQ,LQ,s2,s2\np1,HQ,ground-truth,HQ,s2,s2\n\
        p2,LQ,ground-truth,ground-truth,s1,s1\np2,ground-truth,HQ,HQ,s2,s2\n\
        p2,LQ,ground-truth,LQ,,\np2,LQ,HQ,HQ,s1,s2\n";

    fn by_scene() -> Detection {
        let options = crate::data::TrialsOptions { scenes: true, allow_ground_truth: true, ..Default::default() };
        let parsed = crate::data::parse_trials_with(BY_SCENE, "t.csv", None, &options).unwrap();
        let split = split(parsed, None);
        assert!(split.preference.is_some());
        analyze_detection_by_scene(
            split.detection.as_ref().unwrap(),
            split.detection_scenes.as_ref(),
            &DetectionOptions::default(),
        )
        .unwrap()
    }

    #[test]
    fn detection_rates_are_broken_down_by_scene_configuration() {
        let detection = by_scene();
        // the conditions' rates count every detection trial, the empty-scene one included
        assert_eq!(detection.judgments, 7);
        let rates: Vec<(&str, u64, u64)> =
            detection.conditions.iter().map(|c| (c.condition.as_str(), c.correct, c.trials)).collect();
        assert_eq!(rates, [("HQ", 1, 3), ("LQ", 2, 4)]);
        let scenes: Vec<(&str, u64, u64)> =
            detection.scenes.iter().map(|s| (s.scene.as_str(), s.correct, s.trials)).collect();
        assert_eq!(scenes, [("s1", 3, 3), ("s2", 0, 3)]);
        let s1 = &detection.scenes[0];
        let per_condition: Vec<(&str, u64, u64)> =
            s1.conditions.iter().map(|c| (c.condition.as_str(), c.correct, c.trials)).collect();
        assert_eq!(per_condition, [("HQ", 1, 1), ("LQ", 2, 2)]);
        // 3 of 3: R's binom.test(3, 3) gives p = 0.25 and the interval [0.2924018, 1]
        assert!((s1.p.p - 0.25).abs() < 1e-12 && (s1.ci[0] - 0.292_401_8).abs() < 1e-6 && s1.ci[1] == 1.0);
        assert!(
            detection.warnings.iter().any(|w| w.starts_with("1 detection trial without a scene")),
            "{:?}",
            detection.warnings
        );
        // p1 saw s1 and s2 twice each, p2 s1 once and s2 once: first showings 4 (s1 2 of 2
        // told apart, s2 0 of 2), second showings 2 (s1 1 of 1, s2 0 of 1)
        let showings: Vec<(u64, u64, u64)> =
            detection.showings.iter().map(|s| (s.showing, s.correct, s.trials)).collect();
        assert_eq!(showings, [(1, 2, 4), (2, 1, 2)]);
        let json = serde_json::to_value(&detection).unwrap();
        assert_eq!(json["showings"][0]["showing"], 1);
        assert_eq!(json["scenes"][1]["scene"], "s2");
        assert_eq!(json["scenes"][1]["rate"], 0.0);
        assert_eq!(json["scenes"][0]["conditions"][0]["condition"], "HQ");
        assert!(json["scenes"][0]["p"].is_number());
    }

    #[test]
    fn without_scene_columns_there_is_no_scene_breakdown() {
        let options = crate::data::TrialsOptions { scenes: true, allow_ground_truth: true, ..Default::default() };
        let text = "participant,left,right,chosen\np1,ground-truth,LQ,LQ\np2,LQ,ground-truth,LQ\n";
        let parsed = crate::data::parse_trials_with(text, "t.csv", None, &options).unwrap();
        let split = split(parsed, None);
        let detection = analyze_detection_by_scene(
            split.detection.as_ref().unwrap(),
            split.detection_scenes.as_ref(),
            &DetectionOptions::default(),
        )
        .unwrap();
        assert!(detection.scenes.is_empty());
        assert!(serde_json::to_value(&detection).unwrap().get("scenes").is_none());
    }

    #[test]
    fn the_table_prints_the_scene_breakdown() {
        let report = crate::report::Report {
            preference: None,
            detection: Some(by_scene()),
            metrics: None,
            threshold: None,
            ratings: None,
        };
        let text = crate::table::render_report(&report);
        assert!(text.contains("per scene configuration"), "{text}");
        let line = text.lines().find(|line| line.starts_with("s2 ")).unwrap();
        assert!(line.contains("HQ 0/2, LQ 0/1") && line.contains("0.000"), "{line}");
        let line = text.lines().find(|line| line.starts_with("showing 2")).unwrap();
        assert!(line.contains("0.500"), "{line}");
    }

    #[test]
    fn d_prime_is_finite_at_zero_and_one() {
        let all = d_prime_2afc(20, 20);
        assert_eq!(all.corrected_pc, Some(0.975));
        assert!(all.d_prime.is_finite() && all.se.is_finite() && all.d_prime > 2.0);
        let none = d_prime_2afc(0, 20);
        assert!((none.d_prime + all.d_prime).abs() < 1e-12);
        let one = d_prime_2afc(1, 1);
        assert_eq!((one.d_prime, one.corrected_pc), (0.0, Some(0.5)));
    }
}
