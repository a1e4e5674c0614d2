//! The Analysis JSON of docs/design.md as types: the analysis, its items, components, models,
//! tests, observer screening, bootstrap, groups, and the parts that could not be estimated.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::agreement::{self, Agreement};
use crate::data::LeftOut;
use crate::fit::{Fit, Method};
use crate::pvalue::PValue;

/// One condition's row in the analysis.
#[derive(Debug, Clone, Serialize)]
pub struct Item {
    pub condition: String,
    /// λ relative to the reference of its component; absent where the condition was never compared.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub log_worth: Option<f64>,
    /// The standard error of `log_worth` (and of its Wald interval): the larger of `model_se`
    /// and the participant-cluster robust one (maximum-likelihood fits; see `robust`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub se: Option<f64>,
    /// The item model's own standard error (inverse Fisher information, BradleyTerry2's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model_se: Option<f64>,
    /// exp(λ) / Σ exp(λ) over its component.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub worth: Option<f64>,
    pub wins: u64,
    pub comparisons: u64,
    /// Index into `components`, present only when the comparison graph is disconnected.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub component: Option<usize>,
    /// λ under the factor model, relative to the reference.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fitted_log_worth: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fitted_worth: Option<f64>,
    /// Bootstrap interval of `log_worth` (95 %; percentile, widened for few participants).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ci: Option<[f64; 2]>,
    /// The centred MAP log-worth with the prior N(0, `prior_sd`²) per condition (mean 0 over the
    /// conditions; `analysis::map`): what `prior = "spread"` optimises.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub log_worth_map: Option<f64>,
    /// JOD (`--scale jod`): pwcmp's `pw_scale`, mean about 0.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub jod: Option<f64>,
    /// `pw_scale_bootstrp`'s 95 % percentile interval of `jod` (`--scale jod --bootstrap N`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub jod_ci: Option<[f64; 2]>,
}

/// A connected component of the comparison graph.
#[derive(Debug, Clone, Serialize)]
pub struct Component {
    pub conditions: Vec<String>,
    pub reference: String,
    pub method: Method,
    /// Conditions that never lost (resp. never won) within the component, where separation
    /// made the maximum-likelihood estimate not exist.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub never_lost: Vec<String>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub never_won: Vec<String>,
}

/// Fit statistics of a model.
#[derive(Debug, Clone, Serialize)]
pub struct ModelSummary {
    pub method: Method,
    pub log_likelihood: f64,
    /// Log-likelihood without binomial coefficients (additive over data splits).
    #[serde(skip)]
    pub kernel_log_likelihood: f64,
    pub deviance: f64,
    pub aic: f64,
    pub df_residual: i64,
    pub parameters: usize,
    pub iterations: usize,
}

impl ModelSummary {
    pub(crate) fn from_fits(fits: &[&Fit]) -> ModelSummary {
        let method = if fits.iter().any(|f| f.method == Method::Firth) { Method::Firth } else { Method::Ml };
        let log_likelihood: f64 = fits.iter().map(|f| f.log_likelihood).sum();
        let parameters: usize = fits.iter().map(|f| f.beta.len()).sum();
        ModelSummary {
            method,
            log_likelihood,
            kernel_log_likelihood: fits.iter().map(|f| f.kernel_log_likelihood).sum(),
            deviance: fits.iter().map(|f| f.deviance).sum(),
            aic: -2.0 * log_likelihood + 2.0 * parameters as f64,
            df_residual: fits.iter().map(|f| f.n_observations as i64).sum::<i64>() - parameters as i64,
            parameters,
            iterations: fits.iter().map(|f| f.iterations).max().unwrap_or(0),
        }
    }
}

/// A likelihood-ratio test.
#[derive(Debug, Clone, Serialize)]
pub struct LrTest {
    pub chi2: f64,
    pub df: i64,
    #[serde(flatten)]
    pub p: PValue,
}

impl LrTest {
    pub(crate) fn new(chi2: f64, df: i64) -> Option<LrTest> {
        (df > 0).then(|| {
            let chi2 = chi2.max(0.0);
            LrTest { chi2, df, p: PValue::chi2_upper(chi2, df as f64) }
        })
    }
}

/// One term of the factor model.
#[derive(Debug, Clone, Serialize)]
pub struct Covariate {
    pub name: String,
    pub estimate: f64,
    /// The standard error `z`, `p` and the Wald interval use: the larger of `model_se` and the
    /// participant-cluster robust (sandwich) standard error (docs/analysis.md, "Participants'
    /// own tastes").
    pub se: f64,
    /// The model's standard error (inverse Fisher information, as BradleyTerry2's).
    pub model_se: f64,
    pub z: f64,
    #[serde(flatten)]
    pub p: PValue,
    /// Bootstrap interval (95 %; percentile, widened for few participants).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ci: Option<[f64; 2]>,
}

/// A term left out of the factor model and why.
#[derive(Debug, Clone, Serialize)]
pub struct DroppedTerm {
    pub name: String,
    pub reason: String,
}

/// The factor model's fit.
#[derive(Debug, Clone, Serialize)]
pub struct CovariateModel {
    pub formula: String,
    #[serde(flatten)]
    pub summary: ModelSummary,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lr_vs_items: Option<LrTest>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub dropped: Vec<DroppedTerm>,
}

/// Coefficient of consistence of one participant.
#[derive(Debug, Clone, Serialize)]
pub struct ParticipantConsistence {
    pub participant: String,
    #[serde(flatten)]
    pub consistence: agreement::Consistence,
}

/// Observer screening: how likely each participant's choices are under the consensus of the
/// others (leave-one-out item model).
#[derive(Debug, Clone, Serialize)]
pub struct ObserverScreening {
    pub alpha: f64,
    pub participants: Vec<Observer>,
    /// Names of the flagged participants (also marked in `participants`); nobody is dropped.
    pub flagged: Vec<String>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Observer {
    pub participant: String,
    pub judgments: u64,
    /// Mean log-likelihood per judgment under the leave-one-out fit.
    pub mean_log_likelihood: f64,
    /// Standardised log-likelihood: (observed − expected) / sd under the leave-one-out fit
    /// (descriptive; `p` comes from the exact or saddlepoint null distribution).
    pub z: f64,
    #[serde(flatten)]
    pub p: PValue,
    pub flagged: bool,
}

/// Bootstrap settings and outcome (the intervals sit on the items and covariates).
#[derive(Debug, Clone, Serialize)]
pub struct Bootstrap {
    pub replicates: usize,
    pub seed: u64,
    /// Replicates whose fit did not exist (e.g. separation in a resample); left out of the intervals.
    pub failed: usize,
    pub level: f64,
}

/// A group of `--group-by` whose models could not be fitted, and why; the other groups and the
/// test across groups go on without it.
#[derive(Debug, Clone, Serialize)]
pub struct NotEstimable {
    /// Always `false`: tells this entry from an estimated group's analysis in the JSON.
    pub estimable: bool,
    pub judgments: u64,
    pub participants: usize,
    pub reason: String,
}

/// An optional part of the analysis (or of its `metrics` section) that can fail to be
/// estimable on the data so far while everything else is reported.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Part {
    FactorModel,
    ObserverScreening,
    Bootstrap,
    /// The likelihood-ratio test of equal effects across the groups of `--group-by`.
    GroupTest,
    /// The whole stimulus-metrics analysis (`--stimuli`).
    Metrics,
    /// The log-worth per stimulus of the metrics analysis (it then falls back to conditions).
    StimulusModel,
    /// Every correlation of a metric with the perceived log-worth.
    MetricCorrelations,
    /// The JOD scale of `--scale jod`.
    JodScale,
    /// The Davidson fit of the judgments with ties.
    Davidson,
}

impl Part {
    /// The part's name in a sentence.
    pub fn describe(self) -> &'static str {
        match self {
            Part::FactorModel => "factor model",
            Part::ObserverScreening => "observer screening",
            Part::Bootstrap => "bootstrap",
            Part::GroupTest => "test of equal effects across groups",
            Part::Metrics => "metrics analysis",
            Part::StimulusModel => "stimulus model",
            Part::MetricCorrelations => "metric correlations",
            Part::JodScale => "JOD scale",
            Part::Davidson => "Davidson tie model",
        }
    }
}

/// A part of the analysis that could not be estimated on these data, and why (JSON
/// `not_estimable: [{"part": "observer_screening", "reason": "…"}]`).
#[derive(Debug, Clone, Serialize)]
pub struct NotEstimablePart {
    pub part: Part,
    pub reason: String,
}

/// Records a part as not estimable: in `list`, and as the sentence
/// "`<part>` not estimable: `<reason>`" in `warnings`, which every reader of the analysis shows.
pub(crate) fn not_estimable_part(
    warnings: &mut Vec<String>,
    list: &mut Vec<NotEstimablePart>,
    part: Part,
    reason: String,
) {
    warnings.push(format!("{} not estimable: {reason}", part.describe()));
    list.push(NotEstimablePart { part, reason });
}

/// One group's result: its analysis, or why there is none.
#[derive(Debug, Clone, Serialize)]
#[serde(untagged)]
pub enum GroupResult {
    Estimated(Box<Analysis>),
    NotEstimable(NotEstimable),
}

impl GroupResult {
    /// The group's analysis, where it could be estimated.
    pub fn analysis(&self) -> Option<&Analysis> {
        match self {
            GroupResult::Estimated(analysis) => Some(analysis),
            GroupResult::NotEstimable(_) => None,
        }
    }
}

/// The analysis of a data set (docs/design.md's Analysis JSON).
#[derive(Debug, Clone, Serialize)]
pub struct Analysis {
    pub judgments: u64,
    pub participants: usize,
    pub conditions: usize,
    pub reference: String,
    pub method: Method,
    pub items: Vec<Item>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub components: Option<Vec<Component>>,
    pub item_model: ModelSummary,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub covariates: Option<Vec<Covariate>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub covariate_model: Option<CovariateModel>,
    pub agreement: Agreement,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub consistence: Vec<ParticipantConsistence>,
    /// Per group of `--group-by`: its analysis, or why it could not be estimated.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub groups: Option<BTreeMap<String, GroupResult>>,
    /// Likelihood-ratio test that the model's effects are equal in every estimable group.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub group_test: Option<LrTest>,
    /// Groups left out of `group_test` because they could not be estimated.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub group_test_left_out: Vec<String>,
    /// Participants (pilots, excluded) left out before the analysis; absent when none were.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub left_out: Option<LeftOut>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bootstrap: Option<Bootstrap>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub observers: Option<ObserverScreening>,
    /// `--scale jod`: pwcmp's outlier analysis and the significance of neighbouring JODs (the
    /// JODs themselves are on `items`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub jod_scale: Option<crate::scales::jod::JodSection>,
    /// Where some judgments are ties: Davidson's tie model over all judgments (the item model
    /// above is the Bradley–Terry fit of the judgments without ties).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub davidson: Option<crate::scales::davidson::DavidsonSection>,
    /// Optional parts that could not be estimated on these data, each with its reason (also
    /// said in `warnings`); everything else is reported. Groups that could not be estimated
    /// are in `groups`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub not_estimable: Vec<NotEstimablePart>,
    pub warnings: Vec<String>,
}
