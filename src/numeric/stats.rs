//! Order statistics and robust weights.

/// The value at quantile `q` (0..=1) of `values`, the element at index `round((n - 1) q)` in
/// sorted order (for `q = 0.5`: the middle one, the upper of the two for an even count); `None`
/// when there are no values. Reorders `values` (a selection, not a full sort).
pub fn quantile(values: &mut [f64], q: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let k = ((values.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
    Some(*values.select_nth_unstable_by(k, f64::total_cmp).1)
}

/// The direction in which `points` spread least (unit length, either sign): the normal of the
/// plane through them. `points` must not be empty.
pub fn least_spread_direction(points: &[nalgebra::Vector3<f64>]) -> nalgebra::Vector3<f64> {
    let n = points.len() as f64;
    let mean = points.iter().sum::<nalgebra::Vector3<f64>>() / n;
    let cov = points.iter().fold(nalgebra::Matrix3::zeros(), |c, q| {
        c + (q - mean) * (q - mean).transpose()
    }) / n;
    let eig = cov.symmetric_eigen();
    eig.eigenvectors.column(eig.eigenvalues.imin()).into_owned()
}

/// The median of `values` (the upper middle one for an even count); `None` when empty.
/// Reorders `values`.
pub fn median(values: &mut [f64]) -> Option<f64> {
    quantile(values, 0.5)
}

/// Residuals beyond this many Huber thresholds get no weight in [`huber_weight`].
pub const OUTLIER_DELTAS: f64 = 5.0;

/// The IRLS weight of a residual `r` under a redescending Huber loss with threshold `delta`: 1
/// within `delta`, `delta / |r|` out to [`OUTLIER_DELTAS`] thresholds, 0 beyond.
#[inline]
pub fn huber_weight(r: f64, delta: f64) -> f64 {
    let a = r.abs();
    if a <= delta {
        1.0
    } else if a <= OUTLIER_DELTAS * delta {
        delta / a
    } else {
        // Redescending, as a uniform outlier component would be: a point this far off is no
        // evidence about the surface at all (Huber alone lets a few stereo strays 20 cm behind a
        // can pull its hidden back out to them).
        0.0
    }
}

/// The Huber loss of a residual: quadratic within `delta`, linear beyond.
#[inline]
pub fn huber(r: f64, delta: f64) -> f64 {
    let a = r.abs();
    if a <= delta {
        0.5 * r * r
    } else {
        delta * (a - 0.5 * delta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_is_the_middle_or_the_upper_middle() {
        assert_eq!(median(&mut []), None);
        assert_eq!(median(&mut [3.0]), Some(3.0));
        assert_eq!(median(&mut [5.0, 1.0, 3.0]), Some(3.0));
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), Some(3.0));
    }

    #[test]
    fn quantile_rounds_its_index() {
        let mut v: Vec<f64> = (0..21).rev().map(f64::from).collect();
        assert_eq!(quantile(&mut v, 0.95), Some(19.0));
        assert_eq!(quantile(&mut v, 0.0), Some(0.0));
        assert_eq!(quantile(&mut v, 1.0), Some(20.0));
    }

    #[test]
    fn huber_weight_redescends() {
        assert_eq!(huber_weight(0.5, 1.0), 1.0);
        assert_eq!(huber_weight(-2.0, 1.0), 0.5);
        assert_eq!(huber_weight(5.5, 1.0), 0.0);
        assert_eq!(huber(2.0, 1.0), 1.5);
    }
}
