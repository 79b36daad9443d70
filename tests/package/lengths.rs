//! The rooms are livable: no function outside tests over 100 lines, no file over 600 without a
//! line at its top that says why.
//!
//! syn says which functions there are and which are test code; their lengths come from the source
//! text, from the `fn` keyword to the closing brace, matched by a scanner that skips comments,
//! strings and character literals. Spans would give the lines too, but only with proc-macro2's
//! `span-locations`, a feature that, enabled by a dev-dependency alone, made the lint, doc and
//! test steps each rebuild every procedural macro in the tree.

use std::path::{Path, PathBuf};

use crate::architecture::{is_test_only, read, root};

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
fn long_functions(file: &Path, text: &str, limit: usize) -> Vec<String> {
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
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn no_function_over_100_lines_and_no_file_over_600_without_a_reason() {
    let mut files = Vec::new();
    for dir in ["src", "drivers/src", "tests", "benches"] {
        rust_files(&root().join(dir), &mut files);
    }
    files.sort();
    let (mut long, mut large) = (Vec::new(), Vec::new());
    for f in &files {
        let text = read(f);
        let in_tests = f.starts_with(root().join("tests")) || f.ends_with("tests.rs");
        if !in_tests {
            long.extend(long_functions(f.strip_prefix(root()).unwrap(), &text, 100));
        }
        // The reason is the module's first paragraph or the one after it.
        let head: String = text.lines().take(16).collect::<Vec<_>>().join("\n");
        if text.lines().count() > 600 && !head.contains("Over 600 lines") {
            large.push(format!(
                "{} ({} lines)",
                f.strip_prefix(root()).unwrap().display(),
                text.lines().count()
            ));
        }
    }
    assert!(
        long.is_empty(),
        "functions over 100 lines outside tests:\n{}",
        long.join("\n")
    );
    assert!(
        large.is_empty(),
        "files over 600 lines with no `Over 600 lines ...` reason at the top:\n{}",
        large.join("\n")
    );
}

#[test]
fn lengths_count_code_braces_only_and_leave_test_code_out() {
    // Braces in strings, raw strings, characters and comments are not the code's; a lifetime is
    // not a character; a test function of the same name earlier in the file is passed over.
    let text = r###"
#[cfg(test)]
mod tests {
    fn go() {
        let _ = 1;
        let _ = 2;
        let _ = 3;
    }
}

/// Five lines, from `fn` to its brace.
fn go<'a>(s: &'a str) -> usize {
    let _ = ("}", '{', '}', r#"}"}"#, b"{", '\'', "\"}"); // }
    /* } /* nested } */ } */
    s.len()
}

impl S {
    fn short(&self) {}
    fn declared();
    fn six() -> [u8; 2] {
        let x = [0u8; 2];
        let r#type = x;
        // {
        r#type
    }
}
"###;
    let file = Path::new("made/up.rs");
    assert_eq!(long_functions(file, text, 6), Vec::<String>::new());
    assert_eq!(
        long_functions(file, text, 4),
        vec!["made/up.rs:12 go (5 lines)", "made/up.rs:21 six (6 lines)"]
    );
}
