//! The scalar the kinematics is generic over: `f32` on the microcontroller, `f64` on the host.

use nalgebra::RealField;

/// A floating-point scalar usable by every algorithm in this crate.
///
/// `RealField` (through nalgebra's `libm` feature) supplies `sin`, `cos`, `atan2`, `sqrt` without
/// `std`; this trait adds the few constants the solvers need to pick scale-aware thresholds.
pub trait Real: RealField + Copy + core::fmt::Debug + Default {
    /// Machine epsilon of the type.
    const EPSILON: Self;
    /// Converts an `f64` literal or measurement (rounding to the nearest value for `f32`).
    fn of(x: f64) -> Self;
    /// Widens to `f64` (exact for both implementations).
    fn to_f64(self) -> f64;
    /// True unless NaN or infinite.
    fn finite(self) -> bool;
    /// `(sin, cos)`, in the type's own precision: for `f32` computed in `f32` ([`crate::trig`]),
    /// not through `libm`'s `f64` path, which a single-precision FPU runs in software.
    fn sin_cos_fast(self) -> (Self, Self);
}

impl Real for f32 {
    const EPSILON: Self = f32::EPSILON;
    fn of(x: f64) -> Self {
        x as f32
    }
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    fn finite(self) -> bool {
        self.is_finite()
    }
    fn sin_cos_fast(self) -> (Self, Self) {
        crate::trig::sin_cos(self)
    }
}

impl Real for f64 {
    const EPSILON: Self = f64::EPSILON;
    fn of(x: f64) -> Self {
        x
    }
    fn to_f64(self) -> f64 {
        self
    }
    fn finite(self) -> bool {
        self.is_finite()
    }
    fn sin_cos_fast(self) -> (Self, Self) {
        // nalgebra's (libm without std): f64 is the FPU-less path anyway.
        nalgebra::ComplexField::sin_cos(self)
    }
}
