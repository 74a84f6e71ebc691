//! Cartesian tracking for the control tick: every tick the goal moves a little, and the joint
//! values that reached the previous goal are the best seed for the next one. The tick must finish
//! on time, so the solve has a fixed iteration budget and never restarts; if the budget runs out
//! the closest joint values found are used and the next tick continues from them.

use kinematics::ik::{IkConfig, IkProblem, IkSolution, IkStatus, Target};
use kinematics::nalgebra::SVector;
use kinematics::{Chain, Real};

/// Warm-started IK state across control ticks.
#[derive(Clone, Copy, Debug)]
pub struct Tracker<T: Real, const N: usize> {
    /// Joint values of the last tick (the next seed).
    pub q: SVector<T, N>,
    config: IkConfig<T>,
}

impl<T: Real, const N: usize> Tracker<T, N> {
    /// A tracker starting at `q`, with at most `iterations_per_tick` solver iterations per tick.
    pub fn new(q: SVector<T, N>, iterations_per_tick: u32) -> Self {
        let config = IkConfig {
            max_iterations: iterations_per_tick,
            attempt_iterations: iterations_per_tick,
            max_restarts: 0,
            ..IkConfig::default()
        };
        Self { q, config }
    }

    /// One tick toward `target`. The joint values move only to what the solver returns (always
    /// within limits); on invalid input (NaN target) they stay where they are.
    pub fn step(&mut self, chain: &Chain<T, N>, target: Target<T>) -> IkSolution<T, N> {
        let solution = chain.solve(&IkProblem { target, seed: self.q, config: self.config });
        if !matches!(solution.status, IkStatus::InvalidInput(_)) {
            self.q = solution.q;
        }
        solution
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builtin;
    use kinematics::nalgebra::Vector3;

    /// The tool follows a 10 cm line in 2 mm steps at 4 iterations per tick; every tick converges
    /// to 0.1 mm and most need no more than two iterations.
    #[test]
    fn follows_a_line_in_few_iterations_per_tick() {
        let arm = builtin::arm().unwrap();
        let start = SVector::<f32, 5>::from([0.1, -0.4, 0.6, 0.8, 0.0]);
        let mut tracker = Tracker::new(start, 4);
        let p0 = arm.tool_pose(&start).translation;
        let mut iterations = [0u32; 5];
        for step in 1..=50 {
            let target = p0 + Vector3::new(0.0, 0.002, -0.001) * step as f32;
            let s = tracker.step(&arm, Target::Position(target));
            assert_eq!(s.status, IkStatus::Converged, "tick {step}: {s:?}");
            assert!(s.position_error <= 1e-4);
            iterations[s.iterations as usize] += 1;
        }
        assert!(iterations[0] + iterations[1] + iterations[2] >= 45, "iteration histogram {iterations:?}");
    }

    #[test]
    fn a_nan_target_leaves_the_joints_alone() {
        let arm = builtin::arm().unwrap();
        let start = SVector::<f32, 5>::from([0.1, -0.4, 0.6, 0.8, 0.0]);
        let mut tracker = Tracker::new(start, 4);
        let s = tracker.step(&arm, Target::Position(Vector3::new(f32::NAN, 0.0, 0.1)));
        assert!(matches!(s.status, IkStatus::InvalidInput(_)));
        assert_eq!(tracker.q, start);
    }
}
