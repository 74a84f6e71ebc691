//! What the disassembly of a board binary tells: the direct call graph, every call site into core's
//! panic machinery, and each function's stack frame, hence a static bound of the stack depth.
//!
//! The text is `llvm-objdump -d --no-show-raw-insn -C` from the pinned toolchain's `llvm-tools`
//! component (the same LLVM that generated the code, so it knows every Thumb-2 encoding rustc
//! emits). Source locations come from `llvm-addr2line` over the ELF's debug info (the release
//! profiles keep `debug = true`; it costs no flash).
//!
//! Limits, by design of a text-level analysis: only direct branches are edges (a `blx rN` through a
//! trait object or function pointer is counted, not followed), recursion is cut, and a frame is
//! what the prologue reserves (`push`, `vpush`, `str rN, [sp, #-N]!`, `sub sp`). So the stack
//! bound is a lower bound of the static worst case; stack painting under QEMU is the check.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context, Result};
use serde::Serialize;

use crate::runtime::board;
use crate::support::rust_symbols::pretty;

/// The two LLVM tools used.
#[derive(Clone, Debug)]
pub struct Tools {
    objdump: PathBuf,
    addr2line: Option<PathBuf>,
}

impl Tools {
    /// Finds `llvm-objdump` in the toolchain that `rust-toolchain.toml` pins (rustc run from the
    /// board crates, so rustup picks that toolchain): `$(rustc --print sysroot)/lib/rustlib/<host>/bin`,
    /// installing the `llvm-tools` component first where it is missing ([`board::ensure_toolchain`]).
    /// `llvm-addr2line` is taken from there too, else from `PATH` (the component does not ship it
    /// in every release); without it the panic sites are listed without their source lines.
    pub fn find() -> Result<Tools> {
        // With the component there, as `ensure_toolchain` checks, `llvm-objdump` is in this folder.
        let bin = board::ensure_toolchain(&board::boards_dir())?.llvm_bin();
        let objdump = bin.join("llvm-objdump");
        let on_path = || {
            Command::new("llvm-addr2line")
                .arg("--version")
                .output()
                .ok()
                .filter(|o| o.status.success())
                .map(|_| "llvm-addr2line".into())
        };
        let addr2line = Some(bin.join("llvm-addr2line")).filter(|p| p.is_file()).or_else(on_path);
        Ok(Tools { objdump, addr2line })
    }

    /// The disassembly of `elf`, names demangled.
    pub fn disassemble(&self, elf: &Path) -> Result<String> {
        let output = Command::new(&self.objdump)
            .args(["-d", "--no-show-raw-insn", "-C"])
            .arg(elf)
            .output()
            .with_context(|| format!("cannot run {}", self.objdump.display()))?;
        if !output.status.success() {
            bail!("llvm-objdump failed on {}: {}", elf.display(), String::from_utf8_lossy(&output.stderr).trim());
        }
        String::from_utf8(output.stdout).context("llvm-objdump wrote text that is not UTF-8")
    }

    /// The source locations of each address, innermost inlined frame first, without the frames of
    /// the standard library (files under `/rustc/`, where the panic machinery itself lives); `None`
    /// without llvm-addr2line.
    pub fn locate(&self, elf: &Path, addresses: &[u64]) -> Result<Option<Vec<Vec<String>>>> {
        let Some(addr2line) = &self.addr2line else { return Ok(None) };
        if addresses.is_empty() {
            return Ok(Some(Vec::new()));
        }
        // `-a` heads each address's group of (function, location) pairs, so one run serves all.
        let output = Command::new(addr2line)
            .args(["-a", "-i", "-f", "-C", "-e"])
            .arg(elf)
            .args(addresses.iter().map(|a| format!("{a:#x}")))
            .output()
            .with_context(|| format!("cannot run {}", addr2line.display()))?;
        if !output.status.success() {
            bail!("llvm-addr2line failed: {}", String::from_utf8_lossy(&output.stderr).trim());
        }
        Ok(Some(parse_locations(&String::from_utf8_lossy(&output.stdout), addresses)))
    }
}

/// Groups llvm-addr2line's `-a -i -f` output (an address line, then function and `file:line:col`
/// lines per inlined frame) by address, as `file:line:col function`.
fn parse_locations(text: &str, addresses: &[u64]) -> Vec<Vec<String>> {
    let mut groups: Vec<Vec<String>> = Vec::new();
    let mut lines = text.lines();
    while let Some(line) = lines.next() {
        if line.strip_prefix("0x").is_some_and(|a| u64::from_str_radix(a.trim(), 16).is_ok()) {
            groups.push(Vec::new());
            continue;
        }
        let function = line;
        let location = lines.next().unwrap_or("??");
        if location.starts_with("/rustc/") {
            continue;
        }
        if let Some(group) = groups.last_mut() {
            group.push(format!("{} {}", short_path(location), pretty(function)));
        }
    }
    groups.resize(addresses.len(), Vec::new());
    groups
}

/// A source path as a reader finds it: relative to the workspace, or from the crate's directory
/// for a dependency in cargo's registry.
fn short_path(location: &str) -> String {
    let workspace = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let workspace = std::fs::canonicalize(&workspace).unwrap_or(workspace);
    if let Some(rest) = location.strip_prefix(&format!("{}/", workspace.display())) {
        return rest.to_string();
    }
    match location.find("/registry/src/") {
        // `.../registry/src/index.crates.io-HASH/defmt-rtt-1.0.0/src/lib.rs:...`
        Some(i) => location[i..].splitn(5, '/').nth(4).unwrap_or(location).to_string(),
        None => location.to_string(),
    }
}

/// A function of the disassembly.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Function {
    /// The symbol as llvm-objdump prints it (unique: it keeps the hash).
    pub symbol: String,
    /// Bytes its prologue reserves on the stack.
    pub frame: u64,
    /// Direct branches to other functions: (site address, target symbol).
    pub calls: Vec<(u64, String)>,
    /// `blx rN` sites: calls through a pointer, not followed.
    pub indirect_calls: usize,
}

/// The parsed disassembly.
#[derive(Clone, Debug, Default)]
pub struct Program {
    /// The functions in address order.
    pub functions: Vec<Function>,
    index: HashMap<String, usize>,
}

impl Program {
    /// Parses llvm-objdump's text.
    pub fn parse(text: &str) -> Program {
        let mut functions: Vec<Function> = Vec::new();
        for line in text.lines() {
            if let Some(symbol) = function_header(line) {
                functions.push(Function { symbol: symbol.to_string(), ..Function::default() });
                continue;
            }
            let (Some(function), Some((address, op, operands))) = (functions.last_mut(), instruction(line)) else {
                continue;
            };
            function.frame += frame_bytes(op, operands);
            if is_branch(op) {
                match branch_target(operands) {
                    Some(target) if target != function.symbol => function.calls.push((address, target.to_string())),
                    Some(_) => {}
                    None if op == "blx" => function.indirect_calls += 1,
                    None => {}
                }
            }
        }
        let index = functions.iter().enumerate().map(|(i, f)| (f.symbol.clone(), i)).collect();
        Program { functions, index }
    }

    /// The function named `name` (its demangled path without the hash, e.g.
    /// `board_mps2_an386::run`).
    pub fn find(&self, name: &str) -> Option<&Function> {
        self.functions.iter().find(|f| pretty(&f.symbol) == name)
    }

    /// Every call site into core's panic entry points, except the entry points' calls to each
    /// other and the panic handler's own.
    pub fn panic_sites(&self) -> Vec<PanicSite> {
        let mut sites = Vec::new();
        for f in &self.functions {
            let name = pretty(&f.symbol);
            if is_panic_entry(&name) || name == "rust_begin_unwind" {
                continue;
            }
            for (address, target) in &f.calls {
                let target = pretty(target);
                if is_panic_entry(&target) {
                    sites.push(PanicSite { address: *address, function: name.clone(), target });
                }
            }
        }
        sites
    }

    /// The deepest chain of frames from `root` over direct calls, recursion cut.
    pub fn stack_bound(&self, root: &Function) -> StackBound {
        let root = self.index[&root.symbol];
        let mut memo: HashMap<usize, (u64, Option<usize>)> = HashMap::new();
        let mut on_path = vec![false; self.functions.len()];
        self.deepest(root, &mut memo, &mut on_path);
        let (bytes, _) = memo[&root];
        let mut path = Vec::new();
        let mut indirect_calls = 0;
        let mut next = Some(root);
        while let Some(i) = next {
            let f = &self.functions[i];
            path.push(Frame { function: pretty(&f.symbol), bytes: f.frame });
            indirect_calls += f.indirect_calls;
            next = memo.get(&i).and_then(|(_, callee)| *callee);
        }
        StackBound { root: pretty(&self.functions[root].symbol), bytes, path, indirect_calls }
    }

    /// The depth below `i` and the callee that gives it. A function already on the path is a
    /// recursion and counts nothing more; the memo makes the walk linear in the graph.
    fn deepest(&self, i: usize, memo: &mut HashMap<usize, (u64, Option<usize>)>, on_path: &mut [bool]) -> u64 {
        if let Some((bytes, _)) = memo.get(&i) {
            return *bytes;
        }
        on_path[i] = true;
        let mut best = (0, None);
        for (_, target) in &self.functions[i].calls {
            let Some(&callee) = self.index.get(target) else { continue };
            if on_path[callee] {
                continue;
            }
            let depth = self.deepest(callee, memo, on_path);
            if depth > best.0 {
                best = (depth, Some(callee));
            }
        }
        on_path[i] = false;
        let total = self.functions[i].frame + best.0;
        memo.insert(i, (total, best.1));
        total
    }
}

/// A call into core's panic machinery.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct PanicSite {
    /// The branch instruction's address.
    pub address: u64,
    /// The function it is in.
    pub function: String,
    /// The panic entry point it calls.
    pub target: String,
}

/// One frame of the deepest chain.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Frame {
    /// The function.
    pub function: String,
    /// Its frame's bytes.
    pub bytes: u64,
}

/// The static stack bound from one root.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct StackBound {
    /// Where the chain starts.
    pub root: String,
    /// The sum of the chain's frames.
    pub bytes: u64,
    /// The chain, caller first.
    pub path: Vec<Frame>,
    /// Calls through pointers in the chain's functions, which could go deeper.
    pub indirect_calls: usize,
}

/// Whether `name` (demangled, no hash) is one of core's panic entry points: everything in
/// `core::panicking` (`panic`, `panic_fmt`, `panic_bounds_check`, `panic_const::*`, ...) and the
/// cold `*_fail`/`*_failed` functions that the slice, str, option and result checks call
/// (`core::slice::index::slice_index_fail`, `copy_from_slice::len_mismatch_fail`,
/// `core::option::unwrap_failed`, `core::result::unwrap_failed`, ...), and `core::cell`'s
/// `panic_already_borrowed`.
pub fn is_panic_entry(name: &str) -> bool {
    let Some(path) = name.strip_prefix("core::") else { return false };
    let last = path.rsplit("::").next().unwrap_or(path);
    path.starts_with("panicking::")
        || last.ends_with("_fail")
        || last.ends_with("_failed")
        || last.starts_with("panic_")
}

/// The symbol of a `ADDR <symbol>:` line.
fn function_header(line: &str) -> Option<&str> {
    let (address, rest) = line.split_once(' ')?;
    if address.is_empty() || !address.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    rest.strip_prefix('<')?.strip_suffix(">:")
}

/// Address, mnemonic and operands (without llvm-objdump's `@ comment`) of an instruction line
/// such as ` 80001a4:      \tbeq\t0x80001aa <__stext+0x12> @ imm = #0x2`.
fn instruction(line: &str) -> Option<(u64, &str, &str)> {
    let (address, rest) = line.trim_start().split_once(':')?;
    let address = u64::from_str_radix(address, 16).ok()?;
    let mut fields = rest.split('\t').skip(1);
    let op = fields.next()?.trim();
    let operands = fields.next().unwrap_or("");
    let operands = operands.split_once(" @").map_or(operands, |(o, _)| o).trim();
    Some((address, op, operands))
}

/// Bytes an instruction takes off the stack pointer in a prologue.
fn frame_bytes(op: &str, operands: &str) -> u64 {
    let base = op.trim_end_matches(".w").trim_end_matches(".n");
    match base {
        "push" => 4 * registers(operands),
        "vpush" => registers(operands) * if operands.contains('d') { 8 } else { 4 },
        "stmdb" if operands.starts_with("sp!,") => 4 * registers(operands),
        // `str rN, [sp, #-4]!`: a one-register push.
        "str" => operands
            .split_once("[sp, #-")
            .and_then(|(_, rest)| rest.strip_suffix("]!"))
            .and_then(immediate_value)
            .unwrap_or(0),
        "sub" | "subw" => {
            let imm = operands.strip_prefix("sp, sp, #").or_else(|| operands.strip_prefix("sp, #"));
            imm.and_then(immediate_value).unwrap_or(0)
        }
        _ => 0,
    }
}

/// The number of registers in a `{r4, r5, lr}` or `{d8-d11}` list.
fn registers(operands: &str) -> u64 {
    let Some(list) = operands.split_once('{').and_then(|(_, l)| l.split_once('}')).map(|(l, _)| l) else { return 0 };
    list.split(',')
        .map(str::trim)
        .filter(|r| !r.is_empty())
        .map(|r| match r.split_once('-') {
            Some((a, b)) => match (number_of(a), number_of(b)) {
                (Some(a), Some(b)) if b >= a => b - a + 1,
                _ => 1,
            },
            None => 1,
        })
        .sum()
}

fn number_of(register: &str) -> Option<u64> {
    register.trim().trim_start_matches(|c: char| c.is_ascii_alphabetic()).parse().ok()
}

/// `0x1c` (LLVM 15 and later) or `28` (older llvm-objdump).
fn immediate_value(text: &str) -> Option<u64> {
    let text = text.trim();
    match text.strip_prefix("0x") {
        Some(hex) => u64::from_str_radix(hex, 16).ok(),
        None => text.parse().ok(),
    }
}

/// Whether `op` branches: `b`, `bl`, `blx`, `cbz`, `cbnz` and the conditional `bCC` forms, with or
/// without a `.w`/`.n` width. A conditional branch to another function is a tail call.
fn is_branch(op: &str) -> bool {
    const CONDITIONS: [&str; 16] =
        ["eq", "ne", "cs", "hs", "cc", "lo", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le"];
    let base = op.trim_end_matches(".w").trim_end_matches(".n");
    matches!(base, "b" | "bl" | "blx" | "cbz" | "cbnz")
        || base.strip_prefix('b').is_some_and(|c| CONDITIONS.contains(&c))
}

/// The function a branch enters, from `0x800a41a <_defmt_timestamp>`. A target with an offset
/// (`<start+0x33e>`) is inside a function, not a call: a branch within the function itself, or
/// alignment padding that llvm-objdump decodes as an instruction.
fn branch_target(operands: &str) -> Option<&str> {
    let start = operands.find('<')?;
    let end = operands.rfind('>')?;
    let target = operands.get(start + 1..end)?;
    if target.rsplit_once('+').is_some_and(|(_, offset)| offset.starts_with("0x")) {
        return None;
    }
    (!target.starts_with('$')).then_some(target)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_add_up_pushes_vector_pushes_and_stack_reservations() {
        assert_eq!(frame_bytes("push", "{r4, r5, r6, r7, lr}"), 20);
        assert_eq!(frame_bytes("push.w", "{r8, r9, r10, r11}"), 16);
        assert_eq!(frame_bytes("vpush", "{d8, d9, d10, d11}"), 32);
        assert_eq!(frame_bytes("vpush", "{d8-d15}"), 64);
        assert_eq!(frame_bytes("sub", "sp, #0x1e4"), 0x1e4);
        assert_eq!(frame_bytes("sub.w", "sp, sp, #0x1100"), 0x1100);
        assert_eq!(frame_bytes("subw", "sp, sp, #1176"), 1176);
        assert_eq!(frame_bytes("str", "r7, [sp, #-4]!"), 4);
        assert_eq!(frame_bytes("str", "r11, [sp, #-0x4]!"), 4);
        assert_eq!(frame_bytes("sub", "r0, #0x10"), 0);
        assert_eq!(frame_bytes("sub.w", "r1, sp, #0x10"), 0);
        assert_eq!(frame_bytes("ldr", "r0, [sp, #0x10]"), 0);
    }

    const LISTING: &str = "\
00003364 <board_mps2_an386::__cortex_m_rt_main::h5ff0954e5d0addcc>:
    3364:      \tpush\t{r7, lr}
    3366:      \tmov\tr7, sp
    3368:      \tsub\tsp, #0x10
    336a:      \tbl\t0x33bc <board_mps2_an386::run::h1d4ec13a0945665a> @ imm = #0x4e
    336e:      \tbeq.w\t0x3400 <core::panicking::panic_bounds_check::h0123456789abcdef> @ imm = #0x8e
    3372:      \tb\t0x3364 <board_mps2_an386::__cortex_m_rt_main::h5ff0954e5d0addcc+0x4> @ imm = #-0x10

000033bc <board_mps2_an386::run::h1d4ec13a0945665a>:
    33bc:      \tpush\t{r4, r5, r6, r7, lr}
    33be:      \tvpush\t{d8, d9}
    33c2:      \tsub.w\tsp, sp, #0x400
    33c6:      \tblx\tr3
    33c8:      \tbl\t0x3364 <board_mps2_an386::__cortex_m_rt_main::h5ff0954e5d0addcc> @ imm = #-0x68
    33cc:      \tbl\t0x3400 <core::panicking::panic_bounds_check::h0123456789abcdef> @ imm = #0x30
    33d0:      \tldr\tr0, [pc, #0x38]         @ 0x340c <core::panicking::panic_fmt::habcdef0123456789>
    33d2: 38 00 00 20  \t.word\t0x20000038

00003400 <core::panicking::panic_bounds_check::h0123456789abcdef>:
    3400:      \tpush\t{r7, lr}
    3402:      \tbl\t0x340c <core::panicking::panic_fmt::habcdef0123456789> @ imm = #0x6

0000340c <core::panicking::panic_fmt::habcdef0123456789>:
    340c:      \tbl\t0x3410 <rust_begin_unwind> @ imm = #0x0

00003410 <rust_begin_unwind>:
    3410:      \tb.w\t0x340c <core::panicking::panic_fmt::habcdef0123456789> @ imm = #-0x8
";

    #[test]
    fn direct_branches_are_calls_and_register_calls_are_counted() {
        let program = Program::parse(LISTING);
        let main = program.find("board_mps2_an386::__cortex_m_rt_main").unwrap();
        assert_eq!(main.frame, 8 + 16);
        let targets: Vec<&str> = main.calls.iter().map(|(_, t)| t.as_str()).collect();
        assert_eq!(
            targets,
            ["board_mps2_an386::run::h1d4ec13a0945665a", "core::panicking::panic_bounds_check::h0123456789abcdef"],
            "a branch back into the function itself is no call"
        );
        let run = program.find("board_mps2_an386::run").unwrap();
        assert_eq!(run.frame, 20 + 16 + 0x400);
        assert_eq!(run.indirect_calls, 1);
        assert_eq!(run.calls.len(), 2, "a literal load naming a symbol is no call");
    }

    #[test]
    fn panic_sites_leave_out_the_panic_machinery_itself() {
        let program = Program::parse(LISTING);
        let sites = program.panic_sites();
        let found: Vec<(u64, &str)> = sites.iter().map(|s| (s.address, s.function.as_str())).collect();
        assert_eq!(found, [(0x336e, "board_mps2_an386::__cortex_m_rt_main"), (0x33cc, "board_mps2_an386::run")]);
        assert!(sites.iter().all(|s| s.target == "core::panicking::panic_bounds_check"));
    }

    #[test]
    fn the_stack_bound_follows_the_deepest_chain_and_cuts_recursion() {
        let program = Program::parse(LISTING);
        let bound = program.stack_bound(program.find("board_mps2_an386::__cortex_m_rt_main").unwrap());
        let chain: Vec<(&str, u64)> = bound.path.iter().map(|f| (f.function.as_str(), f.bytes)).collect();
        assert_eq!(
            chain,
            [
                ("board_mps2_an386::__cortex_m_rt_main", 24),
                ("board_mps2_an386::run", 1060),
                ("core::panicking::panic_bounds_check", 8),
            ]
        );
        assert_eq!(bound.bytes, 24 + 1060 + 8);
        assert_eq!(bound.indirect_calls, 1);
    }

    #[test]
    fn panic_entry_points_are_recognised_by_their_paths() {
        for name in [
            "core::panicking::panic_fmt",
            "core::panicking::panic_const::panic_const_div_by_zero",
            "core::slice::index::slice_index_fail",
            "core::slice::<impl [T]>::copy_from_slice::len_mismatch_fail",
            "core::option::unwrap_failed",
            "core::option::expect_failed",
            "core::result::unwrap_failed",
            "core::cell::panic_already_borrowed",
        ] {
            assert!(is_panic_entry(name), "{name}");
        }
        for name in ["firmware::app::Firmware<_,_>::tick", "core::fmt::write", "defmt_rtt::panic_count"] {
            assert!(!is_panic_entry(name), "{name}");
        }
    }

    #[test]
    fn addr2line_groups_skip_the_standard_library() {
        let text = "0x336e\nfirmware::tick\n/rustc/abc/library/core/src/slice/index.rs:10:5\nfirmware::tick\n\
                    /x/y.rs:3:9\n0x33cc\nrun\n??:0:0\n";
        let groups = parse_locations(text, &[0x336e, 0x33cc]);
        assert_eq!(groups, [vec!["/x/y.rs:3:9 firmware::tick".to_string()], vec!["??:0:0 run".to_string()]]);
    }
}
