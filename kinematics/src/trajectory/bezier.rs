//! Cubic Bezier control points for a Hermite segment, and back: the same curve described by four
//! points instead of two values and two velocities.
//!
//! On `[t0, t1]` with `h = t1 - t0`: `b0 = p0`, `b1 = p0 + h v0 / 3`, `b2 = p1 - h v1 / 3`,
//! `b3 = p1`, since a cubic Bezier curve leaves `b0` with derivative `3 (b1 - b0)` and arrives at
//! `b3` with `3 (b3 - b2)` in the unit parameter. The conversion is exact in exact arithmetic; in
//! floating point a round trip agrees to a few ulps (exactly when `h / 3` and the products are
//! representable).

use super::HermiteSegment;
use crate::Real;
use nalgebra::SVector;

impl<T: Real, const J: usize> HermiteSegment<T, J> {
    /// The segment's cubic Bezier control points `[b0, b1, b2, b3]` (over the parameter
    /// `s = (t - t0) / h`).
    pub fn to_bezier(&self) -> [SVector<T, J>; 4] {
        let third = (self.t1 - self.t0) / T::of(3.0);
        [self.p0, self.p0 + self.v0 * third, self.p1 - self.v1 * third, self.p1]
    }

    /// The Hermite segment on `[t0, t1]` whose curve has the control points `control`.
    /// `t1 > t0` is the caller's to ensure (otherwise velocities are infinite or NaN).
    pub fn from_bezier(t0: T, t1: T, control: [SVector<T, J>; 4]) -> Self {
        let rate = T::of(3.0) / (t1 - t0);
        let [b0, b1, b2, b3] = control;
        HermiteSegment { t0, t1, p0: b0, v0: (b1 - b0) * rate, p1: b3, v1: (b3 - b2) * rate }
    }
}

/// The point at parameter `s` (in [0, 1]; not clamped) of the cubic Bezier curve with control
/// points `control`, by de Casteljau's repeated linear interpolation.
pub fn bezier_point<T: Real, const J: usize>(control: &[SVector<T, J>; 4], s: T) -> SVector<T, J> {
    let lerp = |a: SVector<T, J>, b: SVector<T, J>| a + (b - a) * s;
    let [b0, b1, b2, b3] = *control;
    let (c0, c1, c2) = (lerp(b0, b1), lerp(b1, b2), lerp(b2, b3));
    let (d0, d1) = (lerp(c0, c1), lerp(c1, c2));
    lerp(d0, d1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    #[test]
    fn round_trip_is_exact_on_representable_values() {
        let seg = HermiteSegment {
            t0: 1.0,
            t1: 4.0,
            p0: Vector2::new(0.5, -2.0),
            v0: Vector2::new(1.0, 0.25),
            p1: Vector2::new(3.0, 1.0),
            v1: Vector2::new(-0.5, 2.0),
        };
        let control = seg.to_bezier();
        assert_eq!(control[1], Vector2::new(1.5, -1.75));
        assert_eq!(HermiteSegment::from_bezier(1.0, 4.0, control), seg);
    }

    #[test]
    fn de_casteljau_matches_the_hermite_segment() {
        let seg = HermiteSegment {
            t0: -0.3,
            t1: 0.9,
            p0: Vector2::new(0.1, 2.0),
            v0: Vector2::new(-1.3, 0.7),
            p1: Vector2::new(1.7, -0.4),
            v1: Vector2::new(2.2, 0.0),
        };
        let control = seg.to_bezier();
        for i in 0..=10 {
            let s = f64::from(i) / 10.0;
            let t = -0.3 + 1.2 * s;
            assert!((bezier_point(&control, s) - seg.sample(t).position).norm() < 1e-14);
        }
    }
}
