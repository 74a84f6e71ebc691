//! SIL scenarios: the firmware application behind the host link, on simulated servos, driven by
//! the host's link client, all on one virtual clock (`armctl::runtime::sil`). The safety monitor checks
//! every goal the simulated servos receive against the joint limits and the per-period velocity
//! limit; every scenario ends by asserting it saw nothing wrong.

use armctl::arm::servos::ServoSetup;
use armctl::arm::ArmSpec;
use armctl::link::arm_config::configure_messages;
use armctl::link::client::{LinkClient, LinkConfig, LinkError};
use armctl::link::session::Session;
use armctl::runtime::sil::{Sil, SilOptions};
use firmware::link::frame::{decode_payload, encode_message, FrameDecoder, FrameKind, MAX_ENCODED, MAX_FRAME};
use firmware::link::message::{
    CartesianKeyframe, CartesianTarget, FirmwareMessage, HostMessage, JointKeyframe, NakReason, RunState, Status,
    Timing,
};

type Client = LinkClient<Sil>;

fn client(options: &SilOptions) -> Client {
    let sil = Sil::new(options).unwrap();
    let mut client = LinkClient::new(sil, LinkConfig::default());
    let info = client.hello().unwrap();
    if info.arm_name.is_empty() {
        let arm = options.arm.clone();
        let servos = ServoSetup::for_arm(&arm.name).unwrap();
        for m in configure_messages(&arm, &servos).unwrap() {
            client.request(&m).unwrap();
        }
        assert_eq!(client.hello().unwrap().arm_name.as_str(), options.arm.name.as_str());
    }
    client
}

/// Torque on once the firmware has read every servo (it refuses until then).
fn torque_on(c: &mut Client) {
    for _ in 0..50 {
        match c.request(&HostMessage::Torque { on: true }) {
            Ok(_) => return,
            Err(LinkError::Nak(NakReason::NotReady)) => c.transport().run_for(0.02),
            Err(e) => panic!("torque on: {e}"),
        }
    }
    panic!("torque never came on");
}

/// Polls status until the arm is at rest again (or `seconds` of virtual time pass).
fn wait_idle(c: &mut Client, seconds: f64) -> Status {
    let end = c.transport().now_s() + seconds;
    loop {
        let s = c.status().unwrap();
        if s.state == RunState::Idle || c.transport().now_s() > end {
            return s;
        }
        c.transport().run_for(0.05);
    }
}

/// Lets `seconds` pass with the host polling status every 50 ms (so the watchdog stays quiet).
fn poll_for(c: &mut Client, seconds: f64) -> Status {
    let end = c.transport().now_s() + seconds;
    loop {
        let s = c.status().unwrap();
        if c.transport().now_s() >= end {
            return s;
        }
        c.transport().run_for(0.05);
    }
}

fn tool_position(arm: &ArmSpec, q: &[f32]) -> [f64; 3] {
    let q: Vec<f64> = q.iter().map(|x| f64::from(*x)).collect();
    let pose = armctl::arm::dof::build(arm.clone()).unwrap().tool_pose(&q).unwrap();
    [pose.translation.x, pose.translation.y, pose.translation.z]
}

fn distance(a: [f64; 3], b: [f32; 3]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - f64::from(y)).powi(2)).sum::<f64>().sqrt()
}

fn assert_safe(c: &mut Client) {
    let m = c.transport().monitor();
    assert!(m.checked > 0, "the monitor checked nothing");
    assert!(m.violations.is_empty(), "{} violations, first {:?}", m.violation_count, m.violations.first());
}

#[test]
fn so101_moves_its_tool_to_a_target_within_a_millimetre() {
    let options = SilOptions::new("so101").unwrap();
    let mut c = client(&options);
    torque_on(&mut c);
    let arm = ArmSpec::load("so101", None).unwrap();
    let target = [0.2f32, 0.05, 0.15];
    let reply = c
        .request(&HostMessage::MoveTo {
            path: firmware::link::message::MovePath::Auto,
            target: CartesianTarget { position: target, orientation: None },
            timing: Timing::MaxSpeed(0.1),
        })
        .unwrap();
    assert!(matches!(reply, FirmwareMessage::Ack { .. }));
    let s = wait_idle(&mut c, 10.0);
    assert_eq!(s.state, RunState::Idle);
    let reached = tool_position(&arm, &s.measured);
    assert!(distance(reached, target) < 1e-3, "reached {reached:?}");
    assert_safe(&mut c);
}

/// 1% of bytes dropped and 0.1% of bits flipped (0.8% of bytes get one flipped bit).
fn lossy(seed: u64) -> armctl::sim::Faults {
    armctl::sim::Faults { seed, drop_rate: 0.01, bit_flip_rate: 0.008, ..Default::default() }
}

/// A smooth joint trajectory inside the SO-101's limits: keyframes every 0.1 s.
fn wave(n: usize, joints: usize) -> Vec<JointKeyframe> {
    (1..=n)
        .map(|k| {
            let t = k as f32 * 0.1;
            let positions = (0..joints)
                .map(|j| 0.4 * (std::f32::consts::TAU * t / 4.0 + j as f32 * 0.5).sin() - 0.4 * (j as f32 * 0.5).sin())
                .collect();
            JointKeyframe { time: t, positions, velocities: None, gripper: None }
        })
        .collect()
}

/// Streams `keyframes` with flow control: fills the queue, starts, pushes the rest as slots free.
fn stream(c: &mut Client, keyframes: &[JointKeyframe]) {
    for (i, k) in keyframes.iter().enumerate() {
        let reply = c.push(&HostMessage::PushKeyframe(k.clone())).unwrap_or_else(|e| panic!("keyframe {i}: {e}"));
        assert!(matches!(reply, FirmwareMessage::Ack { .. }));
        if i == 15 {
            c.request(&HostMessage::Start).unwrap();
        }
    }
}

#[test]
fn streaming_over_a_lossy_link_and_bus_loses_and_doubles_no_keyframe() {
    let mut options = SilOptions::new("so101").unwrap();
    options.link_faults = lossy(7);
    options.bus_faults = lossy(11);
    let mut c = client(&options);
    torque_on(&mut c);
    let keyframes = wave(150, 5);
    stream(&mut c, &keyframes);
    let s = wait_idle(&mut c, 30.0);
    assert_eq!(s.state, RunState::Idle);
    let board = c.transport().board();
    let counters = board.counters().unwrap();
    assert_eq!(counters.keyframes as usize, keyframes.len(), "keyframes accepted by the controller");
    let session = board.session();
    let (down, up) = c.transport().link_fault_stats();
    assert!(down.dropped + up.dropped > 0 && down.flipped + up.flipped > 0, "the faults did happen");
    assert!(c.stats().retransmissions > 0 && session.repeats > 0, "losses cost retransmissions and repeats");
    assert!(s.errors.bus_timeouts > 0 || s.errors.bus_errors > 0, "bus faults show in the status");
    assert_eq!(s.errors.underruns, 0, "the host kept the queue fed");
    assert_eq!(s.errors.watchdog_trips, 0, "the host stayed in contact");
    // The arm ends at the last keyframe.
    let last = &keyframes.last().unwrap().positions;
    for (j, (m, k)) in s.measured.iter().zip(last).enumerate() {
        assert!((m - k).abs() < 0.01, "joint {j}: ended at {m}, last keyframe {k}");
    }
    // A goal the line corrupted past Feetech's 8-bit checksum is not the firmware's and is not
    // judged. Such goals stay rare (5 of about 5300 here: one sync write in the run), so the monitor
    // still judges nearly all of them.
    let m = c.transport().monitor();
    assert!(m.corrupted * 200 < m.checked, "{} of {} goals excused as corrupted on the line", m.corrupted, m.checked);
    assert_safe(&mut c);
}

#[test]
fn a_servo_that_stops_answering_is_reported_and_recovers() {
    let options = SilOptions::new("so101").unwrap();
    let mut c = client(&options);
    torque_on(&mut c);
    c.request(&HostMessage::MoveJoints {
        positions: [0.5, 0.3, -0.3, 0.2, 0.0].into_iter().collect(),
        timing: Timing::Duration(2.0),
    })
    .unwrap();
    poll_for(&mut c, 0.3);
    c.transport().bus().borrow_mut().faults().config_mut().silent = vec![3];
    let s = poll_for(&mut c, 0.3);
    assert_eq!(s.state, RunState::Moving);
    assert_eq!(s.lost_servos, 1 << 2, "servo 3 (joint 3) reported lost");
    assert!(s.errors.bus_timeouts >= 5);
    c.transport().bus().borrow_mut().faults().config_mut().silent.clear();
    let s = poll_for(&mut c, 0.1);
    assert_eq!(s.lost_servos, 0, "servo 3 back");
    let s = wait_idle(&mut c, 5.0);
    assert_eq!(s.lost_servos, 0, "servo 3 back");
    assert_eq!(s.state, RunState::Idle);
    assert!((s.measured[2] + 0.3).abs() < 0.01, "joint 3 reached its goal: {}", s.measured[2]);
    assert_safe(&mut c);
}

#[test]
fn the_watchdog_stops_the_arm_when_the_host_falls_silent_mid_trajectory() {
    let options = SilOptions::new("so101").unwrap();
    let mut c = client(&options);
    torque_on(&mut c);
    let keyframes = wave(30, 5);
    for k in &keyframes {
        c.push(&HostMessage::PushKeyframe(k.clone())).unwrap();
    }
    c.request(&HostMessage::Start).unwrap();
    c.transport().run_for(0.5);
    let moving = c.status().unwrap();
    assert_eq!(moving.state, RunState::Moving);
    // The host says nothing for 2 s: the 500 ms watchdog brakes the arm to a halt.
    c.transport().run_for(2.0);
    let s = c.status().unwrap();
    assert_eq!(s.errors.watchdog_trips, 1);
    assert_eq!(s.state, RunState::Idle, "stopped and holding");
    assert!(s.measured.iter().zip(&s.setpoints).all(|(m, p)| (m - p).abs() < 0.01));
    // Recovery: the host is back and the arm obeys again.
    c.request(&HostMessage::MoveJoints { positions: [0.0; 5].into_iter().collect(), timing: Timing::Duration(2.0) })
        .unwrap();
    let s = wait_idle(&mut c, 5.0);
    assert!(s.measured.iter().all(|m| m.abs() < 0.01), "{:?}", s.measured);
    assert_safe(&mut c);
}

/// Writes `bytes` to the link and collects the frames that come back within 100 ms.
fn raw_exchange(c: &mut Client, bytes: &[u8]) -> Vec<(FrameKind, FirmwareMessage)> {
    use std::io::{Read, Write};
    let sil = c.transport();
    sil.write_all(bytes).unwrap();
    let mut decoder = FrameDecoder::<{ MAX_ENCODED }>::new();
    let mut got = Vec::new();
    let end = sil.now_s() + 0.1;
    let mut byte = [0u8; 1];
    while sil.now_s() < end {
        if sil.read(&mut byte).is_ok() {
            if let Some(Ok(frame)) = decoder.push(byte[0]) {
                got.push((frame.kind, decode_payload::<FirmwareMessage>(frame.payload).unwrap()));
            }
        }
    }
    got
}

fn nak_of(replies: &[(FrameKind, FirmwareMessage)]) -> NakReason {
    match replies {
        [(_, FirmwareMessage::Nak { reason })] => *reason,
        other => panic!("expected one nak, got {other:?}"),
    }
}

#[test]
fn bad_requests_get_a_reason_and_change_nothing() {
    let options = SilOptions::new("so101").unwrap();
    let mut c = client(&options);
    torque_on(&mut c);
    c.transport().run_for(0.1);
    let before = c.status().unwrap();
    let mut frame = [0u8; MAX_FRAME];
    let mut send = |c: &mut Client, seq: u8, m: &HostMessage| {
        let n = encode_message(seq, FrameKind::Request, m, &mut frame).unwrap();
        nak_of(&raw_exchange(c, &frame[..n]))
    };
    // NaN in a target (the client refuses it before sending; the firmware refuses it too).
    let nan = HostMessage::MoveTo {
        path: firmware::link::message::MovePath::Auto,
        target: CartesianTarget { position: [f32::NAN, 0.1, 0.1], orientation: None },
        timing: Timing::MaxSpeed(0.1),
    };
    assert!(matches!(c.request(&nan), Err(LinkError::Invalid(_))));
    assert!(matches!(send(&mut c, 200, &nan), NakReason::BadValue(_)));
    // Unreachable: 2 m away.
    let far = HostMessage::MoveTo {
        path: firmware::link::message::MovePath::Auto,
        target: CartesianTarget { position: [2.0, 0.0, 0.1], orientation: None },
        timing: Timing::MaxSpeed(0.1),
    };
    assert!(matches!(c.request(&far), Err(LinkError::Nak(NakReason::Unreachable))));
    // A joint beyond its limit, and the wrong joint count.
    let beyond = HostMessage::MoveJoints {
        positions: [0.0, 0.0, 3.0, 0.0, 0.0].into_iter().collect(),
        timing: Timing::Duration(1.0),
    };
    assert!(matches!(c.request(&beyond), Err(LinkError::Nak(NakReason::JointLimit { joint: 2 }))));
    let six = HostMessage::MoveJoints { positions: [0.0; 6].into_iter().collect(), timing: Timing::Duration(1.0) };
    assert!(matches!(c.request(&six), Err(LinkError::Nak(NakReason::BadValue(_)))));
    // An oversized frame: 300 bytes without a delimiter.
    let mut long = vec![0x55u8; 300];
    long.push(0);
    assert_eq!(nak_of(&raw_exchange(&mut c, &long)), NakReason::Oversized);
    // A frame with a good CRC but an unknown message (variant 99).
    let n = firmware::link::frame::encode_frame(201, FrameKind::Request, &[99, 1, 2], &mut frame).unwrap();
    assert_eq!(nak_of(&raw_exchange(&mut c, &frame[..n])), NakReason::UnknownMessage);
    // A corrupt frame.
    let n = encode_message(202, FrameKind::Request, &HostMessage::Stop, &mut frame).unwrap();
    frame[2] ^= 0x10;
    assert_eq!(nak_of(&raw_exchange(&mut c, &frame[..n])), NakReason::Corrupt);
    // Nothing changed: same state, same setpoints, and the counters say why.
    let after = c.status().unwrap();
    assert_eq!(after.state, RunState::Idle);
    assert_eq!(after.setpoints, before.setpoints);
    assert_eq!(after.errors.link_oversized, 1);
    assert_eq!(after.errors.link_corrupt, 1, "{:?}", after.errors);
    assert!(after.errors.naks >= 7, "{:?}", after.errors);
    // And the arm still obeys.
    c.request(&HostMessage::MoveJoints { positions: [0.2; 5].into_iter().collect(), timing: Timing::Duration(1.0) })
        .unwrap();
    let s = wait_idle(&mut c, 5.0);
    assert!(s.measured.iter().all(|m| (m - 0.2).abs() < 0.01), "{:?}", s.measured);
    assert_safe(&mut c);
}

#[test]
fn open_manipulator_x_on_dynamixel_reaches_cartesian_targets_and_keyframes() {
    let options = SilOptions::new("open-manipulator-x").unwrap();
    let mut c = client(&options);
    torque_on(&mut c);
    let arm = ArmSpec::load("open-manipulator-x", None).unwrap();
    for target in [[0.2f32, 0.0, 0.1], [0.15, 0.1, 0.15], [0.18, -0.08, 0.05]] {
        c.request(&HostMessage::MoveTo {
            path: firmware::link::message::MovePath::Auto,
            target: CartesianTarget { position: target, orientation: None },
            timing: Timing::Duration(1.5),
        })
        .unwrap();
        let s = wait_idle(&mut c, 10.0);
        let reached = tool_position(&arm, &s.measured);
        assert!(distance(reached, target) < 1e-3, "target {target:?} reached {reached:?}");
    }
    // Cartesian keyframes: IK on the firmware, then played like joint keyframes.
    let points = [[0.2f32, 0.05, 0.1], [0.2, 0.05, 0.05], [0.2, -0.05, 0.05], [0.2, -0.05, 0.1]];
    for (i, p) in points.iter().enumerate() {
        let k = CartesianKeyframe {
            time: 1.0 + i as f32,
            target: CartesianTarget { position: *p, orientation: None },
            gripper: None,
        };
        c.push(&HostMessage::PushCartesianKeyframe(k)).unwrap();
    }
    c.request(&HostMessage::Start).unwrap();
    let s = wait_idle(&mut c, 10.0);
    let reached = tool_position(&arm, &s.measured);
    assert!(distance(reached, points[3]) < 1e-3, "last keyframe reached {reached:?}");
    assert_eq!(c.transport().board().counters().unwrap().keyframes, 4);
    assert_safe(&mut c);
}

#[test]
fn the_same_seed_gives_the_same_run() {
    let run = || {
        let mut options = SilOptions::new("so101").unwrap();
        // A fifth of lossy()'s rates on the link: at lossy()'s, a 109-byte status gets through
        // one attempt in seven, so one of the ~200 statuses of the wait gives up after its 40
        // attempts about every other seed (this one did once the status grew by the collision
        // fields). What is tested is that the same faults give the same run.
        options.link_faults =
            armctl::sim::Faults { seed: 3, drop_rate: 0.002, bit_flip_rate: 0.0016, ..Default::default() };
        options.bus_faults = lossy(4);
        let mut c = client(&options);
        c.transport().record();
        torque_on(&mut c);
        stream(&mut c, &wave(40, 5));
        wait_idle(&mut c, 10.0);
        (c.transport().take_trace(), c.stats())
    };
    let (a, sa) = run();
    let (b, sb) = run();
    assert!(a.len() > 400);
    assert_eq!(a, b);
    assert_eq!(sa, sb);
}

#[test]
fn keyframes_faster_than_the_limits_are_followed_with_lag_and_idle_means_at_rest() {
    let options = SilOptions::new("so101").unwrap();
    let mut c = client(&options);
    torque_on(&mut c);
    // 1 rad in 0.2 s asks for 5 rad/s or more; the limit is 2 rad/s.
    let k = JointKeyframe {
        time: 0.2,
        positions: [1.0, 0.0, 0.0, 0.0, 0.0].into_iter().collect(),
        velocities: None,
        gripper: None,
    };
    c.push(&HostMessage::PushKeyframe(k)).unwrap();
    c.request(&HostMessage::Start).unwrap();
    let s = wait_idle(&mut c, 5.0);
    assert_eq!(s.state, RunState::Idle);
    assert!((s.setpoints[0] - 1.0).abs() < 1e-4, "idle only once the setpoint is on the keyframe: {:?}", s.setpoints);
    assert_safe(&mut c);
}

#[test]
fn telemetry_pause_resume_and_emergency_stop_over_the_link() {
    let options = SilOptions::new("so101").unwrap();
    let mut c = client(&options);
    torque_on(&mut c);
    // Telemetry at 50 Hz: frames arrive unasked while the host waits.
    c.request(&HostMessage::SetTelemetry { rate_hz: 50 }).unwrap();
    c.wait_once().unwrap();
    let t = c.telemetry().expect("telemetry arrived").time;
    c.wait_once().unwrap();
    c.wait_once().unwrap();
    assert!(c.telemetry().unwrap().time > t, "telemetry keeps coming");
    c.request(&HostMessage::SetTelemetry { rate_hz: 0 }).unwrap();
    // Pause slows the playback to a standstill on its path; start resumes it.
    for k in wave(30, 5) {
        c.push(&HostMessage::PushKeyframe(k)).unwrap();
    }
    c.request(&HostMessage::Start).unwrap();
    poll_for(&mut c, 0.5);
    c.request(&HostMessage::Pause).unwrap();
    let paused = poll_for(&mut c, 0.5);
    assert_eq!(paused.state, RunState::Paused);
    let still = poll_for(&mut c, 0.2);
    assert_eq!(still.setpoints, paused.setpoints, "paused means still");
    assert!(still.queued > 0, "the queue is kept");
    c.request(&HostMessage::Start).unwrap();
    assert_eq!(poll_for(&mut c, 0.2).state, RunState::Moving);
    // Emergency stop with torque off: the servos go limp; only torque on leaves it.
    c.request(&HostMessage::EStop { mode: firmware::link::message::EStopMode::TorqueOff }).unwrap();
    let s = poll_for(&mut c, 0.1);
    assert_eq!(s.state, RunState::TorqueOff);
    let bus = c.transport().bus().clone();
    assert!(bus.borrow().servos().iter().all(|s| !s.torque()), "every servo limp");
    let back = HostMessage::MoveJoints { positions: [0.0; 5].into_iter().collect(), timing: Timing::Duration(1.0) };
    assert!(matches!(c.request(&back), Err(LinkError::Nak(NakReason::EStopped))));
    torque_on(&mut c);
    c.request(&back).unwrap();
    let s = wait_idle(&mut c, 5.0);
    assert!(s.measured.iter().all(|m| m.abs() < 0.01), "{:?}", s.measured);
    assert_safe(&mut c);
}

#[test]
fn a_home_built_arm_from_an_arm_file_with_servos_is_configured_and_driven() {
    // The OpenManipulator-X geometry as an arm file of someone's own, with its first servo
    // mounted the other way round and the third off-centre.
    // Removed when dropped, also when the test fails.
    let file = tempfile::Builder::new().prefix("sil-arm-").suffix(".toml").tempfile().unwrap().into_temp_path();
    std::fs::write(
        &file,
        r#"
name = "my-arm"
[[joint]]
type = "revolute"
xyz = [0.012, 0, 0.017]
axis = [0, 0, 1]
limits = [-2.8, 2.8]
[[joint]]
type = "revolute"
xyz = [0, 0, 0.0595]
axis = [0, 1, 0]
limits = [-1.79, 1.57]
[[joint]]
type = "revolute"
xyz = [0.024, 0, 0.128]
axis = [0, 1, 0]
limits = [-0.94, 1.38]
[[joint]]
type = "revolute"
xyz = [0.124, 0, 0]
axis = [0, 1, 0]
limits = [-1.79, 2.04]
[tool]
xyz = [0.126, 0, 0]
[servos]
model = "XM430-W350"
ids = [11, 12, 13, 14]
zero = [2048, 2048, 1948, 2048]
reversed = [true, false, false, false]
max_velocity = 1.5
max_acceleration = 6.0
"#,
    )
    .unwrap();
    let options = SilOptions::new("open-manipulator-x").unwrap();
    let mut session = Session::over(Sil::new(&options).unwrap());
    let (info, arm) = armctl::runtime::connection::handshake(&mut session, Some(file.to_str().unwrap())).unwrap();
    let mut c = session.into_client();
    assert_eq!(info.arm_name.as_str(), "my-arm");
    torque_on(&mut c);
    // Joint 3 reads -100 ticks off its zero: the firmware knows its mapping.
    let s = c.status().unwrap();
    assert!((s.measured[2] - 100.0 * std::f32::consts::TAU / 4096.0).abs() < 1e-3, "{:?}", s.measured);
    let target = [0.18f32, 0.06, 0.08];
    c.request(&HostMessage::MoveTo {
        path: firmware::link::message::MovePath::Auto,
        target: CartesianTarget { position: target, orientation: None },
        timing: Timing::MaxSpeed(0.1),
    })
    .unwrap();
    let s = wait_idle(&mut c, 10.0);
    let reached = tool_position(&arm, &s.measured);
    assert!(distance(reached, target) < 1e-3, "reached {reached:?}");
    // The reversed servo turned the other way: its ticks fall as joint 1 rises.
    let goal =
        c.transport().bus().borrow().servo(11).unwrap().get(firmware::bus::table::XM430_W350.items.goal_position);
    assert!((s.measured[0] > 0.0) == (goal < 2048), "joint 1 at {} rad, servo 11 goal {goal}", s.measured[0]);
    assert_safe(&mut c);
}
