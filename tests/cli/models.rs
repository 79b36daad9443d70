//! The shipped model library loads, and broken model files are refused with the file, the field
//! and what was wrong.

use sqscan::model::{Model, load_dir};
use std::path::{Path, PathBuf};

fn models_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("models")
}

#[test]
fn every_shipped_model_loads() {
    let all = load_dir(&models_dir()).unwrap();
    assert!(all.len() >= 15, "only {} models", all.len());
    for m in &all {
        let m = m.as_ref().unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(m.connections.len(), m.parts.len() - 1);
    }
    let cup = Model::load("cup", &models_dir()).unwrap();
    assert_eq!(cup.parts.len(), 2);
    assert!((cup.connections[0].angle.to_degrees() - 90.0).abs() < 1e-9);
    assert!((cup.connections[0].distance - 0.05).abs() < 1e-12);
    let mallet = Model::load("mallet", &models_dir()).unwrap();
    assert!((mallet.connections[0].distance - 0.17).abs() < 1e-12);
    let bowl = Model::load("bowl", &models_dir()).unwrap();
    assert_eq!(bowl.parts[0].shape.a, [0.06, 0.06, 0.02]);
    assert_eq!(bowl.parts[0].hypotheses, Some(10));
}

fn refused(text: &str) -> String {
    let err = Model::from_toml_str(text, Path::new("models/broken.toml"))
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("models/broken.toml: "), "{err}");
    err
}

const PART: &str = "[[part]]\nname = \"p\"\na = [0.01, 0.02, 0.03]\ne1 = 0.5\ne2 = 1.0\n";

#[test]
fn broken_models_are_refused_naming_file_field_and_fault() {
    Model::from_toml_str(PART, Path::new("models/broken.toml")).unwrap();
    let e = refused(&PART.replace("e1 = 0.5", "e1 = 2.5"));
    assert!(e.contains("part[0] (p).e1") && e.contains("2.5"), "{e}");
    let e = refused(&PART.replace("0.01, 0.02", "-0.01, 0.02"));
    assert!(e.contains("part[0] (p).a") && e.contains("a1"), "{e}");
    let e = refused(&PART.replace("0.01, 0.02, 0.03", "10, 20, 30"));
    assert!(e.contains("mm"), "{e}");
    let e = refused(&format!("{PART}kz = 0.3\n"));
    assert!(e.contains("kz"), "{e}");
    let e = refused(&PART.replace("e2 = 1.0\n", ""));
    assert!(e.contains("e2"), "{e}");
    let e = refused(&PART.replace("e1 = 0.5", "e1 = \"round\""));
    assert!(e.contains("e1") && e.contains("line"), "{e}");
    let e = refused("name = \"x\"\n");
    assert!(e.contains("0 parts"), "{e}");
    let e = refused(&format!("{PART}{}", PART));
    assert!(e.contains("share this name"), "{e}");
    let two = format!("{PART}{}", PART.replace("\"p\"", "\"q\""));
    let e = refused(&two);
    assert!(e.contains("2 parts need 1 connections"), "{e}");
    let e = refused(&format!(
        "{two}[[connection]]\nparts = [\"p\", \"r\"]\nangle_deg = 0\ndistance = 0\n"
    ));
    assert!(e.contains("connection[0].parts") && e.contains("\"r\""), "{e}");
    let e = refused(&format!(
        "{two}[[connection]]\nparts = [\"p\", \"q\"]\nangle_deg = 0\ndistance = 0.05\n"
    ));
    assert!(
        e.contains("connection[0].distance") && e.contains("0.0000 m apart"),
        "{e}"
    );
    let e = refused(&format!(
        "{two}[[connection]]\nparts = [\"p\", \"q\"]\nangle_deg = 45\ndistance = 0\n"
    ));
    assert!(e.contains("connection[0].angle") && e.contains("45.00 deg"), "{e}");
    let e = refused(&format!("{two}[[connection]]\nparts = [\"p\", \"q\"]\ndistance = 0\n"));
    assert!(e.contains("exactly one of angle_rad, angle_deg"), "{e}");
    let e = refused(&PART.replace(
        "e2 = 1.0",
        "e2 = 1.0\npose = { position = [0, 0, 0], orientation = [0, 0, 0, 3] }",
    ));
    assert!(e.contains("part[0] (p).pose") && e.contains("unit quaternion"), "{e}");
}

#[test]
fn a_missing_model_names_the_file() {
    let e = Model::load("no_such_object", &models_dir()).unwrap_err().to_string();
    assert!(e.contains("no_such_object.toml"), "{e}");
}
