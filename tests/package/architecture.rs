//! The map in `docs/ARCHITECTURE.md` is true and the rooms are livable: no import circle
//! between the files of a crate (from `use`, `super::` and fully qualified paths alike, also
//! inside macros); each top-level module of the library uses only modules of its own layer or
//! of layers above it in the document's table, where every module has a row; no function
//! outside tests over 100 lines; no file over 600 without a line at its top that says why.
//!
//! The checks are the procedural macros of `house/` (sqscan-house), which read the sources when
//! this test is compiled; see its crate documentation for why.

use sqscan_house::{function_lengths, import_circles, large_files, layer_breaches, long_functions};

#[test]
fn no_import_circle_between_files() {
    let found = import_circles!(
        "src/lib.rs",
        "src/bin/sqscan/main.rs",
        "src/bin/sqscand.rs",
        "drivers/src/lib.rs",
        "house/src/lib.rs"
    );
    assert!(found.is_empty(), "import circles:\n{}", found.join("\n"));
}

#[test]
fn every_module_uses_only_its_own_layer_or_those_above_it() {
    let wrong = layer_breaches!("src/lib.rs", "docs/ARCHITECTURE.md");
    assert!(
        wrong.is_empty(),
        "the layers of docs/ARCHITECTURE.md:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn no_function_over_100_lines_and_no_file_over_600_without_a_reason() {
    let long = long_functions!(100, "src", "drivers/src", "house/src", "tests", "benches");
    assert!(
        long.is_empty(),
        "functions over 100 lines outside tests:\n{}",
        long.join("\n")
    );
    let large = large_files!(600, "src", "drivers/src", "house/src", "tests", "benches");
    assert!(
        large.is_empty(),
        "files over 600 lines with no `Over 600 lines ...` reason at the top:\n{}",
        large.join("\n")
    );
}

/// The circle check itself, on made-up crates (tests/package/fixtures): a circle closed by a
/// path inside `println!` is found; a test module's use and a module's re-export of its part
/// are not taken for circles; a part using what its parent's `mod.rs` defines, while the parent
/// uses the part, is a circle.
#[test]
fn the_check_finds_a_circle_closed_inside_a_macro_and_not_one_through_a_re_export() {
    let circle = import_circles!("tests/package/fixtures/circle/lib.rs");
    assert_eq!(circle.len(), 1, "{circle:?}");
    assert!(circle[0].contains("b -> a (super::a::A::default)"), "{circle:?}");
    let none = import_circles!("tests/package/fixtures/reexport/lib.rs");
    assert!(none.is_empty(), "{none:?}");
    let parent = import_circles!("tests/package/fixtures/parent/lib.rs");
    assert_eq!(
        parent.len(),
        1,
        "a part using what its parent defines, which uses it: {parent:?}"
    );
}

/// The length check itself, on a made-up file: lines from `fn` to the closing brace, braces in
/// strings, raw strings, characters and comments left out, test code passed over.
#[test]
fn lengths_count_code_braces_only_and_leave_test_code_out() {
    assert!(function_lengths!("tests/package/fixtures/lengths.rs", 6).is_empty());
    assert_eq!(
        function_lengths!("tests/package/fixtures/lengths.rs", 4),
        [
            "tests/package/fixtures/lengths.rs:14 go (5 lines)",
            "tests/package/fixtures/lengths.rs:23 six (6 lines)"
        ]
    );
}
