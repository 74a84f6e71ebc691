//! The streaming player, ticked at a fine step: no jump in position or velocity across appended
//! keyframes, replacement, underrun, resume and stop, and braking within the acceleration limits.

use kinematics::nalgebra::Vector3;
use kinematics::trajectory::{JointLimits, Player, PlayerKeyframe, PushError, Sample, State};
use proptest::prelude::*;

const DT: f64 = 1e-3;
const VMAX: f64 = 5.0;
const AMAX: f64 = 60.0;

fn limits() -> JointLimits<f64, 3> {
    JointLimits::new(Vector3::repeat(-10.0), Vector3::repeat(10.0), Vector3::repeat(VMAX), Vector3::repeat(AMAX))
        .unwrap()
}

fn key(time: f64, p: [f64; 3]) -> PlayerKeyframe<f64, 3> {
    PlayerKeyframe::new(time, Vector3::from(p))
}

/// Checks consecutive samples: |Δposition| <= v_max dt and |Δvelocity| <= a_max dt per joint.
#[derive(Default)]
struct Continuity {
    last: Option<Sample<f64, 3>>,
}

impl Continuity {
    fn check(&mut self, s: Sample<f64, 3>, vmax: f64, amax: f64) -> Result<(), TestCaseError> {
        if let Some(last) = self.last {
            for j in 0..3 {
                let dp = (s.position[j] - last.position[j]).abs();
                let dv = (s.velocity[j] - last.velocity[j]).abs();
                prop_assert!(dp <= vmax * DT + 1e-12, "position jump {dp} on joint {j}");
                prop_assert!(dv <= amax * DT + 1e-9, "velocity jump {dv} on joint {j}");
            }
        }
        self.last = Some(s);
        Ok(())
    }
}

/// Keyframe steps: at least 0.3 s apart, at most 0.3 rad per joint, so Catmull-Rom segments stay
/// well inside VMAX and AMAX (|v| <= 3.5, |a| <= 47 by the Hermite bounds).
fn steps() -> impl Strategy<Value = Vec<(f64, [f64; 3])>> {
    proptest::collection::vec((0.3..0.8f64, proptest::array::uniform3(-0.3..0.3f64)), 3..12)
}

fn stream(start: f64, origin: [f64; 3], steps: &[(f64, [f64; 3])]) -> Vec<PlayerKeyframe<f64, 3>> {
    let (mut t, mut p) = (start, origin);
    steps
        .iter()
        .map(|(gap, d)| {
            t += gap;
            for j in 0..3 {
                p[j] += d[j];
            }
            key(t, p)
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Keyframes are appended a little before they are needed (two ahead, with a queue of 3):
    /// every join is continuous, and the stream ends at rest without an underrun.
    #[test]
    fn appended_keyframes_join_smoothly(steps in steps()) {
        let mut player = Player::<f64, 3, 3>::new(Vector3::zeros(), limits()).unwrap();
        let keys = stream(0.1, [0.0; 3], &steps);
        let end = keys.last().unwrap().time;
        let (mut next, mut c) = (0, Continuity::default());
        let mut t = 0.0;
        while t < end + 0.5 {
            // Keep about two keyframes ahead of the playhead.
            while next < keys.len() && keys[next].time < t + 1.0 && player.free_slots() > 0 {
                player.push(keys[next]).unwrap();
                next += 1;
            }
            let tick = player.tick(t);
            prop_assert!(!tick.underrun);
            c.check(tick.sample, VMAX, AMAX)?;
            t += DT;
        }
        let last = player.tick(t);
        prop_assert_eq!(last.state, State::Idle);
        prop_assert!((last.sample.position - keys.last().unwrap().position).norm() < 1e-12);
        prop_assert_eq!(player.underruns(), 0);
    }

    /// Halfway through, the rest of the trajectory is replaced by another one starting 0.5 s later:
    /// no jump, and the new keyframes are reached.
    #[test]
    fn replacement_starts_from_the_current_state(first in steps(), second in steps(), at in 0.2..0.9f64) {
        let mut player = Player::<f64, 3, 16>::new(Vector3::zeros(), limits()).unwrap();
        let keys = stream(0.1, [0.0; 3], &first);
        for k in &keys {
            player.push(*k).unwrap();
        }
        let switch = keys.last().unwrap().time * at;
        let mut c = Continuity::default();
        let mut t = 0.0;
        while t < switch {
            c.check(player.tick(t).sample, VMAX, AMAX)?;
            t += DT;
        }
        let here = player.tick(t);
        c.check(here.sample, VMAX, AMAX)?;
        // The new trajectory starts near where the arm is (within its first step).
        let origin = [here.sample.position[0], here.sample.position[1], here.sample.position[2]];
        let new = stream(t + 0.2, origin, &second);
        player.replace(&new).unwrap();
        let end = new.last().unwrap().time;
        let mut reached = 0;
        while t < end + 0.5 {
            t += DT;
            let tick = player.tick(t);
            c.check(tick.sample, VMAX, AMAX)?;
            if reached < new.len() && (tick.sample.position - new[reached].position).norm() < 1e-9 {
                reached += 1;
            }
        }
        prop_assert_eq!(player.tick(t).state, State::Idle);
        prop_assert!((player.tick(t).sample.position - new.last().unwrap().position).norm() < 1e-12);
    }

    /// A stop at any moment decelerates within the acceleration limits and holds; keyframes
    /// pushed afterwards resume without a jump.
    #[test]
    fn stop_brakes_within_limits_and_resumes(steps in steps(), at in 0.1..0.9f64) {
        let mut player = Player::<f64, 3, 16>::new(Vector3::zeros(), limits()).unwrap();
        let keys = stream(0.1, [0.0; 3], &steps);
        for k in &keys {
            player.push(*k).unwrap();
        }
        let mut c = Continuity::default();
        let mut t = 0.0;
        while t < keys.last().unwrap().time * at {
            c.check(player.tick(t).sample, VMAX, AMAX)?;
            t += DT;
        }
        player.stop();
        prop_assert_eq!(player.queued(), 0);
        let mut state = player.tick(t).state;
        while state == State::Stopping {
            let tick = player.tick(t);
            state = tick.state;
            prop_assert!(tick.sample.acceleration.iter().all(|a| a.abs() <= AMAX + 1e-9));
            c.check(tick.sample, VMAX, AMAX)?;
            t += DT;
        }
        prop_assert_eq!(state, State::Holding);
        let held = player.tick(t).sample;
        prop_assert_eq!(held.velocity, Vector3::zeros());
        for _ in 0..100 {
            t += DT;
            prop_assert_eq!(player.tick(t).sample, held);
        }
        let p = held.position;
        let resume = stream(t + 0.05, [p[0], p[1], p[2]], &steps[..2]);
        for k in &resume {
            player.push(*k).unwrap();
        }
        while t < resume[1].time + 0.1 {
            t += DT;
            let tick = player.tick(t);
            c.check(tick.sample, VMAX, AMAX)?;
        }
        prop_assert!((player.tick(t).sample.position - resume[1].position).norm() < 1e-12);
    }
}

/// Keyframes with given non-zero velocities, then nothing: the player brakes within a_max,
/// reports one underrun, comes back to the last keyframe within the limits and ends there, and
/// plays keyframes that come again from there.
#[test]
fn underrun_brakes_comes_back_and_resumes() {
    let mut player = Player::<f64, 3, 4>::new(Vector3::zeros(), limits()).unwrap();
    let v = Vector3::new(1.5, -0.5, 0.0);
    let last = Vector3::new(0.4, -0.1, 0.0);
    player.push(PlayerKeyframe { velocity: Some(v), ..key(0.5, [0.4, -0.1, 0.0]) }).unwrap();
    let mut c = Continuity::default();
    let (mut t, mut underruns, mut states) = (0.0, 0, Vec::new());
    let mut farthest = 0.0f64;
    while t < 1.0 {
        let tick = player.tick(t);
        c.check(tick.sample, VMAX, AMAX).unwrap();
        assert!(tick.sample.acceleration.iter().all(|a| a.abs() <= AMAX + 1e-9));
        underruns += usize::from(tick.underrun);
        if t >= 0.5 {
            farthest = farthest.max((tick.sample.position - last).amax());
        }
        if states.last() != Some(&tick.state) {
            states.push(tick.state);
        }
        t += DT;
    }
    assert_eq!(states, [State::Playing, State::Underrun, State::Returning, State::Idle]);
    assert_eq!((underruns, player.underruns()), (1, 1));
    // Stopping distance v^2 / 2a on the slowest-to-stop joint, the other in proportion: the pass.
    let stop = 1.5 / AMAX;
    let pass = (v * stop / 2.0).amax();
    assert!((player.largest_pass() - pass).abs() < 1e-12, "{} against {pass}", player.largest_pass());
    assert!((farthest - pass).abs() < 1e-9, "never farther than the brake went");
    assert_eq!(player.tick(t).sample.position, last);
    assert_eq!(player.tick(t).sample.velocity, Vector3::zeros());
    // Resume.
    player.push(key(t + 0.5, [0.0, 0.0, 0.0])).unwrap();
    let end = t + 0.5;
    while t < end + 0.1 {
        t += DT;
        let tick = player.tick(t);
        c.check(tick.sample, VMAX, AMAX).unwrap();
        assert!(t >= end || tick.state == State::Playing);
    }
    assert_eq!(player.tick(t).state, State::Idle);
    assert_eq!(player.tick(t).sample.position, Vector3::zeros());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// A stream of keyframes with velocities (as a teleoperation or a policy sends them) that
    /// stops at any point: the player brakes and comes back within the limits, ends exactly on the
    /// last keyframe, within the time the brake and a rest-to-rest return need, and its pass is
    /// the brake's stopping distance, v^2 / 2a on the joint that stops last.
    #[test]
    fn a_stream_that_stops_ends_on_its_last_keyframe(steps in steps(), keep in 1..12usize) {
        let mut player = Player::<f64, 3, 16>::new(Vector3::zeros(), limits()).unwrap();
        let all = stream(0.1, [0.0; 3], &steps);
        let keys = &all[..keep.min(all.len())];
        // Each keyframe carries the velocity of the step that reaches it, as `Streamer::send` does.
        let mut previous = (0.0, Vector3::zeros());
        for k in keys {
            let v = (k.position - previous.1) / (k.time - previous.0);
            previous = (k.time, k.position);
            player.push(PlayerKeyframe { velocity: Some(v.map(|x| x.clamp(-VMAX, VMAX))), ..*k }).unwrap();
        }
        let last = keys.last().unwrap();
        let v_last = player_velocity_at_end(keys);
        let brake = limits().stopping_time(&v_last);
        let pass = (v_last * brake / 2.0).amax();
        let back = limits().rest_to_rest_time(&Vector3::zeros(), &Vector3::repeat(pass));
        let mut c = Continuity::default();
        let mut t = 0.0;
        while t < last.time + brake + back + 2.0 * DT {
            let tick = player.tick(t);
            c.check(tick.sample, VMAX, AMAX)?;
            prop_assert!((tick.sample.position - last.position).amax() <= pass + 1e-9 || t < last.time);
            t += DT;
        }
        let end = player.tick(t);
        prop_assert_eq!(end.state, State::Idle);
        prop_assert_eq!(end.sample.position, last.position);
        prop_assert_eq!(player.underruns(), u32::from(v_last != Vector3::zeros()));
        prop_assert!((player.largest_pass() - pass).abs() < 1e-9, "{} against {}", player.largest_pass(), pass);
    }
}

/// The velocity the stream's last keyframe carries (its step over its time).
fn player_velocity_at_end(keys: &[PlayerKeyframe<f64, 3>]) -> Vector3<f64> {
    let n = keys.len();
    let (t0, p0) = if n > 1 { (keys[n - 2].time, keys[n - 2].position) } else { (0.0, Vector3::zeros()) };
    ((keys[n - 1].position - p0) / (keys[n - 1].time - t0)).map(|x| x.clamp(-VMAX, VMAX))
}

/// A keyframe arriving while braking from an underrun is taken at once, without a jump.
#[test]
fn keyframe_during_underrun_brake_resumes_smoothly() {
    let mut player = Player::<f64, 3, 4>::new(Vector3::zeros(), limits()).unwrap();
    let v = Vector3::new(3.0, 0.0, -3.0);
    player.push(PlayerKeyframe { velocity: Some(v), ..key(0.5, [0.5, 0.0, -0.5]) }).unwrap();
    let mut c = Continuity::default();
    let mut t = 0.0;
    while t < 0.52 {
        c.check(player.tick(t).sample, VMAX, AMAX).unwrap();
        t += DT;
    }
    assert_eq!(player.tick(t).state, State::Underrun);
    player.push(key(1.2, [1.5, 0.0, -1.5])).unwrap();
    assert_eq!(player.tick(t).state, State::Playing);
    while t < 1.3 {
        c.check(player.tick(t).sample, VMAX, AMAX).unwrap();
        t += DT;
    }
    assert_eq!(player.tick(t).sample.position, Vector3::new(1.5, 0.0, -1.5));
}

/// A late keyframe (its time already past when the player resumes) is shifted, not jumped to.
#[test]
fn late_keyframes_are_shifted_not_jumped_to() {
    let mut player = Player::<f64, 3, 4>::new(Vector3::zeros(), limits()).unwrap();
    let mut c = Continuity::default();
    for i in 0..100 {
        c.check(player.tick(f64::from(i) * DT).sample, VMAX, AMAX).unwrap();
    }
    player.push(key(0.05, [0.2, 0.2, 0.2])).unwrap();
    player.push(key(0.55, [0.3, 0.3, 0.3])).unwrap();
    let mut t = 0.1;
    while t < 2.0 {
        c.check(player.tick(t).sample, VMAX, AMAX).unwrap();
        t += DT;
    }
    assert_eq!(player.tick(t).sample.position, Vector3::repeat(0.3));
}

/// A stream longer than the queue whose first keyframe is late (far from where the player
/// rests, at time 0): the queued keyframes are shifted, and so are the ones pushed after them, so
/// the stream keeps its spacing and none is refused as not later than the last.
#[test]
fn keyframes_pushed_after_a_shift_are_shifted_alike() {
    let mut player = Player::<f64, 3, 4>::new(Vector3::zeros(), limits()).unwrap();
    let stream: Vec<_> = (0..12).map(|i| key(0.1 * f64::from(i), [0.8, 0.01 * f64::from(i), 0.0])).collect();
    for k in &stream[..4] {
        player.push(*k).unwrap();
    }
    player.tick(0.0);
    let shift = player.shift();
    // The first keyframe is 0.8 rad away: a rest-to-rest move needs sqrt(6 * 0.8 / AMAX) at least.
    assert!(shift >= (6.0 * 0.8 / AMAX).sqrt() - 1e-9, "shift {shift}");
    let mut next = 4;
    let mut t = 0.0;
    while t < 4.0 {
        while next < stream.len() && player.free_slots() > 0 {
            player.push(stream[next]).unwrap();
            next += 1;
        }
        player.tick(t);
        t += DT;
    }
    assert_eq!(next, stream.len());
    // Each keyframe is passed at its time plus the shift.
    let mut again = Player::<f64, 3, 4>::new(Vector3::zeros(), limits()).unwrap();
    for k in &stream[..4] {
        again.push(*k).unwrap();
    }
    let mut next = 4;
    for i in 0..=400 {
        let t = f64::from(i) * DT;
        while next < stream.len() && again.free_slots() > 0 {
            again.push(stream[next]).unwrap();
            next += 1;
        }
        let sample = again.tick(t).sample;
        if let Some(k) = stream[1..].iter().find(|k| ((k.time + shift) - t).abs() < DT / 2.0) {
            assert!((sample.position - k.position).norm() < 1e-4, "at {t}: {:?} vs {:?}", sample.position, k.position);
        }
    }
    // A stop starts a new timeline.
    player.stop();
    assert_eq!(player.shift(), 0.0);
}

#[test]
fn queue_full_and_bad_keyframes_change_nothing() {
    let mut player = Player::<f64, 3, 2>::new(Vector3::zeros(), limits()).unwrap();
    player.push(key(1.0, [0.1, 0.2, 0.3])).unwrap();
    player.push(key(2.0, [0.2, 0.2, 0.3])).unwrap();
    assert_eq!(player.free_slots(), 0);
    assert_eq!(player.push(key(3.0, [0.0; 3])), Err(PushError::QueueFull));
    let mut twin = player.clone();
    twin.tick(0.0);
    player.tick(0.0);
    assert_eq!(player.push(key(3.0, [f64::NAN, 0.0, 0.0])), Err(PushError::NonFinite));
    assert_eq!(player.push(key(f64::INFINITY, [0.0; 3])), Err(PushError::NonFinite));
    assert_eq!(player.replace(&[key(3.0, [0.0, f64::NAN, 0.0])]), Err(PushError::NonFinite));
    assert_eq!(player.free_slots(), 1);
    for i in 0..3000 {
        let t = f64::from(i) * DT;
        assert_eq!(player.tick(t), twin.tick(t));
    }
}

#[test]
fn six_joint_f32_player_plays() {
    let l = JointLimits::<f32, 6>::new(
        kinematics::nalgebra::SVector::repeat(-3.0),
        kinematics::nalgebra::SVector::repeat(3.0),
        kinematics::nalgebra::SVector::repeat(2.0),
        kinematics::nalgebra::SVector::repeat(10.0),
    )
    .unwrap();
    let mut player = Player::<f32, 6, 8>::new(kinematics::nalgebra::SVector::zeros(), l).unwrap();
    for i in 1..=8u8 {
        let p = kinematics::nalgebra::SVector::repeat(0.1 * f32::from(i % 3));
        player.push(PlayerKeyframe::new(0.5 * f32::from(i), p)).unwrap();
    }
    assert_eq!(player.tick(0.0).state, State::Playing);
    assert_eq!(player.tick(1.3).state, State::Playing);
    assert_eq!(player.tick(5.0).state, State::Idle);
}
