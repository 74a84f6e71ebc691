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
    /// The nearest value to an integer.
    fn of_i64(x: i64) -> Self;
    /// The exact binary value of a finite number: `(negative, m, e)` with `self = ±m · 2^e`
    /// (`m` below 2^53), read from its bits, so no other float type is involved (an `f32` widened
    /// to `f64` costs a library call on a single-precision FPU).
    fn to_binary(self) -> (bool, u64, i32);
    /// The square root. For `f32` on a Cortex-M with a single-precision FPU, the FPU's own
    /// instruction (`vsqrt.f32`, 14 cycles), not `libm`'s `sqrtf` (about a hundred instructions in
    /// software): stable Rust reaches the instruction only through `std` or assembly. Elsewhere the
    /// same as `RealField::sqrt`.
    fn root(self) -> Self;
}

/// Splits IEEE 754 bits with `fraction` fraction bits and exponent bias `bias`.
fn binary(bits: u64, fraction: u32, exponent_bits: u32, bias: i32) -> (bool, u64, i32) {
    let negative = bits >> (fraction + exponent_bits) & 1 == 1;
    let exponent = ((bits >> fraction) & ((1 << exponent_bits) - 1)) as i32;
    let m = bits & ((1 << fraction) - 1);
    // Subnormals have no hidden bit and the smallest exponent.
    match exponent {
        0 => (negative, m, 1 - bias - fraction as i32),
        e => (negative, m | 1 << fraction, e - bias - fraction as i32),
    }
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
    fn of_i64(x: i64) -> Self {
        x as f32
    }
    fn to_binary(self) -> (bool, u64, i32) {
        binary(u64::from(self.to_bits()), 23, 8, 127)
    }
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    #[allow(unsafe_code)]
    fn root(self) -> Self {
        let root: u32;
        // SAFETY: the FPU's square root of one register, which is saved on the stack and restored
        // around it; no other memory is touched and the condition flags are left alone. Every
        // `eabihf` Arm target has a VFP, and every VFP has `vsqrt.f32`. The operands go through
        // core registers because the compiler does not count the M4F's FPU as the `vfp2` feature
        // its floating-point register class asks for.
        unsafe {
            core::arch::asm!(
                "vpush {{s0}}",
                "vmov s0, {x}",
                "vsqrt.f32 s0, s0",
                "vmov {root}, s0",
                "vpop {{s0}}",
                x = in(reg) self.to_bits(),
                root = lateout(reg) root,
                options(pure, nomem, preserves_flags)
            );
        }
        f32::from_bits(root)
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    fn root(self) -> Self {
        nalgebra::ComplexField::sqrt(self)
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
    fn of_i64(x: i64) -> Self {
        x as f64
    }
    fn to_binary(self) -> (bool, u64, i32) {
        binary(self.to_bits(), 52, 11, 1023)
    }
    fn root(self) -> Self {
        nalgebra::ComplexField::sqrt(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `±m · 2^e` rebuilt in f64 (exact for both types' values) is the number, normals and
    /// subnormals alike.
    #[test]
    fn the_binary_value_is_exact() {
        let rebuild = |(negative, m, e): (bool, u64, i32)| {
            let v = m as f64 * 2f64.powi(e);
            if negative {
                -v
            } else {
                v
            }
        };
        for x in [0.0f32, -0.0, 1.0, -1.5, core::f32::consts::PI, 1e-40, -3.4e38, f32::MIN_POSITIVE] {
            assert_eq!(rebuild(x.to_binary()), f64::from(x), "{x}");
        }
        for x in [0.0f64, 1.0, -2.75, core::f64::consts::PI, 1e-310, 1e300] {
            assert_eq!(rebuild(x.to_binary()), x, "{x}");
        }
        assert!((-0.0f32).to_binary().0);
    }
}
