//! What the controller counts and reports: loop timing, per-servo bus health, IK and watchdog.

use kinematics::ik::IkStatus;

use super::Mode;

/// Why a servo's position did not arrive on a tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// No reply within the timeout, retries included (unpowered, unplugged, wrong id or baud).
    NoReply,
    /// The servo refused the read with an error number (Dynamixel).
    Refused,
    /// The whole transaction failed on the port (the serial driver reported an error).
    Port,
}

/// One servo's record on the bus.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ServoHealth {
    /// Ticks on which its position did not arrive.
    pub missed: u32,
    /// Missed ticks in a row, up to now.
    pub consecutive: u16,
    /// Replies carrying a hardware alert (overload, overheating, voltage).
    pub alerts: u32,
    /// The last alert's error byte.
    pub last_alert: Option<u8>,
    /// Why the last missed tick missed.
    pub last_fault: Option<Fault>,
    /// Lost: silent for [`super::Config::lost_after`] ticks in a row. Cleared by its next reply.
    pub lost: bool,
    /// Times it came back after being lost.
    pub recoveries: u32,
}

/// Counters since the controller started.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// Ticks run.
    pub ticks: u32,
    /// Ticks that started more than one period after the previous one, or whose work took longer
    /// than a period.
    pub deadline_misses: u32,
    /// Work time of the last tick, µs (bus transactions included).
    pub last_loop_us: u32,
    /// Longest work time of a tick, µs.
    pub max_loop_us: u32,
    /// Servo positions that did not arrive, summed over servos and ticks.
    pub missing_replies: u32,
    /// Bus transactions that failed on the port.
    pub bus_errors: u32,
    /// Tracking ticks whose IK did not converge within the per-tick budget.
    pub ik_failures: u32,
    /// Cartesian moves whose straight line ran into the joint limits, finished by a joint-space
    /// move to the solution found before moving.
    pub line_fallbacks: u32,
    /// Times the watchdog stopped the arm.
    pub watchdog_trips: u32,
    /// Commands refused.
    pub refusals: u32,
    /// Keyframes accepted into the queue (joint and Cartesian).
    pub keyframes: u32,
    /// Goals not sent because a joint value had no tick value (never expected: the limits keep
    /// setpoints inside every servo's range).
    pub mapping_errors: u32,
}

/// What one tick did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TickReport {
    /// The mode after the tick.
    pub mode: Mode,
    /// Servos (bit `i` for joint `i`) whose position did not arrive this tick.
    pub missing: u32,
    /// Servos that became lost this tick.
    pub lost: u32,
    /// Servos that answered again after being lost.
    pub recovered: u32,
    /// Whether goals were sent this tick.
    pub wrote_goals: bool,
    /// The IK outcome of a tracking tick.
    pub ik: Option<IkStatus>,
    /// The watchdog stopped the arm on this tick.
    pub watchdog: bool,
    /// This tick missed its deadline.
    pub late: bool,
    /// Work time of this tick, µs.
    pub loop_us: u32,
}

impl TickReport {
    pub(super) fn new(mode: Mode) -> Self {
        Self {
            mode,
            missing: 0,
            lost: 0,
            recovered: 0,
            wrote_goals: false,
            ik: None,
            watchdog: false,
            late: false,
            loop_us: 0,
        }
    }
}
