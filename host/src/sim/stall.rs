//! A servo stalled against something its link has run into (the table, an obstacle, another link
//! of the arm: [`super::contact`] finds where; the servo, [`super::servo`], holds the stop): its horn cannot pass the contact going the way it
//! was going, while it stays free to move back.
//!
//! What the stalled servo reports, as a real one pushing against a wall would:
//! - its present position stays at the contact while its goal lies beyond it;
//! - its load (STS3215 `Present_Load`, the one effort reading the simulator models) follows the
//!   goal's distance past the contact, [`JAW_STIFFNESS`] per tick as for a gripper closing on an
//!   object, capped by its torque limit;
//! - a Feetech servo whose load stays at or above its overload torque (`Overload_Torque`, 80 % from
//!   the factory) for [`PROTECTION_TIME_NS`] sets its overload bit (0x20). The real STS3215 then
//!   falls back to its protective torque (`Protective_Torque`, 20 %) and keeps pushing softly; the
//!   simulator's hardware errors switch the torque off instead, as for every other fault.
//!
//! Not modelled here: the current, heat from the stall and gravity, which physical servos have
//! ([`super::drive`]) and ideal ones do not (a limp or overloaded arm stays where it is in
//! either); a Dynamixel's overload; and any give in the link or the obstacle (the stop is rigid).

use firmware::bus::feetech::StatusError;

/// Load per tick of goal past the contact, in thousandths of the servo's full effort: 25 ticks
/// (about 2° of the horn) push at half effort. A round figure for a stiff object (a gripper's
/// jaws on it, a link on the table), not a measurement of a servo.
pub const JAW_STIFFNESS: i64 = 20;

/// How long a Feetech servo's load may stay at or above its overload torque before its overload
/// protection trips: `Protection_Time` (address 35, 10 ms units) at 200, as read from real
/// STS3215s (the simulator's control table has no item for it, so it is fixed).
pub const PROTECTION_TIME_NS: u64 = 2_000_000_000;

/// Feetech's overload torque (address 36, percent of the maximum torque): the load above which the
/// protection timer runs.
pub const OVERLOAD_TORQUE: firmware::bus::table::Item = firmware::bus::table::sts3215::OVERLOAD_TORQUE;

/// The overload bit of a Feetech status.
pub const OVERLOAD: u8 = StatusError::OVERLOAD;

/// Where a horn is stopped: it cannot pass `at` (its own ticks, before the homing offset) moving
/// in the direction of `toward` (+1 or -1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stop {
    /// The contact, in the horn's own ticks.
    pub at: f64,
    /// The blocked direction: +1 (increasing ticks) or -1.
    pub toward: f64,
}

impl Stop {
    /// Whether `actual` lies past the contact in the blocked direction.
    pub fn blocks(&self, actual: f64) -> bool {
        (actual - self.at) * self.toward > 0.0
    }

    /// `actual`, held at the contact when it lies past it.
    pub fn clamp(&self, actual: f64) -> f64 {
        if self.blocks(actual) {
            self.at
        } else {
            actual
        }
    }

    /// How far (ticks) a goal `past` ticks from the contact (the goal's distance from it, in the
    /// horn's direction) pushes into it: zero for a goal on the free side.
    pub fn push(&self, past: f64) -> f64 {
        (past * self.toward).max(0.0)
    }
}

/// The load (thousandths of full effort) of a horn pushed `push` ticks past its contact, before
/// the torque limit caps it.
pub fn load(push: f64) -> i64 {
    (push.round() as i64).saturating_mul(JAW_STIFFNESS).min(1000)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stop_holds_one_way_only_and_loads_with_the_push() {
        let stop = Stop { at: 2500.0, toward: 1.0 };
        assert_eq!(stop.clamp(2600.0), 2500.0);
        assert_eq!(stop.clamp(2400.0), 2400.0, "free to move back");
        assert_eq!(stop.push(30.0), 30.0);
        assert_eq!(stop.push(-30.0), 0.0);
        let down = Stop { at: 1000.0, toward: -1.0 };
        assert!(down.blocks(999.0) && !down.blocks(1001.0));
        assert_eq!(down.push(-25.0), 25.0);
        // 25 ticks push at half effort; the full effort is the ceiling.
        assert_eq!(load(25.0), 500);
        assert_eq!(load(400.0), 1000);
    }
}
