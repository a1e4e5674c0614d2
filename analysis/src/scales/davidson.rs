//! Davidson's tie extension of Bradley–Terry (Davidson 1970, "On extending the Bradley–Terry
//! model to accommodate ties in paired comparison experiments", JASA 65:317–328), for the
//! "not sure" answer (`chosen = tie`):
//!
//! P(i over j) = πᵢ / (πᵢ + πⱼ + ν√(πᵢπⱼ)), P(tie) = ν√(πᵢπⱼ) / (πᵢ + πⱼ + ν√(πᵢπⱼ)),
//!
//! with λᵢ = ln πᵢ (0 at the reference condition, as the item model's log-worth) and ν ≥ 0.
//! Without ties ν = 0 and the model is Bradley–Terry. Maximum likelihood by Newton–Raphson
//! ([`crate::newton`], the loop of the Bradley–Terry fit too) in
//! (λ, θ = ln ν): with dᵢⱼ = (λᵢ − λⱼ)/2 a pair's log-likelihood is
//! (wᵢ − wⱼ)·dᵢⱼ + t·θ − n·ln(2 cosh dᵢⱼ + e^θ), concave, and its Hessian depends on the data only
//! through n, so observed and expected information agree. Standard errors from the inverse
//! information; se(ν) = ν·se(θ) (delta method).

/// One unordered pair's judgments.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TiePair {
    pub i: usize,
    pub j: usize,
    pub wins_i: f64,
    pub wins_j: f64,
    pub ties: f64,
}

/// The Davidson fit.
#[derive(Debug, Clone, PartialEq)]
pub struct DavidsonFit {
    /// λ per condition, 0 at the reference.
    pub log_worth: Vec<f64>,
    /// Standard error of λ (0 at the reference).
    pub se: Vec<f64>,
    /// ν (0 where there are no ties).
    pub nu: f64,
    /// se(ν); absent where there are no ties (ν = 0 lies on the boundary).
    pub nu_se: Option<f64>,
    pub log_likelihood: f64,
    pub iterations: usize,
}

/// Why the Davidson model could not be fitted, with the values that show it.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DavidsonFailure {
    /// The comparison graph is not connected, or a condition is never compared: `condition`
    /// (an index of the fit's conditions) is not reached from the reference.
    #[error("the comparison graph is not connected")]
    Disconnected { condition: usize },
    /// A condition never won and never tied (or always won), so λ is infinite.
    #[error("a set of conditions never lost (or never won), so the maximum-likelihood estimate does not exist")]
    Separation,
    /// No convergence within `iterations`; the last step moved a parameter by `last_change`.
    #[error("Newton–Raphson did not converge")]
    NotConverged { iterations: usize, last_change: f64 },
}

/// Log-likelihood (without multinomial constants) and, where asked, score and information of
/// the model at (λ, θ). `column[c]` is condition c's parameter index (`None` at the reference);
/// θ is the last parameter where `with_nu`.
fn evaluate(
    pairs: &[TiePair],
    column: &[Option<usize>],
    beta: &[f64],
    with_nu: bool,
    derivatives: Option<(&mut [f64], &mut [f64])>,
) -> f64 {
    let q = beta.len();
    let lambda = |c: usize| column[c].map_or(0.0, |k| beta[k]);
    let theta = if with_nu { beta[q - 1] } else { f64::NEG_INFINITY };
    let mut log_likelihood = 0.0;
    let mut derivatives = derivatives;
    if let Some((score, information)) = derivatives.as_mut() {
        score.fill(0.0);
        information.fill(0.0);
    }
    for pair in pairs {
        let n = pair.wins_i + pair.wins_j + pair.ties;
        let d = (lambda(pair.i) - lambda(pair.j)) / 2.0;
        // ln(e^d + e^−d + e^θ), stably
        let m = d.abs().max(theta);
        let den = (d - m).exp() + (-d - m).exp() + (theta - m).exp();
        let log_den = m + den.ln();
        let tie_term = if pair.ties > 0.0 { pair.ties * theta } else { 0.0 };
        log_likelihood += (pair.wins_i - pair.wins_j) * d + tie_term - n * log_den;
        let Some((score, information)) = derivatives.as_mut() else { continue };
        let p_i = (d - log_den).exp();
        let p_j = (-d - log_den).exp();
        let p_t = (theta - log_den).exp();
        // derivatives in d and θ; λᵢ moves d by ½, λⱼ by −½
        let s_d = (pair.wins_i - pair.wins_j) - n * (p_i - p_j);
        let i_dd = n * ((p_i + p_j) - (p_i - p_j) * (p_i - p_j));
        let i_dt = -n * (p_i - p_j) * p_t;
        let i_tt = n * p_t * (1.0 - p_t);
        let (a, b) = (column[pair.i], column[pair.j]);
        let mut add = |x: usize, y: usize, value: f64| information[x * q + y] += value;
        for (k, sign) in [(a, 0.5), (b, -0.5)] {
            let Some(k) = k else { continue };
            score[k] += sign * s_d;
            for (l, sign_l) in [(a, 0.5), (b, -0.5)] {
                if let Some(l) = l {
                    add(k, l, sign * sign_l * i_dd);
                }
            }
            if with_nu {
                add(k, q - 1, sign * i_dt);
                add(q - 1, k, sign * i_dt);
            }
        }
        if with_nu {
            score[q - 1] += pair.ties - n * p_t;
            add(q - 1, q - 1, i_tt);
        }
    }
    log_likelihood
}

/// The Davidson log-likelihood as [`crate::newton`]'s objective.
struct Likelihood<'a> {
    pairs: &'a [TiePair],
    column: &'a [Option<usize>],
    with_nu: bool,
}

impl crate::newton::Concave for Likelihood<'_> {
    type Failure = DavidsonFailure;

    fn value(&self, beta: &[f64]) -> f64 {
        evaluate(self.pairs, self.column, beta, self.with_nu, None)
    }

    /// I⁻¹U; an estimate beyond |40| is running off to infinity (separation).
    fn step(&self, beta: &[f64]) -> Result<Vec<f64>, DavidsonFailure> {
        if beta.iter().any(|b| b.abs() > 40.0) {
            return Err(DavidsonFailure::Separation);
        }
        let q = beta.len();
        let (mut score, mut information) = (vec![0.0; q], vec![0.0; q * q]);
        evaluate(self.pairs, self.column, beta, self.with_nu, Some((&mut score, &mut information)));
        let l = crate::newton::cholesky(&information, q).ok_or(DavidsonFailure::Separation)?;
        Ok(crate::newton::solve(&l, &score))
    }
}

/// Fits the Davidson model to the pairs of `n_conditions` conditions (each compared at least
/// once, the graph connected), with `reference`'s log-worth 0. Iterates until no parameter
/// moves by more than `tolerance`.
pub fn fit(
    n_conditions: usize,
    pairs: &[TiePair],
    reference: usize,
    tolerance: f64,
) -> Result<DavidsonFit, DavidsonFailure> {
    // connected, every condition compared
    let mut seen = vec![false; n_conditions];
    let mut stack = vec![reference];
    seen[reference] = true;
    while let Some(c) = stack.pop() {
        for pair in pairs.iter().filter(|p| p.wins_i + p.wins_j + p.ties > 0.0) {
            for (x, y) in [(pair.i, pair.j), (pair.j, pair.i)] {
                if x == c && !seen[y] {
                    seen[y] = true;
                    stack.push(y);
                }
            }
        }
    }
    if let Some(condition) = seen.iter().position(|s| !s) {
        return Err(DavidsonFailure::Disconnected { condition });
    }
    let total_ties: f64 = pairs.iter().map(|p| p.ties).sum();
    let total: f64 = pairs.iter().map(|p| p.wins_i + p.wins_j + p.ties).sum();
    let with_nu = total_ties > 0.0;
    let mut column = vec![None; n_conditions];
    let mut k = 0;
    for (c, slot) in column.iter_mut().enumerate() {
        if c != reference {
            *slot = Some(k);
            k += 1;
        }
    }
    let q = k + usize::from(with_nu);
    let mut beta = vec![0.0; q];
    if with_nu {
        // ν's start: the tie share against the decided share, as if all worths were equal
        let decided = (total - total_ties).max(0.5);
        beta[q - 1] = (2.0 * total_ties / decided).ln();
    }
    let problem = Likelihood { pairs, column: &column, with_nu };
    let settings = crate::newton::Settings { tolerance, max_iterations: 200, min_scale: 1e-6 };
    let maximum = crate::newton::maximise(&problem, beta, settings).map_err(|stop| match stop {
        crate::newton::Stop::Failed(failure) => failure,
        crate::newton::Stop::NotFinite => DavidsonFailure::Separation,
        crate::newton::Stop::NotConverged { iterations, last_change, .. } => {
            DavidsonFailure::NotConverged { iterations, last_change }
        }
    })?;
    let beta = maximum.beta;
    if beta.iter().any(|b| b.abs() > 40.0) {
        return Err(DavidsonFailure::Separation);
    }
    let (mut score, mut information) = (vec![0.0; q], vec![0.0; q * q]);
    evaluate(pairs, &column, &beta, with_nu, Some((&mut score, &mut information)));
    let l = crate::newton::cholesky(&information, q).ok_or(DavidsonFailure::Separation)?;
    let inverse = crate::newton::inverse(&l, q);
    let log_worth = (0..n_conditions).map(|c| column[c].map_or(0.0, |k| beta[k]) + 0.0).collect();
    let se = (0..n_conditions).map(|c| column[c].map_or(0.0, |k| inverse[k * q + k].sqrt())).collect();
    let (nu, nu_se) = if with_nu {
        let nu = beta[q - 1].exp();
        (nu, Some(nu * inverse[(q - 1) * q + q - 1].sqrt()))
    } else {
        (0.0, None)
    };
    Ok(DavidsonFit { log_worth, se, nu, nu_se, log_likelihood: maximum.value, iterations: maximum.iterations })
}

/// One condition in the `davidson` section.
#[derive(Debug, Clone, serde::Serialize)]
pub struct DavidsonItem {
    pub condition: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub log_worth: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub se: Option<f64>,
}

/// The `davidson` section of the Analysis JSON.
#[derive(Debug, Clone, serde::Serialize)]
pub struct DavidsonSection {
    pub items: Vec<DavidsonItem>,
    pub nu: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nu_se: Option<f64>,
    /// Judgments answered `tie`.
    pub ties: u64,
    pub log_likelihood: f64,
}

/// The Davidson fit of the active participants' choices and ties over the compared conditions,
/// `reference` at 0, or why it could not be fitted.
pub fn section(
    tallies: &crate::design::ParticipantTallies,
    ties: &[crate::data::Judgment],
    active: &[usize],
    condition_names: &[String],
    reference: usize,
    tolerance: f64,
) -> Result<DavidsonSection, DavidsonFailure> {
    let n = condition_names.len();
    let mut table = vec![[0.0f64; 3]; n * n];
    for pair in tallies.pooled(n, active) {
        let cell = &mut table[pair.i * n + pair.j];
        cell[0] += pair.wins_i as f64;
        cell[1] += pair.wins_j as f64;
    }
    let mut tie_count = 0;
    for tie in ties {
        let (i, j) = (tie.left.min(tie.right) as usize, tie.left.max(tie.right) as usize);
        table[i * n + j][2] += tie.count as f64;
        tie_count += tie.count;
    }
    let compared: Vec<usize> =
        (0..n).filter(|&c| (0..n).any(|d| table[c.min(d) * n + c.max(d)].iter().sum::<f64>() > 0.0)).collect();
    let mut local = vec![usize::MAX; n];
    for (k, &c) in compared.iter().enumerate() {
        local[c] = k;
    }
    let pairs: Vec<TiePair> = (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
        .filter(|&(i, j)| table[i * n + j].iter().sum::<f64>() > 0.0)
        .map(|(i, j)| {
            let [a, b, t] = table[i * n + j];
            TiePair { i: local[i], j: local[j], wins_i: a, wins_j: b, ties: t }
        })
        .collect();
    let reference = if local[reference] == usize::MAX { compared[0] } else { reference };
    let fitted = fit(compared.len(), &pairs, local[reference], tolerance)?;
    let items = (0..n)
        .map(|c| DavidsonItem {
            condition: condition_names[c].clone(),
            log_worth: (local[c] != usize::MAX).then(|| fitted.log_worth[local[c]]),
            se: (local[c] != usize::MAX).then(|| fitted.se[local[c]]),
        })
        .collect();
    Ok(DavidsonSection {
        items,
        nu: fitted.nu,
        nu_se: fitted.nu_se,
        ties: tie_count,
        log_likelihood: fitted.log_likelihood,
    })
}

#[cfg(test)]
mod tests;
