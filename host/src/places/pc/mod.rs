//! Driving a real arm from this PC: the firmware core against the user's USB serial adapter
//! (`armctl --bus PORT --protocol sts|dxl2`). What connecting needs first:
//! - [`latency`]: the FTDI adapter's latency timer, and the warning with its fix when it is slow;
//! - [`setup`]: the servo settings written when connecting (LeRobot's), without switching torque.

pub mod latency;
pub mod setup;
