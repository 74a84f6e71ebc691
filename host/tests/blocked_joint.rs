//! A joint that ends its move far from its setpoint fails the move by name, and is held where it
//! stands (`armctl::commands::drive::blocked`); random moves on physical servos carrying 200 g
//! never fail that way.

mod support;

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
