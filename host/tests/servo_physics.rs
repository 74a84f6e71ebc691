//! The simulated servos with physics (`--servos physical`, docs/servo-model.md) end to end: the
//! `armctl` binary with `--sim`, where the SO-101's servos carry its links under gravity.

mod support;

use serde_json::Value;
use support::{armctl, assert_fails};

fn numbers(v: &Value) -> Vec<f64> {
    v.as_array().unwrap_or_else(|| panic!("not an array: {v}")).iter().map(|x| x.as_f64().unwrap()).collect()
}

/// A move to the same point on ideal servos, and on physical ones with and without 200 g at the
/// tool, each with the firmware's gravity compensation off and on: the ideal arm arrives (within
/// 1 mm); uncompensated, the physical arm's tool ends below the target by its servos' sag, further
/// with the payload; compensated, it arrives within 2 mm either way. Printed for the manual
/// (`-- --nocapture`).
#[test]
fn gravity_compensation_brings_the_sagging_tool_to_its_target() {
    let target = "0.25,0.05,0.15";
    let mut errors = Vec::new();
    for extra in [
        &["--servos", "ideal"][..],
        &["--servos", "physical", "--gravity-compensation", "off"],
        &["--servos", "physical"],
        &["--servos", "physical", "--payload-kg", "0.2", "--gravity-compensation", "off"],
        &["--servos", "physical", "--payload-kg", "0.2"],
    ] {
        let mut args = vec!["--sim", "--json"];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["move", "--to", target, "--speed", "0.2"]);
        let run = armctl(&args);
        let v = run.json();
        let reached = numbers(&v["reached"]);
        let error = v["error_mm"].as_f64().unwrap();
        eprintln!("{extra:?}: error {error:.2} mm, reached z {:.4} m", reached[2]);
        errors.push((error, reached[2]));
    }
    let [(ideal, _), (sagging, z), (compensated, _), (heavy, z_heavy), (heavy_compensated, _)] = errors[..] else {
        unreachable!()
    };
    assert!(ideal < 1.0, "ideal servos: {ideal} mm");
    assert!(sagging > 2.0 && z < 0.15, "physical servos, uncompensated: {sagging} mm, z {z}");
    assert!(heavy > sagging + 1.0 && z_heavy < z, "with 200 g: {heavy} mm against {sagging} mm");
    assert!(compensated < 2.0, "physical servos, compensated: {compensated} mm");
    assert!(heavy_compensated < 2.0, "with 200 g, compensated: {heavy_compensated} mm");
}

/// Gravity compensation asked of servos that do not sag, or of an arm without masses: one line
/// each, nothing moved.
#[test]
fn gravity_compensation_refuses_what_it_cannot_do() {
    assert_fails(&["--sim", "--gravity-compensation", "on", "joints", "--q", "0,0,0,0,0"], &["--servos physical"]);
    assert_fails(
        &[
            "--sim",
            "--arm",
            "open-manipulator-x",
            "--servos",
            "physical",
            "--gravity-compensation",
            "on",
            "joints",
            "--q",
            "0,0,0,0",
        ],
        &["open-manipulator-x has no masses"],
    );
}

/// A payload without physical servos, one beyond the servos' stall torque, one that is not a
/// mass, servos that are neither kind, and servos asked of a board: each one line, nothing moved.
#[test]
fn bad_servo_options_fail_in_one_line() {
    assert_fails(&["--sim", "--payload-kg", "0.2", "status"], &["physical servos only"]);
    assert_fails(
        &["--sim", "--servos", "physical", "--payload-kg", "3", "status"],
        &["payload of 3 kg", "shoulder_lift", "stall torque"],
    );
    assert_fails(&["--sim", "--servos", "physical", "--payload-kg", "nan", "status"], &["payload"]);
    assert_fails(&["--sim", "--servos", "physical", "--payload-kg", "-1", "status"], &["payload"]);
    assert_fails(&["--sim", "--servos", "sideways", "status"], &["sideways"]);
    assert_fails(&["--port", "/dev/null", "--servos", "physical", "status"], &["need --sim"]);
}

/// `armctl sim servos --servos physical` on a pty, in real time: a client that comes after the line
/// has been quiet for seconds is answered at once (the servos are kept up to date while it is
/// quiet), and the shoulder lift, torque on, sags below the goal it holds with its load reported.
#[test]
fn physical_servos_on_a_pty_answer_after_a_quiet_line_and_sag() {
    let (mut sim, port) =
        support::sim_servos(&["--pty", "--arm", "so101", "--servos", "physical"], std::process::Stdio::null());
    std::thread::sleep(std::time::Duration::from_secs(2));
    let on = armctl(&["servo", "torque", "--port", &port, "--protocol", "sts", "--id", "2", "on"]);
    std::thread::sleep(std::time::Duration::from_secs(1));
    let read = armctl(&[
        "servo",
        "read",
        "--port",
        &port,
        "--protocol",
        "sts",
        "--id",
        "2",
        "--item",
        "present_position,goal_position,present_load",
        "--json",
    ]);
    let _ = sim.kill();
    let _ = sim.wait();
    assert_eq!(on.code, 0, "{}", on.stderr);
    let v = read.json();
    let item = |name: &str| v["items"][name].as_i64();
    let (present, goal, load) = (item("present_position"), item("goal_position"), item("present_load"));
    let (Some(present), Some(goal), Some(load)) = (present, goal, load) else { panic!("{v}") };
    assert!((present - goal).abs() >= 5 && load != 0, "present {present}, goal {goal}, load {load}: {v}");
}
