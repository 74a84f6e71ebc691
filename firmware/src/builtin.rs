//! The arm the firmware drives when the host configures none: an SO-101 (Feetech STS3215 servos).

use kinematics::{presets, Chain, ChainError};

/// Joint count of the built-in arm.
pub const JOINTS: usize = 5;

/// The built-in arm's chain, in the firmware's scalar.
pub fn arm() -> Result<Chain<f32, JOINTS>, ChainError> {
    presets::so101()
}
