//! `armctl view` in a real browser: runs host/tests/view/e2e.mjs (node, playwright-core and
//! Debian's headless Chromium; helpers shared with rig.mjs in harness.mjs), which starts `armctl
//! view --sim`, loads its page and checks the 3D view, a joint slider, dragging the target gizmo, stopping a playing file, the API's refusals
//! of bad input, the token (out of the address bar; requests without it, or from a foreign Origin
//! or Host, refused; a hostile page on another origin in the same browser moves nothing), and
//! measures the cost (websocket messages per second, server CPU). Screenshots and cost.json go to
//! target/view-e2e/ (CI keeps target/). Then host/tests/view/rig.mjs does the same for `armctl
//! view --rig bimanual-so101`: both arms drawn, the second one driven, STOP stopping both.
//!
//! Skips with a message where node, Chromium or the npm packages are missing (`npm ci --prefix
//! host/tests/view`; `apt-get install chromium`), and fails instead when the `CI` variable is set:
//! .ci/run installs them.

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::thread;
use std::time::{Duration, Instant};

/// Longer than the script's own limit (3 minutes), which ends the server and the browser itself.
const WATCHDOG: Duration = Duration::from_secs(240);

/// What the script needs and is missing, each with how to get it.
fn missing(script_dir: &Path, chromium: &Path) -> Vec<(String, String)> {
    let mut missing = Vec::new();
    let node = Command::new("node").arg("--version").stdout(Stdio::null()).stderr(Stdio::null()).status();
    if !node.is_ok_and(|s| s.success()) {
        missing.push(("node".to_string(), "apt-get install nodejs npm".to_string()));
    }
    if !chromium.is_file() {
        missing.push((chromium.display().to_string(), "apt-get install chromium, or set CHROMIUM".to_string()));
    }
    if !script_dir.join("node_modules/playwright-core").is_dir() {
        missing.push(("playwright-core".to_string(), "npm ci --prefix host/tests/view".to_string()));
    }
    missing
}

/// Echoes a pipe line by line as it comes (the test harness captures it unless --nocapture) and
/// returns all of it.
fn echo(pipe: impl Read + Send + 'static) -> thread::JoinHandle<String> {
    thread::spawn(move || {
        let mut all = String::new();
        for line in BufReader::new(pipe).lines().map_while(Result::ok) {
            println!("{line}");
            all.push_str(&line);
            all.push('\n');
        }
        all
    })
}

/// One browser test at a time: each runs Chromium's software WebGL and real-time simulated arms,
/// and measures timing, on a shared machine.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

#[test]
fn the_page_shows_and_drives_the_simulated_arm() {
    if let Some(stdout) = run_script("e2e.mjs") {
        assert!(stdout.lines().any(|l| l.starts_with("cost: ")), "no cost line:\n{stdout}");
    }
}

/// `armctl view --rig bimanual-so101`: host/tests/view/rig.mjs checks that the page draws both arms
/// at their bases and lists their telemetry, drives the second arm once it is picked (a slider,
/// a world-frame target), and that STOP stops both.
#[test]
fn the_rig_page_draws_both_arms_and_drives_the_second() {
    run_script("rig.mjs");
}

/// Runs `script` (in host/tests/view) with node and asserts it passed; returns its stdout, or
/// `None` where it was skipped.
fn run_script(script: &str) -> Option<String> {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let host = Path::new(env!("CARGO_MANIFEST_DIR"));
    let script_dir = host.join("tests/view");
    let chromium = std::env::var_os("CHROMIUM").map_or_else(|| PathBuf::from("/usr/bin/chromium"), PathBuf::from);
    let missing = missing(&script_dir, &chromium);
    if !missing.is_empty() {
        let (what, install): (Vec<_>, Vec<_>) = missing.into_iter().unzip();
        armctl_test_support::skip(env!("CARGO_TARGET_TMPDIR"), &what.join(", "), &install.join("; "));
        return None;
    }
    let out = host.join("../target/view-e2e");
    std::fs::create_dir_all(&out).expect("the output folder can be made");

    let mut child = Command::new("node")
        .arg(script)
        .current_dir(&script_dir)
        .env("ARMCTL", env!("CARGO_BIN_EXE_armctl"))
        .env("VIEW_E2E_OUT", &out)
        .env("CHROMIUM", &chromium)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("node starts");
    let stdout = echo(child.stdout.take().unwrap());
    let stderr = echo(child.stderr.take().unwrap());
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("waiting for node") {
            break status;
        }
        if started.elapsed() > WATCHDOG {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{script} still ran after {} s: killed", WATCHDOG.as_secs());
        }
        thread::sleep(Duration::from_millis(100));
    };
    let stdout = stdout.join().unwrap();
    let stderr = stderr.join().unwrap();
    let failed: Vec<&str> = stdout.lines().filter(|l| l.starts_with("not ok")).collect();
    assert!(
        status.success() && failed.is_empty(),
        "{script} exited with {status}; screenshots in {}\n{}\n{stderr}",
        out.display(),
        failed.join("\n")
    );
    Some(stdout)
}
