//! The cup of the simulated Fig. 3 sweep with wild returns added (issue 18): found, and in what
//! time, over 20 noise and search seeds. `cargo run --release --example wild_points`.

use sqscan::detect::{Params, detect};
use sqscan::model::Model;
use sqscan::sim::{Scene, simulate};
use std::path::Path;
fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::from_file(&root.join("scenes/fig3_table.toml"), &root.join("models")).unwrap();
    let cup = Model::load("cup", &root.join("models")).unwrap();
    for (label, extra) in [
        ("plain", vec![]),
        ("30 m", vec![[30.0f32, 0.0, 0.7], [0.0, 30.0, 0.7]]),
        ("3e38", vec![[3e38f32, 0.0, 0.7], [0.0, -3e38, 3e38]]),
    ] {
        let mut times = vec![];
        let mut found = 0;
        for seed in 0..20u64 {
            let sweep = simulate(&scene, seed);
            let mut pts = sweep.cloud.points.clone();
            pts.extend_from_slice(&extra);
            let p = Params {
                seed,
                viewpoint: sweep.cloud.viewpoint_position(),
                ..Params::default()
            };
            let r = detect(&pts, &cup, &p);
            times.push(r.timing.total_ms);
            if r.detections.first().is_some_and(|d| d.found) {
                found += 1;
            }
        }
        times.sort_by(f64::total_cmp);
        println!(
            "{label}: found {found}/20, median {:.1} ms, p95 {:.1} ms",
            times[10], times[18]
        );
    }
}
