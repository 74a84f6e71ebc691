//! Why the controller refuses a command: one answer for every part of it that checks a value (the
//! commands, the gripper). Its own module, beneath them all, so that none of them imports another
//! for it.

/// Why a command was refused. Nothing changed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Refusal {
    /// A value is NaN or infinite.
    NotFinite,
    /// A joint value lies outside the joint's limits.
    OutOfRange {
        /// The joint.
        joint: usize,
    },
    /// A duration or speed is not positive, or a quaternion is zero.
    BadParameter,
    /// No joint values reach the Cartesian goal within the joint limits.
    Unreachable {
        /// The closest the tool got, m.
        position_error: f32,
    },
    /// Emergency stopped: only torque on (or off) is accepted.
    EStopped,
    /// The torque is off.
    TorqueOff,
    /// Not every servo's position has been read yet.
    NoPosition,
    /// The keyframe queue is full.
    QueueFull,
    /// The keyframe is not later than the last one queued.
    TimeNotIncreasing,
    /// Nothing to start, or nothing playing to pause.
    WrongMode,
    /// The arm has no gripper.
    NoGripper,
    /// The target brings two checked parts closer than the collision margin.
    Collision {
        /// The pair and their distance at the target.
        contact: kinematics::collision::Contact<f32>,
    },
}

impl core::fmt::Display for Refusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NotFinite => write!(f, "NaN or infinite value"),
            Self::OutOfRange { joint } => write!(f, "joint {joint}: outside its limits"),
            Self::BadParameter => write!(f, "duration, speed or quaternion not usable"),
            Self::Unreachable { position_error } => write!(f, "unreachable: closest {position_error} m away"),
            Self::EStopped => write!(f, "emergency stopped"),
            Self::TorqueOff => write!(f, "torque is off"),
            Self::NoPosition => write!(f, "servo positions not read yet"),
            Self::QueueFull => write!(f, "keyframe queue full"),
            Self::TimeNotIncreasing => write!(f, "keyframe time not later than the previous one"),
            Self::WrongMode => write!(f, "not possible in this mode"),
            Self::NoGripper => write!(f, "the arm has no gripper"),
            Self::Collision { contact } => {
                write!(f, "body {} within {} m of {:?}", contact.body, contact.distance, contact.other)
            }
        }
    }
}
