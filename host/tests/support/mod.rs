//! What the command-line tests share: running the `armctl` binary and reading what it printed.
//! Each test crate that needs it declares `mod support;`; not every crate uses every item.
#![allow(dead_code)]

pub mod view;

use serde_json::Value;
use std::process::{Command, Stdio};

/// One run of `armctl`.
pub struct Run {
    /// Its exit code.
    pub code: i32,
    /// Everything on stdout.
    pub stdout: String,
    /// Everything on stderr.
    pub stderr: String,
}

impl Run {
    /// The JSON line on stdout of a successful run.
    pub fn json(&self) -> Value {
        assert_eq!(self.code, 0, "exit code; stderr: {}", self.stderr);
        let lines: Vec<&str> = self.stdout.lines().collect();
        assert_eq!(lines.len(), 1, "expected one stdout line, got {:?}", self.stdout);
        serde_json::from_str(lines[0]).unwrap_or_else(|e| panic!("not JSON ({e}): {}", lines[0]))
    }
}

/// Runs `armctl` with `args`, no input, and waits for it.
pub fn armctl(args: &[&str]) -> Run {
    let output =
        Command::new(env!("CARGO_BIN_EXE_armctl")).args(args).stdin(Stdio::null()).output().expect("armctl runs");
    Run {
        code: output.status.code().expect("armctl exits normally"),
        stdout: String::from_utf8(output.stdout).expect("UTF-8 stdout"),
        stderr: String::from_utf8(output.stderr).expect("UTF-8 stderr"),
    }
}
