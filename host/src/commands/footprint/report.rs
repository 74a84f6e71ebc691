//! The footprint report itself: section sizes, panic sites, the static stack bound and the measured
//! stack of each board binary (needs the `board-tools` feature).

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::Serialize;

use super::disasm::{PanicSite, Program, StackBound, Tools};
use super::elf::Sizes;
use super::measure::{self, MeasuredStack};
use super::{Board, FootprintRequest, FLASH_GOAL, STACK_GOAL, STATIC_RAM_GOAL};

impl Board {
    const ALL: [Board; 2] = [Board::Mps2An386, Board::Stm32f411];

    /// Where the stack bound starts: on the MPS2, `main` paints the stack between start-up and the
    /// control loop, so each has its own figure to compare with the measurement.
    fn roots(self) -> &'static [&'static str] {
        match self {
            Board::Mps2An386 => &["board_mps2_an386::start", "board_mps2_an386::run"],
            Board::Stm32f411 => &["board_stm32f411::start", "board_stm32f411::run"],
        }
    }

    /// Builds the release binary and returns its path.
    fn build(self) -> Result<PathBuf> {
        match self {
            Board::Mps2An386 => crate::runtime::qemu::build(crate::runtime::qemu::FIRMWARE_BIN),
            Board::Stm32f411 => {
                crate::runtime::board::build(&crate::runtime::board::boards_dir().join("stm32f411"), "board-stm32f411")
            }
        }
    }
}

/// A figure against its goal.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Budget {
    /// The figure.
    pub bytes: u64,
    /// The goal.
    pub goal_bytes: u64,
    /// Whether the figure is within the goal.
    pub met: bool,
}

impl Budget {
    fn new(bytes: u64, goal_bytes: u64) -> Budget {
        Budget { bytes, goal_bytes, met: bytes <= goal_bytes }
    }
}

/// A panic site with where it comes from in the source.
#[derive(Clone, Debug, Serialize)]
pub struct SiteReport {
    /// The call.
    #[serde(flatten)]
    pub site: PanicSite,
    /// `file:line:col function`, innermost inlined frame first, standard library frames left out
    /// (`None` without llvm-addr2line).
    pub locations: Option<Vec<String>>,
}

/// The stack measured under QEMU.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct MeasuredReport {
    /// Start-up's depth against the goal.
    pub startup: Budget,
    /// The control loop's high-water mark against the goal.
    pub control_loop: Budget,
}

/// Everything reported on one binary.
#[derive(Clone, Debug, Serialize)]
pub struct BoardReport {
    /// The board, if known.
    pub board: Option<&'static str>,
    /// The ELF.
    pub elf: PathBuf,
    /// Section sizes.
    pub sections: Sizes,
    /// Flash against the goal.
    pub flash: Budget,
    /// Static RAM against the goal.
    pub static_ram: Budget,
    /// The number of panic sites.
    pub panic_site_count: usize,
    /// The panic sites.
    pub panic_sites: Vec<SiteReport>,
    /// The static stack bound from each root.
    pub static_stack: Vec<StackBound>,
    /// The stack measured under QEMU, if it was.
    pub measured_stack: Option<MeasuredReport>,
    /// Why the stack was not measured.
    pub measured_stack_skipped: Option<String>,
}

/// Runs `armctl footprint`.
pub(super) fn run(args: &FootprintRequest, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let tools = Tools::find()?;
    let mut reports = Vec::new();
    match &args.elf {
        Some(elf) => reports.push(report(&tools, elf, args.board, args, err)?),
        None => {
            let boards = args.board.map_or(Board::ALL.to_vec(), |b| vec![b]);
            for board in boards {
                let elf = board.build()?;
                reports.push(report(&tools, &elf, Some(board), args, err)?);
            }
        }
    }
    if args.json {
        writeln!(out, "{}", serde_json::json!({ "boards": reports }))?;
    } else {
        for (i, r) in reports.iter().enumerate() {
            if i > 0 {
                writeln!(out)?;
            }
            print_report(out, r)?;
        }
    }
    Ok(0)
}

fn report(
    tools: &Tools,
    elf: &Path,
    board: Option<Board>,
    args: &FootprintRequest,
    err: &mut dyn Write,
) -> Result<BoardReport> {
    let bytes = std::fs::read(elf).with_context(|| format!("cannot read {}", elf.display()))?;
    let sections = Sizes::of_elf(&bytes).with_context(|| elf.display().to_string())?;
    let program = Program::parse(&tools.disassemble(elf)?);
    // The board whose firmware functions the ELF has: the board crate's other binary, `opcount`,
    // links some of its functions too, but it is not the firmware (no start-up or loop to bound).
    let board =
        board.or_else(|| Board::ALL.into_iter().find(|b| b.roots().iter().all(|root| program.find(root).is_some())));

    let sites = program.panic_sites();
    let addresses: Vec<u64> = sites.iter().map(|s| s.address).collect();
    let mut locations = tools.locate(elf, &addresses)?.map(Vec::into_iter);
    let panic_sites: Vec<SiteReport> = sites
        .into_iter()
        .map(|site| SiteReport { site, locations: locations.as_mut().and_then(Iterator::next) })
        .collect();

    let roots: Vec<&str> = match board {
        Some(b) => b.roots().to_vec(),
        None => vec!["main"],
    };
    let mut static_stack = Vec::new();
    for root in &roots {
        let f = program.find(root).with_context(|| format!("{} has no function {root}", elf.display()))?;
        static_stack.push(program.stack_bound(f));
    }

    let (measured_stack, measured_stack_skipped) = if board.is_none() {
        (None, Some("not measured: not a board's firmware (measured on the mps2-an386 firmware only)".to_string()))
    } else if board != Some(Board::Mps2An386) {
        (None, Some("not measured: QEMU emulates only the mps2-an386 board".to_string()))
    } else if args.no_qemu {
        (None, Some("not measured (--no-qemu)".to_string()))
    } else if !crate::runtime::qemu::available() {
        (None, Some("not measured: qemu-system-arm is missing (apt-get install qemu-system-arm)".to_string()))
    } else {
        writeln!(err, "measuring the stack under QEMU (move, streamed keyframes, arm sent over the link)...")?;
        let m: MeasuredStack = measure::measure(elf).context("measuring the stack under QEMU")?;
        let measured = MeasuredReport {
            startup: Budget::new(m.startup, STACK_GOAL),
            control_loop: Budget::new(m.control_loop, STACK_GOAL),
        };
        (Some(measured), None)
    };

    Ok(BoardReport {
        board: board.map(Board::name),
        elf: elf.to_path_buf(),
        sections,
        flash: Budget::new(sections.flash(), FLASH_GOAL),
        static_ram: Budget::new(sections.static_ram(), STATIC_RAM_GOAL),
        panic_site_count: panic_sites.len(),
        panic_sites,
        static_stack,
        measured_stack,
        measured_stack_skipped,
    })
}

fn kib(bytes: u64) -> String {
    format!("{:.1} KiB", bytes as f64 / 1024.0)
}

/// `12345 bytes (12.1 KiB), goal 16 KiB: met`.
fn against_goal(b: &Budget) -> String {
    let verdict = if b.met { "met" } else { "missed" };
    format!("{} bytes ({}), goal {} KiB: {verdict}", b.bytes, kib(b.bytes), b.goal_bytes / 1024)
}

fn print_report(out: &mut dyn Write, r: &BoardReport) -> Result<()> {
    let s = &r.sections;
    writeln!(out, "{} ({})", r.board.unwrap_or("unknown board"), r.elf.display())?;
    writeln!(out, "  flash          {}", against_goal(&r.flash))?;
    writeln!(
        out,
        "                 .vector_table {} + .text {} + .rodata {} + .data {}",
        s.vector_table, s.text, s.rodata, s.data
    )?;
    writeln!(out, "  static RAM     {}", against_goal(&r.static_ram))?;
    writeln!(out, "                 .data {} + .bss {} + .uninit {}", s.data, s.bss, s.uninit)?;
    writeln!(out, "  panic paths    {} call sites into core's panic entry points", r.panic_site_count)?;
    for p in &r.panic_sites {
        writeln!(out, "    {:#x} in {} -> {}", p.site.address, p.site.function, p.site.target)?;
        match &p.locations {
            Some(chain) => {
                for l in chain {
                    writeln!(out, "        {l}")?;
                }
            }
            None => writeln!(out, "        (no source lines: llvm-addr2line is missing)")?,
        }
    }
    writeln!(
        out,
        "  static stack   deepest chain of direct calls; indirect calls are not followed, so this is a lower \
         bound of the static worst case (the measured figure is the check)"
    )?;
    for bound in &r.static_stack {
        writeln!(
            out,
            "    from {}: {} bytes ({}), {} indirect call sites on the chain not followed",
            bound.root,
            bound.bytes,
            kib(bound.bytes),
            bound.indirect_calls
        )?;
        for frame in &bound.path {
            writeln!(out, "      {:>6}  {}", frame.bytes, frame.function)?;
        }
    }
    match (&r.measured_stack, &r.measured_stack_skipped) {
        (Some(m), _) => {
            writeln!(
                out,
                "  measured stack by painting under QEMU (SO-101 on simulated servos: a Cartesian move, 40 \
                 streamed keyframes, the arm sent over the link; gravity compensation on)"
            )?;
            writeln!(out, "    start-up     {}", against_goal(&m.startup))?;
            writeln!(out, "    control loop {}", against_goal(&m.control_loop))?;
        }
        (None, why) => writeln!(out, "  measured stack {}", why.as_deref().unwrap_or("not measured"))?,
    }
    Ok(())
}
