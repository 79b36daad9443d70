//! Whether what was found looks like what was shown. Geometry seen from one side cannot tell
//! two objects of one size and shape apart (a cereal box from another of its size, a floral
//! canister from the end of a can lying behind something), and a scan seldom shows the side that
//! would. Where the sensor gives each point a colour (an RGB-D camera, a colour line scanner such
//! as SICK's ColorRanger), the learner keeps the colours of the object's points as a histogram
//! ([`crate::model::Model::colour`]), and a detection whose surface points share less than
//! [`MIN_SIMILARITY`] of it is not the object (`detect::check_colour`, where the scene's
//! colours are at hand).
//!
//! The histogram is of chromaticity, `r = R / (R + G + B)` and `g = G / (R + G + B)`, not of
//! RGB: it leaves out the brightness, which the light and the angle of a face to it change from
//! scene to scene, and keeps hue and saturation, which they change much less. Similarity is the
//! histograms' intersection (the share of one that the other holds): 1 for the same colours, 0
//! for none in common. A box shows another face elsewhere, and a face seen at a grazing angle
//! or half in shadow shifts its colours: the bar is low, to reject colours that have little to
//! do with the object's (a yellow box for a green one, a white canister for an orange can), not
//! to tell prints apart.

/// Bins along each chromaticity coordinate.
pub const BINS: usize = 10;
/// Chromaticity coordinates at or above this fall in the last bin: only deep reds and greens
/// reach it, and they need no finer bins.
pub const RANGE: f64 = 0.7;
/// A histogram of fewer points says too little: no check.
pub const MIN_POINTS: usize = 30;
/// A detection whose surface's histogram shares less than this with the model's is not the
/// object. The instances of the twelve objects of the real table scenes found by geometry
/// share 0.45 to 0.98 with the view each was learned from; the other objects the geometry
/// takes for them, 0.16 and up.
pub const MIN_SIMILARITY: f64 = 0.35;

/// A normalized chromaticity histogram of `colours` (`BINS * BINS` shares, `r` major, summing
/// to 1); `None` below [`MIN_POINTS`].
pub fn histogram(colours: impl IntoIterator<Item = [u8; 3]>) -> Option<Vec<f64>> {
    let mut h = vec![0.0; BINS * BINS];
    let mut n = 0usize;
    for [r, g, b] in colours {
        // +1: a black point has no chromaticity; it counts as grey.
        let (r, g, b) = (f64::from(r) + 1.0, f64::from(g) + 1.0, f64::from(b) + 1.0);
        let s = r + g + b;
        let bin = |x: f64| ((x / s / RANGE * BINS as f64) as usize).min(BINS - 1);
        h[bin(r) * BINS + bin(g)] += 1.0;
        n += 1;
    }
    if n < MIN_POINTS {
        return None;
    }
    for v in &mut h {
        *v /= n as f64;
    }
    Some(h)
}

/// The share of histogram `a` that `b` holds (their intersection): 1 for equal histograms.
pub fn similarity(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x.min(*y)).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_colours_are_similar_and_others_not() {
        let yellow = histogram(std::iter::repeat_n([230, 200, 40], 100)).unwrap();
        let darker_yellow = histogram(std::iter::repeat_n([115, 100, 20], 100)).unwrap();
        let green = histogram(std::iter::repeat_n([60, 160, 60], 100)).unwrap();
        assert!(
            (similarity(&yellow, &darker_yellow) - 1.0).abs() < 1e-9,
            "brightness is left out"
        );
        assert_eq!(similarity(&yellow, &green), 0.0);
        let half: Vec<[u8; 3]> = (0..100)
            .map(|i| if i % 2 == 0 { [230, 200, 40] } else { [60, 160, 60] })
            .collect();
        assert!((similarity(&yellow, &histogram(half).unwrap()) - 0.5).abs() < 1e-9);
    }

    #[test]
    fn too_few_points_give_no_histogram() {
        assert!(histogram(std::iter::repeat_n([1, 2, 3], MIN_POINTS - 1)).is_none());
        let h = histogram(std::iter::repeat_n([0, 0, 0], MIN_POINTS)).unwrap();
        assert!((h.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        let white = histogram(std::iter::repeat_n([255, 255, 255], MIN_POINTS)).unwrap();
        assert_eq!(similarity(&h, &white), 1.0, "black counts as grey");
    }
}
