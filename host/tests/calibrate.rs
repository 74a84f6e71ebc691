//! `armctl calibrate` end to end, as a person runs it: the simulated servos served by `armctl sim
//! servos --pty --arm ARM`, their horns started away from the servos' middle (`--start`) and turned
//! by the simulator's hand (`sweep` on its stdin) between the steps, which the test answers on
//! `armctl calibrate`'s stdin. Then the servos' registers, the LeRobot file, the arm file and a
//! connection through `--bus --arm FILE` are checked against what the hand did.
//!
//! No timing is asserted: each step waits (generously) for what the programs print. A hand's move
//! is reported done only once the bus has read the horn where the hand left it, and the recording
//! is the only reader during step 2, so each end of a sweep is in the recording: the ranges are
//! expected exactly, without the few ticks a 20 ms sampling would miss of a moving horn.

use std::io::{BufRead, BufReader, Write};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use armctl::arm::calibration::{lerobot, record, MotorCalibration};
use armctl::arm::ArmSpec;
use serde_json::Value;

/// How long a step may take before the test gives up: far more than any step needs.
const PATIENCE: Duration = Duration::from_secs(60);

const ARMCTL: &str = env!("CARGO_BIN_EXE_armctl");

/// The bus's baud rate: the default of `sim servos`, `calibrate` and `--bus` on both protocols,
/// given to `armctl servo`, whose Dynamixel default is the factory 57600.
const BAUD: &str = "1000000";

/// A child process whose stdout lines arrive on a channel; killed when dropped.
struct Process {
    child: Child,
    stdin: Option<ChildStdin>,
    lines: Receiver<String>,
    /// Every stdout line seen so far.
    seen: Vec<String>,
    stderr: Option<std::thread::JoinHandle<String>>,
}

impl Process {
    fn spawn(args: &[&str]) -> Process {
        let mut child = Command::new(ARMCTL)
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("armctl starts");
        let stdout = child.stdout.take().unwrap();
        let (tx, lines) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let mut stderr = child.stderr.take().unwrap();
        let stderr = std::thread::spawn(move || {
            let mut text = String::new();
            let _ = std::io::Read::read_to_string(&mut stderr, &mut text);
            text
        });
        Process { stdin: child.stdin.take(), child, lines, seen: Vec::new(), stderr: Some(stderr) }
    }

    /// The next stdout line.
    fn line(&mut self, waiting_for: &str) -> String {
        match self.lines.recv_timeout(PATIENCE) {
            Ok(line) => {
                self.seen.push(line.clone());
                line
            }
            Err(RecvTimeoutError::Timeout) => {
                panic!("no line in {PATIENCE:?} waiting for {waiting_for}: {:?}", self.seen)
            }
            Err(RecvTimeoutError::Disconnected) => {
                let stderr = self.stderr_now();
                panic!("stdout ended waiting for {waiting_for}: {:?}; stderr {stderr}", self.seen)
            }
        }
    }

    /// Reads stdout lines up to and including the first that starts with `prefix`.
    fn until(&mut self, prefix: &str) -> String {
        loop {
            let line = self.line(prefix);
            if line.starts_with(prefix) {
                return line;
            }
        }
    }

    fn send(&mut self, text: &str) {
        let stdin = self.stdin.as_mut().expect("stdin is open");
        if let Err(e) = writeln!(stdin, "{text}").and_then(|()| stdin.flush()) {
            // The process ended before reading it: what it said is the failure, not the pipe.
            let (code, stderr) = self.finish();
            panic!("sending {text:?}: {e}; it had ended with {code}: {:?}; stderr {stderr}", self.seen);
        }
    }

    fn close_stdin(&mut self) {
        self.stdin = None;
    }

    /// The exit code, once the process ends (within [`PATIENCE`]), and its stderr.
    fn finish(&mut self) -> (i32, String) {
        self.close_stdin();
        let started = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                while let Ok(line) = self.lines.recv_timeout(Duration::from_secs(5)) {
                    self.seen.push(line);
                }
                return (status.code().expect("exits normally"), self.stderr_now());
            }
            assert!(started.elapsed() < PATIENCE, "armctl did not end: {:?}", self.seen);
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    fn stderr_now(&mut self) -> String {
        if self.child.try_wait().ok().flatten().is_none() {
            return "(still running)".into();
        }
        self.stderr.take().map(|t| t.join().unwrap()).unwrap_or_default()
    }
}

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `armctl sim servos --pty --arm ARM --start ...`, and its pty's path.
fn simulator(arm: &str, start: &[(u8, i64)]) -> (Process, String) {
    let start: Vec<String> = start.iter().map(|(id, t)| format!("{id}={t}")).collect();
    let start = start.join(",");
    let mut sim = Process::spawn(&["sim", "servos", "--pty", "--arm", arm, "--start", &start]);
    let path = sim.line("the pty's path");
    assert!(path.starts_with("/dev/"), "{path}");
    (sim, path)
}

/// Sends the hand's `commands` and waits for each one's `done` line (in any order). A move is
/// done once the position there has been read, so the calibration (`reader`) must be reading:
/// if it ends first, the failure shows what it said rather than the hand's wait running out.
fn hand(sim: &mut Process, commands: &[String], reader: &mut Process) {
    for c in commands {
        sim.send(c);
    }
    let mut waiting: Vec<String> = commands.iter().map(|c| format!("done {c}")).collect();
    let started = Instant::now();
    while !waiting.is_empty() {
        let line = match sim.lines.recv_timeout(Duration::from_millis(200)) {
            Ok(line) => line,
            Err(RecvTimeoutError::Timeout) => {
                if reader.child.try_wait().ok().flatten().is_some() {
                    let stderr = reader.stderr_now();
                    panic!("the calibration ended during the hand's moves: {:?}; stderr {stderr}", reader.seen);
                }
                assert!(
                    started.elapsed() < PATIENCE,
                    "no line in {PATIENCE:?} waiting for the hand's moves: {:?}",
                    sim.seen
                );
                continue;
            }
            Err(RecvTimeoutError::Disconnected) => panic!("the simulator ended: {:?}", sim.seen),
        };
        sim.seen.push(line.clone());
        assert!(!line.starts_with("error"), "{line}");
        waiting.retain(|w| *w != line);
    }
}

/// Runs a one-shot armctl: (exit code, stdout, stderr).
fn armctl(args: &[&str]) -> (i32, String, String) {
    let o = Command::new(ARMCTL).args(args).stdin(Stdio::null()).output().unwrap();
    (o.status.code().unwrap(), String::from_utf8(o.stdout).unwrap(), String::from_utf8(o.stderr).unwrap())
}

/// The named registers of servo `id`, read with `armctl servo read --item`.
fn registers(path: &str, protocol: &str, id: u8, items: &[&str]) -> Vec<i64> {
    let (code, out, err) = armctl(&[
        "servo",
        "read",
        "--port",
        path,
        "--protocol",
        protocol,
        "--baud",
        BAUD,
        "--id",
        &id.to_string(),
        "--item",
        &items.join(","),
    ]);
    assert_eq!(code, 0, "{err}");
    let values: Vec<i64> = out.lines().skip(1).map(|l| l.rsplit(" = ").next().unwrap().parse().unwrap()).collect();
    assert_eq!(values.len(), items.len(), "{out}");
    values
}

/// A folder of its own, removed when dropped (also when the test fails).
fn temp_dir(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("armctl-calibrate-{name}-")).tempdir().unwrap()
}

/// One joint (or the gripper) as the hand moves it, in the horn's own ticks: where the person
/// holds it for step 1 (the middle of its range), and the two stops it is swept to in step 2.
#[derive(Clone, Copy)]
struct Joint {
    id: u8,
    middle: i64,
    stops: Option<(i64, i64)>,
}

/// What the servo reports with its horn at `actual` ticks and `offset` applied.
fn corrected(protocol: &str, actual: i64, offset: i64) -> i64 {
    match protocol {
        // STS3215: present = actual - offset, on a single-turn encoder.
        "sts" => (actual - offset).rem_euclid(4096),
        // Dynamixel X: present = actual + offset.
        _ => actual + offset,
    }
}

/// The calibration a correct run must produce from what the hand did: LeRobot's half-turn
/// offsets and the stops in the offset-corrected frame (a joint without stops is full-turn).
fn expected(protocol: &str, joints: &[Joint]) -> Vec<MotorCalibration> {
    joints
        .iter()
        .map(|j| {
            let homing_offset = if protocol == "sts" { j.middle - 2047 } else { 2047 - j.middle };
            let (range_min, range_max) = match j.stops {
                Some((lo, hi)) => (corrected(protocol, lo, homing_offset), corrected(protocol, hi, homing_offset)),
                None => (0, 4095),
            };
            MotorCalibration {
                id: j.id,
                drive_mode: 0,
                homing_offset: homing_offset as i32,
                range_min: range_min as i32,
                range_max: range_max as i32,
            }
        })
        .collect()
}

/// Runs `armctl calibrate --bus PATH --protocol PROTOCOL ARGS` to the end, the hand moving
/// `joints` (the gripper last) as a person does: the middles held in step 1, each swept joint
/// from its middle to one stop, to the other and back in step 2. Its stdout lines.
fn by_hand(sim: &mut Process, path: &str, protocol: &str, args: &[&str], joints: &[Joint]) -> Vec<String> {
    let mut all = vec!["calibrate", "--bus", path, "--protocol", protocol];
    all.extend(args);
    let mut cal = Process::spawn(&all);
    cal.until("step 1 of 2: move the arm to the middle of its range");
    cal.send("");
    cal.until("step 2 of 2: move every joint");
    // Each swept joint from its middle to one stop, to the other, and back to the middle (the
    // full-turn wrist roll is not swept: it gets the whole turn).
    let swept: Vec<&Joint> = joints.iter().filter(|j| j.stops.is_some()).collect();
    let leg = |from: fn(&Joint) -> i64, to: fn(&Joint) -> i64, seconds: f64| -> Vec<String> {
        swept.iter().map(|j| format!("sweep {} {} {} {seconds}", j.id, from(j), to(j))).collect()
    };
    // The hand rests a moment at each stop, as a person's does: a move counts as done after one
    // read of the position there, and on a loaded machine that read's reply can come too late
    // for the calibration, which would then miss the stop by the ticks of the next move.
    let stop0: fn(&Joint) -> i64 = |j| j.stops.unwrap().0;
    let stop1: fn(&Joint) -> i64 = |j| j.stops.unwrap().1;
    hand(sim, &leg(|j| j.middle, stop0, 0.25), &mut cal);
    hand(sim, &leg(stop0, stop0, 0.1), &mut cal);
    hand(sim, &leg(stop0, stop1, 0.25), &mut cal);
    hand(sim, &leg(stop1, stop1, 0.1), &mut cal);
    hand(sim, &leg(stop1, |j| j.middle, 0.25), &mut cal);
    cal.send("");
    let (code, err) = cal.finish();
    assert_eq!(code, 0, "stdout {:?}\nstderr {err}", cal.seen);
    assert!(cal.seen.iter().any(|l| l.starts_with("wrote ")), "{:?}", cal.seen);
    std::mem::take(&mut cal.seen)
}

/// Calibrates `arm` over the simulator with the hand's `joints` (the gripper last), then checks
/// everything the calibration wrote.
fn calibrate_end_to_end(arm: &str, protocol: &str, joints: &[Joint]) {
    let dir = temp_dir(arm);
    let toml = dir.path().join("my-arm.toml");
    let json = dir.path().join("my-arm.json");
    let start: Vec<(u8, i64)> = joints.iter().map(|j| (j.id, j.middle)).collect();
    let (mut sim, path) = simulator(arm, &start);
    let args = ["--arm", arm, "--out", toml.to_str().unwrap(), "--lerobot-json", json.to_str().unwrap()];
    by_hand(&mut sim, &path, protocol, &args, joints);
    let want = expected(protocol, joints);

    // The servos hold the offsets and limits.
    for m in &want {
        let held = registers(&path, protocol, m.id, &["homing_offset", "min_position_limit", "max_position_limit"]);
        assert_eq!(held, [m.homing_offset, m.range_min, m.range_max].map(i64::from), "servo {}", m.id);
    }

    // LeRobot's file: the motors by name, the values the hand's moves give, LeRobot's text.
    let text = std::fs::read_to_string(&json).unwrap();
    let file = lerobot::parse(&text).unwrap();
    let spec = ArmSpec::load(arm, None).unwrap();
    let mut names: Vec<String> = spec.joints.iter().map(|j| j.name.clone()).collect();
    names.push("gripper".into());
    assert_eq!(file.motors.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>(), names);
    assert_eq!(file.motors.iter().map(|(_, m)| *m).collect::<Vec<_>>(), want);
    assert_eq!(lerobot::to_text(&file), text, "written as LeRobot's json.dump(indent=4) writes it");
    let json_value: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(json_value["gripper"]["range_min"], i64::from(want.last().unwrap().range_min));
    let (code, out, err) = armctl(&[
        "servo",
        "calibration",
        "check",
        "--port",
        &path,
        "--protocol",
        protocol,
        "--baud",
        BAUD,
        "--file",
        json.to_str().unwrap(),
    ]);
    assert_eq!(
        (code, out.trim()),
        (0, format!("calibration matches the servos ({} motors)", want.len()).as_str()),
        "{err}"
    );

    // The arm file: the same joints, the calibration, the gripper's range, and each joint's limits
    // the tighter of the arm's and the measured range (centred on the joint's zero, LeRobot's
    // degree mode: (max - min) / 2 * 360 / 4095 degrees a side) less the margin.
    let file_arm = ArmSpec::load(toml.to_str().unwrap(), None).unwrap_or_else(|e| panic!("{e:#}"));
    assert_eq!(file_arm.joints.len(), spec.joints.len());
    let servos = file_arm.servos.as_ref().expect("[servos]");
    let n = spec.joints.len();
    assert_eq!(servos.calibration.as_deref(), Some(&want[..n]));
    let gripper = servos.gripper.expect("[gripper]");
    assert_eq!((gripper.id, gripper.closed, gripper.open), (want[n].id, want[n].range_min, want[n].range_max));
    let margin = 2f64.to_radians();
    assert_eq!(record::STOP_MARGIN_DEG, 2.0);
    for ((before, after), m) in spec.joints.iter().zip(&file_arm.joints).zip(&want) {
        let half = f64::from(m.range_max - m.range_min) / 2.0 * std::f64::consts::TAU / 4095.0;
        let lower = before.lower.max(-half + margin);
        let upper = before.upper.min(half - margin);
        assert!(
            (after.lower - lower).abs() < 1e-12 && (after.upper - upper).abs() < 1e-12,
            "{}: {after:?}",
            before.name
        );
        assert_eq!((after.origin.translation, after.axis), (before.origin.translation, before.axis), "{}", before.name);
        assert!((after.origin.rotation - before.origin.rotation).amax() < 1e-12, "{}", before.name);
    }

    // Driving the arm from the file: connecting finds the calibration on the servos, and the joints
    // read LeRobot's degree mode of where the hand left them (the middles held in step 1, 2047).
    for args in [vec!["--arm", toml.to_str().unwrap()], vec!["--arm", arm, "--calibration", json.to_str().unwrap()]] {
        let mut all = vec!["--bus", path.as_str(), "--protocol", protocol];
        all.extend(args);
        all.extend(["status", "--json"]);
        let (code, out, err) = armctl(&all);
        assert_eq!(code, 0, "{all:?}: {err}");
        assert!(!err.contains("does not hold the calibration"), "{err}");
        let status: Value = serde_json::from_str(out.lines().last().unwrap()).unwrap();
        assert_eq!(status["state"], "TorqueOff");
        for (j, m) in want[..n].iter().enumerate() {
            let mid = f64::from(m.range_min + m.range_max) / 2.0;
            let angle = (2047.0 - mid) * std::f64::consts::TAU / 4095.0;
            let measured = status["measured"][j].as_f64().unwrap();
            assert!((measured - angle).abs() < 1e-5, "joint {j}: {measured} vs {angle}");
        }
    }
    drop(sim);
}

/// The SO-101 (STS3215, ids 1 to 5, gripper 6): every horn far from the servo's middle, one range
/// across the encoder's 0/4095 point (the shoulder pan's stops at 1800 and, past a whole turn,
/// 4100), the wrist roll full-turn.
#[test]
fn an_so101_is_calibrated_over_the_simulator() {
    let joints = [
        Joint { id: 1, middle: 3000, stops: Some((1800, 4100)) },
        Joint { id: 2, middle: 1100, stops: Some((300, 1900)) },
        Joint { id: 3, middle: 2900, stops: Some((2000, 3800)) },
        Joint { id: 4, middle: 1500, stops: Some((700, 2300)) },
        Joint { id: 5, middle: 600, stops: None },
        Joint { id: 6, middle: 2600, stops: Some((2200, 3400)) },
    ];
    calibrate_end_to_end("so101", "sts", &joints);
}

/// The OpenManipulator-X (XM430-W350, ids 11 to 14, gripper 15): its horns within 1024 ticks of
/// the servo's middle, the most a Dynamixel X applies in position control mode.
#[test]
fn an_open_manipulator_x_is_calibrated_over_the_simulator() {
    let joints = [
        Joint { id: 11, middle: 2600, stops: Some((1800, 3400)) },
        Joint { id: 12, middle: 1500, stops: Some((800, 2300)) },
        Joint { id: 13, middle: 3000, stops: Some((2500, 3500)) },
        Joint { id: 14, middle: 1100, stops: Some((400, 1800)) },
        Joint { id: 15, middle: 2048, stops: Some((1700, 2900)) },
    ];
    calibrate_end_to_end("open-manipulator-x", "dxl2", &joints);
}

/// Starts `armctl calibrate` of the SO-101 on `path`, writing into `dir`.
fn so101_calibration(path: &str, dir: &std::path::Path) -> Process {
    let toml = dir.join("my.toml");
    let json = dir.join("my.json");
    Process::spawn(&[
        "calibrate",
        "--bus",
        path,
        "--protocol",
        "sts",
        "--arm",
        "so101",
        "--out",
        toml.to_str().unwrap(),
        "--lerobot-json",
        json.to_str().unwrap(),
    ])
}

fn one_error_line(err: &str, needles: &[&str]) {
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "one line: {err}");
    assert!(lines[0].starts_with("error: "), "{err}");
    for needle in needles {
        assert!(lines[0].contains(needle), "{needle:?} not in {err}");
    }
}

/// Input that ends before step 1, or during step 2, and a joint that was not moved: one error
/// line each, and nothing further written (no file; the servos as the message says).
#[test]
fn bad_input_stops_the_calibration_with_one_line_and_writes_nothing_further() {
    let dir = temp_dir("bad-input");
    let (mut sim, path) = simulator("so101", &[(1, 3000), (2, 1100)]);
    let nothing_written = || {
        assert!(!dir.path().join("my.toml").exists() && !dir.path().join("my.json").exists(), "no file is written");
    };

    let mut cal = so101_calibration(&path, dir.path());
    cal.until("step 1 of 2");
    let (code, err) = cal.finish();
    assert_eq!(code, 1);
    one_error_line(&err, &["standard input ended before step 1", "nothing was calibrated", "torque is off"]);
    assert_eq!(registers(&path, "sts", 1, &["homing_offset", "max_position_limit"]), [0, 4095]);
    nothing_written();

    let mut cal = so101_calibration(&path, dir.path());
    cal.until("step 1 of 2");
    cal.send("");
    cal.until("step 2 of 2");
    let (code, err) = cal.finish();
    assert_eq!(code, 1);
    one_error_line(&err, &["standard input ended during step 2", "the homing offsets are written", "no file"]);
    assert_eq!(registers(&path, "sts", 1, &["homing_offset"]), [953]);
    nothing_written();

    // Every joint but the elbow (servo 3) is moved.
    let mut cal = so101_calibration(&path, dir.path());
    cal.until("step 1 of 2");
    cal.send("");
    cal.until("step 2 of 2");
    let moved = [(1, 3000), (2, 1100), (4, 2048), (6, 2048)];
    hand(&mut sim, &moved.map(|(id, m)| format!("sweep {id} {m} {} 0.1", m - 500)), &mut cal);
    hand(&mut sim, &moved.map(|(id, m)| format!("sweep {id} {} {} 0.1", m - 500, m + 500)), &mut cal);
    cal.send("");
    let (code, err) = cal.finish();
    assert_eq!(code, 1);
    one_error_line(
        &err,
        &["joint 3 (elbow_flex, servo 3) moved only 0 ticks (2047..2047)", "not moved through its range", "no file"],
    );
    assert_eq!(
        registers(&path, "sts", 1, &["min_position_limit", "max_position_limit"]),
        [0, 4095],
        "no limit written"
    );
    nothing_written();
    drop(sim);
}

/// A horn a half turn from the servo's middle needs an offset the STS3215 cannot hold (LeRobot's
/// "Magnitude ... exceeds 2047"): refused naming the servo, its registers put back as they were.
#[test]
fn an_offset_beyond_the_servos_reach_is_refused_and_the_registers_restored() {
    let dir = temp_dir("offset");
    let (_sim, path) = simulator("so101", &[(1, 4095)]);
    for (addr, value) in [("31", "-3"), ("11", "4000")] {
        let (code, _, err) = armctl(&[
            "servo",
            "write",
            "--port",
            &path,
            "--protocol",
            "sts",
            "--id",
            "1",
            "--addr",
            addr,
            "--value",
            value,
        ]);
        assert_eq!(code, 0, "{err}");
    }
    let mut cal = so101_calibration(&path, dir.path());
    cal.until("step 1 of 2");
    cal.send("");
    let (code, err) = cal.finish();
    assert_eq!(code, 1);
    one_error_line(
        &err,
        &["joint 1 (shoulder_pan, servo 1): homing offset 2048: magnitude exceeds 2047", "as they were"],
    );
    assert_eq!(
        registers(&path, "sts", 1, &["homing_offset", "min_position_limit", "max_position_limit"]),
        [-3, 0, 4000]
    );
    assert!(!dir.path().join("my.toml").exists());
}

/// Arguments refused before any port is opened, and an arm file whose calibration has a range
/// of zero width: one line naming the line and key.
#[test]
fn bad_arguments_and_a_zero_width_range_in_the_arm_file_are_one_line() {
    let dir = temp_dir("arguments");
    let out = dir.path().join("x.toml");
    let out = out.to_str().unwrap();
    for (args, needle) in [
        (
            vec!["--bus", "/dev/no-such-port", "--protocol", "sts", "--arm", "so101", "--out", out],
            "/dev/no-such-port: no such serial port",
        ),
        (
            vec!["--bus", "/dev/no-such-port", "--protocol", "sts", "--arm", "ur5e", "--out", out],
            "arm ur5e has no servos to calibrate",
        ),
        (
            vec!["--bus", "/dev/no-such-port", "--protocol", "dxl2", "--arm", "so101", "--out", out],
            "--protocol dxl2 does not speak to them",
        ),
        (
            vec!["--bus", "/dev/no-such-port", "--protocol", "sts", "--arm", "so101", "--out", "x.json"],
            "must end in .toml",
        ),
    ] {
        let mut all = vec!["calibrate"];
        all.extend(args);
        let (code, _, err) = armctl(&all);
        assert_eq!(code, 1, "{all:?}");
        one_error_line(&err, &[needle]);
    }
    let spec = ArmSpec::load("so101", None).unwrap();
    let mut servos = armctl::arm::servos::ServoSetup::for_arm("so101").unwrap();
    servos.calibration = Some(
        (1..=5)
            .map(|id| MotorCalibration { id, drive_mode: 0, homing_offset: 0, range_min: 1000, range_max: 3000 })
            .collect(),
    );
    let text = armctl::arm::toml_writer::to_text(&ArmSpec { servos: Some(servos), ..spec }, &[]);
    let bad = text.replace("range_max = [3000, 3000, 3000", "range_max = [3000, 3000, 1000");
    assert_ne!(bad, text);
    let path = dir.path().join("zero.toml");
    std::fs::write(&path, &bad).unwrap();
    let line = bad.lines().position(|l| l.starts_with("range_max")).unwrap() + 1;
    let (code, _, err) = armctl(&["fk", "--arm", path.to_str().unwrap(), "--q", "0,0,0,0,0"]);
    assert_eq!(code, 1);
    one_error_line(
        &err,
        &[&format!("line {line}, column 13: [servos] range_max: joint 3 (elbow_flex): range_min and range_max are both 1000: a range of zero width")],
    );
}

/// A person's arm file for the SO-101's servos: a DH table in degrees, comments on every table
/// and on the keys a calibration sets, the gripper's range to be measured.
const PERSONS_ARM: &str = r#"# My SO-101 clone, measured with calipers: standard DH, degrees.
name = "my-so101"
convention = "dh"
angles = "degrees"   # alpha, theta and the limits

[[joint]]
name = "shoulder_pan"
type = "revolute"
a = 0
alpha = 90           # the shoulder's axis lies flat
d = 0.0624
limits = [-110, 110]

[[joint]]
name = "shoulder_lift"
type = "revolute"
a = 0.1159
alpha = 0
d = 0
theta = 75.96        # the upper arm's bend
limits = [-100, 100]

[[joint]]
name = "elbow_flex"
type = "revolute"
a = 0.1350
alpha = 0
d = 0
limits = [-96.8, 96.8]

[[joint]]
name = "wrist_flex"
type = "revolute"
a = 0
alpha = 90
d = 0
limits = [-95, 95]

[[joint]]
name = "wrist_roll"
type = "revolute"
a = 0
alpha = 0
d = 0.0601
limits = [-157, 157]  # the cable stops it

[tool]                # between the jaws
xyz = [0, 0, 0.098]

# Feetech STS3215s, as the kit comes.
[servos]
model = "STS3215"
ids = [1, 2, 3, 4, 5]   # base first
max_velocity = 1.5      # rad/s: slow while I learn
max_acceleration = 6.0  # rad/s²

[gripper]
id = 6
closed = 2000   # a guess until calibrated
open = 3000
opening_mm = 90 # measured
"#;

/// `armctl calibrate --arm my.toml --out my.toml` on a person's arm file: only the servos'
/// calibration keys and the gripper's range change (the rest compared byte for byte, comments,
/// degrees and DH table included); the file loads as the same arm with the new calibration, its
/// limits (degrees in the file) tightened to the measured ranges; calibrating again writes the
/// same file.
#[test]
fn a_persons_arm_file_gets_the_calibration_and_keeps_everything_else() {
    let joints = [
        Joint { id: 1, middle: 3000, stops: Some((1800, 4100)) },
        Joint { id: 2, middle: 1100, stops: Some((300, 1900)) },
        Joint { id: 3, middle: 2900, stops: Some((2000, 3800)) },
        Joint { id: 4, middle: 1500, stops: Some((700, 2300)) },
        Joint { id: 5, middle: 600, stops: None },
        Joint { id: 6, middle: 2600, stops: Some((2200, 3400)) },
    ];
    let want = expected("sts", &joints);
    let dir = temp_dir("persons-file");
    let file = dir.path().join("my.toml");
    std::fs::write(&file, PERSONS_ARM).unwrap();
    let before = ArmSpec::load(file.to_str().unwrap(), None).unwrap();
    let start: Vec<(u8, i64)> = joints.iter().map(|j| (j.id, j.middle)).collect();
    let (mut sim, path) = simulator("so101", &start);
    let args = ["--arm", file.to_str().unwrap(), "--out", file.to_str().unwrap()];
    let seen = by_hand(&mut sim, &path, "sts", &args, &joints);
    assert!(
        seen.iter().any(|l| l.contains("(its servos' calibration and gripper range; the rest as it was)")),
        "{seen:?}"
    );

    let list =
        |f: fn(&MotorCalibration) -> i32| want[..5].iter().map(|m| f(m).to_string()).collect::<Vec<_>>().join(", ");
    let calibration = format!(
        "homing_offset = [{}]\nrange_min = [{}]\nrange_max = [{}]\n",
        list(|m| m.homing_offset),
        list(|m| m.range_min),
        list(|m| m.range_max)
    );
    let g = want[5];
    let expected_text = PERSONS_ARM
        .replace("max_acceleration = 6.0  # rad/s²\n", &format!("max_acceleration = 6.0  # rad/s²\n{calibration}"))
        .replace("closed = 2000   # a guess", &format!("closed = {}   # a guess", g.range_min))
        .replace("open = 3000\n", &format!("open = {}\n", g.range_max));
    let text = std::fs::read_to_string(&file).unwrap();
    assert_eq!(text, expected_text);

    // The same arm, the new calibration, the limits the file's tightened to the measured ranges.
    let after = ArmSpec::load(file.to_str().unwrap(), None).unwrap_or_else(|e| panic!("{e:#}"));
    assert_eq!(after.tool, before.tool);
    let servos = after.servos.as_ref().unwrap();
    assert_eq!(servos.calibration.as_deref(), Some(&want[..5]));
    assert_eq!(servos.gripper.map(|g| (g.id, g.closed, g.open)), Some((6, g.range_min, g.range_max)));
    let old = before.servos.as_ref().unwrap();
    assert_eq!((servos.max_velocity, servos.max_acceleration, &servos.ids), (1.5, 6.0, &old.ids));
    for ((b, a), m) in before.joints.iter().zip(&after.joints).zip(&want) {
        assert_eq!((&a.name, a.kind, a.origin, a.axis), (&b.name, b.kind, b.origin, b.axis));
        let (lower, upper) = record::joint_limits(b, m, 4096).unwrap();
        assert_eq!((a.lower, a.upper), (lower, upper), "{}", a.name);
    }
    assert!(after.joints[0].upper < 110f64.to_radians(), "the pan's range was tightened");
    let (code, _, err) = armctl(&["--bus", &path, "--protocol", "sts", "--arm", file.to_str().unwrap(), "status"]);
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("does not hold the calibration"), "{err}");

    // Again, from the preset this time (the same joints and servos: the same arm), into the same
    // file: the same text.
    let args = ["--arm", "so101", "--out", file.to_str().unwrap()];
    by_hand(&mut sim, &path, "sts", &args, &joints);
    assert_eq!(std::fs::read_to_string(&file).unwrap(), expected_text, "calibrating again changes nothing");
    drop(sim);
}

/// An existing `--out` that is not an arm file of the arm being calibrated is refused with one
/// line before the port is opened (the port does not even exist), and left as it was.
#[test]
fn an_out_that_is_not_this_arms_file_is_refused_and_left_alone() {
    let dir = temp_dir("refused-out");
    let other = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/examples/arms/six-dof.toml")).unwrap();
    for (name, text, arm, needle) in [
        (
            "robot.toml",
            "<?xml version=\"1.0\"?>\n<robot name=\"so101\"></robot>\n".to_string(),
            "so101",
            "it is a URDF (XML), not an arm file (TOML)",
        ),
        (
            "broken.toml",
            PERSONS_ARM.replace("[servos]", "[servos"),
            "so101",
            "it is not an arm file armctl reads (line",
        ),
        ("cargo.toml", "[package]\nname = \"x\"\n".to_string(), "so101", "unknown field `package`"),
        ("other.toml", other, "so101", "it is another arm: "),
        (
            "omx.toml",
            PERSONS_ARM.to_string(),
            "open-manipulator-x",
            "it is another arm: my-so101 has joints shoulder_pan",
        ),
    ] {
        let out = dir.path().join(name);
        std::fs::write(&out, &text).unwrap();
        let protocol = if arm == "so101" { "sts" } else { "dxl2" };
        let (code, stdout, err) = armctl(&[
            "calibrate",
            "--bus",
            "/dev/no-such-port",
            "--protocol",
            protocol,
            "--arm",
            arm,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!((code, stdout.as_str()), (1, ""), "{name}: {err}");
        one_error_line(
            &err,
            &[&format!("--out {} exists and is not written over: ", out.display()), needle, "nothing was written"],
        );
        assert_eq!(std::fs::read_to_string(&out).unwrap(), text, "{name} is unchanged");
    }
}
