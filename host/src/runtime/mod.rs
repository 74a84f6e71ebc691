//! Where the firmware core runs on this PC: [`sil`] (compiled in, on a virtual clock, against
//! simulated servos), [`pc`] (compiled in, on the PC's clock, against the servos of a USB adapter
//! or a simulated bus on a pty), [`serve`] (a core's link on a pty, for other programs) and
//! [`qemu`] (the real board binary under `qemu-system-arm`), with the board
//! build ([`board`]) that QEMU, the footprint report and the instruction counts share. [`qemu`]
//! decodes the firmware's defmt log, so it is built with the `board-tools` feature. Wherever it
//! runs, [`connection`] opens its link (where the arm is: [`connection::Place`]) and [`driver`]
//! holds it with the arm's kinematics for the drive operations; [`servo_session`] is a servo bus
//! on a real port, for the tools that talk to servos without the core.

pub mod board;
pub mod connection;
pub mod driver;
pub mod gravity;
pub mod pc;
#[cfg(feature = "board-tools")]
pub mod qemu;
pub mod serve;
pub mod servo_session;
pub mod sil;
