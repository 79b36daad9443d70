//! Hand-made scenes where a grasp must be found, and where one must be refused.

use super::*;
use crate::geometry::Superquadric;
use nalgebra::{Isometry3, UnitQuaternion, Vector3};

fn table() -> Plane {
    Plane {
        normal: Vector3::z(),
        d: 0.0,
    }
}

/// The table's points (z = 0) over a square of half-size `half` about the origin, 4 mm apart.
fn table_points(half: f64) -> Vec<[f32; 3]> {
    let n = (half / 0.004) as i32;
    let mut out = Vec::new();
    for i in -n..=n {
        for j in -n..=n {
            out.push([i as f32 * 0.004, j as f32 * 0.004, 0.0]);
        }
    }
    out
}

/// A part standing on the table at (x, y), turned by `yaw` about z.
fn standing(shape: Superquadric, x: f64, y: f64, yaw: f64) -> PlacedSuperquadric {
    PlacedSuperquadric::new(
        shape,
        Isometry3::from_parts(
            Vector3::new(x, y, shape.a[2]).into(),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
        ),
    )
}

fn cuboid(a: [f64; 3]) -> Superquadric {
    Superquadric::new(a, 0.1, 0.1, 0.0, 0.0).unwrap()
}

fn cylinder(r: f64, half_height: f64) -> Superquadric {
    Superquadric::new([r, r, half_height], 0.1, 1.0, 0.0, 0.0).unwrap()
}

/// The surface of `placed` as scene points, 3 mm apart (its hidden back too: the checks must
/// not depend on what a view hides).
fn points_of(placed: &PlacedSuperquadric) -> Vec<[f32; 3]> {
    placed
        .sample_surface(0.003)
        .into_iter()
        .filter(|p| p.z > 0.001)
        .map(|p| [p.x as f32, p.y as f32, p.z as f32])
        .collect()
}

fn closed(placed: PlacedSuperquadric) -> Part {
    Part { placed, open: false }
}

/// The closing direction of a grasp in the cloud's frame.
fn closing(g: &Grasp) -> Vector3<f64> {
    g.pose.rotation * Vector3::x()
}

fn approach(g: &Grasp) -> Vector3<f64> {
    g.pose.rotation * Vector3::z()
}

/// Every grasp holds what the checks promise: contacts on the fitted surface, the opening in
/// the gripper's range, the pre-grasp pose back along the approach, the gripper above the
/// table.
fn assert_sound(grasps: &[Grasp], parts: &[Part], gripper: &Gripper) {
    for g in grasps {
        let part = &parts[g.part].placed;
        // On the fitted surface, or where the pads closed on the points measured near it.
        for c in &g.contacts[..if g.kind == Kind::Rim { 1 } else { 2 }] {
            assert!(
                part.surface_distance(c).abs() < OBJECT_BAND,
                "contact {c} off the surface"
            );
        }
        assert!(g.opening >= gripper.min_opening && g.opening + 2.0 * gripper.clearance <= gripper.max_opening + 1e-12);
        let back = g.pose.translation.vector - g.pregrasp.translation.vector;
        assert!((back - approach(g) * gripper.pregrasp).norm() < 1e-9);
        let swept = Swept::new(gripper, g.opening);
        assert!(swept.lowest_over(&g.pose, &table()) >= gripper.clearance - 1e-9);
    }
}

#[test]
fn a_lone_box_is_taken_across_its_thin_side() {
    let gripper = Gripper::default();
    let boxed = standing(cuboid([0.03, 0.08, 0.10]), 0.0, 0.0, 0.3);
    let parts = [closed(boxed)];
    let mut scene = table_points(0.3);
    scene.extend(points_of(&boxed));
    let grasps = plan(&parts, &scene, Some(&table()), None, &gripper, 5);
    assert!(!grasps.is_empty(), "no grasp of a 60 mm box");
    assert_sound(&grasps, &parts, &gripper);
    let thin = boxed.pose.rotation * Vector3::x();
    for g in &grasps {
        // Only the 60 mm side fits the 85 mm opening.
        assert!(
            closing(g).dot(&thin).abs() > 0.999,
            "closing {} not across the thin side",
            closing(g)
        );
        assert!((g.opening - 0.06).abs() < 1e-3, "opening {}", g.opening);
    }
    // Too tall for the fingers to reach its middle from above: the best is taken near its top.
    let first = &grasps[0];
    assert!(
        first.pose.translation.z > 0.15,
        "first grasp at {}",
        first.pose.translation.vector
    );
}

#[test]
fn a_box_pressed_against_another_is_not_taken_across_the_touching_sides() {
    let gripper = Gripper::default();
    // A 50 x 70 mm box: both sides fit; a second box touches its +x face.
    let boxed = standing(cuboid([0.025, 0.035, 0.05]), 0.0, 0.0, 0.0);
    let neighbour = standing(cuboid([0.04, 0.06, 0.07]), 0.025 + 0.04 + 0.001, 0.0, 0.0);
    let parts = [closed(boxed)];
    let mut scene = table_points(0.3);
    scene.extend(points_of(&boxed));
    let alone = plan(&parts, &scene, Some(&table()), None, &gripper, 20);
    assert!(
        alone.iter().any(|g| closing(g).x.abs() > 0.99),
        "alone, it is taken across x"
    );
    scene.extend(points_of(&neighbour));
    let grasps = plan(&parts, &scene, Some(&table()), None, &gripper, 20);
    assert!(!grasps.is_empty(), "the box is still free across y");
    assert_sound(&grasps, &parts, &gripper);
    for g in &grasps {
        assert!(
            closing(g).x.abs() < 1e-6,
            "a finger would go into the neighbour: closing {}",
            closing(g)
        );
        // Nor does a finger or the palm come from the neighbour's side.
        assert!(approach(g).x > -0.5, "approach {} from the neighbour", approach(g));
    }
}

#[test]
fn a_mug_with_a_can_beside_it_is_not_taken_from_the_cans_side() {
    let gripper = Gripper::default();
    let mug = standing(cylinder(0.032, 0.045), 0.0, 0.0, 0.0);
    // A can 6 mm from the mug's wall on -y.
    let can = standing(cylinder(0.033, 0.06), 0.0, -(0.032 + 0.006 + 0.033), 0.0);
    let parts = [closed(mug)];
    let mut scene = table_points(0.3);
    scene.extend(points_of(&mug));
    scene.extend(points_of(&can));
    let grasps = plan(&parts, &scene, Some(&table()), None, &gripper, 20);
    assert!(!grasps.is_empty(), "the mug is free from above and from +y");
    assert_sound(&grasps, &parts, &gripper);
    for g in &grasps {
        let swept = Swept::new(&gripper, g.opening);
        let can_points: Vec<Point3<f64>> = points_of(&can)
            .iter()
            .map(|p| Point3::new(p[0] as f64, p[1] as f64, p[2] as f64))
            .collect();
        let grid = crate::cloud::grid::Grid::new(&can_points, OTHERS_CELL);
        assert!(!swept.hits_others(&g.pose, &can_points, &grid, gripper.clearance));
        // Closing along y would put a finger into the 6 mm gap.
        assert!(closing(g).y.abs() < 0.9, "closing {} towards the can", closing(g));
    }
}

#[test]
fn a_bowl_too_wide_to_close_across_is_taken_at_its_rim() {
    let gripper = Gripper::default();
    // 150 mm across, flaring out towards its rim.
    let bowl = Superquadric::new([0.06, 0.06, 0.04], 0.3, 1.0, 0.25, 0.25).unwrap();
    let placed = standing(bowl, 0.0, 0.0, 0.0);
    let parts = [Part { placed, open: true }];
    let mut scene = table_points(0.3);
    scene.extend(points_of(&placed).into_iter().filter(|p| (p[2] as f64) < 0.079));
    let grasps = plan(&parts, &scene, Some(&table()), None, &gripper, 5);
    assert!(!grasps.is_empty(), "no rim grasp");
    assert_sound(&grasps, &parts, &gripper);
    // A body of revolution: every rim grasp is the same grasp.
    assert_eq!(grasps.len(), 1, "{grasps:?}");
    let g = &grasps[0];
    assert_eq!(g.kind, Kind::Rim);
    assert!(g.pose.translation.z > 0.04, "pads at {}", g.pose.translation.vector);
    // Down along the flared wall.
    assert!(approach(g).z < -0.8, "approach {}", approach(g));
}

#[test]
fn a_can_gets_one_grasp_for_each_way_its_symmetry_leaves_different() {
    let gripper = Gripper::default();
    let can = standing(cylinder(0.03, 0.04), 0.1, 0.0, 0.0);
    let parts = [closed(can)];
    let mut scene = table_points(0.3);
    scene.extend(points_of(&can));
    let grasps = plan(&parts, &scene, Some(&table()), None, &gripper, 50);
    assert!(!grasps.is_empty());
    assert_sound(&grasps, &parts, &gripper);
    // From above at the centre first (straight down, across its axis).
    let first = &grasps[0];
    assert!(approach(&grasps[0]).z < -0.99, "first approach {}", approach(first));
    // No two grasps alike up to a turn about the can's axis.
    for (i, a) in grasps.iter().enumerate() {
        for b in &grasps[i + 1..] {
            let same_height = (a.pose.translation.z - b.pose.translation.z).abs() < 1e-3;
            let same_tilt = (approach(a).z - approach(b).z).abs() < 1e-3;
            let same_close = (closing(a).z.abs() - closing(b).z.abs()).abs() < 1e-3;
            let radial = |g: &Grasp| (g.pose.translation.vector - can.pose.translation.vector).xy().norm();
            let same_radius = (radial(a) - radial(b)).abs() < 1e-3;
            assert!(
                !(same_height && same_tilt && same_close && same_radius),
                "{a:?} repeats {b:?}"
            );
        }
    }
}

#[test]
fn nothing_is_planned_for_absurd_settings_or_inputs() {
    let can = standing(cylinder(0.03, 0.04), 0.0, 0.0, 0.0);
    let parts = [closed(can)];
    let scene = points_of(&can);
    let mut bad = Gripper {
        friction: f64::NAN,
        ..Gripper::default()
    };
    assert!(bad.validate().is_err());
    assert!(plan(&parts, &scene, Some(&table()), None, &bad, 5).is_empty());
    bad = Gripper {
        min_opening: 0.1,
        ..Gripper::default()
    };
    assert!(matches!(
        bad.validate(),
        Err(GripperError::Field {
            field: "min_opening",
            ..
        })
    ));
    // Wild points in the scene are skipped, not a panic.
    let mut wild = scene.clone();
    wild.extend([[f32::NAN, 0.0, 0.0], [f32::INFINITY, 1.0, 1.0], [1e30, -1e30, 0.0]]);
    let g = plan(&parts, &wild, Some(&table()), None, &Gripper::default(), 5);
    assert!(!g.is_empty());
    assert!(plan(&[], &wild, None, None, &Gripper::default(), 5).is_empty());
}

#[test]
fn asked_to_occupy_unseen_space_no_finger_goes_behind_the_box() {
    // Seen from far along -x and above: the sensor sees the box's front and top, and the table
    // but for the box's shadow behind it.
    let viewpoint = Point3::new(-1.0, 0.0, 0.6);
    let boxed = standing(cuboid([0.03, 0.035, 0.05]), 0.0, 0.0, 0.0);
    let kernel = crate::geometry::Kernel::new(&boxed.shape);
    let mut scene: Vec<[f32; 3]> = table_points(0.3)
        .into_iter()
        .filter(|p| !((-0.031..0.2).contains(&p[0]) && p[1].abs() < 0.036))
        .collect();
    for p in boxed.sample_surface(0.003) {
        let n = boxed.pose.rotation * kernel.residual_grad(&boxed.to_local(&p)).grad;
        if n.dot(&(viewpoint - p)) > 0.0 && p.z > 0.001 {
            scene.push([p.x as f32, p.y as f32, p.z as f32]);
        }
    }
    let parts = [closed(boxed)];
    let free = plan(&parts, &scene, Some(&table()), Some(viewpoint), &Gripper::default(), 50);
    assert!(
        free.iter().any(|g| closing(g).x.abs() > 0.99),
        "the unseen space free, the box is taken along the line of sight too"
    );
    let careful = Gripper {
        occupy_unseen: true,
        ..Gripper::default()
    };
    let grasps = plan(&parts, &scene, Some(&table()), Some(viewpoint), &careful, 50);
    assert!(!grasps.is_empty(), "the box is still free across the line of sight");
    assert_sound(&grasps, &parts, &careful);
    for g in &grasps {
        // A finger behind the box along the line of sight would be where nothing was seen.
        assert!(
            closing(g).x.abs() < 0.5,
            "closing {} along the line of sight",
            closing(g)
        );
    }
}

/// A part moved by `shift` in the cloud's frame.
fn moved(placed: &PlacedSuperquadric, shift: Vector3<f64>) -> PlacedSuperquadric {
    let mut p = *placed;
    p.pose.translation.vector += shift;
    p
}

#[test]
fn the_pads_close_on_the_box_that_was_seen_not_on_its_fit_4_mm_off() {
    let gripper = Gripper::default();
    // The fit lies 4 mm to -x of the box the sensor saw.
    let seen = standing(cuboid([0.025, 0.05, 0.04]), 0.0, 0.0, 0.0);
    let fitted = moved(&seen, Vector3::new(-0.004, 0.0, 0.0));
    let parts = [closed(fitted)];
    let mut scene = table_points(0.3);
    scene.extend(points_of(&seen));
    let grasps = plan(&parts, &scene, Some(&table()), None, &gripper, 5);
    let across_x: Vec<&Grasp> = grasps.iter().filter(|g| closing(g).x.abs() > 0.999).collect();
    assert!(!across_x.is_empty(), "no grasp across the 50 mm side: {grasps:?}");
    for g in across_x {
        // Both contacts on the seen faces (x = +-25 mm), to within the points' spacing.
        for c in &g.contacts {
            assert!((c.x.abs() - 0.025).abs() < 0.0015, "contact {c} off the seen face");
        }
        assert!(
            g.pose.translation.x.abs() < 0.0015,
            "centre {}",
            g.pose.translation.vector
        );
        assert!((g.opening - 0.05).abs() < 0.002, "opening {}", g.opening);
    }
}

#[test]
fn the_pads_close_on_the_bowls_rim_that_was_seen_not_on_its_fit_4_mm_off() {
    let gripper = Gripper::default();
    let bowl = Superquadric::new([0.06, 0.06, 0.04], 0.3, 1.0, 0.25, 0.25).unwrap();
    let seen = standing(bowl, 0.0, 0.0, 0.0);
    let fitted = moved(&seen, Vector3::new(0.004, 0.0, 0.0));
    let parts = [Part {
        placed: fitted,
        open: true,
    }];
    let mut scene = table_points(0.3);
    scene.extend(points_of(&seen).into_iter().filter(|p| (p[2] as f64) < 0.079));
    let grasps = plan(&parts, &scene, Some(&table()), None, &gripper, 5);
    let g = grasps.iter().find(|g| g.kind == Kind::Rim).expect("a rim grasp");
    // The outer pad's contact on the seen wall, not 4 mm off it where the fit's wall is.
    let off = seen.surface_distance(&g.contacts[0]).abs();
    assert!(
        off < 0.002,
        "outer contact {} is {:.1} mm off the seen wall",
        g.contacts[0],
        off * 1e3
    );
}

#[test]
fn a_can_is_taken_from_above_as_deep_as_the_fingers_reach() {
    let gripper = Gripper::default();
    // 80 mm tall: from above, the pads reach 30 mm down its side with the palm 5 mm over its top.
    let can = standing(cylinder(0.03, 0.04), 0.0, 0.0, 0.0);
    let parts = [closed(can)];
    let mut scene = table_points(0.3);
    scene.extend(points_of(&can));
    let grasps = plan(&parts, &scene, Some(&table()), None, &gripper, 50);
    assert_sound(&grasps, &parts, &gripper);
    // Measured at the pads' edges alone, the contacts lay on a chord inside the can, and its
    // widest section stood in the closing fingers' path: only a shallower grasp came back.
    let palm_over_top = grasps
        .iter()
        .filter(|g| approach(g).z < -0.99)
        .map(|g| g.pose.translation.z + (gripper.finger_depth - gripper.pad_from_tip) - 2.0 * can.shape.a[2])
        .min_by(f64::total_cmp)
        .expect("a grasp from above");
    assert!(
        (palm_over_top - gripper.clearance).abs() < 0.0015,
        "the palm {:.1} mm over the top",
        palm_over_top * 1e3
    );
    for g in grasps.iter().filter(|g| approach(g).z < -0.99) {
        assert!(
            (g.opening - 0.06).abs() < 0.0015,
            "opening {} across a 60 mm can",
            g.opening
        );
    }
}

/// A compound whose parts lie absurdly far apart, with infinite points in the cloud: its reach
/// is beyond single precision, so the infinite points pass the reach test, and its voxels'
/// bounds lie at the ends of i64's range. The near part is planned for, the infinite points
/// kept out of the grids (which take finite points), and a debug build does not overflow
/// reckoning the voxels.
#[test]
fn a_reach_beyond_single_precision_with_infinite_points_is_planned_without_overflow() {
    let gripper = Gripper::default();
    let can = standing(cylinder(0.03, 0.04), 0.0, 0.0, 0.0);
    let far = standing(cylinder(0.03, 0.04), 1e20, 0.0, 0.0);
    let mut scene = table_points(0.05);
    scene.extend(points_of(&can));
    scene.extend([
        [f32::INFINITY, 0.0, 0.05],
        [f32::NEG_INFINITY, f32::INFINITY, 0.05],
        [f32::NAN, 0.0, 0.0],
    ]);
    let grasps = plan(&[closed(can), closed(far)], &scene, Some(&table()), None, &gripper, 5);
    assert!(!grasps.is_empty(), "the near can is free to take");
}
