//! Where the firmware core runs on this PC: [`sil`] (compiled in, on a virtual clock, against
//! simulated servos) and [`qemu`] (the real board binary under `qemu-system-arm`), with the board
//! build ([`board`]) that QEMU, the footprint report and the instruction counts share.

pub mod board;
pub mod qemu;
pub mod sil;
