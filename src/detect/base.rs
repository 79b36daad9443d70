//! The base of a container standing on its rim. Upside down, a container's top is its base, and
//! only the base tells a vessel on its rim from a closed part of its shape (a lidded canister
//! for a mug): vessels (mugs, bowls, pots) stand on a foot ring with the middle of the base
//! raised inside it, so upside down the middle lies a few millimetres below the ring, where a
//! lid or the top of a closed can is flat or domed.

use crate::geometry::Superquadric;
use crate::numeric::median;
use nalgebra::Vector3;

/// How far (m) from the end of a part its base's points may lie: a fifth of its half-height, or
/// three noise bands where the noise is larger.
pub fn window(shape: &Superquadric, band: f64) -> f64 {
    (0.2 * shape.a[2]).max(3.0 * band)
}

/// How far across the end (1 at its edge) what stands on the base may reach: the bottom of what
/// stands there may be as wide as the end itself (a can on an upturned bowl).
const STANDING_ON_RADIUS: f64 = 1.25;

/// How far from its end plane, as a share of the half-height, the model's surface may lie and
/// still be the foot it stands on.
const FOOT_DEPTH: f64 = 0.05;

/// The top of a part standing on its rim (its local -z up): points within the base [`window`]
/// of the top are collected, those within the inner 40 % of the foot (the middle) and those
/// from 55 % to its edge (where the ring is), and the middle's median height is compared with
/// that of the highest of four overlapping annuli out there (55-70, 65-80, 75-90 and 85-100 %):
/// the ring is where the base stands, at whatever share of the radius the vessel has it (a
/// learned model's radius is the vessel's own, and its foot ring then lies near the edge).
pub struct BaseCap {
    window: f64,
    middle: Vec<f64>,
    /// Points over the middle of the foot, above the top by more than the window and by less
    /// than the part's height: something standing on the base.
    standing_on: usize,
    ring: Vec<(f64, f64)>,
    shape: Superquadric,
    /// The superellipse's section at the foot's height, as a share of its middle section.
    foot_scale: f64,
}

impl BaseCap {
    pub fn new(shape: &Superquadric, band: f64) -> BaseCap {
        BaseCap {
            window: window(shape, band),
            middle: Vec::new(),
            standing_on: 0,
            ring: Vec::new(),
            shape: *shape,
            foot_scale: (1.0 - (1.0 - FOOT_DEPTH).powf(2.0 / shape.e1))
                .powf(shape.e1 / 2.0)
                .max(1e-6),
        }
    }

    /// Take a local point; whether it lies in the base's recess: near the top, within the
    /// ring's outer edge.
    pub fn add(&mut self, q: &Vector3<f64>) -> bool {
        let h = -q.z;
        let above = h - self.shape.a[2];
        if above.abs() > self.window {
            if above > self.window && above < 2.0 * self.shape.a[2] && self.end_radius(q) < STANDING_ON_RADIUS {
                self.standing_on += 1;
            }
            return false;
        }
        let r = self.foot_radius(q);
        if r < 0.4 {
            self.middle.push(h);
        } else if (0.55..1.0).contains(&r) {
            // (radius, height): the annuli are chosen in `recess`.
            self.ring.push((r, h));
        }
        r < 0.88
    }

    /// The radius of a local point across the model's end (its cross-section there, before the
    /// end is rounded off), 1 on its edge.
    fn end_radius(&self, q: &Vector3<f64>) -> f64 {
        let s = &self.shape;
        let at_end = s.untaper(&Vector3::new(q.x, q.y, -s.a[2]));
        s.section_radius(at_end.x, at_end.y)
    }

    /// The radius of a local point across the model's foot, 1 on its edge: the outline of the
    /// end where the model's surface lies within [`FOOT_DEPTH`] of its half-height from the end
    /// plane. A rounded end (a bowl's, e1 well above 0.1) stands on less than its full
    /// cross-section, and a tapered part's end is narrower or wider than its middle.
    fn foot_radius(&self, q: &Vector3<f64>) -> f64 {
        let s = &self.shape;
        let at_foot = s.untaper(&Vector3::new(q.x, q.y, -(1.0 - FOOT_DEPTH) * s.a[2]));
        s.section_radius(at_foot.x, at_foot.y) / self.foot_scale
    }

    /// The highest annulus minus the middle (m); minus infinity (no sign of a base) with fewer
    /// than 10 points in the middle or in every annulus, plus infinity when the middle is
    /// unseen because something stands on the base (an upturned bowl under a can): then
    /// nothing can be told either way, and what stands on it is not held against the vessel.
    pub fn recess(&mut self) -> f64 {
        const MIN: usize = 10;
        if self.middle.len() < MIN && self.standing_on >= MIN {
            return f64::INFINITY;
        }
        if self.middle.len() < MIN || self.ring.len() < MIN {
            return f64::NEG_INFINITY;
        }
        let Some(m) = median(&mut self.middle) else {
            return f64::NEG_INFINITY;
        };
        let mut best = f64::NEG_INFINITY;
        for lo in [0.55, 0.65, 0.75, 0.85] {
            let mut hs: Vec<f64> = self
                .ring
                .iter()
                .filter(|(r, _)| (lo..lo + 0.15).contains(r))
                .map(|p| p.1)
                .collect();
            if hs.len() >= MIN
                && let Some(h) = median(&mut hs)
            {
                best = best.max(h - m);
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The top of a mug-sized cylinder on its rim (local -z up): a flat lid gives no recess, a
    /// base whose middle lies 3 mm below its ring gives 3 mm, and a top seen by a few points
    /// gives no sign of a base at all.
    #[test]
    fn a_vessel_base_is_told_from_a_flat_lid() {
        let shape = Superquadric::new([0.04, 0.04, 0.05], 0.1, 1.0, 0.0, 0.0).unwrap();
        let cap = |depth: f64, n: usize| {
            let mut b = BaseCap::new(&shape, 0.002);
            for k in 0..n {
                let r = 0.04 * (k % 20) as f64 / 20.0;
                let t = k as f64 * 0.7;
                let h = if r < 0.02 { 0.05 - depth } else { 0.05 };
                b.add(&Vector3::new(r * t.cos(), r * t.sin(), -h));
            }
            b.recess()
        };
        assert!(cap(0.0, 400).abs() < 1e-12);
        assert!((cap(0.003, 400) - 0.003).abs() < 1e-12);
        assert_eq!(cap(0.003, 15), f64::NEG_INFINITY);
    }

    /// A foot ring near the edge (beyond 85 % of the foot, as a learned model of the vessel's
    /// own radius has it) is found: it read as no recess when the ring was looked for at
    /// 65-88 % of the foot (the learned mug on the printed mug of mOSD learn38: 0.9 mm).
    #[test]
    fn a_foot_ring_near_the_edge_is_found() {
        let shape = Superquadric::new([0.04, 0.04, 0.05], 0.1, 1.0, 0.0, 0.0).unwrap();
        let mut b = BaseCap::new(&shape, 0.002);
        let foot = 0.04 * b.foot_scale;
        for k in 0..2000 {
            let r = foot * (k % 50) as f64 / 50.0;
            let t = k as f64 * 0.7;
            let h = if r < 0.85 * foot { 0.047 } else { 0.05 };
            b.add(&Vector3::new(r * t.cos(), r * t.sin(), -h));
        }
        assert!((b.recess() - 0.003).abs() < 1e-9, "{}", b.recess());
    }
}
