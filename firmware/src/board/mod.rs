//! What every board shares, so that a board is only its pin map, its UART drivers and its clock:
//!
//! - [`rx_ring`]: the ring the host link's receive interrupt fills, byte by byte, so that no byte
//!   is lost while the loop is busy with the servo bus;
//! - [`main_loop`]: the loop that hands those bytes to the firmware and runs the control tick on
//!   its schedule.

pub mod main_loop;
pub mod rx_ring;

pub use main_loop::MainLoop;
pub use rx_ring::RxRing;
