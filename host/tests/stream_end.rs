//! A stream that stops without a word (a policy ending, a teleop leader put down): the arm ends on
//! the last keyframe it was sent. Measured from outside, as Python's `Arm.stream` drives it: the
//! firmware core on this PC in real time, its servos simulated on a pty behind a USB adapter's
//! latency, and the same [`Streamer`] the Python package and LeRobot's `armctl_follower` push
//! through.
//!
//! Ramps at 30, 60 and 90 deg/s in random directions through every joint (the fastest at the
//! ramp's speed) from random starts, at 30 readings a second, then nothing: within 1 s of the last
//! reading the measured joints are within 0.1 deg of it and stay there, on the SO-101 (Feetech) and the OpenManipulator-X (Dynamixel).
//! The status says how far the brake carried the arm past (`largest_pass`): the stopping distance
//! `v² / 2a` of the joint that stops last, against the last keyframe's speed.

use std::time::{Duration, Instant};

use armctl::arm::servos::servos_of;
use armctl::motion::teleop::leader::Reading;
use armctl::motion::teleop::stream::{Settings, Streamer};
use armctl::runtime::connection::Place;
use armctl::runtime::driver::Driver;
use kinematics::SplitMix64;

/// Readings a second, as LeRobot's control loop sends them.
const RATE: f64 = 30.0;
/// How long each ramp streams before it stops, s.
const RAMP: f64 = 0.6;
/// The goal: at rest on the last reading within this much (deg) ...
const REST_DEG: f64 = 0.1;
/// ... within this long after it (s).
const WITHIN: f64 = 1.0;

/// One ramp's figures.
struct Ended {
    /// The rest error against the last reading once settled, deg.
    rest_deg: f64,
    /// From the last reading to the moment the arm was within [`REST_DEG`] for good, s.
    settled_s: f64,
    /// The status's largest pass, deg, and the stopping distance expected from the last step, deg.
    pass_deg: f64,
    expected_pass_deg: f64,
}

fn open(arm: &str) -> (Driver, Option<armctl::sim::PtyServer>) {
    let place = Place { sim: true, arm: Some(arm.to_string()), ..Place::default() };
    // The stream's end is the subject, not the collision check: a random ramp may run the arm
    // into the table or itself, which the firmware would stop (collision_sil tests that).
    let mut target = place.target().unwrap();
    if let armctl::runtime::connection::Target::Sim(options) = &mut target {
        (options.arm.collision, options.contact) = (None, None);
    }
    let (target, servos) = target.in_real_time().unwrap();
    let driver = Driver::open(target, Some(arm), &mut std::io::sink()).unwrap();
    (driver, servos)
}

/// Streams a ramp from where the arm holds, at `speed` (rad/s, the fastest joint's) in a random
/// direction with room for the ramp and its stopping distance, then stops sending and watches.
fn ramp_then_silence(driver: &mut Driver, speed: f64, rng: &mut SplitMix64) -> Ended {
    let period = Duration::from_secs_f64(1.0 / RATE);
    // Python's default lead: a period and 8 ms.
    let settings = Settings::for_follower(driver, period, period + Duration::from_millis(8), None, false).unwrap();
    let servos = servos_of(driver.arm()).unwrap();
    let stop = speed * speed / (2.0 * servos.max_acceleration);
    let start: Vec<f64> = driver.status().unwrap().setpoints.iter().map(|&x| f64::from(x)).collect();
    let mut direction: Vec<f64> = (0..start.len()).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let largest = direction.iter().fold(0.0f64, |m, d| m.max(d.abs()));
    for (j, d) in direction.iter_mut().enumerate() {
        *d /= largest;
        // Room for the ramp and the brake past its end, with a margin: else the other way.
        let (lo, hi) = settings.range[j];
        let reach = d.abs() * (speed * RAMP + stop) + 0.05;
        if start[j] + d.signum() * reach > hi || start[j] + d.signum() * reach < lo {
            *d = -*d;
        }
    }
    let mut stream = Streamer::begin(driver, settings).unwrap();
    let began = Instant::now();
    let steps = (RAMP * RATE).round() as usize;
    let mut last = start.clone();
    let mut last_at = began;
    for i in 1..=steps {
        let due = began + period.mul_f64(i as f64);
        std::thread::sleep(due.saturating_duration_since(Instant::now()));
        let t = i as f64 / RATE;
        let q: Vec<f64> = start.iter().zip(&direction).map(|(s, d)| s + d * speed * t).collect();
        let read_at = Instant::now();
        let sent = stream.send(driver, &Reading { joints: q.clone(), gripper: None }, read_at).unwrap();
        assert_eq!(sent.joints, q, "the ramp is within the limits: sent as read");
        (last, last_at) = (q, read_at);
    }
    // The stream stops without a word: no close, no last keyframe at rest.
    drop(stream);
    let mut settled = None;
    let mut rest_deg = f64::INFINITY;
    while last_at.elapsed() < Duration::from_secs_f64(WITHIN + 0.5) {
        let status = driver.status().unwrap();
        let error = status.measured.iter().zip(&last).map(|(m, q)| (f64::from(*m) - q).abs()).fold(0.0, f64::max);
        rest_deg = error.to_degrees();
        match (rest_deg < REST_DEG, settled) {
            (true, None) => settled = Some(last_at.elapsed().as_secs_f64()),
            (false, _) => settled = None,
            _ => {}
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let status = driver.status().unwrap();
    Ended {
        rest_deg,
        settled_s: settled.unwrap_or(f64::INFINITY),
        pass_deg: f64::from(status.largest_pass).to_degrees(),
        expected_pass_deg: stop.to_degrees(),
    }
}

fn arm_ends_on_its_last_reading(arm: &str, seed: u64) {
    let (mut driver, servos) = open(arm);
    driver.torque_on().unwrap();
    let mut rng = SplitMix64::new(seed);
    let mut misses = Vec::new();
    for speed_deg in [30.0, 60.0, 90.0, 30.0, 60.0, 90.0] {
        let e = ramp_then_silence(&mut driver, f64::to_radians(speed_deg), &mut rng);
        eprintln!(
            "{arm} {speed_deg} deg/s: at rest {:.3} deg from the last reading, {:.2} s after it; passed it by {:.2} deg (v²/2a {:.2})",
            e.rest_deg, e.settled_s, e.pass_deg, e.expected_pass_deg
        );
        if e.rest_deg >= REST_DEG || e.settled_s > WITHIN {
            misses.push(format!("{speed_deg} deg/s: {:.3} deg after {:.2} s", e.rest_deg, e.settled_s));
        }
        // The pass is the brake's: v²/2a at the last keyframe's speed, which the readings' timing
        // on the playback clock moves by a few per cent.
        let ratio = e.pass_deg / e.expected_pass_deg;
        assert!(
            (0.7..1.4).contains(&ratio),
            "{arm} {speed_deg} deg/s: passed by {:.2} deg, expected about {:.2}",
            e.pass_deg,
            e.expected_pass_deg
        );
    }
    assert!(misses.is_empty(), "{arm}: not at rest on the last reading within {WITHIN} s: {misses:?}");
    let monitor = servos.as_ref().and_then(|s| s.monitor()).expect("a simulated arm has a safety monitor");
    assert!(monitor.checked > 0 && monitor.violation_count == 0, "{:?}", monitor.violations);
}

#[test]
fn so101_ends_on_the_last_reading_of_a_stream_that_stops() {
    arm_ends_on_its_last_reading("so101", 11);
}

#[test]
fn open_manipulator_x_ends_on_the_last_reading_of_a_stream_that_stops() {
    arm_ends_on_its_last_reading("open-manipulator-x", 12);
}
