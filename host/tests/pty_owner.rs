//! Every pseudo-terminal armctl opens is its owner's alone (mode 0600), whatever mode the devpts
//! mount gives a new one. This machine's mount may give 0600 already; a usual desktop's gives
//! 0620 (group tty, through which `write` and `wall` reach a terminal). So these tests run armctl
//! in a user and mount namespace of its own, with a devpts instance mounted `mode=620` on its
//! /dev/pts, as on a desktop, and look at the ptys from outside through `/proc/PID/root`. In that
//! instance every pty is one armctl opened. Where unprivileged namespaces are not allowed (or
//! `unshare` is missing) the tests say so and skip: the unit tests of `armctl::support::pty_owner` and
//! the mode checks in sim_servos.rs and pc_bus.rs still run.

use std::io::{BufRead, BufReader, Read};
use std::os::unix::fs::MetadataExt;
use std::path::Path;
use std::process::{Child, Command, Stdio};

/// Mounts a devpts instance of the namespace's own on /dev/pts as a desktop's is mounted (without
/// `gid=5`: group tty is not mapped into the namespace), then runs the rest of the command line.
const DESKTOP_DEVPTS: &str =
    "mount -t devpts -o newinstance,mode=620,ptmxmode=666 devpts /dev/pts && exec \"$0\" \"$@\"";

fn unshare() -> Command {
    let mut command = Command::new("unshare");
    command.args(["--user", "--map-root-user", "--mount", "sh", "-c", DESKTOP_DEVPTS]);
    command
}

/// Whether this machine lets the tests mount a devpts of their own; says why not if it does not.
fn namespaces_allowed() -> bool {
    let probe = unshare().arg("true").stdin(Stdio::null()).stdout(Stdio::null()).stderr(Stdio::piped()).output();
    match probe {
        Ok(out) if out.status.success() => true,
        Ok(out) => {
            let why = String::from_utf8_lossy(&out.stderr);
            let what = format!("a devpts of its own in a user namespace ({})", why.trim());
            armctl_test_support::skip(
                env!("CARGO_TARGET_TMPDIR"),
                &what,
                "sysctl kernel.unprivileged_userns_clone=1, or a machine that allows user namespaces",
            );
            false
        }
        Err(e) => {
            armctl_test_support::skip(
                env!("CARGO_TARGET_TMPDIR"),
                &format!("unshare ({e})"),
                "apt-get install util-linux",
            );
            false
        }
    }
}

/// A running armctl, killed when dropped (a failed assertion included).
struct Running(Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// `armctl ARGS` on the desktop-like devpts; returns it and its first stdout line.
fn armctl_on_desktop_devpts(args: &[&str]) -> (Running, String) {
    let mut child = unshare()
        .arg(env!("CARGO_BIN_EXE_armctl"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("unshare starts");
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut first).unwrap();
    if first.is_empty() {
        let _ = child.wait();
        let mut why = String::new();
        let _ = child.stderr.take().unwrap().read_to_string(&mut why);
        panic!("armctl {args:?} printed no pty: {why}");
    }
    (Running(child), first.trim().to_string())
}

/// The path, mode (in octal) and owner of every pty in `child`'s devpts instance, its ptmx left
/// out.
fn ptys_of(Running(child): &Running) -> Vec<(String, String, u32)> {
    let root = format!("/proc/{}/root", child.id());
    // The namespace's /dev/pts is the desktop-like mount, or nothing here would mean anything.
    let mounts = std::fs::read_to_string(format!("/proc/{}/mountinfo", child.id())).unwrap();
    let devpts = mounts.lines().rfind(|l| l.split(' ').nth(4) == Some("/dev/pts"));
    assert!(devpts.is_some_and(|l| l.contains("mode=620")), "the namespace's /dev/pts: {devpts:?}");
    let mut ptys: Vec<(String, String, u32)> = std::fs::read_dir(Path::new(&root).join("dev/pts"))
        .unwrap()
        .flatten()
        .filter(|e| e.file_name() != "ptmx")
        .map(|e| {
            let meta = e.metadata().unwrap();
            (
                format!("/dev/pts/{}", e.file_name().to_string_lossy()),
                format!("{:04o}", meta.mode() & 0o7777),
                meta.uid(),
            )
        })
        .collect();
    ptys.sort();
    ptys
}

/// This user (the owner of /proc/self: the effective user, proc(5)).
fn me() -> u32 {
    std::fs::metadata("/proc/self").unwrap().uid()
}

/// `armctl sim servos --pty`: the one pty, the printed one, is 0600 and this user's.
#[test]
fn sim_servos_makes_its_pty_private_where_devpts_gives_0620() {
    if !namespaces_allowed() {
        return;
    }
    let (child, path) = armctl_on_desktop_devpts(&["sim", "servos", "--protocol", "sts", "--ids", "1", "--pty"]);
    let ptys = ptys_of(&child);
    drop(child);
    assert_eq!(ptys, [(path, "0600".to_string(), me())]);
}

/// `armctl serve --sim`: the link's pty (printed) and the simulated servos' pty behind the core,
/// both 0600 and this user's.
#[test]
fn serve_makes_both_its_ptys_private_where_devpts_gives_0620() {
    if !namespaces_allowed() {
        return;
    }
    let (child, path) = armctl_on_desktop_devpts(&["serve", "--sim"]);
    let ptys = ptys_of(&child);
    drop(child);
    assert_eq!(ptys.len(), 2, "the servos' pty and the link's: {ptys:?}");
    assert!(ptys.iter().any(|(p, ..)| *p == path), "{path} among {ptys:?}");
    for (pty, mode, owner) in &ptys {
        assert_eq!((mode.as_str(), *owner), ("0600", me()), "{pty}: (mode, owner)");
    }
}
