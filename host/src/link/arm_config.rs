//! The messages that send an arm to the firmware: [`HostMessage::ConfigureBegin`], its bus
//! ([`HostMessage::ConfigureBus`]), one
//! [`HostMessage::ConfigureJoint`] per joint, [`HostMessage::ConfigureGripper`] if the arm has a
//! gripper, its collision geometry if it has any ([`HostMessage::ConfigureCollision`], one
//! [`HostMessage::ConfigureBody`] per body, [`HostMessage::ConfigureObstacle`] per obstacle,
//! [`HostMessage::ConfigureAllowed`] per allowed pair: see [`collision_messages`]), its digest
//! ([`HostMessage::ConfigureDigest`]), [`HostMessage::ConfigureCommit`]. The geometry comes
//! from the host's arm description ([`ArmSpec`]); the servos (model, ids, speed limits) from a
//! [`ServoSetup`].

use anyhow::{anyhow, bail, Result};
use firmware::bus::mapping::{Direction, JointMapping};
use firmware::link::message::{
    BodyConfig, CollisionPart, GripperConfig, HostMessage, JointConfig, JointType, ObstacleShape, ServoConfig,
    MAX_BODIES, MAX_JOINTS, MAX_NAME, MAX_OBSTACLES,
};
use kinematics::collision::{Part, Shape};
use kinematics::nalgebra::Matrix3;
use kinematics::JointKind;

use crate::arm::collision::{collision_of, CollisionSpec};

use crate::arm::servos::ServoSetup;
use crate::arm::ArmSpec;

/// Roll, pitch and yaw (URDF's fixed-axis convention, `R = Rz(yaw) Ry(pitch) Rx(roll)`) of a
/// rotation matrix.
pub fn rpy(r: &Matrix3<f64>) -> [f64; 3] {
    let pitch = (-r[(2, 0)]).atan2((r[(2, 1)].powi(2) + r[(2, 2)].powi(2)).sqrt());
    if r[(2, 0)].abs() < 1.0 - 1e-12 {
        [r[(2, 1)].atan2(r[(2, 2)]), pitch, r[(1, 0)].atan2(r[(0, 0)])]
    } else {
        // Gimbal lock: only roll - yaw (or roll + yaw) is defined; put it all in roll.
        [(-r[(1, 2)]).atan2(r[(1, 1)]), pitch, 0.0]
    }
}

fn f32s(v: [f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}

/// The link's form of a joint's servo mapping.
pub fn servo_config(m: &JointMapping) -> ServoConfig {
    ServoConfig {
        id: m.id,
        ticks_per_revolution: m.ticks_per_revolution,
        zero: m.zero,
        reversed: m.direction == Direction::Reverse,
        min_ticks: m.min_ticks,
        max_ticks: m.max_ticks,
        zero_half: m.zero_half,
        truncate: m.truncate,
    }
}

/// The digest of an arm's configure messages (FNV-1a, 32 bits, over their frames as the link
/// encodes them), never 0: what the firmware reports while it runs the arm
/// ([`firmware::link::message::Info::arm_digest`]). Any change to what is sent (a joint, a servo's
/// calibration, the gripper, the bus) changes it.
pub fn digest_of(messages: &[HostMessage]) -> u32 {
    let mut hash: u32 = 0x811c_9dc5;
    let mut frame = [0u8; firmware::link::frame::MAX_ENCODED];
    for m in messages {
        let n = firmware::link::frame::encode_message(0, firmware::link::frame::FrameKind::Request, m, &mut frame)
            .unwrap_or(0);
        for &b in &frame[..n] {
            hash = (hash ^ u32::from(b)).wrapping_mul(0x0100_0193);
        }
    }
    hash.max(1)
}

/// Whether the firmware checks every goal against the arm's collision geometry.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CollisionCheck {
    /// It does (the default): the geometry is sent with the check on.
    #[default]
    On,
    /// It does not (`--no-collision-check`, for a test that must see the arm reach a contact):
    /// the geometry is sent with the check off, and the firmware's status says so.
    Off,
}

/// The digest [`configure_messages`] sends for `arm` with `servos`.
pub fn arm_digest(arm: &ArmSpec, servos: &ServoSetup) -> Result<u32> {
    arm_digest_checked(arm, servos, CollisionCheck::On)
}

/// The digest [`configure_messages_checked`] sends: the check's state is part of the arm.
pub fn arm_digest_checked(arm: &ArmSpec, servos: &ServoSetup, check: CollisionCheck) -> Result<u32> {
    Ok(digest_of(&arm_messages(arm, servos, check)?))
}

/// The messages that configure `arm` with `servos` on the firmware: the arm, its digest, commit.
pub fn configure_messages(arm: &ArmSpec, servos: &ServoSetup) -> Result<Vec<HostMessage>> {
    configure_messages_checked(arm, servos, CollisionCheck::On)
}

/// [`configure_messages`] with the collision check on or off.
pub fn configure_messages_checked(
    arm: &ArmSpec,
    servos: &ServoSetup,
    check: CollisionCheck,
) -> Result<Vec<HostMessage>> {
    let mut messages = arm_messages(arm, servos, check)?;
    let digest = digest_of(&messages);
    messages.push(HostMessage::ConfigureDigest { digest });
    messages.push(HostMessage::ConfigureCommit);
    Ok(messages)
}

/// The messages that describe `arm` with `servos` (begin, bus, joints, gripper, collision
/// geometry), each checked as the firmware will check it.
fn arm_messages(arm: &ArmSpec, servos: &ServoSetup, check: CollisionCheck) -> Result<Vec<HostMessage>> {
    let n = arm.joints.len();
    if n == 0 || n > MAX_JOINTS {
        bail!("arm {} has {n} joints; the link carries 1 to {MAX_JOINTS}", arm.name);
    }
    if servos.ids.len() != n {
        bail!("arm {} has {n} joints but {} servo ids", arm.name, servos.ids.len());
    }
    if servos.zero.as_ref().is_some_and(|z| z.len() != n) || servos.reversed.as_ref().is_some_and(|r| r.len() != n) {
        bail!("arm {}: the servo zero and reversed lists need one entry per joint ({n})", arm.name);
    }
    let mut name = heapless::String::<MAX_NAME>::new();
    if name.push_str(&arm.name).is_err() {
        bail!("arm name {:?} is longer than {MAX_NAME} bytes", arm.name);
    }
    let mut messages = vec![HostMessage::ConfigureBegin {
        name,
        joints: n as u8,
        tool_xyz: f32s(arm.tool.translation.into()),
        tool_rpy: f32s(rpy(&arm.tool.rotation)),
        model: servos.model.number,
    }];
    // The bus goes with the arm: a board switches its servo bus to it (protocol and baud rate).
    messages.push(HostMessage::ConfigureBus { protocol: servos.model.protocol.into(), baud: servos.baud });
    for (j, (joint, &id)) in arm.joints.iter().zip(&servos.ids).enumerate() {
        let kind = match joint.kind {
            JointKind::Revolute => JointType::Revolute,
            JointKind::Continuous => JointType::Continuous,
            JointKind::Prismatic => bail!("joint {}: prismatic joints have no servo mapping yet", joint.name),
            JointKind::Fixed => {
                bail!("joint {}: a fixed joint has no servo: fold it into the next joint's origin", joint.name)
            }
        };
        messages.push(HostMessage::ConfigureJoint {
            index: j as u8,
            joint: JointConfig {
                kind,
                origin_xyz: f32s(joint.origin.translation.into()),
                origin_rpy: f32s(rpy(&joint.origin.rotation)),
                axis: f32s(joint.axis),
                lower: joint.lower as f32,
                upper: joint.upper as f32,
                max_velocity: servos.max_velocity as f32,
                max_acceleration: servos.max_acceleration as f32,
                servo: servo_config(&servos.mapping(j).ok_or_else(|| anyhow::anyhow!("servo {id}: no mapping"))?),
            },
        });
    }
    if let Some(g) = &servos.gripper {
        messages.push(HostMessage::ConfigureGripper(GripperConfig {
            id: g.id,
            closed: g.closed,
            open: g.open,
            effort: g.effort as f32,
            speed: g.speed as f32,
        }));
    }
    if let Some(spec) = collision_of(arm) {
        messages.extend(collision_messages(&spec, n, check).map_err(|e| anyhow!("arm {}: {e:#}", arm.name))?);
    }
    for m in &messages {
        if let Err(e) = m.validate() {
            bail!("arm {} cannot be sent: {:?} is {:?}", arm.name, e.field, e.problem);
        }
    }
    Ok(messages)
}

fn f32s_of(v: &kinematics::nalgebra::Vector3<f64>) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// The link's form of an obstacle's shape (a box's axes as a unit quaternion, w-first).
pub fn obstacle_shape(shape: &Shape<f64>) -> ObstacleShape {
    match shape {
        Shape::Capsule(c) => ObstacleShape::Capsule { a: f32s_of(&c.a), b: f32s_of(&c.b), radius: c.radius as f32 },
        Shape::Box { centre, rotation, half } => ObstacleShape::Box {
            centre: f32s_of(centre),
            rotation: kinematics::quaternion_wxyz(rotation).map(|x| x as f32),
            half: f32s_of(half),
        },
        Shape::HalfSpace { normal, offset } => {
            ObstacleShape::HalfSpace { normal: f32s_of(normal), offset: *offset as f32 }
        }
    }
}

/// The messages that send `spec`, the geometry of an arm of `joints` joints: the margin and the
/// check, each body and obstacle in order, each allowed pair by index. The whole geometry is
/// first built as the firmware will build it (in f32, at its capacity), so what it would refuse
/// is refused here, by name, before anything is sent.
pub fn collision_messages(spec: &CollisionSpec, joints: usize, check: CollisionCheck) -> Result<Vec<HostMessage>> {
    spec.scene::<f32, MAX_BODIES, MAX_OBSTACLES>(joints)?;
    let mut messages =
        vec![HostMessage::ConfigureCollision { margin: spec.margin as f32, check: check == CollisionCheck::On }];
    for (i, body) in spec.bodies.iter().enumerate() {
        let frame = body.link.map(u8::try_from).transpose()?;
        let c = &body.capsule;
        let config = BodyConfig { frame, a: f32s_of(&c.a), b: f32s_of(&c.b), radius: c.radius as f32 };
        messages.push(HostMessage::ConfigureBody { index: i as u8, body: config });
    }
    for (o, obstacle) in spec.obstacles.iter().enumerate() {
        messages.push(HostMessage::ConfigureObstacle { index: o as u8, shape: obstacle_shape(&obstacle.shape) });
    }
    for [a, b] in &spec.allowed {
        // Named as `scene` found them: a body first, then the other part.
        let (body, other) = match (spec.part(a), spec.part(b)) {
            (Some(Part::Body(i)), Some(other)) | (Some(other), Some(Part::Body(i))) => (i, other),
            _ => bail!("allowed pair {a} and {b}: not a body and another part"),
        };
        let other = match other {
            Part::Body(j) => CollisionPart::Body(j),
            Part::Obstacle(o) => CollisionPart::Obstacle(o),
        };
        messages.push(HostMessage::ConfigureAllowed { body, other });
    }
    for m in &messages {
        if let Err(e) = m.validate() {
            bail!("collision geometry cannot be sent: {}", crate::link::client::Value(&e));
        }
    }
    Ok(messages)
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::Pose;

    #[test]
    fn rpy_inverts_from_xyz_rpy() {
        for rpy_in in [[0.1, -0.4, 2.0], [0.0, 0.0, 0.0], [-3.0, 1.2, -0.7], [1.0, std::f64::consts::FRAC_PI_2, 0.0]] {
            let pose = Pose::<f64>::from_xyz_rpy([0.0; 3], rpy_in);
            let back = Pose::<f64>::from_xyz_rpy([0.0; 3], rpy(&pose.rotation));
            assert!((back.rotation - pose.rotation).amax() < 1e-7, "{rpy_in:?}");
        }
    }

    /// The built-in arm reports the digest of the `so101` preset as shipped, so a host sending
    /// the preset finds it running; a calibration, another gripper or another bus changes it.
    #[test]
    fn the_builtin_arm_is_the_so101_preset_as_a_host_sends_it() {
        // The built-in arm carries no collision geometry: it is the preset without it (a host
        // sends the preset's geometry, so it sends the arm again).
        let so101 = ArmSpec { collision: None, ..ArmSpec::load("so101", None).unwrap() };
        let shipped = ServoSetup::for_arm("so101").unwrap();
        let sent = configure_messages(&so101, &shipped).unwrap();
        let builtin: Vec<HostMessage> = firmware::builtin::SO101.messages().collect();
        assert_eq!(builtin, sent, "firmware::builtin::SO101 should be these messages");
    }

    #[test]
    fn the_builtin_digest_is_the_so101_presets() {
        let so101 = ArmSpec { collision: None, ..ArmSpec::load("so101", None).unwrap() };
        let shipped = ServoSetup::for_arm("so101").unwrap();
        let digest = arm_digest(&so101, &shipped).unwrap();
        assert_eq!(digest, firmware::builtin::DIGEST, "firmware::builtin::DIGEST should be {digest:#010x}");
        let mut other = shipped.clone();
        other.zero = Some(vec![2048, 2048, 2049, 2048, 2048]);
        assert_ne!(arm_digest(&so101, &other).unwrap(), digest);
        let slower = ServoSetup { baud: 500_000, ..shipped.clone() };
        assert_ne!(arm_digest(&so101, &slower).unwrap(), digest);
        let no_gripper = ServoSetup { gripper: None, ..shipped };
        assert_ne!(arm_digest(&so101, &no_gripper).unwrap(), digest);
    }
}
