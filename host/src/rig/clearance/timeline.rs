//! A rig's play checked on its one timeline, as the players will play it: each arm's cubic
//! Hermite segments from where it stands (the file's velocities, else the player's Catmull-Rom
//! ones, at rest at its last keyframe), sampled every [`STEP`] and at every keyframe; and where
//! two arms would come too close, the keyframes that stop every arm short of it.

use anyhow::Result;

use super::{Clearance, Near};
use crate::link::session::Keyframe;
use crate::motion::reach;
use crate::rig::Rig;

/// The timeline's sampling period (s): the firmware's control period.
pub const STEP: f64 = 0.01;
/// Points checked on the way to a first keyframe at time 0.
const APPROACH_STEPS: usize = 50;

/// A knot of an arm's motion: time (s), positions, and velocities (`None`: the player's
/// Catmull-Rom ones).
type Knot = (f64, Vec<f64>, Option<Vec<f64>>);

/// One arm's motion on the timeline, from where it stands.
struct Track {
    knots: Vec<Knot>,
}

impl Track {
    /// The player's velocity at knot `k`: given, else Catmull-Rom over its neighbours, zero at the
    /// ends (the arm starts at rest, and ends at rest at its last keyframe).
    fn velocity(&self, k: usize) -> Vec<f64> {
        let (_, p, given) = &self.knots[k];
        if let Some(v) = given {
            return v.clone();
        }
        match (k.checked_sub(1).and_then(|i| self.knots.get(i)), self.knots.get(k + 1)) {
            (Some((t0, p0, _)), Some((t1, p1, _))) => p0.iter().zip(p1).map(|(a, b)| (b - a) / (t1 - t0)).collect(),
            _ => vec![0.0; p.len()],
        }
    }

    /// The positions at time `t` (held before the first knot and after the last).
    fn at(&self, t: f64) -> Vec<f64> {
        let Some(k) = self.knots.iter().position(|(tk, _, _)| *tk > t) else {
            return self.knots.last().map(|(_, p, _)| p.clone()).unwrap_or_default();
        };
        if k == 0 {
            return self.knots[0].1.clone();
        }
        let ((t0, p0, _), (t1, p1, _)) = (&self.knots[k - 1], &self.knots[k]);
        let (v0, v1) = (self.velocity(k - 1), self.velocity(k));
        let h = t1 - t0;
        let s = ((t - t0) / h).clamp(0.0, 1.0);
        let (s2, s3) = (s * s, s * s * s);
        let (h00, h10, h01, h11) = (2.0 * s3 - 3.0 * s2 + 1.0, s3 - 2.0 * s2 + s, -2.0 * s3 + 3.0 * s2, s3 - s2);
        (0..p0.len()).map(|j| h00 * p0[j] + h10 * h * v0[j] + h01 * p1[j] + h11 * h * v1[j]).collect()
    }
}

/// Where a rig's play would bring two arms too close.
#[derive(Clone, Debug, PartialEq)]
pub struct Collision {
    /// The first time on the timeline at which they are (s).
    pub at: f64,
    /// The two arms' bodies there.
    pub near: Near,
}

/// What [`timeline`] found: the play as it is, or the keyframes to keep so every arm stops short.
#[derive(Clone, Debug, PartialEq)]
pub enum Verdict {
    /// Every pair keeps its margin at every sample; the closest any came.
    Clear(Option<Near>),
    /// Two arms would come too close: how many keyframes of each part to play (their last kept
    /// keyframe before the contact, each arm then at rest there, that timeline checked clear too),
    /// and until when.
    StopShort {
        /// The contact the full file would reach.
        collision: Collision,
        /// Keyframes to keep, per part.
        keep: Vec<usize>,
        /// The last kept keyframe's time (s); 0 when nothing is kept.
        until: f64,
    },
}

/// Checks a rig's play: `parts` is each part's arm and keyframes (as they are pushed), `current`
/// every arm's joint values now. Cartesian keyframes are solved on the host, each seeded from
/// the one before.
pub fn timeline(rig: &Rig, parts: &[(usize, &[(usize, Keyframe)])], current: &[Vec<f64>]) -> Result<Verdict> {
    let clearance = Clearance::of(rig)?;
    let mut solved: Vec<(usize, Vec<Knot>)> = Vec::new();
    for &(arm, keyframes) in parts {
        let model = rig.arms[arm].driver.model();
        let mut seed = current.get(arm).cloned();
        let mut knots = Vec::new();
        for (_, keyframe) in keyframes {
            let knot = match keyframe {
                Keyframe::Joints(k) => {
                    let p: Vec<f64> = k.positions.iter().map(|&x| f64::from(x)).collect();
                    let v = k.velocities.as_ref().map(|v| v.iter().map(|&x| f64::from(x)).collect());
                    (f64::from(k.time), p, v)
                }
                Keyframe::Pose(k) => {
                    let position = k.target.position.map(f64::from);
                    let orientation = k.target.orientation.map(|q| q.map(f64::from));
                    let outcome = reach::solve(model, position, orientation, seed.clone())?;
                    (f64::from(k.time), outcome.q, None)
                }
            };
            seed = Some(knot.1.clone());
            knots.push(knot);
        }
        solved.push((arm, knots));
    }
    let mut keep: Vec<usize> = solved.iter().map(|(_, k)| k.len()).collect();
    let mut first: Option<Collision> = None;
    loop {
        let found = first_contact(&clearance, &solved, &keep, current)?;
        match (found, &first) {
            (Ok(closest), None) => return Ok(Verdict::Clear(closest)),
            (Ok(_), Some(collision)) => {
                let until = solved
                    .iter()
                    .zip(&keep)
                    .filter_map(|((_, k), &n)| n.checked_sub(1).map(|i| k[i].0))
                    .fold(0.0, f64::max);
                return Ok(Verdict::StopShort { collision: collision.clone(), keep, until });
            }
            (Err(collision), _) => {
                // Every part up to its last keyframe before the contact; then checked again, as
                // ending there changes the last segment's velocities.
                let before: Vec<usize> =
                    solved.iter().map(|(_, k)| k.iter().take_while(|(t, _, _)| *t < collision.at).count()).collect();
                let shorter: Vec<usize> = before.iter().zip(&keep).map(|(&b, &n)| b.min(n)).collect();
                let shorter = if shorter == keep {
                    // The contact is on the way to each part's first keyframe left: keep none of
                    // those that move.
                    keep.iter().map(|&n| n.saturating_sub(1)).collect()
                } else {
                    shorter
                };
                first.get_or_insert(collision);
                if shorter.iter().all(|&n| n == 0) {
                    let collision = first.clone().expect("set above");
                    return Ok(Verdict::StopShort { collision, keep: shorter, until: 0.0 });
                }
                keep = shorter;
            }
        }
    }
}

/// The first sample at which two arms are too close (`Err`), or the closest they came (`Ok`).
fn first_contact(
    clearance: &Clearance,
    solved: &[(usize, Vec<Knot>)],
    keep: &[usize],
    current: &[Vec<f64>],
) -> Result<std::result::Result<Option<Near>, Collision>> {
    // Arms whose first keyframe is at 0: the player takes them there from where they stand before
    // its clock runs; that way is checked as a straight line in joint space, all of them together.
    let mut approaches: Vec<(usize, Vec<f64>, Vec<f64>)> = Vec::new();
    let tracks: Vec<(usize, Track)> = solved
        .iter()
        .zip(keep)
        .map(|((arm, knots), &n)| {
            let mut all = vec![(0.0, current[*arm].clone(), None)];
            all.extend(knots.iter().take(n).cloned());
            if all.len() > 1 && all[1].0 <= 0.0 {
                let (_, from, _) = all.remove(0);
                approaches.push((*arm, from, all[0].1.clone()));
            }
            (*arm, Track { knots: all })
        })
        .collect();
    if !approaches.is_empty() {
        let mut q: Vec<Option<Vec<f64>>> = current.iter().cloned().map(Some).collect();
        for (arm, track) in &tracks {
            q[*arm] = Some(track.at(0.0));
        }
        for k in 0..=APPROACH_STEPS {
            let s = k as f64 / APPROACH_STEPS as f64;
            for (arm, from, to) in &approaches {
                q[*arm] = Some(from.iter().zip(to).map(|(a, b)| a + s * (b - a)).collect());
            }
            if let Some(near) = clearance.closest(&clearance.placed(&q)?).filter(Near::too_close) {
                return Ok(Err(Collision { at: 0.0, near }));
            }
        }
    }
    let end = tracks.iter().filter_map(|(_, t)| t.knots.last().map(|k| k.0)).fold(0.0, f64::max);
    let mut times: Vec<f64> = (0..=((end / STEP).ceil() as usize)).map(|i| (i as f64 * STEP).min(end)).collect();
    times.extend(tracks.iter().flat_map(|(_, t)| t.knots.iter().map(|k| k.0)));
    times.sort_by(f64::total_cmp);
    times.dedup();
    let mut closest: Option<Near> = None;
    for t in times {
        let mut q: Vec<Option<Vec<f64>>> = current.iter().cloned().map(Some).collect();
        for (arm, track) in &tracks {
            q[*arm] = Some(track.at(t));
        }
        if let Some(near) = clearance.closest(&clearance.placed(&q)?) {
            if near.too_close() {
                return Ok(Err(Collision { at: t, near }));
            }
            if closest.as_ref().is_none_or(|c| near.distance < c.distance) {
                closest = Some(near);
            }
        }
    }
    Ok(Ok(closest))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_track_passes_its_knots_with_the_players_velocities_and_holds_at_the_ends() {
        let track = Track { knots: vec![(0.0, vec![0.0], None), (1.0, vec![1.0], None), (2.0, vec![0.0], None)] };
        assert_eq!(track.at(-1.0), vec![0.0]);
        assert_eq!(track.at(1.0), vec![1.0]);
        assert_eq!(track.at(5.0), vec![0.0]);
        // Catmull-Rom at the middle knot: (0 - 0) / 2 = 0, so each half is a rest-to-rest cubic:
        // 3s^2 - 2s^3 at s = 0.25 is 0.15625.
        assert!((track.at(0.25)[0] - 0.15625).abs() < 1e-12);
        let moving = Track { knots: vec![(0.0, vec![0.0], None), (1.0, vec![1.0], None), (2.0, vec![2.0], None)] };
        // A straight line at 1 rad/s through the middle knot: the cubic is that line in the
        // second half (end velocity 0 bends it: h00 + h10 + h01 at s = 0.5 gives 1.5 + 0.125 = 1.625).
        assert!((moving.at(1.5)[0] - 1.625).abs() < 1e-12, "{:?}", moving.at(1.5));
    }
}
