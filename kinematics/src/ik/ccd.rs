//! Cyclic coordinate descent (CCD): one joint at a time, each moved to its exact optimum with the
//! others held, sweeping from the tool joint to the base.
//!
//! Kept for comparison: no Jacobian and no linear solve, every joint update is closed form and
//! respects that joint's limits exactly, and far from the target it makes large, stable moves; but
//! it favours the distal joints and converges only linearly near the solution.
//!
//! Each joint sees a weighted point set carried by the tool: the tool origin (weight 1) and, for a
//! pose target, the points at distance `w` (the orientation weight) along the three tool axes
//! (weight 1/2 each), each to be brought onto the matching point of the target frame; for a tilt
//! target, the two points at `w` either side along the tool's vertical, onto the base's z axis
//! through the target (see [`PointSet::new`]). The weights
//! make the point-set error agree with the residual's cost `|dp|^2 + w^2 |dtheta|^2` to second
//! order, so the orientation is honoured on the scale the other methods use. For a revolute joint
//! with axis `a` through `o`, and `r = p - o`, `t = target - o`, the best rotation is
//! `theta = atan2(sum w a.(r x t), sum w (r.t - (a.r)(a.t)))`; when that angle lies outside the
//! limits the better of the two limits is taken (the objective is unimodal on the circle). A
//! prismatic joint moves by the weighted mean of `a.(t - p)`, clamped. One iteration is one sweep.

use super::dls::done;
use super::{Descent, DescentEnd, IkMethod, Residual, Target};
use crate::{axis_angle_matrix, Chain, JointKind, Real};
use nalgebra::{SVector, Vector3};

/// Cyclic coordinate descent, tip to base. Stateless.
#[derive(Clone, Copy, Debug, Default)]
pub struct CyclicCoordinateDescent;

/// Consecutive sweeps in which the cost falls by less than [`SLOW`] (relative) after which an
/// attempt counts as stalled (CCD converges linearly, so the bar is low).
const PATIENCE: u32 = 8;
const SLOW: f64 = 1e-4;

/// The tool-carried points (at most four) and their targets and weights.
struct PointSet<T: Real> {
    points: [Vector3<T>; 4],
    targets: [Vector3<T>; 4],
    weights: [T; 4],
    len: usize,
}

impl<T: Real> PointSet<T> {
    fn new(residual: &Residual<T>, tool: &crate::Pose<T>) -> Self {
        let zero = Vector3::zeros();
        let mut set = Self {
            points: [tool.translation, zero, zero, zero],
            targets: [*residual.target.position(), zero, zero, zero],
            weights: [T::one(), T::zero(), T::zero(), T::zero()],
            len: 1,
        };
        if let Target::Pose(goal) = &residual.target {
            let w = residual.weight;
            for axis in 0..3 {
                set.points[axis + 1] = tool.translation + tool.rotation.column(axis) * w;
                set.targets[axis + 1] = goal.translation + goal.rotation.column(axis) * w;
                set.weights[axis + 1] = T::of(0.5);
            }
            set.len = 4;
        }
        if let Target::Tilt(goal) = &residual.target {
            // Two points at distance `w` either side of the tool origin along the tool's vertical
            // (the base's z as the target carries it), each to be brought onto the matching point
            // along the base's z through the target position. Their mean is the tool origin, so
            // with weight 1/2 each the cross terms cancel and the point-set error is exactly
            // `|dp|^2 + w^2 |z - v|^2`: the origin itself is not needed (weight 0). A turn about the
            // base's z through the target moves none of the targets, so the yaw is left free.
            let w = residual.weight;
            let v = tool.rotation * goal.rotation.row(2).transpose() * w;
            let up = Vector3::new(T::zero(), T::zero(), w);
            set.points[1] = tool.translation + v;
            set.targets[1] = goal.translation + up;
            set.points[2] = tool.translation - v;
            set.targets[2] = goal.translation - up;
            set.weights = [T::zero(), T::of(0.5), T::of(0.5), T::zero()];
            set.len = 3;
        }
        set
    }
}

impl<T: Real, const N: usize> IkMethod<T, N> for CyclicCoordinateDescent {
    fn descend(&self, chain: &Chain<T, N>, residual: &Residual<T>, start: SVector<T, N>, budget: u32) -> Descent<T, N> {
        let mut q = start;
        let mut error = residual.error(&chain.tool_pose(&q));
        // For a pose target the point-set error is the residual's cost only to second order, so a
        // sweep can raise the cost slightly: the best iterate is kept.
        let (mut best_q, mut best) = (q, error);
        let mut unproductive = 0;
        for iteration in 0..budget {
            if residual.converged(&best) {
                return done(best_q, best, iteration, DescentEnd::Converged);
            }
            sweep(chain, residual, &mut q);
            let previous = error;
            error = residual.error(&chain.tool_pose(&q));
            if !error.cost.finite() {
                // Unreachable with finite input; kept so that no input makes the method loop on NaN.
                return done(best_q, best, iteration + 1, DescentEnd::Stalled);
            }
            if error.cost < best.cost {
                (best_q, best) = (q, error);
            }
            let slow = error.cost >= previous.cost * (T::one() - T::of(SLOW));
            unproductive = if slow { unproductive + 1 } else { 0 };
            if unproductive >= PATIENCE {
                let end = if residual.converged(&best) { DescentEnd::Converged } else { DescentEnd::Stalled };
                return done(best_q, best, iteration + 1, end);
            }
        }
        let end = if residual.converged(&best) { DescentEnd::Converged } else { DescentEnd::OutOfBudget };
        done(best_q, best, budget, end)
    }
}

/// One sweep from the last joint to the first, updating `q` in place (always within limits).
fn sweep<T: Real, const N: usize>(chain: &Chain<T, N>, residual: &Residual<T>, q: &mut SVector<T, N>) {
    // Joint k's frame depends only on joints 0..=k, which a tip-to-base sweep has not touched yet
    // when it reaches k, so one FK serves the whole sweep; the tool points are moved rigidly.
    let frames = chain.forward(q);
    let mut set = PointSet::new(residual, &frames.tool);
    for k in (0..N).rev() {
        let joint = &chain.joints()[k];
        let frame = &frames.joints[k];
        let a = frame.rotation * joint.axis;
        let o = frame.translation;
        let current = q[k];
        let next = match joint.kind {
            JointKind::Fixed => continue,
            JointKind::Prismatic => {
                let (mut num, mut den) = (T::zero(), T::zero());
                for i in 0..set.len {
                    num += set.weights[i] * a.dot(&(set.targets[i] - set.points[i]));
                    den += set.weights[i];
                }
                joint.normalise(current + num / den)
            }
            JointKind::Revolute | JointKind::Continuous => {
                let (mut sin_part, mut cos_part) = (T::zero(), T::zero());
                for i in 0..set.len {
                    let r = set.points[i] - o;
                    let t = set.targets[i] - o;
                    sin_part += set.weights[i] * a.dot(&r.cross(&t));
                    cos_part += set.weights[i] * (r.dot(&t) - a.dot(&r) * a.dot(&t));
                }
                best_angle(joint, current, sin_part, cos_part)
            }
        };
        if !next.finite() {
            continue;
        }
        let delta = next - current;
        q[k] = next;
        for p in set.points.iter_mut().take(set.len) {
            *p = match joint.kind {
                JointKind::Prismatic => *p + a * delta,
                _ => o + axis_angle_matrix(&a, delta) * (*p - o),
            };
        }
    }
}

/// The admissible value of a rotary joint that maximises `cos_part cos(d) + sin_part sin(d)` over
/// the rotation `d` from `current`: the unconstrained optimum if the joint admits it (up to whole
/// turns), otherwise the better of the two limits. Keeps `current` when there is no information
/// (both parts zero, e.g. every point on the axis).
fn best_angle<T: Real>(joint: &crate::Joint<T>, current: T, sin_part: T, cos_part: T) -> T {
    if !(sin_part.finite() && cos_part.finite()) || (sin_part == T::zero() && cos_part == T::zero()) {
        return current;
    }
    let gain = |value: T| {
        let (s, c) = (value - current).sin_cos_fast();
        cos_part * c + sin_part * s
    };
    let optimum = joint.normalise(current + sin_part.atan2(cos_part));
    if joint.kind == JointKind::Continuous {
        return optimum;
    }
    let mut best = current;
    for candidate in [optimum, joint.limits.lower, joint.limits.upper] {
        if joint.admits(candidate) && gain(candidate) > gain(best) {
            best = candidate;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ik::{IkConfig, IkProblem, IkStatus};
    use crate::{presets, Joint, Limits, Pose, SplitMix64};

    #[test]
    fn one_link_lands_in_one_sweep() {
        // A single revolute joint: the closed-form angle is exact, so one sweep reaches the target.
        let chain = presets::planar::<f64, 1>().unwrap();
        let residual = Residual::new(Target::Position(Vector3::new(-0.6, 0.8, 0.0)), &IkConfig::default());
        let d = CyclicCoordinateDescent.descend(&chain, &residual, SVector::from([0.0]), 5);
        assert_eq!((d.end, d.iterations), (DescentEnd::Converged, 1));
        assert!((d.q[0] - 0.8f64.atan2(-0.6)).abs() <= 1e-12);
    }

    #[test]
    fn planar_position_targets_converge() {
        let chain = presets::planar::<f64, 4>().unwrap();
        let config = IkConfig { attempt_iterations: 2000, max_iterations: 20_000, ..IkConfig::default() };
        let mut rng = SplitMix64::new(11);
        for _ in 0..20 {
            let goal = chain.random_configuration(&mut rng);
            let target = Target::Position(chain.tool_pose(&goal).translation);
            let s = chain.solve_with(&CyclicCoordinateDescent, &IkProblem { target, seed: chain.middle(), config });
            assert_eq!(s.status, IkStatus::Converged, "{s:?}");
        }
    }

    #[test]
    fn ur5e_pose_targets_converge_with_orientation() {
        let chain = presets::ur5e::<f64>().unwrap();
        let config = IkConfig { attempt_iterations: 2000, max_iterations: 20_000, ..IkConfig::default() };
        let mut rng = SplitMix64::new(13);
        let mut converged = 0;
        for _ in 0..10 {
            let goal = chain.random_configuration(&mut rng);
            let target = Target::Pose(chain.tool_pose(&goal));
            let s = chain.solve_with(&CyclicCoordinateDescent, &IkProblem { target, seed: chain.middle(), config });
            assert!(chain.admits(&s.q));
            if s.status == IkStatus::Converged {
                assert!(s.orientation_error <= 1e-5);
                converged += 1;
            }
        }
        assert!(converged >= 9, "{converged}/10");
    }

    #[test]
    fn limited_joint_takes_the_better_limit() {
        // One joint limited to [-0.5, 0.5]. From 0 towards 2.0 rad the upper limit is the better
        // end. From 0.5 towards 3.5 rad the raw optimum 0.5 + 3.0 is past the upper limit, yet the
        // lower limit is nearer in angle (the other way round): clamping would stay at 0.5.
        let link = Pose::from_xyz_rpy([1.0, 0.0, 0.0], [0.0; 3]);
        let joint = Joint::revolute(Pose::identity(), [0.0, 0.0, 1.0], Limits::symmetric(0.5));
        let chain = Chain::<f64, 1>::new([joint], link).unwrap();
        for (start, angle, expected) in [(0.0, 2.0f64, 0.5), (0.5, 3.5, -0.5), (0.0, 0.3, 0.3)] {
            let target = Target::Position(Vector3::new(angle.cos(), angle.sin(), 0.0));
            let residual = Residual::new(target, &IkConfig::default());
            let d = CyclicCoordinateDescent.descend(&chain, &residual, SVector::from([start]), 1);
            assert!((d.q[0] - expected).abs() <= 1e-12, "{angle}: {d:?}");
            assert!(chain.admits(&d.q));
        }
    }

    #[test]
    fn prismatic_joint_moves_by_the_mean_projection() {
        let slide = Joint::prismatic(Pose::identity(), [1.0, 0.0, 0.0], Limits::new(0.0, 1.0));
        let turn = Joint::continuous(Pose::identity(), [0.0, 0.0, 1.0]);
        let chain = Chain::<f64, 2>::new([slide, turn], Pose::from_xyz_rpy([0.5, 0.0, 0.0], [0.0; 3])).unwrap();
        let residual = Residual::new(Target::Position(Vector3::new(0.7, 0.3, 0.0)), &IkConfig::default());
        let d = CyclicCoordinateDescent.descend(&chain, &residual, SVector::from([0.0, 0.0]), 200);
        assert_eq!(d.end, DescentEnd::Converged, "{d:?}");
        assert!(chain.admits(&d.q));
        // Beyond the slide's range: it stops at its limit and the method stalls, honestly.
        let residual = Residual::new(Target::Position(Vector3::new(3.0, 0.0, 0.0)), &IkConfig::default());
        let d = CyclicCoordinateDescent.descend(&chain, &residual, SVector::from([0.0, 0.0]), 200);
        assert_eq!(d.end, DescentEnd::Stalled);
        assert!((d.q[0] - 1.0).abs() <= 1e-12 && (d.error.position - 1.5).abs() <= 1e-9, "{d:?}");
    }

    #[test]
    fn f32_does_not_panic() {
        let chain = presets::ur5e::<f32>().unwrap();
        let goal = chain.tool_pose(&SVector::from([0.3, -1.2, 1.0, -0.5, 1.1, 0.2]));
        let residual = Residual::new(Target::Pose(goal), &IkConfig::default());
        let d = CyclicCoordinateDescent.descend(&chain, &residual, chain.middle(), 300);
        assert!(chain.admits(&d.q) && d.error.cost.is_finite());
    }
}
