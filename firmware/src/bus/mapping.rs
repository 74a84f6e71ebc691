//! Per-joint conversion between the joint angle of the kinematics (radians, SI) and the servo's
//! position ticks. Ticks exist only in the servo layer; everything above speaks radians.
//!
//! `ticks = zero + direction * angle * ticks_per_revolution / 2π`, rounded to the nearest tick,
//! and a goal outside the servo's tick limits is refused, never wrapped or silently clamped.
//!
//! A LeRobot calibration maps differently, and the mapping can follow it exactly
//! ([`JointMapping::lerobot`]): LeRobot's degree mode commands `int(deg * max_res / 360 + mid)`,
//! with `max_res` one less than the ticks per turn (4095), `mid` the middle of the calibrated range
//! (a half tick when its ends' sum is odd), and Python's `int()`, which truncates toward zero.

use super::Id;
use kinematics::Real;

/// Which way the servo turns for a positive joint angle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// Ticks grow with the joint angle.
    Forward,
    /// Ticks fall as the joint angle grows (a servo mounted the other way round).
    Reverse,
}

/// How one joint's angle maps to one servo's ticks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JointMapping {
    /// The servo's bus id.
    pub id: Id,
    /// Encoder ticks per revolution (4096 on the X-series and the STS3215).
    pub ticks_per_revolution: u32,
    /// The tick value at joint angle zero (2048 for a servo centred at zero).
    pub zero: i32,
    /// The turning direction.
    pub direction: Direction,
    /// Lowest tick the servo may be sent.
    pub min_ticks: i32,
    /// Highest tick the servo may be sent.
    pub max_ticks: i32,
    /// The angle zero lies half a tick above `zero`.
    pub zero_half: bool,
    /// Whole ticks by truncation toward zero (LeRobot's `int()`), not to the nearest.
    pub truncate: bool,
}

/// Why a joint value has no tick value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MappingError {
    /// NaN or infinite angle.
    NotFinite {
        /// The servo.
        id: Id,
    },
    /// The angle maps outside the servo's tick limits.
    OutOfLimits {
        /// The servo.
        id: Id,
        /// The tick value it maps to (saturated to the i32 range).
        ticks: i64,
    },
}

impl core::fmt::Display for MappingError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NotFinite { id } => write!(f, "servo {id}: joint value is not finite"),
            Self::OutOfLimits { id, ticks } => write!(f, "servo {id}: {ticks} ticks is outside its limits"),
        }
    }
}

impl JointMapping {
    /// A servo centred at zero (`ticks_per_revolution / 2` ticks), turning forward, with its full
    /// single-turn range `0..ticks_per_revolution`.
    pub fn centred(id: Id, ticks_per_revolution: u32) -> Self {
        let tpr = i32::try_from(ticks_per_revolution).unwrap_or(i32::MAX);
        Self {
            id,
            ticks_per_revolution,
            zero: tpr / 2,
            direction: Direction::Forward,
            min_ticks: 0,
            max_ticks: tpr - 1,
            zero_half: false,
            truncate: false,
        }
    }

    /// LeRobot's degree mode for a servo of `resolution` ticks a turn calibrated to
    /// `range_min..=range_max` (raw, offset-corrected ticks): the angle zero at the range's middle,
    /// `resolution - 1` ticks a turn, truncation, and the calibrated range as the tick limits.
    /// LeRobot ignores `drive_mode` in degree mode, so the direction is forward.
    pub fn lerobot(id: Id, resolution: u32, range_min: i32, range_max: i32) -> Self {
        let sum = i64::from(range_min) + i64::from(range_max);
        Self {
            id,
            ticks_per_revolution: resolution.saturating_sub(1),
            zero: i32::try_from(sum.div_euclid(2)).unwrap_or(i32::MAX),
            direction: Direction::Forward,
            min_ticks: range_min,
            max_ticks: range_max,
            zero_half: sum.rem_euclid(2) == 1,
            truncate: true,
        }
    }

    /// The angle zero in ticks (`zero`, plus the half tick).
    fn zero_ticks(&self) -> f64 {
        f64::from(self.zero) + if self.zero_half { 0.5 } else { 0.0 }
    }

    fn sign(&self) -> f64 {
        match self.direction {
            Direction::Forward => 1.0,
            Direction::Reverse => -1.0,
        }
    }

    /// Ticks per radian (positive).
    fn ticks_per_radian(&self) -> f64 {
        f64::from(self.ticks_per_revolution) / core::f64::consts::TAU
    }

    /// The tick goal for a joint angle, rounded to the nearest tick (or truncated); refused when not finite or
    /// outside `min_ticks..=max_ticks`.
    pub fn to_ticks<T: Real>(&self, radians: T) -> Result<i32, MappingError> {
        if !radians.finite() {
            return Err(MappingError::NotFinite { id: self.id });
        }
        // f64 keeps a tick exact for any angle a servo can reach, in both scalar types.
        let exact = self.zero_ticks() + self.sign() * radians.to_f64() * self.ticks_per_radian();
        let ticks = if self.truncate { libm::trunc(exact) } else { round(exact) };
        if ticks < f64::from(self.min_ticks) || ticks > f64::from(self.max_ticks) {
            // `as` saturates: the value is only reported.
            return Err(MappingError::OutOfLimits { id: self.id, ticks: ticks as i64 });
        }
        Ok(ticks as i32)
    }

    /// The joint angle of a tick value (exact up to the scalar's rounding).
    pub fn to_radians<T: Real>(&self, ticks: i32) -> T {
        T::of(self.sign() * (f64::from(ticks) - self.zero_ticks()) / self.ticks_per_radian())
    }

    /// The joint range the tick limits allow, `(lowest, highest)` in radians.
    pub fn joint_range<T: Real>(&self) -> (T, T) {
        let (a, b) = (self.to_radians::<T>(self.min_ticks), self.to_radians::<T>(self.max_ticks));
        if a <= b {
            (a, b)
        } else {
            (b, a)
        }
    }
}

/// Round half away from zero without std.
fn round(x: f64) -> f64 {
    libm::round(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::PI;

    #[test]
    fn centred_servo_maps_quarter_turns_to_1024_ticks() {
        let m = JointMapping::centred(1, 4096);
        assert_eq!(m.to_ticks(0.0f64), Ok(2048));
        assert_eq!(m.to_ticks(PI / 2.0), Ok(3072));
        assert_eq!(m.to_ticks(-PI / 2.0), Ok(1024));
        assert_eq!(m.to_ticks(-PI), Ok(0));
        // +π is tick 4096: one past the single-turn range.
        assert_eq!(m.to_ticks(PI), Err(MappingError::OutOfLimits { id: 1, ticks: 4096 }));
        assert_eq!(m.to_ticks(f32::NAN), Err(MappingError::NotFinite { id: 1 }));
    }

    #[test]
    fn reverse_direction_and_offset() {
        let m = JointMapping { zero: 1000, direction: Direction::Reverse, ..JointMapping::centred(3, 4096) };
        assert_eq!(m.to_ticks(PI / 4.0), Ok(1000 - 512));
        assert!((m.to_radians::<f64>(1000 - 512) - PI / 4.0).abs() < 1e-12);
        // Reversed, a quarter turn forward is 1024 ticks below zero: below tick 0.
        assert_eq!(m.to_ticks(PI / 2.0), Err(MappingError::OutOfLimits { id: 3, ticks: -24 }));
        let (lo, hi) = m.joint_range::<f64>();
        assert!(lo < hi);
        assert!((hi - 1000.0 / 4096.0 * 2.0 * PI).abs() < 1e-12);
    }

    #[test]
    fn extreme_tick_values_from_a_servo_do_not_overflow() {
        let m = JointMapping::centred(1, 4096);
        assert!(m.to_radians::<f64>(i32::MIN) < -3e6);
        assert!(m.to_radians::<f32>(i32::MAX) > 3e6);
    }

    #[test]
    fn ticks_round_trip_within_half_a_tick() {
        let m = JointMapping::centred(1, 4096);
        for t in 0..4096 {
            assert_eq!(m.to_ticks(m.to_radians::<f32>(t)), Ok(t));
        }
    }
}
