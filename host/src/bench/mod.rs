//! Benchmarks: `armctl bench ik` (the solve-rate protocol, beside the `k` crate's solver), `bus`
//! (wire time of a control cycle), `rate` (the controller's rate against the wire-time limit) and
//! `mcu` (instructions per operation on the Cortex-M4F under QEMU).

pub mod bus;
pub mod ik;
pub mod k;
pub mod mcu;
pub mod rate;
