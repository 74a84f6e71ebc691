//! The servo bus simulator: N simulated servos on one line, for software-in-the-loop tests in
//! process and, on a pseudo-terminal, for any program that opens a serial port.
//!
//! - [`clock`]: the virtual clock (nanoseconds, shared), a [`firmware::bus::master::Clock`].
//! - [`motion`]: the servos' trapezoidal motion profile (their reference).
//! - [`drive`]: a servo's motor, gearbox, friction, heat and position loop; [`drive_table`] the
//!   published figures of each model, [`drive_models`] which model gets which, through which
//!   registers.
//! - [`physics`]: the drives stepped against the arm's gravity and inertia.
//! - [`servo`]: one servo: control table, instructions, status return level, hardware errors.
//! - [`faults`]: silent servos, corrupted replies, lost bytes and flipped bits, seeded.
//! - [`bus`]: the line: instruction decoding, reply timing, collisions.
//! - [`port`]: the master's end of an in-memory line, an `embedded-io` port on the virtual clock.
//! - [`pty`]: a bus served on a pseudo-terminal, on real time.
//! - [`latency`]: a USB serial adapter's latency timer, for the replies on a pty.
//! - [`monitor`]: safety monitors that check every goal the servos receive.
//! - [`scene`]: an object on the table for a simulated gripper to pick up.
//! - [`world`]: the arm's collision geometry placed by what its servos hold.
//! - [`contact`]: links that run into the table, an obstacle or each other stop there.
//! - [`stall`]: a servo stalled against such a contact: its load, its overload.
//! - [`recording`]: the served servos' positions and goals on a fixed grid of real time, as CSV.
//!
//! The codecs, control tables and wire-time arithmetic are the firmware's own
//! ([`firmware::bus`]): the simulator exercises the same code the boards run.

pub mod bus;
pub mod clock;
pub mod contact;
pub mod drive;
pub mod drive_models;
pub mod drive_table;
pub mod faults;
pub mod latency;
pub mod monitor;
pub mod motion;
pub mod physics;
pub mod port;
pub mod pty;
pub mod recording;
pub mod scene;
pub mod servo;
pub mod stall;
pub mod world;

pub use bus::{BusStats, Frame, SimBus, WireByte};
pub use clock::VirtualClock;
pub use contact::ContactModel;
pub use faults::{FaultStats, Faults};
pub use monitor::{limits_of, GoalLimit, MonitorReport, RealTimeMonitor, DEFAULT_PERIOD};
pub use physics::Physics;
pub use port::{PortStats, SharedBus, SimPort};
pub use pty::{arm_bus, serve_arm, so101_bus, HandHandle, MonitorHandle, PtyServer, Register, ServeOptions, SimConfig};
pub use recording::Recorder;
pub use scene::Scene;
pub use servo::{Jaw, SimServo};
pub use world::World;

/// A bus shared with a port on a fresh virtual clock: what a SIL test connects a master to.
pub fn connect(bus: SimBus) -> (SharedBus, SimPort, VirtualClock) {
    let bus = std::rc::Rc::new(std::cell::RefCell::new(bus));
    let clock = VirtualClock::new();
    let port = SimPort::new(bus.clone(), clock.clone());
    (bus, port, clock)
}
