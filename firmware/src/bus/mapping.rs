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

    /// The tick goal for a joint angle, rounded to the nearest tick (or truncated); refused when
    /// not finite or outside `min_ticks..=max_ticks`.
    ///
    /// Computed in integers: the angle's exact binary value times the ticks per radian in fixed
    /// point ([`INV_TAU`]), so a tick is exact for any angle a servo can reach (within 1e-11 of a
    /// tick, as f64 arithmetic would be) without the double-precision library a
    /// single-precision FPU would need for it.
    pub fn to_ticks<T: Real>(&self, radians: T) -> Result<i32, MappingError> {
        if !radians.finite() {
            return Err(MappingError::NotFinite { id: self.id });
        }
        let (negative, m, e) = radians.to_binary();
        // |angle| in ticks, FRAC fraction bits: m · tpr · INV_TAU · 2^(e - 50). m < 2^53, tpr is
        // capped at 2^24 ticks a turn and INV_TAU < 2^48, so the product fits 125 bits.
        let tpr = u128::from(self.ticks_per_revolution.min(1 << 24));
        let product = u128::from(m) * tpr * u128::from(INV_TAU);
        let shift = e - 50 + FRAC as i32;
        let magnitude = if product == 0 {
            0
        } else if shift >= 0 {
            // Only for angles of at least 2^33 rad (f32) or 2^62 rad (f64), far beyond any servo:
            // saturated, as the value is only reported.
            if shift > 2 {
                i128::MAX / 4
            } else {
                (product << shift).min(u128::MAX >> 2) as i128
            }
        } else {
            (product >> (-shift).min(127)) as i128
        };
        let turning_up = negative == (self.direction == Direction::Reverse);
        let angle = if turning_up { magnitude } else { -magnitude };
        let zero = (i128::from(self.zero) << FRAC) + if self.zero_half { 1 << (FRAC - 1) } else { 0 };
        let exact = angle + zero;
        // Whole ticks: toward zero (LeRobot's int()), or half away from zero.
        let away = if self.truncate { 0 } else { 1 << (FRAC - 1) };
        let ticks = if exact >= 0 { (exact + away) >> FRAC } else { -((-exact + away) >> FRAC) };
        if ticks < i128::from(self.min_ticks) || ticks > i128::from(self.max_ticks) {
            let reported = i64::try_from(ticks).unwrap_or(if ticks < 0 { i64::MIN } else { i64::MAX });
            return Err(MappingError::OutOfLimits { id: self.id, ticks: reported });
        }
        // Within min_ticks..=max_ticks, both i32.
        Ok(i32::try_from(ticks).unwrap_or(self.max_ticks))
    }

    /// The joint angle of a tick value (within the scalar's rounding: two roundings in `f32`).
    pub fn to_radians<T: Real>(&self, ticks: i32) -> T {
        // In half ticks from the angle zero: exact in integers.
        let half_ticks = 2 * (i64::from(ticks) - i64::from(self.zero)) - i64::from(self.zero_half);
        let signed = match self.direction {
            Direction::Forward => half_ticks,
            Direction::Reverse => -half_ticks,
        };
        let half_ticks_per_turn = 2 * i64::from(self.ticks_per_revolution.max(1));
        T::of_i64(signed) * (T::of(core::f64::consts::TAU) / T::of_i64(half_ticks_per_turn))
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

/// Fraction bits of the fixed-point ticks [`JointMapping::to_ticks`] computes.
const FRAC: u32 = 40;

/// 2^50 / 2π, rounded to the nearest integer (179192535600708.08...): radians to turns in fixed
/// point, with a relative error below 3e-15.
const INV_TAU: u64 = 179_192_535_600_708;

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

    /// The integer arithmetic against the same formula in f64 (which the firmware used before),
    /// over a million angles in f32 and in f64 on four mappings: the same tick, but where the
    /// exact value lies within 1e-9 of where rounding or truncation turns (the last bits of either
    /// computation may fall either way there); and the angles refused alike.
    #[test]
    fn integer_ticks_are_the_f64_formulas() {
        let f64_ticks = |m: &JointMapping, radians: f64| -> (f64, i64) {
            let sign = if m.direction == Direction::Reverse { -1.0 } else { 1.0 };
            let zero = f64::from(m.zero) + if m.zero_half { 0.5 } else { 0.0 };
            let exact = zero + sign * radians * f64::from(m.ticks_per_revolution) / core::f64::consts::TAU;
            let whole = if m.truncate { exact.trunc() } else { exact.round() };
            // How far from where the whole tick changes.
            let turn = if m.truncate { exact - exact.floor() } else { exact - exact.floor() - 0.5 };
            (turn.abs().min((1.0 - turn.abs()).abs()), whole as i64)
        };
        let mappings = [
            JointMapping::centred(1, 4096),
            JointMapping { direction: Direction::Reverse, zero: 1000, ..JointMapping::centred(2, 4096) },
            JointMapping::lerobot(3, 4096, 893, 3092),
            JointMapping::lerobot(4, 4096, 758, 3292),
        ];
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut compared = 0;
        for i in 0..1_000_000 {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let m = &mappings[i % mappings.len()];
            // Uniform over ±4 rad, reaching past both ends of every mapping.
            let radians = (seed >> 11) as f64 / (1u64 << 53) as f64 * 8.0 - 4.0;
            for (radians, got) in
                [(radians, m.to_ticks(radians)), (f64::from(radians as f32), m.to_ticks(radians as f32))]
            {
                let (margin, want) = f64_ticks(m, radians);
                if margin < 1e-9 {
                    continue;
                }
                match got {
                    Ok(t) => assert_eq!(i64::from(t), want, "{m:?} at {radians}"),
                    Err(MappingError::OutOfLimits { ticks, .. }) => {
                        assert_eq!(ticks, want, "{m:?} at {radians}");
                        assert!(want < i64::from(m.min_ticks) || want > i64::from(m.max_ticks));
                    }
                    Err(e) => panic!("{e}"),
                }
                compared += 1;
            }
        }
        assert!(compared > 1_999_000, "{compared}");
        // Far beyond any servo: refused, the reported value saturated, not wrapped.
        let m = JointMapping::centred(1, 4096);
        assert!(matches!(m.to_ticks(1e30f32), Err(MappingError::OutOfLimits { ticks, .. }) if ticks > 1_000_000));
        assert!(matches!(m.to_ticks(-1e300f64), Err(MappingError::OutOfLimits { ticks, .. }) if ticks < -1_000_000));
        assert_eq!(m.to_ticks(1e-40f32), Ok(2048));
    }

    #[test]
    fn ticks_round_trip_within_half_a_tick() {
        let m = JointMapping::centred(1, 4096);
        for t in 0..4096 {
            assert_eq!(m.to_ticks(m.to_radians::<f32>(t)), Ok(t));
        }
    }
}
