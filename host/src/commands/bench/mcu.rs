//! `armctl bench mcu`: instructions per operation of the firmware's per-tick work on the Cortex-M4F,
//! counted by the board crate's `opcount` binary under `qemu-system-arm -icount shift=0`, and of
//! the kinematic tree's (`kinematics::tree`, which the firmware does not run yet) in f32 on a
//! two-arm body, with the bytes of stack its IK takes.
//!
//! The binary times each operation over a batch of repetitions with SysTick, which under
//! `-icount shift=0` on the 25 MHz core clock counts one tick per 40 guest instructions, the same
//! on every run and every host (the design notes kept outside this repository, "Boards"). Here the ticks become instructions per
//! operation: `ticks * 40 / reps`, less the same figure for an empty loop of the same shape. A
//! tick is 40 instructions, so over 100 repetitions the figures resolve 0.4 instruction.
//!
//! The calibration line checks the factor itself: a hand-written loop of exactly 10 instructions
//! per iteration must come out at 10. These are instruction counts, not cycles: QEMU charges every
//! instruction alike (a divide, a load that would wait on flash, a taken branch), so cycles on a
//! real M4F at zero wait states are somewhat higher.

use std::io::Write;

use anyhow::{anyhow, bail, Result};
use serde_json::{json, Value};

#[cfg(feature = "board-tools")]
use crate::runtime::qemu::{self, Qemu, QemuConfig};

/// The board binary that counts.
pub const OPCOUNT_BIN: &str = "opcount";
/// How long QEMU may take: building is done before, and the run itself takes a few seconds.
#[cfg(feature = "board-tools")]
const RUN_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(120);
/// The calibration's name in the firmware's output.
pub const CALIBRATION: &str = "calib_nop";
/// The empty loop's name: its per-repetition cost is subtracted from every operation.
const EMPTY: &str = "empty";

/// The goals the issue sets, in instructions per operation.
pub const GOALS: [(&str, u64); 5] = [
    ("ik_track_1cm", 50_000),
    ("fk6", 4_000),
    ("hermite6_gripper", 1_500),
    ("collision_so101", 20_000),
    ("collision_24x8", 20_000),
];

/// What each operation is, for the table's readers.
const DESCRIPTIONS: [(&str, &str); 18] = [
    ("fk6", "forward kinematics of the 6-joint UR5e, every frame, f32"),
    ("rnea6", "inverse dynamics of the 6-joint UR5e (recursive Newton-Euler, gravity), f32"),
    ("sincos", "one f32 sin and cos (kinematics::trig, in f32)"),
    ("sincos_libm", "the same with libm's sincosf (f64 inside, software)"),
    ("dls_iter", "one damped-least-squares iteration, full pose"),
    ("ik_track_1cm", "tracking IK step, target 1 cm away, warm start"),
    ("hermite6", "player tick, 6 joints, inside a Hermite segment"),
    ("hermite6_gripper", "the same tick with the gripper's keyframe track and ramp"),
    ("tree_fk", "FK of a two-arm tree (torso, 2 x 5 joints), every frame"),
    ("tree_jacobian", "both hands' Jacobians of that tree, from its frames"),
    ("tree_ik_track_1cm", "tree IK, both hands 1 cm away, positions, warm start"),
    ("collision_so101", "FK + collision check, SO-101: 6 capsules, table, box (median of free poses)"),
    ("collision_24x8", "FK + collision check, 24 capsules, 8 obstacles (median of free poses)"),
    ("sync_write6_sts", "encode a Feetech sync write of 6 goals"),
    ("sync_write6_dxl2", "encode a Dynamixel 2.0 sync write of 6 goals"),
    ("sync_read6_sts", "decode 6 Feetech replies of a sync read"),
    ("sync_read6_dxl2", "decode 6 Dynamixel 2.0 replies of a sync read"),
    ("calib_nop", "calibration"),
];

/// One `op` line of the firmware's output.
#[derive(Clone, Debug, PartialEq)]
pub struct OpLine {
    /// The operation.
    pub name: String,
    /// Repetitions timed together.
    pub reps: u32,
    /// SysTick ticks the batch took.
    pub ticks: u32,
    /// Further `key=value` fields (solver iterations, packet bytes, the calibration's expectation).
    pub extra: Vec<(String, u32)>,
}

impl OpLine {
    /// Instructions per repetition, before the empty loop is subtracted.
    fn per_rep(&self, instructions_per_tick: u32) -> f64 {
        f64::from(self.ticks) * f64::from(instructions_per_tick) / f64::from(self.reps)
    }

    /// The value of the extra field `key`.
    pub fn field(&self, key: &str) -> Option<u32> {
        self.extra.iter().find(|(k, _)| k == key).map(|(_, v)| *v)
    }
}

/// One operation's count.
#[derive(Clone, Debug, PartialEq)]
pub struct OpCount {
    /// What the firmware measured.
    pub line: OpLine,
    /// Instructions per operation, the empty loop's subtracted.
    pub instructions: f64,
    /// The goal, if it sets one.
    pub goal: Option<u64>,
}

impl OpCount {
    /// Whether the goal is met (`None` without a goal).
    pub fn met(&self) -> Option<bool> {
        self.goal.map(|g| self.instructions <= g as f64)
    }
}

/// The calibration: a loop of known length timed the same way.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Calibration {
    /// Instructions per iteration, as written.
    pub expected: u32,
    /// Instructions per iteration, as measured with the tick factor.
    pub measured: f64,
}

impl Calibration {
    /// Measured over expected: 1 when one tick is exactly the assumed number of instructions.
    pub fn ratio(&self) -> f64 {
        self.measured / f64::from(self.expected)
    }
}

/// Everything `opcount` reported.
#[derive(Clone, Debug, PartialEq)]
pub struct McuReport {
    /// Guest instructions per SysTick tick, as the firmware states it.
    pub instructions_per_tick: u32,
    /// Instructions of one empty repetition (subtracted from every operation).
    pub empty_per_rep: f64,
    /// The calibration.
    pub calibration: Calibration,
    /// The operations, in the firmware's order.
    pub ops: Vec<OpCount>,
    /// The firmware's warnings (a tracking step that did not converge within its budget).
    pub warnings: Vec<String>,
}

/// Builds `opcount`, runs it under QEMU and reads its counts (needs the `board-tools` feature).
#[cfg(not(feature = "board-tools"))]
pub fn measure() -> Result<McuReport> {
    Err(crate::runtime::board::without_tools("bench mcu"))
}

/// Builds `opcount`, runs it under QEMU and reads its counts.
#[cfg(feature = "board-tools")]
pub fn measure() -> Result<McuReport> {
    use anyhow::Context;
    require_qemu("bench mcu")?;
    let elf = qemu::build(OPCOUNT_BIN)?;
    let qemu = Qemu::start(&QemuConfig::new(elf, None))?;
    let (status, lines) = qemu.wait(RUN_TIMEOUT)?;
    if !status.success() {
        bail!("{OPCOUNT_BIN} ended with {status}; its log:\n{}", lines.join("\n"));
    }
    parse(&lines).with_context(|| format!("reading the log of {OPCOUNT_BIN}:\n{}", lines.join("\n")))
}

/// Fails in one line where qemu-system-arm is missing: `armctl COMMAND` runs the firmware under it.
#[cfg(feature = "board-tools")]
pub(crate) fn require_qemu(command: &str) -> Result<()> {
    if !qemu::available() {
        bail!("qemu-system-arm is not installed (apt-get install qemu-system-arm): `{command}` runs the firmware under it");
    }
    Ok(())
}

/// Reads `opcount`'s log lines (as `armctl::runtime::qemu` decodes them: level, then the message).
pub fn parse(lines: &[String]) -> Result<McuReport> {
    let mut instructions_per_tick = None;
    let mut raw = Vec::new();
    let mut warnings = Vec::new();
    for line in lines {
        let Some((level, message)) = line.split_once(' ') else { continue };
        let message = message.trim_start();
        match level {
            "ERROR" => bail!("the firmware reported: {message}"),
            "WARN" => warnings.push(message.to_string()),
            _ => {}
        }
        if let Some(rest) = message.strip_prefix("clock ") {
            instructions_per_tick =
                fields(rest).into_iter().find(|(k, _)| k == "instructions_per_tick").map(|(_, v)| v);
        } else if let Some(rest) = message.strip_prefix("op ") {
            raw.push(op_line(rest)?);
        }
    }
    let instructions_per_tick = instructions_per_tick.ok_or_else(|| anyhow!("no `clock` line in the log"))?;
    if !lines.iter().any(|l| l.trim_end().ends_with(" done")) {
        bail!("the log ends before `done`");
    }
    let find = |name: &str| raw.iter().find(|l| l.name == name).ok_or_else(|| anyhow!("no `op {name}` line"));
    let empty_per_rep = find(EMPTY)?.per_rep(instructions_per_tick);
    let calib = find(CALIBRATION)?;
    let expected = calib.field("expected").ok_or_else(|| anyhow!("the calibration line has no `expected`"))?;
    let calibration = Calibration { expected, measured: calib.per_rep(instructions_per_tick) };
    let ops = raw
        .iter()
        .filter(|l| l.name != EMPTY && l.name != CALIBRATION)
        .map(|l| OpCount {
            line: l.clone(),
            instructions: l.per_rep(instructions_per_tick) - empty_per_rep,
            goal: GOALS.iter().find(|(n, _)| *n == l.name).map(|(_, g)| *g),
        })
        .collect();
    Ok(McuReport { instructions_per_tick, empty_per_rep, calibration, ops, warnings })
}

/// `NAME reps=R ticks=T [key=value ...]`.
fn op_line(text: &str) -> Result<OpLine> {
    let (name, rest) = text.split_once(' ').ok_or_else(|| anyhow!("`op {text}`: no fields"))?;
    let mut extra = fields(rest);
    let mut take = |key: &str| {
        let i = extra.iter().position(|(k, _)| k == key).ok_or_else(|| anyhow!("`op {text}`: no {key}"))?;
        Ok::<u32, anyhow::Error>(extra.remove(i).1)
    };
    let reps = take("reps")?;
    let ticks = take("ticks")?;
    if reps == 0 {
        bail!("`op {text}`: zero repetitions");
    }
    Ok(OpLine { name: name.to_string(), reps, ticks, extra })
}

/// The `key=value` fields (decimal values) of a line; other words are skipped.
fn fields(text: &str) -> Vec<(String, u32)> {
    text.split_whitespace()
        .filter_map(|w| w.split_once('='))
        .filter_map(|(k, v)| v.parse().ok().map(|v| (k.to_string(), v)))
        .collect()
}

/// `armctl bench mcu`: the table on `out`, or with `json` one JSON object (indented).
pub fn run(json: bool, out: &mut dyn Write) -> Result<i32> {
    let report = measure()?;
    if json {
        writeln!(out, "{}", serde_json::to_string_pretty(&to_json(&report))?)?;
    } else {
        write_table(&report, out)?;
    }
    Ok(0)
}

fn describe(name: &str) -> &'static str {
    DESCRIPTIONS.iter().find(|(n, _)| *n == name).map_or("", |(_, d)| d)
}

/// The extra fields worth showing beside the count.
fn note(line: &OpLine) -> String {
    line.extra.iter().map(|(k, v)| format!("{k}={v}")).collect::<Vec<_>>().join(" ")
}

fn write_table(r: &McuReport, out: &mut dyn Write) -> Result<()> {
    writeln!(
        out,
        "Instructions per operation on the Cortex-M4F (mps2-an386 under qemu-system-arm -icount shift=0; SysTick: {} \
         instructions per tick; empty-loop overhead of {:.1} instructions per repetition subtracted)",
        r.instructions_per_tick, r.empty_per_rep
    )?;
    writeln!(out, "{:<18} {:>12} {:>8}  {:<7} {:<48} note", "operation", "instructions", "goal", "", "what")?;
    for op in &r.ops {
        let goal = op.goal.map_or_else(|| "-".to_string(), |g| g.to_string());
        let met = match op.met() {
            Some(true) => "met",
            Some(false) => "MISSED",
            None => "",
        };
        writeln!(
            out,
            "{:<18} {:>12.0} {:>8}  {:<7} {:<48} {}",
            op.line.name,
            op.instructions,
            goal,
            met,
            describe(&op.line.name),
            note(&op.line)
        )?;
    }
    writeln!(
        out,
        "calibration: a loop of {} instructions per iteration measured {:.3} (ratio {:.4})",
        r.calibration.expected,
        r.calibration.measured,
        r.calibration.ratio()
    )?;
    for w in &r.warnings {
        writeln!(out, "warning from the firmware: {w}")?;
    }
    Ok(())
}

fn to_json(r: &McuReport) -> Value {
    json!({
        "instructions_per_tick": r.instructions_per_tick,
        "empty_loop_instructions": r.empty_per_rep,
        "calibration": {
            "expected": r.calibration.expected,
            "measured": r.calibration.measured,
            "ratio": r.calibration.ratio(),
        },
        "warnings": r.warnings,
        "operations": r.ops.iter().map(|op| json!({
            "name": op.line.name,
            "instructions": op.instructions,
            "reps": op.line.reps,
            "ticks": op.line.ticks,
            "goal": op.goal,
            "met": op.met(),
            "fields": op.line.extra.iter().map(|(k, v)| (k.clone(), json!(v))).collect::<serde_json::Map<_, _>>(),
        })).collect::<Vec<_>>(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(text: &str) -> Vec<String> {
        text.lines().map(str::to_string).collect()
    }

    /// The parse of a log as `armctl::runtime::qemu` decodes it: ticks to instructions, empty loop off.
    #[test]
    fn parses_the_counts_and_subtracts_the_empty_loop() {
        let log = lines(
            "INFO  clock core_hz=25000000 instructions_per_tick=40 (-icount shift=0: 1 instruction per ns)\n\
             INFO  op calib_nop reps=100000 ticks=25000 expected=10\n\
             INFO  op empty reps=100 ticks=10\n\
             INFO  op fk6 reps=100 ticks=10010\n\
             INFO  op ik_track_1cm reps=100 ticks=200000 iterations=2\n\
             INFO  done",
        );
        let r = parse(&log).unwrap();
        assert_eq!(r.instructions_per_tick, 40);
        assert_eq!(r.empty_per_rep, 4.0);
        assert_eq!(r.calibration, Calibration { expected: 10, measured: 10.0 });
        assert_eq!(r.ops.len(), 2);
        assert_eq!(r.ops[0].instructions, 4000.0);
        assert_eq!(r.ops[0].met(), Some(true));
        assert_eq!(r.ops[1].instructions, 79_996.0);
        assert_eq!(r.ops[1].met(), Some(false));
        assert_eq!(r.ops[1].line.field("iterations"), Some(2));
    }

    #[test]
    fn a_wrapped_batch_or_a_cut_log_is_an_error() {
        let wrapped = lines("INFO  clock instructions_per_tick=40\nERROR op fk6 reps=100 wrapped\nINFO  done");
        assert!(parse(&wrapped).is_err());
        let cut = lines("INFO  clock instructions_per_tick=40\nINFO  op empty reps=100 ticks=10");
        assert!(parse(&cut).is_err());
    }
}
