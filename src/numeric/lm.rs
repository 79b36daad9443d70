//! One damped Levenberg-Marquardt solver for the small dense problems of this crate: the pose of
//! a superquadric (5 or 6 parameters), the rigid pose of a compound object (6), and a learned
//! superquadric's shape and pose (13).
//!
//! Hand-written rather than the `levenberg-marquardt` crate (`benches/lm.rs` compares the two):
//! every problem here has at most 13 parameters, so the normal equations are a fixed-size system
//! that a problem builds in one pass over its points without storing an n x N Jacobian; the
//! parameters live on a manifold (poses, bounded sizes), so a problem applies its own step; and a
//! problem decides whether one pass yields the cost and the normal equations together (cheap to
//! keep for a candidate that is then accepted) or the cost alone (cheap to reject).

use nalgebra::{SMatrix, SVector};

/// A least-squares problem in `N` parameters: `cost(x) = sum_i w_i r_i(x)^2`.
pub trait LeastSquares<const N: usize> {
    /// The parameters (a pose, a shape and pose...).
    type Params: Clone;
    /// What an evaluation keeps for linearising at the same parameters: the residuals, or the
    /// normal equations themselves when they come from the same pass as the cost.
    type Evaluation;

    /// The cost at `x` and what [`LeastSquares::linearize`] needs there.
    fn evaluate(&self, x: &Self::Params) -> (f64, Self::Evaluation);

    /// The Gauss-Newton matrix `J^T W J` and the gradient `J^T W r` at `x`, given `x`'s
    /// evaluation.
    fn linearize(&self, x: &Self::Params, at: &Self::Evaluation) -> (SMatrix<f64, N, N>, SVector<f64, N>);

    /// The parameters moved by `delta` (on the manifold, within the bounds).
    fn step(&self, x: &Self::Params, delta: &SVector<f64, N>) -> Self::Params;
}

/// How the damping term is added to the diagonal of the normal matrix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Damping {
    /// `lambda * max(h_kk, floor)`: Marquardt's scaling, with a floor so that a zero column
    /// cannot make a zero pivot.
    Marquardt { floor: f64 },
    /// `lambda * (h_kk + share * trace(H) / N + floor)`: Marquardt's scaling plus a share of the
    /// mean diagonal, for parameters of very different scales (log sizes, exponents, angles,
    /// metres) some of which a problem may hold fixed (a zero column).
    MarquardtPlusMean { share: f64, floor: f64 },
}

/// What `max_iterations` counts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Budget {
    /// Every solve of the damped system, accepted or not (a fixed cost per fit: the detector's
    /// thousands of pose fits).
    Attempts,
    /// Accepted steps, each with a new linearisation; rejected ones only raise the damping.
    Steps,
}

/// The solver's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmSettings {
    pub max_iterations: usize,
    pub budget: Budget,
    /// Stop after an accepted step that lowers the cost by less than this share.
    pub rel_tol: f64,
    pub damping: Damping,
    pub lambda_start: f64,
    /// The damping is multiplied by this after an accepted step...
    pub lambda_down: f64,
    /// ...but not below this,
    pub lambda_min: f64,
    /// and by this after a rejected step or a failed factorisation.
    pub lambda_up: f64,
    /// Attempts are made while the damping is at most this; past it the step is too small to
    /// matter and the solver stops.
    pub lambda_max: f64,
}

impl LmSettings {
    /// The settings of the detector's pose fits: `max_iterations` attempts, Marquardt damping
    /// from 1e-3, up 10x and down 10x, given up past 1e8.
    pub fn attempts(max_iterations: usize, rel_tol: f64) -> LmSettings {
        LmSettings {
            max_iterations,
            budget: Budget::Attempts,
            rel_tol,
            damping: Damping::Marquardt { floor: 1e-12 },
            lambda_start: 1e-3,
            lambda_down: 0.1,
            lambda_min: 1e-9,
            lambda_up: 10.0,
            lambda_max: 1e8,
        }
    }
}

/// Where the solver stopped.
#[derive(Debug, Clone)]
pub struct Minimum<P> {
    pub x: P,
    pub cost: f64,
    /// Solves of the damped system made.
    pub attempts: usize,
    /// Steps accepted.
    pub steps: usize,
}

/// Minimise `problem` from `start`. The cost never rises: the result is `start` when no step
/// lowered it.
pub fn minimize<const N: usize, P: LeastSquares<N>>(
    problem: &P,
    start: P::Params,
    s: &LmSettings,
) -> Minimum<P::Params> {
    let mut x = start;
    let (mut cost, mut at) = problem.evaluate(&x);
    let mut lambda = s.lambda_start;
    let (mut attempts, mut steps) = (0, 0);
    'steps: loop {
        if s.budget == Budget::Steps && steps >= s.max_iterations {
            break;
        }
        let (h, g) = problem.linearize(&x, &at);
        let scale: SVector<f64, N> = match s.damping {
            Damping::Marquardt { floor } => SVector::from_fn(|k, _| h[(k, k)].max(floor)),
            Damping::MarquardtPlusMean { share, floor } => {
                let mean = share * h.trace() / N as f64;
                SVector::from_fn(|k, _| h[(k, k)] + mean + floor)
            }
        };
        loop {
            if lambda > s.lambda_max || (s.budget == Budget::Attempts && attempts >= s.max_iterations) {
                break 'steps;
            }
            attempts += 1;
            let mut a = h;
            for k in 0..N {
                a[(k, k)] += lambda * scale[k];
            }
            let Some(chol) = a.cholesky() else {
                lambda *= s.lambda_up;
                continue;
            };
            let candidate = problem.step(&x, &chol.solve(&(-g)));
            let (c1, at1) = problem.evaluate(&candidate);
            if c1.is_finite() && c1 < cost {
                let relative = (cost - c1) / cost.max(1e-300);
                (x, cost, at) = (candidate, c1, at1);
                lambda = (lambda * s.lambda_down).max(s.lambda_min);
                steps += 1;
                if relative < s.rel_tol {
                    break 'steps;
                }
                continue 'steps;
            }
            lambda *= s.lambda_up;
        }
    }
    Minimum {
        x,
        cost,
        attempts,
        steps,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Vector2};

    /// Rosenbrock's function as least squares: r = (10 (y - x^2), 1 - x).
    struct Rosenbrock;

    impl LeastSquares<2> for Rosenbrock {
        type Params = Vector2<f64>;
        type Evaluation = ();
        fn evaluate(&self, p: &Vector2<f64>) -> (f64, ()) {
            let r = [10.0 * (p.y - p.x * p.x), 1.0 - p.x];
            (r[0] * r[0] + r[1] * r[1], ())
        }
        fn linearize(&self, p: &Vector2<f64>, _: &()) -> (Matrix2<f64>, Vector2<f64>) {
            let r = Vector2::new(10.0 * (p.y - p.x * p.x), 1.0 - p.x);
            let j = Matrix2::new(-20.0 * p.x, 10.0, -1.0, 0.0);
            (j.transpose() * j, j.transpose() * r)
        }
        fn step(&self, p: &Vector2<f64>, d: &Vector2<f64>) -> Vector2<f64> {
            p + d
        }
    }

    #[test]
    fn finds_rosenbrocks_minimum() {
        let mut s = LmSettings::attempts(200, 1e-15);
        s.budget = Budget::Steps;
        let m = minimize(&Rosenbrock, Vector2::new(-1.2, 1.0), &s);
        assert!((m.x - Vector2::new(1.0, 1.0)).norm() < 1e-6, "{:?}", m.x);
        assert!(m.cost < 1e-12);
        assert!(m.steps <= m.attempts);
    }

    #[test]
    fn an_attempt_budget_bounds_the_work_and_the_cost_never_rises() {
        let start = Vector2::new(-1.2, 1.0);
        let c0 = Rosenbrock.evaluate(&start).0;
        let m = minimize(&Rosenbrock, start, &LmSettings::attempts(3, 0.0));
        assert_eq!(m.attempts, 3);
        assert!(m.cost <= c0);
    }
}
