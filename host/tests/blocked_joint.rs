//! A joint that ends its move far from its setpoint fails the move by name, and is held where it
//! stands (`armctl::commands::drive::blocked`); random moves on physical servos carrying 200 g
//! never fail that way.

mod support;

use armctl::commands::drive::blocked::BLOCKED_RAD;
use armctl::commands::drive::joints::{joints, JointsRequest};
use armctl::runtime::connection::Place;
use armctl::runtime::driver::Driver;
use armctl::sim::physics::{Payload, ServoKind};
use kinematics::SplitMix64;
use support::armctl;

/// The simulated SO-101 with `servos`, the collision check on or off.
fn open(servos: ServoKind, check: bool) -> Driver {
    let place = Place {
        sim: true,
        arm: Some("so101".into()),
        servos: Some(servos),
        no_collision_check: !check,
        ..Place::default()
    };
    let (target, arm) = place.target_and_arm().unwrap();
    Driver::open(target, arm, &mut std::io::sink()).unwrap()
}

/// Into the table with the check off: the wrist stops on it, the move fails naming it with where
/// it stands and where it was sent, and every setpoint is moved to its joint.
#[test]
fn a_blocked_joint_fails_the_move_by_name_and_is_held_where_it_stands() {
    let run = armctl(&["--sim", "--no-collision-check", "joints", "--q", "0,1.5,1.5,1.5,0"]);
    assert_eq!(run.code, 1, "{}", run.stderr);
    let error = run.stderr.lines().last().unwrap_or_default();
    assert!(
        error.starts_with("error: wrist_flex stopped") && error.contains("short of its setpoint (at "),
        "{}",
        run.stderr
    );
    assert!(error.ends_with("every joint is now held where it stands"), "{error}");

    let mut d = open(ServoKind::Ideal, false);
    let request = JointsRequest::new(vec![0.0, 1.5, 1.5, 1.5, 0.0], None, None, 30.0).unwrap();
    let err = joints(&mut d, &request, &mut std::io::sink()).unwrap_err().to_string();
    assert!(err.starts_with("wrist_flex stopped"), "{err}");
    let status = d.status().unwrap();
    for (m, s) in status.measured.iter().zip(&status.setpoints) {
        assert!((m - s).abs() < 0.02, "held away from where it stands: {:?} {:?}", status.measured, status.setpoints);
    }
}

/// A sphere in the tool's path as the pan turns to 0.5 rad, on neither side of it at the start.
const HIDDEN_SPHERE: &str = "sphere:0.38,-0.095,0.226,0.03";

/// An obstacle the firmware is not told of (`--hidden-obstacle`): the check passes the move, the
/// simulated pan stops on the sphere, and the move fails naming it, on ideal and physical servos,
/// on the drive commands' simulated board and on the core run in real time (teleop, view, Python's
/// streams) with every joint held where it stands. Without `--sim` the option is refused.
#[test]
fn an_obstacle_hidden_from_the_firmware_stops_the_pan_and_fails_the_move_by_name() {
    for servos in ["ideal", "physical"] {
        let run =
            armctl(&["--sim", "--servos", servos, "--hidden-obstacle", HIDDEN_SPHERE, "joints", "--q", "0.5,0,0,0,0"]);
        assert_eq!(run.code, 1, "{servos}: {}", run.stderr);
        let error = run.stderr.lines().last().unwrap_or_default();
        assert!(error.starts_with("error: shoulder_pan stopped"), "{servos}: {}", run.stderr);
        // Stopped on the sphere's near side: between the start and the sphere's centre (0.25 rad).
        let at: f64 = error.split("(at ").nth(1).and_then(|t| t.split(',').next()).unwrap().parse().unwrap();
        assert!(at > 0.02 && at < 0.25, "{servos}: {error}");
    }
    let free = armctl(&["--sim", "--servos", "physical", "joints", "--q", "0.5,0,0,0,0"]);
    assert_eq!(free.code, 0, "without the sphere the same move is made: {}", free.stderr);

    let place = Place {
        sim: true,
        arm: Some("so101".into()),
        servos: Some(ServoKind::Physical(None)),
        hidden_obstacles: vec![HIDDEN_SPHERE.parse().unwrap()],
        ..Place::default()
    };
    let (target, servos) = place.target().unwrap().in_real_time().unwrap();
    let mut d = Driver::open(target, place.arm_name(), &mut std::io::sink()).unwrap();
    let request = JointsRequest::new(vec![0.5, 0.0, 0.0, 0.0, 0.0], None, None, 30.0).unwrap();
    let err = joints(&mut d, &request, &mut std::io::sink()).unwrap_err().to_string();
    assert!(err.starts_with("shoulder_pan stopped"), "{err}");
    // The pan is held where it stopped; the others stand within the bound of their setpoints.
    // Not closer: the simulated contact is rigid, without sliding, so a joint whose motion presses
    // the gripper against the sphere at all is stopped too, wherever it was (docs/collisions.md).
    let status = d.status().unwrap();
    assert!((status.measured[0] - status.setpoints[0]).abs() < 0.02, "{status:?}");
    for (m, s) in status.measured.iter().zip(&status.setpoints) {
        assert!((m - s).abs() < BLOCKED_RAD, "{:?} {:?}", status.measured, status.setpoints);
    }
    drop(d);
    drop(servos);

    let run = armctl(&["--bus", "/dev/null", "--protocol", "sts", "--hidden-obstacle", HIDDEN_SPHERE, "status"]);
    assert_eq!(run.code, 1, "{}", run.stderr);
    assert_eq!(
        run.stderr.trim(),
        "error: --hidden-obstacle puts an obstacle in the simulated world only: it needs --sim"
    );
}

/// Random collision-free joint targets across the SO-101's range, on physical servos with 200 g at
/// the tool: none fails as blocked (`BLOCKED_JOINT_MOVES` of them, 30 by default; the issue's
/// 1000 by the same test). Targets the collision check refuses are counted apart.
#[test]
fn random_moves_on_physical_servos_are_never_taken_for_blocked() {
    let moves: usize = std::env::var("BLOCKED_JOINT_MOVES").ok().and_then(|n| n.parse().ok()).unwrap_or(30);
    let mut d = open(ServoKind::Physical(Some(Payload { kg: 0.2, at: [0.0; 3] })), true);
    let arm = armctl::arm::dof::build(d.arm().clone()).unwrap();
    let mut rng = SplitMix64::new(3939);
    let (mut moved, mut refused, mut blocked, mut worst) = (0, 0, Vec::new(), 0.0f32);
    for _ in 0..moves {
        let q = arm.random_configuration(&mut rng);
        let request = JointsRequest::new(q.clone(), None, None, 30.0).unwrap();
        match joints(&mut d, &request, &mut std::io::sink()) {
            Ok(_) => {
                moved += 1;
                let s = d.status().unwrap();
                let error = s.measured.iter().zip(&s.setpoints).map(|(m, t)| (m - t).abs()).fold(0.0, f32::max);
                worst = worst.max(error);
            }
            Err(e) if e.to_string().contains("short of its setpoint") => blocked.push(format!("{q:.3?}: {e}")),
            Err(_) => refused += 1,
        }
    }
    println!("{moves} random targets: {moved} moved, {refused} refused, {} taken for blocked; largest joint error at rest {worst:.4} rad", blocked.len());
    assert!(blocked.is_empty(), "false stops: {blocked:#?}");
    assert!(moved >= moves / 2, "{moved} of {moves} moved");
}
