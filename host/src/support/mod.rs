//! What every layer may use, beneath all of them: values people type ([`numbers`],
//! [`json_lines`]), one line of JSON written ([`json_out`]), PNG charts ([`plot`]),
//! pseudo-terminals kept to their owner ([`pty_owner`]), Ctrl-C ([`interrupt`]) and Rust's mangled
//! symbol names read back as paths ([`rust_symbols`]).

pub mod interrupt;
pub mod json_lines;
pub mod json_out;
pub mod numbers;
pub mod plot;
pub mod pty_owner;
pub mod rust_symbols;
