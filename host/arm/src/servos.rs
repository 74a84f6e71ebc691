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
    /// The gripper, an actuator outside the kinematic chain on the same bus (`None`: no gripper).
    pub gripper: Option<GripperSpec>,
    /// The LeRobot calibration of the gripper's servo, where the calibration has one: its range
    /// is in `gripper`; the whole entry is kept so that connecting checks the servo holds it, as
    /// it checks the joints' (LeRobot's `is_calibrated` compares every motor).
    pub gripper_calibration: Option<MotorCalibration>,
    /// The bus's baud rate (the arm file's `baud`, by default [`DEFAULT_BAUD`]): a board switches
    /// its servo bus to it when the arm is sent.
    pub baud: u32,
}

/// The servo bus's baud rate when the arm file names none: 1 Mbps, what LeRobot uses for its
/// Feetech and Dynamixel arms alike, and the OpenManipulator-X's as ROBOTIS ships it.
pub const DEFAULT_BAUD: u32 = 1_000_000;

/// A gripper: one servo of the arm's model, driven between two tick positions.
///
/// Opening is given in percent, 0 closed to 100 open, as LeRobot's `RANGE_0_100` gripper
/// normalisation: `ticks = closed + pct / 100 * (open - closed)`. A LeRobot calibration gives
/// `closed = range_min`, `open = range_max` (swapped with `drive_mode` 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GripperSpec {
    /// Bus id.
    pub id: u8,
    /// Ticks with the jaws closed (0 %).
    pub closed: i32,
    /// Ticks with the jaws open (100 %).
    pub open: i32,
    /// The effort used unless a command names another, percent of the servo's maximum torque
    /// (STS3215 `Torque_Limit`) or current (Dynamixel `Current_Limit`), 1..=100.
    pub effort: f64,
    /// The distance between the jaws when open, mm (the simulator's jaws, the demo's table): the
    /// opening is taken as linear in ticks, 0 mm closed.
    pub opening_mm: f64,
    /// How fast the firmware moves the gripper's goal, percent of the stroke per second.
    pub speed: f64,
}

/// The grippers' default speed, percent of the stroke per second: a full close or open in a
/// second, well inside what the servos do (the SO-101's 110° stroke at the STS3215's 270°/s
/// no-load speed takes 0.4 s).
pub const GRIPPER_SPEED: f64 = 100.0;

impl GripperSpec {
    /// The SO-101's gripper: servo 6 (STS3215), as the firmware's built-in arm has it
    /// ([`firmware::builtin::GRIPPER`]: the URDF's gripper joint limits on a factory-fresh servo,
    /// effort 50 %). The opening is the simulator's round figure, not a measurement of the printed
    /// jaws.
    pub const SO101: Self = Self {
        id: firmware::builtin::GRIPPER.id,
        closed: firmware::builtin::GRIPPER.closed,
        open: firmware::builtin::GRIPPER.open,
        effort: firmware::builtin::GRIPPER.effort as f64,
        opening_mm: 90.0,
        speed: firmware::builtin::GRIPPER.speed as f64,
    };
    /// The OpenManipulator-X's gripper: servo 15 (XM430-W350) in current-based position mode. The
    /// nominal ticks are a guess to be calibrated: the servo's middle closed, a quarter turn open.
    /// The opening is ROBOTIS's published stroke (20 to 75 mm), taken as 0 to 75 mm.
    pub const OPEN_MANIPULATOR_X: Self =
        Self { id: 15, closed: 2048, open: 3072, effort: 50.0, opening_mm: 75.0, speed: GRIPPER_SPEED };

    /// The ticks of an opening of `pct` percent (0 closed, 100 open), truncated toward zero as
    /// LeRobot's `_unnormalize` does; `pct` is clamped to 0..=100.
    pub fn ticks(&self, pct: f64) -> i32 {
        let pct = if pct.is_nan() { 0.0 } else { pct.clamp(0.0, 100.0) };
        (f64::from(self.closed) + pct / 100.0 * f64::from(self.open - self.closed)) as i32
    }

    /// The opening of `ticks`, percent (not clamped: a jaw pushed past its range reads beyond).
    pub fn percent(&self, ticks: i32) -> f64 {
        f64::from(ticks - self.closed) / f64::from(self.open - self.closed) * 100.0
    }

    /// Takes a LeRobot calibration of the gripper servo: its range, closed at `range_min` unless
    /// `drive_mode` is 1.
    pub fn calibrated(&self, c: &MotorCalibration) -> Self {
        let (closed, open) = if c.drive_mode == 1 { (c.range_max, c.range_min) } else { (c.range_min, c.range_max) };
        Self { closed, open, ..*self }
    }
}

impl ServoSetup {
    /// The servos of a preset arm as shipped: SO-101 with STS3215 ids 1 to 5, OpenManipulator-X
    /// with XM430-W350 ids 11 to 14 (ROBOTIS's numbering), each with its gripper ([`GripperSpec`]). Both at 2 rad/s and 8 rad/s², well
    /// inside what the servos do under load.
    pub fn for_arm(name: &str) -> Option<Self> {
        let (model, ids, gripper): (&'static Model, Vec<u8>, _) = match name {
            "so101" => (&STS3215, (1..=5).collect(), GripperSpec::SO101),
            "open-manipulator-x" => (&XM430_W350, (11..=14).collect(), GripperSpec::OPEN_MANIPULATOR_X),
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
            gripper: Some(gripper),
            gripper_calibration: None,
            baud: DEFAULT_BAUD,
        })
    }

    /// Every servo on the bus, the joints' (base first) then the gripper's.
    pub fn bus_ids(&self) -> Vec<u8> {
        self.ids.iter().copied().chain(self.gripper.map(|g| g.id)).collect()
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

    /// The range joint `j` of `arm` is commanded within, as the firmware holds it (`f32`): the
    /// joint's limits intersected with what its servo's ticks reach, half a tick inside so that
    /// rounding to ticks never lands outside ([`firmware::controller::config::joint_limits`]).
    /// `None` when `j` is beyond the servos or nothing of the range is left.
    pub fn commanded_range(&self, arm: &ArmSpec, j: usize) -> Option<(f32, f32)> {
        let joint = arm.joints.get(j)?;
        let mapping = self.mapping(j)?;
        let (lo, hi) = mapping.joint_range::<f32>();
        let half_tick = std::f32::consts::PI / mapping.ticks_per_revolution.max(1) as f32;
        let lower = (joint.lower as f32).max(lo + half_tick);
        let upper = (joint.upper as f32).min(hi - half_tick);
        (lower <= upper).then_some((lower, upper))
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
        // The gripper's entry is optional: LeRobot's files have one, a calibration of the chain
        // alone (or an older file) leaves the gripper's nominal range.
        if let Some(g) = self.gripper.as_mut() {
            if let Some((_, m)) = calibration.by_id(g.id) {
                *g = g.calibrated(m);
                self.gripper_calibration = Some(*m);
            }
        }
        Ok(())
    }
}

/// The servos of `arm`: those its arm file names, else those of the preset of its name.
pub fn servos_of(arm: &ArmSpec) -> Option<ServoSetup> {
    arm.servos.clone().or_else(|| ServoSetup::for_arm(&arm.name))
}
