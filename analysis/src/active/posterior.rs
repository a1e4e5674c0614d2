//! The Gaussian posterior of active selection: mean and full covariance of θ (log-worths or
//! factor effects), updated by assumed-density filtering one judgment at a time (O(p²)), the
//! comparison graph's components (union–find), the state's id, the EIG of a pair, and the
//! greedy batch of pairs for one participant.

use std::sync::OnceLock;

use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::best_pair::BestPair;
use super::quadrature::{EIG_NODES, Rule, UPDATE_NODES};
use super::{ActiveError, Link, Result, Target};
use crate::design::{find, union};

/// Names a posterior state: the judgments it absorbed and a 64-bit fingerprint of their
/// sequence. Equal ids mean the same log (up to 2⁻⁶⁴ odds), hence the same state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub struct StateId {
    pub judgments: u64,
    pub fingerprint: u64,
}

impl std::fmt::Display for StateId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}-{:016x}", self.judgments, self.fingerprint)
    }
}

/// SplitMix64's finaliser: the fingerprint's mixing step.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// How one judgment is absorbed. [`Update::Adf`] is the one used; the other is kept for the
/// benchmark's comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Update {
    /// Assumed-density filtering: match mean and variance of the tilted projection.
    Adf,
    /// Online Laplace (extended Kalman): one Newton step of the new term at the current mean.
    OnlineLaplace,
}

/// The posterior N(mean, covariance) over θ, with what active selection needs besides.
#[derive(Debug, Clone)]
pub struct Posterior {
    link: Link,
    prior_sd: f64,
    n_conditions: usize,
    /// `design[condition]` for the factor target; `None` for the log-worths (X = I).
    design: Option<Vec<Vec<f64>>>,
    /// The `both` target's effect projection ([`super::both::effect_projection`]); `None`
    /// for the other targets.
    effects: Option<Vec<Vec<f64>>>,
    mean: Vec<f64>,
    /// Row-major p × p, kept exactly symmetric (every update adds a symmetric product).
    covariance: Vec<f64>,
    judgments: u64,
    fingerprint: u64,
    /// Union–find over the conditions, by the judged pairs.
    parent: Vec<usize>,
    components: usize,
    /// ρ_max of the choice's score EIG(ρ·m, v); see [`Posterior::with_mean_weight`].
    mean_weight: f64,
    /// Judgments per condition over which ρ rises to ρ_max; see [`Posterior::with_mean_ramp`].
    mean_ramp: f64,
    eig_rule: Rule,
    update_rule: Rule,
    /// Whether the batch scores by the hierarchical prior on the log-worths' spread
    /// ([`Posterior::with_spread_prior`]).
    spread: bool,
    /// Judgments per condition after which a spread-prior posterior scores as the fixed prior
    /// does ([`Posterior::with_spread_switch`]); infinite: never.
    spread_until: f64,
    /// Every judgment absorbed, (winner, loser), in order, kept only under the spread prior:
    /// what its refits read (the other posteriors stay O(p²) whatever the log).
    log: Vec<(usize, usize)>,
    /// The spread mixture's moment-matched Gaussian at this state, once a batch needed it.
    pub(super) spread_fit: OnceLock<super::laplace::LaplaceFit>,
}

impl Posterior {
    /// The prior N(0, prior_sd²·I) for `target`, with likelihood `link`.
    pub fn new(target: &Target, link: Link, prior_sd: f64) -> Result<Posterior> {
        target.check()?;
        if !(prior_sd > 0.0 && prior_sd.is_finite()) {
            return Err(ActiveError::BadOption {
                option: "prior_sd",
                message: format!("the prior standard deviation must be positive and finite, got {prior_sd}"),
            });
        }
        let n_conditions = target.conditions();
        let design = match target {
            Target::Worths { .. } | Target::Both { .. } => None,
            Target::Factors { design } => Some(design.clone()),
        };
        let effects = match target {
            Target::Both { design } => Some(super::both::effect_projection(design)?),
            _ => None,
        };
        let p = design.as_ref().map_or(n_conditions, |d| d[0].len());
        let mut covariance = vec![0.0; p * p];
        for a in 0..p {
            covariance[a * p + a] = prior_sd * prior_sd;
        }
        Ok(Posterior {
            link,
            prior_sd,
            n_conditions,
            design,
            effects,
            mean: vec![0.0; p],
            covariance,
            judgments: 0,
            fingerprint: 0,
            parent: (0..n_conditions).collect(),
            components: n_conditions,
            mean_weight: super::DEFAULT_MEAN_WEIGHT,
            mean_ramp: super::MEAN_WEIGHT_RAMP,
            eig_rule: Rule::gauss_hermite(EIG_NODES),
            update_rule: Rule::gauss_hermite(UPDATE_NODES),
            spread: false,
            spread_until: f64::INFINITY,
            log: Vec::new(),
            spread_fit: OnceLock::new(),
        })
    }

    /// Scores batches under the hierarchical prior on the log-worths' spread
    /// ([`super::spread`]): before a batch, the posterior over the prior sd τ (hyperprior
    /// Gamma(2, 2/`prior_sd`), one Laplace refit of every judgment per τ of the grid), the
    /// mixture's moment-matched Gaussian, and the score EIG(ρ·m, v) on it with ρ_max
    /// ([`Posterior::with_mean_weight`]; 1: the plain EIG) from the first judgment, no ramp;
    /// the ADF posterior and the ramp are then not used for the choice. Computed once per state
    /// (concurrent participants at one state share it). Only for the log-worths target.
    pub fn with_spread_prior(mut self) -> Result<Posterior> {
        if self.judgments > 0 {
            return Err(ActiveError::BadOption {
                option: "spread_prior",
                message: format!(
                    "the hierarchical prior on the spread needs every judgment; set it before the first, not after {}",
                    self.judgments
                ),
            });
        }
        if self.design.is_some() || self.effects.is_some() {
            return Err(ActiveError::BadOption {
                option: "spread_prior",
                message: "the hierarchical prior on the spread applies to the log-worths target only".into(),
            });
        }
        self.spread = true;
        Ok(self)
    }

    /// Under the spread prior, scores by it only for the first `judgments_per_condition` judgments
    /// per condition, then as the fixed prior's design does: EIG(ρ·m, v) on the ADF posterior
    /// (which absorbed every judgment from the first) with ρ ramped to [`super::DEFAULT_MEAN_WEIGHT`]
    /// over [`super::MEAN_WEIGHT_RAMP`] judgments per condition, as that design has it (at 15 per
    /// condition ρ is ⅜, ½ from 20). The served `prior = "spread"` switches
    /// at [`super::SPREAD_SWITCH`]: the mixture is the better rule early, the ramp's ρ ½ late
    /// (issue 48; docs/simulate/README.md). No refit is made after the switch.
    pub fn with_spread_switch(mut self, judgments_per_condition: f64) -> Result<Posterior> {
        if !self.spread {
            return Err(ActiveError::BadOption {
                option: "spread_switch",
                message: "the switch from the spread prior needs the spread prior (with_spread_prior) first".into(),
            });
        }
        if !(judgments_per_condition >= 0.0) {
            return Err(ActiveError::BadOption {
                option: "spread_switch",
                message: format!("the switch must not be negative or NaN, got {judgments_per_condition}"),
            });
        }
        self.spread_until = judgments_per_condition;
        Ok(self)
    }

    /// Whether the next batch is scored under the spread prior (before its switch).
    pub fn scores_by_spread(&self) -> bool {
        self.spread && (self.judgments as f64) < self.spread_until * self.n_conditions as f64
    }

    /// A posterior for scoring one batch: this one's judgments and comparison graph, with the
    /// given moments and mean weight, no spread prior.
    fn scorer(&self, mean: Vec<f64>, covariance: Vec<f64>, mean_weight: f64, mean_ramp: f64) -> Posterior {
        Posterior {
            link: self.link,
            prior_sd: self.prior_sd,
            n_conditions: self.n_conditions,
            design: None,
            effects: None,
            mean,
            covariance,
            judgments: self.judgments,
            fingerprint: self.fingerprint,
            parent: self.parent.clone(),
            components: self.components,
            mean_weight,
            mean_ramp,
            eig_rule: self.eig_rule.clone(),
            update_rule: self.update_rule.clone(),
            spread: false,
            spread_until: f64::INFINITY,
            log: Vec::new(),
            spread_fit: OnceLock::new(),
        }
    }

    /// The spread mixture's moment-matched Gaussian at this state (computed once).
    fn spread_fit(&self) -> Result<&super::laplace::LaplaceFit> {
        if let Some(fit) = self.spread_fit.get() {
            return Ok(fit);
        }
        let mixture = super::spread::spread_posterior(self.n_conditions, self.link, self.prior_sd, &self.log).map_err(
            |error| match error {
                ActiveError::Degenerate { message, .. } => self.degenerate(message),
                other => other,
            },
        )?;
        Ok(self.spread_fit.get_or_init(|| mixture.moment_matched()))
    }

    /// Sets ρ_max, the largest weight of the posterior mean difference in the score of a pair:
    /// the batch scores EIG(ρ·m, v) with ρ rising linearly from 0 to ρ_max over the first
    /// [`super::MEAN_WEIGHT_RAMP`] judgments per condition. ρ = 1 is the plain EIG
    /// ([`Posterior::eig`]); ρ = 0 scores by the variance of the difference alone. Default
    /// [`super::DEFAULT_MEAN_WEIGHT`] (the module doc says why).
    pub fn with_mean_weight(mut self, mean_weight: f64) -> Result<Posterior> {
        if !(0.0..=1.0).contains(&mean_weight) {
            return Err(ActiveError::BadOption {
                option: "mean_weight",
                message: format!("the weight of the mean difference must be within 0 and 1, got {mean_weight}"),
            });
        }
        self.mean_weight = mean_weight;
        Ok(self)
    }

    /// The largest ρ, reached after [`super::MEAN_WEIGHT_RAMP`] judgments per condition.
    pub fn mean_weight(&self) -> f64 {
        self.mean_weight
    }

    /// Sets the ramp: ρ rises from 0 to ρ_max over the first `judgments_per_condition`
    /// judgments per condition (default [`super::MEAN_WEIGHT_RAMP`]); 0: ρ_max from the start.
    pub fn with_mean_ramp(mut self, judgments_per_condition: f64) -> Result<Posterior> {
        if !(judgments_per_condition >= 0.0 && judgments_per_condition.is_finite()) {
            return Err(ActiveError::BadOption {
                option: "mean_ramp",
                message: format!("the ramp must be finite and not negative, got {judgments_per_condition}"),
            });
        }
        self.mean_ramp = judgments_per_condition;
        Ok(self)
    }

    /// ρ now: ρ_max · min(1, judgments / (ramp · conditions)); ρ_max without a ramp.
    pub fn effective_mean_weight(&self) -> f64 {
        if self.mean_ramp == 0.0 {
            return self.mean_weight;
        }
        let ramp = self.mean_ramp * self.n_conditions as f64;
        self.mean_weight * (self.judgments as f64 / ramp).min(1.0)
    }

    /// Re-anchors the posterior on `fit`, a Laplace refit of every judgment absorbed
    /// ([`super::laplace::refit`] of the same target, link and prior): mean and covariance are
    /// the fit's, the rest (judgments, state id, the comparison graph) stays. ADF never revisits
    /// a judgment; this does, at the refit's O(p³) cost. Refused: a fit of another size or with
    /// a non-finite value.
    pub fn reanchor(&mut self, fit: &super::laplace::LaplaceFit) -> Result<()> {
        let p = self.mean.len();
        if fit.mean.len() != p || fit.covariance.len() != p * p {
            return Err(self.degenerate(format!("a refit of {} parameters for a posterior of {p}", fit.mean.len())));
        }
        if fit.mean.iter().chain(&fit.covariance).any(|v| !v.is_finite()) {
            return Err(self.degenerate("a refit with a non-finite value".into()));
        }
        self.mean = fit.mean.clone();
        // kept exactly symmetric, as every update keeps it
        for a in 0..p {
            for b in 0..p {
                self.covariance[a * p + b] = 0.5 * (fit.covariance[a * p + b] + fit.covariance[b * p + a]);
            }
        }
        Ok(())
    }

    pub fn link(&self) -> Link {
        self.link
    }

    pub fn prior_sd(&self) -> f64 {
        self.prior_sd
    }

    pub fn conditions(&self) -> usize {
        self.n_conditions
    }

    /// Number of parameters p (conditions, or factors).
    pub fn parameters(&self) -> usize {
        self.mean.len()
    }

    /// Posterior mean of θ.
    pub fn mean(&self) -> &[f64] {
        &self.mean
    }

    /// Posterior covariance of θ, row-major p × p.
    pub fn covariance(&self) -> &[f64] {
        &self.covariance
    }

    /// The covariance, writable, to break the posterior on purpose in tests.
    #[cfg(test)]
    pub(super) fn covariance_for_tests(&mut self) -> &mut [f64] {
        &mut self.covariance
    }

    /// Judgments absorbed so far.
    pub fn judgments(&self) -> u64 {
        self.judgments
    }

    /// The state's id, for the server's log of which state chose a trial.
    pub fn state_id(&self) -> StateId {
        StateId { judgments: self.judgments, fingerprint: self.fingerprint }
    }

    /// Whether the judged pairs connect every condition.
    pub fn connected(&self) -> bool {
        self.components == 1
    }

    /// Posterior mean log-worth of every condition (X·mean for the factor target).
    pub fn log_worths(&self) -> Vec<f64> {
        match &self.design {
            None => self.mean.clone(),
            Some(design) => design.iter().map(|row| dot(row, &self.mean)).collect(),
        }
    }

    fn check_condition(&self, condition: usize) -> Result<()> {
        if condition >= self.n_conditions {
            return Err(ActiveError::UnknownCondition { condition, conditions: self.n_conditions });
        }
        Ok(())
    }

    fn degenerate(&self, message: String) -> ActiveError {
        ActiveError::Degenerate { judgments: self.judgments, message }
    }

    /// The direction a = x_w − x_l of a judgment in θ-space (dense, length p).
    fn direction(&self, winner: usize, loser: usize) -> Vec<f64> {
        match &self.design {
            None => {
                let mut a = vec![0.0; self.n_conditions];
                a[winner] = 1.0;
                a[loser] = -1.0;
                a
            }
            Some(design) => design[winner].iter().zip(&design[loser]).map(|(w, l)| w - l).collect(),
        }
    }

    /// Σ·a and aᵀθ for the direction of (winner, loser); O(2p) for log-worths, O(p²) for factors.
    fn project(&self, winner: usize, loser: usize) -> (Vec<f64>, f64) {
        let p = self.mean.len();
        match &self.design {
            None => {
                let (w, l) = (winner * p, loser * p);
                let u = (0..p).map(|k| self.covariance[w + k] - self.covariance[l + k]).collect();
                (u, self.mean[winner] - self.mean[loser])
            }
            Some(_) => {
                let a = self.direction(winner, loser);
                let u = (0..p).map(|r| dot(&self.covariance[r * p..(r + 1) * p], &a)).collect();
                (u, dot(&a, &self.mean))
            }
        }
    }

    /// Absorbs one judgment, `winner` chosen over `loser`, by ADF. O(p²).
    pub fn update(&mut self, winner: usize, loser: usize) -> Result<()> {
        self.update_by(Update::Adf, winner, loser)
    }

    /// Absorbs one judgment by the given method (the benchmark compares them).
    pub fn update_by(&mut self, method: Update, winner: usize, loser: usize) -> Result<()> {
        self.check_condition(winner)?;
        self.check_condition(loser)?;
        if winner == loser {
            return Err(ActiveError::SameCondition { condition: winner });
        }
        let (u, m) = self.project(winner, loser);
        let a_u = match &self.design {
            None => u[winner] - u[loser],
            Some(_) => dot(&self.direction(winner, loser), &u),
        };
        let v = a_u;
        if !(v > 0.0 && v.is_finite() && m.is_finite()) {
            return Err(self.degenerate(format!("variance {v:e} and mean {m:e} of the judged difference")));
        }
        // New mean and variance of d, as the rank-one update's two coefficients.
        let (mean_shift, variance_drop) = match method {
            Update::Adf => {
                let (z, new_m, new_v) = self.link.tilted(m, v, &self.update_rule);
                if !(z > 0.0 && new_m.is_finite() && new_v > 0.0 && new_v <= v) {
                    return Err(self.degenerate(format!("ADF moments Z = {z:e}, m = {new_m:e}, v = {new_v:e}")));
                }
                ((new_m - m) / v, (v - new_v) / (v * v))
            }
            Update::OnlineLaplace => {
                let (g, h) = self.link.log_derivatives(m);
                let shrink = h / (1.0 + h * v);
                // Σ′a = Σa·(1 − h·v/(1 + h·v)); the mean moves by Σ′a·g.
                (g * (1.0 - shrink * v), shrink)
            }
        };
        let p = self.mean.len();
        for r in 0..p {
            self.mean[r] += u[r] * mean_shift;
            let ur = u[r] * variance_drop;
            let row = &mut self.covariance[r * p..(r + 1) * p];
            for (entry, &uc) in row.iter_mut().zip(&u) {
                *entry -= ur * uc;
            }
        }
        self.judgments += 1;
        if self.spread {
            self.log.push((winner, loser));
            self.spread_fit = OnceLock::new();
        }
        self.fingerprint = mix(self.fingerprint ^ mix(((winner as u64) << 32) | loser as u64));
        if union(&mut self.parent, winner, loser) {
            self.components -= 1;
        }
        Ok(())
    }

    /// The log-worths' mean and covariance (n and n × n row-major): θ itself, or X·θ.
    fn worth_moments(&self) -> (Vec<f64>, Vec<f64>) {
        match &self.design {
            None => (self.mean.clone(), self.covariance.clone()),
            Some(design) => {
                let n = self.n_conditions;
                let p = self.mean.len();
                // X·Σ (n × p), then (X·Σ)·Xᵀ.
                let x_sigma: Vec<Vec<f64>> = design
                    .iter()
                    .map(|row| (0..p).map(|c| (0..p).map(|r| row[r] * self.covariance[r * p + c]).sum()).collect())
                    .collect();
                let mut c = vec![0.0; n * n];
                for i in 0..n {
                    for j in 0..n {
                        c[i * n + j] = dot(&x_sigma[i], &design[j]);
                    }
                }
                (self.log_worths(), c)
            }
        }
    }

    /// Expected information gain (nats) about θ of one judgment of the pair (i, j).
    pub fn eig(&self, i: usize, j: usize) -> f64 {
        let (u, m) = self.project(i, j);
        let v = match &self.design {
            None => u[i] - u[j],
            Some(_) => dot(&self.direction(i, j), &u),
        };
        self.link.eig(m, v, &self.eig_rule)
    }

    /// A batch of `trials` pairs for one participant, each `(i, j)` with i < j, best first:
    /// greedily the pair of largest score EIG(ρ·m, v) (ρ: [`Posterior::effective_mean_weight`]), then a fantasy update (the outcome-averaged ADF
    /// covariance, mean unchanged), then the next. No pair follows itself (nor `previous`, the
    /// participant's last pair); until the judged pairs and the batch so far connect every
    /// condition, only pairs joining two components are candidates. Ties (relative 1e-12) are
    /// broken by `rng`. O(trials · n²) EIG evaluations plus, for factors, O(n²·p) once.
    pub fn best_pairs(
        &self,
        trials: usize,
        previous: Option<(usize, usize)>,
        rng: &mut ChaCha8Rng,
    ) -> Result<Vec<(usize, usize)>> {
        if trials == 0 {
            return Err(ActiveError::NoTrials);
        }
        if let Some((a, b)) = previous {
            self.check_condition(a)?;
            self.check_condition(b)?;
        }
        if self.scores_by_spread() {
            let fit = self.spread_fit()?;
            if fit.mean.iter().chain(&fit.covariance).any(|v| !v.is_finite()) {
                return Err(self.degenerate("the spread mixture has a non-finite moment".into()));
            }
            let scoring = self.scorer(fit.mean.clone(), fit.covariance.clone(), self.mean_weight, 0.0);
            return scoring.best_pairs(trials, previous, rng);
        }
        if self.spread {
            // past the switch: the fixed prior's design on the ADF posterior
            let scoring = self.scorer(
                self.mean.clone(),
                self.covariance.clone(),
                super::DEFAULT_MEAN_WEIGHT,
                super::MEAN_WEIGHT_RAMP,
            );
            return scoring.best_pairs(trials, previous, rng);
        }
        if let Some(projection) = &self.effects {
            let input = super::both::BothBatch {
                link: self.link,
                rule: &self.update_rule,
                mean: &self.mean,
                covariance: &self.covariance,
                projection,
                mean_weight: self.effective_mean_weight(),
                parent: self.parent.clone(),
                components: self.components,
            };
            let last = previous.map(|(a, b)| (a.min(b), a.max(b)));
            return super::both::best_pairs(input, trials, last, rng).map_err(|error| match error {
                ActiveError::Degenerate { message, .. } => self.degenerate(message),
                other => other,
            });
        }
        let n = self.n_conditions;
        let p = self.mean.len();
        let (worth_mean, worth_cov) = self.worth_moments();
        // Variance of every pair's difference, in the order (0,1), (0,2), …, (n−2, n−1).
        let mut pair_variance = Vec::with_capacity(n * (n - 1) / 2);
        for i in 0..n {
            for j in i + 1..n {
                let v = worth_cov[i * n + i] + worth_cov[j * n + j] - 2.0 * worth_cov[i * n + j];
                if !(v > 0.0 && v.is_finite()) {
                    return Err(self.degenerate(format!("variance {v:e} of the pair ({i}, {j})")));
                }
                pair_variance.push(v);
            }
        }
        if let Some(k) = worth_mean.iter().position(|m| !m.is_finite()) {
            return Err(self.degenerate(format!("mean {} of condition {k}", worth_mean[k])));
        }
        let mean_weight = self.effective_mean_weight();
        let mut parent = self.parent.clone();
        let mut components = self.components;
        let mut last = previous.map(|(a, b)| (a.min(b), a.max(b)));
        // The fantasy updates so far: Σ_now = Σ − Σₗ cₗ·uₗ·uₗᵀ (θ-space).
        let mut fantasies: Vec<(Vec<f64>, f64)> = Vec::new();
        let mut batch = Vec::with_capacity(trials);
        for _ in 0..trials {
            let mut best = BestPair::new();
            let mut index = 0;
            for i in 0..n {
                for j in i + 1..n {
                    let v = pair_variance[index];
                    index += 1;
                    if last == Some((i, j)) || (components > 1 && find(&mut parent, i) == find(&mut parent, j)) {
                        continue;
                    }
                    let score = self.link.eig(mean_weight * (worth_mean[i] - worth_mean[j]), v, &self.eig_rule);
                    best.offer((i, j), score, rng);
                }
            }
            let (i, j) = best.pair.expect("at least 3 conditions leave a pair besides the last one");
            batch.push((i, j));
            last = Some((i, j));
            if union(&mut parent, i, j) {
                components -= 1;
            }
            if batch.len() == trials {
                break;
            }
            // Fantasy update along a = x_i − x_j.
            let a = self.direction(i, j);
            let mut u: Vec<f64> = (0..p).map(|r| dot(&self.covariance[r * p..(r + 1) * p], &a)).collect();
            for (previous_u, c) in &fantasies {
                let along = c * dot(previous_u, &a);
                for (uk, pk) in u.iter_mut().zip(previous_u) {
                    *uk -= along * pk;
                }
            }
            let v = dot(&a, &u);
            let m = worth_mean[i] - worth_mean[j];
            let (z, _, v_won) = self.link.tilted(m, v, &self.update_rule);
            let (_, _, v_lost) = self.link.tilted(-m, v, &self.update_rule);
            let expected_v = z * v_won + (1.0 - z) * v_lost;
            let c = (v - expected_v) / (v * v);
            if !(c.is_finite() && c >= 0.0) {
                return Err(self.degenerate(format!("fantasy update of the pair ({i}, {j}) with variance {v:e}")));
            }
            let worth_u: Vec<f64> = match &self.design {
                None => u.clone(),
                Some(design) => design.iter().map(|row| dot(row, &u)).collect(),
            };
            let mut index = 0;
            for i in 0..n {
                for j in i + 1..n {
                    let along = worth_u[i] - worth_u[j];
                    pair_variance[index] = (pair_variance[index] - c * along * along).max(f64::MIN_POSITIVE);
                    index += 1;
                }
            }
            fantasies.push((u, c));
        }
        Ok(batch)
    }
}

pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
