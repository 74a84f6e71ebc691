//! LeRobot's normalisation (`MotorsBus._normalize` and `_unnormalize` in `motors_bus.py`): raw
//! ticks (offset-corrected, as the servo reports them) to the values its policies and kinematics
//! see, and back. The arithmetic is Python's in the same order, in f64 as Python's floats are,
//! with `int()`'s truncation toward zero, so the ticks are the very ones LeRobot would command.
//!
//! - Degrees (body joints, LeRobot's default since 2025): `(ticks - mid) * 360 / max_res` with
//!   `mid = (range_min + range_max) / 2` and `max_res` the model's resolution less one (4095 on the
//!   STS3215 and the X-series), not clamped; back: `int(deg * max_res / 360 + mid)`. `drive_mode` is
//!   not looked at.
//! - 0 to 100 (the gripper) and -100 to 100: clamped to the range, scaled, and inverted when
//!   `drive_mode` is 1 and LeRobot applies drive modes (its Feetech bus does; Dynamixel inverts in
//!   hardware instead).

use super::MotorCalibration;

/// Python's `int()` of a float: truncation toward zero.
fn int(x: f64) -> i64 {
    x.trunc() as i64
}

fn mid(m: &MotorCalibration) -> f64 {
    (f64::from(m.range_min) + f64::from(m.range_max)) / 2.0
}

/// Degrees of `ticks` for a servo of `resolution` ticks a turn.
pub fn degrees(ticks: i64, m: &MotorCalibration, resolution: u32) -> f64 {
    let max_res = f64::from(resolution) - 1.0;
    (ticks as f64 - mid(m)) * 360.0 / max_res
}

/// The ticks LeRobot commands for `degrees`.
pub fn ticks_from_degrees(degrees: f64, m: &MotorCalibration, resolution: u32) -> i64 {
    let max_res = f64::from(resolution) - 1.0;
    int((degrees * max_res / 360.0) + mid(m))
}

/// `x` limited to `lo..=hi` (Python's `min(hi, max(lo, x))`).
fn bounded(x: f64, lo: f64, hi: f64) -> f64 {
    hi.min(lo.max(x))
}

/// 0 to 100 of `ticks` over the range (inverted when `drive_mode` applies).
pub fn range_0_100(ticks: i64, m: &MotorCalibration, apply_drive_mode: bool) -> f64 {
    let (lo, hi) = (f64::from(m.range_min), f64::from(m.range_max));
    let norm = ((bounded(ticks as f64, lo, hi) - lo) / (hi - lo)) * 100.0;
    if apply_drive_mode && m.drive_mode != 0 {
        100.0 - norm
    } else {
        norm
    }
}

/// The ticks LeRobot commands for `percent` (0 to 100).
pub fn ticks_from_range_0_100(percent: f64, m: &MotorCalibration, apply_drive_mode: bool) -> i64 {
    let (lo, hi) = (f64::from(m.range_min), f64::from(m.range_max));
    let value = if apply_drive_mode && m.drive_mode != 0 { 100.0 - percent } else { percent };
    int((bounded(value, 0.0, 100.0) / 100.0) * (hi - lo) + lo)
}

/// -100 to 100 of `ticks` over the range (negated when `drive_mode` applies).
pub fn range_m100_100(ticks: i64, m: &MotorCalibration, apply_drive_mode: bool) -> f64 {
    let (lo, hi) = (f64::from(m.range_min), f64::from(m.range_max));
    let norm = (((bounded(ticks as f64, lo, hi) - lo) / (hi - lo)) * 200.0) - 100.0;
    if apply_drive_mode && m.drive_mode != 0 {
        -norm
    } else {
        norm
    }
}

/// The ticks LeRobot commands for `value` (-100 to 100).
pub fn ticks_from_range_m100_100(value: f64, m: &MotorCalibration, apply_drive_mode: bool) -> i64 {
    let (lo, hi) = (f64::from(m.range_min), f64::from(m.range_max));
    let value = if apply_drive_mode && m.drive_mode != 0 { -value } else { value };
    int(((bounded(value, -100.0, 100.0) + 100.0) / 200.0) * (hi - lo) + lo)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cal(range_min: i32, range_max: i32, drive_mode: u8) -> MotorCalibration {
        MotorCalibration { id: 1, drive_mode, homing_offset: 0, range_min, range_max }
    }

    // The expected values below were computed by Python 3 with the arithmetic of LeRobot's
    // `_normalize` and `_unnormalize` (motors_bus.py), for a 4096-tick servo (max_res 4095).

    /// (range_min, range_max, drive_mode, ticks, degrees)
    const DEGREES: [(i32, i32, u8, i64, f64); 16] = [
        (758, 3292, 0, 758, -111.38461538461539),
        (758, 3292, 0, 2047, 1.934065934065934),
        (758, 3292, 0, 3292, 111.38461538461539),
        (758, 3292, 0, 4000, 173.62637362637363),
        (893, 3092, 1, 893, -96.65934065934066),
        (893, 3092, 1, 2047, 4.791208791208791),
        (893, 3092, 1, 3092, 96.65934065934066),
        (893, 3092, 1, 4000, 176.4835164835165),
        (0, 4095, 0, 0, -180.0),
        (0, 4095, 0, 2047, -0.04395604395604396),
        (0, 4095, 0, 4095, 180.0),
        (0, 4095, 0, 4000, 171.64835164835165),
        (2019, 3367, 1, 2019, -59.252747252747255),
        (2019, 3367, 1, 2047, -56.79120879120879),
        (2019, 3367, 1, 3367, 59.252747252747255),
        (2019, 3367, 1, 4000, 114.9010989010989),
    ];

    /// (range_min, range_max, drive_mode, degrees, ticks)
    const TICKS: [(i32, i32, u8, f64, i64); 13] = [
        (758, 3292, 0, -90.0, 1001),
        (758, 3292, 0, -12.34, 1884),
        (758, 3292, 0, 0.0, 2025),
        (758, 3292, 0, 0.01, 2025),
        (758, 3292, 0, 45.5, 2542),
        (758, 3292, 0, 179.9, 4071),
        (893, 3092, 1, -90.0, 968),
        (893, 3092, 1, -12.34, 1852),
        (893, 3092, 1, 45.5, 2510),
        (0, 4095, 0, 0.0, 2047),
        (0, 4095, 0, 179.9, 4093),
        // int() truncates toward zero: -227.5 is -227, not floor's -228.
        (0, 4095, 0, -200.0, -227),
        (2019, 3367, 1, 179.9, 4739),
    ];

    #[test]
    fn degree_mode_matches_lerobot_and_ignores_drive_mode() {
        for (lo, hi, dm, ticks, want) in DEGREES {
            assert_eq!(degrees(ticks, &cal(lo, hi, dm), 4096), want, "{lo}..{hi} at {ticks}");
            assert_eq!(degrees(ticks, &cal(lo, hi, 1 - dm), 4096), want, "drive_mode does not count");
        }
        for (lo, hi, dm, deg, want) in TICKS {
            assert_eq!(ticks_from_degrees(deg, &cal(lo, hi, dm), 4096), want, "{lo}..{hi} at {deg} deg");
            assert_eq!(ticks_from_degrees(deg, &cal(lo, hi, 1 - dm), 4096), want, "drive_mode does not count");
        }
    }

    /// (range_min, range_max, drive_mode, ticks, 0..100, -100..100), drive modes applied.
    const RANGES: [(i32, i32, u8, i64, f64, f64); 8] = [
        (758, 3292, 0, 0, 0.0, -100.0),
        (758, 3292, 0, 2500, 68.74506708760852, 37.49013417521704),
        (758, 3292, 0, 4095, 100.0, 100.0),
        (893, 3092, 1, 0, 100.0, 100.0),
        (893, 3092, 1, 2500, 26.921327876307416, -46.15734424738517),
        (893, 3092, 1, 3092, 0.0, -100.0),
        (2019, 3367, 1, 2500, 64.31750741839762, 28.63501483679525),
        (0, 4095, 0, 2500, 61.05006105006105, 22.100122100122107),
    ];

    /// (range_min, range_max, drive_mode, value, ticks of 0..100, of -100..100, of -value in -100..100)
    const BACK: [(i32, i32, u8, f64, i64, i64, i64); 10] = [
        (758, 3292, 0, -5.0, 758, 1961, 2088),
        (758, 3292, 0, 33.3, 1601, 2446, 1603),
        (758, 3292, 0, 99.99, 3291, 3291, 758),
        (758, 3292, 0, 120.0, 3292, 3292, 758),
        (893, 3092, 1, -5.0, 3092, 2047, 1937),
        (893, 3092, 1, 33.3, 2359, 1626, 2358),
        (893, 3092, 1, 50.0, 1992, 1442, 2542),
        (2019, 3367, 1, 99.99, 2019, 2019, 3366),
        (0, 4095, 0, 50.0, 2047, 3071, 1023),
        (0, 4095, 0, 100.0, 4095, 4095, 0),
    ];

    #[test]
    fn range_modes_match_lerobot_with_drive_mode_and_clamping() {
        for (lo, hi, dm, ticks, pct, sym) in RANGES {
            let m = cal(lo, hi, dm);
            assert_eq!(range_0_100(ticks, &m, true), pct, "{lo}..{hi} dm {dm} at {ticks}");
            assert_eq!(range_m100_100(ticks, &m, true), sym, "{lo}..{hi} dm {dm} at {ticks}");
        }
        for (lo, hi, dm, value, pct, sym, neg) in BACK {
            let m = cal(lo, hi, dm);
            assert_eq!(ticks_from_range_0_100(value, &m, true), pct, "{lo}..{hi} dm {dm} at {value}");
            assert_eq!(ticks_from_range_m100_100(value, &m, true), sym, "{lo}..{hi} dm {dm} at {value}");
            assert_eq!(ticks_from_range_m100_100(-value, &m, true), neg, "{lo}..{hi} dm {dm} at -{value}");
        }
        // Without drive modes applied (LeRobot's Dynamixel bus), drive_mode 1 changes nothing.
        assert_eq!(range_0_100(2500, &cal(893, 3092, 1), false), range_0_100(2500, &cal(893, 3092, 0), true));
    }
}
