//! The shapes collision is checked between: a link's bodies are capsules (a sphere is the capsule
//! whose two ends coincide), the surroundings are capsules, boxes and half-spaces (a table is the
//! half-space below its top).

use nalgebra::{Matrix3, Vector3};

use crate::{Pose, Real};

/// The points within `radius` of the segment from `a` to `b`; a sphere when `a == b`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Capsule<T: Real> {
    /// One end of the core segment.
    pub a: Vector3<T>,
    /// The other end.
    pub b: Vector3<T>,
    /// Radius (m), at least zero.
    pub radius: T,
}

impl<T: Real> Capsule<T> {
    /// A sphere of `radius` about `centre`.
    pub fn sphere(centre: Vector3<T>, radius: T) -> Self {
        Self { a: centre, b: centre, radius }
    }

    /// The same capsule moved by `pose` (its frame's pose in the base frame).
    pub fn placed(&self, pose: &Pose<T>) -> Self {
        Self {
            a: pose.rotation * self.a + pose.translation,
            b: pose.rotation * self.b + pose.translation,
            radius: self.radius,
        }
    }

    /// True if every number is finite and the radius is not negative.
    pub fn is_valid(&self) -> bool {
        finite3(&self.a) && finite3(&self.b) && self.radius.finite() && self.radius >= T::zero()
    }

    /// The centre and radius of a sphere that holds the whole capsule.
    pub(crate) fn bounding_sphere(&self) -> (Vector3<T>, T) {
        let half = T::of(0.5);
        ((self.a + self.b) * half, (self.b - self.a).norm_squared().root() * half + self.radius)
    }
}

/// An obstacle: what the arm's bodies must keep clear of.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape<T: Real> {
    /// A capsule or a sphere.
    Capsule(Capsule<T>),
    /// A box: its centre, its axes (the rotation's columns) and its half sizes along them.
    Box {
        /// Centre, base frame.
        centre: Vector3<T>,
        /// Orthonormal: the box's axes in the base frame.
        rotation: Matrix3<T>,
        /// Half the size along each axis (m), each positive.
        half: Vector3<T>,
    },
    /// The half-space `normal · x <= offset`: below a table's top when the normal is up.
    HalfSpace {
        /// Unit normal, pointing out of the solid.
        normal: Vector3<T>,
        /// The surface's distance from the origin along the normal.
        offset: T,
    },
}

impl<T: Real> Shape<T> {
    /// An axis-aligned box from its centre and full sizes.
    pub fn aligned_box(centre: Vector3<T>, size: Vector3<T>) -> Self {
        Shape::Box { centre, rotation: Matrix3::identity(), half: size * T::of(0.5) }
    }

    /// The table whose top is the plane `z = height`, the solid below it.
    pub fn table(height: T) -> Self {
        Shape::HalfSpace { normal: Vector3::z(), offset: height }
    }

    /// True if every number is finite, sizes are positive, a box's axes orthonormal and a
    /// half-space's normal of unit length.
    pub fn is_valid(&self) -> bool {
        let tolerance = T::of(1e-4);
        match self {
            Shape::Capsule(c) => c.is_valid(),
            Shape::Box { centre, rotation, half } => {
                finite3(centre)
                    && rotation.iter().all(|x| x.finite())
                    && (rotation.transpose() * rotation - Matrix3::identity()).iter().all(|x| x.abs() <= tolerance)
                    && finite3(half)
                    && half.iter().all(|h| *h > T::zero())
            }
            Shape::HalfSpace { normal, offset } => {
                finite3(normal) && offset.finite() && (normal.norm() - T::one()).abs() <= tolerance
            }
        }
    }
}

fn finite3<T: Real>(v: &Vector3<T>) -> bool {
    v.iter().all(|x| x.finite())
}
