//! The last stage before the servos: whatever the mode produced, the setpoint sent moves by at
//! most what the joint, velocity and acceleration limits allow in one tick.
//!
//! Order matters. The velocity a step asks for is first capped by the velocity limit and by the
//! speed from which the joint can still stop on the desired position, plus the speed at which that
//! position itself moves (so a moving reference is followed without lag, and one that stops is
//! not overshot); then it
//! may differ from the previous tick's velocity by at most `a_max * dt`. Both caps pull toward
//! values within `±v_max`, so the result stays within it. Last, the position is clamped into the
//! joint range; the previous setpoint is inside it, so the clamp only shortens the step.

use kinematics::nalgebra::SVector;
use kinematics::trajectory::JointLimits;

/// A setpoint and the velocity it moved at on the last tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Setpoint<const N: usize> {
    /// Joint values (rad).
    pub position: SVector<f32, N>,
    /// Joint velocities (rad/s).
    pub velocity: SVector<f32, N>,
}

/// The highest speed from which a joint decelerating at `a` stops within `distance`, for a
/// discrete brake of `dt` steps: `v = a dt k` with `a dt² k (k + 1) / 2 <= distance`.
fn stopping_speed(distance: f32, a: f32, dt: f32) -> f32 {
    let adt = a * dt;
    if adt <= 0.0 {
        return 0.0;
    }
    let k = (libm::sqrtf(1.0 + 8.0 * distance / (adt * dt)) - 1.0) * 0.5;
    adt * k.max(0.0)
}

/// The next setpoint toward `desired`, which moves at `desired_velocity` (zero for a goal to stop
/// on), `dt` seconds after `from`, within `limits`. A desired value that is not finite counts as
/// "stay".
pub fn limit_step<const N: usize>(
    from: &Setpoint<N>,
    desired: &SVector<f32, N>,
    desired_velocity: &SVector<f32, N>,
    limits: &JointLimits<f32, N>,
    dt: f32,
) -> Setpoint<N> {
    let mut next = *from;
    if dt.is_nan() || dt <= 0.0 {
        return Setpoint { position: from.position, velocity: SVector::zeros() };
    }
    for j in 0..N {
        let p = from.position[j];
        let v = from.velocity[j];
        let (vmax, amax) = (limits.max_velocity[j], limits.max_acceleration[j]);
        let target = if desired[j].is_finite() { desired[j] } else { p };
        let target = within(target, limits.lower[j], limits.upper[j]);
        let error = target - p;
        let moving = if desired_velocity[j].is_finite() { libm::fabsf(desired_velocity[j]) } else { 0.0 };
        let cap = vmax.min(stopping_speed(libm::fabsf(error), amax, dt) + moving);
        let raw = error / dt;
        let dv = amax * dt;
        let velocity = within(within(raw, -cap, cap), v - dv, v + dv);
        // Unclamped, the step lands on the target exactly (not one rounding off it), so a
        // setpoint that has arrived comes to rest with a velocity of exactly zero.
        let position =
            if velocity == raw { target } else { within(p + velocity * dt, limits.lower[j], limits.upper[j]) };
        next.position[j] = position;
        next.velocity[j] = (position - p) / dt;
    }
    next
}

/// `x` limited to `lo..=hi`. Unlike `f32::clamp` it has no panic for `lo > hi` (the firmware links
/// no panic path; see the board's panic handler): then it returns `hi`, and a NaN `x` gives `lo`.
#[inline]
pub fn within(x: f32, lo: f32, hi: f32) -> f32 {
    x.max(lo).min(hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::nalgebra::Vector2;

    #[test]
    fn within_limits_like_clamp_and_never_panics() {
        assert_eq!(within(0.5, -1.0, 1.0), 0.5);
        assert_eq!(within(3.0, -1.0, 1.0), 1.0);
        assert_eq!(within(-3.0, -1.0, 1.0), -1.0);
        assert_eq!(within(f32::NAN, -1.0, 1.0), -1.0);
        // Where f32::clamp would panic (lo > hi), the upper bound wins.
        assert_eq!(within(0.0, 1.0, -1.0), -1.0);
    }

    fn limits() -> JointLimits<f32, 2> {
        JointLimits::new(Vector2::repeat(-1.0), Vector2::repeat(1.0), Vector2::repeat(2.0), Vector2::repeat(10.0))
            .unwrap()
    }

    #[test]
    fn a_far_goal_is_reached_without_exceeding_any_limit_or_overshooting() {
        let l = limits();
        let mut s = Setpoint { position: Vector2::new(-0.9, 0.0), velocity: Vector2::zeros() };
        let goal = Vector2::new(0.8, 5.0);
        let dt = 0.01;
        let mut highest = -2.0f32;
        for _ in 0..300 {
            let n = limit_step(&s, &goal, &Vector2::zeros(), &l, dt);
            for j in 0..2 {
                assert!(libm::fabsf(n.position[j] - s.position[j]) <= 2.0 * dt + 1e-6);
                assert!(libm::fabsf(n.velocity[j] - s.velocity[j]) <= 10.0 * dt + 1e-3, "joint {j}: {s:?} -> {n:?}");
                assert!(n.position[j] >= -1.0 && n.position[j] <= 1.0);
            }
            highest = highest.max(n.position[0]);
            s = n;
        }
        assert!((s.position[0] - 0.8).abs() < 1e-5, "{s:?}");
        assert_eq!(s.position[1], 1.0);
        assert!(highest <= 0.8 + 1e-3, "overshoot to {highest}");
    }

    #[test]
    fn nan_and_zero_dt_stay_put() {
        let l = limits();
        let s = Setpoint { position: Vector2::new(0.1, 0.2), velocity: Vector2::zeros() };
        let n = limit_step(&s, &Vector2::new(f32::NAN, 0.2), &Vector2::zeros(), &l, 0.01);
        assert_eq!(n.position, s.position);
        let n = limit_step(&s, &Vector2::new(0.5, 0.5), &Vector2::zeros(), &l, 0.0);
        assert_eq!(n.position, s.position);
    }
}
