//! The servos that drive an arm's joints: their model, bus ids, zero offsets, directions and speed
//! limits, from the arm file's `[servos]` table or the presets' as shipped.

use firmware::bus::table::{Model, STS3215, XM430_W350};

use super::ArmSpec;

/// The servos of an arm.
#[derive(Clone, Debug, PartialEq)]
pub struct ServoSetup {
    /// Their model (all joints alike).
    pub model: &'static Model,
    /// Bus ids, base joint first.
    pub ids: Vec<u8>,
    /// Ticks at joint value zero, per joint (`None`: half a turn, the servo's middle).
    pub zero: Option<Vec<i32>>,
    /// Servos turning against their joint's axis, per joint (`None`: none).
    pub reversed: Option<Vec<bool>>,
    /// Joint speed limit, rad/s.
    pub max_velocity: f64,
    /// Joint acceleration limit, rad/s².
    pub max_acceleration: f64,
}

impl ServoSetup {
    /// The servos of a preset arm as shipped: SO-101 with STS3215 ids 1 to 5, OpenManipulator-X
    /// with XM430-W350 ids 11 to 14 (ROBOTIS's numbering). Both at 2 rad/s and 8 rad/s², well
    /// inside what the servos do under load.
    pub fn for_arm(name: &str) -> Option<Self> {
        let (model, ids): (&'static Model, Vec<u8>) = match name {
            "so101" => (&STS3215, (1..=5).collect()),
            "open-manipulator-x" => (&XM430_W350, (11..=14).collect()),
            _ => return None,
        };
        Some(Self { model, ids, zero: None, reversed: None, max_velocity: 2.0, max_acceleration: 8.0 })
    }
}

/// The servos of `arm`: those its arm file names, else those of the preset of its name.
pub fn servos_of(arm: &ArmSpec) -> Option<ServoSetup> {
    arm.servos.clone().or_else(|| ServoSetup::for_arm(&arm.name))
}
