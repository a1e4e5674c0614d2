//! `mrstudy-analysis`: the statistics of paired-comparison and task experiments.
//!
//! - Bradley–Terry item model (log-worth per condition) and factor model (object covariates,
//!   λᵢ = Σₖ βₖ·xᵢₖ), maximum likelihood with Firth's bias reduction where separation makes the
//!   MLE not exist;
//! - Kendall & Babington Smith's coefficient of agreement (and its generalisation to unbalanced
//!   designs), the coefficient of consistence;
//! - per-group fits and tests, bootstrap over participants, observer screening;
//! - Friedman tests, Kendall's W and Wilcoxon signed-rank post-hoc tests for lab tasks;
//! - detection of renderings against the ground truth ("real or rendered?": rates, exact
//!   binomial tests, d′, power; [`detection`]) and which image error predicts preference
//!   (rank correlations of stimulus metrics with perceived worth; [`stimulus_metrics`]), both
//!   gathered with the preference analysis in [`report`];
//! - SVG worth plots and scatter plots;
//! - active pair selection: a Bayesian Bradley–Terry / Thurstone posterior updated one
//!   judgment at a time and the pairs of largest expected information gain ([`active`]);
//! - the benchmark behind `mrstudy bench analysis` ([`bench`](mod@bench)).
//!
//! Invariant: this crate does no IO of its own and knows nothing of HTTP, the database or the
//! renderer. It parses text it is handed and returns typed results; callers print them.

pub mod active;
pub mod agreement;
pub mod analysis;
pub mod bench;
pub mod command;
pub mod data;
pub mod design;
pub mod detection;
pub mod error;
pub mod figures;
pub mod fit;
mod newton;
pub mod plot;
pub mod pvalue;
pub mod quantile;
pub mod ratings;
pub mod report;
pub mod scales;
pub mod screening;
pub mod stimulus_metrics;
pub mod table;
pub mod task;
pub mod threshold;

pub use analysis::{Analysis, Options, analyze};
pub use error::{AnalysisError, Result};
