//! Gradient descent on several targets at once: the problem's tool target plus any number of
//! handles, points fixed to a joint frame (or the tool) each pulled towards a point in space.
//!
//! The objective is `C(q) = cost(q) + sum_i 1/2 |p_i(q) - h_i|^2`, where `cost` is the residual's
//! (half the squared weighted tool error). Its gradient needs only Jacobian transposes:
//! `-J^T e + sum_i J_i^T (p_i - h_i)`, with `J_i` the point Jacobian of handle i (exact also for the
//! orientation part, since the derivative of half the squared rotation angle along a world rotation
//! `dphi` is `-w . dphi`). The step length comes from a backtracking (Armijo) line search that
//! starts from the last accepted length doubled, so it grows while steps succeed and halves while
//! they fail; the first trial is the length at which the linear model would reach zero cost.
//!
//! Kept for comparison and for the one thing the single-target methods cannot do: pose a chain by
//! several points at once (an elbow kept out of the way while the tool reaches). "Converged" still
//! means the tool target is within tolerance; with handles the descent goes on to the minimum of the
//! whole objective, where conflicting handles may hold the tool away from its target.

use super::dls::done;
use super::{Descent, DescentEnd, IkMethod, Residual};
use crate::{wrap_angle, Chain, Frames, JointKind, Real};
use nalgebra::{SVector, Vector3};

/// A point fixed to one frame of the chain, pulled towards a point in the base frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Handle<T: Real> {
    /// The frame the point moves with: joint index `0..N` (the frame after that joint's motion), or
    /// `N` for the tool frame. A handle naming a frame beyond `N` is ignored.
    pub frame: usize,
    /// The point in that frame (m).
    pub point: Vector3<T>,
    /// Where it should go, in the base frame (m).
    pub target: Vector3<T>,
}

/// Gradient descent on the tool target plus `handles`. Holds only a borrowed slice: no heap.
/// Handles with non-finite coordinates or an out-of-range frame are ignored.
#[derive(Clone, Copy, Debug)]
pub struct GradientDescent<'a, T: Real> {
    /// Extra point targets (none for plain gradient descent on the tool target).
    pub handles: &'a [Handle<T>],
}

impl<'a, T: Real> GradientDescent<'a, T> {
    /// Gradient descent on the tool target and `handles`.
    pub fn new(handles: &'a [Handle<T>]) -> Self {
        Self { handles }
    }
}

impl<T: Real> Default for GradientDescent<'_, T> {
    /// The tool target only.
    fn default() -> Self {
        Self { handles: &[] }
    }
}

/// Trials of one line search before the step counts as failed (the length may fall by 2^-40).
const HALVINGS: u32 = 40;
/// Armijo constant: a step must achieve this fraction of the decrease the gradient predicts.
const ARMIJO: f64 = 1e-4;
/// Consecutive iterations in which the objective falls by less than [`SLOW`] (relative) after which
/// the descent counts as stalled (first-order: linear convergence is expected, so the bar is low).
const PATIENCE: u32 = 8;
const SLOW: f64 = 1e-5;

/// The objective at one joint vector.
#[derive(Clone, Copy)]
struct Point<T: Real, const N: usize> {
    q: SVector<T, N>,
    frames: Frames<T, N>,
    error: super::ErrorTerms<T>,
    objective: T,
}

impl<T: Real, const N: usize> IkMethod<T, N> for GradientDescent<'_, T> {
    fn descend(&self, chain: &Chain<T, N>, residual: &Residual<T>, start: SVector<T, N>, budget: u32) -> Descent<T, N> {
        let mut here = self.evaluate(chain, residual, start);
        let only_tool = self.active::<N>().next().is_none();
        let mut length = None;
        let mut unproductive = 0;
        for iteration in 0..budget {
            if only_tool && residual.converged(&here.error) {
                return done(here.q, here.error, iteration, DescentEnd::Converged);
            }
            let g = self.gradient(chain, residual, &here);
            let g2 = g.norm_squared();
            if !(g2 > T::zero() && g2.finite()) {
                return finish(residual, &here, iteration, DescentEnd::Stalled);
            }
            // First trial: where the linear model reaches zero objective; later, double the last.
            let mut s = length.map_or(here.objective / g2, |l: T| l * T::of(2.0));
            let mut accepted = None;
            for _ in 0..HALVINGS {
                let trial = self.evaluate(chain, residual, chain.step(&here.q, &(g * -s)));
                let moved = displacement(chain, &here.q, &trial.q);
                let predicted = g.dot(&moved);
                if trial.objective < here.objective && trial.objective <= here.objective + predicted * T::of(ARMIJO) {
                    accepted = Some(trial);
                    break;
                }
                s *= T::of(0.5);
            }
            let Some(next) = accepted else {
                return finish(residual, &here, iteration + 1, DescentEnd::Stalled);
            };
            length = Some(s);
            let slow = next.objective > here.objective * (T::one() - T::of(SLOW));
            unproductive = if slow { unproductive + 1 } else { 0 };
            here = next;
            if unproductive >= PATIENCE {
                return finish(residual, &here, iteration + 1, DescentEnd::Stalled);
            }
        }
        finish(residual, &here, budget, DescentEnd::OutOfBudget)
    }
}

impl<T: Real> GradientDescent<'_, T> {
    /// The handles that take part: frame in range and finite coordinates.
    fn active<const N: usize>(&self) -> impl Iterator<Item = &Handle<T>> {
        self.handles.iter().filter(|h| h.frame <= N && h.point.iter().chain(h.target.iter()).all(|v| v.finite()))
    }

    /// World position of a handle's point.
    fn position<const N: usize>(frames: &Frames<T, N>, h: &Handle<T>) -> Vector3<T> {
        let frame = if h.frame < N { &frames.joints[h.frame] } else { &frames.tool };
        frame.rotation * h.point + frame.translation
    }

    fn evaluate<const N: usize>(&self, chain: &Chain<T, N>, residual: &Residual<T>, q: SVector<T, N>) -> Point<T, N> {
        let frames = chain.forward(&q);
        let error = residual.error(&frames.tool);
        let mut objective = error.cost;
        for h in self.active::<N>() {
            objective += (Self::position(&frames, h) - h.target).norm_squared() * T::of(0.5);
        }
        Point { q, frames, error, objective }
    }

    /// Gradient of the objective.
    fn gradient<const N: usize>(
        &self,
        chain: &Chain<T, N>,
        residual: &Residual<T>,
        here: &Point<T, N>,
    ) -> SVector<T, N> {
        let (j, e) = residual.task::<6, N>(chain, &here.frames, &here.error);
        let mut g = -(j.transpose() * e);
        for h in self.active::<N>() {
            let p = Self::position(&here.frames, h);
            // A point on joint k's frame moves with joints 0..=k; one on the tool with all of them.
            let jp = chain.point_jacobian(&here.frames, (h.frame + 1).min(N), &p);
            g += jp.fixed_rows::<3>(0).transpose() * (p - h.target);
        }
        g
    }
}

/// The joint motion from `from` to `to` as a step: the angular difference wrapped to (-pi, pi] for
/// rotary joints (a whole-turn shift by normalisation is no motion), the plain difference for
/// prismatic ones (a clamped step moves less than asked).
fn displacement<T: Real, const N: usize>(
    chain: &Chain<T, N>,
    from: &SVector<T, N>,
    to: &SVector<T, N>,
) -> SVector<T, N> {
    SVector::from_fn(|i, _| match chain.joints()[i].kind {
        JointKind::Prismatic | JointKind::Fixed => to[i] - from[i],
        JointKind::Revolute | JointKind::Continuous => wrap_angle(to[i] - from[i]),
    })
}

fn finish<T: Real, const N: usize>(
    residual: &Residual<T>,
    here: &Point<T, N>,
    iterations: u32,
    otherwise: DescentEnd,
) -> Descent<T, N> {
    let end = if residual.converged(&here.error) { DescentEnd::Converged } else { otherwise };
    done(here.q, here.error, iterations, end)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ik::{IkConfig, IkProblem, IkStatus, Target};
    use crate::{presets, SplitMix64};

    #[test]
    fn default_is_tool_target_only_and_converges_on_planar() {
        let chain = presets::planar::<f64, 3>().unwrap();
        let config = IkConfig { attempt_iterations: 2000, max_iterations: 20_000, ..IkConfig::default() };
        let mut rng = SplitMix64::new(17);
        let mut solved = 0;
        while solved < 20 {
            let goal = chain.random_configuration(&mut rng);
            let point = chain.tool_pose(&goal).translation;
            // Near full stretch the cost is ill-conditioned (the folding direction has curvature of
            // the order of the bend squared) and steepest descent needs tens of thousands of
            // iterations: a target 2.995 m out of 3 was still 5e-4 m away after 20 000 (ten
            // attempts). Inside 90% of the reach it converges, in 10 to 143 iterations here.
            if point.norm() > 2.7 {
                continue;
            }
            solved += 1;
            let target = Target::Position(point);
            let problem = IkProblem { target, seed: chain.middle(), config };
            let s = chain.solve_with(&GradientDescent::default(), &problem);
            assert_eq!(s.status, IkStatus::Converged, "{s:?}");
            assert_eq!(chain.solve_with(&GradientDescent::new(&[]), &problem), s);
        }
    }

    #[test]
    fn ur5e_position_targets_converge_within_limits() {
        let chain = presets::ur5e::<f64>().unwrap();
        let config = IkConfig { attempt_iterations: 2000, max_iterations: 20_000, ..IkConfig::default() };
        let mut rng = SplitMix64::new(19);
        let mut converged = 0;
        for _ in 0..20 {
            let goal = chain.random_configuration(&mut rng);
            let target = Target::Position(chain.tool_pose(&goal).translation);
            let s = chain.solve_with(&GradientDescent::default(), &IkProblem { target, seed: chain.middle(), config });
            assert!(chain.admits(&s.q));
            converged += usize::from(s.status == IkStatus::Converged);
        }
        assert!(converged >= 19, "{converged}/20");
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let chain = presets::ur5e::<f64>().unwrap();
        let goal = chain.tool_pose(&SVector::from([0.3, -1.2, 1.0, -0.5, 1.1, 0.2]));
        let residual = Residual::new(Target::Pose(goal), &IkConfig { orientation_weight: 0.3, ..IkConfig::default() });
        let handles = [
            Handle { frame: 2, point: Vector3::new(0.1, -0.2, 0.05), target: Vector3::new(0.2, 0.1, 0.5) },
            Handle { frame: 6, point: Vector3::new(0.0, 0.0, 0.1), target: Vector3::new(-0.3, 0.2, 0.4) },
            Handle { frame: 0, point: Vector3::zeros(), target: Vector3::new(0.0, 0.0, 1.0) },
        ];
        let method = GradientDescent::new(&handles);
        let q = SVector::from([0.1, -0.9, 0.7, 0.2, 0.8, -0.4]);
        let g = method.gradient(&chain, &residual, &method.evaluate(&chain, &residual, q));
        let h = 1e-6;
        for i in 0..6 {
            let mut dq = SVector::<f64, 6>::zeros();
            dq[i] = h;
            let f = |q| method.evaluate(&chain, &residual, q).objective;
            let numeric = (f(q + dq) - f(q - dq)) / (2.0 * h);
            assert!((numeric - g[i]).abs() <= 1e-6 * (1.0 + numeric.abs()), "{i}: {numeric} vs {}", g[i]);
        }
    }

    #[test]
    fn two_handles_pull_the_elbow_and_the_tool() {
        // planar:3 has a one-parameter family of solutions for a tool point; a handle on the elbow
        // (the origin of joint 2's frame) picks one. Both targets come from one configuration, so
        // both can be met together.
        let chain = presets::planar::<f64, 3>().unwrap();
        let pose = SVector::from([0.9, -1.3, 1.6]);
        let frames = chain.forward(&pose);
        let elbow = frames.joints[2].translation;
        let tool = frames.tool.translation;
        let handles = [
            Handle { frame: 2, point: Vector3::zeros(), target: elbow },
            Handle { frame: 3, point: Vector3::zeros(), target: tool },
        ];
        let start = SVector::from([-0.4, 0.5, 0.3]);
        let residual = Residual::new(Target::Position(tool), &IkConfig::default());
        let distances = |q: &SVector<f64, 3>| {
            let f = chain.forward(q);
            ((f.joints[2].translation - elbow).norm(), (f.tool.translation - tool).norm())
        };
        let before = distances(&start);
        assert!(before.0 > 0.5 && before.1 > 0.5);

        let d = GradientDescent::new(&handles).descend(&chain, &residual, start, 5000);
        let after = distances(&d.q);
        assert!(after.0 <= 1e-4 && after.1 <= 1e-4, "{before:?} -> {after:?}");
        assert_eq!(d.end, DescentEnd::Converged);
        assert!(chain.admits(&d.q));

        // Without the elbow handle the tool still arrives but the elbow lands elsewhere.
        let plain = GradientDescent::default().descend(&chain, &residual, start, 5000);
        let plain = distances(&plain.q);
        assert!(plain.1 <= 1e-4 && plain.0 > 0.1, "{plain:?}");
    }

    #[test]
    fn conflicting_handle_stops_short_and_says_so() {
        // The elbow pulled far away from where the tool target allows: the objective's minimum
        // leaves the tool short of its target, which must not be reported as converged.
        let chain = presets::planar::<f64, 3>().unwrap();
        let residual = Residual::new(Target::Position(Vector3::new(1.0, 1.0, 0.0)), &IkConfig::default());
        let handles = [Handle { frame: 1, point: Vector3::zeros(), target: Vector3::new(-3.0, -3.0, 0.0) }];
        let d = GradientDescent::new(&handles).descend(&chain, &residual, SVector::from([0.2, 0.3, 0.4]), 5000);
        assert_eq!(d.end, DescentEnd::Stalled);
        assert!(d.error.position > 0.1 && chain.admits(&d.q), "{d:?}");
    }

    #[test]
    fn bad_handles_are_ignored_and_nothing_panics() {
        let chain = presets::ur5e::<f32>().unwrap();
        let residual = Residual::new(Target::Position(Vector3::new(0.3f32, 0.2, 0.4)), &IkConfig::default());
        let handles = [
            Handle { frame: 99, point: Vector3::zeros(), target: Vector3::zeros() },
            Handle { frame: 1, point: Vector3::new(f32::NAN, 0.0, 0.0), target: Vector3::zeros() },
        ];
        let with = GradientDescent::new(&handles).descend(&chain, &residual, chain.middle(), 300);
        let without = GradientDescent::default().descend(&chain, &residual, chain.middle(), 300);
        assert_eq!((with.q, with.iterations, with.end), (without.q, without.iterations, without.end));
        assert!(chain.admits(&with.q) && with.error.cost.is_finite());
    }
}
