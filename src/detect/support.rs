//! What a part rests on (the shell test of [`super::verify`] leaves it out): the support plane's
//! points the plane removal left, or the top of whatever else the part stands on.

use super::plane_check::approximation_tolerance;
use super::space::SearchSpace;
use crate::cloud::plane::Plane;
use crate::geometry::PlacedSuperquadric;
use crate::surface_samples::LocalSamples;
use nalgebra::{Point3, Vector3};

/// The radius (m) of the patch around a point that tells a surface parallel to the support
/// plane from a wall.
const SUPPORT_PATCH: f64 = 0.012;

/// The surface a part may rest on, where it is not the support plane: the plane through its
/// lowest point along the support plane's normal, parallel to it. The top of a box, a tin or a
/// book that an object stands on continues outwards from its base, just outside its surface; it
/// is not the object's own surface going on past the model's edge (a larger object of the same
/// shape), and it is not counted in the shell. The side wall of a larger object around a
/// too-small fit goes on past the base's height, and still counts there.
#[derive(Clone, Copy)]
pub(super) struct Support {
    /// The support plane's normal (towards the objects) and the part's lowest height along it;
    /// `None` without a support plane, or where the part rests on it.
    base: Option<(Vector3<f64>, f64)>,
    /// How far from that height (m) a point is on the support.
    band: f64,
    /// The support plane, and the height over it (m) below which a point is the plane's own:
    /// [`PLANE_RESIDUE`] times the removal band at the part, at most the approximation
    /// tolerance of its shape.
    plane: Option<(Plane, f64)>,
    /// The lowest of the part's surface samples along the support plane's normal, its height
    /// over the plane, and how far above its support it may stand, where that height is more:
    /// the part is raised off the plane.
    raised: Option<(f64, f64, f64)>,
}

/// Below this many times the plane removal's band (three noise sigmas) over the support plane a
/// point is the plane's, left by the removal: the noise's tail and the table's unevenness. Kept
/// in the shell, they lay along the foot of every object standing on the table (a standing
/// cereal box in mOSD learn32: 300 of its 460 shell points within 5 mm of the table, the
/// removal's band 3.9 mm), and counted against it.
const PLANE_RESIDUE: f64 = 2.0;

/// A surface a raised part may rest on faces up within this angle of the support plane's
/// normal (its cosine, 26 degrees): the top of a box or a book, and of a lying can within 0.44
/// of its radius to either side of the line it is highest along.
const LEVEL_COS: f64 = 0.9;

/// Points in a [`SUPPORT_PATCH`] that give a surface's direction.
const MIN_PATCH: usize = 6;

impl Support {
    pub(super) fn new(
        space: &SearchSpace<'_>,
        placed: &PlacedSuperquadric,
        band: f64,
        noise_band: f64,
        samples: &LocalSamples,
    ) -> Support {
        let base = space.plane.and_then(|plane| {
            let n = plane.normal;
            let r = placed.pose.rotation.to_rotation_matrix();
            let half = placed.shape.local_half_extents();
            let depth: f64 = (0..3).map(|i| n.dot(&r.matrix().column(i)).abs() * half[i]).sum();
            let lowest = n.dot(&placed.pose.translation.vector) - depth;
            // On the support plane itself there is nothing to leave out: the plane's points are
            // gone, and what is left at the base's height there is other objects' walls (a
            // larger box's, around a fit on its lower part).
            (lowest + plane.d > band).then_some((n, lowest))
        });
        let centre = Point3::from(placed.pose.translation.vector);
        // Never more than the model's approximation of the part's own foot: a small part's
        // lowest wall must still answer for what lies around it.
        let residue = (PLANE_RESIDUE * 3.0 * space.noise.at(&centre)).min(approximation_tolerance(&placed.shape));
        let plane = space.plane.map(|p| (p, residue));
        // The base above is the corner of the box round the shape, which lies below a round
        // section's lowest point (by up to 40 % of the radius, turned 45 degrees): what the
        // part rests on is measured at the lowest surface sample.
        // A learned model can be short of its object by a few per cent of a size (the sensor
        // loses the edges of what it shows the learner): fitted to the object's top, it stands
        // that much off the plane. A tenth of its height, as the plane check's tolerance, is
        // allowed before it must rest on something else.
        let raised = space.plane.and_then(|plane| {
            let n_local = placed.pose.rotation.inverse() * plane.normal;
            let (lowest, highest) = samples
                .iter()
                .map(|(q, _)| n_local.dot(q))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), h| (lo.min(h), hi.max(h)));
            let allowed = band.max(noise_band + 0.1 * (highest - lowest));
            let lowest = plane.normal.dot(&placed.pose.translation.vector) + lowest;
            (lowest.is_finite() && lowest + plane.d > allowed).then_some((lowest, lowest + plane.d, allowed))
        });
        Support {
            base,
            band,
            plane,
            raised,
        }
    }

    /// Whether a point lies on the surface the part may rest on: at the base's height, on a
    /// surface parallel to the support plane there. Most of its neighbours within
    /// [`SUPPORT_PATCH`] (four in five) lie within half that of its height; on the side wall of
    /// a larger object around the fit, which also crosses the base's height, they spread over
    /// the whole patch. (So does the top of a support next to its edge, where its side wall
    /// drops away: an upturned bowl whose rim rests near the edge of a tin is held to its shell
    /// test there.)
    pub(super) fn holds(&self, space: &SearchSpace<'_>, p: &Point3<f64>) -> bool {
        if let Some((plane, residue)) = &self.plane
            && plane.signed_distance(p) < *residue
        {
            return true;
        }
        let Some((n, h)) = self.base else { return false };
        let height = n.dot(&p.coords);
        if (height - h).abs() > self.band {
            return false;
        }
        let (mut level, mut all) = (0usize, 0usize);
        space.grid.for_each_within(space.points, p, SUPPORT_PATCH, |k| {
            all += 1;
            level += usize::from((n.dot(&space.points[k].coords) - height).abs() <= 0.5 * SUPPORT_PATCH);
        });
        5 * level >= 4 * all
    }

    /// How high (m) the part's lowest surface sample lies above the support plane, where that is
    /// more than the part may stand off its support (the larger of the base band and the noise
    /// band plus a tenth of the part's height along the plane's normal): it stands on something
    /// else, or floats.
    pub(super) fn raised(&self) -> Option<f64> {
        self.raised.map(|(_, h, _)| h)
    }

    /// Whether `p` lies on a surface a raised part may rest on: at its base's height (or as far
    /// below it as the part may stand off its support), above the
    /// table's residue, its neighbours within [`SUPPORT_PATCH`] on a surface facing up. (The
    /// patch test of [`Support::holds`] passes at the foot of a wall, where the plane's removal
    /// cut the neighbours below: a larger box's wall next to a model lifted onto its upper
    /// part.) Never for a part on the support plane.
    pub(super) fn rests_on(&self, space: &SearchSpace<'_>, p: &Point3<f64>) -> bool {
        let (Some((lowest, _, allowed)), Some((plane, residue))) = (self.raised, &self.plane) else {
            return false;
        };
        let n = plane.normal;
        let below = lowest - n.dot(&p.coords);
        if below > allowed || below < -self.band || plane.signed_distance(p) < *residue {
            return false;
        }
        // The patch's plane from the refinement's subsample (a twelfth of the smallest size
        // apart) where it holds enough points, at a fraction of the cost of the whole cloud's;
        // from the whole cloud where a large part's subsample is too sparse for the patch.
        let mut near: Vec<Vector3<f64>> = Vec::new();
        space
            .mid_grid
            .for_each_within(space.mid, p, SUPPORT_PATCH, |k| near.push(space.mid[k].coords));
        if near.len() < MIN_PATCH {
            near.clear();
            space
                .grid
                .for_each_within(space.points, p, SUPPORT_PATCH, |k| near.push(space.points[k].coords));
        }
        near.len() >= MIN_PATCH && crate::numeric::least_spread_direction(&near).dot(&n).abs() >= LEVEL_COS
    }
}

#[cfg(test)]
mod tests {
    use super::super::prepare::{index, scene};
    use super::super::verify::score;
    use super::super::{Params, detect};
    use super::{PLANE_RESIDUE, approximation_tolerance};
    use crate::cloud::grid::Grid;
    use crate::cloud::plane::orthonormal_basis;
    use crate::detect::accept::MIN_RESTING_ON;
    use crate::detect::prepare::simulated_model;
    use crate::model::Model;
    use nalgebra::Point3;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};
    use std::sync::Arc;

    /// The plane removal leaves the table's noise tail just above its band. Along the foot of a
    /// part standing on the table those points are the table's, not the part's surface going on
    /// past its model, and are not in its shell (a standing cereal box of mOSD learn32 had 300 of
    /// its 460 shell points there, a standing Pringles can of test32 was refused for them).
    #[test]
    fn the_tables_residue_at_a_standing_parts_foot_is_not_in_its_shell() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let models = root.join("models");
        // A spray tin standing alone, seen by a sensor of little noise: the residue's height (a
        // tenth of the tin's radius) then lies above the removal's band.
        let rig = std::fs::read_to_string(root.join("scenes/fig4_tools.toml")).unwrap();
        let rig = &rig[rig.find("[table]").unwrap()..rig.find("[[object]]").unwrap()];
        let text = format!(
            "description = \"a spray tin alone\"\n{}\n[[object]]\nmodel = \"spray_tin\"\npose = {{ position = [0.85, 0.0, 0.0] }}\n",
            rig.replace("noise_sigma_at_1m = 0.002", "noise_sigma_at_1m = 0.0006")
        );
        let dir = std::env::temp_dir().join(format!("sqscan-residue-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("tin.toml"), text).unwrap();
        let sim = crate::sim::Scene::from_file(&dir.join("tin.toml"), &models).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        let sweep = crate::sim::simulate(&sim, 1);
        let model = Model::load("spray_tin", &models).unwrap();
        let params = Params {
            viewpoint: sweep.cloud.viewpoint_position(),
            ..Params::default()
        };
        let found = detect(&sweep.cloud.points, &model, &params);
        let pose = found.best_found().expect("the tin is found").pose;
        let placed = model.placed_parts(&pose)[0];
        let mut prep = index(Arc::new(scene(&sweep.cloud.points, &params)), &model, &params);
        let shell = |prep: &super::super::prepare::Prepared| {
            score(&prep.space(), &placed, 0.0, params.gamma, &prep.samples[0]).shell_points
        };
        let before = shell(&prep);
        // A ring of the table's points around the foot, between the removal's band and the
        // residue's height over the table, just outside the wall's surface band.
        let plane = prep.scene.plane.expect("a table");
        let centre = Point3::from(placed.pose.translation.vector);
        let removal = 3.0 * prep.noise().at(&centre);
        let residue = (PLANE_RESIDUE * removal).min(approximation_tolerance(&placed.shape));
        assert!(residue > removal, "{residue} over {removal}");
        let surface_band = (2.5 * prep.noise().at(&centre)).max(0.002);
        let foot = centre - plane.normal * plane.signed_distance(&centre);
        let (u, w) = orthonormal_basis(&plane.normal);
        let radius = placed.shape.a[0];
        let ring: Vec<Point3<f64>> = (0..120)
            .map(|k| {
                let t = k as f64 / 120.0 * std::f64::consts::TAU;
                let out = radius + surface_band + 0.0015;
                foot + plane.normal * (0.5 * (removal + residue)) + (u * t.cos() + w * t.sin()) * out
            })
            .collect();
        assert!(
            ring.iter().all(|p| placed.surface_distance(p) > surface_band),
            "the ring lies outside the surface band"
        );
        prep.mid.extend(ring);
        prep.mid_grid = Grid::new(&prep.mid, 1.2 * prep.max_size);
        let after = shell(&prep);
        assert!(
            after <= before + 3,
            "shell points {before} without the ring, {after} with it"
        );
    }

    /// `scenes/stacked/flat_under_others.toml`'s table top (m) in the base frame.
    const TABLE: f64 = 0.72;

    fn model(name: &str, a: [f64; 3]) -> Model {
        let text = format!("name = \"{name}\"\n[[part]]\nname = \"body\"\na = {a:?}\ne1 = 0.1\ne2 = 0.1\n");
        Model::from_toml_str(&text, std::path::Path::new("test.toml")).unwrap()
    }

    /// What a placement of a box model rests on, as [`score`] measures it.
    fn raised(scene_seed: u64, m: &Model, at: [f64; 3], yaw_deg: f64) -> Option<(f64, usize)> {
        let (model, params, prep) = simulated_model("stacked/flat_under_others", scene_seed, m.clone());
        let pose = Isometry3::from_parts(
            Translation3::new(at[0], at[1], TABLE + at[2]),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_deg.to_radians()),
        );
        let placed = model.placed_parts(&pose)[0];
        score(&prep.space(), &placed, 0.0, params.gamma, &prep.samples[0]).raised
    }

    /// A whole object does not float. A thin box's model laid on the top of a thicker box lying
    /// flat (its top on the thicker box's top, its walls on the upper part of the thicker box's
    /// walls) stands off the table with nothing level at its foot: only the thicker box's walls,
    /// going on down. The box standing on the flat box rests on that box's top, seen round its
    /// foot.
    #[test]
    fn a_thin_box_model_on_a_thick_box_floats_and_a_box_on_a_box_rests() {
        // The flat box is 56 mm tall; the thin model 36 mm, its top on the flat box's top.
        let thin = model("thin", [0.13, 0.09, 0.018]);
        let on_it = model("on_it", [0.09, 0.07, 0.04]);
        for seed in 1..=3 {
            let (h, n) = raised(seed, &thin, [0.85, -0.16, 0.038], 25.0).expect("the thin model is raised");
            assert!((h - 0.02).abs() < 0.003, "seed {seed}: {h} m over the table");
            assert!((n as f64) < MIN_RESTING_ON, "seed {seed}: {n} points to rest on");
            let (h, n) = raised(seed, &on_it, [0.87, -0.15, 0.096], -10.0).expect("the box on top is raised");
            assert!((h - 0.056).abs() < 0.003, "seed {seed}: {h} m over the table");
            assert!(n as f64 >= 3.0 * MIN_RESTING_ON, "seed {seed}: {n} points to rest on");
            // On the table, nothing is asked of it.
            assert_eq!(raised(seed, &thin, [0.3, 0.4, 0.018], 0.0), None);
        }
    }

    /// An open container standing upright on something rests on it: the white bowl on the
    /// upturned pot of `scenes/stacked/bowl_on_pot.toml` is found at every search seed. The
    /// pot's top, seen round the bowl's flaring foot, lies within the bowl's surface band where
    /// the fit sits a few millimetres low, and counts; the bowl's own inside bottom does not.
    #[test]
    fn the_white_bowl_standing_on_the_upturned_pot_rests_on_it() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let models = root.join("models");
        let sim = crate::sim::Scene::from_file(&root.join("scenes/stacked/bowl_on_pot.toml"), &models).unwrap();
        let sweep = crate::sim::simulate(&sim, 1);
        let bowl = Model::load("white_bowl", &models).unwrap();
        let table = sim.table.as_ref().expect("the scene has a table").height;
        let on_pot = Point3::new(0.80, 0.18, table + 0.1);
        for seed in 0..8 {
            let params = Params {
                seed,
                all: true,
                viewpoint: sweep.cloud.viewpoint_position(),
                ..Params::default()
            };
            let found = detect(&sweep.cloud.points, &bowl, &params);
            assert!(
                found
                    .detections
                    .iter()
                    .any(|d| d.found && (Point3::from(d.pose.translation.vector) - on_pot).xy().norm() < 0.01),
                "seed {seed}: the bowl on the pot is not found"
            );
        }
    }
}
