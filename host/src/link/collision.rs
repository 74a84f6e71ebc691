//! The firmware's collision reports in words: the pair it stopped short of (or refused a target
//! for), named from the arm's [`CollisionSpec`]. The firmware names parts by index; the host,
//! which sent the geometry ([`super::arm_config`]), knows their names.

use firmware::link::message::{CollisionPart, CollisionStop, NakReason};
use kinematics::collision::{Contact, Part};

use crate::arm::collision::{collision_of, CollisionSpec};
use crate::arm::ArmSpec;

/// The contact the firmware reported, as the kinematics crate has it.
pub fn contact(body: u8, other: CollisionPart, distance: f32) -> Contact<f32> {
    let other = match other {
        CollisionPart::Body(i) => Part::Body(i),
        CollisionPart::Obstacle(o) => Part::Obstacle(o),
    };
    Contact { body, other, distance }
}

/// "gripper and table are 3.2 mm apart (margin 10 mm)", the parts named from `spec`; by index
/// where the host has no geometry for the arm (a board configured by another host).
pub fn describe(spec: Option<&CollisionSpec>, contact: &Contact<f32>) -> String {
    match spec {
        Some(spec) => spec.describe(contact),
        None => {
            let other = match contact.other {
                Part::Body(i) => format!("body {i}"),
                Part::Obstacle(o) => format!("obstacle {o}"),
            };
            format!("body {} and {other} are {:.1} mm apart", contact.body, f64::from(contact.distance) * 1e3)
        }
    }
}

/// A collision stop of `arm` in words.
pub fn stop(arm: &ArmSpec, stop: &CollisionStop) -> String {
    describe(collision_of(arm).as_ref(), &contact(stop.body, stop.other, stop.distance))
}

/// The firmware's refusal of a target in contact, in words; `None` for any other nak.
pub fn refusal(arm: &ArmSpec, reason: &NakReason) -> Option<String> {
    let NakReason::Collision { body, other, distance } = *reason else { return None };
    let pair = describe(collision_of(arm).as_ref(), &contact(body, other, distance));
    Some(format!("the firmware's collision check refused the target: {pair} there"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stop_is_named_from_the_arms_geometry_or_by_index_without_it() {
        let mut arm = ArmSpec { collision: None, ..ArmSpec::load("so101", None).unwrap() };
        let spec = CollisionSpec::from_frames(&arm, 0.02);
        let last = CollisionStop { body: 5, other: CollisionPart::Obstacle(0), distance: 0.0032, count: 2 };
        assert_eq!(stop(&arm, &last), "body 5 and obstacle 0 are 3.2 mm apart");
        arm.collision = Some(spec.clone());
        let named = format!("{} and table are 3.2 mm apart (margin 10 mm)", spec.bodies[5].name);
        assert_eq!(stop(&arm, &last), named);
        let nak = NakReason::Collision { body: 5, other: CollisionPart::Obstacle(0), distance: 0.0032 };
        assert!(refusal(&arm, &nak).unwrap().ends_with(&format!("{named} there")));
        assert_eq!(refusal(&arm, &NakReason::Unreachable), None);
    }
}
