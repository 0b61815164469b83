//! The layers of `src/` hold: `db` ← `engine` ← `sim` (← the command in `src/cli/`, a separate
//! binary that sees only the library's public items). No module imports from a layer above its
//! own, and no two modules of the library import each other, directly or around a cycle; nor do
//! two modules of the rasterizer (`raster/src/`).
//!
//! A module here is a layer's direct child (`engine::paging`, `db::archive`, with everything
//! below it), or in the rasterizer the crate root's child (`batch`, `pipeline`); comments are
//! not imports, and neither are test modules (`#[cfg(test)] mod tests` at the end of a file:
//! a module's tests may use a fixture built on the module).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The library's layers, lowest first.
const LAYERS: [&str; 3] = ["db", "engine", "sim"];

/// One `crate::layer::module` path in a file of module `from`.
#[derive(Debug)]
struct Reference {
    from: String,
    to: String,
    file: String,
    line: usize,
}

fn rank(module: &str) -> Option<usize> {
    let layer = module.split("::").next()?;
    LAYERS.iter().position(|l| *l == layer)
}

/// The module a file of the library belongs to (`src/engine/cracks/stitch.rs` →
/// `engine::cracks`), or `None` outside the layers (`lib.rs`, `error.rs`, the command).
fn module_of(relative: &Path) -> Option<String> {
    let parts: Vec<String> = relative
        .iter()
        .map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string())
        .collect();
    let layer = parts.first()?;
    LAYERS.contains(&layer.as_str()).then_some(())?;
    match parts.get(1).map(String::as_str) {
        None | Some("mod") => Some(layer.clone()),
        Some(child) => Some(format!("{layer}::{child}")),
    }
}

/// The identifier at the start of `s`.
fn ident(s: &str) -> &str {
    let end = s
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .unwrap_or(s.len());
    &s[..end]
}

/// `text` up to the brace that closes the group it starts in.
fn group(text: &str) -> &str {
    let mut depth = 0usize;
    for (k, c) in text.char_indices() {
        match c {
            '{' => depth += 1,
            '}' if depth == 0 => return &text[..k],
            '}' => depth -= 1,
            _ => {}
        }
    }
    text
}

/// Every `layer::module` that `code` names after `crate::`, also inside `crate::{..}` groups,
/// with the byte offset of its `crate::`.
fn targets(code: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    for (k, _) in code.match_indices("crate::") {
        let rest = &code[k + "crate::".len()..];
        let paths: Vec<&str> = match rest.strip_prefix('{') {
            Some(inner) => group(inner).split([',', '{', '}']).map(str::trim).collect(),
            None => vec![rest],
        };
        for path in paths {
            let layer = ident(path);
            let Some(tail) = path[layer.len()..].strip_prefix("::") else {
                continue;
            };
            if !LAYERS.contains(&layer) {
                continue;
            }
            let child = ident(tail);
            let module = if child.is_empty() || child.starts_with(char::is_uppercase) {
                layer.to_string()
            } else {
                format!("{layer}::{child}")
            };
            out.push((k, module));
        }
    }
    out
}

/// `text` with its comment lines blanked, so offsets still give line numbers.
fn without_comments(text: &str) -> String {
    text.lines()
        .map(|l| {
            if l.trim_start().starts_with("//") {
                ""
            } else {
                l
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The references between modules in `files` (path relative to `src/`, text).
fn references(files: &[(PathBuf, String)]) -> Vec<Reference> {
    let mut out = Vec::new();
    for (path, text) in files {
        let Some(from) = module_of(path) else {
            continue;
        };
        let code = without_comments(text);
        let code = code.split("#[cfg(test)]\nmod tests").next().unwrap_or("");
        let mut found = targets(code);
        // A layer's re-exports (`pub use client::*;` in `engine/mod.rs`) make its root depend on
        // the child that defines them.
        if !from.contains("::") {
            for (k, _) in code.match_indices("pub use ") {
                let child = ident(&code[k + "pub use ".len()..]);
                if !matches!(child, "" | "crate" | "self" | "super") {
                    found.push((k, format!("{from}::{child}")));
                }
            }
        }
        for (offset, to) in found {
            if to != from {
                out.push(Reference {
                    from: from.clone(),
                    to,
                    file: path.display().to_string(),
                    line: code[..offset].matches('\n').count() + 1,
                });
            }
        }
    }
    out
}

/// The rasterizer's module graph: which of the crate root's children each names after
/// `crate::` (also inside `crate::{..}` groups), from `files` (path relative to `raster/src/`,
/// text), outside comments and test modules.
fn raster_graph(files: &[(PathBuf, String)]) -> BTreeMap<String, BTreeSet<String>> {
    let module = |path: &Path| -> Option<String> {
        let first = path.iter().next()?.to_string_lossy();
        let name = first.trim_end_matches(".rs");
        (name != "lib").then(|| name.to_string())
    };
    let modules: BTreeSet<String> = files.iter().filter_map(|(p, _)| module(p)).collect();
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (path, text) in files {
        let Some(from) = module(path) else {
            continue;
        };
        let code = without_comments(text);
        let code = code.split("#[cfg(test)]\nmod tests").next().unwrap_or("");
        for (k, _) in code.match_indices("crate::") {
            let rest = &code[k + "crate::".len()..];
            let paths: Vec<&str> = match rest.strip_prefix('{') {
                Some(inner) => group(inner).split([',', '{', '}']).map(str::trim).collect(),
                None => vec![rest],
            };
            for to in paths.into_iter().map(ident) {
                if modules.contains(to) && to != from {
                    graph
                        .entry(from.clone())
                        .or_default()
                        .insert(to.to_string());
                }
            }
        }
    }
    graph
}

/// The import cycles of the rasterizer's modules, as `violations` words them.
fn raster_cycles(files: &[(PathBuf, String)]) -> Vec<String> {
    let graph = raster_graph(files);
    let graph: BTreeMap<&str, BTreeSet<&str>> = graph
        .iter()
        .map(|(k, v)| (k.as_str(), v.iter().map(String::as_str).collect()))
        .collect();
    cycles(&graph)
        .into_iter()
        .map(|c| format!("import cycle: {}", c.join(" -> ")))
        .collect()
}

/// What breaks the layering: imports from a higher layer, and import cycles between modules.
fn violations(files: &[(PathBuf, String)]) -> Vec<String> {
    let refs = references(files);
    let mut out: Vec<String> = refs
        .iter()
        .filter(|r| rank(&r.to) > rank(&r.from))
        .map(|r| {
            format!(
                "src/{}:{}: {} imports {}, a layer above it",
                r.file, r.line, r.from, r.to
            )
        })
        .collect();
    let mut graph: BTreeMap<&str, BTreeSet<&str>> = BTreeMap::new();
    for r in &refs {
        graph.entry(&r.from).or_default().insert(&r.to);
    }
    for cycle in cycles(&graph) {
        out.push(format!("import cycle: {}", cycle.join(" -> ")));
    }
    out
}

/// The strongly connected components of more than one module (Tarjan), each listed from its
/// smallest member.
fn cycles<'a>(graph: &BTreeMap<&'a str, BTreeSet<&'a str>>) -> Vec<Vec<&'a str>> {
    struct Walk<'a, 'g> {
        graph: &'g BTreeMap<&'a str, BTreeSet<&'a str>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        found: Vec<Vec<&'a str>>,
    }
    impl<'a> Walk<'a, '_> {
        fn visit(&mut self, v: &'a str) {
            let i = self.index.len();
            self.index.insert(v, i);
            self.low.insert(v, i);
            self.stack.push(v);
            for &w in self.graph.get(v).into_iter().flatten() {
                if !self.index.contains_key(w) {
                    self.visit(w);
                    let low = self.low[v].min(self.low[w]);
                    self.low.insert(v, low);
                } else if self.stack.contains(&w) {
                    let low = self.low[v].min(self.index[w]);
                    self.low.insert(v, low);
                }
            }
            if self.low[v] == self.index[v] {
                let at = self
                    .stack
                    .iter()
                    .rposition(|&x| x == v)
                    .expect("on the stack");
                let mut component = self.stack.split_off(at);
                if component.len() > 1 {
                    component.sort();
                    self.found.push(component);
                }
            }
        }
    }
    let mut walk = Walk {
        graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        found: Vec::new(),
    };
    for &v in graph.keys() {
        if !walk.index.contains_key(v) {
            walk.visit(v);
        }
    }
    walk.found
}

fn rust_files(dir: &Path, root: &Path, out: &mut Vec<(PathBuf, String)>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            rust_files(&path, root, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            let text = std::fs::read_to_string(&path).unwrap();
            out.push((path.strip_prefix(root).unwrap().to_path_buf(), text));
        }
    }
}

#[test]
fn no_module_imports_from_a_layer_above_or_around_a_cycle() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &src, &mut files);
    let refs = references(&files);
    assert!(
        refs.iter()
            .any(|r| r.from == "sim::fly" && r.to == "engine"),
        "the scan sees the library's imports"
    );
    let found = violations(&files);
    assert!(found.is_empty(), "{}", found.join("\n"));
}

#[test]
fn no_two_modules_of_the_rasterizer_import_each_other_around_a_cycle() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("raster/src");
    let mut files = Vec::new();
    rust_files(&src, &src, &mut files);
    let graph = raster_graph(&files);
    assert!(
        graph.get("batch").is_some_and(|to| to.contains("pipeline")),
        "the scan sees the rasterizer's imports"
    );
    let found = raster_cycles(&files);
    assert!(found.is_empty(), "{}", found.join("\n"));
}

#[test]
fn a_cycle_between_the_rasterizers_modules_is_reported() {
    let file = |path: &str, text: &str| (PathBuf::from(path), text.to_string());
    let files = [
        file("lib.rs", "mod batch;\nmod draw;\n"),
        file("batch.rs", "use crate::draw::Rasterizer;\n"),
        file(
            "draw.rs",
            "use crate::{lines::LineState, RasterError};\n#[cfg(test)]\nmod tests {\n    use crate::shade::Shade;\n}\n",
        ),
        file(
            "lines.rs",
            "// crate::shade in a comment\nfn f() { crate::batch::flush() }\n",
        ),
        file("shade.rs", "use crate::pipeline::fixed::FixedPipeline;\n"),
        file("pipeline/mod.rs", "use crate::shade::Shade;\n"),
    ];
    assert_eq!(
        raster_cycles(&files),
        [
            "import cycle: batch -> draw -> lines",
            "import cycle: pipeline -> shade",
        ]
    );
}

#[test]
fn an_upward_import_and_a_cycle_are_reported() {
    let file = |path: &str, text: &str| (PathBuf::from(path), text.to_string());
    let files = [
        file("db/tile/mod.rs", "use crate::engine::masks::MaskSet;\n"),
        file(
            "engine/masks.rs",
            "// crate::sim::fly in a comment is no import\nuse crate::{\n    db::tile,\n    engine::Engine,\n};\n",
        ),
        file(
            "engine/budget.rs",
            "fn f() { crate::engine::importance::g() }\n",
        ),
        file(
            "engine/importance.rs",
            "use crate::engine::budget::Budget;\n",
        ),
        file(
            "sim/fly.rs",
            "use crate::engine::Engine;\nuse crate::sim::clock::Clock;\n",
        ),
        file("sim/mod.rs", "pub mod fly;\npub use fly::Flight;\n"),
        file("sim/stats.rs", "use crate::sim::Flight;\n"),
        file("sim/clock.rs", "use crate::sim::Flight;\n"),
    ];
    let found = violations(&files);
    assert_eq!(
        found,
        [
            "src/db/tile/mod.rs:1: db::tile imports engine::masks, a layer above it",
            "import cycle: db::tile -> engine::masks",
            "import cycle: engine::budget -> engine::importance",
            "import cycle: sim -> sim::clock -> sim::fly",
        ],
        "{found:#?}"
    );
}
