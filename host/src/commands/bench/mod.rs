//! Benchmarks: `armctl bench ik` (the solve-rate protocol, beside the `k` crate's solver when built
//! with the `compare-k` feature), `bus`
//! (wire time of a control cycle), `rate` (the controller's rate against the wire-time limit) and
//! `mcu` (instructions per operation on the Cortex-M4F under QEMU), `loop-pass` (the main loop's
//! longest pass under QEMU, scaled to the STM32F411, against its watchdog) and `pc` (the core hosted
//! on this PC against simulated servos on a pty, in real time), `plan` (planning around obstacles
//! and one collision check, on the host).

pub mod bus;
pub mod ik;
#[cfg(feature = "compare-k")]
pub mod k;
pub mod loop_pass;
pub mod mcu;
pub mod pc;
pub mod plan;
pub mod rate;
pub mod servos;
