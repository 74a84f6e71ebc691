//! A rigid body's mass properties: its mass, its centre of mass and its inertia about that centre,
//! in the frame of the joint that carries it (URDF's `<inertial>`), and how two bodies on one
//! frame combine (a link and what is fixed to it, a payload in the gripper).

use nalgebra::{Matrix3, Vector3};

use crate::Real;

/// The mass properties of one body, in its frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inertia<T: Real> {
    /// Mass (kg).
    pub mass: T,
    /// Centre of mass (m), in the frame.
    pub com: Vector3<T>,
    /// Inertia tensor about the centre of mass (kg m²), in the frame's axes.
    pub tensor: Matrix3<T>,
}

/// Why mass properties were refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InertiaError {
    /// A number is not finite.
    NotFinite,
    /// The mass is negative.
    NegativeMass,
    /// The tensor is not one a body can have: not symmetric, not positive semi-definite, or a
    /// moment larger than the other two together.
    NotPhysical,
}

impl core::fmt::Display for InertiaError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            InertiaError::NotFinite => "a mass, centre of mass or inertia is not a finite number",
            InertiaError::NegativeMass => "a mass is negative",
            InertiaError::NotPhysical => {
                "an inertia tensor is not symmetric or not positive semi-definite, or its moments break the triangle inequality"
            }
        })
    }
}

impl<T: Real> Inertia<T> {
    /// No mass.
    pub fn zero() -> Self {
        Self { mass: T::zero(), com: Vector3::zeros(), tensor: Matrix3::zeros() }
    }

    /// A point mass at `com`.
    pub fn point(mass: T, com: Vector3<T>) -> Self {
        Self { mass, com, tensor: Matrix3::zeros() }
    }

    /// Checks the numbers: finite, a mass not negative, a symmetric tensor that is positive
    /// semi-definite (no principal minor negative) and whose diagonal moments are each at most the
    /// sum of the other two, all within rounding, as every body's tensor is in any frame.
    pub fn validated(self) -> Result<Self, InertiaError> {
        let finite = self.mass.finite() && self.com.iter().chain(self.tensor.iter()).all(|x| x.finite());
        if !finite {
            return Err(InertiaError::NotFinite);
        }
        if self.mass < T::zero() {
            return Err(InertiaError::NegativeMass);
        }
        let t = &self.tensor;
        let scale = t.iter().fold(T::zero(), |m, x| m.max(x.abs()));
        let slack = scale * T::of(1e-6);
        let symmetric =
            (t.m12 - t.m21).abs() <= slack && (t.m13 - t.m31).abs() <= slack && (t.m23 - t.m32).abs() <= slack;
        let (a, b, c) = (t.m11, t.m22, t.m33);
        // Positive semi-definite: every principal minor (the moments, the three 2 x 2 ones, the
        // determinant) not negative.
        let minor = |p: T, q: T, r: T| p * q - r * r;
        let moments = a >= -slack && b >= -slack && c >= -slack;
        let slack2 = slack * scale;
        let minors = minor(a, b, t.m12) >= -slack2 && minor(a, c, t.m13) >= -slack2 && minor(b, c, t.m23) >= -slack2;
        let determinant = t.determinant() >= -slack2 * scale;
        let triangle = a <= b + c + slack && b <= a + c + slack && c <= a + b + slack;
        if symmetric && moments && minors && determinant && triangle {
            Ok(self)
        } else {
            Err(InertiaError::NotPhysical)
        }
    }

    /// This body as seen from a frame in which its own frame is at `translation` turned by
    /// `rotation` (the columns its axes): the same body, its numbers in the other frame.
    pub fn moved(&self, rotation: &Matrix3<T>, translation: &Vector3<T>) -> Self {
        Self {
            mass: self.mass,
            com: rotation * self.com + translation,
            tensor: rotation * self.tensor * rotation.transpose(),
        }
    }

    /// The two bodies as one (both in the same frame): the masses add, the centre of mass is
    /// their weighted mean, and each tensor is carried to it by the parallel-axis theorem.
    pub fn combined(&self, other: &Self) -> Self {
        let mass = self.mass + other.mass;
        if mass <= T::zero() {
            return Self::zero();
        }
        let com = (self.com * self.mass + other.com * other.mass) / mass;
        let shifted = |body: &Self| {
            let d = body.com - com;
            // Steiner: I + m (|d|² E - d dᵀ).
            body.tensor + (Matrix3::identity() * d.norm_squared() - d * d.transpose()) * body.mass
        };
        Self { mass, com, tensor: shifted(self) + shifted(other) }
    }
}
