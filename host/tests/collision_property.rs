//! What a person does with the simulated arm: random joint targets across the whole ranges, on
//! the SO-101 (its geometry fitted to its meshes) and the OpenManipulator-X (capsules from its
//! frames), each standing on its table with a box beside it, every target sent through the same
//! `joints` operation as `armctl --sim joints`, one after another from wherever the last left the
//! arm. Judged from outside the firmware and the host's check:
//! - a target the simulator's own geometry (`sim::World`) puts within the margin is refused, and
//!   the arm does not move;
//! - over every move, no goal the simulated servos got came within the margin (the simulator's
//!   safety monitor, which places every goal configuration the servos received), less the
//!   rounding of a goal to whole servo ticks.
//!
//! Sized for CI: 40 targets per arm. The 1000 per arm are a run of the same test with
//! `ARMCTL_COLLISION_TARGETS=1000` (docs/collisions.md gives its figures and the command);
//! `armctl bench plan` measures the planner alone over 1000 blocked moves.

use armctl::arm::collision::ObstacleSpec;
use armctl::commands::drive::joints::{joints, JointsRequest};
use armctl::runtime::connection::Target;
use armctl::runtime::driver::Driver;
use armctl::runtime::sil::SilOptions;
use armctl::sim::World;
use kinematics::collision::Shape;
use kinematics::nalgebra::Vector3;
use kinematics::SplitMix64;

/// A goal is whole ticks: 4096 per turn on either servo, half a tick at 0.35 m of reach is
/// 0.27 mm per joint; five joints' roundings together stay under this.
const TICK_ROUNDING_M: f64 = 0.002;

/// Targets per arm, unless `ARMCTL_COLLISION_TARGETS` says how many.
const TARGETS: usize = 40;

fn targets() -> usize {
    match std::env::var("ARMCTL_COLLISION_TARGETS") {
        Ok(n) => n.parse().unwrap_or_else(|_| panic!("ARMCTL_COLLISION_TARGETS={n}: not a count")),
        Err(_) => TARGETS,
    }
}

/// Where every simulated servo's horn is ([`armctl::runtime::sil::Sil::horns`]).
fn horns(driver: &mut Driver) -> Vec<f64> {
    driver.sil().unwrap().horns()
}

struct Tally {
    refused_in_contact: usize,
    reached: usize,
    not_planned: usize,
}

fn random_targets(arm: &str, box_at: [f64; 3], seed: u64) -> Tally {
    let mut options = SilOptions::new(arm).unwrap();
    let mut spec = options.arm.collision.clone().expect("the preset carries its geometry");
    let shape = Shape::aligned_box(Vector3::from(box_at), Vector3::new(0.06, 0.10, 0.10));
    spec.obstacles.push(ObstacleSpec { name: "box".into(), shape });
    options.arm.collision = Some(spec.clone());
    options.contact = Some(spec.clone());
    let mut world = World::new(&options.arm, spec).unwrap();
    let limits: Vec<(f64, f64)> = options.arm.joints.iter().map(|j| (j.lower, j.upper)).collect();
    let mut driver = Driver::open(Target::Sim(Box::new(options)), Some(arm), &mut std::io::sink()).unwrap();
    let mut rng = SplitMix64::new(seed);
    let mut tally = Tally { refused_in_contact: 0, reached: 0, not_planned: 0 };
    let count = targets();
    for k in 0..count {
        let q: Vec<f64> = limits.iter().map(|&(lo, hi)| rng.uniform(lo, hi)).collect();
        let in_contact = world.within_margin(&q);
        let before = horns(&mut driver);
        let request = JointsRequest::new(q.clone(), None, None, 20.0).unwrap();
        let result = joints(&mut driver, &request, &mut std::io::sink());
        match (in_contact, result) {
            (Some(contact), Err(e)) => {
                let after = horns(&mut driver);
                assert_eq!(before, after, "target {k} {q:?}: refused ({e}) but a servo's horn moved");
                assert!(e.to_string().contains("collision"), "target {k}: refused for another reason: {e}");
                let _ = contact;
                tally.refused_in_contact += 1;
            }
            (Some(contact), Ok(report)) => {
                panic!("target {k} {q:?} is in contact ({:?}) and was not refused: {report:?}", world.names(&contact))
            }
            (None, Ok(_)) => tally.reached += 1,
            // A free target the planner could not reach within its budget: refused, said so.
            (None, Err(e)) if e.to_string().contains("no collision-free path") => tally.not_planned += 1,
            (None, Err(e)) => panic!("target {k} {q:?} is free and failed: {e}"),
        }
    }
    let sil = driver.sil().unwrap();
    let record = sil.monitor().contacts.clone().expect("the monitor has the geometry");
    eprintln!(
        "{arm}: {} targets: {} refused in contact, {} reached, {} not planned; {}",
        count,
        tally.refused_in_contact,
        tally.reached,
        tally.not_planned,
        record.summary()
    );
    if let Some(closest) = &record.closest {
        assert!(closest.distance >= record.margin - TICK_ROUNDING_M, "{arm}: a goal came within the margin: {closest}");
    }
    assert!(record.checked > 100, "{}", record.summary());
    tally
}

#[test]
fn random_targets_on_the_so101_are_refused_in_contact_and_no_goal_comes_within_the_margin() {
    let t = random_targets("so101", [0.20, 0.12, 0.05], 45);
    assert!(t.refused_in_contact > 0 && t.reached > 0, "the targets should be of both kinds");
}

#[test]
fn random_targets_on_the_open_manipulator_are_refused_in_contact_and_no_goal_comes_within_the_margin() {
    let t = random_targets("open-manipulator-x", [0.18, 0.12, 0.05], 46);
    assert!(t.refused_in_contact > 0 && t.reached > 0, "the targets should be of both kinds");
}
