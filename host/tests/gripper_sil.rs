//! The gripper in software in the loop: the firmware core drives the simulated SO-101 and
//! OpenManipulator-X, whose simulated jaws stop on an object and load the servo. Every goal the
//! servos receive, the gripper's included, is checked by the SIL's safety monitor.

use armctl::link::client::{LinkClient, LinkConfig, LinkError};
use armctl::runtime::sil::{Sil, SilOptions};
use firmware::link::message::{
    Field, FirmwareMessage, GripperStatus, HostMessage, JointKeyframe, Joints, NakReason, Status,
};

fn client(arm: &str, object_mm: Option<f64>) -> LinkClient<Sil> {
    let options = SilOptions { object_mm, ..SilOptions::new(arm).unwrap() };
    let mut session = armctl::link::session::Session::over(Sil::new(&options).unwrap());
    armctl::runtime::connection::handshake(&mut session, Some(arm)).unwrap();
    let mut c = session.into_client();
    // Until every servo has been read, torque on is refused as not ready.
    for _ in 0..10 {
        match c.request(&HostMessage::Torque { on: true }) {
            Ok(_) => return c,
            Err(LinkError::Nak(NakReason::NotReady)) => c.wait_once().unwrap(),
            Err(e) => panic!("torque on: {e}"),
        }
    }
    panic!("torque on was never accepted");
}

fn gripper(c: &mut LinkClient<Sil>) -> GripperStatus {
    c.status().unwrap().gripper.expect("the arm has a gripper")
}

fn ack(c: &mut LinkClient<Sil>, message: &HostMessage) {
    let reply = c.request(message).unwrap();
    assert!(matches!(reply, FirmwareMessage::Ack { .. }), "{message:?}: {reply:?}");
}

/// Polls (one read timeout of virtual time each) until `done` or `seconds` of virtual time.
fn until(c: &mut LinkClient<Sil>, seconds: f64, done: impl Fn(&GripperStatus) -> bool) -> GripperStatus {
    let end = c.transport().now_s() + seconds;
    loop {
        let g = gripper(c);
        if done(&g) || c.transport().now_s() > end {
            return g;
        }
        c.wait_once().unwrap();
    }
}

fn assert_safe(c: &mut LinkClient<Sil>, what: &str) {
    let monitor = c.transport().monitor();
    assert!(monitor.checked > 0, "{what}: no goal checked");
    assert_eq!(monitor.violation_count, 0, "{what}: {:?}", monitor.violations);
}

/// Closing on a 30 mm object: the jaws stop there (within a tick of the contact), the load rises
/// above the hold threshold but stays within the effort limit, the status says it holds
/// something, and the goal sent is no more than the squeeze past the contact. Opening lets go.
#[test]
fn grasp_and_release_on_both_arms() {
    for (arm, opening_mm) in [("so101", 90.0), ("open-manipulator-x", 75.0)] {
        let mut c = client(arm, Some(30.0));
        ack(&mut c, &HostMessage::Gripper { opening: 0.0, effort: Some(40.0) });
        let held = until(&mut c, 3.0, |g| g.holding);
        assert!(held.holding, "{arm}: no grasp: {held:?}");
        let contact = 30.0 / opening_mm * 100.0;
        assert!((held.opening - contact as f32).abs() < 0.2, "{arm}: stopped at {held:?}, contact {contact} %");
        // Thresholds: the firmware's HOLD_LOAD (10 %) and the effort limit asked for (40 %).
        assert!(held.load.abs() >= 10.0 && held.load.abs() <= 40.0 + 0.5, "{arm}: load {held:?}");
        // Held for a second: it stays, and nothing goes past the squeeze.
        let later = until(&mut c, 1.0, |_| false);
        assert!(later.holding, "{arm}: let go: {later:?}");
        ack(&mut c, &HostMessage::Gripper { opening: 100.0, effort: None });
        let open = until(&mut c, 3.0, |g| g.opening > 99.0);
        assert!(!open.holding && open.opening > 99.0, "{arm}: {open:?}");
        assert!(open.load.abs() < 10.0, "{arm}: load when open {open:?}");
        assert_safe(&mut c, arm);
    }
}

/// With nothing between the jaws the gripper closes fully and holds nothing; an object taken
/// out of a holding grip is noticed: the jaws close on.
#[test]
fn closing_on_nothing_and_losing_the_object() {
    let mut c = client("so101", None);
    ack(&mut c, &HostMessage::Gripper { opening: 0.0, effort: None });
    let closed = until(&mut c, 3.0, |g| g.opening < 0.5);
    assert!(!closed.holding && closed.opening < 0.5, "{closed:?}");

    let mut c = client("so101", Some(40.0));
    ack(&mut c, &HostMessage::Gripper { opening: 0.0, effort: None });
    assert!(until(&mut c, 3.0, |g| g.holding).holding);
    c.transport().set_object(None).unwrap();
    let lost = until(&mut c, 3.0, |g| !g.holding && g.opening < 0.5);
    assert!(!lost.holding && lost.opening < 0.5, "{lost:?}");
    assert_safe(&mut c, "lost object");
}

/// Keyframes carry the gripper's opening; the firmware interpolates it between them on the
/// playback clock (linearly, then ramped at the gripper's speed).
#[test]
fn keyframes_drive_the_gripper_with_the_joints() {
    let mut c = client("so101", None);
    let start: Status = c.status().unwrap();
    let q: Joints = start.measured.clone();
    for (time, pct) in [(0.5f32, 100.0f32), (1.5, 20.0)] {
        let k = JointKeyframe { time, positions: q.clone(), velocities: None, gripper: Some(pct) };
        ack(&mut c, &HostMessage::PushKeyframe(k));
    }
    ack(&mut c, &HostMessage::Start);
    // Halfway between the keyframes (t = 1.0 s) the goal is halfway: 60 %, within the ramp.
    let t0 = c.transport().now_s();
    let mid = until(&mut c, 1.0, |_| false);
    let elapsed = c.transport().now_s() - t0;
    let expected = 100.0 - 80.0 * ((elapsed - 0.5) / 1.0).clamp(0.0, 1.0) as f32;
    assert!((mid.goal - expected).abs() < 6.0, "goal {} at {elapsed:.3} s, expected about {expected}", mid.goal);
    let end = until(&mut c, 3.0, |g| (g.opening - 20.0).abs() < 1.0);
    assert!((end.opening - 20.0).abs() < 1.0 && (end.goal - 20.0).abs() < 1e-3, "{end:?}");
    assert_safe(&mut c, "keyframes");
}

/// Bad gripper values are refused (by the message's own check, which the client runs before
/// sending and the firmware again on arrival) and change nothing.
#[test]
fn bad_gripper_values_are_refused() {
    let mut c = client("so101", None);
    let before = gripper(&mut c);
    let bad = [(f32::NAN, None), (101.0, None), (-0.5, None), (50.0, Some(0.0)), (50.0, Some(f32::INFINITY))];
    for (opening, effort) in bad {
        let message = HostMessage::Gripper { opening, effort };
        let e = message.validate().unwrap_err();
        assert_eq!(e.field, Field::Gripper, "{opening} {effort:?}");
        assert!(matches!(c.request(&message), Err(LinkError::Invalid(_))), "{opening} {effort:?}");
    }
    let k =
        JointKeyframe { time: 1.0, positions: c.status().unwrap().measured, velocities: None, gripper: Some(150.0) };
    assert!(matches!(c.request(&HostMessage::PushKeyframe(k)), Err(LinkError::Invalid(_))));
    let after = gripper(&mut c);
    assert_eq!(before.goal, after.goal);
    assert_eq!(c.status().unwrap().queued, 0);
}

/// An arm without a gripper naks gripper requests and gripper keyframes, and reports none.
#[test]
fn an_arm_without_a_gripper_says_so() {
    let options = SilOptions::new("so101").unwrap();
    let c = LinkClient::new(Sil::new(&options).unwrap(), LinkConfig::default());
    let mut spec = armctl::arm::ArmSpec::load("so101", None).unwrap();
    let mut servos = armctl::arm::servos::servos_of(&spec).unwrap();
    spec.name = "so101-no-gripper".into();
    servos.gripper = None;
    spec.servos = Some(servos);
    let mut session = armctl::link::session::Session::new(c);
    armctl::runtime::connection::handshake_with(&mut session, Some(spec)).unwrap();
    let mut c = session.into_client();
    c.wait_once().unwrap();
    let reply = c.request(&HostMessage::Gripper { opening: 10.0, effort: None });
    assert!(matches!(reply, Err(LinkError::Nak(NakReason::NoGripper))), "{reply:?}");
    let k = JointKeyframe { time: 1.0, positions: c.status().unwrap().measured, velocities: None, gripper: Some(50.0) };
    let reply = c.request(&HostMessage::PushKeyframe(k));
    assert!(matches!(reply, Err(LinkError::Nak(NakReason::NoGripper))), "{reply:?}");
    assert!(c.status().unwrap().gripper.is_none());
}

/// The tool point of the simulated arm for the measured joints (m).
fn tool(arm: &dyn armctl::arm::dof::DynArm, c: &mut LinkClient<Sil>) -> [f64; 3] {
    let q: Vec<f64> = c.status().unwrap().measured.iter().map(|x| f64::from(*x)).collect();
    let p = arm.tool_pose(&q).unwrap().translation;
    [p.x, p.y, p.z]
}

fn so101() -> Box<dyn armctl::arm::dof::DynArm> {
    armctl::arm::dof::build(armctl::arm::ArmSpec::load("so101", None).unwrap()).unwrap()
}

/// An object on the table is picked up only where it lies and only by jaws that come to it open
/// wider than it: jaws closing 5 cm away hold nothing; jaws closed narrower than it do not take
/// it in; open ones do, and closing then holds it. It rides with the tool and stays where the
/// jaws let go of it.
#[test]
fn an_object_on_the_table_is_picked_only_where_it_lies() {
    let arm = so101();
    let mut c = client("so101", None);
    let here = tool(arm.as_ref(), &mut c);
    let away = [here[0] + 0.05, here[1], here[2]];
    c.transport().put_object(so101(), 30.0, away).unwrap();
    ack(&mut c, &HostMessage::Gripper { opening: 0.0, effort: None });
    let closed = until(&mut c, 3.0, |g| g.opening < 0.5);
    assert!(!closed.holding && closed.opening < 0.5, "closed away from the object: {closed:?}");
    assert_eq!(c.transport().object().unwrap().position(), away);
    assert!(!c.transport().object().unwrap().between_jaws());

    // At the tool now, but the jaws are closed: it cannot be between them.
    c.transport().put_object(so101(), 30.0, here).unwrap();
    until(&mut c, 0.5, |_| false);
    assert!(!c.transport().object().unwrap().between_jaws());
    // Opened past it, the jaws take it in; closing holds it.
    ack(&mut c, &HostMessage::Gripper { opening: 100.0, effort: None });
    until(&mut c, 3.0, |g| g.opening > 99.0);
    assert!(c.transport().object().unwrap().between_jaws());
    ack(&mut c, &HostMessage::Gripper { opening: 0.0, effort: None });
    let held = until(&mut c, 3.0, |g| g.holding);
    assert!(held.holding && c.transport().object().unwrap().held(), "{held:?}");

    // Carried: the base turns 0.3 rad, and the object goes along with the tool.
    let mut q = c.status().unwrap().measured;
    q[0] += 0.3;
    ack(&mut c, &HostMessage::MoveJoints { positions: q, timing: firmware::link::message::Timing::Duration(1.0) });
    until(&mut c, 2.0, |_| false);
    let there = tool(arm.as_ref(), &mut c);
    let object = c.transport().object().unwrap().position();
    let moved = (0..3).map(|i| (there[i] - here[i]).powi(2)).sum::<f64>().sqrt();
    let off = (0..3).map(|i| (object[i] - there[i]).powi(2)).sum::<f64>().sqrt();
    assert!(moved > 0.03 && off < 1e-3, "tool moved {moved} m, object {off} m from it");
    assert!(gripper(&mut c).holding);

    // Let go: it stays there while the jaws open.
    ack(&mut c, &HostMessage::Gripper { opening: 100.0, effort: None });
    let open = until(&mut c, 3.0, |g| g.opening > 99.0);
    assert!(!open.holding && !c.transport().object().unwrap().held(), "{open:?}");
    assert_eq!(c.transport().object().unwrap().position(), object);
    assert_safe(&mut c, "object on the table");
}

/// Keyframes that all carry the gripper, more than the queue holds, streamed as fast as the acks
/// allow: the acks count the gripper's track too, so none is refused as a full queue.
#[test]
fn acks_leave_room_for_gripper_keyframes() {
    let mut c = client("so101", None);
    let q: Joints = c.status().unwrap().measured;
    for i in 0..100u16 {
        let time = 0.5 + 0.1 * f32::from(i);
        let k = JointKeyframe { time, positions: q.clone(), velocities: None, gripper: Some(f32::from(i % 2) * 50.0) };
        c.push(&HostMessage::PushKeyframe(k)).unwrap_or_else(|e| panic!("keyframe {i}: {e}"));
        if i == 10 {
            ack(&mut c, &HostMessage::Start);
        }
    }
    assert_safe(&mut c, "gripper keyframes");
}
