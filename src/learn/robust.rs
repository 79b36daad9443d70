//! The robust fit: IRLS with redescending Huber weights around the one Levenberg-Marquardt solver
//! ([`crate::numeric::lm`]), with the Jacobian of [`super::gradient`] (forward differences for
//! the costs it does not differentiate).

use super::residual::{Problem, RayRead};
use super::state::{Mat, NP, State, Vect};
use crate::numeric::{Budget, Damping, LeastSquares, LmSettings, huber_weight, median, minimize};
use rayon::prelude::*;

/// Weighted LM with a forward-difference Jacobian, bounds by projection.
pub(super) fn lm(problem: &Problem, start: State, weights: &[f64], iterations: usize) -> State {
    let settings = LmSettings {
        max_iterations: iterations,
        budget: Budget::Steps,
        rel_tol: 1e-7,
        damping: Damping::MarquardtPlusMean {
            share: 1e-9,
            floor: 1e-12,
        },
        lambda_start: 1e-3,
        lambda_down: 0.2,
        lambda_min: 1e-9,
        lambda_up: 10.0,
        // Attempts below 1e10.
        lambda_max: 1e10_f64.next_down(),
    };
    minimize(&Weighted { problem, weights }, start, &settings).x
}

/// A learning problem with IRLS weights on its residuals.
pub(super) struct Weighted<'a> {
    problem: &'a Problem<'a>,
    weights: &'a [f64],
}

impl LeastSquares<NP> for Weighted<'_> {
    type Params = State;
    /// The residuals, and what the points' rays read (where the Jacobian is taken).
    type Evaluation = (Vec<f64>, Vec<Option<RayRead>>);

    fn evaluate(&self, s: &State) -> (f64, Self::Evaluation) {
        let mut r = Vec::with_capacity(self.problem.len());
        let mut reads = Vec::new();
        let record = self.problem.rays.is_some().then_some(&mut reads);
        self.problem.residuals_read(s, &mut r, record);
        let cost = r.iter().zip(self.weights).map(|(r, w)| w * r * r).sum::<f64>();
        (cost, (r, reads))
    }

    fn linearize(&self, s: &State, (r0, reads): &Self::Evaluation) -> (Mat, Vect) {
        super::gradient::normal_equations(self.problem, s, r0, reads, self.weights)
            .unwrap_or_else(|| forward_differences(self.problem, s, r0, self.weights))
    }

    fn step(&self, s: &State, d: &Vect) -> State {
        s.step(d)
    }
}

/// `J^T W J` and `J^T W r` by forward differences of every residual (the costs
/// [`super::gradient`] does not differentiate, and its reference in the tests).
pub(super) fn forward_differences(problem: &Problem, s: &State, r0: &[f64], weights: &[f64]) -> (Mat, Vect) {
    let n = problem.len();
    // The columns in parallel: the later stages fit one start at a time, and a residual
    // evaluation (thousands of points and free-space samples, the seen-surface queries)
    // is the whole cost. The same arithmetic as one after the other, so the same result.
    let columns: Vec<Option<(Vec<f64>, f64)>> = (0..NP)
        .into_par_iter()
        .map(|k| {
            let (sk, h) = super::gradient::column_step(problem, s, k)?;
            let mut r = Vec::with_capacity(n);
            problem.residuals(&sk, &mut r);
            Some((r, h))
        })
        .collect();
    let mut h = Mat::zeros();
    let mut g = Vect::zeros();
    for i in 0..n {
        let w = weights[i];
        if w == 0.0 || !r0[i].is_finite() {
            continue;
        }
        let j = Vect::from_fn(|k, _| columns[k].as_ref().map_or(0.0, |(r, h)| (r[i] - r0[i]) / h));
        if j.iter().any(|v| !v.is_finite()) {
            continue;
        }
        h.ger(w, &j, &j, 1.0);
        g += j * (w * r0[i]);
    }
    (h, g)
}

/// IRLS around LM: Huber weights from the robust spread of the residuals, re-estimated each round.
/// Returns the state, the final Huber threshold and the residuals.
pub(super) fn robust_fit(
    problem: &Problem,
    start: State,
    rounds: usize,
    iterations: usize,
    min_delta: f64,
) -> (State, f64) {
    let n = problem.len();
    let mut s = start;
    let mut weights = vec![1.0; n];
    let mut r = Vec::with_capacity(n);
    let mut delta = f64::INFINITY;
    for round in 0..rounds {
        if round > 0 {
            problem.residuals(&s, &mut r);
            let mut abs: Vec<f64> = r[..problem.points.len()].iter().map(|v| v.abs()).collect();
            delta = (2.0 * 1.4826 * median(&mut abs).unwrap_or(0.0)).max(min_delta);
            for (w, v) in weights.iter_mut().zip(&r) {
                *w = huber_weight(*v, delta);
            }
            // The support term is not data: always full weight.
            for w in weights.iter_mut().skip(problem.points.len() + problem.free.len()) {
                *w = 1.0;
            }
        }
        s = lm(problem, s, &weights, iterations);
    }
    (s, delta)
}
