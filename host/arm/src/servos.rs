//! The servos that drive an arm's joints: their model, bus ids, zero offsets, directions and speed
//! limits, from the arm file's `[servos]` table or the presets' as shipped.

use firmware::bus::mapping::{Direction, JointMapping};
use firmware::bus::table::{Model, STS3215, XM430_W350};

use super::calibration::MotorCalibration;
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
    /// A LeRobot calibration of each joint's servo, in joint order (`None`: the nominal mapping of
    /// `zero` and `reversed`, which fits factory-fresh servos).
    pub calibration: Option<Vec<MotorCalibration>>,
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
        Some(Self {
            model,
            ids,
            zero: None,
            reversed: None,
            max_velocity: 2.0,
            max_acceleration: 8.0,
            calibration: None,
        })
    }

    /// How joint `j`'s angle maps to its servo's ticks: LeRobot's degree mode over the calibrated
    /// range when there is a calibration ([`JointMapping::lerobot`]), else the nominal mapping
    /// (`zero`, by default the servo's middle; `reversed`; the whole single-turn range). `None` when
    /// `j` is beyond the servos.
    pub fn mapping(&self, j: usize) -> Option<JointMapping> {
        let id = *self.ids.get(j)?;
        let tpr = self.model.ticks_per_revolution;
        if let Some(c) = self.calibration.as_ref().and_then(|c| c.get(j)) {
            return Some(JointMapping::lerobot(id, tpr, c.range_min, c.range_max));
        }
        Some(JointMapping {
            zero: self.zero.as_ref().and_then(|z| z.get(j).copied()).unwrap_or((tpr / 2) as i32),
            direction: if self.reversed.as_ref().is_some_and(|r| r.get(j) == Some(&true)) {
                Direction::Reverse
            } else {
                Direction::Forward
            },
            ..JointMapping::centred(id, tpr)
        })
    }

    /// Takes a LeRobot calibration: each servo's entry found by its id. Fails, naming the servo,
    /// when one has none.
    pub fn calibrate(&mut self, calibration: &super::calibration::Calibration) -> anyhow::Result<()> {
        let entries =
            self.ids
                .iter()
                .map(|&id| {
                    calibration.by_id(id).map(|(_, m)| *m).ok_or_else(|| {
                        anyhow::anyhow!("the calibration has no motor with id {id}, a servo of this arm")
                    })
                })
                .collect::<anyhow::Result<Vec<_>>>()?;
        self.calibration = Some(entries);
        Ok(())
    }
}

/// The servos of `arm`: those its arm file names, else those of the preset of its name.
pub fn servos_of(arm: &ArmSpec) -> Option<ServoSetup> {
    arm.servos.clone().or_else(|| ServoSetup::for_arm(&arm.name))
}
