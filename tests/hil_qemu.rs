//! Hardware in the loop, simulated: the real firmware binary for the MPS2 AN386 (Cortex-M4F) runs
//! under `qemu-system-arm -icount shift=0`, its UART1 on the simulated servo bus's pty and its
//! UART0 on a pty that the host's link client opens as a serial port (the serialport crate), as
//! `armctl --port` does with a board. Skips with a message where qemu-system-arm is missing, and
//! fails instead when the `CI` variable is set.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

use armctl::drive::connection::handshake;
use armctl::link::client::LinkError;
use armctl::link::client::{LinkClient, LinkConfig};
use armctl::sim::{Faults, PtyServer, SimConfig};
use firmware::bus::table::STS3215;
use firmware::link::message::{CartesianTarget, HostMessage, NakReason, RunState, Timing};
use serialport::SerialPort;

/// Kills QEMU when the test ends, however it ends.
struct Qemu(Child);

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn qemu_available() -> bool {
    let found = Command::new("qemu-system-arm").arg("--version").stdout(Stdio::null()).status().is_ok();
    if !found {
        assert!(std::env::var_os("CI").is_none(), "qemu-system-arm is missing, and CI is set: the HIL tests must run");
        eprintln!(
            "SKIPPED: qemu-system-arm is not installed (apt-get install qemu-system-arm); the HIL test did not run"
        );
    }
    found
}

/// Builds the board binary (release) and returns the ELF's path.
fn firmware_elf() -> PathBuf {
    let board = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../firmware/boards/mps2-an386");
    let status = Command::new("cargo").args(["build", "--release", "--quiet"]).current_dir(&board).status().unwrap();
    assert!(status.success(), "the mps2-an386 firmware builds");
    board.join("target/thumbv7em-none-eabihf/release/board-mps2-an386")
}

#[test]
fn the_real_firmware_under_qemu_drives_simulated_servos_to_a_target() {
    if !qemu_available() {
        return;
    }
    let elf = firmware_elf();
    let bus = PtyServer::spawn(SimConfig {
        protocol: STS3215.protocol,
        model: &STS3215,
        ids: (1..=5).collect(),
        baud: 1_000_000,
        faults: Faults::default(),
        duplicates: Vec::new(),
        fixed_baud: true,
    })
    .unwrap();
    // The host link's pty is made here and handed to QEMU by path, like the bus's.
    let (mut link, slave) = serialport::TTYPort::pair().unwrap();
    link.set_timeout(std::time::Duration::from_millis(20)).unwrap();
    let slave_path = slave.name().unwrap();
    let child = Command::new("qemu-system-arm")
        .args(["-machine", "mps2-an386", "-nographic", "-monitor", "none", "-icount", "shift=0", "-kernel"])
        .arg(&elf)
        .args(["-serial", &slave_path, "-serial", bus.path()])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let qemu = Qemu(child);
    let mut client = LinkClient::new(link, LinkConfig::default());
    let (info, arm) = handshake(&mut client, None).unwrap();
    assert_eq!(info.arm_name.as_str(), "so101");
    assert_eq!(info.queue_capacity, 32);
    let c = &mut client;
    for _ in 0..100 {
        match c.request(&HostMessage::Torque { on: true }) {
            Err(LinkError::Nak(NakReason::NotReady)) => c.wait_once().unwrap(),
            other => {
                other.unwrap();
                break;
            }
        }
    }
    let target = [0.2f32, 0.05, 0.15];
    c.request(&HostMessage::MoveTo {
        target: CartesianTarget { position: target, orientation: None },
        timing: Timing::MaxSpeed(0.2),
    })
    .unwrap();
    let mut status = c.status().unwrap();
    for _ in 0..1500 {
        if status.state == RunState::Idle {
            break;
        }
        c.wait_once().unwrap();
        status = c.status().unwrap();
    }
    assert_eq!(status.state, RunState::Idle);
    let q: Vec<f64> = status.measured.iter().map(|x| f64::from(*x)).collect();
    let reached = armctl::dof::build(arm).unwrap().tool_pose(&q).unwrap().translation;
    let error = ((reached.x - 0.2).powi(2) + (reached.y - 0.05).powi(2) + (reached.z - 0.15).powi(2)).sqrt();
    assert!(error < 1e-3, "reached {reached:?}, {error} m from the target");
    assert_eq!(status.errors.bus_errors, 0);
    drop(qemu);
    drop(slave);
    bus.stop().unwrap();
}
