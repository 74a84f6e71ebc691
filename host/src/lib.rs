//! The host side of the servo-arm project: the `armctl` command-line tool as a library, so that
//! integration tests run exactly the code the binary runs.
#![warn(missing_docs)]

pub mod arm;
pub mod bench;
pub mod bench_bus;
pub mod bench_mcu;
pub mod bench_rate;
pub mod bus_args;
pub mod cli;
pub mod demo;
pub mod demo_plot;
pub mod dof;
pub mod drive;
pub mod footprint;
pub mod kcompare;
pub mod link;
pub mod parse;
pub mod plot;
pub mod qemu;
pub mod servo;
pub mod sil;
pub mod sim;
pub mod trajectory;
