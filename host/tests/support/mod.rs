//! What the command-line tests share: running the `armctl` binary and reading what it printed.
//! Each test crate that needs it declares `mod support;`; not every crate uses every item.
#![allow(dead_code)]

pub mod view;

use serde_json::Value;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

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

/// Asserts a failed run: exit code 1 (2 for clap's own usage errors), nothing on stdout, one
/// stderr line starting `error:` that contains every one of `needles`.
pub fn assert_fails(args: &[&str], needles: &[&str]) {
    let run = armctl(args);
    assert!(run.code == 1 || run.code == 2, "{args:?} should fail; code {}, stdout: {}", run.code, run.stdout);
    assert!(run.stdout.is_empty(), "{args:?}: stdout should be empty, got {:?}", run.stdout);
    let lines: Vec<&str> = run.stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{args:?}: expected one stderr line, got {:?}", run.stderr);
    assert!(lines[0].starts_with("error:"), "{args:?}: {}", lines[0]);
    for needle in needles {
        assert!(lines[0].contains(needle), "{args:?}: {:?} does not mention {needle:?}", lines[0]);
    }
}

/// A file path in a folder of its own, made by `tempfile`: the folder and whatever the test wrote
/// in it are removed when this is dropped, also when the test fails. Reads as a [`Path`].
pub struct TempPath {
    path: PathBuf,
    _dir: tempfile::TempDir,
}

impl TempPath {
    /// `name` (which may hold folders that are not made) in a fresh folder.
    pub fn new(name: &str) -> Self {
        let dir = tempfile::Builder::new().prefix("armctl-test-").tempdir().expect("a temporary folder");
        Self { path: dir.path().join(name), _dir: dir }
    }
}

impl std::ops::Deref for TempPath {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.path
    }
}

impl AsRef<Path> for TempPath {
    fn as_ref(&self) -> &Path {
        &self.path
    }
}

/// Runs `armctl serve` with `args`; returns the child, the pty path it printed first (checked to
/// be its owner's alone) and the thread that collects its stderr.
pub fn serve(args: &[&str]) -> (Child, String, std::thread::JoinHandle<String>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_armctl"))
        .arg("serve")
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("armctl serve starts");
    let mut stderr = child.stderr.take().unwrap();
    let errors = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = stderr.read_to_string(&mut text);
        text
    });
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut first).unwrap();
    assert!(first.starts_with("/dev/"), "first stdout line should be the pty path, got {first:?}");
    let path = first.trim().to_string();
    if let Err(e) = std::panic::catch_unwind(|| armctl_test_support::assert_private(&path)) {
        let _ = child.kill();
        let _ = child.wait();
        std::panic::resume_unwind(e);
    }
    (child, path, errors)
}

/// Runs `armctl sim servos` with `args` (stdin closed, stderr to `stderr`); returns the child and
/// the first line it printed (the pty's path with `--pty`).
pub fn sim_servos(args: &[&str], stderr: Stdio) -> (Child, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_armctl"))
        .args(["sim", "servos"])
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(stderr)
        .spawn()
        .expect("armctl sim servos starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    (child, line.trim().to_string())
}

/// Writes the SO-101 preset without its collision geometry, as the arm file `so101-bare.toml` in
/// `dir` (its servos written out with it), for a test whose subject is not the collision check:
/// poses the SO-101's fitted capsules call collisions (a human motion's, a start folded over the
/// base), which with the geometry are refused before anything moves.
#[allow(dead_code)]
pub fn so101_without_geometry(dir: &Path) -> PathBuf {
    let mut so101 = armctl::arm::ArmSpec::load("so101", None).expect("the so101 preset");
    // The preset's servos come by its name: written out, they go with the new name.
    so101.servos = armctl::arm::servos::servos_of(&so101);
    (so101.name, so101.collision) = ("so101-bare".into(), None);
    let path = dir.join("so101-bare.toml");
    std::fs::write(&path, armctl::arm::toml_writer::to_text(&so101, &[])).expect("the arm file written");
    path
}
