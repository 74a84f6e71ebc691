//! The arm the firmware drives when the host configures none: an SO-101 (Feetech STS3215 servos).

use kinematics::nalgebra::SVector;
use kinematics::{presets, Chain, ChainError};

use crate::app::ArmSetup;
use crate::bus::mapping::JointMapping;
use crate::bus::table::STS3215;
use crate::controller::ConfigError;

/// Joint count of the built-in arm.
pub const JOINTS: usize = 5;

/// Joint speed limit of the built-in arm (rad/s): under half the STS3215's no-load speed at 7.4 V
/// (about 4.7 rad/s), so the servos keep up under load.
pub const MAX_VELOCITY: f32 = 2.0;

/// Joint acceleration limit of the built-in arm (rad/s²).
pub const MAX_ACCELERATION: f32 = 8.0;

/// The built-in arm's chain, in the firmware's scalar.
pub fn arm() -> Result<Chain<f32, JOINTS>, ChainError> {
    presets::so101()
}

/// The built-in arm with its servos: ids 1 to 5 from the base (as the SO-101 assembly guide sets
/// them), 4096 ticks per turn, centred at zero, turning with the joint axes.
pub fn setup() -> Result<ArmSetup<JOINTS>, ConfigError> {
    let chain = arm().map_err(|_| ConfigError::BadLimits { joint: 0 })?;
    let mappings = core::array::from_fn(|j| JointMapping::centred(j as u8 + 1, STS3215.ticks_per_revolution));
    let velocity = SVector::repeat(MAX_VELOCITY);
    let acceleration = SVector::repeat(MAX_ACCELERATION);
    ArmSetup::new("so101", chain, mappings, &STS3215, velocity, acceleration)
}
