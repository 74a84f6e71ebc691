//! Hardware in the loop, simulated: the real firmware binary for the MPS2 AN386 (Cortex-M4F) runs
//! under `qemu-system-arm -icount shift=0` (`armctl::places::qemu`), its UART1 on the simulated servo bus's
//! pty and its UART0 on a pty that the host opens as a serial port (the serialport crate), exactly
//! as `armctl --port` does with a board. The SIL scenarios' expectations are checked again here:
//! targets within a millimetre, a streamed trajectory with no keyframe lost, faults on the servo
//! side reported and survived, the gripper closing on an object and opening. Skips with a message where qemu-system-arm is missing, and fails
//! instead when the `CI` variable is set.

use std::sync::Mutex;
use std::time::Duration;

use armctl::arm::servos::ServoSetup;
use armctl::arm::ArmSpec;
use armctl::drive::connection::{open, Connection, Target};
use armctl::link::arm_config::configure_messages;
use armctl::link::client::LinkClient;
use armctl::link::ready::{request_when_ready, wait_idle};
use armctl::link::Transport;
use armctl::places::qemu::{self, Qemu, QemuConfig};
use armctl::sim::so101_bus;
use armctl::sim::{Faults, PtyServer};
use firmware::link::message::{CartesianTarget, HostMessage, JointKeyframe, RunState, Status, Timing};

type Client = LinkClient<Box<dyn Transport>>;

/// One QEMU at a time: on a two-core machine, parallel emulators would slow each other into bus
/// timeouts that say nothing about the firmware.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// The firmware under QEMU on simulated SO-101 servos, with the host's link open.
struct Rig {
    link: Connection,
    bus: PtyServer,
    board: Qemu,
}

fn rig() -> Option<Rig> {
    if !qemu::available() {
        assert!(std::env::var_os("CI").is_none(), "qemu-system-arm is missing, and CI is set: the HIL tests must run");
        eprintln!(
            "SKIPPED: qemu-system-arm is not installed (apt-get install qemu-system-arm); the HIL test did not run"
        );
        return None;
    }
    let elf = qemu::build(qemu::FIRMWARE_BIN).unwrap();
    let bus = PtyServer::spawn(so101_bus(Faults::default())).unwrap();
    let board = Qemu::start(&QemuConfig { elf, bus: Some(bus.path().to_string()) }).unwrap();
    let link = open(Target::Port { path: board.link_path().to_string(), baud: 1_000_000 }, None, &mut std::io::sink())
        .unwrap();
    assert_eq!(link.info.arm_name.as_str(), "so101");
    assert_eq!(link.info.queue_capacity, 32);
    Some(Rig { link, bus, board })
}

fn torque_on(c: &mut Client) {
    request_when_ready(c, &HostMessage::Torque { on: true }, 200).unwrap();
}

/// Polls status for about `duration` of wall time (the firmware runs at about real-time pace).
fn poll_for(c: &mut Client, duration: Duration) -> Status {
    let end = std::time::Instant::now() + duration;
    loop {
        let status = c.status().unwrap();
        if std::time::Instant::now() >= end {
            return status;
        }
        c.wait_once().unwrap();
    }
}

fn tool_error(arm: &ArmSpec, q: &[f32], target: [f32; 3]) -> f64 {
    let q: Vec<f64> = q.iter().map(|x| f64::from(*x)).collect();
    let reached = armctl::arm::dof::build(arm.clone()).unwrap().tool_pose(&q).unwrap().translation;
    let d = [reached.x - f64::from(target[0]), reached.y - f64::from(target[1]), reached.z - f64::from(target[2])];
    d.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn move_to(c: &mut Client, arm: &ArmSpec, target: [f32; 3]) {
    c.request(&HostMessage::MoveTo {
        target: CartesianTarget { position: target, orientation: None },
        timing: Timing::MaxSpeed(0.2),
    })
    .unwrap();
    let status = wait_idle(c, 2000).unwrap();
    assert_eq!(status.state, RunState::Idle);
    let error = tool_error(arm, &status.measured, target);
    assert!(error < 1e-3, "target {target:?} missed by {error} m");
}

/// The control loop's stack high-water mark, as the firmware logged it last.
fn logged_stack(board: &Qemu) -> u64 {
    armctl::footprint::measure::logged_bytes(board.log(), "control loop stack high-water").unwrap()
}

#[test]
fn the_real_firmware_reaches_targets_and_follows_a_streamed_trajectory() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let Some(mut rig) = rig() else { return };
    let arm = rig.link.arm.clone();
    let c = &mut rig.link.client;
    torque_on(c);
    for target in [[0.2f32, 0.05, 0.15], [0.25, -0.05, 0.1]] {
        move_to(c, &arm, target);
    }
    // A joint trajectory longer than the queue, streamed as slots free (as `armctl play` does).
    let keyframes: Vec<JointKeyframe> = (1..=60)
        .map(|k| {
            let t = k as f32 * 0.1;
            let positions = (0..5)
                .map(|j| 0.3 * (std::f32::consts::TAU * t / 3.0 + j as f32 * 0.5).sin() - 0.3 * (j as f32 * 0.5).sin());
            JointKeyframe { time: t, positions: positions.collect(), velocities: None, gripper: None }
        })
        .collect();
    let before = c.status().unwrap();
    for (i, k) in keyframes.iter().enumerate() {
        c.push(&HostMessage::PushKeyframe(k.clone())).unwrap_or_else(|e| panic!("keyframe {i}: {e}"));
        if i == 15 {
            c.request(&HostMessage::Start).unwrap();
        }
    }
    let status = wait_idle(c, 5000).unwrap();
    assert_eq!(status.state, RunState::Idle);
    assert_eq!(status.errors.underruns, before.errors.underruns, "the host kept the queue fed");
    let last = &keyframes.last().unwrap().positions;
    for (j, (m, k)) in status.measured.iter().zip(last).enumerate() {
        assert!((m - k).abs() < 0.01, "joint {j}: ended at {m}, last keyframe {k}");
    }
    assert_eq!(status.errors.bus_errors, 0);
    assert_eq!(status.errors.watchdog_trips, 0);
    eprintln!("control loop: mean {} us, max {} us", status.timing.mean_us, status.timing.max_us);
    eprintln!("stack high-water: {} bytes", logged_stack(&rig.board));
    drop(rig.link);
    rig.bus.stop().unwrap();
}

#[test]
fn faults_on_the_servo_side_are_reported_and_survived() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let Some(mut rig) = rig() else { return };
    let arm = rig.link.arm.clone();
    let c = &mut rig.link.client;
    // The arm sent over the link, joint by joint, replaces the built-in one (the firmware's
    // deepest path: a whole new controller).
    let so101 = ArmSpec::load("so101", None).unwrap();
    for message in configure_messages(&so101, &ServoSetup::for_arm("so101").unwrap()).unwrap() {
        c.request(&message).unwrap();
    }
    torque_on(c);
    // A servo falls silent mid-move: reported lost, then back, and the move completes.
    c.request(&HostMessage::MoveJoints {
        positions: [0.5, 0.3, -0.3, 0.2, 0.0].into_iter().collect(),
        timing: Timing::Duration(3.0),
    })
    .unwrap();
    poll_for(c, Duration::from_millis(300));
    rig.bus.set_faults(Faults { silent: vec![3], ..Faults::default() });
    let status = poll_for(c, Duration::from_millis(500));
    assert_eq!(status.lost_servos, 1 << 2, "servo 3 (joint 3) reported lost");
    assert!(status.errors.bus_timeouts >= 5);
    rig.bus.set_faults(Faults::default());
    poll_for(c, Duration::from_millis(300));
    let status = wait_idle(c, 2000).unwrap();
    assert_eq!(status.lost_servos, 0, "servo 3 back");
    assert_eq!(status.state, RunState::Idle);
    assert!((status.measured[2] + 0.3).abs() < 0.01, "joint 3 reached its goal: {}", status.measured[2]);
    // A lossy, corrupting bus: retries absorb it and the target is still reached.
    rig.bus.set_faults(Faults { seed: 5, drop_rate: 0.01, corrupt_rate: 0.02, ..Faults::default() });
    let before = c.status().unwrap().errors;
    move_to(c, &arm, [0.2, 0.0, 0.15]);
    let after = c.status().unwrap().errors;
    assert!(after.bus_timeouts + after.bus_errors > before.bus_timeouts + before.bus_errors, "the faults did happen");
    eprintln!("stack high-water: {} bytes", logged_stack(&rig.board));
    drop(rig.link);
    rig.bus.stop().unwrap();
}

/// Polls status (one read timeout of wall time each) until `done` or `timeout`.
fn poll_until(c: &mut Client, timeout: Duration, done: impl Fn(&Status) -> bool) -> Status {
    let end = std::time::Instant::now() + timeout;
    loop {
        let status = c.status().unwrap();
        if done(&status) || std::time::Instant::now() >= end {
            return status;
        }
        c.wait_once().unwrap();
    }
}

/// The real firmware's gripper (servo 6, in the joints' sync write and read) closes on a 30 mm
/// object between the simulated jaws: it stops there, the load rises, and its own grasp detection
/// says it holds something; opened, it lets go.
#[test]
fn the_real_firmware_closes_the_gripper_on_an_object_and_opens_it() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let Some(mut rig) = rig() else { return };
    let gripper = ServoSetup::for_arm("so101").unwrap().gripper.unwrap();
    rig.bus.put_object(gripper.id, Some(armctl::sim::Jaw::for_object(&gripper, 30.0).unwrap()));
    let c = &mut rig.link.client;
    torque_on(c);
    c.request(&HostMessage::Gripper { opening: 0.0, effort: None }).unwrap();
    let held = poll_until(c, Duration::from_secs(5), |s| s.gripper.is_some_and(|g| g.holding));
    let g = held.gripper.expect("the built-in SO-101 has a gripper");
    assert!(g.holding, "no grasp: {g:?}");
    let contact = 30.0 / gripper.opening_mm * 100.0;
    assert!((f64::from(g.opening) - contact).abs() < 0.3, "stopped at {g:?}, the object at {contact:.1} %");
    assert!(g.load.abs() >= 10.0, "load {g:?}");
    c.request(&HostMessage::Gripper { opening: 100.0, effort: None }).unwrap();
    let open = poll_until(c, Duration::from_secs(5), |s| s.gripper.is_some_and(|g| g.opening > 99.0));
    let g = open.gripper.unwrap();
    assert!(!g.holding && g.opening > 99.0, "{g:?}");
    assert_eq!(open.errors.bus_errors, 0);
    drop(rig.link);
    rig.bus.stop().unwrap();
}
