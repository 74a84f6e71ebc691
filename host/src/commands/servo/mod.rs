//! `armctl servo`: setting up serial bus servos on a real port (what Dynamixel Wizard or LeRobot's
//! set-up scripts are used for): scan a bus, read and write control-table bytes, change a servo's id
//! or baud rate, switch torque.
//!
//! The bus code is the firmware's ([`firmware::bus`]): its codecs, its [`Master`] with timeouts and
//! retries, its model tables. This module adds only what a PC needs around it:
//! - [`crate::link::serial`] (below it): a `serialport` port as an `embedded-io` stream, and a `std` clock;
//! - [`items`]: every named control-table item of a model, to decode what a read returns;
//! - [`crate::runtime::servo_session`]: an open bus, with servo identification and one-line error texts;
//! - [`commands`]: the commands themselves;
//! - [`calibration`]: a LeRobot calibration file checked against the servos, and written to them;
//! - [`calibrate`]: `armctl calibrate`, LeRobot's calibration procedure on an arm's servos;
//! - [`ports`]: `armctl ports`, the USB serial ports and the device behind each;
//! - [`crate::cli::servo`]: their command-line arguments.
//!
//! [`Master`]: firmware::bus::master::Master

pub mod calibrate;
pub mod calibration;
pub mod commands;
pub mod items;
pub mod ports;
