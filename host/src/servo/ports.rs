//! `armctl ports`: the serial ports of this machine with the USB device behind each, so a person
//! finds which one is the arm's adapter (LeRobot ships `lerobot-find-port` for this).
//!
//! Linux only, and without libudev: the kernel's sysfs says it all. `/sys/class/tty/NAME/device`
//! leads to the USB interface (CDC-ACM) or the usb-serial port (FTDI, CH340, CP210x), whose
//! ancestor USB device holds `idVendor`, `idProduct`, `manufacturer`, `product` and `serial`.
//! `/dev/serial/by-id` gives the stable names udev made, when it runs.

use std::path::{Path, PathBuf};

use serde::Serialize;

/// A serial port backed by a USB device.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct UsbPort {
    /// The device node (`/dev/ttyUSB0`).
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
    /// Its stable names under `/dev/serial/by-id`.
    pub by_id: Vec<String>,
}

/// Reads a sysfs attribute, trimmed; `None` when absent or empty.
fn attribute(dir: &Path, name: &str) -> Option<String> {
    let text = std::fs::read_to_string(dir.join(name)).ok()?;
    Some(text.trim().to_string()).filter(|t| !t.is_empty())
}

/// The USB device above a tty's `device` link: the first ancestor (at most a few levels up) that
/// has an `idVendor`.
fn usb_device(tty: &Path) -> Option<PathBuf> {
    let mut dir = std::fs::canonicalize(tty.join("device")).ok()?;
    for _ in 0..4 {
        if dir.join("idVendor").is_file() {
            return Some(dir);
        }
        dir = dir.parent()?.to_path_buf();
    }
    None
}

/// The USB serial ports, by reading `sys` (normally `/sys`) and `dev` (normally `/dev`), sorted by
/// path. Ports with no USB device behind them (the built-in `ttyS*`) are left out.
pub fn usb_ports(sys: &Path, dev: &Path) -> Vec<UsbPort> {
    let Ok(entries) = std::fs::read_dir(sys.join("class/tty")) else {
        return Vec::new();
    };
    let by_id: Vec<(PathBuf, String)> = std::fs::read_dir(dev.join("serial/by-id"))
        .map(|links| {
            links
                .flatten()
                .filter_map(|link| {
                    let target = std::fs::canonicalize(link.path()).ok()?;
                    Some((target, link.path().display().to_string()))
                })
                .collect()
        })
        .unwrap_or_default();
    let mut ports: Vec<UsbPort> = entries
        .flatten()
        .filter_map(|entry| {
            let usb = usb_device(&entry.path())?;
            let node = dev.join(entry.file_name());
            let canonical = std::fs::canonicalize(&node).unwrap_or_else(|_| node.clone());
            let mut names: Vec<String> =
                by_id.iter().filter(|(target, _)| *target == canonical).map(|(_, name)| name.clone()).collect();
            names.sort();
            Some(UsbPort {
                path: node.display().to_string(),
                vendor_id: attribute(&usb, "idVendor")?,
                product_id: attribute(&usb, "idProduct").unwrap_or_default(),
                manufacturer: attribute(&usb, "manufacturer"),
                product: attribute(&usb, "product"),
                serial_number: attribute(&usb, "serial"),
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
    use std::os::unix::fs::symlink;

    /// A sysfs and /dev tree as Linux lays them out for an FTDI adapter (usb-serial) and a CDC-ACM
    /// board, plus a built-in UART with no USB device.
    fn fake_tree() -> PathBuf {
        let root = std::env::temp_dir().join(format!("armctl-ports-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let sys = root.join("sys");
        let usb = sys.join("devices/pci0000:00/0000:00:14.0/usb1");
        let write = |dir: &Path, attributes: &[(&str, &str)]| {
            std::fs::create_dir_all(dir).unwrap();
            for (name, value) in attributes {
                std::fs::write(dir.join(name), format!("{value}\n")).unwrap();
            }
        };
        let ftdi = usb.join("1-1");
        write(&ftdi, &[("idVendor", "0403"), ("idProduct", "6014"), ("manufacturer", "FTDI"), ("serial", "FT8ABC")]);
        write(&ftdi.join("1-1:1.0/ttyUSB0"), &[]);
        let acm = usb.join("1-2");
        write(&acm, &[("idVendor", "1a86"), ("idProduct", "55d3"), ("product", "USB Single Serial")]);
        write(&acm.join("1-2:1.0"), &[]);
        let uart = sys.join("devices/platform/serial8250/tty/ttyS0");
        write(&uart, &[]);
        let class = sys.join("class/tty");
        for (name, device) in
            [("ttyUSB0", ftdi.join("1-1:1.0/ttyUSB0")), ("ttyACM0", acm.join("1-2:1.0")), ("ttyS0", uart.clone())]
        {
            write(&class.join(name), &[]);
            symlink(device, class.join(name).join("device")).unwrap();
        }
        let dev = root.join("dev");
        write(&dev.join("serial/by-id"), &[]);
        for node in ["ttyUSB0", "ttyACM0", "ttyS0"] {
            std::fs::write(dev.join(node), b"").unwrap();
        }
        symlink("../../ttyUSB0", dev.join("serial/by-id/usb-FTDI_FT232H_FT8ABC-if00-port0")).unwrap();
        root
    }

    #[test]
    fn lists_usb_ports_with_their_device_and_leaves_built_in_ones_out() {
        let root = fake_tree();
        let ports = usb_ports(&root.join("sys"), &root.join("dev"));
        let dev = root.join("dev");
        assert_eq!(ports.len(), 2, "{ports:?}");
        assert_eq!(ports[0].path, dev.join("ttyACM0").display().to_string());
        assert_eq!((ports[0].vendor_id.as_str(), ports[0].product_id.as_str()), ("1a86", "55d3"));
        assert_eq!(ports[0].product.as_deref(), Some("USB Single Serial"));
        assert_eq!(ports[0].manufacturer, None);
        assert!(ports[0].by_id.is_empty());
        assert_eq!(ports[1].serial_number.as_deref(), Some("FT8ABC"));
        assert_eq!(ports[1].by_id, [dev.join("serial/by-id/usb-FTDI_FT232H_FT8ABC-if00-port0").display().to_string()]);
        let line = describe(&ports[1]);
        assert!(line.contains("0403:6014  FTDI  serial FT8ABC  (") && line.contains("usb-FTDI_FT232H"), "{line}");
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn no_sysfs_means_no_ports() {
        assert!(usb_ports(Path::new("/nonexistent-sys"), Path::new("/nonexistent-dev")).is_empty());
    }
}
