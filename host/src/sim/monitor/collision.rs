//! The monitor's collision rule: every goal configuration the servos were told to go to (each
//! joint's goal, mapped to its angle as the firmware maps it) is placed in the arm's geometry
//! ([`crate::sim::World`]), and one whose checked pairs come closer than the margin is recorded
//! with the two bodies and their distance. It judges the goals the servos received, not what the
//! firmware says of them: a test asserts "no goal within the margin" from this record.
//!
//! A configuration is judged whenever a joint's goal arrives (one sync write of all joints is one
//! configuration), with every joint's goal as the servos then hold them; none is judged while a
//! joint's servo is limp or missing, or holds a goal the line corrupted.

use crate::sim::World;

use super::MAX_VIOLATIONS;

/// A goal configuration whose bodies came closer than the margin.
#[derive(Clone, Debug, PartialEq)]
pub struct GoalContact {
    /// When, s (as the monitor's violations).
    pub time: f64,
    /// The two parts: a body of the arm, and another body or an obstacle.
    pub bodies: [String; 2],
    /// Their signed distance (m; negative: they overlap).
    pub distance: f64,
    /// The goal, as joint angles (rad), base first.
    pub goal: Vec<f64>,
    /// "gripper and table are 3.2 mm apart (margin 10 mm)".
    pub what: String,
}

impl std::fmt::Display for GoalContact {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "goal at {:.3} s: {}", self.time, self.what)
    }
}

/// What the rule found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ContactRecord {
    /// The margin judged against (m).
    pub margin: f64,
    /// Goal configurations judged.
    pub checked: u64,
    /// Those within the margin (also those beyond the first [`MAX_VIOLATIONS`]).
    pub count: u64,
    /// The first [`MAX_VIOLATIONS`] of them, in order.
    pub contacts: Vec<GoalContact>,
    /// The closest any judged goal brought two checked parts.
    pub closest: Option<GoalContact>,
}

impl ContactRecord {
    /// One line: `0 of 412 goals within the 10 mm margin (closest 23.1 mm: gripper and table)`.
    pub fn summary(&self) -> String {
        let mut line =
            format!("{} of {} goals within the {:.0} mm margin", self.count, self.checked, self.margin * 1e3);
        if let Some(c) = &self.closest {
            line.push_str(&format!(" (closest {:.1} mm: {} and {})", c.distance * 1e3, c.bodies[0], c.bodies[1]));
        }
        line
    }

    /// As JSON, for the reports that carry the monitor's findings.
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "goals_checked": self.checked,
            "within_margin": self.count,
            "margin_m": self.margin,
            "closest_m": self.closest.as_ref().map(|c| c.distance),
            "closest_pair": self.closest.as_ref().map(|c| c.bodies.clone()),
            "first": self.contacts.iter().take(10).map(|c| serde_json::json!({
                "time_s": c.time, "bodies": c.bodies, "distance_m": c.distance, "goal_rad": c.goal,
            })).collect::<Vec<_>>(),
        })
    }
}

/// Judges goal configurations in an arm's geometry.
#[derive(Clone, Debug)]
pub struct CollisionRule {
    world: World,
}

impl CollisionRule {
    /// The rule for the arm and geometry of `world`, at its margin.
    pub fn new(world: World) -> Self {
        Self { world }
    }

    /// An empty record at the rule's margin, for [`CollisionRule::judge`] to fill.
    pub fn record(&self) -> ContactRecord {
        ContactRecord { margin: self.world.geometry().margin, ..ContactRecord::default() }
    }

    /// The joints' servo ids, base first: whose goals make a configuration.
    pub fn ids(&self) -> Vec<u8> {
        self.world.ids()
    }

    /// Judges the configuration of `goals` (each joint's goal, ticks, base first) received at
    /// `time` (s), into `record`.
    pub fn judge(&mut self, record: &mut ContactRecord, time: f64, goals: &[i64]) {
        let q: Vec<f64> = goals.iter().enumerate().map(|(j, &g)| self.world.angle(j, g as f64)).collect();
        let Some(closest) = self.world.closest(&q) else { return };
        record.checked += 1;
        let found = |world: &World, contact| GoalContact {
            time,
            bodies: world.names(&contact),
            distance: contact.distance,
            goal: q.clone(),
            what: world.describe(&contact),
        };
        if record.closest.as_ref().is_none_or(|c| closest.distance < c.distance) {
            record.closest = Some(found(&self.world, closest));
        }
        // The firmware's own test (the first pair within the margin), so that what the rule names
        // is what a firmware's check would have named.
        if let Some(contact) = self.world.within_margin(&q) {
            record.count += 1;
            if record.contacts.len() < MAX_VIOLATIONS {
                record.contacts.push(found(&self.world, contact));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::arm::collision::CollisionSpec;
    use crate::arm::ArmSpec;

    fn rule() -> CollisionRule {
        let arm = ArmSpec::load("so101", None).unwrap();
        CollisionRule::new(World::new(&arm, CollisionSpec::from_frames(&arm, 0.02)).unwrap())
    }

    #[test]
    fn a_goal_below_the_table_is_recorded_with_its_bodies_and_a_free_one_is_not() {
        let mut rule = rule();
        let mut r = rule.record();
        rule.judge(&mut r, 0.5, &[2048; 5]);
        assert_eq!((r.checked, r.count), (1, 0));
        let free = r.closest.clone().unwrap();
        assert!(free.distance > 0.01, "{free}");
        // Shoulder lift 1.6 rad forward (2048 + 1.6 · 4096 / 2π).
        let low = [2048, 3091, 2048, 2048, 2048];
        rule.judge(&mut r, 1.0, &low);
        assert_eq!((r.checked, r.count), (2, 1));
        let c = &r.contacts[0];
        assert_eq!(c.bodies[1], "table", "{c}");
        assert!(c.distance < 0.01, "{c}");
        assert_eq!(c.time, 1.0);
        assert!((c.goal[1] - 1043.0 * std::f64::consts::TAU / 4096.0).abs() < 1e-12);
        assert!(c.to_string().starts_with("goal at 1.000 s: "), "{c}");
        assert!(r.closest.as_ref().unwrap().distance <= c.distance);
        assert!(r.summary().starts_with("1 of 2 goals within the 10 mm margin (closest "), "{}", r.summary());
        assert_eq!(r.json()["within_margin"], 1);
    }
}
