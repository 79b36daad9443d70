//! Detection time in one warm process: `cargo run --release --example warm -- MODEL CLOUD [N]`
//! runs the detector on one cloud for seeds 1..=N and prints the median of each stage's time.
use sqscan::cloud::read_cloud;
use sqscan::detect::{Params, detect};
use sqscan::model::Model;
use std::path::Path;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let model = Model::load(&args[1], &root.join("models")).unwrap();
    let cloud = read_cloud(Path::new(&args[2])).unwrap();
    let n: u64 = args.get(3).map_or(31, |s| s.parse().unwrap());
    let (mut plane, mut search, mut verify, mut total, mut found) = (vec![], vec![], vec![], vec![], 0);
    for seed in 1..=n {
        let p = Params {
            seed,
            viewpoint: cloud.viewpoint_position().or(Some(nalgebra::Point3::origin())),
            ..Params::default()
        };
        let r = detect(&cloud.points, &model, &p);
        plane.push(r.timing.plane_ms);
        search.push(r.timing.search_ms);
        verify.push(r.timing.verify_ms);
        total.push(r.timing.total_ms);
        found += r.detections.first().is_some_and(|d| d.found) as usize;
    }
    println!(
        "{} found {found}/{n}: median plane {:.2} search {:.2} verify {:.2} total {:.2} ms",
        args[1],
        median(plane),
        median(search),
        median(verify),
        median(total)
    );
}
