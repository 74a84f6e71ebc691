//! What the drive operations say of the firmware's collision check: a move it stopped short of
//! a contact fails naming the pair ([`crate::link::collision`] names it), and `status` says
//! whether goals are checked at all.

use firmware::link::message::{CollisionCheck, PathTaken, Status};

use crate::arm::ArmSpec;
pub use crate::link::collision::{refusal, stop};

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
