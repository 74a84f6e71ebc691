//! A recording of the served servos' positions on a fixed grid of real time, for a program that
//! judges the motion afterwards (its jerk, its lag behind the goal): `armctl sim servos --record`.
//!
//! The file is CSV: a header `t,pos_<id>...,goal_<id>...`, then one row every [`PERIOD_NS`] since
//! the server started: `t` in seconds (4 decimals), each servo's position in ticks (2 decimals),
//! then each servo's goal in whole ticks, the servos in bus order. Positions and goals are in the
//! frame the servo reports and takes goals in (after its homing offset), so that the lag is the
//! difference of two columns; positions are not rounded to whole ticks, as the present position
//! item is, so that their differences show the profile's jerk and not the quantisation.
//!
//! The serving thread of [`super::pty::PtyServer`] owns the recorder and calls
//! [`Recorder::catch_up`] whenever it wakes, before it carries out what woke it: every grid point
//! up to then is written from the servos as they stood before. A horn follows its motion profile,
//! a pure function of time from the profile's last change on ([`super::motion::Profile::at`]), and
//! the profiles change only when the thread carries something out, each time after catching up to
//! its wake: so the grid points written at a wake all lie after the last change, and their
//! positions are the horn's path, not a value held since the last wake, however late the thread
//! wakes. (The bus stamps a burst's instructions back from the wake by their wire time, so the
//! rows of that sliver, a fraction of a millisecond for a control tick's packets at 1 Mbps, show
//! the servo as it stood before them.) One change can lie after its wake: a partial packet an
//! emulated master left on the line (`--fixed-baud`) is carried out stamped at the end of its line
//! gap. A servo's grid points before its last goal write are evaluated at that write (which is
//! what its profile gives them anyway): held there, never extrapolated backwards.
//!
//! Rows are buffered and flushed at least every [`FLUSH_NS`] and when the server stops, always whole
//! rows: a server killed outright leaves a file that ends with a complete row.

use std::fmt::Write as _;
use std::io::{BufWriter, Write};
use std::path::Path;

use firmware::bus::Protocol;

use super::{SimBus, SimServo};

/// The grid's period: a row every 2 ms of real time since the server started.
pub const PERIOD_NS: u64 = 2_000_000;

/// The longest time rows stay in the buffer.
pub const FLUSH_NS: u64 = 500_000_000;

/// Writes the positions and goals of a bus's first servos, one row per grid point.
pub struct Recorder {
    out: Box<dyn Write + Send>,
    /// Servos recorded: the bus's first ones (its ids in order; a duplicate's twin comes after).
    columns: usize,
    /// The grid point to write next.
    next: u64,
    /// When the rows were last flushed, ns.
    flushed_ns: u64,
}

impl std::fmt::Debug for Recorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder").field("columns", &self.columns).field("next", &self.next).finish_non_exhaustive()
    }
}

impl Recorder {
    /// Creates (or empties) `path` and writes the header for servos `ids` (a bus's ids in order).
    pub fn create(path: &Path, ids: &[u8]) -> std::io::Result<Self> {
        let file = std::fs::File::create(path)?;
        Self::new(Box::new(BufWriter::new(file)), ids)
    }

    /// A recorder writing to `out`, its header already written and flushed.
    pub fn new(mut out: Box<dyn Write + Send>, ids: &[u8]) -> std::io::Result<Self> {
        let mut header = String::from("t");
        for prefix in ["pos", "goal"] {
            for id in ids {
                let _ = write!(header, ",{prefix}_{id}");
            }
        }
        header.push('\n');
        out.write_all(header.as_bytes())?;
        out.flush()?;
        Ok(Self { out, columns: ids.len(), next: 0, flushed_ns: 0 })
    }

    /// Writes every grid point up to `now_ns` not written yet, from `bus` as it stands (before
    /// what arrived at `now_ns` is carried out); flushes when the rows have waited [`FLUSH_NS`].
    pub fn catch_up(&mut self, bus: &SimBus, now_ns: u64) -> std::io::Result<()> {
        let last = now_ns / PERIOD_NS;
        if self.next <= last {
            // Copies, brought up to each grid point in turn: a gripper's horn then stops at the
            // object between its jaws as it does for a servo read that often (the servo itself
            // finds the contact only when it is next brought up to date).
            let mut servos: Vec<SimServo> = bus.servos().iter().take(self.columns).cloned().collect();
            let mut row = String::new();
            for k in self.next..=last {
                let t_ns = k * PERIOD_NS;
                row.clear();
                let _ = write!(row, "{}.{:04}", t_ns / 1_000_000_000, t_ns % 1_000_000_000 / 100_000);
                for servo in &mut servos {
                    // Never before its last goal (see the module's doc).
                    let at = t_ns.max(servo.goal_written_ns());
                    servo.update(at);
                    let _ = write!(row, ",{:.2}", position(servo, at));
                }
                for servo in &servos {
                    let _ = write!(row, ",{}", servo.get(servo.model().items.goal_position));
                }
                row.push('\n');
                // One write per row: the buffer hands the file whole rows only.
                self.out.write_all(row.as_bytes())?;
            }
            self.next = last + 1;
        }
        if now_ns.saturating_sub(self.flushed_ns) >= FLUSH_NS {
            self.out.flush()?;
            self.flushed_ns = now_ns;
        }
        Ok(())
    }

    /// Catches up to `now_ns` and flushes: the server stops.
    pub fn finish(&mut self, bus: &SimBus, now_ns: u64) -> std::io::Result<()> {
        self.catch_up(bus, now_ns)?;
        self.out.flush()?;
        self.flushed_ns = now_ns;
        Ok(())
    }
}

/// Where `servo`'s horn stands at `t_ns` in the frame of its goal and present position (after
/// the homing offset, as the servo's own correction maps it, see [`super::servo`]), unrounded.
fn position(servo: &SimServo, t_ns: u64) -> f64 {
    let actual = servo.actual_position(t_ns);
    let offset = servo.homing_offset() as f64;
    match servo.model().protocol {
        Protocol::Feetech => (actual - offset).rem_euclid(f64::from(servo.model().ticks_per_revolution)),
        Protocol::Dxl2 => actual + offset,
    }
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};

    use firmware::bus::table::{sts3215, STS3215};

    use super::*;

    const MS: u64 = 1_000_000;

    /// A writer whose bytes the test reads back.
    #[derive(Clone, Default)]
    struct Shared(Arc<Mutex<Vec<u8>>>);

    impl Write for Shared {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    impl Shared {
        fn text(&self) -> String {
            String::from_utf8(self.0.lock().unwrap().clone()).unwrap()
        }
    }

    fn goal(bus: &mut SimBus, id: u8, ticks: i64, t_ns: u64) {
        let item = STS3215.items.goal_position;
        let mut bytes = [0u8; 2];
        item.encode(ticks, STS3215.endian, &mut bytes).unwrap();
        bus.servo_mut(id).unwrap().write(item.address, &bytes, t_ns).unwrap();
    }

    #[test]
    fn rows_follow_the_grid_and_the_profile_between_wakes() {
        let mut bus = SimBus::new(Protocol::Feetech, &STS3215, &[1, 2], 1_000_000);
        bus.servo_mut(1).unwrap().write(STS3215.items.torque_enable.address, &[1], 0).unwrap();
        let out = Shared::default();
        let mut rec = Recorder::new(Box::new(out.clone()), &[1, 2]).unwrap();
        rec.catch_up(&bus, 3 * MS).unwrap();
        goal(&mut bus, 1, 2148, 3 * MS);
        // A long sleep: the rows between are the profile's, not the position held at the wake.
        rec.catch_up(&bus, 41 * MS).unwrap();
        rec.finish(&bus, 41 * MS).unwrap();
        let text = out.text();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "t,pos_1,pos_2,goal_1,goal_2");
        assert_eq!(lines[1], "0.0000,2048.00,2048.00,2048,2048");
        assert_eq!(lines[2], "0.0020,2048.00,2048.00,2048,2048");
        assert_eq!(lines.len(), 1 + 21, "t = 0, 2, ..., 40 ms");
        let mut servo = bus.servo(1).unwrap().clone();
        for (k, line) in lines[1..].iter().enumerate() {
            let fields: Vec<&str> = line.split(',').collect();
            let t_ns = k as u64 * 2 * MS;
            assert_eq!(fields[0], format!("{:.4}", t_ns as f64 * 1e-9));
            if k >= 2 {
                servo.update(t_ns);
                assert_eq!(fields[1], format!("{:.2}", servo.actual_position(t_ns)), "{line}");
                assert_eq!(fields[3], "2148");
            }
        }
        let moved: f64 = lines[21].split(',').nth(1).unwrap().parse().unwrap();
        assert!(moved > 2048.0, "{}", lines[21]);
    }

    #[test]
    fn positions_are_in_the_offset_corrected_frame_of_the_goal() {
        let mut bus = SimBus::new(Protocol::Feetech, &STS3215, &[1], 1_000_000);
        let servo = bus.servo_mut(1).unwrap();
        servo.set(sts3215::HOMING_OFFSET, 48);
        servo.set_position(2048, 0);
        let out = Shared::default();
        let mut rec = Recorder::new(Box::new(out.clone()), &[1]).unwrap();
        rec.finish(&bus, 0).unwrap();
        assert_eq!(out.text(), "t,pos_1,goal_1\n0.0000,2000.00,2000\n");
    }
}
