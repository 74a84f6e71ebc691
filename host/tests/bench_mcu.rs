//! `armctl bench mcu` end to end: the board crate's `opcount` binary built and run under
//! `qemu-system-arm -icount shift=0`, its log read back through the command line. Checks that every
//! operation was counted and that the tick-to-instruction factor holds (the calibration loop of
//! known length comes out within 5 %). The goals are reported by the command, not asserted
//! here: a count over a goal is a finding, not a broken build. Skips with a message where
//! qemu-system-arm is missing, and fails instead when the `CI` variable is set.

use serde_json::Value;

/// Every operation the issues ask for (the `tree_` ones: issue 30, kinematic trees; the
/// `collision_` ones: issue 45, one full collision check; `rnea6`: issue 39, inverse dynamics).
const OPERATIONS: [&str; 15] = [
    "fk6",
    "rnea6",
    "dls_iter",
    "ik_track_1cm",
    "hermite6",
    "hermite6_gripper",
    "tree_fk",
    "tree_jacobian",
    "tree_ik_track_1cm",
    "sync_write6_sts",
    "sync_write6_dxl2",
    "sync_read6_sts",
    "sync_read6_dxl2",
    "collision_so101",
    "collision_24x8",
];

fn qemu_available() -> bool {
    armctl_test_support::needs_qemu(env!("CARGO_TARGET_TMPDIR"), armctl::runtime::qemu::available())
}

#[test]
fn every_operation_is_counted_and_the_calibration_holds() {
    if !qemu_available() {
        return;
    }
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = armctl::cli::main(["armctl", "bench", "mcu", "--json"], &mut out, &mut err);
    let err = String::from_utf8_lossy(&err);
    assert_eq!(code, 0, "armctl bench mcu failed: {err}");
    let report: Value = serde_json::from_slice(&out).unwrap_or_else(|e| panic!("not JSON ({e}): {err}"));

    let ratio = report["calibration"]["ratio"].as_f64().unwrap();
    assert!((ratio - 1.0).abs() <= 0.05, "a 10-instruction loop measured {} instructions", report["calibration"]);

    let ops = report["operations"].as_array().unwrap();
    for name in OPERATIONS {
        let op = ops.iter().find(|op| op["name"] == name).unwrap_or_else(|| panic!("{name} was not counted"));
        let instructions = op["instructions"].as_f64().unwrap();
        assert!(instructions > 0.0, "{name}: {instructions} instructions");
        // A collision check is timed only at poses free of contact: at least one must be.
        if name.starts_with("collision_") {
            let poses = op["fields"]["poses"].as_u64().unwrap_or(0);
            assert!(poses > 0, "{name}: no free pose timed: {op}");
        }
        if let Some(goal) = op["goal"].as_u64() {
            eprintln!("{name}: {instructions:.0} instructions (goal {goal})");
        }
    }
}
