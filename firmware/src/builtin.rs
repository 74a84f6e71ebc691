//! The arm the firmware drives when the host configures none: an SO-101 (Feetech STS3215 servos).

use kinematics::{presets, Chain, ChainError};

use crate::app::ArmSetup;
use crate::bus::mapping::JointMapping;
use crate::bus::table::STS3215;
use crate::controller::{ConfigError, GripperConfig};

/// Joint count of the built-in arm.
pub const JOINTS: usize = 5;
/// Its name, as the host's preset calls it.
pub const NAME: &str = "so101";

/// Its digest ([`crate::link::message::Info::arm_digest`]): the one the host computes for the
/// `so101` preset with its servos as shipped, so that a host sending that preset finds it already
/// running, and one sending another arm of the name (a calibrated SO-101) finds it different.
/// `host/src/link/arm_config.rs` checks that the two agree.
pub const DIGEST: u32 = 0xb24a_4ff4;

/// Joint speed limit of the built-in arm (rad/s): under half the STS3215's no-load speed at 7.4 V
/// (about 4.7 rad/s), so the servos keep up under load.
pub const MAX_VELOCITY: f32 = 2.0;

/// Joint acceleration limit of the built-in arm (rad/s²).
pub const MAX_ACCELERATION: f32 = 8.0;

/// The built-in arm's chain, in the firmware's scalar.
pub fn arm() -> Result<Chain<f32, JOINTS>, ChainError> {
    presets::so101()
}

/// The SO-101's gripper: servo 6 (STS3215), between the URDF's gripper joint limits
/// (`so101_new_calib.urdf`: -10° closed, 100° open) on a factory-fresh servo whose middle (2048)
/// is the joint's zero: 2048 - 10/360 * 4096 = 1934 and 2048 + 100/360 * 4096 = 3186 ticks
/// (rounded). Effort 50 %, LeRobot's Max_Torque_Limit 500 of 1000; 100 % of the stroke a second.
pub const GRIPPER: GripperConfig = GripperConfig { id: 6, closed: 1934, open: 3186, effort: 50.0, speed: 100.0 };

/// The built-in arm with its servos, on a firmware of `N` joints (at least [`JOINTS`]; more are
/// padding): ids 1 to 5 from the base (as the SO-101 assembly guide sets them), 4096 ticks per
/// turn, centred at zero, turning with the joint axes; and its gripper, servo 6 ([`GRIPPER`]).
pub fn setup<const N: usize>() -> Result<ArmSetup<N>, ConfigError> {
    let mut setup = ArmSetup::blank(&STS3215);
    set_up(&mut setup)?;
    Ok(setup)
}

/// [`setup`], in place: how a board builds its built-in arm in static memory.
pub fn set_up<const N: usize>(setup: &mut ArmSetup<N>) -> Result<(), ConfigError> {
    let chain = arm().map_err(|_| ConfigError::BadLimits { joint: 0 })?;
    let mappings: [JointMapping; JOINTS] =
        core::array::from_fn(|j| JointMapping::centred(j as u8 + 1, STS3215.ticks_per_revolution));
    let (velocity, acceleration) = ([MAX_VELOCITY; JOINTS], [MAX_ACCELERATION; JOINTS]);
    setup.set_padded(NAME, chain.joints(), *chain.tool(), &mappings, &STS3215, &velocity, &acceleration)?;
    setup.gripper = Some(GRIPPER);
    setup.digest = DIGEST;
    Ok(())
}
