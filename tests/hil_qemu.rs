//! Hardware in the loop, simulated: the real firmware binary for the MPS2 AN386 (Cortex-M4F) runs
//! under `qemu-system-arm -icount shift=0` (`armctl::runtime::qemu`), its UART1 on the simulated servo bus's
//! pty and its UART0 on a pty that the host opens as a serial port (the serialport crate), exactly
//! as `armctl --port` does with a board. The SIL scenarios' expectations are checked again here:
//! targets within a millimetre, a streamed trajectory with no keyframe lost, faults on the servo
//! side reported and survived, the gripper closing on an object and opening. Every rig checks
//! that both ptys, QEMU's UART0 and the servos', are their owner's alone (mode 0600). Skips with a
//! message where qemu-system-arm is missing, and fails instead when the `CI` variable is set.

use std::sync::Mutex;
use std::time::Duration;

use armctl::arm::servos::ServoSetup;
use armctl::arm::ArmSpec;
use armctl::link::arm_config::configure_messages;
use armctl::link::session::{Keyframe, Session};
use armctl::link::Transport;
use armctl::runtime::connection::{open, Connection, Target};
use armctl::runtime::qemu::{self, Gdb, Qemu, QemuConfig};
use armctl::sim::so101_bus;
use armctl::sim::{Faults, PtyServer, SimConfig};
use firmware::link::message::{CartesianTarget, HostMessage, JointKeyframe, MovePath, RunState, Status, Timing};

type Client = Session<Box<dyn Transport>>;

/// One QEMU at a time: on a two-core machine, parallel emulators would slow each other into bus
/// timeouts that say nothing about the firmware.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// The firmware under QEMU on simulated SO-101 servos, with the host's link open.
struct Rig {
    link: Connection,
    bus: PtyServer,
    board: Qemu,
}

/// The firmware under QEMU with its servo bus on `servos`, its link opened as `armctl --port PTY
/// [--arm ARM]` opens a board's; `None` (after saying so) where qemu-system-arm is missing.
fn rig_on(servos: SimConfig, arm: Option<&str>) -> Option<Rig> {
    if !qemu_here() {
        return None;
    }
    let elf = qemu::build(qemu::FIRMWARE_BIN).unwrap();
    let bus = PtyServer::spawn(servos).unwrap();
    let board = Qemu::start(&QemuConfig::new(elf, Some(bus.path().to_string()))).unwrap();
    board.wait_started(qemu::START_TIMEOUT).unwrap();
    let path = board.link_path().to_string();
    // The pty QEMU opened for UART0 (the one `armctl sim --qemu` prints) and the servos' pty.
    armctl_test_support::assert_private(&path);
    armctl_test_support::assert_private(bus.path());
    let link =
        open(Target::Port { path, baud: 1_000_000, arm: None, gravity: None }, arm, &mut std::io::sink()).unwrap();
    assert_eq!(link.info.queue_capacity, 32);
    Some(Rig { link, bus, board })
}

/// The built-in SO-101, found without `--arm`.
fn rig() -> Option<Rig> {
    let rig = rig_on(so101_bus(Faults::default()), None)?;
    assert_eq!(rig.link.info.arm_name.as_str(), "so101");
    Some(rig)
}

/// Read timeouts a request waits through `NotReady` (4 s at 20 ms: after a reset the firmware
/// reads every servo first, and it takes a new arm only once the torque is off).
const NOT_READY_WAITS: usize = 200;

fn torque_on(c: &mut Client) {
    c.torque_on(NOT_READY_WAITS).unwrap();
}

/// Polls status for about `duration` of wall time (the firmware runs at about real-time pace).
fn poll_for(c: &mut Client, duration: Duration) -> Status {
    let end = std::time::Instant::now() + duration;
    loop {
        let status = c.status().unwrap();
        if std::time::Instant::now() >= end {
            return status;
        }
        c.pause().unwrap();
    }
}

/// Where the tool is at joint values `q` (m, forward kinematics in f64).
fn tool_position(arm: &ArmSpec, q: &[f32]) -> [f64; 3] {
    let q: Vec<f64> = q.iter().map(|x| f64::from(*x)).collect();
    let p = armctl::arm::dof::build(arm.clone()).unwrap().tool_pose(&q).unwrap().translation;
    [p.x, p.y, p.z]
}

fn tool_error(arm: &ArmSpec, q: &[f32], target: [f32; 3]) -> f64 {
    let reached = tool_position(arm, q);
    reached.iter().zip(target).map(|(r, t)| (r - f64::from(t)).powi(2)).sum::<f64>().sqrt()
}

fn move_to(c: &mut Client, arm: &ArmSpec, target: [f32; 3]) {
    let target_at = CartesianTarget { position: target, orientation: None };
    c.move_to(target_at, Timing::MaxSpeed(0.2), MovePath::Auto).unwrap();
    let status = c.wait_idle(2000).unwrap();
    assert_eq!(status.state, RunState::Idle);
    let error = tool_error(arm, &status.measured, target);
    assert!(error < 1e-3, "target {target:?} missed by {error} m");
}

/// Streams `keyframes` (more than the queue holds) as slots free, as `armctl play` does, starting
/// playback at the 16th; waits until the arm is at rest and checks that no keyframe came late and
/// that the arm ended on the last one within 0.01 rad.
fn stream(c: &mut Client, keyframes: &[JointKeyframe]) -> Status {
    let before = c.status().unwrap();
    for (i, k) in keyframes.iter().enumerate() {
        c.push(&Keyframe::Joints(k.clone())).unwrap_or_else(|e| panic!("keyframe {i}: {e}"));
        if i == 15 {
            c.start().unwrap();
        }
    }
    let status = c.wait_idle(5000).unwrap();
    assert_eq!(status.state, RunState::Idle);
    assert_eq!(status.errors.underruns, before.errors.underruns, "the host kept the queue fed");
    for (j, (m, k)) in status.measured.iter().zip(&keyframes.last().unwrap().positions).enumerate() {
        assert!((m - k).abs() < 0.01, "joint {j}: ended at {m}, last keyframe {k}");
    }
    status
}

/// The control loop's stack high-water mark, as the firmware logged it last.
fn logged_stack(board: &Qemu) -> u64 {
    armctl::commands::footprint::measure::logged_bytes(board.log(), "control loop stack high-water").unwrap()
}

#[test]
fn the_real_firmware_reaches_targets_and_follows_a_streamed_trajectory() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let Some(mut rig) = rig() else { return };
    let arm = rig.link.arm.clone();
    let c = &mut rig.link.session;
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
    let status = stream(c, &keyframes);
    assert_eq!(status.errors.bus_errors, 0);
    assert_eq!(status.errors.watchdog_trips, 0);
    // The real ELF's link receive counters: QEMU holds a byte back until the UART's is read (no
    // overrun), and one request at a time never fills the 512-byte ring.
    assert_eq!((status.errors.link_dropped, status.errors.link_overruns), (0, 0), "{:?}", status.errors);
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
    let c = &mut rig.link.session;
    // The arm sent over the link, joint by joint, replaces the built-in one (the firmware's
    // deepest path: a whole new controller).
    let so101 = ArmSpec::load("so101", None).unwrap();
    c.configure_arm(&so101, &ServoSetup::for_arm("so101").unwrap(), 0).unwrap();
    torque_on(c);
    // A servo falls silent mid-move: reported lost, then back, and the move completes.
    c.move_joints([0.5, 0.3, -0.3, 0.2, 0.0].into_iter().collect(), Timing::Duration(3.0)).unwrap();
    poll_for(c, Duration::from_millis(300));
    rig.bus.set_faults(Faults { silent: vec![3], ..Faults::default() });
    let status = poll_for(c, Duration::from_millis(500));
    assert_eq!(status.lost_servos, 1 << 2, "servo 3 (joint 3) reported lost");
    assert!(status.errors.bus_timeouts >= 5);
    rig.bus.set_faults(Faults::default());
    poll_for(c, Duration::from_millis(300));
    let status = c.wait_idle(2000).unwrap();
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
        c.pause().unwrap();
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
    let c = &mut rig.link.session;
    torque_on(c);
    c.gripper(0.0, None).unwrap();
    let held = poll_until(c, Duration::from_secs(5), |s| s.gripper.is_some_and(|g| g.holding));
    let g = held.gripper.expect("the built-in SO-101 has a gripper");
    assert!(g.holding, "no grasp: {g:?}");
    let contact = 30.0 / gripper.opening_mm * 100.0;
    assert!((f64::from(g.opening) - contact).abs() < 0.3, "stopped at {g:?}, the object at {contact:.1} %");
    assert!(g.load.abs() >= 10.0, "load {g:?}");
    c.gripper(100.0, None).unwrap();
    let open = poll_until(c, Duration::from_secs(5), |s| s.gripper.is_some_and(|g| g.opening > 99.0));
    let g = open.gripper.unwrap();
    assert!(!g.holding && g.opening > 99.0, "{g:?}");
    assert_eq!(open.errors.bus_errors, 0);
    drop(rig.link);
    rig.bus.stop().unwrap();
}

/// The firmware under QEMU on the simulated servos of `arm` (a preset's name or an arm file),
/// sent over the link as `armctl --port PTY --arm ...` sends it: the board switches from its
/// built-in SO-101 on Feetech to the arm's joints, gripper, protocol and baud rate.
fn rig_for(arm: &str) -> Option<(Rig, ArmSpec)> {
    let spec = ArmSpec::load(arm, None).unwrap();
    let rig = rig_on(armctl::sim::arm_bus(&spec, Faults::default()).unwrap(), Some(arm))?;
    assert_eq!(rig.link.info.arm_name.as_str(), spec.name);
    assert_eq!(usize::from(rig.link.info.joints), spec.dof());
    Some((rig, spec))
}

/// A joint vector a fraction of the way from the middle of each joint's range to its ends.
fn inside(arm: &ArmSpec, fractions: impl Fn(usize) -> f64) -> Vec<f32> {
    arm.joints
        .iter()
        .enumerate()
        .map(|(j, joint)| {
            let (middle, half) = ((joint.lower + joint.upper) / 2.0, (joint.upper - joint.lower) / 2.0);
            (middle + fractions(j) * half) as f32
        })
        .collect()
}

/// A Cartesian target: the tool at joint values `q`.
fn tool_at(arm: &ArmSpec, q: &[f32]) -> [f32; 3] {
    tool_position(arm, q).map(|x| x as f32)
}

/// One board binary for any arm: `arm` sent over the link, then two Cartesian targets (the tool
/// at two joint vectors inside the ranges) reached within 1 mm; 60 keyframes with the gripper
/// streamed past the 32-slot queue with no underrun; the gripper closed and opened. No servo got a
/// goal outside its limits. A host that reconnects finds the arm it sent (with the torque on, a
/// second sending would be refused); an arm refused at commit, or on a bus the board's UART cannot
/// reach, leaves this one running.
fn any_arm_on_the_real_firmware(arm: &str) {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let Some((mut rig, spec)) = rig_for(arm) else { return };
    let c = &mut rig.link.session;
    torque_on(c);
    // Both clear of the table and of the arm itself on the SO-101 and the OpenManipulator-X (the
    // second was -0.25 cos(j + 2) once: 3 mm from the table on the OpenManipulator-X).
    for fractions in [|j: usize| 0.3 * ((j + 1) as f64).sin(), |j: usize| 0.25 * ((j + 2) as f64).cos()] {
        move_to(c, &spec, tool_at(&spec, &inside(&spec, fractions)));
    }
    // From where the arm stands, each joint swinging up to 0.3 rad and back, kept inside its range;
    // the gripper opening and closing with it.
    let start = c.status().unwrap().measured;
    let keyframes: Vec<JointKeyframe> = (1..=60)
        .map(|k| {
            let t = k as f32 * 0.1;
            let positions = spec.joints.iter().zip(&start).enumerate().map(|(j, (joint, &q0))| {
                let room = (joint.upper as f32 - q0).min(q0 - joint.lower as f32).clamp(0.0, 0.3);
                let phase = j as f32 * 0.5;
                q0 + room * 0.9 * ((std::f32::consts::TAU * t / 3.0 + phase).sin() - phase.sin()) / 2.0
            });
            let gripper = Some(50.0 + 40.0 * (std::f32::consts::TAU * t / 3.0).sin());
            JointKeyframe { time: t, positions: positions.collect(), velocities: None, gripper }
        })
        .collect();
    stream(c, &keyframes);
    // Waits in wall time: under QEMU the firmware's clock runs slower than the wall's while it
    // busy-waits for replies (1 ns of virtual time per instruction emulated), and Dynamixel's
    // 500 µs return delays make that most of a tick.
    c.gripper(0.0, None).unwrap();
    let closed = poll_until(c, Duration::from_secs(20), |s| s.gripper.is_some_and(|g| g.opening < 1.0));
    assert!(closed.gripper.is_some_and(|g| g.opening < 1.0 && !g.holding), "{:?}", closed.gripper);
    c.gripper(100.0, None).unwrap();
    let opened = poll_until(c, Duration::from_secs(20), |s| s.gripper.is_some_and(|g| g.opening > 99.0));
    assert!(opened.gripper.is_some_and(|g| g.opening > 99.0), "{:?}", opened.gripper);
    assert_eq!((opened.errors.bus_errors, opened.errors.watchdog_trips), (0, 0));
    let monitor = rig.bus.monitor().unwrap();
    assert!(monitor.checked > 1000, "{monitor:?}");
    assert!(monitor.violations.iter().all(|v| !v.what.contains("outside")), "{:?}", monitor.violations);
    eprintln!(
        "{}: {} goals checked, largest step {:.2} of the speed limit's; stack high-water {} bytes",
        spec.name,
        monitor.checked,
        monitor.max_step_ratio,
        logged_stack(&rig.board)
    );

    // Reconnecting finds the arm as it was sent: the same arm is not sent again (it could not be:
    // the torque is on).
    let held = opened.measured.clone();
    drop(rig.link);
    let path = rig.board.link_path().to_string();
    let mut link =
        open(Target::Port { path, baud: 1_000_000, arm: None, gravity: None }, Some(arm), &mut std::io::sink())
            .unwrap();
    assert_eq!(link.info.arm_name.as_str(), spec.name);
    let c = &mut link.session;
    let status = c.status().unwrap();
    assert_eq!(status.state, RunState::Idle, "torque still on, holding");
    assert!(status.measured.iter().zip(&held).all(|(a, b)| (a - b).abs() < 0.01));

    // Refused sendings change nothing: one cut short (no joints), and one on a bus faster than the
    // MPS2's UART reaches.
    c.torque_off().unwrap();
    poll_until(c, Duration::from_secs(1), |s| s.state == RunState::TorqueOff);
    // An arm cut short is what the product never sends: the raw requests of the link's client.
    let so101 = ArmSpec::load("so101", None).unwrap();
    let messages = configure_messages(&so101, &ServoSetup::for_arm("so101").unwrap()).unwrap();
    for m in messages.iter().take(3) {
        c.client().request(m).unwrap();
    }
    let refused = c.client().request(&HostMessage::ConfigureCommit).unwrap_err().to_string();
    assert!(refused.contains("not possible"), "{refused}");
    let mut fast = ServoSetup::for_arm("open-manipulator-x").unwrap();
    fast.baud = 2_000_000;
    let omx = ArmSpec::load("open-manipulator-x", None).unwrap();
    // The status says TorqueOff as soon as the request is taken, but the torque goes off at the
    // firmware's next tick, and until then a commit is refused "not possible": under QEMU on a
    // loaded machine that tick can come after the messages above, so each is sent again while
    // not ready (the session's configure_arm, made for this). Only the commit is refused, for
    // its bus: every message before it was taken.
    let refused = format!("{:#}", c.configure_arm(&omx, &fast, NOT_READY_WAITS).unwrap_err());
    assert!(refused.contains("servo bus"), "{refused}");
    assert_eq!(c.hello().unwrap().arm_name.as_str(), spec.name);
    torque_on(c);
    move_to(c, &spec, tool_at(&spec, &inside(&spec, |j| 0.2 * ((j + 3) as f64).sin())));
    drop(link);
    rig.bus.stop().unwrap();
}

#[test]
fn the_real_firmware_drives_an_open_manipulator_x_on_dynamixel() {
    any_arm_on_the_real_firmware("open-manipulator-x");
}

#[test]
fn the_real_firmware_drives_a_six_joint_arm_file_on_feetech() {
    any_arm_on_the_real_firmware(concat!(env!("CARGO_MANIFEST_DIR"), "/../host/examples/arms/six-dof.toml"));
}

/// RAM far from anything the firmware uses (its statics and stack are within the first 64 KiB of
/// the 4 MiB at 0x20000000): where the resets test puts the instruction it points the core at.
const SCRATCH: u32 = 0x2030_0000;

/// Waits for the firmware to start again after a reset: its start line among the log's lines after
/// the first `seen`; returns those lines.
fn restarted(board: &Qemu, seen: usize) -> Vec<String> {
    let end = std::time::Instant::now() + qemu::START_TIMEOUT;
    loop {
        let lines = board.log().lines_from(seen);
        if lines.iter().any(|l| l.contains("static state:")) {
            return lines;
        }
        assert!(std::time::Instant::now() < end, "the firmware did not start again: {lines:#?}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Whether servo `id` has its torque on as the simulated servo itself has it, asked until it says
/// `expected` or 10 s have passed: a hand can turn a horn only while its torque is off
/// ([`PtyServer::hand`]), and then does (to 2048, the middle).
fn servo_torque_becomes(bus: &PtyServer, id: u8, expected: bool) -> bool {
    let end = std::time::Instant::now() + Duration::from_secs(10);
    loop {
        let ticket = bus.hand(id, 2048, 2048, 0.05);
        let torqued = loop {
            if let Some(event) = bus.hand_events().into_iter().find(|e| e.ticket == ticket) {
                break match event.result {
                    Ok(()) => false,
                    Err(why) if why.contains("torque on") => true,
                    Err(why) => panic!("the hand could not tell servo {id}'s torque: {why}"),
                };
            }
            assert!(std::time::Instant::now() < end + Duration::from_secs(5), "the hand never came back");
            std::thread::sleep(Duration::from_millis(10));
        };
        if torqued == expected || std::time::Instant::now() > end {
            return torqued;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The host link opened again (after the board reset: a new session).
fn reopen(board: &Qemu) -> Connection {
    let target = Target::Port { path: board.link_path().to_string(), baud: 1_000_000, arm: None, gravity: None };
    open(target, None, &mut std::io::sink()).unwrap()
}

/// The firmware's status once it has settled into `state` (within 10 s).
fn settles_in(c: &mut Client, state: RunState) -> Status {
    poll_until(c, Duration::from_secs(10), |s| s.state == state)
}

/// Asserts that lines containing `texts` are among `lines`, in that order.
fn logged(lines: &[String], texts: &[&str]) {
    let mut from = 0;
    for text in texts {
        let Some(at) = lines[from..].iter().position(|l| l.contains(text)) else {
            panic!("no \"{text}\" in the log after line {from}: {lines:#?}")
        };
        eprintln!("firmware: {}", lines[from + at]);
        from += at + 1;
    }
}

/// Whether QEMU can run here; if not, the test skips (fails where `CI` is set) saying so.
fn qemu_here() -> bool {
    armctl_test_support::needs_qemu(env!("CARGO_TARGET_TMPDIR"), qemu::available())
}

/// The firmware `elf` started under QEMU with its gdb stub (`Qemu::start_with_debugger`), on
/// simulated SO-101 servos: after a power-on, the servos' torque goes off.
fn debugged(elf: std::path::PathBuf) -> (PtyServer, Qemu, QemuConfig) {
    let bus = PtyServer::spawn(so101_bus(Faults::default())).unwrap();
    let config = QemuConfig::new(elf, Some(bus.path().to_string()));
    let board = Qemu::start_with_debugger(&config).unwrap();
    board.wait_started(qemu::START_TIMEOUT).unwrap();
    logged(&board.log().lines(), &["reset by power-on: the servos' torque goes off"]);
    (bus, board, config)
}

/// The torque switched on over `link` and the firmware idle, servo 1 torqued as the servo itself
/// says.
fn torqued(link: &mut Connection, bus: &PtyServer) {
    torque_on(&mut link.session);
    settles_in(&mut link.session, RunState::Idle);
    assert!(servo_torque_becomes(bus, 1, true), "torque on did not reach servo 1");
}

/// Points the core, stopped by `gdb`, at `instruction` (a Thumb instruction's two bytes, written
/// to [`SCRATCH`]), and lets it run.
fn run_at_scratch(mut gdb: Gdb, instruction: [u8; 2]) {
    gdb.write_memory(SCRATCH, &instruction).unwrap();
    gdb.set_pc(SCRATCH | 1).unwrap();
    gdb.resume().unwrap();
}

/// `b .`: a branch to itself, the core stopped for good as far as the watchdog can tell.
const SPIN: [u8; 2] = [0xfe, 0xe7];

/// The firmware stopped some way after the log's first `seen` lines: lines containing `texts`
/// come in that order (then the watchdog's NMI, then its reset, which takes the torque off), it
/// starts again, and servo 1 goes limp. Returns the host link, opened again, the firmware settled
/// with its torque off.
fn watchdog_takes_the_torque_off(board: &Qemu, bus: &PtyServer, seen: usize, texts: &[&str]) -> Connection {
    let lines = restarted(board, seen);
    let texts = [texts, &[WATCHDOG_NMI, "reset by the watchdog: the servos' torque goes off"]].concat();
    logged(&lines, &texts);
    let mut link = reopen(board);
    assert!(!servo_torque_becomes(bus, 1, false), "servo 1 kept its torque after the watchdog's reset");
    settles_in(&mut link.session, RunState::TorqueOff);
    link
}

/// The watchdog's NMI line: nothing has fed it for 100 ms.
const WATCHDOG_NMI: &str = "watchdog: the firmware stopped; the board resets";

/// Each reset the MPS2 can tell apart under QEMU, acted out from outside as on a board (QEMU's gdb
/// stub stands in for a probe), does to the simulated servos' torque what
/// `firmware::board::reset` decides: the reset button (QEMU's `system_reset`) keeps it, held where
/// the arm stands; a stopped control loop (the core sent to a branch-to-self: the watchdog), a
/// fault (an undefined instruction: the HardFault handler, then the watchdog) and a power-on (a
/// new QEMU on the same, still torqued, servos) take it off. The servos are asked directly.
#[test]
fn each_reset_does_to_the_servos_torque_what_the_board_decides() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    if !qemu_here() {
        return;
    }
    let (bus, board, config) = debugged(qemu::build(qemu::FIRMWARE_BIN).unwrap());
    let mut link = reopen(&board);
    torqued(&mut link, &bus);

    // The reset button: held where it stands.
    drop(link);
    let seen = board.log().lines().len();
    let mut gdb = board.debugger().unwrap();
    gdb.monitor("system_reset").unwrap();
    gdb.resume().unwrap();
    logged(&restarted(&board, seen), &["reset by the reset pin: servos found torqued are held where they stand"]);
    let mut link = reopen(&board);
    settles_in(&mut link.session, RunState::Idle);
    std::thread::sleep(Duration::from_millis(500));
    assert!(servo_torque_becomes(&bus, 1, true), "the reset button took servo 1's torque off");
    assert_eq!(link.session.status().unwrap().state, RunState::Idle);

    // The control loop stops (the core spins on `b .`): the watchdog resets the board, limp.
    drop(link);
    let seen = board.log().lines().len();
    run_at_scratch(board.debugger().unwrap(), SPIN);
    let mut link = watchdog_takes_the_torque_off(&board, &bus, seen, &[]);

    // A fault (an undefined instruction, `udf #254`): logged where, then the watchdog, limp.
    torqued(&mut link, &bus);
    drop(link);
    let seen = board.log().lines().len();
    run_at_scratch(board.debugger().unwrap(), [0xfe, 0xde]);
    let lines = restarted(&board, seen);
    logged(&lines, &["HardFault: pc 0x20300000", "reset by a fault (then the watchdog): the servos' torque goes off"]);
    let mut link = reopen(&board);
    assert!(!servo_torque_becomes(&bus, 1, false), "servo 1 kept its torque after the fault");
    settles_in(&mut link.session, RunState::TorqueOff);

    // Power-on: the board starts anew (a new QEMU) on servos still torqued.
    torqued(&mut link, &bus);
    drop(link);
    drop(board);
    let board = Qemu::start(&config).unwrap();
    board.wait_started(qemu::START_TIMEOUT).unwrap();
    logged(&board.log().lines(), &["reset by power-on: the servos' torque goes off"]);
    let mut link = reopen(&board);
    assert!(!servo_torque_becomes(&bus, 1, false), "servo 1 kept its torque after a power-on");
    settles_in(&mut link.session, RunState::TorqueOff);
    drop(link);
    drop(board);
    bus.stop().unwrap();
}

/// A start-up that stops ends in the watchdog's reset, and the servos' torque goes off: the
/// watchdog runs from the first line of `main`. Acted out with the servos torqued: the reset
/// button (`system_reset`, which on its own keeps the torque), the core stopped by a breakpoint
/// at the board's `start` and sent to a branch-to-self there.
#[test]
fn a_start_up_that_stops_ends_in_the_watchdogs_reset_with_the_torque_off() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    if !qemu_here() {
        return;
    }
    let elf = qemu::build(qemu::FIRMWARE_BIN).unwrap();
    let start = qemu::function_address(&elf, "board_mps2_an386::start").unwrap();
    let held = "reset by the reset pin: servos found torqued are held where they stand";
    stopped_while_torqued(elf, &[held], |mut gdb| {
        gdb.set_breakpoint(start).unwrap();
        gdb.monitor("system_reset").unwrap();
        let stop = gdb.run_to_stop(qemu::START_TIMEOUT).unwrap();
        eprintln!("stopped at start ({start:#x}): {stop}");
        gdb.remove_breakpoint(start).unwrap();
        run_at_scratch(gdb, SPIN);
    });
}

/// A panic ends in the watchdog's reset, and the servos' torque goes off: the board binary built
/// with debug assertions (`qemu::PANIC_TEST_PROFILE`, whose panic handler logs and stops; the
/// release build has no panic path) runs with the servos torqued, and the core is sent to its
/// `injected_panic`.
#[test]
fn a_panic_ends_in_the_watchdogs_reset_with_the_torque_off() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    if !qemu_here() {
        return;
    }
    let built = std::time::Instant::now();
    let elf = qemu::build_with_profile(qemu::FIRMWARE_BIN, qemu::PANIC_TEST_PROFILE).unwrap();
    eprintln!("the {} build: {:.1} s", qemu::PANIC_TEST_PROFILE, built.elapsed().as_secs_f64());
    let injected = qemu::function_address(&elf, "injected_panic").unwrap();
    stopped_while_torqued(elf, &["panic at src/main.rs:"], |mut gdb| {
        gdb.set_pc(injected | 1).unwrap();
        gdb.resume().unwrap();
    });
}

/// The firmware `elf` under QEMU, its servos torqued, then stopped by `stop` (given the debugger,
/// the machine halted): lines containing `texts` follow in that order, then the watchdog's reset,
/// and the servos go limp.
fn stopped_while_torqued(elf: std::path::PathBuf, texts: &[&str], stop: impl FnOnce(Gdb)) {
    let (bus, board, _) = debugged(elf);
    let mut link = reopen(&board);
    torqued(&mut link, &bus);
    drop(link);
    let seen = board.log().lines().len();
    stop(board.debugger().unwrap());
    drop(watchdog_takes_the_torque_off(&board, &bus, seen, texts));
    drop(board);
    bus.stop().unwrap();
}
