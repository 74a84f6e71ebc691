//! The layers of the two crates with layers of their own modules, read from their source, as
//! docs/developing.md ("The host crate's layout") draws them:
//! - the host crate (`armctl`): a module uses only the rows below its own (the folders of host/src:
//!   cli; view; rig; commands; motion; runtime; link, sim; support), and nothing imports `cli`;
//! - the firmware core (`firmware`): board; app; builtin; controller, link; bus, tracking; crc16,
//!   place (`controller` and `link` do not import each other, `bus` is beneath both);
//! - in both: no two modules import each other, directly or round a circle (`controller::command`
//!   and `controller::gripper` once did, and `link::frame` and `link::message`);
//! - every top-level module of both is in docs/developing.md's layout section, so that the page
//!   cannot drift from the tree again.
//!
//! Every `crate::a::b` and `super::x` path in code (comments and doc text left out) is an edge from
//! the file's module to the deepest module the path names. A module and its own ancestors may refer
//! to each other (a parent re-exports its children, a child uses its parent's types).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A crate's top-level modules from the top down; a module may use the modules of lower rows only,
/// not its own row's nor a higher one's.
type Rows = &'static [&'static [&'static str]];

/// The host's rows. `arm` is not here: it is the crate `armctl-arm` (host/arm), beneath all of
/// them, and cargo does not let it import armctl. The Python binding (host/python) is a crate of
/// its own beside `cli`.
const HOST: Rows =
    &[&["cli"], &["view"], &["rig"], &["commands"], &["motion"], &["runtime"], &["link", "sim"], &["support"]];

/// The firmware core's rows (firmware/src).
const FIRMWARE: Rows =
    &[&["board"], &["app"], &["builtin"], &["controller", "link"], &["bus", "tracking"], &["crc16", "place"]];

/// The imports against the host's rows that the code still has, each with what would remove it.
/// The test fails on any other, and on an entry here that the code no longer needs, so that the
/// list only shrinks.
const HOST_DEBTS: &[(&str, &str, &str)] = &[];

fn row(rows: Rows, top: &str) -> Option<usize> {
    rows.iter().position(|r| r.contains(&top))
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

/// The imports of `g` against `rows`, as `from uses to` lines, each with the row it broke, leaving
/// out the `debts` (`from` a module or its ancestor, `to` a top-level module).
fn against_rows(g: &Graph, rows: Rows, debts: &[(&str, &str, &str)]) -> Vec<String> {
    let mut wrong = Vec::new();
    for (from, tos) in &g.edges {
        let Some(top) = from.first() else { continue };
        let here = row(rows, top).unwrap_or_else(|| panic!("module {top} is in no row"));
        for to in tos {
            let Some(target) = to.first() else { continue };
            if target == top {
                continue;
            }
            let there = row(rows, target).unwrap_or_else(|| panic!("module {target} is in no row"));
            let owed = debts.iter().any(|(f, t, _)| from.starts_with(&module(f)) && t == target);
            if there <= here && !owed {
                wrong.push(format!("{} uses {}", from.join("::"), to.join("::")));
            }
        }
    }
    wrong
}

/// The `debts` that no import of `g` needs any more.
fn paid(g: &Graph, debts: &[(&'static str, &'static str, &'static str)]) -> Vec<&'static str> {
    debts
        .iter()
        .filter(|(f, t, _)| {
            !g.edges.iter().any(|(from, tos)| {
                from.starts_with(&module(f)) && tos.iter().any(|to| to.first().map(String::as_str) == Some(*t))
            })
        })
        .map(|(f, _, _)| *f)
        .collect()
}

/// The top-level modules of a crate's `src` folder: its folders and `.rs` files but `lib` and
/// `main`.
fn top_level(krate: &str) -> BTreeSet<String> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(krate).join("src");
    let mut out = BTreeSet::new();
    for entry in std::fs::read_dir(src).unwrap().flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if entry.path().is_dir() {
            out.insert(name);
        } else if let Some(stem) = name.strip_suffix(".rs") {
            if stem != "lib" && stem != "main" {
                out.insert(stem.to_string());
            }
        }
    }
    out
}

#[test]
fn every_top_level_module_is_in_a_row_and_every_row_names_one() {
    for (krate, rows) in [("host", HOST), ("firmware", FIRMWARE)] {
        let tops = top_level(krate);
        let missing: Vec<&String> = tops.iter().filter(|t| row(rows, t).is_none()).collect();
        assert!(missing.is_empty(), "{krate}/src: {missing:?} in no row of tests/layers.rs: put each in its layer");
        let stale: Vec<&&str> = rows.iter().flat_map(|r| r.iter()).filter(|n| !tops.contains(**n)).collect();
        assert!(stale.is_empty(), "tests/layers.rs names {stale:?}, which {krate}/src no longer has");
    }
}

#[test]
fn every_host_module_uses_only_the_rows_below_it() {
    let g = graph("host");
    let wrong = against_rows(&g, HOST, HOST_DEBTS);
    assert!(wrong.is_empty(), "imports against the host's layers (tests/layers.rs, HOST):\n{}", wrong.join("\n"));
    let paid = paid(&g, HOST_DEBTS);
    assert!(paid.is_empty(), "HOST_DEBTS lists imports the code no longer has: remove {paid:?}");
}

#[test]
fn every_firmware_module_uses_only_the_rows_below_it() {
    let wrong = against_rows(&graph("firmware"), FIRMWARE, &[]);
    assert!(
        wrong.is_empty(),
        "imports against the firmware's layers (tests/layers.rs, FIRMWARE):\n{}",
        wrong.join("\n")
    );
}

#[test]
fn an_import_against_the_rows_is_found() {
    // The firmware's link importing its controller (a row of its own), and the host's support
    // importing cli: both must be caught, with nothing else.
    let tree = |frame: &str| {
        graph_of(&[
            (module(""), "pub mod bus;\npub mod controller;\npub mod link;".to_string()),
            (module("bus"), String::new()),
            (module("controller"), "use crate::bus::Bus;".to_string()),
            (module("link"), "pub mod frame;".to_string()),
            (module("link::frame"), frame.to_string()),
        ])
    };
    assert!(against_rows(&tree("use crate::bus::Bus;"), FIRMWARE, &[]).is_empty());
    assert_eq!(against_rows(&tree("use crate::controller::Command;"), FIRMWARE, &[]), ["link::frame uses controller"]);
    let host = graph_of(&[
        (module(""), "pub mod cli;\npub mod support;".to_string()),
        (module("cli"), "use crate::support::numbers;".to_string()),
        (module("support"), "pub mod numbers;".to_string()),
        (module("support::numbers"), "fn f() { crate::cli::main(); }".to_string()),
    ]);
    assert_eq!(against_rows(&host, HOST, &[]), ["support::numbers uses cli"]);
}

/// The section of docs/developing.md that draws the layout: from its heading to the next.
fn layout_section() -> String {
    let page = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/developing.md")).unwrap();
    let start =
        page.find("\n## The host crate's layout").expect("docs/developing.md: no section \"The host crate's layout\"");
    let rest = &page[start + 1..];
    rest[..rest[3..].find("\n## ").map_or(rest.len(), |e| e + 3)].to_string()
}

#[test]
fn every_top_level_module_is_in_the_developing_page() {
    let section = layout_section();
    // A line of the drawing: indented, its first word the folder (`cli/`) or file (`place.rs`).
    let drawn: BTreeSet<String> = section
        .lines()
        .filter(|l| l.starts_with("    "))
        .filter_map(|l| l.split_whitespace().next())
        .map(str::to_string)
        .collect();
    for krate in ["host", "firmware"] {
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(krate).join("src");
        let missing: Vec<String> = top_level(krate)
            .into_iter()
            .map(|t| if src.join(&t).is_dir() { format!("{t}/") } else { format!("{t}.rs") })
            .filter(|t| !drawn.contains(t))
            .collect();
        assert!(
            missing.is_empty(),
            "docs/developing.md, \"The host crate's layout\", does not draw {krate}/src's {missing:?}"
        );
    }
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
    assert!(has("cli::drive", "commands::drive::gripper"));
    assert!(has("runtime::sil", "sim"));
    assert!(has("cli::demo", "commands::demo"));
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

/// The modules of `sources` outside `cli` whose code names the `clap` crate.
fn using_clap(sources: &[(Module, String)]) -> Vec<String> {
    sources
        .iter()
        .filter(|(m, _)| m.first().map(String::as_str) != Some("cli"))
        .filter(|(_, text)| text.lines().map(code).any(|l| l.contains("clap::") || l.contains("use clap")))
        .map(|(m, _)| m.join("::"))
        .collect()
}

#[test]
fn clap_stays_in_the_command_line() {
    // The commands take plain requests; only `cli` parses (issue 40): the Python binding, the
    // view and a rig build the same requests without a parser in between.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let host = sources(&root.join("host/src"));
    assert_eq!(using_clap(&host), Vec::<String>::new(), "modules below the command line that use clap");
    let python = sources(&root.join("host/python/src"));
    assert_eq!(using_clap(&python), Vec::<String>::new(), "the Python binding uses clap");
    // A check that reads nothing passes anything: the command line itself is seen to use it.
    let cli: Vec<(Module, String)> =
        host.into_iter().filter(|(m, _)| m.first().map(String::as_str) == Some("cli")).collect();
    let renamed: Vec<(Module, String)> =
        cli.into_iter().map(|(m, t)| (module(&format!("x::{}", m.join("::"))), t)).collect();
    assert!(using_clap(&renamed).len() >= 5, "the check does not see cli's own use of clap");
}
