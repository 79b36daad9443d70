//! Issue #6: a model learned from a simulated single-object scan (fig3 rig, 2 mm noise at 1 m)
//! of every shipped single-part model: sizes within 5 mm and e1, e2 within 0.1 of the truth,
//! after matching the learned axes to the true ones (symmetric equivalents compare equal).

use sqscan::learn::LearnParams;
use sqscan::learn::simulated::learn_simulated;
use sqscan::model::Model;
use std::path::PathBuf;

fn model(name: &str) -> Model {
    Model::load(name, &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("models")).unwrap()
}

fn check(name: &str) {
    let m = model(name);
    let t = learn_simulated(&m, None, 1, &LearnParams::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
    let r = &t.learned.parts[0];
    eprintln!(
        "{name}: truth {} | learned {} | da {:?} de1 {:.3} de2 {:.3} centre {:.4} | {} pts, {} object, rms {:.2} mm, start {}, open {}, {:.2} s",
        t.truth.shape,
        r.placed.shape,
        t.errors.da.map(|d| (d * 1e4).round() / 10.0),
        t.errors.de1,
        t.errors.de2,
        t.errors.centre,
        t.points,
        t.learned.object_points,
        r.rms * 1e3,
        r.start,
        r.open,
        t.seconds
    );
    assert!(
        t.errors.max_size_error() < 0.005 && t.errors.max_exponent_error() < 0.1,
        "{name}: size errors {:?} m, e1 {:+.3}, e2 {:+.3}",
        t.errors.da,
        t.errors.de1,
        t.errors.de2
    );
}

macro_rules! cases {
    ($($name:ident),*) => {
        $(#[test]
        fn $name() {
            check(stringify!($name));
        })*
    };
}

cases!(
    ball,
    book,
    bowl,
    cup_body,
    large_wooden_bowl,
    mallet_head,
    mallet_shaft,
    mouse,
    mug,
    pen,
    spray_tin,
    white_bowl,
    wooden_bowl
);
