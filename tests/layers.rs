//! The layers of the two crates with layers of their own modules, read from their source:
//! - the host crate (`armctl`): a module uses only the modules below it (DESIGN.md, "host/src");
//! - both the host crate and the firmware core: no two modules import each other, directly or
//!   round a circle (`controller::command` and `controller::gripper` once did, and `link::frame`
//!   and `link::message`).
//!
//! Every `crate::a::b` and `super::x` path in code (comments and doc text left out) is an edge from
//! the file's module to the deepest module the path names. A module and its own ancestors may refer
//! to each other (a parent re-exports its children, a child uses its parent's types).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The host's top-level modules from the bottom up; each may use those on lower rows only, not
/// its own row's. `cli` is on top and nothing uses it.
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

type Module = Vec<String>;

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

/// The module path of a source file: `link/frame.rs` -> `link::frame`, `link/mod.rs` -> `link`,
/// `lib.rs` (or `main.rs`) -> ``.
fn module_of(src: &Path, file: &Path) -> Module {
    let relative = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Module = relative.iter().map(|p| p.to_string_lossy().into_owned()).collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib" | "main")) {
        parts.pop();
    }
    parts
}

/// The code of a line, without a `//` comment (a string literal holding `//` would only hide an
/// edge, never invent one).
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
    modules: BTreeSet<Module>,
    edges: BTreeMap<Module, BTreeSet<Module>>,
}

/// Every file under `src` as its module and its text.
fn sources(src: &Path) -> Vec<(Module, String)> {
    let mut all = Vec::new();
    files(src, &mut all);
    all.iter().map(|f| (module_of(src, f), std::fs::read_to_string(f).unwrap())).collect()
}

/// The import graph of the modules' texts.
fn graph_of(sources: &[(Module, String)]) -> Graph {
    let modules: BTreeSet<Module> = sources.iter().map(|(m, _)| m.clone()).collect();
    // The deepest known module a path names.
    let resolve = |path: &[String]| -> Module {
        (0..=path.len()).rev().map(|n| path[..n].to_vec()).find(|p| modules.contains(p)).unwrap_or_default()
    };
    let mut edges: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    for (from, text) in sources {
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

/// The import graph of a crate's `src` folder (`host` or `firmware`).
fn graph(krate: &str) -> Graph {
    graph_of(&sources(&Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(krate).join("src")))
}

/// Whether `a` is `b` or one of its ancestors, or the other way round.
fn related(a: &[String], b: &[String]) -> bool {
    a.starts_with(b) || b.starts_with(a)
}

/// The first import circle found (its modules, the first repeated at the end), if any.
fn circle(g: &Graph) -> Option<Vec<Module>> {
    // Depth-first search, ignoring edges between a module and its ancestors. State 1: on the
    // stack; 2: done.
    fn visit(
        node: &Module,
        g: &Graph,
        state: &mut BTreeMap<Module, u8>,
        stack: &mut Vec<Module>,
    ) -> Option<Vec<Module>> {
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
            if let Some(c) = visit(module, g, &mut state, &mut Vec::new()) {
                return Some(c);
            }
        }
    }
    None
}

#[test]
fn every_module_uses_only_the_modules_below_it() {
    let g = graph("host");
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

/// Panics naming the first import circle of `krate`'s modules.
fn assert_no_circle(krate: &str) {
    if let Some(c) = circle(&graph(krate)) {
        let names: Vec<String> = c.iter().map(|m| m.join("::")).collect();
        panic!("an import circle in {krate}: {}", names.join(" -> "));
    }
}

#[test]
fn no_two_host_modules_import_each_other_round_a_circle() {
    assert_no_circle("host");
}

#[test]
fn no_two_firmware_modules_import_each_other_round_a_circle() {
    assert_no_circle("firmware");
}

/// `a::b` as a module path; `` is the crate root.
fn module(path: &str) -> Module {
    path.split("::").filter(|s| !s.is_empty()).map(str::to_string).collect()
}

#[test]
fn the_host_graph_sees_the_imports_it_checks() {
    // A check that reads nothing passes anything: make sure known edges are found.
    let g = graph("host");
    let has = |from: &str, to: &str| g.edges.get(&module(from)).is_some_and(|t| t.contains(&module(to)));
    assert!(has("cli::drive", "drive::args"));
    assert!(has("places::sil", "sim"));
    assert!(has("cli", "demo"));
    assert!(g.modules.len() > 60, "{} modules", g.modules.len());
}

#[test]
fn the_firmware_graph_sees_the_imports_it_checks() {
    // A check that reads nothing passes anything: make sure known edges are found.
    let g = graph("firmware");
    let has = |from: &str, to: &str| g.edges.get(&module(from)).is_some_and(|t| t.contains(&module(to)));
    assert!(has("link::frame", "link::cobs"));
    assert!(has("controller::command", "controller::gripper"));
    assert!(has("board::main_loop", "app"));
    assert!(g.modules.len() > 40, "{} modules", g.modules.len());
}

#[test]
fn a_circle_is_found() {
    // Two modules that import each other, as `link::frame` and `link::message` once did.
    let tree = |message: &str| {
        vec![
            (module(""), "pub mod link;".to_string()),
            (module("link"), "pub mod frame;\npub mod message;".to_string()),
            (module("link::frame"), "use super::message::NakReason;".to_string()),
            (module("link::message"), message.to_string()),
        ]
    };
    assert_eq!(circle(&graph_of(&tree("/// [`super::frame`] in doc text is no edge"))), None);
    let found = circle(&graph_of(&tree("const M: usize = crate::link::frame::MAX_FRAME;"))).unwrap();
    let names: Vec<String> = found.iter().map(|m| m.join("::")).collect();
    assert_eq!(names.len(), 3, "{names:?}");
    assert!(names.contains(&"link::frame".to_string()) && names.contains(&"link::message".to_string()), "{names:?}");
}
