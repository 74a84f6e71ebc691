//! Where the firmware core runs on this PC: [`sil`] (compiled in, on a virtual clock, against
//! simulated servos), [`pc`] (compiled in, on the PC's clock, against the servos of a USB adapter
//! or a simulated bus on a pty), [`serve`] (a core's link on a pty, for other programs) and
//! [`qemu`] (the real board binary under `qemu-system-arm`), with the board
//! build ([`board`]) that QEMU, the footprint report and the instruction counts share. [`qemu`]
//! decodes the firmware's defmt log, so it is built with the `board-tools` feature.

pub mod board;
pub mod connection;
pub mod pc;
#[cfg(feature = "board-tools")]
pub mod qemu;
pub mod serve;
pub mod servo_session;
pub mod session;
pub mod sil;
