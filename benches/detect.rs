//! Detector speed on the paper's scenes: the bowl, the cup (body + handle) and the cup body alone
//! in `fig3_table`, the mallet (head + shaft) in `fig4_tools`, each on one simulated sweep with a
//! new search seed per iteration. Figures go to BENCHMARKS.md beside the paper's Tables I and II.

use criterion::{Criterion, criterion_group, criterion_main};
use sqscan::detect::{Params, detect};
use sqscan::model::Model;
use sqscan::sim::{Scene, simulate};
use std::path::Path;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let models = root.join("models");
    let mut g = c.benchmark_group("detect");
    g.sample_size(20).measurement_time(Duration::from_secs(8));
    for (scene, model) in [
        ("fig3_table", "bowl"),
        ("fig3_table", "cup"),
        ("fig3_table", "cup_body"),
        ("fig4_tools", "mallet"),
    ] {
        let s = Scene::from_file(&root.join(format!("scenes/{scene}.toml")), &models).expect("shipped scene");
        let m = Model::load(model, &models).expect("shipped model");
        let sweep = simulate(&s, 0);
        let viewpoint = sweep.cloud.viewpoint_position();
        let mut seed = 0;
        g.bench_function(format!("{scene}/{model}"), |b| {
            b.iter(|| {
                seed += 1;
                // Only the time is measured here; how often it is right is `sqscan eval`'s job.
                detect(
                    &sweep.cloud.points,
                    &m,
                    &Params {
                        seed,
                        viewpoint,
                        ..Params::default()
                    },
                )
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
