//! Newton–Raphson for a concave objective (a log-likelihood or log-posterior): the one loop of
//! the Bradley–Terry fit ([`crate::fit::fit_ml`]), Davidson's tie model
//! ([`crate::scales::davidson::fit`]) and the active selection's Laplace refit
//! ([`crate::active::laplace::refit`]), and the dense Cholesky factorisation, solve and inverse
//! their steps, observer screening's leave-one-out steps and the standard errors use.
//!
//! Each iteration takes the model's Newton step I(β)⁻¹U(β), halved until the objective does not
//! fall by more than 1e-12 of its size (or the step is below `min_scale` of the full one, then
//! taken as it is); converged when no parameter moved by more than `tolerance`.

/// An objective to maximise and its Newton step.
pub(crate) trait Concave {
    /// Why the model has no step at some β (singular information, a diverging estimate).
    type Failure;
    /// The objective at `beta`.
    fn value(&self, beta: &[f64]) -> f64;
    /// The Newton step at `beta`: the inverse information (or negative Hessian) times the score.
    fn step(&self, beta: &[f64]) -> Result<Vec<f64>, Self::Failure>;
}

/// Convergence settings of [`maximise`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct Settings {
    /// Converged when the largest parameter change of an iteration is below this.
    pub(crate) tolerance: f64,
    pub(crate) max_iterations: usize,
    /// The step halving stops (and takes the step) below this fraction of the full step.
    pub(crate) min_scale: f64,
}

/// Where [`maximise`] converged.
#[derive(Debug, Clone)]
pub(crate) struct Maximum {
    pub(crate) beta: Vec<f64>,
    pub(crate) value: f64,
    pub(crate) iterations: usize,
}

/// Why [`maximise`] stopped without converging.
#[derive(Debug, Clone)]
pub(crate) enum Stop<F> {
    /// The model had no step.
    Failed(F),
    /// A step was not finite.
    NotFinite,
    /// No convergence in `iterations`; `beta` is where it stopped, `last_change` the last
    /// iteration's largest parameter change.
    NotConverged { beta: Vec<f64>, iterations: usize, last_change: f64 },
}

/// Newton–Raphson with step halving from `start`.
pub(crate) fn maximise<P: Concave>(
    problem: &P,
    start: Vec<f64>,
    settings: Settings,
) -> Result<Maximum, Stop<P::Failure>> {
    let mut beta = start;
    let mut value = problem.value(&beta);
    let mut last_change = f64::INFINITY;
    for iteration in 1..=settings.max_iterations {
        let step = problem.step(&beta).map_err(Stop::Failed)?;
        let mut scale = 1.0;
        let mut candidate;
        let mut candidate_value;
        loop {
            candidate = beta.iter().zip(&step).map(|(b, s)| b + scale * s).collect::<Vec<_>>();
            candidate_value = problem.value(&candidate);
            if candidate_value >= value - 1e-12 * value.abs().max(1.0) || scale < settings.min_scale {
                break;
            }
            scale *= 0.5;
        }
        last_change = step.iter().map(|s| (scale * s).abs()).fold(0.0, f64::max);
        if !last_change.is_finite() {
            return Err(Stop::NotFinite);
        }
        beta = candidate;
        value = candidate_value;
        if last_change < settings.tolerance {
            return Ok(Maximum { beta, value, iterations: iteration });
        }
    }
    Err(Stop::NotConverged { beta, iterations: settings.max_iterations, last_change })
}

/// The Cholesky factor L (row-major, lower; L·Lᵀ = A) of a symmetric positive-definite q×q
/// matrix, read from its lower triangle; `None` if it is not positive definite.
pub(crate) fn cholesky(a: &[f64], q: usize) -> Option<Vec<f64>> {
    let mut l = vec![0.0; q * q];
    for i in 0..q {
        for j in 0..=i {
            let sum: f64 = (0..j).map(|k| l[i * q + k] * l[j * q + k]).sum();
            if i == j {
                let d = a[i * q + i] - sum;
                if !(d > 0.0 && d.is_finite()) {
                    return None;
                }
                l[i * q + i] = d.sqrt();
            } else {
                l[i * q + j] = (a[i * q + j] - sum) / l[j * q + j];
            }
        }
    }
    Some(l)
}

/// Solves L·Lᵀ·x = b for the factor `l` of [`cholesky`].
pub(crate) fn solve(l: &[f64], b: &[f64]) -> Vec<f64> {
    let q = b.len();
    let mut y = b.to_vec();
    for i in 0..q {
        let sum: f64 = (0..i).map(|k| l[i * q + k] * y[k]).sum();
        y[i] = (y[i] - sum) / l[i * q + i];
    }
    for i in (0..q).rev() {
        let sum: f64 = (i + 1..q).map(|k| l[k * q + i] * y[k]).sum();
        y[i] = (y[i] - sum) / l[i * q + i];
    }
    y
}

/// The inverse (row-major q×q) of L·Lᵀ for the factor `l` of [`cholesky`].
pub(crate) fn inverse(l: &[f64], q: usize) -> Vec<f64> {
    let mut inverse = vec![0.0; q * q];
    let mut unit = vec![0.0; q];
    for column in 0..q {
        unit.fill(0.0);
        unit[column] = 1.0;
        for (row, x) in solve(l, &unit).into_iter().enumerate() {
            inverse[row * q + column] = x;
        }
    }
    inverse
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ℓ(β) = −½ (β − m)ᵀ A (β − m): one full Newton step from anywhere lands on m.
    struct Quadratic {
        a: Vec<f64>,
        m: Vec<f64>,
    }

    impl Concave for Quadratic {
        type Failure = ();
        fn value(&self, beta: &[f64]) -> f64 {
            let d: Vec<f64> = beta.iter().zip(&self.m).map(|(b, m)| b - m).collect();
            let q = d.len();
            -0.5 * (0..q).map(|i| (0..q).map(|j| d[i] * self.a[i * q + j] * d[j]).sum::<f64>()).sum::<f64>()
        }
        fn step(&self, beta: &[f64]) -> Result<Vec<f64>, ()> {
            let l = cholesky(&self.a, beta.len()).ok_or(())?;
            let q = beta.len();
            let score: Vec<f64> =
                (0..q).map(|i| -(0..q).map(|j| self.a[i * q + j] * (beta[j] - self.m[j])).sum::<f64>()).collect();
            Ok(solve(&l, &score))
        }
    }

    #[test]
    fn a_quadratic_is_maximised_in_one_step_and_its_inverse_is_exact() {
        let a = vec![4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0];
        let problem = Quadratic { a: a.clone(), m: vec![1.0, -2.0, 0.5] };
        let settings = Settings { tolerance: 1e-12, max_iterations: 10, min_scale: 1e-6 };
        let found = maximise(&problem, vec![0.0; 3], settings).unwrap();
        for (b, m) in found.beta.iter().zip(&problem.m) {
            assert!((b - m).abs() < 1e-12, "{:?}", found.beta);
        }
        assert_eq!(found.iterations, 2, "one step to the maximum, one that moves nothing");
        let inverse = inverse(&cholesky(&a, 3).unwrap(), 3);
        for i in 0..3 {
            for j in 0..3 {
                let product: f64 = (0..3).map(|k| a[i * 3 + k] * inverse[k * 3 + j]).sum();
                assert!((product - f64::from(u8::from(i == j))).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn a_matrix_that_is_not_positive_definite_has_no_factor() {
        assert!(cholesky(&[1.0, 2.0, 2.0, 1.0], 2).is_none());
        assert!(cholesky(&[f64::INFINITY], 1).is_none());
    }
}
