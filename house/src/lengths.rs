//! Function lengths, from the source text.
//!
//! syn says which functions there are and which are test code; their lengths come from the source
//! text, from the `fn` keyword to the closing brace, matched by a scanner that skips comments,
//! strings and character literals (spans would give the lines too, but only with proc-macro2's
//! `span-locations`).

use std::path::{Path, PathBuf};

use crate::modules::is_test_only;

/// A function found by syn: its name and whether it is test code.
struct Found {
    name: String,
    test: bool,
}

/// Every function of `items` (free, a method, inside a module or a macro call), in source order.
fn functions(items: &[syn::Item], test: bool, out: &mut Vec<Found>) {
    let add = |name: &syn::Ident, attrs: &[syn::Attribute], out: &mut Vec<Found>| {
        out.push(Found {
            name: name.to_string(),
            test: test || is_test_only(attrs),
        })
    };
    for item in items {
        match item {
            syn::Item::Fn(f) => add(&f.sig.ident, &f.attrs, out),
            syn::Item::Impl(i) => {
                for it in &i.items {
                    if let syn::ImplItem::Fn(f) = it {
                        let attrs = [i.attrs.as_slice(), f.attrs.as_slice()].concat();
                        add(&f.sig.ident, &attrs, out);
                    }
                }
            }
            syn::Item::Mod(m) => {
                if let Some((_, inner)) = &m.content {
                    functions(inner, test || is_test_only(&m.attrs), out);
                }
            }
            // A function inside a macro call (`widened! { fn .. }`) is still a function.
            syn::Item::Macro(m) => {
                if let Ok(inner) = syn::parse2::<syn::File>(m.mac.tokens.clone()) {
                    functions(&inner.items, test, out);
                }
            }
            _ => {}
        }
    }
}

/// The source with every comment, string and character literal blanked to spaces (line breaks
/// kept), so that the braces left are the code's.
fn code_only(text: &str) -> Vec<u8> {
    let b = text.as_bytes();
    let mut out = b.to_vec();
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let blank = |out: &mut Vec<u8>, from: usize, to: usize| {
        for c in &mut out[from..to] {
            if *c != b'\n' {
                *c = b' ';
            }
        }
    };
    let mut i = 0;
    while i < b.len() {
        let prev = if i > 0 { b[i - 1] } else { b' ' };
        let end = if b[i..].starts_with(b"//") {
            b[i..].iter().position(|&c| c == b'\n').map_or(b.len(), |n| i + n)
        } else if b[i..].starts_with(b"/*") {
            let (mut depth, mut j) = (0usize, i);
            while j < b.len() {
                if b[j..].starts_with(b"/*") {
                    depth += 1;
                    j += 2;
                } else if b[j..].starts_with(b"*/") {
                    depth -= 1;
                    j += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    j += 1;
                }
            }
            j
        } else if b[i] == b'r' && (!ident(prev) || (prev == b'b' && i >= 2 && !ident(b[i - 2]))) {
            // A raw string: r"..", r#".."#, br".." (and a raw identifier r#name is left).
            let hashes = b[i + 1..].iter().take_while(|&&c| c == b'#').count();
            if b.get(i + 1 + hashes) == Some(&b'"') {
                let close: Vec<u8> = std::iter::once(b'"').chain(std::iter::repeat_n(b'#', hashes)).collect();
                let body = i + 2 + hashes;
                b[body..]
                    .windows(close.len())
                    .position(|w| w == close.as_slice())
                    .map_or(b.len(), |n| body + n + close.len())
            } else {
                i + 1
            }
        } else if b[i] == b'"' {
            let mut j = i + 1;
            while j < b.len() && b[j] != b'"' {
                j += if b[j] == b'\\' { 2 } else { 1 };
            }
            j + 1
        } else if b[i] == b'\'' {
            // A character literal ('{', '\'', 'é'), or a lifetime ('a), which stays.
            let after = &text[i + 1..];
            let first = after.chars().next().map_or(0, char::len_utf8);
            if after.starts_with('\\') {
                after.get(2..).and_then(|a| a.find('\'')).map_or(b.len(), |n| i + 4 + n)
            } else if after[first..].starts_with('\'') {
                i + 2 + first
            } else {
                i + 1
            }
        } else {
            i + 1
        };
        let end = end.min(b.len());
        if end > i + 1 {
            blank(&mut out, i, end);
        }
        i = end.max(i + 1);
    }
    out
}

/// Where the next `fn name` at or after `from` starts in `code`, and how many lines it spans from
/// the `fn` keyword to its closing brace (1 for a declaration without a body).
fn span_of(code: &[u8], from: usize, name: &str) -> Option<(usize, usize)> {
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let mut at = from;
    let start = loop {
        let n = code.get(at..)?.windows(2).position(|w| w == b"fn")?;
        let s = at + n;
        at = s + 2;
        let before_ok = s == 0 || !ident(code[s - 1]);
        let rest = &code[s + 2..];
        let gap = rest.iter().take_while(|c| c.is_ascii_whitespace()).count();
        let named = gap > 0
            && rest[gap..].starts_with(name.as_bytes())
            && !rest.get(gap + name.len()).is_some_and(|&c| ident(c));
        if before_ok && named {
            break s;
        }
    };
    let (mut round, mut depth) = (0i32, 0i32);
    let mut end = code.len();
    for (j, &c) in code.iter().enumerate().skip(start) {
        match c {
            b'(' | b'[' => round += 1,
            b')' | b']' => round -= 1,
            b';' if round == 0 && depth == 0 => {
                end = j;
                break;
            }
            b'{' => depth += 1,
            b'}' => {
                depth -= 1;
                if depth == 0 {
                    end = j;
                    break;
                }
            }
            _ => {}
        }
    }
    let lines = code[start..end].iter().filter(|&&c| c == b'\n').count() + 1;
    Some((start, lines))
}

/// Every function outside tests in `text` longer than `limit` lines, as `file:line name (n lines)`.
pub(crate) fn long_functions(file: &Path, text: &str, limit: usize) -> Vec<String> {
    let parsed = syn::parse_file(text).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    let mut found = Vec::new();
    functions(&parsed.items, false, &mut found);
    let code = code_only(text);
    let mut out = Vec::new();
    let mut cursor = 0;
    for f in found {
        let (start, lines) = span_of(&code, cursor, &f.name)
            .unwrap_or_else(|| panic!("{}: fn {} not found in the text", file.display(), f.name));
        cursor = start + 2;
        if !f.test && lines > limit {
            let line = code[..start].iter().filter(|&&c| c == b'\n').count() + 1;
            out.push(format!("{}:{line} {} ({lines} lines)", file.display(), f.name));
        }
    }
    out
}

/// Every `.rs` file under `dir`.
pub(crate) fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// Every function outside tests longer than `limit` lines in the `.rs` files under `dirs` of
/// `base` (none in files under a `tests` directory or named `tests.rs`), and every file over
/// `file_limit` lines without an `Over N lines` reason in its first 16 lines; and the files
/// read.
pub(crate) fn long_functions_and_files(
    base: &Path,
    dirs: &[String],
    limit: usize,
    file_limit: usize,
) -> (Vec<String>, Vec<String>, Vec<PathBuf>) {
    let mut files = Vec::new();
    for dir in dirs {
        rust_files(&base.join(dir), &mut files);
    }
    files.sort();
    let (mut long, mut large) = (Vec::new(), Vec::new());
    let reason = format!("Over {file_limit} lines");
    for f in &files {
        let text = crate::modules::read(f);
        let rel = f.strip_prefix(base).unwrap_or(f);
        let in_tests = rel.starts_with("tests") || f.ends_with("tests.rs");
        if !in_tests {
            long.extend(long_functions(rel, &text, limit));
        }
        // The reason is the module's first paragraph or the one after it.
        let head: String = text.lines().take(16).collect::<Vec<_>>().join("\n");
        let n = text.lines().count();
        if n > file_limit && !head.contains(&reason) {
            large.push(format!("{} ({n} lines)", rel.display()));
        }
    }
    (long, large, files)
}
