//! The simulator knows contact: with the firmware's collision check off (it is sent no
//! geometry, as before the check existed), a move through the table stops the simulated SO-101
//! on the table, its servos stalled, and the simulator's safety monitor names the goals that came
//! within the margin, judged from the goals the servos received; a free move reports none.
//!
//! Until the presets carry their fitted geometry, the world here is the arm's frames as capsules
//! ([`CollisionSpec::from_frames`], 20 mm radius) on a table at the base plane.

use armctl::arm::collision::CollisionSpec;
use armctl::commands::drive::move_to::{move_to, MoveRequest};
use armctl::runtime::connection::Target;
use armctl::runtime::driver::Driver;
use armctl::runtime::sil::SilOptions;
use armctl::sim::monitor::ContactRecord;
use armctl::sim::World;
use firmware::link::message::MovePath;

/// The simulated SO-101 on a table its firmware knows nothing of.
fn driver() -> (Driver, World) {
    let mut options = SilOptions::new("so101").unwrap();
    options.arm.collision = None;
    let geometry = CollisionSpec::from_frames(&options.arm, 0.02);
    options.contact = Some(geometry.clone());
    let world = World::new(&options.arm, geometry).unwrap();
    let driver = Driver::open(Target::Sim(Box::new(options)), Some("so101"), &mut std::io::sink()).unwrap();
    (driver, world)
}

/// What a move did: the outcome, the monitor's record, the lowest tool height and the closest
/// any two checked parts came over the measured positions of every tick, and the stalls.
struct Run {
    outcome: String,
    record: ContactRecord,
    lowest_tool: f64,
    closest: f64,
    closest_pair: [String; 2],
    stalls: u64,
}

fn run(to: [f64; 3]) -> Run {
    let (mut driver, mut world) = driver();
    driver.sil().unwrap().record();
    let request = MoveRequest::new(to, None, None, None, MovePath::Auto, 20.0).unwrap();
    let outcome = match move_to(&mut driver, &request, &mut std::io::sink()) {
        Ok(report) => report.text(),
        Err(e) => format!("failed: {e}"),
    };
    let sil = driver.sil().unwrap();
    // A second of rest after it: a stalled servo keeps pushing.
    sil.run_for(1.0);
    let trace = sil.take_trace();
    let record = sil.monitor().contacts.clone().expect("the monitor has the geometry");
    let stalls = sil.bus().borrow().contact().expect("the bus has the geometry").stats().stalls;
    let (mut lowest_tool, mut closest, mut closest_pair) = (f64::INFINITY, f64::INFINITY, Default::default());
    for sample in trace.iter().filter(|s| s.measured.iter().all(|x| x.is_finite())) {
        lowest_tool = lowest_tool.min(world.tool(&sample.measured).unwrap()[2]);
        let c = world.closest(&sample.measured).unwrap();
        if c.distance < closest {
            (closest, closest_pair) = (c.distance, world.names(&c));
        }
    }
    Run { outcome, record, lowest_tool, closest, closest_pair, stalls }
}

/// Half a tick of each joint's position reading, at the SO-101's reach: the measured positions
/// the test places the arm by are whole ticks.
const READING_M: f64 = 0.002;

#[test]
fn a_move_through_the_table_stops_on_it_and_the_monitor_names_the_goals() {
    let r = run([0.20, 0.0, -0.08]);
    eprintln!(
        "{}\n{}; lowest tool {:.4} m; closest {:.4} m ({:?}); {} stalls",
        r.outcome,
        r.record.summary(),
        r.lowest_tool,
        r.closest,
        r.closest_pair,
        r.stalls
    );
    // The tool point is 20 mm inside its capsule: it stays that far above the table.
    assert!(r.lowest_tool > 0.02 - READING_M, "the tool went down to z = {} m", r.lowest_tool);
    assert!(r.closest > -READING_M, "{:?} overlapped by {} m", r.closest_pair, -r.closest);
    assert!(r.closest < READING_M, "it stopped {} m short of anything", r.closest);
    assert!(r.closest_pair.contains(&"table".to_string()), "{:?}", r.closest_pair);
    assert!(r.stalls > 0);
    assert!(r.record.count > 0, "{}", r.record.summary());
    let first = &r.record.contacts[0];
    assert!(first.bodies.contains(&"table".to_string()), "{first}");
    assert!(first.distance < r.record.margin, "{first}");
}

#[test]
fn a_free_move_reports_no_goal_within_the_margin() {
    let r = run([0.20, 0.0, 0.10]);
    eprintln!("{}\n{}", r.outcome, r.record.summary());
    assert!(!r.outcome.starts_with("failed"), "{}", r.outcome);
    assert!(r.record.checked > 100, "{}", r.record.summary());
    assert_eq!(r.record.count, 0, "{:?}", r.record.contacts.first());
    assert_eq!(r.stalls, 0);
    assert!(r.closest > r.record.margin, "{}", r.closest);
}
