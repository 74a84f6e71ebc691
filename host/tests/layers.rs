//! The host crate's layers: a module uses only the modules below it (DESIGN.md, "host/src"), and
//! no two modules import each other, directly or round a circle. Read from the source: every
//! `crate::a::b` and `super::x` path in code (comments and doc text left out) is an edge from the
//! file's module to the deepest module the path names. A module and its own ancestors may refer
//! to each other (a parent re-exports its children, a child uses its parent's types).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The top-level modules from the bottom up; each may use those on lower rows only (and its own
/// row's modules where listed in [`SAME_ROW`]). `cli` is on top and nothing uses it.
/// `arm` is not here: it is the crate `armctl-arm` (host/arm), beneath all of them, and cargo
/// does not let it import armctl.
const ROWS: &[&[&str]] = &[
    &["args", "plot", "pty_owner", "untested"],
    &["link", "sim"],
    &["places"],
    &["motion", "servo"],
    &["drive", "mocap"],
    &["rig"],
    &["demo", "bench", "doctor", "footprint", "teleop", "view"],
    &["cli"],
];

fn row(top: &str) -> usize {
    ROWS.iter().position(|r| r.contains(&top)).unwrap_or_else(|| panic!("module {top} is in no row of ROWS"))
}

/// Every `.rs` file under `dir`.
fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let path = entry.path();
        if path.is_dir() {
            files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The module path of a source file: `drive/commands.rs` -> `drive::commands`, `drive/mod.rs` ->
/// `drive`, `lib.rs` -> ``.
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let relative = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = relative.iter().map(|p| p.to_string_lossy().into_owned()).collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib" | "main")) {
        parts.pop();
    }
    parts
}

/// The code of a line, without a `//` comment (string literals holding `//` are rare here and
/// would only hide an edge, never invent one).
fn code(line: &str) -> &str {
    line.split("//").next().unwrap_or_default()
}

/// The identifier segments of the path at the start of `text`: `a::b::{c, d}` -> `[a, b]`.
fn segments(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for part in text.split("::") {
        let ident: String = part.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
        if ident.is_empty() {
            break;
        }
        let whole = ident.len() == part.len();
        out.push(ident);
        if !whole {
            break;
        }
    }
    out
}

struct Graph {
    modules: BTreeSet<Vec<String>>,
    edges: BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
}

fn graph() -> Graph {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut all = Vec::new();
    files(&src, &mut all);
    let modules: BTreeSet<Vec<String>> = all.iter().map(|f| module_of(&src, f)).collect();
    // The deepest known module a path names.
    let resolve = |path: &[String]| -> Vec<String> {
        (0..=path.len()).rev().map(|n| path[..n].to_vec()).find(|p| modules.contains(p)).unwrap_or_default()
    };
    let mut edges: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
    for file in &all {
        let from = module_of(&src, file);
        let text = std::fs::read_to_string(file).unwrap();
        // Unit tests (at the end of a file by convention) may use anything.
        for line in text.lines().take_while(|l| l.trim() != "#[cfg(test)]").map(code) {
            for (at, _) in line.match_indices("crate::") {
                let path = segments(&line[at + "crate::".len()..]);
                edges.entry(from.clone()).or_default().insert(resolve(&path));
            }
            for (at, _) in line.match_indices("super::") {
                // `super` of `a::b` (file a/b.rs) is `a`; of `a` (a/mod.rs) it is the crate root.
                let mut base = from.clone();
                base.pop();
                let mut rest = &line[at + "super::".len()..];
                while let Some(r) = rest.strip_prefix("super::") {
                    base.pop();
                    rest = r;
                }
                let mut path = base;
                path.extend(segments(rest));
                edges.entry(from.clone()).or_default().insert(resolve(&path));
            }
        }
    }
    Graph { modules, edges }
}

/// Whether `a` is `b` or one of its ancestors, or the other way round.
fn related(a: &[String], b: &[String]) -> bool {
    a.starts_with(b) || b.starts_with(a)
}

#[test]
fn every_module_uses_only_the_modules_below_it() {
    let g = graph();
    let mut wrong = Vec::new();
    for (from, tos) in &g.edges {
        let Some(top) = from.first() else { continue };
        for to in tos {
            let Some(target) = to.first() else { continue };
            if target == top {
                continue;
            }
            if row(target) >= row(top) {
                wrong.push(format!("{} uses {}", from.join("::"), to.join("::")));
            }
        }
    }
    assert!(wrong.is_empty(), "imports against the layers:\n{}", wrong.join("\n"));
}

#[test]
fn no_two_modules_import_each_other_round_a_circle() {
    let g = graph();
    // Depth-first search for a cycle, ignoring edges between a module and its ancestors.
    fn visit(
        node: &Vec<String>,
        g: &Graph,
        state: &mut BTreeMap<Vec<String>, u8>,
        stack: &mut Vec<Vec<String>>,
    ) -> Option<Vec<Vec<String>>> {
        state.insert(node.clone(), 1);
        stack.push(node.clone());
        for next in g.edges.get(node).into_iter().flatten() {
            if related(node, next) {
                continue;
            }
            match state.get(next) {
                Some(1) => {
                    let from = stack.iter().position(|n| n == next).unwrap();
                    let mut circle = stack[from..].to_vec();
                    circle.push(next.clone());
                    return Some(circle);
                }
                Some(_) => {}
                None => {
                    if let Some(c) = visit(next, g, state, stack) {
                        return Some(c);
                    }
                }
            }
        }
        stack.pop();
        state.insert(node.clone(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for module in &g.modules {
        if !state.contains_key(module) {
            if let Some(circle) = visit(module, &g, &mut state, &mut Vec::new()) {
                let names: Vec<String> = circle.iter().map(|m| m.join("::")).collect();
                panic!("an import circle: {}", names.join(" -> "));
            }
        }
    }
}

#[test]
fn the_graph_sees_the_imports_it_checks() {
    // A check that reads nothing passes anything: make sure known edges are found.
    let g = graph();
    let has = |from: &str, to: &str| {
        let from: Vec<String> = from.split("::").map(str::to_string).collect();
        let to: Vec<String> = to.split("::").map(str::to_string).collect();
        g.edges.get(&from).is_some_and(|t| t.contains(&to))
    };
    assert!(has("drive::commands", "drive::args"));
    assert!(has("places::sil", "sim"));
    assert!(has("cli", "demo"));
    assert!(g.modules.len() > 60, "{} modules", g.modules.len());
}
