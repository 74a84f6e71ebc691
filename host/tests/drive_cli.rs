//! Driving an arm end to end: the `armctl` binary with `--sim` (the firmware core and simulated
//! servos in the process, on a virtual clock) for `status`, `torque`, `move`, `joints`, `play`
//! and `stop`; one-line errors for bad input, which never reaches the arm.

use serde_json::Value;
mod support;

use std::process::{Command, Stdio};
use support::{armctl, assert_fails};

fn numbers(v: &Value) -> Vec<f64> {
    v.as_array().unwrap_or_else(|| panic!("not an array: {v}")).iter().map(|x| x.as_f64().unwrap()).collect()
}

fn join(values: &[f64]) -> String {
    values.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(",")
}

fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt()
}

/// SO-101 tool position at `q`, by the host's forward kinematics.
fn fk(q: &[f64]) -> [f64; 3] {
    fk_pose(q).0
}

/// SO-101 tool position and orientation (w, x, y, z) at `q`.
fn fk_pose(q: &[f64]) -> ([f64; 3], [f64; 4]) {
    let arm = armctl::arm::dof::build(armctl::arm::ArmSpec::load("so101", None).unwrap()).unwrap();
    let pose = arm.tool_pose(q).unwrap();
    (pose.translation.into(), pose.quaternion_wxyz())
}

/// A file in the temp directory, removed when dropped (also when the test fails).
struct TempFile(tempfile::TempPath);

impl TempFile {
    fn new(tag: &str, contents: &str) -> Self {
        let prefix = format!("armctl-drive-test-{tag}-");
        let file = tempfile::Builder::new().prefix(&prefix).suffix(".csv").tempfile().unwrap();
        std::fs::write(file.path(), contents).unwrap();
        Self(file.into_temp_path())
    }

    fn path(&self) -> &str {
        self.0.to_str().unwrap()
    }
}

#[test]
fn status_reports_the_controller() {
    let v = armctl(&["--sim", "--json", "status"]).json();
    assert_eq!(v["state"], "TorqueOff", "{v}");
    assert_eq!(v["arm"], "so101");
    assert_eq!(numbers(&v["measured"]).len(), 5);
    assert_eq!(numbers(&v["tool"]).len(), 3);
    assert!(v["free_slots"].as_u64().unwrap() > 0, "{v}");
    // The core in this process has no receive ring or UART: nothing dropped, honestly 0.
    assert_eq!(
        (v["errors"]["link_dropped"].as_u64(), v["errors"]["link_overruns"].as_u64()),
        (Some(0), Some(0)),
        "{v}"
    );
    let run = armctl(&["--sim", "status"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    for field in ["state", "measured", "setpoints", "queue", "ik", "loop", "errors", "link rx"] {
        assert!(run.stdout.lines().any(|l| l.starts_with(field)), "no {field} line in {}", run.stdout);
    }
    assert!(run.stdout.contains("link rx    0 bytes dropped (receive ring full), 0 UART overruns"), "{}", run.stdout);
}

#[test]
fn torque_on_and_off() {
    assert_eq!(armctl(&["--sim", "--json", "torque", "on"]).json()["state"], "Idle");
    assert_eq!(armctl(&["--sim", "--json", "torque", "off"]).json()["state"], "TorqueOff");
    assert_fails(&["--sim", "torque", "sideways"], &["sideways"]);
}

#[test]
fn move_reaches_a_point_within_a_millimetre() {
    let target = fk(&[0.3, -0.4, 0.5, 0.2, 0.0]);
    let run = armctl(&["--sim", "--json", "move", "--to", &join(&target), "--speed", "0.2"]);
    let v = run.json();
    assert!(run.stderr.contains("torque was off"), "{}", run.stderr);
    let reached = numbers(&v["reached"]);
    assert!(distance(&reached, &target) < 1e-3, "{v}");
    assert!(v["error_mm"].as_f64().unwrap() < 1.0, "{v}");
    assert!(v["time_s"].as_f64().unwrap() > 0.0, "{v}");
    assert!(v["orientation_error_deg"].is_null(), "{v}");
    // A full pose.
    let (p, q) = fk_pose(&[0.3, -0.4, 0.5, 0.2, 0.1]);
    let v = armctl(&["--sim", "--json", "move", "--to", &join(&p), "--quat", &join(&q)]).json();
    assert!(v["error_mm"].as_f64().unwrap() < 1.0, "{v}");
    assert!(v["orientation_error_deg"].as_f64().unwrap() < 1.0, "{v}");
    // The human line says the same.
    let run = armctl(&["--sim", "move", "--to", &join(&target), "--duration", "1.5"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(run.stdout.starts_with("move: target") && run.stdout.contains("error"), "{}", run.stdout);
}

#[test]
fn move_refuses_unreachable_and_bad_targets() {
    assert_fails(&["--sim", "move", "--to", "5,0,0"], &["unreachable", "nothing moved"]);
    assert_fails(&["--sim", "move", "--to", "0.2,NaN,0.1"], &["--to", "not a finite number"]);
    assert_fails(&["--sim", "move", "--to", "0.2,0.1"], &["--to", "expected 3"]);
    assert_fails(&["--sim", "move", "--to", "20,0,0"], &["--to", "beyond any desk arm"]);
    assert_fails(&["--sim", "move", "--to", "0.2,0,0.1", "--quat", "1,1,0,0"], &["--quat", "unit quaternion"]);
    assert_fails(&["--sim", "move", "--to", "0.2,0,0.1", "--speed", "-1"], &["--speed"]);
    assert_fails(&["--sim", "move", "--to", "0.2,0,0.1", "--duration", "0"], &["--duration"]);
}

#[test]
fn joints_move() {
    let q = [0.2, -0.3, 0.4, 0.1, -0.2];
    let v = armctl(&["--sim", "--json", "joints", "--q", &join(&q), "--duration", "1"]).json();
    let reached = numbers(&v["reached"]);
    assert!(distance(&reached, &q) < 0.01, "{v}");
    assert!(v["time_s"].as_f64().unwrap() >= 1.0, "{v}");
    assert_fails(&["--sim", "joints", "--q", "0.1,0.2"], &["--q", "2 joint values", "5 joints"]);
    assert_fails(&["--sim", "joints", "--q", "0,0,0,0,9"], &["--q", "joint 5", "outside its limits"]);
    assert_fails(&["--sim", "joints", "--q", "0,x,0,0,0"], &["--q", "value 2"]);
}

#[test]
fn plays_a_joint_keyframe_file() {
    // More keyframes than the queue holds (32), so flow control refills it while playing.
    let mut csv = String::from("t,q1,q2,q3,q4,q5\n");
    // A bump that starts and ends at rest: s = 0.3 sin²(pi u) for u from 0 to 1.
    let bump = |i: u32| 0.3 * (std::f64::consts::PI * f64::from(i) / 79.0).sin().powi(2);
    for i in 0..80 {
        let t = 0.5 + 0.05 * f64::from(i);
        let s = bump(i);
        csv.push_str(&format!("{t},{s},{},{},0.1,{}\n", -s, s * 0.5, s));
    }
    let file = TempFile::new("joints", &csv);
    let run = armctl(&["--sim", "--json", "play", file.path()]);
    let v = run.json();
    assert_eq!(v["format"], "joint");
    assert_eq!(v["keyframes"], 80);
    assert_eq!(v["pushed"], 80);
    // No terminal in the test: one plain progress line, no carriage returns.
    assert!(run.stderr.contains("80/80 keyframes") && !run.stderr.contains('\r'), "{}", run.stderr);
    let end = numbers(&v["joints"]);
    assert!((end[0] - bump(79)).abs() < 0.01 && (end[3] - 0.1).abs() < 0.01, "{v}");
    assert!(v["end_error"].as_f64().unwrap() < 0.01, "{v}");
    assert!(!run.stderr.contains("warning"), "{}", run.stderr);
}

/// A file with the gripper column, longer than the queue: before the start the gripper's track
/// holds one keyframe fewer than the joints' queue (it keeps a slot for where the gripper starts),
/// so filling the queue must stop at the free slots the firmware reports, not at its capacity.
#[test]
fn plays_a_file_with_the_gripper_longer_than_the_queue() {
    let mut csv = String::from("t,q1,q2,q3,q4,q5,gripper\n");
    for i in 1..=60 {
        csv.push_str(&format!("{},0,0,0,0,0,{}\n", 0.05 * f64::from(i), 30.0 + f64::from(i)));
    }
    let file = TempFile::new("gripper", &csv);
    let v = armctl(&["--sim", "--json", "play", file.path()]).json();
    assert_eq!(v["pushed"], 60, "{v}");
}

/// A file longer than the queue whose first keyframe is at time 0 but far from where the arm
/// rests: the firmware shifts the queued keyframes to reach it within the limits, and the ones
/// pushed after them alike, so none is refused as "not later than the previous".
#[test]
fn plays_a_long_file_that_starts_away_from_the_arm() {
    let mut csv = String::from("t,q1,q2,q3,q4,q5\n");
    for i in 0..=40 {
        csv.push_str(&format!("{},{:.4},0,0,0,0\n", 0.1 * f64::from(i), 0.8 * (1.0 - 0.02 * f64::from(i))));
    }
    let file = TempFile::new("far-start", &csv);
    let v = armctl(&["--sim", "--json", "play", file.path()]).json();
    assert_eq!(v["pushed"], 41, "{v}");
    assert!(v["end_error"].as_f64().unwrap() < 0.01, "{v}");
}

#[test]
fn plays_a_cartesian_keyframe_file() {
    let points: Vec<[f64; 3]> = (0..6).map(|i| fk(&[0.1 * f64::from(i), -0.3, 0.4, 0.2, 0.0])).collect();
    let mut csv = String::from("# tool path\nt,x,y,z\n");
    for (i, p) in points.iter().enumerate() {
        csv.push_str(&format!("{},{},{},{}\n", 1.0 + 0.5 * i as f64, p[0], p[1], p[2]));
    }
    let file = TempFile::new("cartesian", &csv);
    let v = armctl(&["--sim", "--json", "play", file.path()]).json();
    assert_eq!(v["format"], "cartesian");
    assert_eq!(v["pushed"], 6);
    assert!(distance(&numbers(&v["tool"]), &points[5]) < 2e-3, "{v}");
}

#[test]
fn plays_a_cartesian_pose_file() {
    let poses: Vec<_> = (0..4).map(|i| fk_pose(&[0.2, -0.3 + 0.1 * f64::from(i), 0.4, 0.2, 0.1])).collect();
    let mut csv = String::from("t,x,y,z,qw,qx,qy,qz\n");
    for (i, (p, q)) in poses.iter().enumerate() {
        csv.push_str(&format!("{},{},{},{},{},{},{},{}\n", 1.0 + i as f64, p[0], p[1], p[2], q[0], q[1], q[2], q[3]));
    }
    let file = TempFile::new("poses", &csv);
    let v = armctl(&["--sim", "--json", "play", file.path()]).json();
    assert_eq!(v["pushed"], 4);
    assert!(distance(&numbers(&v["tool"]), &poses[3].0) < 2e-3, "{v}");
}

/// Ctrl-C during a long move and a long play: the arm is stopped through the link, the command
/// says where, and exits with 130.
#[cfg(unix)]
#[test]
fn ctrl_c_stops_the_arm() {
    let mut long = String::from("t,q1,q2,q3,q4,q5\n");
    for i in 1..=200 {
        long.push_str(&format!("{},{},0.1,0.1,0.1,0.1\n", 100 * i, 0.1 * f64::from(i % 9)));
    }
    let file = TempFile::new("long", &long);
    let runs: [&[&str]; 2] = [
        &["--sim", "joints", "--q", "0.5,-0.5,0.5,0.5,1", "--duration", "80000", "--timeout", "86000"],
        &["--sim", "play", file.path()],
    ];
    for args in runs {
        let child = Command::new(env!("CARGO_BIN_EXE_armctl"))
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("armctl starts");
        // Virtual time runs hundreds of times faster than the wall clock, but these take a day
        // and 5.5 hours of it. Two seconds: `play` checks every segment of its 200 keyframes
        // against the arm's collision geometry before anything moves.
        std::thread::sleep(std::time::Duration::from_millis(2000));
        let kill = Command::new("kill").args(["-INT", &child.id().to_string()]).status().expect("kill runs");
        assert!(kill.success());
        let output = child.wait_with_output().unwrap();
        let stderr = String::from_utf8(output.stderr).unwrap();
        assert_eq!(output.status.code(), Some(130), "{args:?}: {stderr}");
        assert!(stderr.lines().last().unwrap().starts_with("stopped by Ctrl-C at"), "{stderr}");
        assert!(stderr.contains("state Idle"), "{stderr}");
    }
}

#[test]
fn bad_keyframe_files_name_the_line() {
    let cases: [(&str, &[&str]); 7] = [
        ("t,q1,q2,q3,q4,q5\n0,0,0,0,0,0\n1,0,0,x,0,0\n", &["line 3", "column q3"]),
        ("t,q1,q2,q3,q4,q5\n0,0,0,0,0,0\n1,0,0,0,0,9\n", &["line 3", "joint 5", "outside its limits"]),
        ("t,q1,q2\n0,0,0\n1,0.1,0\n", &["line 2", "2 joint values", "5 joints"]),
        ("t,x,y,z\n0,0.2,0,0.1\n0,0.2,0,0.2\n", &["line 3", "not later"]),
        ("t,x,y,z\n0,0.2,0,0.1\n1,0.2,0\n", &["line 3", "3 fields"]),
        ("time,a,b\n0,1,2\n", &["line 1", "header"]),
        ("", &["empty file"]),
    ];
    for (text, needles) in cases {
        let file = TempFile::new("bad", text);
        let mut needles = needles.to_vec();
        needles.push(file.path());
        assert_fails(&["--sim", "play", file.path()], &needles);
    }
    // Unreachable Cartesian keyframes are found on the host before anything is sent, all of
    // them at once, each with how far the closest pose is.
    let file = TempFile::new("far", "t,x,y,z\n0.5,0.2,0,0.1\n1,5,0,0\n2,0.2,0.05,0.1\n3,0,0,3\n");
    assert_fails(
        &["--sim", "play", file.path()],
        &["2 of 4 Cartesian keyframes are unreachable", "line 3 (the closest pose is", "line 5", "nothing moved"],
    );
    assert_fails(&["--sim", "play", "/does/not/exist.csv"], &["/does/not/exist.csv"]);
}

#[test]
fn stop_holds_the_arm() {
    let v = armctl(&["--sim", "--json", "stop"]).json();
    assert_eq!(numbers(&v["joints"]).len(), 5);
}

#[test]
fn the_link_options_are_checked() {
    assert_fails(&["status"], &["--port", "--sim"]);
    assert_fails(&["move", "--to", "0.2,0,0.1"], &["--port", "--sim"]);
    assert_fails(&["--sim", "--port", "/dev/null", "status"], &["--sim"]);
    assert_fails(&["--port", "/dev/does-not-exist", "status"], &["/dev/does-not-exist"]);
    assert_fails(&["--sim", "--arm", "no-such-arm", "status"], &["no-such-arm"]);
    assert_fails(&["--sim", "fk", "--arm", "so101", "--q", "0,0,0,0,0"], &["--sim is not an option of `armctl fk`"]);
    assert_fails(&["--arm", "so101", "status", "--sim", "--arm", "open-manipulator-x"], &["--arm is given twice"]);
    assert_fails(&["--baud", "57600", "status"], &["--baud", "--port"]);
    assert_fails(&["--sim", "--baud", "57600", "status"], &["--baud", "--sim"]);
}

/// The drive options are global: accepted after the command as before it, as clap's global
/// arguments are.
#[test]
fn drive_options_go_before_or_after_the_command() {
    for args in [&["--sim", "status", "--json"][..], &["status", "--sim", "--json"], &["status", "--json", "--sim"]] {
        let v = armctl(args).json();
        assert_eq!(v["arm"], "so101", "{args:?}: {v}");
    }
    let v = armctl(&["status", "--sim", "--arm", "open-manipulator-x", "--json"]).json();
    assert_eq!(v["arm"], "open-manipulator-x", "{v}");
    let run = armctl(&["--sim", "move", "--to", "0.2,0,0.15", "--json"]);
    let v = run.json();
    assert!(v["error_mm"].as_f64().is_some_and(|e| e < 1.0), "{v}");
}

/// The six-joint example arm file (STS3215 servos 1 to 6, gripper 7).
fn six_dof() -> String {
    format!("{}/examples/arms/six-dof.toml", env!("CARGO_MANIFEST_DIR"))
}

/// `--sim --arm FILE`: any arm with a `[servos]` table runs through the firmware core on simulated
/// servos of its model: a 6-joint file reaches a point its own forward kinematics gives, within a
/// millimetre, and closes its gripper on an object; an arm without servos is one line.
#[test]
fn any_arm_file_with_servos_runs_in_simulation() {
    let arm = six_dof();
    let spec = armctl::arm::ArmSpec::load(&arm, None).unwrap();
    let fk = armctl::arm::dof::build(spec).unwrap();
    let p = fk.tool_pose(&[0.4, 0.3, 0.6, 0.0, 0.5, 0.0]).unwrap().translation;
    let target = [p.x, p.y, p.z];
    let v = armctl(&["--sim", "--arm", &arm, "--json", "status"]).json();
    assert_eq!((&v["arm"], v["measured"].as_array().map(Vec::len)), (&"six-dof".into(), Some(6)), "{v}");
    let v = armctl(&["--sim", "--arm", &arm, "--json", "move", "--to", &join(&target)]).json();
    assert!(distance(&numbers(&v["reached"]), &target) < 1e-3, "{v}");
    let v = armctl(&["--sim", "--arm", &arm, "--object-mm", "30", "--json", "gripper", "close"]).json();
    assert_eq!(v["holding"], true, "{v}");
    assert!((v["opening_mm"].as_f64().unwrap() - 30.0).abs() < 0.2, "{v}");
    assert_fails(&["--sim", "--arm", "ur5e", "status"], &["ur5e", "no servos to simulate", "[servos]"]);
}
