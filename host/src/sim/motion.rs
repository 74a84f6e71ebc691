//! The servo's own motion profile: a trapezoid (accelerate, cruise, decelerate) limited by the
//! profile velocity and acceleration, re-planned from the present position and velocity whenever a
//! new goal arrives, as the X-series and STS firmwares do.
//!
//! A profile is a list of constant-acceleration segments, so the position at any time is exact
//! (no integration error that would depend on how often the bus asks).

/// One constant-acceleration piece of a profile.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Segment {
    /// Start time, seconds since the profile began.
    t0: f64,
    /// Position at `t0`, ticks.
    p0: f64,
    /// Velocity at `t0`, ticks/s.
    v0: f64,
    /// Acceleration, ticks/s².
    a: f64,
    /// Duration, s.
    dt: f64,
}

impl Segment {
    fn at(&self, t: f64) -> (f64, f64) {
        let s = (t - self.t0).clamp(0.0, self.dt);
        (self.p0 + self.v0 * s + 0.5 * self.a * s * s, self.v0 + self.a * s)
    }

    fn end(&self) -> (f64, f64, f64) {
        let (p, v) = self.at(self.t0 + self.dt);
        (self.t0 + self.dt, p, v)
    }
}

/// A planned move from a position and velocity to a target, started at a time.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    start_ns: u64,
    target: f64,
    segments: Vec<Segment>,
}

impl Profile {
    /// Standing still at `position` from `start_ns` on.
    pub fn hold(position: f64, start_ns: u64) -> Self {
        Self { start_ns, target: position, segments: Vec::new() }
    }

    /// A move from `position` moving at `velocity` (ticks, ticks/s) to `target`, at most
    /// `max_velocity` ticks/s, accelerating at `acceleration` ticks/s² (infinite: velocity changes
    /// at once). A `max_velocity` that is not positive means no move.
    pub fn plan(
        start_ns: u64,
        position: f64,
        velocity: f64,
        target: f64,
        max_velocity: f64,
        acceleration: f64,
    ) -> Self {
        let mut segments = Vec::new();
        if max_velocity > 0.0 && position != target {
            plan_segments(&mut segments, 0.0, position, velocity, target, max_velocity, acceleration);
        }
        Self { start_ns, target, segments }
    }

    /// The target position.
    pub fn target(&self) -> f64 {
        self.target
    }

    /// Position (ticks) and velocity (ticks/s) at `t_ns`.
    pub fn at(&self, t_ns: u64) -> (f64, f64) {
        let t = t_ns.saturating_sub(self.start_ns) as f64 * 1e-9;
        match self.segments.iter().find(|s| t < s.t0 + s.dt) {
            Some(s) => s.at(t),
            // Finished: exactly on target, whatever rounding the segments accumulated.
            None => (self.target, 0.0),
        }
    }

    /// A bound on how far (ticks) the horn travels from `t0_ns` to `t1_ns`: the integral of its
    /// speed, taken piece by piece at the faster end of each (speed is linear along a
    /// constant-acceleration piece, so its largest value there is at an end). Whatever the
    /// profile does in between (a reversal included), the horn stays this close to where it was.
    pub fn travel_bound(&self, t0_ns: u64, t1_ns: u64) -> f64 {
        let seconds = |t_ns: u64| t_ns.saturating_sub(self.start_ns) as f64 * 1e-9;
        let (t0, t1) = (seconds(t0_ns), seconds(t1_ns));
        self.segments
            .iter()
            .map(|s| {
                let (a, b) = (t0.max(s.t0), t1.min(s.t0 + s.dt));
                if b <= a {
                    return 0.0;
                }
                s.at(a).1.abs().max(s.at(b).1.abs()) * (b - a)
            })
            .sum()
    }

    /// Whether the move is still under way at `t_ns`.
    pub fn moving(&self, t_ns: u64) -> bool {
        self.end_ns().is_some_and(|end| t_ns < end)
    }

    /// When the move ends (`None` for a hold).
    pub fn end_ns(&self) -> Option<u64> {
        let last = self.segments.last()?;
        Some(self.start_ns + ((last.t0 + last.dt) * 1e9).ceil() as u64)
    }
}

fn plan_segments(out: &mut Vec<Segment>, t0: f64, p0: f64, v0: f64, target: f64, vmax: f64, a: f64) {
    let d = target - p0;
    let s = d.signum();
    let dist = d.abs();
    if !a.is_finite() || a <= 0.0 {
        // Unlimited acceleration: cruise at the velocity limit straight to the target.
        out.push(Segment { t0, p0, v0: s * vmax, a: 0.0, dt: dist / vmax });
        return;
    }
    // In the direction of the target.
    let u0 = s * v0;
    if u0 < 0.0 || u0 * u0 / (2.0 * a) > dist + 1e-9 {
        // Moving away, or too fast to stop in time: brake to a stop, then plan from rest.
        let brake = Segment { t0, p0, v0, a: -v0.signum() * a, dt: v0.abs() / a };
        out.push(brake);
        let (t1, p1, _) = brake.end();
        if p1 != target {
            plan_segments(out, t1, p1, 0.0, target, vmax, a);
        }
        return;
    }
    let (mut t, mut p, mut u) = (t0, p0, u0);
    if u > vmax {
        // The velocity limit was lowered mid-move: slow down to it first.
        let seg = Segment { t0: t, p0: p, v0: s * u, a: -s * a, dt: (u - vmax) / a };
        out.push(seg);
        (t, p, _) = seg.end();
        u = vmax;
    }
    let rest = (target - p).abs();
    // Peak velocity of a triangle; capped by the limit, which leaves a cruise.
    let peak = ((2.0 * a * rest + u * u) / 2.0).sqrt().min(vmax).max(u);
    let accel = Segment { t0: t, p0: p, v0: s * u, a: s * a, dt: (peak - u) / a };
    let accel_dist = (peak * peak - u * u) / (2.0 * a);
    let brake_dist = peak * peak / (2.0 * a);
    let cruise_dist = (rest - accel_dist - brake_dist).max(0.0);
    out.push(accel);
    let (t1, p1, _) = accel.end();
    let cruise = Segment { t0: t1, p0: p1, v0: s * peak, a: 0.0, dt: cruise_dist / peak.max(f64::MIN_POSITIVE) };
    out.push(cruise);
    let (t2, p2, _) = cruise.end();
    out.push(Segment { t0: t2, p0: p2, v0: s * peak, a: -s * a, dt: peak / a });
    out.retain(|seg| seg.dt > 0.0);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_and_triangle_take_the_textbook_times() {
        // 1000 ticks at 500 ticks/s, 1000 ticks/s²: 0.5 s up, 1.5 s cruise, 0.5 s down = 2.5 s.
        let p = Profile::plan(0, 0.0, 0.0, 1000.0, 500.0, 1000.0);
        assert_eq!(p.end_ns(), Some(2_500_000_000));
        assert!((p.at(1_250_000_000).0 - 500.0).abs() < 1e-6);
        assert_eq!(p.at(3_000_000_000), (1000.0, 0.0));
        // 100 ticks at 1000 ticks/s²: triangle, peak sqrt(1e5) ≈ 316 ticks/s, 2 * 0.316 s.
        let p = Profile::plan(0, 0.0, 0.0, -100.0, 5000.0, 1000.0);
        let end = p.end_ns().unwrap() as f64 * 1e-9;
        assert!((end - 2.0 * (0.1f64).sqrt()).abs() < 1e-6, "{end}");
    }

    /// The bound covers the travel over any stretch, a reversal included (checked on a grid of
    /// stretches against the positions sampled every 0.1 ms), and is not loose on a cruise.
    #[test]
    fn the_travel_bound_covers_every_stretch() {
        let p = Profile::plan(0, 0.0, 0.0, 1000.0, 500.0, 1000.0);
        let (x, v) = p.at(1_000_000_000);
        // Turned back at full speed: it brakes, then comes back.
        let back = Profile::plan(1_000_000_000, x, v, -200.0, 500.0, 1000.0);
        for profile in [&p, &back] {
            for t0 in (1_000..3_500).step_by(50).map(|ms| ms * 1_000_000u64) {
                for len_ms in [1u64, 7, 50, 400, 2_000] {
                    let t1 = t0 + len_ms * 1_000_000;
                    let start = profile.at(t0).0;
                    let furthest =
                        (0..=len_ms * 10).map(|k| (profile.at(t0 + k * 100_000).0 - start).abs()).fold(0.0, f64::max);
                    let bound = profile.travel_bound(t0, t1);
                    assert!(furthest <= bound + 1e-9, "{t0} +{len_ms} ms: went {furthest}, bound {bound}");
                }
            }
        }
        // Cruising at 500 ticks/s for 0.1 s: 50 ticks, exactly.
        assert!((p.travel_bound(1_000_000_000, 1_100_000_000) - 50.0).abs() < 1e-9);
        assert_eq!(p.travel_bound(3_000_000_000, 4_000_000_000), 0.0, "at rest after the move");
    }

    #[test]
    fn replans_continuously_from_a_moving_start() {
        let p = Profile::plan(0, 0.0, 0.0, 1000.0, 500.0, 1000.0);
        let (x, v) = p.at(1_000_000_000);
        let q = Profile::plan(1_000_000_000, x, v, 0.0, 500.0, 1000.0);
        let (x2, v2) = q.at(1_000_000_000);
        assert!((x2 - x).abs() < 1e-9 && (v2 - v).abs() < 1e-9);
        assert_eq!(q.at(10_000_000_000), (0.0, 0.0));
        // Unlimited acceleration: d / v.
        let r = Profile::plan(0, 10.0, 0.0, 20.0, 100.0, f64::INFINITY);
        assert_eq!(r.end_ns(), Some(100_000_000));
    }
}
