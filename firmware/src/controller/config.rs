//! How the controller runs: tick rate, watchdog, IK budget, and the joint limits it enforces.

use kinematics::nalgebra::SVector;
use kinematics::trajectory::JointLimits;
use kinematics::Chain;

use crate::bus::mapping::JointMapping;
use crate::bus::master::BusConfig;
use crate::bus::table::Model;
use crate::bus::timing::cycle_time_us;

/// Timing and budgets of the control loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Config {
    /// Tick period in microseconds (10 000 = 100 Hz).
    pub period_us: u32,
    /// Host silence, while the arm moves on its own (playing or tracking), after which it stops.
    pub watchdog_ms: u32,
    /// IK iterations per tick while tracking a Cartesian goal: the bound that keeps the tick on time.
    pub ik_iterations_per_tick: u32,
    /// IK iterations (over all restarts) spent when a Cartesian goal is accepted, to refuse
    /// unreachable ones before the arm starts moving.
    pub ik_check_iterations: u32,
    /// Consecutive ticks without a reply after which a servo counts as lost.
    pub lost_after: u16,
}

impl Default for Config {
    /// 100 Hz, a 500 ms watchdog, 4 IK iterations per tick, 300 to check a goal, lost after 5
    /// silent ticks.
    fn default() -> Self {
        Self { period_us: 10_000, watchdog_ms: 500, ik_iterations_per_tick: 4, ik_check_iterations: 300, lost_after: 5 }
    }
}

/// Why a controller could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConfigError {
    /// The period is zero, or shorter than one bus cycle (sync write of goals plus sync read of
    /// positions) at the bus's baud rate and return delay.
    PeriodTooShort {
        /// The shortest period the bus allows, µs.
        minimum_us: u32,
    },
    /// A limit is NaN, not positive where it must be, or the joint's range is empty once the
    /// chain's limits and the servo's tick range are intersected.
    BadLimits {
        /// The joint.
        joint: usize,
    },
    /// More joints than a bus group can address.
    TooManyJoints,
    /// The gripper's positions coincide, its effort or speed is out of range, or its id is a
    /// joint's.
    BadGripper,
    /// The built-in arm's configuration was refused (the firmware takes it as a host's).
    BuiltinRefused,
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::PeriodTooShort { minimum_us } => write!(f, "tick period below the bus cycle of {minimum_us} µs"),
            Self::BadLimits { joint } => write!(f, "joint {joint}: unusable limits"),
            Self::TooManyJoints => write!(f, "more joints than one sync read can address"),
            Self::BadGripper => write!(f, "unusable gripper (positions, effort, speed or id)"),
            Self::BuiltinRefused => write!(f, "the built-in arm's configuration was refused"),
        }
    }
}

/// The shortest tick period, in µs, the bus allows for `joints` servos of `model`: one sync write
/// of goals and one sync read of positions, plus the master's margin for the replies.
pub fn minimum_period_us(model: &Model, bus: &BusConfig, joints: usize) -> u32 {
    let goal = model.items.goal_position.len();
    let position = model.items.present_position.len();
    let us =
        cycle_time_us(bus.protocol, joints, goal, position, bus.baud, bus.return_delay_us) + u64::from(bus.margin_us);
    u32::try_from(us).unwrap_or(u32::MAX)
}

/// The limits the controller enforces: the chain's joint range intersected with what each servo's
/// tick range can reach, and the given velocity and acceleration limits.
pub fn joint_limits<const N: usize>(
    chain: &Chain<f32, N>,
    mappings: &[JointMapping; N],
    max_velocity: SVector<f32, N>,
    max_acceleration: SVector<f32, N>,
) -> Result<JointLimits<f32, N>, ConfigError> {
    let mut lower = SVector::<f32, N>::zeros();
    let mut upper = SVector::<f32, N>::zeros();
    for (j, (joint, mapping)) in chain.joints().iter().zip(mappings).enumerate() {
        let (lo, hi) = mapping.joint_range::<f32>();
        // Half a tick inside the servo's range, so rounding to ticks never lands outside it.
        let half_tick = core::f32::consts::PI / mapping.ticks_per_revolution.max(1) as f32;
        lower[j] = joint.limits.lower.max(lo + half_tick);
        upper[j] = joint.limits.upper.min(hi - half_tick);
        if lower[j].is_nan() || upper[j].is_nan() || lower[j] > upper[j] {
            return Err(ConfigError::BadLimits { joint: j });
        }
    }
    JointLimits::new(lower, upper, max_velocity, max_acceleration).map_err(|e| match e {
        kinematics::trajectory::LimitError::InvalidLimits { joint } => ConfigError::BadLimits { joint },
        _ => ConfigError::BadLimits { joint: 0 },
    })
}
