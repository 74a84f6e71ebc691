//! Every pseudo-terminal that armctl opens, or has QEMU open, takes commands for an arm: it must
//! be its owner's alone. [`make_private`] sets a pty's mode to 0600 and checks the result, and is
//! called as soon as each pty is opened or named, before its path is printed or connected to:
//! `armctl serve`'s link ([`crate::runtime::serve`]), the simulated servo bus
//! ([`crate::sim::PtyServer`]) and QEMU's UART0 (`runtime::qemu`, with the `board-tools` feature).
//!
//! The mode a new pty gets comes from the devpts mount, not from the process: `mode=600` on some
//! machines, but `mode=620,gid=5` (group tty) on a usual desktop Linux, where `write` and `wall`,
//! which run setgid tty, can then put bytes into it. So it is set here, in code, on every
//! machine. Root can open any pty whatever its mode; nothing here changes that.
//!
//! Linux only, as devpts is: this process's user is read from `/proc/self/status`. Uses no other
//! module of this crate.

use std::fs::Permissions;
use std::os::unix::fs::{FileTypeExt, MetadataExt, PermissionsExt};
use std::path::Path;

use anyhow::{anyhow, bail, Result};

/// The mode every pty is given: read and write for its owner, nothing for anyone else.
pub const MODE: u32 = 0o600;

/// Makes the pty at `path` its owner's alone: sets its mode to [`MODE`], then checks that it is a
/// character device owned by this process's (effective) user, and that neither its group nor
/// others keep any permission. An error is one line naming the path.
pub fn make_private(path: impl AsRef<Path>) -> Result<()> {
    let path = path.as_ref();
    secure(path).map_err(|e| anyhow!("cannot make the pseudo-terminal {} its owner's alone: {e:#}", path.display()))
}

fn secure(path: &Path) -> Result<()> {
    if !std::fs::metadata(path)?.file_type().is_char_device() {
        bail!("it is not a character device");
    }
    std::fs::set_permissions(path, Permissions::from_mode(MODE))?;
    // Read back: a file system that ignored the mode, or another owner, would leave it open.
    let meta = std::fs::metadata(path)?;
    let me = effective_uid()?;
    if meta.uid() != me {
        bail!("it belongs to user {}, not to this process's user {me}", meta.uid());
    }
    if meta.mode() & 0o077 != 0 {
        bail!("its mode is still {:04o} after setting {MODE:04o}", meta.mode() & 0o7777);
    }
    Ok(())
}

/// This process's effective user id: the second number of the `Uid:` line of
/// `/proc/self/status` (real, effective, saved, file system; proc(5)).
fn effective_uid() -> Result<u32> {
    let status = std::fs::read_to_string("/proc/self/status")
        .map_err(|e| anyhow!("cannot read /proc/self/status for this process's user: {e}"))?;
    status
        .lines()
        .find_map(|line| line.strip_prefix("Uid:"))
        .and_then(|ids| ids.split_whitespace().nth(1))
        .and_then(|id| id.parse().ok())
        .ok_or_else(|| anyhow!("/proc/self/status names no effective user id"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serialport::{SerialPort, TTYPort};

    fn mode(path: &str) -> u32 {
        std::fs::metadata(path).unwrap().mode() & 0o7777
    }

    /// A pty opened as a desktop's devpts mount (`mode=620`) opens it: readable and writable by
    /// its owner, writable by group tty. Returns both ends (the pty lives while they do).
    fn desktop_pty() -> (TTYPort, TTYPort, String) {
        let (master, slave) = TTYPort::pair().unwrap();
        let path = slave.name().unwrap();
        std::fs::set_permissions(&path, Permissions::from_mode(0o620)).unwrap();
        assert_eq!(mode(&path), 0o620);
        (master, slave, path)
    }

    #[test]
    fn a_pty_a_desktop_mount_leaves_open_to_group_tty_becomes_its_owners_alone() {
        let (_master, _slave, path) = desktop_pty();
        make_private(&path).unwrap();
        assert_eq!(mode(&path), 0o600);
        let me = std::fs::metadata("/proc/self").unwrap().uid();
        assert_eq!(std::fs::metadata(&path).unwrap().uid(), me);
        // Again: already private is fine.
        make_private(&path).unwrap();
        assert_eq!(mode(&path), 0o600);
    }

    #[test]
    fn the_effective_user_is_the_owner_of_this_process() {
        // proc(5): /proc/self belongs to the process's effective user.
        assert_eq!(effective_uid().unwrap(), std::fs::metadata("/proc/self").unwrap().uid());
    }

    #[test]
    fn what_is_not_a_pty_is_refused_in_one_line_naming_it() {
        // Removed when dropped, also when the test fails.
        let temp = tempfile::tempdir().unwrap();
        let dir = temp.path();
        let file = dir.join("not-a-pty");
        std::fs::write(&file, b"").unwrap();
        std::fs::set_permissions(&file, Permissions::from_mode(0o644)).unwrap();
        let gone = dir.join("gone");
        for (path, why) in [(&file, "not a character device"), (&gone, "No such file")] {
            let message = format!("{:#}", make_private(path).unwrap_err());
            assert_eq!(message.lines().count(), 1, "{message}");
            assert!(message.contains(&path.display().to_string()) && message.contains(why), "{message}");
        }
        // Refused before its mode was touched.
        assert_eq!(std::fs::metadata(&file).unwrap().mode() & 0o7777, 0o644);
    }
}
