//! The stack depth measured on the MPS2 AN386 firmware under QEMU: the firmware paints its stack
//! (`board_mps2_an386::stack`) and logs the start-up depth once and the control loop's high-water
//! mark each second it grows. Here the firmware is driven through its deepest paths known: a
//! Cartesian move (IK), a streamed joint trajectory, and an arm sent over the link (a whole new
//! controller built in place).

use std::path::Path;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use firmware::link::message::{CartesianTarget, JointKeyframe, Timing};
use serde::Serialize;

use crate::arm::servos::ServoSetup;
use crate::arm::ArmSpec;
use crate::link::session::Keyframe;
use crate::runtime::connection::{open, Target};
use crate::runtime::qemu::{DefmtLog, Qemu, QemuConfig};
use crate::sim::{so101_bus, Faults, PtyServer};

/// The firmware checks its high-water mark once a second: this long after the last operation, the
/// mark it reached is logged.
const SETTLE: Duration = Duration::from_millis(1500);
/// Wait slots a request refused with `NotReady` is retried for (4 s at the 20 ms read timeout:
/// start-up under QEMU reads every servo first).
const NOT_READY_WAITS: usize = 200;
/// How long a log line may take to show up once due.
const LOG_TIMEOUT: Duration = Duration::from_secs(10);

/// The stack depths the firmware logged, in bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct MeasuredStack {
    /// Deepest during start-up (hardware and firmware core brought up).
    pub startup: u64,
    /// Deepest in the control loop.
    pub control_loop: u64,
}

/// Runs the firmware ELF `elf` (the MPS2 AN386 board binary) under QEMU on simulated SO-101
/// servos, drives it, and reads the stack depths from its log.
pub fn measure(elf: &Path) -> Result<MeasuredStack> {
    let bus = PtyServer::spawn(so101_bus(Faults::default())).context("cannot start the simulated servo bus")?;
    let board = Qemu::start(&QemuConfig::new(elf.to_path_buf(), Some(bus.path().to_string())))?;
    board.wait_started(crate::runtime::qemu::START_TIMEOUT)?;
    let mut link = open(
        Target::Port { path: board.link_path().to_string(), baud: 1_000_000, arm: None, gravity: None },
        None,
        &mut std::io::sink(),
    )?;
    let c = &mut link.session;
    // The SO-101 with collision geometry (its frames' capsules, the table and a box), so that
    // every step below goes through the collision check as well.
    let servos = ServoSetup::for_arm("so101").context("no servo set-up for so101")?;
    let mut checked = ArmSpec::load("so101", None)?;
    let mut geometry = crate::arm::collision::CollisionSpec::from_frames(&checked, 0.02);
    geometry.obstacles.push(crate::arm::collision::ObstacleSpec {
        name: "box".into(),
        shape: kinematics::collision::Shape::aligned_box(
            kinematics::nalgebra::Vector3::new(0.25, -0.25, 0.1),
            kinematics::nalgebra::Vector3::repeat(0.1),
        ),
    });
    checked.collision = Some(geometry);
    checked.name = "so101-checked".into();
    c.configure_arm(&checked, &servos, NOT_READY_WAITS).context("sending the so101 with collision geometry")?;
    // Gravity compensation on, so that every tick below computes its offsets as well.
    let compensation = crate::runtime::gravity::Compensation {
        asked: true,
        ..crate::runtime::gravity::Compensation::by_default(crate::runtime::gravity::Gains::SetUp, Some(0.2))
    };
    // (The SO-101's masses: the renamed arm is the same arm.)
    c.gravity(&crate::runtime::gravity::gravity_parts(&ArmSpec::load("so101", None)?, &compensation)?)
        .context("giving the firmware gravity compensation")?;
    c.torque_on(NOT_READY_WAITS).context("torque on")?;
    c.move_to(
        CartesianTarget { position: [0.2, 0.05, 0.15], orientation: None },
        Timing::MaxSpeed(0.2),
        firmware::link::message::MovePath::Auto,
    )?;
    c.wait_idle(2000)?;
    // More keyframes than the queue holds, streamed as slots free (as `armctl play` does).
    for k in 1..=40 {
        let t = k as f32 * 0.1;
        let positions = (0..5)
            .map(|j| 0.3 * (std::f32::consts::TAU * t / 3.0 + j as f32 * 0.5).sin() - 0.3 * (j as f32 * 0.5).sin());
        c.push(&Keyframe::Joints(JointKeyframe {
            time: t,
            positions: positions.collect(),
            velocities: None,
            gripper: None,
        }))
        .with_context(|| format!("keyframe {k}"))?;
        if k == 15 {
            c.start()?;
        }
    }
    c.wait_idle(5000)?;
    // The firmware takes a new arm only with the torque off.
    c.torque_off()?;
    let so101 = ArmSpec::load("so101", None)?;
    c.configure_arm(&so101, &servos, NOT_READY_WAITS).context("sending the so101 arm over the link")?;
    std::thread::sleep(SETTLE);
    let log = board.log();
    let measured = MeasuredStack {
        startup: logged_bytes(log, "start-up stack")?,
        control_loop: logged_bytes(log, "control loop stack high-water")?,
    };
    drop(link);
    bus.stop().context("stopping the simulated servo bus")?;
    Ok(measured)
}

/// The byte count of the last log line containing `text` (`... N bytes`).
pub fn logged_bytes(log: &DefmtLog, text: &str) -> Result<u64> {
    let Some(line) = log.wait_for(text, LOG_TIMEOUT) else {
        bail!("the firmware logged no \"{text}\" line within {LOG_TIMEOUT:?}");
    };
    line.split_whitespace()
        .rev()
        .nth(1)
        .and_then(|n| n.parse().ok())
        .with_context(|| format!("no byte count in the firmware's log line \"{line}\""))
}
