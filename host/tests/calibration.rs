//! LeRobot calibrations in use: the firmware's joint mapping for a calibrated servo commands the
//! very ticks LeRobot's degree mode commands for the same joint angle, checked against values
//! Python computed with LeRobot's arithmetic and end to end through `armctl --bus --calibration`
//! on simulated servos.

use std::process::{Command, Stdio};

use armctl::arm::calibration::normalise::ticks_from_degrees;
use armctl::arm::calibration::MotorCalibration;
use armctl::arm::servos::servos_of;
use armctl::arm::ArmSpec;
use armctl::sim::{Faults, PtyServer, SimConfig};
use firmware::bus::mapping::JointMapping;

/// (range_min, range_max, drive_mode, degrees, ticks): LeRobot's `_unnormalize` in degree mode,
/// computed by Python 3 for a 4096-tick servo (`int(deg * 4095 / 360 + (min + max) / 2)`).
const LEROBOT: [(i32, i32, u8, f64, i32); 11] = [
    (758, 3292, 0, -90.0, 1001),
    (758, 3292, 0, -12.34, 1884),
    (758, 3292, 0, 0.0, 2025),
    (758, 3292, 0, 45.5, 2542),
    (893, 3092, 1, -90.0, 968),
    (893, 3092, 1, -12.34, 1852),
    (893, 3092, 1, 45.5, 2510),
    (0, 4095, 0, 0.0, 2047),
    (0, 4095, 0, 0.01, 2047),
    (0, 4095, 0, 179.9, 4093),
    (2019, 3367, 1, 45.5, 3210),
];

#[test]
fn a_calibrated_mapping_commands_lerobots_ticks() {
    for (lo, hi, drive_mode, degrees, want) in LEROBOT {
        // LeRobot's degree mode does not look at drive_mode: neither does the mapping.
        let _ = drive_mode;
        let m = JointMapping::lerobot(1, 4096, lo, hi);
        assert_eq!(m.to_ticks(degrees.to_radians()), Ok(want), "{lo}..={hi} at {degrees} deg");
        // The firmware's setpoints are f32: the same tick from the f32 angle.
        assert_eq!(m.to_ticks(degrees.to_radians() as f32), Ok(want), "{lo}..={hi} at {degrees} deg (f32)");
    }
    // Across the range, against the host's copy of LeRobot's arithmetic (itself checked against
    // Python in armctl-arm), away from the few angles whose exact tick is within 1e-6 of a whole
    // one, where the last bit of the two computations may fall either way.
    let cal = MotorCalibration { id: 1, drive_mode: 1, homing_offset: 0, range_min: 893, range_max: 3092 };
    let m = JointMapping::lerobot(1, 4096, cal.range_min, cal.range_max);
    let mut compared = 0;
    for k in -9000..=9000 {
        let degrees = f64::from(k) * 0.01;
        let exact = degrees * 4095.0 / 360.0 + 1992.5;
        if (exact - exact.round()).abs() < 1e-6 || !(893.0..=3093.0).contains(&exact) {
            continue;
        }
        assert_eq!(
            i64::from(m.to_ticks(degrees.to_radians()).unwrap()),
            ticks_from_degrees(degrees, &cal, 4096),
            "{degrees}"
        );
        compared += 1;
    }
    assert!(compared > 17_000, "{compared}");
    // Beyond the calibrated range: refused, never clamped.
    assert!(m.to_ticks(100f64.to_radians()).is_err());
}

fn armctl(args: &[&str]) -> (i32, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_armctl")).args(args).stdin(Stdio::null()).output().unwrap();
    (o.status.code().unwrap(), String::from_utf8(o.stdout).unwrap(), String::from_utf8(o.stderr).unwrap())
}

/// An SO-101 calibration as LeRobot writes it (odd range sums: half-tick middles; drive_mode 1 on
/// the elbow, which degree mode ignores; a wrist flex that was seen to move only +-48 degrees).
const SO101: &str = r#"{
    "shoulder_pan": {"id": 1, "drive_mode": 0, "homing_offset": -1470, "range_min": 758, "range_max": 3291},
    "shoulder_lift": {"id": 2, "drive_mode": 0, "homing_offset": 157, "range_min": 812, "range_max": 3313},
    "elbow_flex": {"id": 3, "drive_mode": 1, "homing_offset": 1007, "range_min": 893, "range_max": 3092},
    "wrist_flex": {"id": 4, "drive_mode": 0, "homing_offset": -1007, "range_min": 1500, "range_max": 2601},
    "wrist_roll": {"id": 5, "drive_mode": 0, "homing_offset": -1838, "range_min": 0, "range_max": 4095},
    "gripper": {"id": 6, "drive_mode": 0, "homing_offset": 1160, "range_min": 2019, "range_max": 3367}
}"#;

/// `armctl --bus --calibration`: servos that do not hold the calibration are refused when
/// connecting; once they do, the goals they hold after `joints` are LeRobot's ticks for those
/// angles; a target beyond a calibrated range is refused and moves nothing; a calibration that
/// lacks a servo of the arm is one line.
#[test]
fn bus_with_a_lerobot_calibration_drives_the_servos_to_lerobots_ticks() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("my_so101.json");
    std::fs::write(&file, SO101).unwrap();
    let calibration = armctl::arm::calibration::lerobot::read(&file).unwrap();
    let mut spec = ArmSpec::load("so101", None).unwrap();
    let mut servos = servos_of(&spec).unwrap();
    servos.calibrate(&calibration).unwrap();
    spec.servos = Some(servos.clone());
    let server = PtyServer::spawn(SimConfig {
        protocol: servos.model.protocol,
        model: servos.model,
        // The gripper (6) is on the bus too, as on a real SO-101: the arm does not drive it yet.
        ids: (1..=6).collect(),
        baud: 1_000_000,
        faults: Faults::default(),
        duplicates: Vec::new(),
        fixed_baud: false,
        burst: None,
        limits: Some(armctl::sim::monitor::limits_of(&spec).unwrap()),
        world: None,
        physics: None,
    })
    .unwrap();
    // The arm stands in the middle of its calibrated ranges: each horn where the servo, once it
    // holds its homing offset, reports the range's middle (STS3215: present = actual - offset).
    for (_, m) in &calibration.motors {
        server.place(m.id, (i64::from(m.range_min + m.range_max) / 2 + i64::from(m.homing_offset)).rem_euclid(4096));
    }
    let port = server.path();
    let file = file.to_str().unwrap();
    let bus = |args: &[&str]| {
        let mut all = vec!["--bus", port, "--protocol", "sts", "--calibration", file];
        all.extend_from_slice(args);
        armctl(&all)
    };
    // Factory-fresh servos do not hold the calibration: refused when connecting, as LeRobot's
    // is_calibrated would, with the fix; once written, accepted.
    let (code, _, err) = bus(&["status"]);
    assert_eq!(code, 1, "{err}");
    let last = err.lines().last().unwrap();
    assert!(last.contains("servo 1 (joint 1) does not hold the calibration: its homing offset is 0"), "{err}");
    assert!(last.contains("armctl servo calibration write"), "{err}");
    let (code, _, err) =
        armctl(&["servo", "calibration", "write", "--port", port, "--protocol", "sts", "--file", file]);
    assert_eq!(code, 0, "{err}");
    let q = [0.3f64, -0.4, 0.5, 0.2, -0.3];
    let joined = q.iter().map(|x| x.to_string()).collect::<Vec<_>>().join(",");
    let (code, out, err) = bus(&["joints", "--q", &joined, "--json"]);
    assert_eq!(code, 0, "{out}{err}");
    for (j, (&angle, (name, m))) in q.iter().zip(&calibration.motors).enumerate() {
        let (code, out, err) = armctl(&[
            "servo",
            "read",
            "--port",
            port,
            "--protocol",
            "sts",
            "--id",
            &m.id.to_string(),
            "--item",
            "goal_position",
        ]);
        assert_eq!(code, 0, "{err}");
        let goal: i64 = out.lines().last().unwrap().trim_start_matches("goal_position = ").parse().unwrap();
        // The firmware's setpoint is the f32 angle.
        let degrees = f64::from(angle as f32).to_degrees();
        assert_eq!(goal, ticks_from_degrees(degrees, m, 4096), "joint {j} ({name}) at {degrees} deg");
    }
    // The wrist's calibrated range ends 48.4 degrees (0.845 rad) above its middle: 1.2 rad is
    // within the URDF's limits but beyond the calibration, and the firmware refuses it.
    let goals = |id: &str| {
        let (_, out, _) =
            armctl(&["servo", "read", "--port", port, "--protocol", "sts", "--id", id, "--item", "goal_position"]);
        out.lines().last().unwrap().to_string()
    };
    let before = goals("4");
    let (code, _, err) = bus(&["joints", "--q", "0.3,-0.4,0.5,1.2,-0.3"]);
    assert_eq!(code, 1, "{err}");
    assert!(err.lines().last().unwrap().contains("refused"), "{err}");
    assert_eq!(goals("4"), before, "nothing moved");
    // The gripper's servo is checked as the joints' are (issue 29): a file whose gripper entry the
    // servo does not hold (a replaced or reset gripper servo) is refused when connecting, naming
    // it; once written, accepted.
    let regripped = dir.path().join("regripped.json");
    std::fs::write(
        &regripped,
        SO101.replace(
            "\"id\": 6, \"drive_mode\": 0, \"homing_offset\": 1160",
            "\"id\": 6, \"drive_mode\": 0, \"homing_offset\": 1100",
        ),
    )
    .unwrap();
    let regripped = regripped.to_str().unwrap();
    let with = |file: &str| armctl(&["--bus", port, "--protocol", "sts", "--calibration", file, "status"]);
    let (code, _, err) = with(regripped);
    assert_eq!(code, 1, "{err}");
    let last = err.lines().last().unwrap();
    assert!(
        last.contains("servo 6 (gripper) does not hold the calibration: its homing offset is 1160")
            && last.contains("says 1100"),
        "{err}"
    );
    // The calibration registers are EEPROM, written with the torque off (the moves above left it on).
    let (code, _, err) = armctl(&["servo", "torque", "--port", port, "--protocol", "sts", "--id", "all", "off"]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) =
        armctl(&["servo", "calibration", "write", "--port", port, "--protocol", "sts", "--file", regripped]);
    assert_eq!(code, 0, "{err}");
    let (code, out, err) = with(regripped);
    assert_eq!(code, 0, "{out}{err}");
    let missing = dir.path().join("five.json");
    std::fs::write(&missing, SO101.replace("\"id\": 3,", "\"id\": 7,")).unwrap();
    let (code, _, err) =
        armctl(&["--bus", port, "--protocol", "sts", "--calibration", missing.to_str().unwrap(), "status"]);
    assert_eq!(code, 1);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("no motor with id 3"), "{err}");
    let report = server.monitor().unwrap();
    assert_eq!(report.violation_count, 0, "{:?}", report.violations);
}
