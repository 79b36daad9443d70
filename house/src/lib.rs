//! The house's checks on the sqscan sources, run by its tests (`tests/package/architecture.rs`):
//! no import circle between the files of a crate, each top-level module of the library using
//! only its own layer or those above it in `docs/ARCHITECTURE.md`'s table, no function outside
//! tests over a length, no file over a length without a reason at its top.
//!
//! Procedural macros, so that syn is built once for the whole tree: as a dev-dependency of a
//! test it was also built for the tests' target, and cargo then built every derive macro of the
//! tree a second time for the test profile (three minutes of the test suite's build on two
//! cores). Each macro reads the files at compile time and expands to the problems it found, a
//! `&[&str]` (empty when all is well), with the files it read included as unused constants so
//! that changing one of them compiles the test again. Paths are relative to the directory of
//! the manifest of the crate that calls the macro.

use std::path::{Path, PathBuf};

use proc_macro::TokenStream;
use quote::quote;
use syn::parse::Parser;
use syn::punctuated::Punctuated;

mod lengths;
mod modules;

/// The macro's arguments: string and integer literals, comma-separated.
fn arguments(input: TokenStream) -> (Vec<String>, Vec<usize>) {
    let args = Punctuated::<syn::Lit, syn::Token![,]>::parse_terminated
        .parse(input)
        .unwrap_or_else(|e| panic!("arguments: {e}"));
    let (mut strings, mut numbers) = (Vec::new(), Vec::new());
    for a in args {
        match a {
            syn::Lit::Str(s) => strings.push(s.value()),
            syn::Lit::Int(i) => numbers.push(i.base10_parse().unwrap_or_else(|e| panic!("{e}"))),
            _ => panic!("arguments are string or integer literals"),
        }
    }
    (strings, numbers)
}

/// The directory of the calling crate's manifest.
fn base() -> PathBuf {
    PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR is set by cargo"))
}

/// `&[problems]`, with every file read included so that a change to it compiles the caller again.
fn expand(problems: &[String], read: &[PathBuf]) -> TokenStream {
    let files: Vec<String> = read
        .iter()
        .filter_map(|p| p.canonicalize().ok())
        .map(|p| p.display().to_string())
        .collect();
    quote!({
        const _: &[&str] = &[#(include_str!(#files)),*];
        &[#(#problems),*] as &'static [&'static str]
    })
    .into()
}

/// `import_circles!("src/lib.rs", ...)`: the import circles between the files of each crate
/// whose root file is given, each as `root:` and the uses that close it.
#[proc_macro]
pub fn import_circles(input: TokenStream) -> TokenStream {
    let (roots, _) = arguments(input);
    let (problems, read) = modules::import_circles(&base(), &roots);
    expand(&problems, &read)
}

/// `layer_breaches!("src/lib.rs", "docs/ARCHITECTURE.md")`: the library's top-level modules
/// without a row in the document's layers table, its uses of a lower layer, and circles between
/// its top-level modules.
#[proc_macro]
pub fn layer_breaches(input: TokenStream) -> TokenStream {
    let (paths, _) = arguments(input);
    let [lib, doc] = &paths[..] else {
        panic!("layer_breaches!(LIB_ROOT, DOCUMENT)")
    };
    let (problems, read) = modules::layer_breaches(&base(), lib, doc);
    expand(&problems, &read)
}

/// `long_functions!(LIMIT, "dir", ...)`: the functions outside tests longer than LIMIT lines
/// in the `.rs` files under the directories (files under `tests` or named `tests.rs` are
/// tests), as `file:line name (n lines)`.
#[proc_macro]
pub fn long_functions(input: TokenStream) -> TokenStream {
    let (dirs, limits) = arguments(input);
    let (long, _, read) = lengths::long_functions_and_files(&base(), &dirs, limits[0], usize::MAX);
    expand(&long, &read)
}

/// `large_files!(LIMIT, "dir", ...)`: the `.rs` files under the directories over LIMIT lines
/// whose first 16 lines give no reason (`Over LIMIT lines ...`).
#[proc_macro]
pub fn large_files(input: TokenStream) -> TokenStream {
    let (dirs, limits) = arguments(input);
    let (_, large, read) = lengths::long_functions_and_files(&base(), &dirs, usize::MAX, limits[0]);
    expand(&large, &read)
}

/// `function_lengths!("file.rs", LIMIT)`: the functions outside tests of one file longer than
/// LIMIT lines, wherever the file lies (the checks' own tests give made-up files).
#[proc_macro]
pub fn function_lengths(input: TokenStream) -> TokenStream {
    let (files, limits) = arguments(input);
    let path = base().join(&files[0]);
    let text = modules::read(&path);
    let long = lengths::long_functions(Path::new(&files[0]), &text, limits[0]);
    expand(&long, &[path])
}
