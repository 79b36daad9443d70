//! Hostile and broken input to the detector (issue 18): each case that once gave a wrong answer
//! keeps a test named after it. Bounds are asserted with a wide margin; the tight figures are in
//! BENCHMARKS.md.

use sqscan::detect::{Params, detect};
use sqscan::eval;
use sqscan::model::Model;
use sqscan::sim::{Scene, simulate};
use std::path::PathBuf;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The cup of the simulated Fig. 3 sweep, found where it is with `extra` points added to the
/// cloud (a few wild returns), at each of a few seeds.
fn cup_found_with(extra: &[[f32; 3]]) {
    let scene = Scene::from_file(&root().join("scenes/fig3_table.toml"), &root().join("models")).unwrap();
    let cup = Model::load("cup", &root().join("models")).unwrap();
    let (_, truth) = eval::truth_pose(&scene, &cup).unwrap();
    for seed in 0..3u64 {
        let sweep = simulate(&scene, seed);
        let mut points = sweep.cloud.points.clone();
        points.extend_from_slice(extra);
        let params = Params {
            seed,
            viewpoint: sweep.cloud.viewpoint_position(),
            ..Params::default()
        };
        let report = detect(&points, &cup, &params);
        let best = report.detections.first();
        assert!(
            best.is_some_and(|d| d.found),
            "seed {seed}: the cup is not found with {extra:?} added: {report:?}"
        );
        let error = (best.unwrap().pose.translation.vector - truth.translation.vector).norm();
        assert!(
            error < 0.01,
            "seed {seed}: the cup is {error} m off with {extra:?} added"
        );
    }
}

#[test]
fn the_cup_is_found_in_the_plain_sweep() {
    cup_found_with(&[]);
}

/// Two returns 30 m away (a window, a reflection) made plane removal fail: the cup went from
/// found to "not here", 15 times slower.
#[test]
fn two_points_thirty_metres_away_do_not_hide_the_cup() {
    cup_found_with(&[[30.0, 0.0, 0.7], [0.0, 30.0, 0.7]]);
}

/// The same with two returns at the end of f32's range.
#[test]
fn two_points_at_the_end_of_f32_do_not_hide_the_cup() {
    cup_found_with(&[[3e38, 0.0, 0.7], [0.0, -3e38, 3e38]]);
}
