//! The whole paired-comparison analysis: from judgments to the Analysis JSON of docs/design.md.
//!
//! Steps, each only where the data call for it:
//! 1. tally judgments per unordered pair; find the connected components of the comparison graph;
//! 2. item model per component (reference condition fixed at 0), by maximum likelihood, or —
//!    where a condition set never loses or never wins within its component (separation, so the
//!    MLE does not exist) — by Firth's bias-reduced likelihood, named in the output;
//! 3. factor model over the identifiable terms of the formula (constant or collinear terms are
//!    dropped with a warning), with its likelihood-ratio test against the item model;
//! 4. agreement (Kendall & Babington Smith's u or its generalisation), consistence per
//!    participant who compared every pair;
//! 5. per group, the same again (a group that cannot be fitted is reported as not estimable,
//!    with the reason, and the others go on), and a likelihood-ratio test of equal effects
//!    across the estimable groups;
//! 6. optionally a bootstrap over participants and observer screening.
//!
//! This module holds the options and the entry points; `output` the Analysis JSON's types,
//! `subset` one fit (steps 1–4 and 6), `groups` step 5, `screen` the observer screening and
//! `bootstrap` the bootstrap.

use crate::data::{ConditionTable, Judgment, Judgments, TrialsOptions};
use crate::design::{self, ParticipantTallies};
use crate::{AnalysisError, Result};

/// When to run observer screening.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Screening {
    /// On for designs up to [`SCREENING_AUTO_LIMIT`] conditions.
    Auto,
    On,
    Off,
}

impl Screening {
    /// `--screen`'s values: (name, help, value).
    pub const NAMES: &[(&str, &str, Screening)] = &[
        ("auto", "On for designs up to 200 conditions", Screening::Auto),
        ("on", "", Screening::On),
        ("off", "", Screening::Off),
    ];
}

/// Screening refits the item model once per participant; above this many conditions `Auto`
/// skips it (and says so).
pub const SCREENING_AUTO_LIMIT: usize = 200;

/// Options of an analysis. `Default` gives the documented defaults; they are also
/// `mrstudy analyze`'s flags (the binary's clap definitions default to this `Default`).
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Reference condition (log-worth 0); default: first of the conditions file, else first by name.
    pub reference: Option<String>,
    /// Factor-model formula, e.g. `gi+cm+ca+gi:ca` or `gi*ca+cm`; default: all factors, main effects.
    pub model: Option<String>,
    /// Fit everything per value of this column (e.g. `gender`) and test whether effects differ.
    pub group_by: Option<String>,
    /// Convergence tolerance (largest parameter change).
    pub tolerance: f64,
    /// Monte-Carlo replicates for the agreement p-value where no closed form applies.
    pub agreement_simulations: usize,
    /// Bootstrap replicates over participants for intervals (0: none; with --stimuli the metric correlations use 1000 unless given).
    pub bootstrap: usize,
    /// Seed for the bootstrap and the agreement simulation.
    pub seed: u64,
    /// Observer screening (leave-one-out); `auto` runs it for up to 200 conditions.
    pub screening: Screening,
    /// Participants whose leave-one-out p-value is below this are flagged.
    pub screening_alpha: f64,
    /// Use Firth's bias-reduced estimate for every model, not only under separation.
    pub always_firth: bool,
    /// Keep participants marked `pilot = true` in the trials CSV (default: left out, and said so).
    pub include_pilots: bool,
    /// Keep participants marked `excluded = true` in the trials CSV (default: left out, and said so).
    pub include_excluded: bool,
    /// `jod`: also pwcmp's JOD scale (Thurstone Case V, 1 JOD = 75 %) per condition, its outlier analysis and, with --bootstrap, its intervals; for a threshold export `log10`, `dB` or `linear` fits on that stimulus scale instead of the export's.
    pub scale: Scale,
    /// Threshold exports: the psychometric function to fit (`weibull`, `logistic`, `normal`) instead of the export's `function`.
    pub function: Option<String>,
    /// Threshold exports: the guess rate to fit with (e.g. 0.5 for 2AFC) instead of the export's `guess`.
    pub guess: Option<f64>,
    /// Prior sd of each log-worth for `log_worth_map`, the centred MAP log-worths (a study's `prior_sd`; default 1).
    pub prior_sd: f64,
}

/// The scale `--scale` asks for besides the Bradley–Terry log-worths.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    /// Bradley–Terry log-worths only.
    #[default]
    Bt,
    /// Also pwcmp's JOD ([`crate::scales::jod`]).
    Jod,
    /// A threshold export fitted with x = log10 intensity ([`crate::threshold::report`]).
    Log10,
    /// A threshold export fitted with x = 20·log10 intensity.
    Db,
    /// A threshold export fitted with x = intensity.
    Linear,
}

impl Scale {
    /// `--scale`'s values: (name, help, value).
    pub const NAMES: &[(&str, &str, Scale)] = &[
        ("bt", "Bradley–Terry log-worths only", Scale::Bt),
        ("jod", "Also pwcmp's JOD", Scale::Jod),
        ("log10", "A threshold export fitted with x = log10 intensity", Scale::Log10),
        ("dB", "A threshold export fitted with x = 20·log10 intensity", Scale::Db),
        ("linear", "A threshold export fitted with x = intensity", Scale::Linear),
    ];

    /// The stimulus scale a threshold export is fitted on instead of its own, if this names one.
    pub fn stimulus_scale(self) -> Option<crate::threshold::StimScale> {
        match self {
            Scale::Bt | Scale::Jod => None,
            Scale::Log10 => Some(crate::threshold::StimScale::Log10),
            Scale::Db => Some(crate::threshold::StimScale::Db),
            Scale::Linear => Some(crate::threshold::StimScale::Linear),
        }
    }
}

impl Default for Options {
    fn default() -> Self {
        Options {
            reference: None,
            model: None,
            group_by: None,
            tolerance: 1e-10,
            agreement_simulations: 10_000,
            bootstrap: 0,
            seed: 1,
            screening: Screening::Auto,
            screening_alpha: 0.01,
            always_firth: false,
            include_pilots: false,
            include_excluded: false,
            scale: Scale::Bt,
            function: None,
            guess: None,
            prior_sd: crate::active::DEFAULT_PRIOR_SD,
        }
    }
}

mod bootstrap;
mod groups;
pub mod map;
mod output;
mod robust;
mod screen;
mod subset;

pub(crate) use output::not_estimable_part;
pub use output::{
    Analysis, Bootstrap, Component, Covariate, CovariateModel, DroppedTerm, GroupResult, Item, LrTest, ModelSummary,
    NotEstimable, NotEstimablePart, Observer, ObserverScreening, Part, ParticipantConsistence,
};
use subset::{Inputs, Subset, analyze_subset};
pub(crate) use subset::{failure_message, fit_items};

/// Parses the trials (and conditions) CSV text and analyses it.
pub fn analyze(trials_csv: &str, conditions_csv: Option<&str>, options: &Options) -> Result<Analysis> {
    analyze_named(trials_csv, "trials CSV", conditions_csv.map(|text| (text, "conditions CSV")), options)
}

/// As [`analyze`], with the sources' names used in error messages (e.g. file paths).
pub fn analyze_named(
    trials_csv: &str,
    trials_name: &str,
    conditions: Option<(&str, &str)>,
    options: &Options,
) -> Result<Analysis> {
    let table = conditions.map(|(text, name)| crate::data::parse_conditions(text, name)).transpose()?;
    analyze_with_table(trials_csv, trials_name, table.as_ref(), options)
}

/// As [`analyze_named`], with the conditions as a table already (a caller that holds the study's
/// conditions need not write them as CSV to have them parsed again).
pub fn analyze_with_table(
    trials_csv: &str,
    trials_name: &str,
    table: Option<&ConditionTable>,
    options: &Options,
) -> Result<Analysis> {
    let trials_options = TrialsOptions {
        group_by: options.group_by.clone(),
        include_pilots: options.include_pilots,
        include_excluded: options.include_excluded,
        ..TrialsOptions::default()
    };
    let parsed = crate::data::parse_trials_with(trials_csv, trials_name, table, &trials_options)?;
    let mut analysis = analyze_judgments_with_ties(&parsed.judgments, &parsed.ties, table, options)?;
    if !parsed.left_out.is_empty() {
        analysis.warnings.insert(0, parsed.left_out.describe());
        analysis.left_out = Some(parsed.left_out);
    }
    Ok(analysis)
}

/// Analyses parsed judgments.
pub fn analyze_judgments(judgments: &Judgments, table: Option<&ConditionTable>, options: &Options) -> Result<Analysis> {
    analyze_judgments_with_ties(judgments, &[], table, options)
}

/// As [`analyze_judgments`], with the judgments answered `tie` (numbered as `judgments`, not
/// among its rows): where there are any, the `davidson` section, and half a vote each way on
/// the JOD scale.
pub fn analyze_judgments_with_ties(
    judgments: &Judgments,
    ties: &[Judgment],
    table: Option<&ConditionTable>,
    options: &Options,
) -> Result<Analysis> {
    if !(options.tolerance > 0.0 && options.tolerance < 1.0) {
        return Err(AnalysisError::BadOption {
            option: "tolerance".into(),
            message: format!("{} is not between 0 and 1", options.tolerance),
        });
    }
    if !(options.prior_sd > 0.0 && options.prior_sd.is_finite()) {
        return Err(AnalysisError::BadOption {
            option: "--prior-sd".into(),
            message: format!("{} is not a positive number", options.prior_sd),
        });
    }
    let reference = match &options.reference {
        Some(name) => judgments.conditions.iter().position(|c| c == name).ok_or_else(|| AnalysisError::BadOption {
            option: "reference".into(),
            message: format!(
                "`{name}` is not a condition of the data (conditions: {})",
                judgments.conditions.join(", ")
            ),
        })?,
        None => 0,
    };
    let terms = match table {
        Some(table) if !table.factors.is_empty() => {
            let formula = options.model.clone().unwrap_or_else(|| table.factors.join("+"));
            Some((formula.clone(), design::parse_formula(&formula, &table.factors)?))
        }
        _ => {
            if let Some(formula) = &options.model {
                return Err(AnalysisError::BadModel {
                    formula: formula.clone(),
                    message: "a factor model needs a conditions file with factor columns".into(),
                });
            }
            None
        }
    };

    let n_participants = judgments.participants.len();
    let n_conditions = judgments.conditions.len();
    let tallies = ParticipantTallies::new(n_participants, n_conditions, judgments.rows.iter());
    let everyone = tallies.present();
    let inputs = Inputs { judgments, table, terms: terms.as_ref(), reference, options };
    let mut analysis = analyze_subset(&inputs, &Subset { tallies: &tallies, active: &everyone, ties })?;
    map::fill_log_worth_map(judgments, options.prior_sd, &mut analysis);

    if !judgments.groups.is_empty() {
        groups::analyze_groups(&inputs, &tallies, &everyone, ties, &mut analysis);
    }
    Ok(analysis)
}
