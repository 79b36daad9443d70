//! The module map: every file of a crate read through its `mod` tree, the paths each uses
//! resolved to the modules they name, and the circles and layer breaches among them.
//!
//! Code under `#[cfg(test)]` is left out: a test may reach wherever it needs to. A `pub use`
//! re-export is followed to where the item lives instead of counting as a use, so that a
//! module's face (its `mod.rs` re-exporting its parts) is not taken for a dependency.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use syn::visit::Visit;

type ModPath = Vec<String>;

#[derive(Default)]
struct Module {
    file: PathBuf,
    children: BTreeSet<String>,
    /// Items defined here (types, functions, traits, constants, macros).
    defines: BTreeSet<String>,
    /// Names that this module's top-level `use` declarations bring in, with the path each is for
    /// (as written, relative to this module).
    imports: BTreeMap<String, ModPath>,
    /// `use x::*` sources, as written.
    globs: Vec<ModPath>,
    /// Every path this module's code uses, as written (relative to this module).
    uses: Vec<ModPath>,
}

struct Crate {
    modules: BTreeMap<ModPath, Module>,
}

pub(crate) fn is_test_only(attrs: &[syn::Attribute]) -> bool {
    attrs.iter().any(|a| {
        a.path().is_ident("cfg")
            && a.meta
                .require_list()
                .map(|l| {
                    l.tokens
                        .clone()
                        .into_iter()
                        .any(|t| matches!(&t, proc_macro2::TokenTree::Ident(i) if i == "test"))
                })
                .unwrap_or(false)
    })
}

/// The `use` tree flattened: (the name it binds, the path, whether it is a glob).
fn flatten_use(tree: &syn::UseTree, prefix: &mut ModPath, out: &mut Vec<(String, ModPath, bool)>) {
    match tree {
        syn::UseTree::Path(p) => {
            prefix.push(p.ident.to_string());
            flatten_use(&p.tree, prefix, out);
            prefix.pop();
        }
        syn::UseTree::Name(n) => {
            let name = n.ident.to_string();
            let mut path = prefix.clone();
            if name != "self" {
                path.push(name.clone());
            }
            let bound = if name == "self" {
                prefix.last().cloned().unwrap_or_default()
            } else {
                name
            };
            out.push((bound, path, false));
        }
        syn::UseTree::Rename(r) => {
            let mut path = prefix.clone();
            if r.ident != "self" {
                path.push(r.ident.to_string());
            }
            out.push((r.rename.to_string(), path, false));
        }
        syn::UseTree::Glob(_) => out.push((String::new(), prefix.clone(), true)),
        syn::UseTree::Group(g) => {
            for t in &g.items {
                flatten_use(t, prefix, out);
            }
        }
    }
}

/// Collects the paths of code outside tests, including `crate::`/`super::` paths in macros.
struct Paths<'a> {
    uses: &'a mut Vec<ModPath>,
}

impl Paths<'_> {
    fn tokens(&mut self, stream: proc_macro2::TokenStream) {
        let mut flat = Vec::new();
        flatten_tokens(stream, &mut flat);
        let mut i = 0;
        while i < flat.len() {
            let starts = matches!(&flat[i], Tok::Ident(_))
                && (i < 2 || !matches!((&flat[i - 2], &flat[i - 1]), (Tok::Colon, Tok::Colon)));
            if starts {
                let mut path = Vec::new();
                let mut j = i;
                while let Tok::Ident(s) = &flat[j] {
                    path.push(s.clone());
                    if j + 3 < flat.len()
                        && matches!((&flat[j + 1], &flat[j + 2]), (Tok::Colon, Tok::Colon))
                        && matches!(&flat[j + 3], Tok::Ident(_))
                    {
                        j += 3;
                    } else {
                        break;
                    }
                }
                if path.len() > 1 {
                    self.uses.push(path);
                }
                i = j + 1;
            } else {
                i += 1;
            }
        }
    }
}

enum Tok {
    Ident(String),
    Colon,
    Other,
}

fn flatten_tokens(stream: proc_macro2::TokenStream, out: &mut Vec<Tok>) {
    for t in stream {
        match t {
            proc_macro2::TokenTree::Ident(i) => out.push(Tok::Ident(i.to_string())),
            proc_macro2::TokenTree::Punct(p) if p.as_char() == ':' => out.push(Tok::Colon),
            proc_macro2::TokenTree::Group(g) => {
                out.push(Tok::Other);
                flatten_tokens(g.stream(), out);
                out.push(Tok::Other);
            }
            _ => out.push(Tok::Other),
        }
    }
}

impl<'ast> Visit<'ast> for Paths<'_> {
    fn visit_item(&mut self, i: &'ast syn::Item) {
        let attrs = match i {
            syn::Item::Fn(f) => &f.attrs,
            syn::Item::Mod(m) => &m.attrs,
            syn::Item::Impl(m) => &m.attrs,
            syn::Item::Const(m) => &m.attrs,
            syn::Item::Struct(m) => &m.attrs,
            syn::Item::Enum(m) => &m.attrs,
            _ => return syn::visit::visit_item(self, i),
        };
        if !is_test_only(attrs) {
            syn::visit::visit_item(self, i);
        }
    }
    fn visit_impl_item_fn(&mut self, f: &'ast syn::ImplItemFn) {
        if !is_test_only(&f.attrs) {
            syn::visit::visit_impl_item_fn(self, f);
        }
    }
    fn visit_item_use(&mut self, u: &'ast syn::ItemUse) {
        let mut flat = Vec::new();
        flatten_use(&u.tree, &mut Vec::new(), &mut flat);
        self.uses.extend(flat.into_iter().map(|(_, p, _)| p));
    }
    fn visit_path(&mut self, p: &'ast syn::Path) {
        if p.leading_colon.is_none() && p.segments.len() > 1 {
            self.uses.push(p.segments.iter().map(|s| s.ident.to_string()).collect());
        }
        syn::visit::visit_path(self, p);
    }
    fn visit_macro(&mut self, m: &'ast syn::Macro) {
        self.tokens(m.tokens.clone());
        syn::visit::visit_macro(self, m);
    }
}

fn item_name(item: &syn::Item) -> Option<String> {
    Some(match item {
        syn::Item::Const(i) => i.ident.to_string(),
        syn::Item::Enum(i) => i.ident.to_string(),
        syn::Item::Fn(i) => i.sig.ident.to_string(),
        syn::Item::Macro(i) => i.ident.as_ref()?.to_string(),
        syn::Item::Static(i) => i.ident.to_string(),
        syn::Item::Struct(i) => i.ident.to_string(),
        syn::Item::Trait(i) => i.ident.to_string(),
        syn::Item::Type(i) => i.ident.to_string(),
        syn::Item::Union(i) => i.ident.to_string(),
        _ => return None,
    })
}

impl Crate {
    fn load(root: &Path) -> Crate {
        let mut krate = Crate {
            modules: BTreeMap::new(),
        };
        let file = syn::parse_file(&read(root)).unwrap_or_else(|e| panic!("{}: {e}", root.display()));
        krate.add(Vec::new(), root, root.parent().unwrap(), &file.items);
        krate
    }

    /// Adds module `path` with `items` (from `file`); its children's files are under `dir`.
    fn add(&mut self, path: ModPath, file: &Path, dir: &Path, items: &[syn::Item]) {
        let mut m = Module {
            file: file.to_path_buf(),
            ..Module::default()
        };
        for item in items {
            match item {
                syn::Item::Mod(sub) if is_test_only(&sub.attrs) => {}
                syn::Item::Mod(sub) => {
                    let name = sub.ident.to_string();
                    m.children.insert(name.clone());
                    let mut child = path.clone();
                    child.push(name.clone());
                    match &sub.content {
                        Some((_, inner)) => self.add(child, file, &dir.join(&name), inner),
                        None => {
                            let flat = dir.join(format!("{name}.rs"));
                            let (f, d) = if flat.exists() {
                                (flat, dir.join(&name))
                            } else {
                                (dir.join(&name).join("mod.rs"), dir.join(&name))
                            };
                            let parsed = syn::parse_file(&read(&f)).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
                            self.add(child, &f, &d, &parsed.items);
                        }
                    }
                }
                syn::Item::Use(u) => {
                    let mut flat = Vec::new();
                    flatten_use(&u.tree, &mut Vec::new(), &mut flat);
                    for (name, p, glob) in flat {
                        if glob {
                            m.globs.push(p.clone());
                        } else {
                            m.imports.insert(name, p.clone());
                        }
                        // A private `use` is this module using the item; a visible one is its
                        // face, followed when another module names the item through it.
                        if matches!(u.vis, syn::Visibility::Inherited) {
                            m.uses.push(p);
                        }
                    }
                }
                other => {
                    if let Some(name) = item_name(other) {
                        m.defines.insert(name);
                    }
                    Paths { uses: &mut m.uses }.visit_item(other);
                }
            }
        }
        self.modules.insert(path, m);
    }

    /// `written`, as code in module `at` wrote it, as a path from the crate root; `None` for
    /// other crates, locals and the prelude.
    fn absolute(&self, at: &ModPath, written: &ModPath, depth: usize) -> Option<ModPath> {
        let first = written.first()?;
        let mut base = at.clone();
        let mut rest = &written[..];
        match first.as_str() {
            "crate" => {
                base.clear();
                rest = &written[1..];
            }
            "self" => rest = &written[1..],
            "super" => {
                while rest.first().is_some_and(|s| s == "super") {
                    base.pop()?;
                    rest = &rest[1..];
                }
            }
            _ => {
                let m = self.modules.get(at)?;
                if m.children.contains(first) {
                    // `child::item`: base is this module.
                } else if let Some(import) = m.imports.get(first) {
                    if depth > 8 || import.first() == Some(first) && import.len() == 1 {
                        return None;
                    }
                    let mut full = self.absolute(at, import, depth + 1)?;
                    full.extend(written[1..].iter().cloned());
                    return Some(full);
                } else {
                    return None;
                }
            }
        }
        base.extend(rest.iter().cloned());
        Some(base)
    }

    /// The module that holds what absolute path `p` names, through re-exports.
    fn owner(&self, p: &ModPath, depth: usize) -> ModPath {
        let mut m: ModPath = Vec::new();
        let mut i = 0;
        while i < p.len() && self.modules[&m].children.contains(&p[i]) {
            m.push(p[i].clone());
            i += 1;
        }
        if i == p.len() || depth > 8 {
            return m;
        }
        let module = &self.modules[&m];
        let name = &p[i];
        if module.defines.contains(name) {
            return m;
        }
        let follow = |written: &ModPath| -> Option<ModPath> {
            let mut target = self.absolute(&m, written, 0)?;
            target.extend(p[i + 1..].iter().cloned());
            Some(self.owner(&target, depth + 1))
        };
        if let Some(owner) = module.imports.get(name).and_then(follow) {
            return owner;
        }
        for glob in &module.globs {
            let Some(source) = self.absolute(&m, glob, 0) else {
                continue;
            };
            let source = self.owner(&source, depth + 1);
            let s = &self.modules[&source];
            if s.defines.contains(name) || s.imports.contains_key(name) || s.children.contains(name) {
                let mut target = source;
                target.extend(p[i..].iter().cloned());
                return self.owner(&target, depth + 1);
            }
        }
        m
    }

    /// Every module's uses of other modules, with one path that shows each.
    fn edges(&self) -> BTreeMap<(ModPath, ModPath), String> {
        let mut edges = BTreeMap::new();
        for (at, m) in &self.modules {
            for written in &m.uses {
                let Some(abs) = self.absolute(at, written, 0) else {
                    continue;
                };
                let to = self.owner(&abs, 0);
                if &to != at && !to.is_empty() {
                    edges.entry((at.clone(), to)).or_insert_with(|| written.join("::"));
                }
            }
        }
        edges
    }
}

pub(crate) fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn name(p: &ModPath) -> String {
    if p.is_empty() { "crate".into() } else { p.join("::") }
}

/// The strongly connected components of more than one node (Tarjan).
fn circles<N: Ord + Clone>(nodes: &BTreeSet<N>, next: &BTreeMap<N, BTreeSet<N>>) -> Vec<Vec<N>> {
    struct T<'a, N: Ord> {
        next: &'a BTreeMap<N, BTreeSet<N>>,
        index: BTreeMap<N, usize>,
        low: BTreeMap<N, usize>,
        stack: Vec<N>,
        on: BTreeSet<N>,
        out: Vec<Vec<N>>,
    }
    impl<N: Ord + Clone> T<'_, N> {
        fn visit(&mut self, v: &N) {
            let i = self.index.len();
            self.index.insert(v.clone(), i);
            self.low.insert(v.clone(), i);
            self.stack.push(v.clone());
            self.on.insert(v.clone());
            for w in self.next.get(v).into_iter().flatten() {
                if !self.index.contains_key(w) {
                    self.visit(w);
                    let l = self.low[v].min(self.low[w]);
                    self.low.insert(v.clone(), l);
                } else if self.on.contains(w) {
                    let l = self.low[v].min(self.index[w]);
                    self.low.insert(v.clone(), l);
                }
            }
            if self.low[v] == self.index[v] {
                let mut scc = Vec::new();
                loop {
                    let w = self.stack.pop().unwrap();
                    self.on.remove(&w);
                    let done = &w == v;
                    scc.push(w);
                    if done {
                        break;
                    }
                }
                if scc.len() > 1 {
                    scc.sort();
                    self.out.push(scc);
                }
            }
        }
    }
    let mut t = T {
        next,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    for n in nodes {
        if !t.index.contains_key(n) {
            t.visit(n);
        }
    }
    t.out
}

/// The circles between files of the crate rooted at `root`, each with the uses that close it.
fn file_circles(krate: &Crate, edges: &BTreeMap<(ModPath, ModPath), String>) -> Vec<String> {
    let file = |p: &ModPath| krate.modules[p].file.clone();
    let nodes: BTreeSet<PathBuf> = krate.modules.values().map(|m| m.file.clone()).collect();
    let mut next: BTreeMap<PathBuf, BTreeSet<PathBuf>> = BTreeMap::new();
    for (a, b) in edges.keys() {
        if file(a) != file(b) {
            next.entry(file(a)).or_default().insert(file(b));
        }
    }
    circles(&nodes, &next)
        .into_iter()
        .map(|scc| {
            let inside: BTreeSet<&PathBuf> = scc.iter().collect();
            let mut text = String::new();
            for ((a, b), via) in edges {
                if inside.contains(&file(a)) && inside.contains(&file(b)) && file(a) != file(b) {
                    text += &format!("\n  {} -> {} ({via})", name(a), name(b));
                }
            }
            text
        })
        .collect()
}

/// The import circles between the files of each crate under `base` (its root file given), as
/// `root:` and the uses that close each circle; and the files read.
pub(crate) fn import_circles(base: &Path, crate_roots: &[String]) -> (Vec<String>, Vec<PathBuf>) {
    let (mut found, mut read) = (Vec::new(), Vec::new());
    for crate_root in crate_roots {
        let krate = Crate::load(&base.join(crate_root));
        for c in file_circles(&krate, &krate.edges()) {
            found.push(format!("{crate_root}:{c}"));
        }
        read.extend(krate.modules.values().map(|m| m.file.clone()));
    }
    (found, read)
}

/// The layers table of the document: each top-level module's row, top row first.
fn layers(doc: &str) -> BTreeMap<String, usize> {
    let table = doc.split("## Layers").nth(1).unwrap_or_default();
    let mut rows = BTreeMap::new();
    let mut row = 0;
    for line in table
        .lines()
        .skip_while(|l| !l.starts_with('|'))
        .take_while(|l| l.starts_with('|'))
    {
        let cells: Vec<&str> = line.split('|').collect();
        let Some(modules) = cells.get(2) else { continue };
        if line.contains("---") || modules.trim() == "modules" {
            continue;
        }
        // A module's name is the first backticked word of each comma-separated entry.
        for entry in modules.split("), ").flat_map(|e| e.split(", ")) {
            if let Some(name) = entry.trim().strip_prefix('`').and_then(|e| e.split('`').next()) {
                rows.entry(name.to_string()).or_insert(row);
            }
        }
        row += 1;
    }
    rows
}

/// How the library at `lib` (a crate root under `base`) breaks the layers table of the document
/// `doc`: top-level modules without a row, uses of a lower layer, circles between top-level
/// modules; and the files read.
pub(crate) fn layer_breaches(base: &Path, lib: &str, doc: &str) -> (Vec<String>, Vec<PathBuf>) {
    let krate = Crate::load(&base.join(lib));
    let doc_path = base.join(doc);
    let rows = layers(&read(&doc_path));
    let mut out = Vec::new();
    if rows.is_empty() {
        out.push(format!("{doc}: no layers table under a \"## Layers\" heading"));
    }
    let top: BTreeSet<&String> = krate.modules.keys().filter(|p| p.len() == 1).map(|p| &p[0]).collect();
    for m in &top {
        if !rows.contains_key(m.as_str()) {
            out.push(format!("{m}: no row in the layers table of {doc}"));
        }
    }
    let mut wrong = Vec::new();
    let mut next: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for ((a, b), via) in krate.edges() {
        let (Some(ta), Some(tb)) = (a.first(), b.first()) else {
            continue;
        };
        if ta == tb {
            continue;
        }
        next.entry(ta.clone()).or_default().insert(tb.clone());
        if let (Some(ra), Some(rb)) = (rows.get(ta), rows.get(tb))
            && rb > ra
        {
            wrong.push(format!(
                "{} (layer {ra}) uses {} (layer {rb}), a lower layer: {via}",
                name(&a),
                name(&b),
            ));
        }
    }
    wrong.sort();
    wrong.dedup();
    out.extend(wrong);
    let nodes: BTreeSet<String> = top.into_iter().cloned().collect();
    for c in circles(&nodes, &next) {
        out.push(format!("a circle between top-level modules: {c:?}"));
    }
    let mut files: Vec<PathBuf> = krate.modules.values().map(|m| m.file.clone()).collect();
    files.push(doc_path);
    (out, files)
}
