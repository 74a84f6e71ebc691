//! Contact: a simulated link that runs into the table, an obstacle or another link of the arm
//! stops there, its servos stalled against it ([`super::stall`]).
//!
//! The bus moves its servos forward in time ([`super::SimBus::advance_to`]); with a
//! [`ContactModel`] it first looks along their motion, in steps of at most [`STEP_NS`], for the
//! first instant two bodies of the arm's geometry ([`super::World`]) overlap (signed distance
//! below zero; the margin is the firmware's business, not physics). It finds that instant by
//! bisection to [`RESOLUTION_NS`], and stops there each servo whose own motion at that instant
//! brings the two bodies closer: its horn cannot go further that way, its present position stays
//! at the contact while its goal lies beyond, its load rises. The others move on, and may in turn
//! be stopped within the same step. A servo whose motion alone does not close the gap (two joints
//! that only together bring the bodies together) is not singled out: then every moving servo stops.
//!
//! A stalled servo keeps pushing toward its goal: whenever another joint moves, its stop is
//! lifted at each step and found again if the contact is still there, so it moves on once another
//! joint has taken the link away; and it moves back as soon as its goal lies on the free side.
//!
//! A pair that already overlaps where a step starts (horns placed by hand into the table, or
//! geometry that overlaps at rest) may stay so, but no servo may make that overlap deeper; every
//! other pair is judged as usual.
//! Limp servos (torque off) are never stopped: a hand moves them where it will.

use kinematics::collision::Contact;

use super::servo::SimServo;
use super::stall::Stop;
use super::world::World;

/// The longest stretch of motion judged at once (ns): a link at the servos' top speed moves a few
/// millimetres in it, less than the thinnest body the presets declare.
pub const STEP_NS: u64 = 1_000_000;

/// How closely the instant of contact is found (ns).
pub const RESOLUTION_NS: u64 = 1_000;

/// What the contact model has seen.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ContactStats {
    /// Times a moving servo was stopped by a contact (not counting a stalled servo found still
    /// stalled at the next advance).
    pub stalls: u64,
    /// The last contact that stopped a servo: "wrist_flex and table overlap by 0.0 mm ..." and the
    /// servo ids it stopped.
    pub last: Option<(String, Vec<u8>)>,
}

/// The arm's geometry on a bus: stops its servos at contacts.
#[derive(Clone, Debug)]
pub struct ContactModel {
    world: World,
    stats: ContactStats,
}

impl ContactModel {
    /// Contact among the bodies and obstacles of `world`.
    pub fn new(world: World) -> Self {
        Self { world, stats: ContactStats::default() }
    }

    /// The geometry.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// What it has seen.
    pub fn stats(&self) -> &ContactStats {
        &self.stats
    }

    /// Moves `servos` (brought up to `from_ns`) on to `to_ns`, stopping those that run into
    /// something; the caller then brings every servo up to `to_ns`.
    pub fn advance(&mut self, servos: &mut [SimServo], from_ns: u64, to_ns: u64) {
        if to_ns <= from_ns {
            return;
        }
        let ids = self.world.ids();
        let found: Option<Vec<usize>> = ids.iter().map(|&id| servos.iter().position(|s| s.id() == id)).collect();
        // An arm with a joint's servo missing from the bus cannot be placed: nothing to model.
        let Some(index) = found else { return };
        // Stalls already counted: those found at the last advance, and those found in this one.
        let mut counted: Vec<bool> = index.iter().map(|&i| servos[i].stop().is_some()).collect();
        let mut start = from_ns;
        while start < to_ns {
            let end = to_ns.min(start.saturating_add(STEP_NS));
            // Only a servo under torque is judged: a limp one goes where the hand takes it.
            let free_moving = |servos: &[SimServo]| {
                index.iter().any(|&i| servos[i].torque() && servos[i].stop().is_none() && servos[i].in_motion(start))
            };
            // A stalled servo pushes on whenever another joint moves (it may clear the way), and
            // leaves its stop behind when its goal lies on the free side. Otherwise nothing has
            // changed for it: the push would find the same contact.
            let moving = free_moving(servos);
            for &i in &index {
                if moving || !servos[i].pushing() {
                    servos[i].release(start);
                }
            }
            if !free_moving(servos) {
                // Nothing moves from here to the end of the advance.
                break;
            }
            let Some(distances) = self.world.pair_distances(&self.angles(servos, &index, start)) else { return };
            match self.clear_until(servos, &index, &distances, start, to_ns) {
                Some(clear) => start = clear,
                None => {
                    self.step(servos, &index, &mut counted, distances, start, end);
                    start = end;
                }
            }
        }
    }

    /// How far past `start` the motion is shown clear without looking along it (`None`: not even
    /// a step): while no point of any body can move half a pair's clearance (`distances`, at
    /// `start`; [`World::motion_bound`] of each servo's travel), no pair can touch. The stretch
    /// is halved from the whole advance down to a step. Far from everything, this is what makes
    /// the simulator keep up in real time: a step looked along costs two placements of every
    /// body, and a debug build cannot make a thousand of those a second.
    fn clear_until(
        &self,
        servos: &[SimServo],
        index: &[usize],
        distances: &[f64],
        start: u64,
        to_ns: u64,
    ) -> Option<u64> {
        // A pair placed overlapping may move but not deeper: no room at all.
        let clearance = distances.iter().map(|d| d.max(0.0)).fold(f64::INFINITY, f64::min);
        let mut span = to_ns - start;
        loop {
            let travel: Vec<f64> = index.iter().map(|&i| servos[i].travel_bound(start, start + span)).collect();
            if 2.0 * self.world.motion_bound(&travel) < clearance {
                return Some(start + span);
            }
            if span <= STEP_NS {
                return None;
            }
            span /= 2;
        }
    }

    /// The joint angles at `t_ns`, each servo's stop included.
    fn angles(&self, servos: &[SimServo], index: &[usize], t_ns: u64) -> Vec<f64> {
        index
            .iter()
            .enumerate()
            .map(|(j, &i)| self.world.angle(j, servos[i].reported(servos[i].horn_at(t_ns))))
            .collect()
    }

    /// The first checked pair (its index in [`World::pairs`]) that overlaps at `t_ns` deeper than
    /// `floor` allows, and the distances there.
    fn worse(&self, servos: &[SimServo], index: &[usize], floor: &[f64], t_ns: u64) -> Option<(usize, Vec<f64>)> {
        let d = self.world.pair_distances(&self.angles(servos, index, t_ns))?;
        let k = d.iter().zip(floor).position(|(d, f)| d < f)?;
        Some((k, d))
    }

    /// Judges the motion from `a_ns` to `b_ns`: no checked pair may overlap, or overlap deeper
    /// than it did at `a_ns` (a configuration placed overlapping may move, but not deeper in).
    /// `distances` are the pairs' at `a_ns`.
    fn step(
        &mut self,
        servos: &mut [SimServo],
        index: &[usize],
        counted: &mut [bool],
        distances: Vec<f64>,
        a_ns: u64,
        b_ns: u64,
    ) {
        let (mut a_ns, mut at_a) = (a_ns, Some(distances));
        // Each round stops at least one servo, or ends.
        for _ in 0..=index.len() {
            let start = match at_a.take() {
                Some(d) => d,
                None => match self.world.pair_distances(&self.angles(servos, index, a_ns)) {
                    Some(d) => d,
                    None => return,
                },
            };
            // A hair below the start's own overlap: rounding is no deeper contact.
            let floor: Vec<f64> = start.iter().map(|d| d.min(0.0) - 1e-9).collect();
            let Some(mut found) = self.worse(servos, index, &floor, b_ns) else { return };
            // The first instant of contact, by bisection.
            let (mut lo, mut hi) = (a_ns, b_ns);
            while hi - lo > RESOLUTION_NS {
                let mid = lo + (hi - lo) / 2;
                match self.worse(servos, index, &floor, mid) {
                    Some(at_mid) => (hi, found) = (mid, at_mid),
                    None => lo = mid,
                }
            }
            let (k, distances) = found;
            let (body, other) = self.world.pairs()[k];
            let (q_lo, q_hi) = (self.angles(servos, index, lo), self.angles(servos, index, hi));
            let gap = self.world.distance(&q_lo, body, other);
            let moving: Vec<usize> =
                (0..index.len()).filter(|&j| servos[index[j]].torque() && q_hi[j] != q_lo[j]).collect();
            let mut closing: Vec<usize> = moving
                .iter()
                .copied()
                .filter(|&j| {
                    let mut q = q_lo.clone();
                    q[j] = q_hi[j];
                    self.world.distance(&q, body, other) < gap
                })
                .collect();
            if closing.is_empty() {
                closing = moving;
            }
            if closing.is_empty() {
                // Nothing under torque moves: a hand's doing.
                return;
            }
            let mut stopped = Vec::new();
            for &j in &closing {
                let servo = &mut servos[index[j]];
                let at = servo.horn_at(lo);
                let toward = (servo.horn_at(hi) - at).signum();
                servo.set_stop(Some(Stop { at, toward }));
                if !counted[j] {
                    counted[j] = true;
                    stopped.push(servo.id());
                }
            }
            if !stopped.is_empty() {
                self.stats.stalls += stopped.len() as u64;
                let contact = Contact { body, other, distance: distances[k] };
                self.stats.last = Some((self.world.describe(&contact), stopped));
            }
            a_ns = lo;
        }
    }
}

#[cfg(test)]
mod tests {
    use firmware::bus::table::sts3215;

    use super::*;
    use crate::arm::collision::CollisionSpec;
    use crate::arm::ArmSpec;
    use crate::sim::SimBus;

    const S: u64 = 1_000_000_000;
    const ELBOW: f64 = -1.2;

    /// The SO-101's servos with its joints' geometry measured from its frames, torque on.
    fn so101() -> (SimBus, World) {
        let arm = ArmSpec::load("so101", None).unwrap();
        let world = World::new(&arm, CollisionSpec::from_frames(&arm, 0.02)).unwrap();
        let servos = crate::arm::servos::servos_of(&arm).unwrap();
        let mut bus = SimBus::new(servos.model.protocol, servos.model, &servos.bus_ids(), 1_000_000);
        for s in bus.servos_mut() {
            s.set_register(sts3215::TORQUE_ENABLE, 1, 0).unwrap();
        }
        bus.set_contact(Some(ContactModel::new(world.clone())));
        (bus, world)
    }

    fn angles(bus: &SimBus, world: &World) -> Vec<f64> {
        let t = bus.now_ns();
        world
            .ids()
            .iter()
            .enumerate()
            .map(|(j, &id)| {
                let s = bus.servo(id).unwrap();
                world.angle(j, s.reported(s.horn_at(t)))
            })
            .collect()
    }

    /// Shoulder lift forward and the elbow folded down: the wrist is driven through the table.
    /// It stops on it: no body overlaps the table by more than what a step's last microsecond
    /// moves, the servos that drove it hold short of their goals and push at full load, and after
    /// the protection time the overload bit is set and the torque goes off.
    #[test]
    fn a_link_driven_into_the_table_stops_on_it_and_its_servo_overloads() {
        let (mut bus, mut world) = so101();
        let goal = world_goal(&world, 1, 1.6);
        bus.servo_mut(2).unwrap().set_register(sts3215::GOAL_POSITION, goal, 0).unwrap();
        let mut deepest: f64 = f64::INFINITY;
        for k in 1..=100 {
            bus.advance_to(k * 10_000_000);
            let q = angles(&bus, &world);
            let closest = world.closest(&q).unwrap();
            deepest = deepest.min(closest.distance);
        }
        assert!(deepest > -1e-4, "overlapped by {} m", -deepest);
        assert!(deepest < 1e-3, "stopped short of the table: {deepest} m");
        let s = bus.servo(2).unwrap();
        let present = s.get(sts3215::PRESENT_POSITION);
        assert!(goal - present > 100, "present {present}, goal {goal}: it should stall well short");
        assert_eq!(s.get(sts3215::PRESENT_LOAD), 1000, "pushing at full effort");
        assert_eq!(s.get(sts3215::MOVING), 0);
        assert_eq!(s.status_error(0), 0, "not yet overloaded after 1 s");
        let stats = bus.contact().unwrap().stats().clone();
        assert_eq!(stats.last.as_ref().unwrap().1, [2], "{stats:?}");
        assert!(stats.last.unwrap().0.contains("table"));
        bus.advance_to(3 * S + 100_000_000);
        let s = bus.servo(2).unwrap();
        assert_eq!(s.status_error(0), OVERLOAD_BIT, "overload after 2 s of pushing at full load");
        assert!(!s.torque());
    }

    const OVERLOAD_BIT: u8 = crate::sim::stall::OVERLOAD;

    /// Joint `j`'s servo ticks for `angle`.
    fn world_goal(world: &World, j: usize, angle: f64) -> i64 {
        let arm = world.arm();
        let m = crate::arm::servos::servos_of(arm).unwrap().mapping(j).unwrap();
        i64::from(m.to_ticks(angle).unwrap())
    }

    /// A stalled servo whose goal comes back moves off the table at once, and its load drops.
    #[test]
    fn a_goal_back_on_the_free_side_moves_away() {
        let (mut bus, world) = so101();
        let goal = world_goal(&world, 1, 1.6);
        bus.servo_mut(2).unwrap().set_register(sts3215::GOAL_POSITION, goal, 0).unwrap();
        bus.advance_to(S);
        let stalled = bus.servo(2).unwrap().get(sts3215::PRESENT_POSITION);
        bus.servo_mut(2).unwrap().set_register(sts3215::GOAL_POSITION, 2048, S).unwrap();
        bus.advance_to(2 * S);
        let s = bus.servo(2).unwrap();
        assert_eq!(s.get(sts3215::PRESENT_POSITION), 2048, "back from {stalled}");
        assert_eq!(s.get(sts3215::PRESENT_LOAD), 0);
        assert_eq!(s.stop(), None);
    }

    /// Self-collision the same way: with no table, the elbow folded back (1.69 rad) brings its
    /// link onto the shoulder's; it stops there, the elbow's servo alone stalled.
    #[test]
    fn a_link_folded_onto_another_stops_on_it() {
        let arm = ArmSpec::load("so101", None).unwrap();
        let geometry = CollisionSpec::from_frames(&arm, 0.02).without(crate::arm::collision::TABLE);
        let mut world = World::new(&arm, geometry).unwrap();
        let (mut bus, _) = so101();
        bus.set_contact(Some(ContactModel::new(world.clone())));
        let goal = world_goal(&world, 2, 1.69);
        bus.servo_mut(3).unwrap().set_register(sts3215::GOAL_POSITION, goal, 0).unwrap();
        bus.advance_to(S);
        let closest = world.closest(&angles(&bus, &world)).unwrap();
        assert!(closest.distance > -1e-4 && closest.distance < 1e-3, "{}", world.describe(&closest));
        assert_eq!(world.names(&closest), ["shoulder_pan", "elbow_flex"]);
        let s = bus.servo(3).unwrap();
        assert!(goal - s.get(sts3215::PRESENT_POSITION) > 20, "{} short of {goal}", s.get(sts3215::PRESENT_POSITION));
        assert!(s.get(sts3215::PRESENT_LOAD) > 0);
        assert_eq!(bus.contact().unwrap().stats().last.as_ref().unwrap().1, [3]);
    }

    /// A stalled servo keeps pushing: once the elbow has lifted the forearm off the table, the
    /// shoulder moves on toward its goal.
    #[test]
    fn a_stalled_servo_moves_on_when_another_joint_clears_the_way() {
        let (mut bus, world) = so101();
        let goal = world_goal(&world, 1, 1.6);
        bus.servo_mut(2).unwrap().set_register(sts3215::GOAL_POSITION, goal, 0).unwrap();
        bus.advance_to(S);
        let stalled = bus.servo(2).unwrap().get(sts3215::PRESENT_POSITION);
        let up = world_goal(&world, 2, ELBOW);
        bus.servo_mut(3).unwrap().set_register(sts3215::GOAL_POSITION, up, S).unwrap();
        bus.advance_to(2 * S);
        let further = bus.servo(2).unwrap().get(sts3215::PRESENT_POSITION);
        assert!(further > stalled + 20, "the shoulder stayed at {further} (stalled at {stalled}, goal {goal})");
    }

    /// A Dynamixel arm (the OpenManipulator-X's XM430s) stops the same way; its overload is not
    /// modelled, so it pushes on without an error.
    #[test]
    fn an_open_manipulator_stops_on_the_table_without_an_overload() {
        use firmware::bus::table::xseries;
        let arm = ArmSpec::load("open-manipulator-x", None).unwrap();
        let world = World::new(&arm, CollisionSpec::from_frames(&arm, 0.02)).unwrap();
        let servos = crate::arm::servos::servos_of(&arm).unwrap();
        let mut bus = SimBus::new(servos.model.protocol, servos.model, &servos.bus_ids(), servos.baud)
            .with_contact(Some(ContactModel::new(world.clone())));
        for s in bus.servos_mut() {
            s.set_register(xseries::TORQUE_ENABLE, 1, 0).unwrap();
        }
        let id = world.ids()[1];
        // Its first link's capsule dips 3 mm into the table at rest: that overlap may stay, no
        // deeper; every other pair must keep clear.
        let start = world.pair_distances(&angles(&bus, &world)).unwrap();
        let goal = world_goal(&world, 1, 1.5);
        bus.servo_mut(id).unwrap().set_register(xseries::GOAL_POSITION, goal, 0).unwrap();
        bus.advance_to(4 * S);
        let end = world.pair_distances(&angles(&bus, &world)).unwrap();
        for (k, (a, b)) in start.iter().zip(&end).enumerate() {
            assert!(*b > a.min(0.0) - 1e-4, "pair {:?}: {a} m at rest, {b} m", world.pairs()[k]);
        }
        let (what, ids) = bus.contact().unwrap().stats().last.clone().unwrap();
        assert!(what.contains("table") && !what.starts_with("joint1"), "{what}");
        assert_eq!(ids, [id]);
        let s = bus.servo(id).unwrap();
        assert!((goal - s.get(xseries::PRESENT_POSITION)).abs() > 20);
        assert!(s.torque() && s.status_error(0) == 0, "no overload modelled on a Dynamixel");
    }

    /// A motion that brings nothing into contact is not touched.
    #[test]
    fn free_motion_is_not_stopped() {
        let (mut bus, world) = so101();
        let goal = world_goal(&world, 1, -0.5);
        bus.servo_mut(2).unwrap().set_register(sts3215::GOAL_POSITION, goal, 0).unwrap();
        bus.advance_to(S);
        assert_eq!(bus.servo(2).unwrap().get(sts3215::PRESENT_POSITION), goal);
        assert_eq!(bus.contact().unwrap().stats().stalls, 0);
    }
}
