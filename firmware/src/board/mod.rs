//! What every board shares, so that a board is only its pin map, its UART drivers and its clock:
//!
//! - [`rx_ring`]: the ring the host link's receive interrupt fills, byte by byte, so that no byte
//!   is lost while the loop is busy with the servo bus;
//! - [`main_loop`]: the loop that hands those bytes to the firmware and runs the control tick on
//!   its schedule, and switches the servo bus when the host sends an arm on another one;
//! - [`reset`]: what each cause of a reset does to the servos' torque;
//! - [`start`]: the firmware and its bus master in static memory, placed and started once, and the
//!   main loop over them;
//! - [`watchdog`]: a watchdog's timeout chosen from its clock's worst case and the loop's longest
//!   pass.
//!
//! What needs the Cortex-M itself (defmt, critical sections, linker sections) is not here, since
//! this crate builds for the host too: it is in `firmware/boards/support`, which only the board
//! binaries build.

pub mod main_loop;
pub mod reset;
pub mod rx_ring;
pub mod start;
pub mod watchdog;

pub use main_loop::MainLoop;
pub use rx_ring::RxRing;
pub use start::{Slots, StartError};

/// The joints a board binary is built for: it drives any arm of 1 to this many joints (and a
/// gripper), the rest padding (fixed joints: see [`crate::app::arm`]).
pub const JOINTS: usize = 6;

/// The servo bus's UART, as the main loop needs it beyond reading and writing: a board switches
/// its baud rate when the host sends an arm on another bus.
pub trait BusPort {
    /// Sets the line's baud rate; the board's [`crate::app::Board::max_bus_baud`] bounds what it is
    /// asked for.
    fn set_baud(&mut self, baud: u32);
}
