//! `sqscan learn --at X,Y,Z` on real scans nobody here made (`tests/data/real`, see its
//! SOURCES.md): the object a point shows, segmented from the mOSD table scenes by geometry, is
//! the object its labels give.

use crate::common::real_data as data;

/// `sqscan learn --at X,Y,Z` on the carried file, its JSON report.
fn learn_at(file: &str, at: &str) -> serde_json::Value {
    let dir = std::env::temp_dir().join(format!(
        "sqscan-learn-at-{}-{}",
        std::process::id(),
        at.replace(',', "_")
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_sqscan"))
        .args(["learn", "--cloud"])
        .arg(data(file))
        .args(["--at", at, "--name", "shown", "--force", "--out"])
        .arg(dir.join("shown.toml"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let _ = std::fs::remove_dir_all(&dir);
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The report took about as many points as the object's labels (within 5 %).
fn assert_takes(report: &serde_json::Value, labelled: f64) {
    let n = report["object_points"].as_u64().unwrap() as f64;
    assert!((n - labelled).abs() < 0.05 * labelled, "{report}");
}

/// The full sizes (2 a, m) of the report's first part, in its axes' order.
fn full_sizes(report: &serde_json::Value) -> Vec<f64> {
    report["parts"][0]["a"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| 2.0 * a.as_f64().unwrap())
        .collect()
}

/// In mOSD learn2 the gittis box (object 2, 13134 points) and the Toppas box (object 3, 10859)
/// touch: one connected cluster of 24285 points, which `--at` took whole. They meet in a
/// concave crease, and the point each one's labelled centroid gives now takes that object
/// alone; the gittis box is learned as from its labels.
#[test]
fn at_takes_the_box_shown_apart_from_the_box_it_touches() {
    let gittis = learn_at("learn2.pcd", "-0.0776,0.0351,0.6255");
    assert_takes(&gittis, 13134.0);
    let mut full = full_sizes(&gittis);
    full.sort_by(f64::total_cmp);
    for (got, want) in full.iter().zip([0.048, 0.125, 0.214]) {
        assert!((got - want).abs() < 0.1 * want, "sizes {full:?}");
    }
    let toppas = learn_at("learn2.pcd", "-0.0533,-0.0907,0.6915");
    assert_takes(&toppas, 10859.0);
}

/// In mOSD learn34 the white bowl (object 4, 9654 points) is seen as its near wall and, beyond
/// it, its inside through the opening: two clusters side by side seen from above, whose tops
/// meet at the rim. Shown at its labelled centroid, on the wall, `--at` took the wall alone and
/// learned a shape 19-21 cm across; the inside within the rim's circle is the bowl's too, and
/// the bowl comes out as from its labels (13 cm across, 9.5 cm high).
#[test]
fn at_takes_the_bowls_inside_beyond_its_wall() {
    let bowl = learn_at("learn34.pcd", "0.0593,0.1654,0.7216");
    assert_takes(&bowl, 9654.0);
    let a = full_sizes(&bowl);
    for (got, want) in a.iter().zip([0.130, 0.130, 0.095]) {
        assert!((got - want).abs() < 0.1 * want, "sizes {a:?}");
    }
}

/// In mOSD learn43 the tall tin (object 4, 13394 points) stands near the table's front edge,
/// where the plane removal leaves a sheet of the table 3-8 mm over the plane (the table is not
/// quite flat there). Shown at its labelled centroid, `--at` took 991 points of that sheet with
/// the tin, and it was learned as an open box 181 x 80 x 172 mm. Below twice the removal's band
/// the points are the plane's; the tin comes out closed and round, as from its labels (about
/// 115 mm across by its wall, 203 mm tall).
#[test]
fn at_leaves_the_tables_residue_at_the_tall_tins_foot() {
    let tin = learn_at("learn43.pcd", "0.1117,0.133,0.6133");
    assert_takes(&tin, 13394.0);
    let part = &tin["parts"][0];
    assert_eq!(part["open"], false, "{tin}");
    assert!(part["e2"].as_f64().unwrap() > 0.8, "{tin}");
    let tallest = full_sizes(&tin).into_iter().fold(0.0f64, f64::max);
    assert!((tallest - 0.203).abs() < 0.1 * 0.203, "{tin}");
}

/// In mOSD learn39 the printed mug (object 4, 3386 points) stands upright; its labelled centroid
/// lies on its near wall. Local convexity splits the mug into its outside (about 2200 points)
/// and its inside seen through the opening (about 1100), which rises to the same rim; `--at`
/// took the outside alone (2307 points), and whether the mug came out open hung on a few dozen
/// points of the table at its foot (without them, a closed 100 x 67 x 37 mm box). The inside,
/// level with the rim and within its circle, is the mug's: it comes out open, 76 mm across and
/// 98 mm tall, as from its labels.
#[test]
fn at_takes_the_mugs_inside_beyond_its_rim() {
    let mug = learn_at("learn39.pcd", "-0.0795,0.0839,0.8192");
    assert_takes(&mug, 3386.0);
    let part = &mug["parts"][0];
    assert_eq!(part["open"], true, "{mug}");
    let a = full_sizes(&mug);
    for (got, want) in a.iter().zip([0.076, 0.076, 0.098]) {
        assert!((got - want).abs() < 0.1 * want, "sizes {a:?}");
    }
}

/// What one view fixes of the gittis box shown in mOSD learn2 (standing, its broad face towards
/// the sensor): the report gives each size the view allows, never below the learned one, and its
/// true thickness (49 mm, its height lying flat elsewhere) and height (213 mm) lie within them.
/// Its length, about 138 mm, does not: the table seen past its ends allows 127 where its points
/// span 124, the depth camera having eaten into its edges.
#[test]
fn at_reports_what_the_view_allows_of_each_size() {
    let gittis = learn_at("learn2.pcd", "-0.0776,0.0351,0.6255");
    let part = &gittis["parts"][0];
    let list = |key: &str| -> Vec<f64> {
        part[key]
            .as_array()
            .unwrap_or_else(|| panic!("{key}: {part}"))
            .iter()
            .map(|v| v.as_f64().unwrap_or(f64::INFINITY))
            .collect()
    };
    let (extent, allowed) = (list("extent_m"), list("allowed_extent_m"));
    for (e, a) in extent.iter().zip(&allowed) {
        assert!(a >= e, "{part}");
    }
    let mut axes: Vec<usize> = (0..3).collect();
    axes.sort_by(|&i, &j| extent[i].total_cmp(&extent[j]));
    let (thin, tall) = (axes[0], axes[2]);
    assert!(
        extent[thin] < 0.049 && allowed[thin] >= 0.049 && allowed[thin] < 0.1,
        "{part}"
    );
    assert!(allowed[tall] >= 0.213 && allowed[tall] < 0.25, "{part}");
}
