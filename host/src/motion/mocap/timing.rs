//! Keyframe times the arm can keep: the human's timing where the arm is fast enough, longer
//! steps where a joint would exceed its velocity or acceleration limit.
//!
//! The firmware enforces its limits whatever the file says, by lagging behind it; the tool then
//! leaves the hand's path. Timing the keyframes within the limits keeps the path and gives up the
//! time instead (the default, [`Timing::Fit`]). The checks use each step's mean joint velocity,
//! Δq / Δt, and the change of that velocity between steps over the time between their middles,
//! starting and ending at rest; the player's cubic Hermite curve through the keyframes is close
//! to these, and the 10 % margin the caller leaves covers the rest.

/// What gives way where the human moves faster than the arm's limits allow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Timing {
    /// The time: a keyframe step takes as long as the limits need, so the tool keeps the hand's
    /// path and the motion plays slower there.
    Fit,
    /// The path: keyframes keep the capture's timing and each joint's step is cut to the velocity
    /// limit, so the tool lags the hand there (and where the acceleration limit holds it back).
    Captured,
}

impl Timing {
    /// Every choice with its name and what it gives up, for the command line's `--timing` and its
    /// help.
    pub const NAMES: [(&'static str, Timing, &'static str); 2] = [
        (
            "fit",
            Timing::Fit,
            "The time: a keyframe step takes as long as the limits need, so the tool keeps the hand's path and the \
             motion plays slower there",
        ),
        (
            "captured",
            Timing::Captured,
            "The path: keyframes keep the capture's timing and each joint's step is cut to the velocity limit, so the \
             tool lags the hand there (and where the acceleration limit holds it back)",
        ),
    ];

    /// The choice of that name, if any.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::NAMES.iter().find(|(n, _, _)| *n == name).map(|&(_, t, _)| t)
    }
}

/// Per-joint limits the keyframes keep (the same for every joint, as the arm files give them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// rad/s.
    pub velocity: f64,
    /// rad/s².
    pub acceleration: f64,
}

/// Keyframe times (from 0) and how many steps the limits touched.
#[derive(Clone, Debug, PartialEq)]
pub struct Timed {
    /// Time of each keyframe, the first at 0.
    pub offsets: Vec<f64>,
    /// Steps made longer ([`Timing::Fit`]) or cut short ([`Timing::Captured`]).
    pub limited: usize,
}

/// The largest amount by which a step of `dq` over `dt` breaks the acceleration limit, coming
/// from velocity `before` over a step of `dt_before` and going on to `after` (0 at the ends).
fn excess(dq: &[f64], dt: f64, before: &[f64], dt_before: f64, limits: &[Limits], end: bool) -> f64 {
    let mut worst = f64::NEG_INFINITY;
    for ((d, b), l) in dq.iter().zip(before).zip(limits) {
        let v = d / dt;
        worst = worst.max((v - b).abs() - l.acceleration * (dt_before + dt) / 2.0);
        if end {
            // Coming to rest at the last keyframe.
            worst = worst.max(v.abs() - l.acceleration * dt / 2.0);
        }
    }
    worst
}

/// The shortest step time from `shortest` up that keeps the acceleration limit (doubling, then
/// halving the bracket to a microsecond).
fn stretch(dq: &[f64], shortest: f64, before: &[f64], dt_before: f64, limits: &[Limits], end: bool) -> f64 {
    let ok = |dt: f64| excess(dq, dt, before, dt_before, limits, end) <= 0.0;
    if ok(shortest) {
        return shortest;
    }
    let (mut lo, mut hi) = (shortest, shortest * 2.0);
    while !ok(hi) {
        (lo, hi) = (hi, hi * 2.0);
    }
    while hi - lo > 1e-6 {
        let mid = (lo + hi) / 2.0;
        if ok(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// Times the keyframes `q`, whose steps were captured `steps` s long, within `limits` (see
/// [`Timing`]); `q` changes only with [`Timing::Captured`].
pub fn time_keyframes(q: &mut [Vec<f64>], steps: &[f64], limits: &Limits, timing: Timing) -> Timed {
    let joints = q.first().map_or(0, Vec::len);
    time_joints(q, steps, &vec![*limits; joints], timing)
}

/// As [`time_keyframes`], with limits of each joint's own (`limits[j]` for joint j). Several arms
/// timed together as one vector of all their joints get one time warp: a step takes as long as
/// the slowest of them needs (see [`super::retarget::timebase`]).
pub fn time_joints(q: &mut [Vec<f64>], steps: &[f64], limits: &[Limits], timing: Timing) -> Timed {
    let joints = q.first().map_or(0, Vec::len);
    assert_eq!(limits.len(), joints, "one limit per joint");
    let mut offsets = vec![0.0];
    let mut limited = 0;
    // The previous step's mean velocity and time: at rest before the first.
    let (mut before, mut dt_before) = (vec![0.0; joints], 0.0);
    let count = q.len();
    for k in 1..count {
        let captured = steps[k - 1];
        let (done, rest) = q.split_at_mut(k);
        let (previous, next) = (&done[k - 1], &mut rest[0]);
        let too_fast =
            next.iter().zip(previous.iter()).zip(limits).any(|((a, b), l)| (a - b).abs() > l.velocity * captured);
        let dt = match timing {
            Timing::Fit => {
                let dq: Vec<f64> = next.iter().zip(previous).map(|(a, b)| a - b).collect();
                // The time the slowest joint needs at its velocity limit.
                let needed = dq.iter().zip(limits).fold(0.0f64, |m, (d, l)| m.max(d.abs() / l.velocity));
                let shortest = captured.max(needed);
                let dt = stretch(&dq, shortest, &before, dt_before, limits, k + 1 == count);
                before = dq.iter().map(|d| d / dt).collect();
                dt
            }
            Timing::Captured => {
                for ((a, b), l) in next.iter_mut().zip(previous.iter()).zip(limits) {
                    *a = a.clamp(b - l.velocity * captured, b + l.velocity * captured);
                }
                captured
            }
        };
        limited += usize::from(dt > captured + 1e-12 || too_fast);
        dt_before = dt;
        offsets.push(offsets[k - 1] + dt);
    }
    Timed { offsets, limited }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: Limits = Limits { velocity: 1.0, acceleration: 4.0 };

    #[test]
    fn slow_steps_keep_the_captured_time_and_fast_ones_stretch() {
        // 0.01 rad per 0.1 s: 0.1 rad/s, well inside.
        let mut q: Vec<Vec<f64>> = (0..5).map(|k| vec![0.01 * k as f64]).collect();
        let t = time_keyframes(&mut q, &[0.1; 4], &LIMITS, Timing::Fit);
        assert_eq!(t.limited, 0);
        assert!(t.offsets.iter().enumerate().all(|(k, o)| (o - 0.1 * k as f64).abs() < 1e-12), "{:?}", t.offsets);
        // 0.5 rad in 0.1 s: 5 rad/s, five times the limit (0.5 s at 1 rad/s); from rest and back
        // to rest at 4 rad/s², 0.5 / dt <= 4 * dt / 2: dt >= sqrt(2 * 0.5 / 4) = 0.5 s as well.
        let mut q = vec![vec![0.0], vec![0.5]];
        let t = time_keyframes(&mut q, &[0.1], &LIMITS, Timing::Fit);
        assert!((t.offsets[1] - 0.5).abs() < 1e-5, "{:?}", t.offsets);
        assert_eq!(t.limited, 1);
    }

    #[test]
    fn every_step_keeps_both_limits() {
        let mut q: Vec<Vec<f64>> =
            (0..40).map(|k| vec![(k as f64 * 0.7).sin(), 0.3 * (k as f64 * 1.3).cos()]).collect();
        let t = time_keyframes(&mut q, &[0.04; 39], &LIMITS, Timing::Fit);
        let mut v_before = [0.0, 0.0];
        let mut dt_before = 0.0;
        for k in 1..q.len() {
            let dt = t.offsets[k] - t.offsets[k - 1];
            for j in 0..2 {
                let v = (q[k][j] - q[k - 1][j]) / dt;
                assert!(v.abs() <= LIMITS.velocity + 1e-9);
                assert!((v - v_before[j]).abs() <= LIMITS.acceleration * (dt + dt_before) / 2.0 + 1e-6);
                v_before[j] = v;
            }
            dt_before = dt;
        }
    }

    #[test]
    fn joints_timed_together_take_the_slowest_ones_time() {
        // Two arms of one joint each. Alone, 0.5 rad at 1 rad/s takes 0.5 s and 0.1 rad at
        // 0.5 rad/s 0.2 s; together the step takes 0.5 s, whichever joint needs it.
        let fast = Limits { velocity: 1.0, acceleration: 100.0 };
        let slow = Limits { velocity: 0.5, acceleration: 100.0 };
        let t = time_joints(&mut [vec![0.0, 0.0], vec![0.5, 0.1]], &[0.1], &[fast, slow], Timing::Fit);
        assert!((t.offsets[1] - 0.5).abs() < 1e-9, "{:?}", t.offsets);
        let t = time_joints(&mut [vec![0.0, 0.0], vec![0.1, 0.5]], &[0.1], &[fast, slow], Timing::Fit);
        assert!((t.offsets[1] - 1.0).abs() < 1e-9, "{:?}", t.offsets);
        // Captured: the times stay, each joint cut to its own limit.
        let mut q = vec![vec![0.0, 0.0], vec![0.5, 0.5]];
        let t = time_joints(&mut q, &[0.1], &[fast, slow], Timing::Captured);
        assert_eq!(t.offsets, vec![0.0, 0.1]);
        assert!((q[1][0] - 0.1).abs() < 1e-12 && (q[1][1] - 0.05).abs() < 1e-12, "{q:?}");
        // With one limit for every joint it is time_keyframes.
        let mut a: Vec<Vec<f64>> = (0..30).map(|k| vec![(k as f64 * 0.7).sin(), (k as f64 * 0.3).cos()]).collect();
        let mut b = a.clone();
        assert_eq!(
            time_joints(&mut a, &[0.04; 29], &[LIMITS, LIMITS], Timing::Fit),
            time_keyframes(&mut b, &[0.04; 29], &LIMITS, Timing::Fit)
        );
    }

    #[test]
    fn captured_timing_cuts_the_steps() {
        let mut q = vec![vec![0.0], vec![0.5], vec![0.5]];
        let t = time_keyframes(&mut q, &[0.1, 0.1], &LIMITS, Timing::Captured);
        assert_eq!(t.offsets, vec![0.0, 0.1, 0.2]);
        assert!((q[1][0] - 0.1).abs() < 1e-12 && (q[2][0] - 0.2).abs() < 1e-12, "{q:?}");
        assert_eq!(t.limited, 2);
    }
}
