//! What the board binaries share beneath their own code: how a defmt log frame is held and never
//! interleaved ([`frames`]), and the RTT transport ([`rtt_log`], feature `rtt-log`). The firmware
//! state's start-up (static slots, placing, starting) is the firmware core's
//! (`firmware::board::start`), because it needs nothing of the Cortex-M and is tested on the host;
//! what is here needs defmt, a critical section or a linker section, which the core, built for the
//! host too, does without.
//!
//! # Panics
//! Nothing here panics: the release boards have no panic path (`armctl footprint` checks), and
//! defmt's own loggers (defmt-rtt, defmt-semihosting) panic on a frame started inside another.
#![no_std]

pub mod frames;
#[cfg(feature = "rtt-log")]
pub mod rtt_log;
