//! `armctl teleop` end to end, with both arms simulated in real time: the leader is SO-101 servos
//! on a pseudo-terminal turned by a scripted hand (`--leader sim`), read through the port by sync
//! read at 1 Mbps behind a USB adapter's 1 ms latency timer; the follower (`--sim`) is the
//! firmware core on this PC driving simulated servos on another pty, also at 1 Mbps with 1 ms,
//! whose safety monitor checks every goal against the arm's limits.
//!
//! The script moves every joint and the trigger, then jumps (0.7 rad on the base in 20 ms): the
//! follower must follow within its speed limit, with no goal outside its limits, and end where
//! the leader ends. The loop's rate and latency are reported, not asserted (the machines are
//! shared): docs/teleoperation.md gives them as measured by the same command.

use serde_json::Value;
use std::path::Path;
mod support;

use support::armctl;

/// The leader's path: joints of the SO-101 (rad) and its trigger (percent).
const SCRIPT: &str = "t,q1,q2,q3,q4,q5,gripper
0,0,0,0,0,0,50
0.8,0.3,-0.2,0.3,0.2,0.1,80
1.6,-0.3,0.2,0.5,-0.2,-0.1,20
1.62,0.4,0.2,0.5,-0.2,-0.1,20
2.6,0.1,-0.1,0.2,0.1,0.05,60
";
/// Where the script ends.
const END: [f64; 5] = [0.1, -0.1, 0.2, 0.1, 0.05];

/// `name` in a folder of its own, removed when dropped (also when the test fails).
fn scratch(name: &str) -> support::TempPath {
    support::TempPath::new(name)
}

fn script() -> support::TempPath {
    let path = scratch("leader.csv");
    std::fs::write(&path, SCRIPT).unwrap();
    path
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn a_leader_drives_the_follower_through_the_firmware_within_its_limits() {
    let script = script();
    let record = scratch("session.csv");
    let run = armctl(&[
        "--sim",
        "teleop",
        "--leader",
        "sim",
        "--leader-script",
        s(&script),
        "--record",
        s(&record),
        "--json",
    ]);
    assert_eq!(run.code, 0, "stderr: {}", run.stderr);
    let report: Value = serde_json::from_str(run.stdout.trim()).unwrap_or_else(|e| panic!("{e}: {}", run.stdout));
    eprintln!("{report}");
    let number = |path: &[&str]| {
        path.iter().fold(&report, |v, k| &v[*k]).as_f64().unwrap_or_else(|| panic!("{path:?} in {report}"))
    };
    // The script lasts 2.6 s and the session 0.2 s more, at 100 keyframes per second: however
    // loaded the machine, most slots run (a late slot is skipped, not made up).
    let keyframes = number(&["keyframes"]);
    assert!((140.0..=290.0).contains(&keyframes), "{keyframes} keyframes");
    assert_eq!(number(&["monitor", "violations"]), 0.0, "safety monitor: {report}");
    assert!(number(&["monitor", "goals"]) > 500.0, "{report}");
    // The jump of 0.7 rad was followed at the speed limit: clamped, never beyond.
    assert!(number(&["clamped_steps"]) >= 10.0, "{report}");
    assert!(number(&["monitor", "max_step_ratio"]) <= 1.0, "{report}");
    // Half the time the follower's goal is within 0.02 rad of the leader one lead earlier (the
    // script moves at most 0.75 rad/s outside the jump, 0.0075 rad per period).
    assert!(number(&["tracking_rad", "p50"]) <= 0.02, "{report}");
    // It ends where the leader ends (servo ticks are 1.5 mrad; the servos settle within a few).
    let rest: Vec<f64> = report["follower_at_rest"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    for (j, (got, want)) in rest.iter().zip(END).enumerate() {
        assert!((got - want).abs() <= 0.01, "joint {}: at rest at {got}, the leader ended at {want}", j + 1);
    }

    // The recording replays with `armctl play`.
    let text = std::fs::read_to_string(&record).unwrap();
    assert!(text.starts_with("t,q1,q2,q3,q4,q5,gripper\n"), "{}", &text[..60.min(text.len())]);
    let replay = armctl(&["--sim", "play", s(&record), "--json"]);
    assert_eq!(replay.code, 0, "replay: {}", replay.stderr);
}

/// A leader pushed past the follower's limits, both ways: the follower is held at each end of its
/// commanded range, and the recording reads back exactly what was sent, the ends included (to six
/// decimals, an end could be written just beyond the range, and a replay then refused).
#[test]
fn a_recording_at_the_limits_reads_back_as_sent() {
    let script = scratch("past-the-limits.csv");
    std::fs::write(&script, "t,q1,q2,q3,q4,q5\n0,0,0,0,0,0\n1.2,2.9,2.9,2.9,2.9,2.9\n2,2.9,2.9,2.9,2.9,2.9\n3.8,-2.9,-2.9,-2.9,-2.9,-2.9\n6,-2.9,-2.9,-2.9,-2.9,-2.9\n")
        .unwrap();
    let record = scratch("at-the-limits.csv");
    // Every joint at its limit, both ways, is a pose the SO-101 collides in (its lower arm in its
    // base, its gripper in the table): the follower's collision check is off here, so that the
    // limits are what holds the recording (the simulated servos still stall at the contacts).
    let (sim, unchecked) = ("--sim", "--no-collision-check");
    let run =
        armctl(&[sim, unchecked, "teleop", "--leader", "sim", "--leader-script", s(&script), "--record", s(&record)]);
    assert_eq!(run.code, 0, "stderr: {}", run.stderr);
    let arm = armctl::arm::ArmSpec::load("so101", None).unwrap();
    let servos = armctl::arm::servos::ServoSetup::for_arm("so101").unwrap();
    let keyframes = armctl::motion::trajectory::read_keyframes(&record).unwrap_or_else(|e| panic!("{e:#}"));
    for j in 0..5 {
        // The range the firmware holds (f32) within the arm's limits (f64), which `play` checks.
        let (lo, hi) = servos.commanded_range(&arm, j).unwrap();
        let (lo, hi) = (f64::from(lo).max(arm.joints[j].lower), f64::from(hi).min(arm.joints[j].upper));
        let values: Vec<f64> = keyframes.positions.iter().map(|q| q[j]).collect();
        assert!(values.iter().all(|v| (lo..=hi).contains(v)), "joint {}: a value outside {lo}..={hi}", j + 1);
        let (min, max) = values.iter().fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        assert_eq!((min, max), (lo, hi), "joint {}: held at each end, written exactly", j + 1);
    }
    // The replay is taken (no value refused as out of range) and played into the same contacts:
    // the simulated servos stall there, so it ends with a joint held short of its setpoint, which
    // `play` names (commands::drive::blocked). Nothing else may fail it.
    let replay = armctl(&[sim, unchecked, "play", s(&record)]);
    let blocked = replay.code == 1 && replay.stderr.contains("short of its setpoint");
    assert!(replay.code == 0 || blocked, "replay: {}", replay.stderr);
}

/// Bad input is one line on stderr and nothing starts: no script for a simulated leader, a
/// leader that is not there, an arm with another joint count, a rate out of range.
#[test]
fn bad_input_is_refused_before_anything_moves() {
    let script = script();
    for (args, needle) in [
        (vec!["--sim", "teleop", "--leader", "sim"], "--leader-script"),
        (vec!["--sim", "teleop", "--leader", "/dev/armctl-no-such-port"], "no such serial port"),
        (vec!["--sim", "teleop", "--leader", "sim", "--leader-script", s(&script), "--rate", "0"], "--rate"),
        (vec!["--sim", "teleop", "--leader", "sim", "--leader-script", s(&script), "--lead-ms", "NaN"], "--lead-ms"),
        (
            vec!["--sim", "--arm", "open-manipulator-x", "teleop", "--leader", "sim", "--leader-script", s(&script)],
            "5 joints",
        ),
        (vec!["teleop", "--leader", "sim", "--leader-script", s(&script)], "--sim"),
        (vec!["--sim", "--object-mm", "30", "teleop", "--leader", "sim", "--leader-script", s(&script)], "--object-mm"),
    ] {
        let run = armctl(&args);
        assert_eq!(run.code, 1, "{args:?}: {}", run.stderr);
        assert!(run.stdout.is_empty(), "{args:?}: {}", run.stdout);
        let errors: Vec<&str> = run.stderr.lines().filter(|l| l.starts_with("error:")).collect();
        assert_eq!(errors.len(), 1, "{args:?}: {}", run.stderr);
        assert!(errors[0].contains(needle), "{args:?}: {:?} does not say {needle:?}", errors[0]);
    }
}

/// Ctrl-C mid-session stops the follower within its limits (it holds, torque on) and exits 130,
/// with the figures so far and no goal outside the limits.
#[test]
fn ctrl_c_stops_the_follower() {
    use std::process::{Command, Stdio};
    let script = script();
    let child = Command::new(env!("CARGO_BIN_EXE_armctl"))
        .args(["--sim", "teleop", "--leader", "sim", "--leader-script", s(&script), "--json"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("armctl starts");
    // The set-up (servo set-up, the buses timed) takes about half a second; the script 2.6 s.
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let kill = Command::new("kill").args(["-INT", &child.id().to_string()]).status().expect("kill runs");
    assert!(kill.success());
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8(output.stderr).unwrap();
    assert_eq!(output.status.code(), Some(130), "{stderr}");
    assert!(stderr.lines().any(|l| l.starts_with("stopped by Ctrl-C at") && l.contains("state Idle")), "{stderr}");
    let report: Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(report["monitor"]["violations"], 0, "{report}");
    assert!(report["keyframes"].as_u64().unwrap() > 20, "{report}");
}

/// The right leader's path: the left one's mirrored about the arms' middle plane (base and wrist
/// roll turned the other way).
const MIRRORED: &str = "t,q1,q2,q3,q4,q5,gripper
0,0,0,0,0,0,50
0.8,-0.3,-0.2,0.3,0.2,-0.1,80
1.6,0.3,0.2,0.5,-0.2,0.1,20
1.62,-0.4,0.2,0.5,-0.2,0.1,20
2.6,-0.1,-0.1,0.2,0.1,-0.05,60
";

/// `armctl teleop --rig`: one simulated leader per follower, named in the rig file, both pairs at
/// once; each follower ends where its own leader ends, within its limits. The bases are 0.5 m
/// apart: closer, the mirrored scripts bring the jaws together, and the followers are held apart
/// (the next test).
#[test]
fn a_rig_has_one_leader_per_follower() {
    let dir = scratch("rig");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("left.csv"), SCRIPT).unwrap();
    std::fs::write(dir.join("right.csv"), MIRRORED).unwrap();
    let pair = |name: &str, y: f64| {
        format!(
            "[[arm]]\nname = \"{name}\"\narm = \"so101\"\nsim = true\nxyz = [0.0, {y}, 0.0]\n[arm.leader]\nsim = true\nscript = \"{name}.csv\"\n"
        )
    };
    let rig = dir.join("rig.toml");
    std::fs::write(&rig, format!("name = \"pairs\"\n{}{}", pair("left", 0.25), pair("right", -0.25))).unwrap();
    let run = armctl(&["teleop", "--rig", s(&rig), "--json"]);
    assert_eq!(run.code, 0, "stderr: {}", run.stderr);
    let report: Value = serde_json::from_str(run.stdout.trim()).unwrap_or_else(|e| panic!("{e}: {}", run.stdout));
    eprintln!("{report}");
    let mirrored_end = [-END[0], END[1], END[2], END[3], -END[4]];
    for (name, end) in [("left", END), ("right", mirrored_end)] {
        let arm = &report["arms"][name];
        assert!((140..=290).contains(&arm["keyframes"].as_u64().unwrap()), "{name}: {arm}");
        assert_eq!(arm["monitor"]["violations"], 0, "{name}: {arm}");
        assert!(arm["monitor"]["max_step_ratio"].as_f64().unwrap() <= 1.0, "{name}: {arm}");
        let rest: Vec<f64> = arm["follower_at_rest"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        for (j, (got, want)) in rest.iter().zip(end).enumerate() {
            assert!((got - want).abs() <= 0.01, "{name} joint {}: at rest at {got}, its leader ended at {want}", j + 1);
        }
    }
    // Bad rig input: one line each, nothing starts.
    let leaderless = dir.join("leaderless.toml");
    std::fs::write(&leaderless, "name = \"x\"\n[[arm]]\nname = \"a\"\narm = \"so101\"\nsim = true\n").unwrap();
    for (args, needle) in [
        (vec!["teleop", "--rig", s(&leaderless)], "has no leader"),
        (vec!["teleop", "--rig", s(&rig), "--leader", "sim"], "leader is in the rig file"),
        (vec!["teleop", "--rig", s(&rig), "--record", "x.csv"], "--record with --rig"),
        (vec!["--sim", "teleop", "--rig", s(&rig)], "--sim"),
    ] {
        let run = armctl(&args);
        assert_eq!(run.code, 1, "{args:?}: {}", run.stderr);
        let errors: Vec<&str> = run.stderr.lines().filter(|l| l.starts_with("error:")).collect();
        assert_eq!(errors.len(), 1, "{args:?}: {}", run.stderr);
        assert!(errors[0].contains(needle), "{args:?}: {:?} does not say {needle:?}", errors[0]);
    }
}

/// Each follower of a teleoperated rig is an obstacle for the others: two leaders turned toward
/// each other (the arms stretched out, each base turning toward the other arm), and the readings
/// that would bring the followers within their margin are held back, counted and named; where
/// the followers rest, the test places every body from their measured joints and finds them
/// apart by the margin at least.
#[test]
fn a_rigs_followers_are_held_apart_when_their_leaders_meet() {
    use armctl::arm::collision::edit::geometry_of;
    use kinematics::collision::distance::capsule_capsule;

    let dir = scratch("meet");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("left.csv"),
        "t,q1,q2,q3,q4,q5,gripper\n0,0,0,0,0,0,50\n1.5,0.6,0,0,0,0,50\n2.0,0.6,0,0,0,0,50\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("right.csv"),
        "t,q1,q2,q3,q4,q5,gripper\n0,0,0,0,0,0,50\n1.5,-0.6,0,0,0,0,50\n2.0,-0.6,0,0,0,0,50\n",
    )
    .unwrap();
    let pair = |name: &str, y: f64| {
        format!(
            "[[arm]]\nname = \"{name}\"\narm = \"so101\"\nsim = true\nxyz = [0.0, {y}, 0.0]\n[arm.leader]\nsim = true\nscript = \"{name}.csv\"\n"
        )
    };
    let rig = dir.join("rig.toml");
    std::fs::write(&rig, format!("name = \"meet\"\n{}{}", pair("left", 0.15), pair("right", -0.15))).unwrap();
    let run = armctl(&["teleop", "--rig", s(&rig), "--json"]);
    assert_eq!(run.code, 0, "stderr: {}", run.stderr);
    let report: Value = serde_json::from_str(run.stdout.trim()).unwrap_or_else(|e| panic!("{e}: {}", run.stdout));
    let held: u64 =
        ["left", "right"].iter().map(|n| report["arms"][n]["held_apart"]["readings"].as_u64().unwrap()).sum();
    assert!(held > 0, "no reading was held back: {report}");
    let named =
        ["left", "right"].iter().filter_map(|n| report["arms"][n]["held_apart"]["first"].as_str()).next().unwrap();
    assert!(named.contains("left/") && named.contains("right/") && named.contains("margin"), "{named}");
    assert!(run.stderr.contains("held back"), "{}", run.stderr);
    let so101 = armctl::arm::ArmSpec::load("so101", None).unwrap();
    let model = armctl::arm::dof::build(so101.clone()).unwrap();
    let spec = geometry_of(&so101);
    let mut placed = Vec::new();
    for (name, y) in [("left", 0.15), ("right", -0.15)] {
        let arm = &report["arms"][name];
        assert_eq!(arm["monitor"]["violations"], 0, "{name}: {arm}");
        let q: Vec<f64> = arm["follower_at_rest"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        let frames = model.joint_frames(&q).unwrap();
        let base = kinematics::Pose::from_translation(kinematics::nalgebra::Vector3::new(0.0, y, 0.0));
        let bodies: Vec<_> = spec
            .bodies
            .iter()
            .map(|b| b.capsule.placed(&base.compose(&b.link.map_or(kinematics::Pose::identity(), |l| frames[l]))))
            .collect();
        placed.push(bodies);
    }
    let closest =
        placed[0].iter().flat_map(|a| placed[1].iter().map(move |b| capsule_capsule(a, b))).fold(f64::MAX, f64::min);
    eprintln!("{named}; {held} readings held; at rest {:.1} mm apart", closest * 1e3);
    assert!(closest >= spec.margin, "the followers rest {:.1} mm apart", closest * 1e3);
}
