//! The circle of a round object's wall seen from one side, in the support plane's basis: what
//! [`super::prism`] takes a standing can's or tin's cross-section from where the wall shows
//! enough of it (the top's outline loses its edge to the sensor).

use nalgebra::{Vector2, Vector3};

/// Wall points at least, and the least arc (rad) they span about the circle fitted to them, for
/// that circle to give the cross-section.
const WALL_MIN_POINTS: usize = 100;
const WALL_MIN_ARC: f64 = std::f64::consts::FRAC_PI_3;
/// Largest median distance of the wall points from their circle (m): a wall, not clutter.
const WALL_MAX_RESIDUAL: f64 = 0.003;

/// The circle through a round object's wall points (in the plane's basis): an algebraic fit
/// (Kasa) to start, then Gauss-Newton steps on the distances (the algebraic fit shrinks a circle
/// fitted to a short arc), again on the points within three median distances of it (a mug's
/// handle, a neighbour's fragment). The reason it cannot be trusted otherwise: too few points,
/// too short an arc, a spread too wide for a wall.
pub(super) fn wall_circle(wall: &[Vector2<f64>]) -> Result<(Vector2<f64>, f64), String> {
    if wall.len() < WALL_MIN_POINTS {
        return Err(format!("{} points on the wall", wall.len()));
    }
    // x^2 + y^2 + D x + E y + F = 0, least squares, about the points' mean for conditioning.
    let mean = wall.iter().sum::<Vector2<f64>>() / wall.len() as f64;
    let local: Vec<Vector2<f64>> = wall.iter().map(|q| q - mean).collect();
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut atb = Vector3::<f64>::zeros();
    for d in &local {
        let row = Vector3::new(d.x, d.y, 1.0);
        ata += row * row.transpose();
        atb += row * -(d.norm_squared());
    }
    let Some(sol) = ata.lu().solve(&atb) else {
        return Err("the wall's points lie on a line".into());
    };
    let c = Vector2::new(-0.5 * sol.x, -0.5 * sol.y);
    let r2 = c.norm_squared() - sol.z;
    if !(r2 > 0.0) {
        return Err("no circle through the wall's points".into());
    }
    let (c, r) = circle_steps(&local, c, r2.sqrt());
    let residual_of = |c: Vector2<f64>, r: f64, pts: &[Vector2<f64>]| {
        let mut res: Vec<f64> = pts.iter().map(|d| ((d - c).norm() - r).abs()).collect();
        crate::numeric::quantile(&mut res, 0.5).unwrap_or(f64::INFINITY)
    };
    let keep = 3.0 * residual_of(c, r, &local);
    let kept: Vec<Vector2<f64>> = local
        .iter()
        .filter(|d| ((*d - c).norm() - r).abs() <= keep)
        .copied()
        .collect();
    if kept.len() < WALL_MIN_POINTS {
        return Err(format!("{} points on the wall's circle", kept.len()));
    }
    let (c, r) = circle_steps(&kept, c, r);
    if !(r.is_finite() && r > 0.0) {
        return Err("the wall's circle did not converge".into());
    }
    let residual = residual_of(c, r, &kept);
    if residual > WALL_MAX_RESIDUAL {
        return Err(format!(
            "the wall's points lie {:.1} mm from their circle (median)",
            residual * 1e3
        ));
    }
    // The arc: the largest gap between the points' directions about the centre leaves the rest.
    let mut angles: Vec<f64> = kept.iter().map(|d| (d - c).y.atan2((d - c).x)).collect();
    angles.sort_by(f64::total_cmp);
    let gap = angles
        .windows(2)
        .map(|w| w[1] - w[0])
        .chain(std::iter::once(
            angles[0] + std::f64::consts::TAU - angles[angles.len() - 1],
        ))
        .fold(0.0, f64::max);
    let arc = std::f64::consts::TAU - gap;
    if arc < WALL_MIN_ARC {
        return Err(format!("the wall shows {:.0} degrees of its circle", arc.to_degrees()));
    }
    Ok((c + mean, r))
}

/// Gauss-Newton steps on the points' distances from the circle (centre `c`, radius `r`).
fn circle_steps(points: &[Vector2<f64>], mut c: Vector2<f64>, mut r: f64) -> (Vector2<f64>, f64) {
    for _ in 0..10 {
        let mut jtj = nalgebra::Matrix3::<f64>::zeros();
        let mut jtr = Vector3::<f64>::zeros();
        for d in points {
            let v = d - c;
            let dist = v.norm();
            if dist < 1e-9 {
                continue;
            }
            let u = v / dist;
            let row = Vector3::new(-u.x, -u.y, -1.0);
            jtj += row * row.transpose();
            jtr += row * (dist - r);
        }
        let Some(step) = jtj.lu().solve(&(-jtr)) else { break };
        c += Vector2::new(step.x, step.y);
        r += step.z;
        if step.norm() < 1e-7 {
            break;
        }
    }
    (c, r)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wall_seen_along_a_short_arc_or_too_few_points_keeps_the_top() {
        let arc: Vec<Vector2<f64>> = (0..200)
            .map(|k| {
                let t = -std::f64::consts::FRAC_PI_2 + 0.5 * (k as f64 / 200.0);
                Vector2::new(0.05 * t.cos(), 0.05 * t.sin())
            })
            .collect();
        assert!(wall_circle(&arc).unwrap_err().contains("degrees"));
        assert!(wall_circle(&arc[..20]).unwrap_err().contains("points"));
        let line: Vec<Vector2<f64>> = (0..200).map(|k| Vector2::new(k as f64 * 1e-3, 0.0)).collect();
        assert!(wall_circle(&line).is_err());
    }
}
