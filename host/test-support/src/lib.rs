//! Tests that cannot run on this machine say so where the person running `cargo test --workspace`
//! looks. A test that needs what cargo cannot install (qemu-system-arm, Chromium, motion-capture
//! data) calls [`skip`] when it is missing:
//! - under `CI` that panics: there every test must run;
//! - elsewhere the test announces itself on the process's stderr at once, which libtest does not
//!   capture (it captures only `print!`/`eprint!`), and leaves a record for [`take`]. The last test
//!   binary of the workspace (tests/untested.rs) takes them and lists them, with the commands that
//!   install what is missing, at the end of the run instead of "ok" lines that hid them.
//!
//! The records of one `cargo test` run are kept apart from any other's by the id of the process
//! that started the test binaries, the same cargo for every binary of one run.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The skipped tests of one run, by what they were missing (with its install command).
pub type Untested = BTreeMap<String, Vec<String>>;

/// Skips the calling test because `missing` is not on this machine; `install` is what installs it.
/// `tmp` is the test's `env!("CARGO_TARGET_TMPDIR")`, shared by every test binary of a workspace.
///
/// # Panics
/// Under `CI`, where the test must run.
pub fn skip(tmp: &str, missing: &str, install: &str) {
    let test = test_name();
    assert!(
        std::env::var_os("CI").is_none(),
        "{test}: {missing} is missing, and CI is set: this test must run ({install})"
    );
    let need = format!("{missing} ({install})");
    let _ = writeln!(std::io::stderr().lock(), "SKIPPED {test}: needs {need}");
    let folder = run_folder(Path::new(tmp), std::os::unix::process::parent_id());
    // A record that cannot be written leaves the line above as the only notice: a test is not
    // failed for its bookkeeping.
    let written = std::fs::create_dir_all(&folder).and_then(|()| {
        std::fs::write(folder.join(format!("{}-{}", std::process::id(), file_safe(&test))), format!("{need}\n{test}\n"))
    });
    if let Err(e) = written {
        let _ = writeln!(
            std::io::stderr().lock(),
            "note: the skip of {test} could not be recorded in {}: {e}",
            folder.display()
        );
    }
}

/// Asserts that the pty at `path` is its owner's alone, as `armctl::support::pty_owner` leaves every
/// pty armctl opens or has QEMU open: mode 0600, owned by this user (the owner of /proc/self,
/// proc(5)). Where devpts gives new ptys 0620 (a desktop's mount), only armctl's own chmod makes
/// this hold.
pub fn assert_private(path: &str) {
    use std::os::unix::fs::MetadataExt;
    let pty = std::fs::metadata(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let me = std::fs::metadata("/proc/self").unwrap().uid();
    let (mode, owner) = (pty.mode() & 0o7777, pty.uid());
    assert!(mode == 0o600 && owner == me, "{path}: mode {mode:04o}, owner {owner}; expected 0600 and {me}");
}

/// Whether a test that runs the firmware under QEMU can run: `available` is what
/// `armctl::runtime::qemu::available` found. Skips it (fails under `CI`) with the install command
/// when not.
pub fn needs_qemu(tmp: &str, available: bool) -> bool {
    if !available {
        skip(tmp, "qemu-system-arm", "apt-get install qemu-system-arm");
    }
    available
}

/// The tests skipped so far in this `cargo test` run (the caller's parent process), removed from
/// `tmp` as they are read. Records of runs over a day old are removed too: a test binary run
/// outside cargo leaves records no summary reads.
pub fn take(tmp: &str) -> Untested {
    let root = Path::new(tmp).join(FOLDER);
    let mine = run_folder(Path::new(tmp), std::os::unix::process::parent_id());
    let mut untested = Untested::new();
    for entry in std::fs::read_dir(&mine).into_iter().flatten().flatten() {
        if let Ok(text) = std::fs::read_to_string(entry.path()) {
            let mut lines = text.lines();
            if let (Some(need), Some(test)) = (lines.next(), lines.next()) {
                untested.entry(need.to_string()).or_default().push(test.to_string());
            }
        }
    }
    let _ = std::fs::remove_dir_all(&mine);
    let day = std::time::Duration::from_secs(24 * 3600);
    for entry in std::fs::read_dir(&root).into_iter().flatten().flatten() {
        let old = entry.metadata().and_then(|m| m.modified()).is_ok_and(|t| t.elapsed().is_ok_and(|age| age > day));
        if old {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
    for tests in untested.values_mut() {
        tests.sort();
    }
    untested
}

/// The lines that tell what did not run: empty when everything ran.
pub fn report(untested: &Untested) -> String {
    let count: usize = untested.values().map(Vec::len).sum();
    if count == 0 {
        return String::new();
    }
    let mut text = format!(
        "\nNOT RUN on this machine: {count} test{} skipped, for want of what cargo cannot install (under CI they fail instead):\n",
        if count == 1 { "" } else { "s" }
    );
    for (need, tests) in untested {
        text.push_str(&format!("  - {need}: {}\n", tests.join(", ")));
    }
    text
}

const FOLDER: &str = "untested";

fn run_folder(tmp: &Path, run: u32) -> PathBuf {
    tmp.join(FOLDER).join(run.to_string())
}

/// `binary::test`: the test binary's name without cargo's hash, and the test's, which libtest
/// gives the thread it runs the test on (the binary's alone where it runs tests on its main thread).
fn test_name() -> String {
    let binary = std::env::current_exe()
        .ok()
        .and_then(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
        .map(|stem| stem.rsplit_once('-').map_or(stem.clone(), |(name, _hash)| name.to_string()))
        .unwrap_or_else(|| "test".to_string());
    match std::thread::current().name() {
        Some(test) if test != "main" => format!("{binary}::{test}"),
        _ => binary,
    }
}

fn file_safe(name: &str) -> String {
    name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '_' || c == '-' { c } else { '_' }).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_report_lists_every_skipped_test_under_what_it_needs() {
        let mut untested = Untested::new();
        untested.insert(
            "qemu-system-arm (apt-get install qemu-system-arm)".into(),
            vec!["hil_qemu::a".into(), "hil_qemu::b".into()],
        );
        untested.insert("node (apt-get install nodejs npm)".into(), vec!["view_browser::c".into()]);
        let text = report(&untested);
        assert!(text.contains("3 tests skipped"), "{text}");
        assert!(
            text.contains("  - qemu-system-arm (apt-get install qemu-system-arm): hil_qemu::a, hil_qemu::b\n"),
            "{text}"
        );
        assert!(text.contains("  - node (apt-get install nodejs npm): view_browser::c\n"), "{text}");
        assert_eq!(report(&Untested::new()), "");
    }

    #[test]
    fn records_are_taken_once_by_the_run_that_made_them() {
        let tmp = tempfile::tempdir().unwrap();
        let tmp_str = tmp.path().to_str().unwrap();
        let run = std::os::unix::process::parent_id();
        let folder = run_folder(tmp.path(), run);
        std::fs::create_dir_all(&folder).unwrap();
        std::fs::write(folder.join("1-x"), "qemu (apt-get install qemu)\nhil::x\n").unwrap();
        // Another run's records (another cargo) are not this run's.
        let other = run_folder(tmp.path(), run.wrapping_add(1));
        std::fs::create_dir_all(&other).unwrap();
        std::fs::write(other.join("1-y"), "node (apt-get install nodejs)\nview::y\n").unwrap();

        let taken = take(tmp_str);
        assert_eq!(taken.len(), 1, "{taken:?}");
        assert_eq!(taken["qemu (apt-get install qemu)"], vec!["hil::x".to_string()]);
        assert!(!folder.exists(), "the run's records are removed once read");
        assert!(other.exists(), "a recent record of another run stays");
        assert!(take(tmp_str).is_empty(), "taken twice");
    }

    #[test]
    fn a_test_is_named_by_its_binary_and_its_thread() {
        let name = std::thread::Builder::new().name("module::a_test".into()).spawn(test_name).unwrap().join().unwrap();
        assert!(name.ends_with("::module::a_test"), "{name}");
        assert!(!name.contains(char::is_whitespace), "{name}");
    }
}
