//! The firmware's collision reports in words: the pair it stopped short of (or refused a target
//! for), named from the arm's [`CollisionSpec`], and whether goals are checked at all. The
//! firmware names parts by index; the host, which sent the geometry, knows their names.

use firmware::link::message::{CollisionCheck, CollisionPart, CollisionStop, NakReason, PathTaken, Status};
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

/// Why a move that ended at `end` failed, if the firmware's collision check stopped it: the arm
/// stopped short of the contact, named.
pub fn stopped(arm: &ArmSpec, end: &Status) -> Option<String> {
    if end.last_move.is_none_or(|m| m.path != PathTaken::CollisionStopped) {
        return None;
    }
    let pair = end.last_collision.as_ref().map_or_else(|| "a contact".to_string(), |s| stop(arm, s));
    Some(format!("the firmware stopped the arm short of a collision: {pair} where it was going"))
}

/// What `armctl status` says of the check: on (and what against), off, or nothing to check; and
/// the last stop.
pub fn status_line(arm: &ArmSpec, s: &Status) -> String {
    let check = match s.collision_check {
        CollisionCheck::NoGeometry => "not checked: the arm has no collision geometry".to_string(),
        CollisionCheck::On { bodies, obstacles } => {
            format!("checked: {bodies} bodies, {obstacles} obstacles")
        }
        CollisionCheck::Off => "CHECK OFF (--no-collision-check): goals are not checked".to_string(),
    };
    match &s.last_collision {
        Some(last) => format!("{check}; last stop (#{}): {}", last.count, stop(arm, last)),
        None => check,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stop_is_named_from_the_arms_geometry_or_by_index_without_it() {
        let mut arm = ArmSpec::load("so101", None).unwrap();
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
