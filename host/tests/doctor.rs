//! `armctl doctor` against `armctl sim servos` on a pseudo-terminal, one fault at a time: each
//! finding is shown by the fault a person would meet, and a clean arm gives only OK lines.
//!
//! The simulator starts from the factory (return delay 500 µs), so a "clean" arm here is one that
//! `--fix` (or `armctl --bus`) has set up, as a person's arm is after its first connection.

mod support;

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::{Mutex, MutexGuard};

use serde_json::Value;
use support::armctl;

/// One simulator and one doctor at a time: the doctor times the line, and a dozen simulators
/// and doctors at once on a 2-core machine would time the machine instead.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// `armctl sim servos --pty ARGS`, killed when dropped.
struct Sim {
    child: Child,
    path: String,
    _turn: MutexGuard<'static, ()>,
}

impl Sim {
    fn start(args: &[&str]) -> Sim {
        // A test that failed while holding the lock poisons it; the next still runs.
        let turn = ONE_AT_A_TIME.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        let mut child = Command::new(env!("CARGO_BIN_EXE_armctl"))
            .args(["sim", "servos", "--pty"])
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("the simulator starts");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).expect("the pty's path");
        let path = line.trim().to_string();
        assert!(path.starts_with("/dev/"), "sim servos {args:?} printed {line:?}");
        Sim { child, path, _turn: turn }
    }

    /// `armctl doctor --bus PTY --json ARGS`: its JSON and exit code.
    fn doctor(&self, args: &[&str]) -> (Value, i32) {
        let mut argv = vec!["doctor", "--bus", &self.path, "--json"];
        argv.extend_from_slice(args);
        let run = armctl(&argv);
        let line =
            run.stdout.lines().next().unwrap_or_else(|| panic!("doctor {args:?}: no output; stderr: {}", run.stderr));
        let json: Value = serde_json::from_str(line).unwrap_or_else(|e| panic!("not JSON ({e}): {line}"));
        (json, run.code)
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The findings of `check`, as (level, message).
fn findings<'a>(report: &'a Value, check: &str) -> Vec<(&'a str, &'a str)> {
    report["findings"]
        .as_array()
        .expect("findings")
        .iter()
        .filter(|f| f["check"] == check)
        .map(|f| (f["level"].as_str().unwrap(), f["message"].as_str().unwrap()))
        .collect()
}

/// The one finding of `check` at `level` whose message holds `text`; panics with the report.
fn expect(report: &Value, check: &str, level: &str, text: &str) {
    let found = findings(report, check);
    assert!(
        found.iter().any(|(l, m)| *l == level && m.contains(text)),
        "expected a {level} {check} finding with {text:?}; {check} findings: {found:?}\nreport: {report}"
    );
}

/// The warnings and failures of every check but `cycle`, which times this machine: under CI's
/// load the cycle of a clean arm has measured 9.8 ms at the 99th percentile and been warned about
/// (the 10 ms period will not hold), which is the check working, not a fault of the arm.
fn counts_but_cycle(report: &Value) -> (u64, u64) {
    let of = |level: &str| {
        report["findings"].as_array().unwrap().iter().filter(|f| f["check"] != "cycle" && f["level"] == level).count()
            as u64
    };
    (of("warn"), of("fail"))
}

/// The set-up `armctl --bus` makes on first connect, given to the simulator's servos.
const SET_UP: [&str; 2] = ["--register", "all:return_delay_time=0"];

#[test]
fn a_clean_arm_gives_only_ok_lines_and_exit_0() {
    let sim = Sim::start(&["--arm", "so101", SET_UP[0], SET_UP[1]]);
    let (report, code) = sim.doctor(&["--arm", "so101"]);
    assert_eq!(counts_but_cycle(&report), (0, 0), "{report}");
    assert_eq!(code, 0);
    for check in ["bus", "ids", "models", "firmware", "power", "settings", "goals", "adapter", "line", "cycle"] {
        assert_eq!(findings(&report, check).len(), 1, "{check}: {report}");
    }
    expect(&report, "ids", "ok", "so101's 6 servos answer, ids 1-6");
    assert_eq!(report["line"]["lost"], 0);
    assert!(report["line"]["reads"].as_u64().unwrap() >= 300);
    // The text form: a line per finding, the counts last.
    let run = armctl(&["doctor", "--bus", &sim.path, "--arm", "so101", "--reads", "20"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(run.stdout.lines().next().unwrap().starts_with("OK    bus"), "{}", run.stdout);
    // The counts last (a warning, if any, the cycle's timing of this machine: see counts_but_cycle).
    assert!(run.stdout.trim_end().ends_with(" WARN, 0 FAIL"), "{}", run.stdout);
    assert!(run.stdout.lines().filter(|l| l.starts_with("WARN")).all(|l| l.contains(" cycle ")), "{}", run.stdout);
}

#[test]
fn a_factory_fresh_arm_warns_of_its_return_delay_and_fix_sets_it_up() {
    let sim = Sim::start(&["--arm", "so101", "--register", "2:goal_position=3000"]);
    let (report, code) = sim.doctor(&["--arm", "so101"]);
    assert_eq!(code, 0, "warnings only: {report}");
    expect(&report, "settings", "warn", "wait up to 500 µs before each reply");
    expect(&report, "goals", "warn", "servo 2 (shoulder_lift)'s goal is 84° (952 ticks) from where it stands");
    assert_eq!(report["fixed"], serde_json::json!([]), "nothing written without --fix");
    // No input: --fix asks, the end of input says no, and nothing is written.
    let (again, _) = sim.doctor(&["--arm", "so101", "--fix"]);
    assert_eq!(again["fixed"], serde_json::json!([]));
    expect(&again, "settings", "warn", "500 µs");
    let (fixed, code) = sim.doctor(&["--arm", "so101", "--fix", "--yes"]);
    assert_eq!(code, 0);
    let written: Vec<&str> = fixed["fixed"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    assert!(written.contains(&"servo 1: return_delay_time 250 -> 0 (EEPROM)"), "{written:?}");
    assert!(written.contains(&"servo 2: goal_position 3000 -> 2048"), "{written:?}");
    assert_eq!(written.len(), 7, "six return delays and one goal: {written:?}");
    assert_eq!(counts_but_cycle(&fixed), (0, 0), "looked at again after the fixes: {fixed}");
    assert!(fixed["servos"].as_array().unwrap().iter().all(|s| s["return_delay_us"] == 0));
}

#[test]
fn every_servo_at_the_factory_id_1() {
    let sim = Sim::start(&["--protocol", "sts", "--ids", "1", "--duplicate", "1"]);
    let (report, code) = sim.doctor(&["--arm", "so101"]);
    assert_eq!(code, 1);
    expect(&report, "ids", "fail", "every servo is still at id 1");
}

#[test]
fn a_missing_and_a_duplicated_id() {
    let sim = Sim::start(&["--arm", "so101", "--silent", "4", "--duplicate", "2", SET_UP[0], SET_UP[1]]);
    let (report, code) = sim.doctor(&["--arm", "so101", "--reads", "50"]);
    assert_eq!(code, 1);
    expect(&report, "ids", "fail", "servo 4 (wrist_flex) does not answer");
    expect(&report, "ids", "fail", "two or more servos answer as id 2");
}

#[test]
fn a_servo_of_another_model_than_the_arm_file_says() {
    let sim = Sim::start(&["--arm", "open-manipulator-x", "--model", "xl430-w250", SET_UP[0], SET_UP[1]]);
    let (report, code) = sim.doctor(&["--arm", "open-manipulator-x", "--reads", "50"]);
    assert_eq!(code, 1);
    expect(&report, "models", "fail", "is model 1060 XL430-W250, but open-manipulator-x has 1020 XM430-W350");
}

#[test]
fn mixed_firmware_versions() {
    let sim = Sim::start(&["--arm", "so101", "--register", "4:firmware_minor_version=9", SET_UP[0], SET_UP[1]]);
    let (report, _) = sim.doctor(&["--arm", "so101", "--reads", "50"]);
    expect(&report, "firmware", "warn", "mixed firmware versions: 3.10 on id 1-3,5-6, 3.9 on id 4");
}

#[test]
fn a_12_volt_supply_on_the_servos() {
    let sim = Sim::start(&["--arm", "so101", "--register", "all:present_voltage=120", SET_UP[0], SET_UP[1]]);
    let (report, _) = sim.doctor(&["--arm", "so101", "--reads", "50"]);
    let power = findings(&report, "power");
    assert!(
        power.iter().any(|(l, m)| *l != "ok" && m.contains("read 12.0 V, above")),
        "a 12 V supply on 7.4 V servos: {power:?}"
    );
}

#[test]
fn a_12_volt_supply_on_5_volt_dynamixels_is_judged_by_their_own_limits() {
    // Koch's XL330s on the XL430s' 12 V supply: the servo's own voltage limits (3.5 to 7.0 V
    // from the factory) say it, with no guessing about versions.
    let sim = Sim::start(&[
        "--protocol",
        "dxl2",
        "--model",
        "xl330-m288",
        "--ids",
        "1-3",
        "--register",
        "all:present_input_voltage=120",
        SET_UP[0],
        SET_UP[1],
    ]);
    let (report, code) = sim.doctor(&["--protocol", "dxl2", "--baud", "1000000", "--reads", "50"]);
    assert_eq!(code, 1);
    expect(&report, "power", "fail", "id 1-3 read 12.0 V, above its own limits 3.5-7.0 V");
}

#[test]
fn a_hot_servo_and_a_hardware_error() {
    let sim = Sim::start(&[
        "--arm",
        "so101",
        "--register",
        "2:present_temperature=71",
        "--hardware-error",
        "5=32",
        SET_UP[0],
        SET_UP[1],
    ]);
    let (report, code) = sim.doctor(&["--arm", "so101", "--reads", "50"]);
    assert_eq!(code, 1);
    expect(&report, "power", "fail", "servo 2 (shoulder_lift) is at 71 °C");
    expect(&report, "power", "fail", "servo 5 (wrist_roll) reports a hardware error: overload");
}

#[test]
fn a_servo_that_does_not_answer_writes() {
    let sim = Sim::start(&["--arm", "so101", "--register", "3:response_status_level=0", SET_UP[0], SET_UP[1]]);
    let (report, code) = sim.doctor(&["--arm", "so101", "--reads", "50"]);
    assert_eq!(code, 1);
    expect(&report, "settings", "fail", "servo 3 has status return level 0");
    let (fixed, code) = sim.doctor(&["--arm", "so101", "--reads", "50", "--fix", "--yes"]);
    assert_eq!(code, 0, "{fixed}");
    assert_eq!(fixed["fixed"], serde_json::json!(["servo 3: response_status_level 0 -> 1 (EEPROM)"]));
}

#[test]
fn an_adapter_that_hears_itself() {
    let sim = Sim::start(&["--arm", "so101", "--echo", SET_UP[0], SET_UP[1]]);
    let (report, code) = sim.doctor(&["--arm", "so101", "--reads", "50"]);
    assert_eq!(code, 1);
    assert_eq!(report["echo"], true);
    expect(&report, "adapter", "fail", "hears its own transmission");
    // The rest is still diagnosed: the doctor skips its own bytes.
    expect(&report, "ids", "ok", "6 servos answer");
}

#[test]
fn an_adapter_with_the_factory_16_ms_latency_timer() {
    let sim = Sim::start(&["--arm", "so101", "--burst-ms", "16", SET_UP[0], SET_UP[1]]);
    let (report, code) = sim.doctor(&["--arm", "so101", "--reads", "60"]);
    assert_eq!(code, 0, "{report}");
    expect(&report, "adapter", "warn", "the adapter holds them");
    expect(&report, "cycle", "warn", "armctl --bus will run at");
}

#[test]
fn a_noisy_line_loses_replies() {
    let sim = Sim::start(&["--arm", "so101", "--bit-flip-rate", "0.002", "--seed", "7", SET_UP[0], SET_UP[1]]);
    let (report, _) = sim.doctor(&["--arm", "so101"]);
    let line = findings(&report, "line");
    assert_eq!(line.len(), 1, "{report}");
    assert_ne!(line[0].0, "ok", "{line:?}");
    assert!(report["line"]["lost"].as_u64().unwrap() > 0);
    // The noise is the line's: no servo is taken for missing or duplicated.
    expect(&report, "ids", "ok", "so101's 6 servos answer");
}

#[test]
fn a_calibration_file_against_the_servos() {
    let dir = tempfile::tempdir().unwrap();
    let names = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"];
    let write = |file: &str, offset_of_2: i64| {
        let motors: serde_json::Map<String, Value> = names
            .iter()
            .enumerate()
            .map(|(i, n)| {
                let offset = if i == 1 { offset_of_2 } else { 0 };
                let motor = serde_json::json!({"id": i + 1, "drive_mode": 0, "homing_offset": offset, "range_min": 0, "range_max": 4095});
                (n.to_string(), motor)
            })
            .collect();
        let path = dir.path().join(file);
        std::fs::write(&path, Value::Object(motors).to_string()).unwrap();
        path.display().to_string()
    };
    let matching = write("matching.json", 0);
    let differing = write("differing.json", 100);
    let too_far = write("too-far.json", 2114);
    let sim = Sim::start(&["--arm", "so101", SET_UP[0], SET_UP[1]]);
    let (report, _) = sim.doctor(&["--arm", "so101", "--reads", "20", "--calibration", &matching]);
    expect(&report, "calibration", "ok", "(6 motors)");
    let (report, code) = sim.doctor(&["--arm", "so101", "--reads", "20", "--calibration", &differing]);
    assert_eq!(code, 1);
    expect(&report, "calibration", "fail", "servo 2 (shoulder_lift): homing offset is 0 on the servo but 100 in");
    let (report, _) = sim.doctor(&["--arm", "so101", "--reads", "20", "--calibration", &too_far]);
    expect(&report, "calibration", "fail", "shoulder_lift: homing offset 2114 in");
    expect(&report, "calibration", "fail", "does not fit the STS3215's register");
}

#[test]
fn the_protocol_and_baud_rate_are_found_when_not_given() {
    let sim = Sim::start(&["--protocol", "dxl2", "--ids", "1-3", "--baud", "57600", SET_UP[0], SET_UP[1]]);
    let (report, _) = sim.doctor(&["--reads", "20"]);
    assert_eq!((report["protocol"].as_str(), report["baud"].as_u64()), (Some("dxl2"), Some(57_600)), "{report}");
    expect(&report, "ids", "ok", "3 servos answer, ids 1-3");
}

#[test]
fn nothing_on_the_bus_is_one_fail_with_what_to_check() {
    let sim = Sim::start(&["--protocol", "sts", "--ids", "100"]);
    let (report, code) = sim.doctor(&["--protocol", "sts", "--baud", "1000000"]);
    assert_eq!(code, 1);
    expect(&report, "bus", "fail", "no servo answered");
    assert_eq!(report["servos"], serde_json::json!([]));
}

#[test]
fn bad_invocations_are_one_line_errors() {
    for (args, text) in [
        (vec!["doctor"], "doctor needs --bus PORT"),
        (vec!["--sim", "doctor"], "--sim is not for it"),
        (
            vec!["--bus", "/dev/nonexistent-armctl-port", "doctor", "--protocol", "sts", "--baud", "1000000"],
            "nonexistent",
        ),
        (
            vec!["doctor", "--bus", "/dev/nonexistent-armctl-port", "--protocol", "sts", "--baud", "1000000"],
            "nonexistent",
        ),
        (vec!["doctor", "--bus", "/dev/null", "--calibration", "/nonexistent.json"], "nonexistent.json"),
    ] {
        let run = armctl(&args);
        assert_ne!(run.code, 0, "{args:?}");
        let lines: Vec<&str> = run.stderr.lines().filter(|l| l.starts_with("error:")).collect();
        assert_eq!(lines.len(), 1, "{args:?}: {}", run.stderr);
        assert!(lines[0].contains(text), "{args:?}: {}", run.stderr);
    }
}
