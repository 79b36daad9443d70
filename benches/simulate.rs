//! Simulator speed: one sweep of each shipped scene (the paper's two at their own resolution, and
//! ten objects under a full 1536-column sensor, which must stay well under a second to drive a
//! real-time mock sensor). Figures go to BENCHMARKS.md.

use criterion::{Criterion, criterion_group, criterion_main};
use sqscan::sim::{Scene, simulate};
use std::path::Path;
use std::time::Duration;

fn scene(name: &str) -> Scene {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    Scene::from_file(&root.join("scenes").join(name), &root.join("models")).expect("shipped scene")
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("simulate");
    g.sample_size(20).measurement_time(Duration::from_secs(10));
    for name in ["fig3_table.toml", "fig4_tools.toml", "clutter10.toml"] {
        let s = scene(name);
        let mut seed = 0;
        g.bench_function(name.trim_end_matches(".toml"), |b| {
            b.iter(|| {
                seed += 1;
                simulate(&s, seed)
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
