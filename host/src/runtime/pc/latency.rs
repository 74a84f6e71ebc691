//! The latency timer of an FTDI USB adapter, and the warning when it is slow.
//!
//! An FTDI chip (ROBOTIS U2D2, many Waveshare boards) holds received bytes until its buffer fills
//! or its latency timer runs out, 16 ms from the factory, so every servo reply can arrive up to
//! 16 ms late. DynamixelSDK sets it to 1 ms: `port_handler_linux.cpp` raises `ASYNC_LOW_LATENCY`
//! on the port, with the comment "set `/sys/bus/usb-serial/devices/{port_name_}/latency_timer` to
//! 1 ms". Linux's `ftdi_sio` driver shows the timer in milliseconds at
//! `/sys/bus/usb-serial/devices/ttyUSBn/latency_timer`; CDC-ACM adapters (`ttyACM*`), the other
//! usb-serial drivers (CH340, CP210x), ptys and other systems have no such file, and nothing to set.

use std::path::{Path, PathBuf};

/// The latency DynamixelSDK sets, in milliseconds.
pub const ADVISED_MS: u32 = 1;

/// The udev rule that sets every FTDI adapter's timer to 1 ms when it is plugged in.
pub const UDEV_RULE: &str = r#"ACTION=="add", SUBSYSTEM=="usb-serial", DRIVER=="ftdi_sio", ATTR{latency_timer}="1""#;

/// Where [`UDEV_RULE`] goes.
pub const UDEV_RULE_FILE: &str = "/etc/udev/rules.d/99-ftdi-latency.rules";

/// An adapter's latency timer as the kernel shows it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LatencyTimer {
    /// The port as it was given (`/dev/serial/by-id/usb-FTDI_...`).
    pub port: PathBuf,
    /// Its device, symlinks resolved (`ttyUSB0`).
    pub device: String,
    /// The sysfs file that holds the timer.
    pub file: PathBuf,
    /// The timer, in milliseconds.
    pub ms: u32,
}

/// The latency timer of the adapter behind `port`, read under `sys` (`/sys` on a real machine).
/// `None` when the port has no such timer (a CDC-ACM adapter, a pty, not Linux) or its file does
/// not hold a number.
pub fn latency_timer(sys: &Path, port: &Path) -> Option<LatencyTimer> {
    // `/dev/serial/by-id/...` is a symlink to `../../ttyUSB0`: the timer is filed under the
    // device's own name. A port that does not exist keeps its given name.
    let device = std::fs::canonicalize(port).unwrap_or_else(|_| port.to_path_buf());
    let device = device.file_name()?.to_str()?.to_string();
    let file = sys.join("bus/usb-serial/devices").join(&device).join("latency_timer");
    let ms = std::fs::read_to_string(&file).ok()?.trim().parse().ok()?;
    Some(LatencyTimer { port: port.to_path_buf(), device, file, ms })
}

impl LatencyTimer {
    /// Three lines when the timer is above [`ADVISED_MS`]: what it costs, the command that sets
    /// it now, and the udev rule that sets it at every plug-in. `None` when it is fine.
    pub fn warning(&self) -> Option<String> {
        if self.ms <= ADVISED_MS {
            return None;
        }
        let port = self.port.display().to_string();
        let name = if self.port.file_name().and_then(|n| n.to_str()) == Some(self.device.as_str()) {
            port
        } else {
            format!("{port} ({})", self.device)
        };
        Some(format!(
            "warning: {name}: the USB adapter's latency timer is {ms} ms, so each servo reply can come up to {ms} ms \
             late (DynamixelSDK sets {ADVISED_MS} ms)\n  \
             now:      echo {ADVISED_MS} | sudo tee {file}\n  \
             for good: echo '{UDEV_RULE}' | sudo tee {UDEV_RULE_FILE} (from the next plug-in)",
            ms = self.ms,
            file = self.file.display(),
        ))
    }
}

/// The warning for `port`'s latency timer read under `sys`, if it is above [`ADVISED_MS`].
pub fn warning(sys: &Path, port: &Path) -> Option<String> {
    latency_timer(sys, port)?.warning()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::symlink;

    /// A `/sys` and `/dev` as Linux lays them out for one FTDI adapter (`ttyUSB0`, with its
    /// `by-id` link) and one CDC-ACM board (`ttyACM0`, no usb-serial entry), the FTDI timer at
    /// `timer`. Each test gets its own folder (tests run in parallel), removed when dropped, also
    /// when the test fails.
    fn fake_tree(timer: &str) -> tempfile::TempDir {
        let temp = tempfile::Builder::new().prefix("armctl-latency-").tempdir().unwrap();
        let root = temp.path();
        let devices = root.join("sys/bus/usb-serial/devices/ttyUSB0");
        std::fs::create_dir_all(&devices).unwrap();
        std::fs::write(devices.join("latency_timer"), timer).unwrap();
        let dev = root.join("dev");
        std::fs::create_dir_all(dev.join("serial/by-id")).unwrap();
        for node in ["ttyUSB0", "ttyACM0"] {
            std::fs::write(dev.join(node), b"").unwrap();
        }
        symlink("../../ttyUSB0", dev.join("serial/by-id/usb-FTDI_FT232R_USB_UART_A10K-if00-port0")).unwrap();
        temp
    }

    #[test]
    fn a_16_ms_timer_gets_the_fix_in_the_warning() {
        let root = fake_tree("16\n");
        let port = root.path().join("dev/ttyUSB0");
        let timer = latency_timer(&root.path().join("sys"), &port).unwrap();
        assert_eq!((timer.device.as_str(), timer.ms), ("ttyUSB0", 16));
        let file = root.path().join("sys/bus/usb-serial/devices/ttyUSB0/latency_timer");
        let expected = format!(
            "warning: {}: the USB adapter's latency timer is 16 ms, so each servo reply can come up to 16 ms late \
             (DynamixelSDK sets 1 ms)\n  \
             now:      echo 1 | sudo tee {}\n  \
             for good: echo 'ACTION==\"add\", SUBSYSTEM==\"usb-serial\", DRIVER==\"ftdi_sio\", ATTR{{latency_timer}}=\"1\"' \
             | sudo tee /etc/udev/rules.d/99-ftdi-latency.rules (from the next plug-in)",
            port.display(),
            file.display()
        );
        assert_eq!(warning(&root.path().join("sys"), &port), Some(expected));
    }

    #[test]
    fn a_1_ms_timer_is_fine() {
        let root = fake_tree("1\n");
        let port = root.path().join("dev/ttyUSB0");
        assert_eq!(latency_timer(&root.path().join("sys"), &port).map(|t| t.ms), Some(1));
        assert_eq!(warning(&root.path().join("sys"), &port), None);
    }

    #[test]
    fn a_cdc_acm_port_has_no_timer() {
        let root = fake_tree("16\n");
        assert_eq!(latency_timer(&root.path().join("sys"), &root.path().join("dev/ttyACM0")), None);
        assert_eq!(warning(&root.path().join("sys"), &root.path().join("dev/ttyACM0")), None);
    }

    #[test]
    fn a_by_id_link_is_followed_to_its_device() {
        let root = fake_tree("16\n");
        let link = root.path().join("dev/serial/by-id/usb-FTDI_FT232R_USB_UART_A10K-if00-port0");
        let timer = latency_timer(&root.path().join("sys"), &link).unwrap();
        assert_eq!((timer.device.as_str(), timer.ms), ("ttyUSB0", 16));
        let text = timer.warning().unwrap();
        assert!(text.starts_with(&format!("warning: {} (ttyUSB0): ", link.display())), "{text}");
        assert!(text.contains("bus/usb-serial/devices/ttyUSB0/latency_timer\n"), "{text}");
    }

    #[test]
    fn garbage_or_an_unreadable_file_gives_no_timer() {
        let root = fake_tree("sixteen\n");
        let (sys, port) = (root.path().join("sys"), root.path().join("dev/ttyUSB0"));
        assert_eq!(latency_timer(&sys, &port), None);
        // A folder where the file should be: reading it fails.
        let file = sys.join("bus/usb-serial/devices/ttyUSB0/latency_timer");
        std::fs::remove_file(&file).unwrap();
        std::fs::create_dir(&file).unwrap();
        assert_eq!(latency_timer(&sys, &port), None);
        assert_eq!(warning(&sys, &port), None);
    }

    #[test]
    fn no_sysfs_means_no_timer() {
        assert_eq!(latency_timer(Path::new("/nonexistent-sys"), Path::new("/dev/ttyUSB0")), None);
    }
}
