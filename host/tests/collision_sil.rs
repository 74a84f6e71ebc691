//! The firmware core's collision check in software in the loop: the simulated SO-101 with its
//! geometry measured from its frames (`CollisionSpec::from_frames`, capsules of 20 mm radius, the
//! table at the base plane, a 10 mm margin), driven by the same operations as `armctl --sim`.
//!
//! Every goal the simulated servos held after each tick (the SIL trace's `goals`, read from the
//! servos, not the firmware's setpoints) is turned back into joint values by the arm's servo
//! mapping and checked here with the f64 scene: no checked pair may come closer than the margin,
//! less the quantisation of a goal to whole ticks (see [`TICK_TOLERANCE`]).
//!
//! The host checks every move first and plans around what is in the way, so the moves that must
//! reach the firmware's check are sent through the session as they are (the link's own requests),
//! past the host's operations; and the simulated servos have no contact of their own here
//! (`SilOptions::contact`), so that what stops the arm is the firmware alone.

use armctl::arm::collision::{collision_of, CollisionSpec, ObstacleSpec};
use armctl::arm::servos::servos_of;
use armctl::arm::ArmSpec;
use armctl::commands::drive::move_to::{move_to, MoveRequest};
use armctl::commands::drive::state::status;
use armctl::runtime::connection::open_sil;
use armctl::runtime::driver::Driver;
use armctl::runtime::sil::{Sil, SilOptions, TraceSample};
use firmware::link::message::{CartesianTarget, CollisionCheck, CollisionPart, Joints, MovePath, Timing};
use kinematics::collision::Shape;
use kinematics::nalgebra::{SVector, Vector3};

/// How much closer than the margin a goal may come by being rounded to whole ticks: the firmware
/// checks its f32 setpoint, the servo gets the nearest tick (half of 2 pi / 4096 rad per joint at
/// most). Each of the five joints moves a point of the arm by at most half a tick times its
/// distance from the joint's axis (under 0.45 m on the SO-101): 5 x 0.77 mrad x 0.45 m = 1.7 mm.
const TICK_TOLERANCE: f64 = 5.0 * (std::f64::consts::PI / 4096.0) * 0.45;

/// The SO-101 with its frames' capsules and the table, and `extra` obstacles.
fn so101(extra: &[ObstacleSpec]) -> ArmSpec {
    let mut arm = ArmSpec::load("so101", None).unwrap();
    let mut spec = CollisionSpec::from_frames(&arm, 0.02);
    spec.obstacles.extend(extra.iter().cloned());
    arm.collision = Some(spec);
    arm
}

/// The angle (rad) about the base's z at which the tool, the rest of the arm at zero, passes
/// through [`cube`]; the SO-101's pan turns the other way (a pan of -0.4 rad puts it there).
const CUBE_PAN: f64 = 0.4;

/// A 60 mm cube where the tool passes, the rest of the arm at zero (the arm stretched out
/// forward, the tool 0.39 m out and 0.226 m up), with the pan at [`CUBE_PAN`]; the zero pose
/// itself is 0.156 m away from its centre.
fn cube() -> ObstacleSpec {
    let (s, c) = CUBE_PAN.sin_cos();
    let centre = Vector3::new(0.3914 * c, 0.3914 * s, 0.2265);
    ObstacleSpec { name: "box".into(), shape: Shape::aligned_box(centre, Vector3::repeat(0.06)) }
}

/// The simulated board of `arm`, its servos without contact of their own.
fn no_contact(arm: &ArmSpec) -> SilOptions {
    SilOptions { contact: None, ..SilOptions::for_arm(arm.clone()).unwrap() }
}

/// What the firmware says when it stops a move of `driver`'s sent as it is: the move is started,
/// waited for, and its end named from the arm's geometry.
fn firmware_stop(arm: &ArmSpec, d: &mut Driver) -> String {
    let end = d.session().wait_idle(2000).unwrap();
    armctl::commands::drive::collision::stopped(arm, &end).unwrap_or_else(|| format!("not stopped: {end:?}"))
}

/// A driver of `arm` on a simulated board that records every tick.
fn driver(arm: &ArmSpec) -> Driver {
    let sil = Sil::new(&no_contact(arm)).unwrap();
    let mut driver = Driver::on(open_sil(sil, arm.clone()).unwrap()).unwrap();
    driver.sil().unwrap().record();
    driver
}

/// The closest any checked pair came over the goals the servos held, in f64, and how many ticks'
/// goals were checked.
fn closest_goal(arm: &ArmSpec, trace: &[TraceSample]) -> (f64, usize) {
    let spec = collision_of(arm).unwrap();
    let servos = servos_of(arm).unwrap();
    let chain = arm.chain::<f64, 5>().unwrap();
    let mut scene = spec.scene::<f64, 24, 8>(5).unwrap();
    let mut closest = f64::INFINITY;
    let mut checked = 0;
    for sample in trace.iter().filter(|s| !s.goals.is_empty()) {
        let q = SVector::<f64, 5>::from_fn(|j, _| {
            let mapping = servos.mapping(j).unwrap();
            let (_, ticks) = sample.goals.iter().find(|(id, _)| *id == mapping.id).unwrap();
            mapping.to_radians::<f64>(*ticks as i32)
        });
        if let Some(c) = scene.closest(&chain.forward(&q).joints) {
            closest = closest.min(c.distance);
        }
        checked += 1;
    }
    (closest, checked)
}

fn assert_goals_keep_the_margin(arm: &ArmSpec, driver: &mut Driver, what: &str) -> f64 {
    let trace = driver.sil().unwrap().take_trace();
    let (closest, checked) = closest_goal(arm, &trace);
    let margin = collision_of(arm).unwrap().margin;
    println!("{what}: {checked} ticks' goals, closest pair {:.2} mm (margin {:.0} mm)", closest * 1e3, margin * 1e3);
    assert!(checked > 0, "{what}: no goal recorded");
    assert!(closest >= margin - TICK_TOLERANCE, "{what}: a goal came {:.2} mm close", closest * 1e3);
    closest
}

/// The first example: the tool 8 cm below the table. The firmware refuses the target at
/// once, the message names the pair, nothing moves; a free move then goes as before.
#[test]
fn a_move_into_the_table_is_refused_naming_the_pair_and_a_free_one_succeeds() {
    let arm = so101(&[]);
    let mut d = driver(&arm);
    d.session().torque_on(20).unwrap();
    let target = CartesianTarget { position: [0.20, 0.0, -0.08], orientation: None };
    let e = d.session().move_to(target, Timing::MaxSpeed(0.1), MovePath::Auto).unwrap_err();
    let armctl::link::client::LinkError::Nak(reason) = &e else { panic!("{e}") };
    let err = armctl::link::collision::refusal(&arm, reason).unwrap_or_else(|| format!("{e}"));
    println!("{err}");
    assert!(err.contains("collision check refused the target") && err.contains("table"), "{err}");
    // The servos held one goal throughout.
    let trace = d.sil().unwrap().take_trace();
    let held: Vec<_> = trace.iter().filter(|s| !s.goals.is_empty()).map(|s| s.goals.clone()).collect();
    assert!(held.windows(2).all(|w| w[0] == w[1]), "a goal changed: {held:?}");
    let after = status(&mut d).unwrap();
    assert!(matches!(after.status.collision_check, CollisionCheck::On { bodies: 6, obstacles: 1 }));
    assert!(after.text().contains("collision  checked: 6 bodies, 1 obstacles"), "{}", after.text());

    let free = MoveRequest::new([0.25, 0.05, 0.12], None, None, None, MovePath::Auto, 20.0).unwrap();
    let report = move_to(&mut d, &free, &mut Vec::new()).unwrap();
    assert!(report.error_mm < 1.0, "{}", report.text());
    assert_goals_keep_the_margin(&arm, &mut d, "free move");
}

/// A joint move whose straight joint path sweeps the tool through a box, from and to free poses:
/// the player brakes short of it, the move fails naming the pair, every goal keeps the margin,
/// and the status reports the stop.
#[test]
fn a_joint_move_through_a_box_stops_short_of_it() {
    let arm = so101(&[cube()]);
    let mut d = driver(&arm);
    d.session().torque_on(20).unwrap();
    let through = Joints::from_slice(&[-2.0 * CUBE_PAN as f32, 0.0, 0.0, 0.0, 0.0]).unwrap();
    d.session().move_joints(through, Timing::MaxSpeed(1.0)).unwrap();
    let err = firmware_stop(&arm, &mut d);
    println!("{err}");
    assert!(err.contains("stopped the arm short of a collision") && err.contains("and box"), "{err}");
    assert_goals_keep_the_margin(&arm, &mut d, "joint move through the box");
    let s = status(&mut d).unwrap();
    let last = s.status.last_collision.expect("the stop is reported");
    assert_eq!((last.other, last.count), (CollisionPart::Obstacle(1), 1));
    assert!(last.distance < 0.01, "{last:?}");
    assert!(s.text().contains("last stop (#1)"), "{}", s.text());
    // It stopped short: the cube's near face (about 0.08 rad before its centre) and the margin
    // still ahead of the pan.
    assert!(f64::from(s.status.measured[0]) > -(CUBE_PAN - 0.08), "{:?}", s.status.measured);
    assert!(s.status.measured[0] < -0.05, "it hardly moved: {:?}", s.status.measured);
}

/// A Cartesian line through the box: the tracking brakes short of it the same way.
#[test]
fn a_line_through_a_box_stops_short_of_it() {
    let arm = so101(&[cube()]);
    let mut d = driver(&arm);
    let tool = status(&mut d).unwrap().tool;
    // The tool's circle at twice the cube's pan: the chord passes through the cube's centre.
    let (s, c) = (2.0 * CUBE_PAN).sin_cos();
    let other_side = [tool[0] * c, tool[0] * s, tool[2]];
    d.session().torque_on(20).unwrap();
    let target = CartesianTarget { position: other_side.map(|x| x as f32), orientation: None };
    d.session().move_to(target, Timing::MaxSpeed(0.1), MovePath::Line).unwrap();
    let err = firmware_stop(&arm, &mut d);
    println!("{err}");
    assert!(err.contains("stopped the arm short of a collision") && err.contains("and box"), "{err}");
    assert_goals_keep_the_margin(&arm, &mut d, "line through the box");
}

/// The geometry sent with the check off: the status says so plainly, and the joint move that
/// stopped short above goes through the box (what `--no-collision-check` is for: the simulator's
/// contact test). The digest covers the check's state.
#[test]
fn with_the_check_off_the_status_says_so_and_nothing_is_checked() {
    let arm = so101(&[cube()]);
    let sil = Sil::new(&no_contact(&arm)).unwrap();
    let mut session = armctl::link::session::Session::over(sil);
    session.set_collision_check(armctl::link::arm_config::CollisionCheck::Off);
    armctl::runtime::connection::handshake_with(&mut session, Some(arm.clone())).unwrap();
    assert_eq!(session.status().unwrap().collision_check, CollisionCheck::Off);
    session.torque_on(20).unwrap();
    let through = [-2.0 * CUBE_PAN as f32, 0.0, 0.0, 0.0, 0.0];
    session.move_joints(Joints::from_slice(&through).unwrap(), Timing::MaxSpeed(1.0)).unwrap();
    let end = session.wait_idle(1000).unwrap();
    assert!((end.measured[0] - through[0]).abs() < 0.01, "{:?}", end.measured);
    assert_eq!(end.last_collision, None);
    let unchecked = armctl::link::arm_config::arm_digest_checked(
        &arm,
        &servos_of(&arm).unwrap(),
        armctl::link::arm_config::CollisionCheck::Off,
    )
    .unwrap();
    let checked = armctl::link::arm_config::arm_digest(&arm, &servos_of(&arm).unwrap()).unwrap();
    assert_ne!(unchecked, checked, "the digest covers the check");
}

/// The firmware refuses geometry that does not fit the arm as a whole: a body on a joint the arm
/// lacks is caught by the host before sending, naming it.
#[test]
fn geometry_that_does_not_fit_is_refused_by_name_before_sending() {
    let mut arm = so101(&[]);
    let spec = arm.collision.as_mut().unwrap();
    spec.bodies[5].link = Some(7);
    let sil = Sil::new(&no_contact(&arm)).unwrap();
    let err = match open_sil(sil, arm.clone()) {
        Ok(_) => panic!("sent"),
        Err(e) => format!("{e:#}"),
    };
    assert!(err.contains("collision body wrist_roll"), "{err}");
    let mut arm = so101(&[]);
    arm.collision.as_mut().unwrap().obstacles[0].shape = Shape::HalfSpace { normal: Vector3::zeros(), offset: 0.0 };
    let sil = Sil::new(&no_contact(&arm)).unwrap();
    let err = match open_sil(sil, arm) {
        Ok(_) => panic!("sent"),
        Err(e) => format!("{e:#}"),
    };
    assert!(err.contains("obstacle table"), "{err}");
}
