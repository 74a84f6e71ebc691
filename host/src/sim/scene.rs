//! An object on the table for a simulated gripper to pick up: it lies at a point in space, comes
//! between the jaws only when the tool is there with the jaws open wider than it, rides with the
//! tool while the jaws grip it, and stays where it was let go.
//!
//! The jaws themselves are the gripper servo's ([`Jaw`]): they stop on the object and the servo's
//! load rises. This module only decides where the object is and when it is between them, from
//! the tool position that forward kinematics gives for the measured joint values. So a demo that
//! closes the gripper away from the object grasps nothing, and the object ends where the arm
//! really carried it. No gravity, no friction, no slip: a held object never falls.
//!
//! Several grippers can share one object ([`Scene::for_gripper`]): each has a scene of its own,
//! for its own jaws, over the same position, so one arm can hand the object to another.

use std::cell::Cell;
use std::rc::Rc;

use anyhow::{bail, Result};

use super::port::SharedBus;
use super::servo::Jaw;
use crate::arm::servos::GripperSpec;

/// How close the tool point must come to the object's centre for the object to slide between
/// the open jaws (m): half a typical jaw's depth, and well above the tool's tracking error.
pub const REACH_M: f64 = 0.01;

/// An object of a given width at a point, and whether the jaws hold it.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    gripper: GripperSpec,
    jaw: Jaw,
    /// The object's width (mm).
    width_mm: f64,
    /// Where the object's centre is (m), shared with the scenes of other grippers.
    position: Rc<Cell<[f64; 3]>>,
    /// Whether it is between the jaws (the gripper servo's [`Jaw`] is set).
    between: bool,
    /// Its offset from the tool point while the jaws grip it (m): it moves with the tool.
    grip: Option<[f64; 3]>,
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt()
}

impl Scene {
    /// An object `width_mm` wide at `position` (m), for the jaws of `gripper`; refused unless it
    /// fits between the open jaws and the position is finite.
    pub fn new(gripper: &GripperSpec, width_mm: f64, position: [f64; 3]) -> Result<Self> {
        if position.iter().any(|x| !x.is_finite()) {
            bail!("the object's position {position:?} is not a finite point");
        }
        let jaw = Jaw::for_object(gripper, width_mm)?;
        Ok(Self {
            gripper: *gripper,
            jaw,
            width_mm,
            position: Rc::new(Cell::new(position)),
            between: false,
            grip: None,
        })
    }

    /// The same object, for the jaws of another gripper (of another arm, in the same world frame):
    /// where either carries it, the other finds it. Refused unless it fits between those jaws.
    pub fn for_gripper(&self, gripper: &GripperSpec) -> Result<Self> {
        let jaw = Jaw::for_object(gripper, self.width_mm)?;
        Ok(Self { gripper: *gripper, jaw, position: Rc::clone(&self.position), between: false, grip: None, ..*self })
    }

    /// Where the object is (m).
    pub fn position(&self) -> [f64; 3] {
        self.position.get()
    }

    /// Whether the jaws hold it now.
    pub fn held(&self) -> bool {
        self.grip.is_some()
    }

    /// Whether the object is between the jaws (held or not).
    pub fn between_jaws(&self) -> bool {
        self.between
    }

    /// Brings the object up to a control tick at `t_ns`, with the tool at `tool` (m): it slides
    /// between jaws that come to it open wider than it, rides with them from the moment they
    /// touch it until they let go, and is left behind when they move away without touching it.
    pub fn update(&mut self, bus: &SharedBus, tool: [f64; 3], t_ns: u64) {
        let mut bus = bus.borrow_mut();
        let Some(servo) = bus.servo_mut(self.gripper.id) else { return };
        servo.update(t_ns);
        let present = servo.get(servo.model().items.present_position) as f64;
        let near = distance(tool, self.position.get()) <= REACH_M;
        if !self.between {
            // The jaws must be open past the contact (not touching) to take the object in.
            if near && !self.jaw.reached(present) {
                self.between = true;
                servo.set_jaw(Some(self.jaw), t_ns);
            }
            return;
        }
        if !self.jaw.reached(present) {
            // Not touching: it rests where it is, and stays behind when the jaws move off.
            self.grip = None;
            if !near {
                self.between = false;
                servo.set_jaw(None, t_ns);
            }
            return;
        }
        let position = self.position.get();
        let offset = *self.grip.get_or_insert([0, 1, 2].map(|i| position[i] - tool[i]));
        self.position.set([0, 1, 2].map(|i| tool[i] + offset[i]));
    }
}
