//! `armctl ports`: the serial ports of this machine with the USB device behind each, so a person
//! finds which one is the arm's adapter (LeRobot ships `lerobot-find-port` for this).
//!
//! The ports come from the serialport crate's enumeration, so the command works wherever it does:
//! on Linux it reads sysfs (this build has no libudev), on macOS it asks IOKit, on Windows the
//! SetupAPI. Each USB port carries its vendor and product ids, maker, product and serial number.
//! On Linux, `/dev/serial/by-id` adds the stable names udev made, when it runs.

use std::path::{Path, PathBuf};

use serde::Serialize;
use serialport::{SerialPortInfo, SerialPortType};

/// A serial port backed by a USB device.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct UsbPort {
    /// The device node (`/dev/ttyUSB0`, `/dev/cu.usbserial-A10K`, `COM3`).
    pub path: String,
    /// USB vendor id, 4 hex digits.
    pub vendor_id: String,
    /// USB product id, 4 hex digits.
    pub product_id: String,
    /// The manufacturer string, if the device has one.
    pub manufacturer: Option<String>,
    /// The product string.
    pub product: Option<String>,
    /// The serial number string.
    pub serial_number: Option<String>,
    /// Its stable names under `/dev/serial/by-id` (Linux with udev).
    pub by_id: Vec<String>,
}

/// The USB serial ports of this machine, sorted by path; `dev` is where the `serial/by-id`
/// links are looked for (`/dev`). Built-in UARTs and Bluetooth ports are left out. An
/// enumeration that fails (no `/sys/class/tty` in a container) lists nothing.
pub fn usb_ports(dev: &Path) -> Vec<UsbPort> {
    // serialport's sysfs scan panics when /sys/class/tty is missing: look first.
    if cfg!(target_os = "linux") && !Path::new("/sys/class/tty").is_dir() {
        return Vec::new();
    }
    from_infos(serialport::available_ports().unwrap_or_default(), &by_id_links(dev))
}

/// The `/dev/serial/by-id` links under `dev`: (the device they point at, the link's path).
fn by_id_links(dev: &Path) -> Vec<(PathBuf, String)> {
    std::fs::read_dir(dev.join("serial/by-id"))
        .map(|links| {
            links
                .flatten()
                .filter_map(|link| {
                    let target = std::fs::canonicalize(link.path()).ok()?;
                    Some((target, link.path().display().to_string()))
                })
                .collect()
        })
        .unwrap_or_default()
}

/// The USB ports among `infos`, each with the `by_id` names that point at it, sorted by path.
pub fn from_infos(infos: Vec<SerialPortInfo>, by_id: &[(PathBuf, String)]) -> Vec<UsbPort> {
    let mut ports: Vec<UsbPort> = infos
        .into_iter()
        .filter_map(|info| {
            let SerialPortType::UsbPort(usb) = info.port_type else { return None };
            let node = PathBuf::from(&info.port_name);
            let canonical = std::fs::canonicalize(&node).unwrap_or_else(|_| node.clone());
            let mut names: Vec<String> =
                by_id.iter().filter(|(target, _)| *target == canonical).map(|(_, name)| name.clone()).collect();
            names.sort();
            Some(UsbPort {
                path: info.port_name,
                vendor_id: format!("{:04x}", usb.vid),
                product_id: format!("{:04x}", usb.pid),
                manufacturer: usb.manufacturer.filter(|t| !t.is_empty()),
                product: usb.product.filter(|t| !t.is_empty()),
                serial_number: usb.serial_number.filter(|t| !t.is_empty()),
                by_id: names,
            })
        })
        .collect();
    ports.sort_by(|a, b| a.path.cmp(&b.path));
    ports
}

/// One line per port: `/dev/ttyACM0  1a86:55d3  QinHeng Electronics  USB Single Serial  serial 5A7B...`.
pub fn describe(port: &UsbPort) -> String {
    let mut line = format!("{}  {}:{}", port.path, port.vendor_id, port.product_id);
    for text in [&port.manufacturer, &port.product].into_iter().flatten() {
        line.push_str("  ");
        line.push_str(text);
    }
    if let Some(serial) = &port.serial_number {
        line.push_str(&format!("  serial {serial}"));
    }
    for name in &port.by_id {
        line.push_str(&format!("  ({name})"));
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;
    use serialport::UsbPortInfo;
    use std::os::unix::fs::symlink;

    fn usb(
        name: &str,
        vid: u16,
        pid: u16,
        manufacturer: Option<&str>,
        product: Option<&str>,
        serial: Option<&str>,
    ) -> SerialPortInfo {
        SerialPortInfo {
            port_name: name.to_string(),
            port_type: SerialPortType::UsbPort(UsbPortInfo {
                vid,
                pid,
                serial_number: serial.map(str::to_string),
                manufacturer: manufacturer.map(str::to_string),
                product: product.map(str::to_string),
            }),
        }
    }

    #[test]
    fn usb_ports_with_their_device_and_by_id_name_built_in_ones_left_out() {
        // Removed when dropped, also when the test fails.
        let root = tempfile::tempdir().unwrap();
        let dev = root.path().join("dev");
        std::fs::create_dir_all(dev.join("serial/by-id")).unwrap();
        for node in ["ttyUSB0", "ttyACM0", "ttyS0"] {
            std::fs::write(dev.join(node), b"").unwrap();
        }
        symlink("../../ttyUSB0", dev.join("serial/by-id/usb-FTDI_FT232H_FT8ABC-if00-port0")).unwrap();
        let node = |n: &str| dev.join(n).display().to_string();
        let infos = vec![
            usb(&node("ttyUSB0"), 0x0403, 0x6014, Some("FTDI"), None, Some("FT8ABC")),
            usb(&node("ttyACM0"), 0x1a86, 0x55d3, None, Some("USB Single Serial"), Some("")),
            SerialPortInfo { port_name: node("ttyS0"), port_type: SerialPortType::PciPort },
            SerialPortInfo { port_name: "/dev/rfcomm0".into(), port_type: SerialPortType::BluetoothPort },
        ];
        let ports = from_infos(infos, &by_id_links(&dev));
        assert_eq!(ports.len(), 2, "{ports:?}");
        assert_eq!(ports[0].path, node("ttyACM0"));
        assert_eq!((ports[0].vendor_id.as_str(), ports[0].product_id.as_str()), ("1a86", "55d3"));
        assert_eq!(ports[0].product.as_deref(), Some("USB Single Serial"));
        assert_eq!((ports[0].manufacturer.as_deref(), ports[0].serial_number.as_deref()), (None, None));
        assert!(ports[0].by_id.is_empty());
        assert_eq!(ports[1].serial_number.as_deref(), Some("FT8ABC"));
        assert_eq!(ports[1].by_id, [dev.join("serial/by-id/usb-FTDI_FT232H_FT8ABC-if00-port0").display().to_string()]);
        let line = describe(&ports[1]);
        assert!(line.contains("0403:6014  FTDI  serial FT8ABC  (") && line.contains("usb-FTDI_FT232H"), "{line}");
    }

    #[test]
    fn a_mac_port_keeps_its_name() {
        let ports = from_infos(vec![usb("/dev/cu.usbmodem58FA0", 0x1a86, 0x55d3, None, None, None)], &[]);
        assert_eq!(ports[0].path, "/dev/cu.usbmodem58FA0");
        assert_eq!(describe(&ports[0]), "/dev/cu.usbmodem58FA0  1a86:55d3");
    }

    #[test]
    fn this_machine_lists_without_panicking() {
        // Whatever the machine has (a container may have no USB port at all).
        let ports = usb_ports(Path::new("/dev"));
        assert!(ports.windows(2).all(|w| w[0].path <= w[1].path));
    }
}
