//! The arm the firmware drives when the host configures none: an SO-101 (Feetech STS3215 servos).
//!
//! It is kept as the very messages a host sends to configure it ([`BuiltinArm`]), and the firmware
//! takes it by replaying them through the request handler's own configuration path: the built-in
//! arm is staged, checked and committed by the code that takes an arm over the link, and a host
//! that sends the `so101` preset sends these messages, byte for byte (a host test compares them).

use heapless::String;
use kinematics::{presets, Chain, ChainError};

use crate::controller::GripperConfig;
use crate::link::message::{self, BusProtocol, HostMessage, JointConfig, JointType, ServoConfig, MAX_NAME};

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

/// The built-in arm's chain from the kinematics presets (`so101_new_calib.urdf`), in the
/// firmware's scalar: what [`SO101`]'s joints describe.
pub fn arm() -> Result<Chain<f32, JOINTS>, ChainError> {
    presets::so101()
}

/// The SO-101's gripper: servo 6 (STS3215), between the URDF's gripper joint limits
/// (`so101_new_calib.urdf`: -10° closed, 100° open) on a factory-fresh servo whose middle (2048)
/// is the joint's zero: 2048 - 10/360 * 4096 = 1934 and 2048 + 100/360 * 4096 = 3186 ticks
/// (rounded). Effort 50 %, LeRobot's Max_Torque_Limit 500 of 1000; 100 % of the stroke a second.
pub const GRIPPER: GripperConfig = GripperConfig { id: 6, closed: 1934, open: 3186, effort: 50.0, speed: 100.0 };

/// An arm kept in flash as the messages that configure it (see [`BuiltinArm::message`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuiltinArm {
    /// Its name.
    pub name: &'static str,
    /// The tool frame after the last joint: position (m) and roll, pitch, yaw (rad).
    pub tool_xyz: [f32; 3],
    /// See `tool_xyz`.
    pub tool_rpy: [f32; 3],
    /// Its servos' model number.
    pub model: u16,
    /// Its servos' bus: protocol and baud rate.
    pub bus: (BusProtocol, u32),
    /// Its joints, base first.
    pub joints: &'static [JointConfig],
    /// Its gripper, if it has one.
    pub gripper: Option<message::GripperConfig>,
    /// The digest of its other messages, as a host computes it.
    pub digest: u32,
}

impl BuiltinArm {
    /// Its `i`-th configure message, in the order a host sends them: begin, bus, the joints, the
    /// gripper, the digest, commit; `None` past the last.
    pub fn message(&self, i: usize) -> Option<HostMessage> {
        let joints = self.joints.len();
        let gripper = usize::from(self.gripper.is_some());
        let message = match i {
            0 => {
                let mut name = String::<MAX_NAME>::new();
                // A name too long is cut; the commit still checks the arm.
                for c in self.name.chars() {
                    if name.push(c).is_err() {
                        break;
                    }
                }
                HostMessage::ConfigureBegin {
                    name,
                    joints: u8::try_from(joints).unwrap_or(u8::MAX),
                    tool_xyz: self.tool_xyz,
                    tool_rpy: self.tool_rpy,
                    model: self.model,
                }
            }
            1 => HostMessage::ConfigureBus { protocol: self.bus.0, baud: self.bus.1 },
            i if i < 2 + joints => {
                let index = i - 2;
                HostMessage::ConfigureJoint { index: index as u8, joint: *self.joints.get(index)? }
            }
            i if i < 2 + joints + gripper => HostMessage::ConfigureGripper(self.gripper?),
            i if i == 2 + joints + gripper => HostMessage::ConfigureDigest { digest: self.digest },
            i if i == 3 + joints + gripper => HostMessage::ConfigureCommit,
            _ => return None,
        };
        Some(message)
    }

    /// Its configure messages in order ([`BuiltinArm::message`]).
    pub fn messages(&self) -> impl Iterator<Item = HostMessage> + '_ {
        (0..).map_while(|i| self.message(i))
    }
}

/// A joint of the built-in arm: revolute about z, its servo centred at zero (2048 of 4096 ticks),
/// turning with the joint, its full single-turn range, and the arm's speed and acceleration limits.
const fn joint(id: u8, origin_xyz: [f32; 3], origin_rpy: [f32; 3], lower: f32, upper: f32) -> JointConfig {
    JointConfig {
        kind: JointType::Revolute,
        origin_xyz,
        origin_rpy,
        axis: [0.0, 0.0, 1.0],
        lower,
        upper,
        max_velocity: MAX_VELOCITY,
        max_acceleration: MAX_ACCELERATION,
        servo: ServoConfig {
            id,
            ticks_per_revolution: 4096,
            zero: 2048,
            reversed: false,
            min_ticks: 0,
            max_ticks: 4095,
            zero_half: false,
            truncate: false,
        },
    }
}

/// The SO-101's joints as the host sends the `so101` preset: the URDF's origins (rotations as
/// the host turns them back into roll, pitch and yaw) and limits in f32, servos 1 to 5 from the
/// base (as the SO-101 assembly guide sets them). The file rounds pi to 3.14159 and pi/2 to
/// 1.5708; the values are the file's (or their f32 round trip), not the constants.
#[allow(clippy::approx_constant)]
const SO101_JOINTS: [JointConfig; JOINTS] = [
    joint(1, [0.0388353, -8.97657e-9, 0.0624], [3.14159, 4.18253e-17, -3.14159], -1.91986, 1.91986),
    joint(2, [-0.0303992, -0.0182778, -0.0542], [1.5707927, -1.5707927, -3.1415927], -1.74533, 1.74533),
    joint(3, [-0.11257, -0.028, 1.73763e-16], [-3.63608e-16, 8.74301e-16, 1.5708], -1.69, 1.69),
    joint(4, [-0.1349, 0.0052, 3.62355e-17], [4.02456e-15, 8.67362e-16, -1.5708], -1.65806, 1.65806),
    joint(5, [5.55112e-17, -0.0611, 0.0181], [1.5708, 0.0486795, 3.14159], -2.74385, 2.84121),
];

/// The built-in SO-101: its five joints on Feetech STS3215 servos at 1 Mbps, and its
/// gripper, servo 6 ([`GRIPPER`]).
#[allow(clippy::approx_constant)]
pub const SO101: BuiltinArm = BuiltinArm {
    name: NAME,
    tool_xyz: [-0.0079, -0.000218121, -0.0981274],
    tool_rpy: [-3.1415927, 2.6535897e-6, -3.1415927],
    model: crate::bus::table::STS3215.number,
    bus: (BusProtocol::Feetech, 1_000_000),
    joints: &SO101_JOINTS,
    gripper: Some(message::GripperConfig {
        id: GRIPPER.id,
        closed: GRIPPER.closed,
        open: GRIPPER.open,
        effort: GRIPPER.effort,
        speed: GRIPPER.speed,
    }),
    digest: DIGEST,
};
