//! Kinematic trees: joints with parents, several end effectors, forward kinematics of every frame
//! in one pass, each end effector's geometric Jacobian (zero columns for the joints that do not
//! move it), and damped least-squares IK over every target at once.
//!
//! A tree of `N` joints is held in topological order: each joint's parent is an earlier joint, or
//! the root (the base frame). `E` end effectors each sit on a joint (or on the root) at a fixed
//! offset. A joint shared by several end effectors (a torso under two arms) moves all of them, and
//! the IK weighs every target through it. A serial chain is the one-leaf case; the chain's own
//! solvers ([`crate::Chain`]) stay as they are, so their figures do not change.
//!
//! Fixed capacity, no heap, no panics: the same rules as the chain. The board's `opcount` binary
//! links the tree's f32 FK, Jacobians and IK for the Cortex-M4F and fails to link if any of it
//! can reach a panic.

use nalgebra::{SMatrix, SVector, Vector3};

use crate::chain::{checked, frame_is_valid};
use crate::fk::write_column;
use crate::ik::IkConfig;
use crate::linalg::cholesky_solve;
use crate::{rotation_error, ChainError, Joint, JointKind, Pose, Real};

/// The least damping of a second-priority step.
const SECOND_DAMPING: f64 = 0.1;
/// The damping of the null-space projector of the first priority.
const PROJECTOR_DAMPING: f64 = 1e-4;

/// Why a tree description was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TreeError {
    /// A joint as a chain would reject it.
    Joint(ChainError),
    /// Joint `joint`'s parent is not an earlier joint (the order must be topological).
    Parent {
        /// Index of the joint.
        joint: usize,
    },
    /// End effector `effector` sits on a joint that does not exist, or its offset is not a frame.
    Effector {
        /// Index of the end effector.
        effector: usize,
    },
}

impl core::fmt::Display for TreeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            TreeError::Joint(e) => write!(f, "{e}"),
            TreeError::Parent { joint } => write!(f, "joint {joint}'s parent is not an earlier joint"),
            TreeError::Effector { effector } => {
                write!(f, "end effector {effector} is on no joint of the tree, or its offset is not a frame")
            }
        }
    }
}

/// Where an end effector sits: on a joint's moving frame (or the root's, `None`), at an offset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Effector<T: Real> {
    /// The joint it is fixed to, or `None` for the root.
    pub joint: Option<usize>,
    /// Its frame relative to that joint's moving frame.
    pub offset: Pose<T>,
}

/// A validated tree of `N` joints and `E` end effectors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tree<T: Real, const N: usize, const E: usize> {
    joints: [Joint<T>; N],
    parents: [Option<usize>; N],
    effectors: [Effector<T>; E],
    /// `moves[e][k]`: joint `k` is on the path from the root to end effector `e`.
    moves: [[bool; N]; E],
}

/// World poses of every joint frame (after its motion) and every end effector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TreeFrames<T: Real, const N: usize, const E: usize> {
    /// Frame of joint k after its motion, in the base frame.
    pub joints: [Pose<T>; N],
    /// End effector frames in the base frame.
    pub effectors: [Pose<T>; E],
}

impl<T: Real, const N: usize, const E: usize> Tree<T, N, E> {
    /// Builds a tree: joint `k`'s origin is relative to its parent's moving frame (`parents[k]`,
    /// an earlier joint, or `None` for the root); axes are normalised.
    pub fn new(
        joints: [Joint<T>; N],
        parents: [Option<usize>; N],
        effectors: [Effector<T>; E],
    ) -> Result<Self, TreeError> {
        let mut checked_joints = joints;
        for (k, (slot, parent)) in checked_joints.iter_mut().zip(parents.iter()).enumerate() {
            *slot = checked(*slot, k).map_err(TreeError::Joint)?;
            if parent.is_some_and(|p| p >= k) {
                return Err(TreeError::Parent { joint: k });
            }
        }
        let mut moves = [[false; N]; E];
        for (e, (effector, path)) in effectors.iter().zip(moves.iter_mut()).enumerate() {
            if effector.joint.is_some_and(|j| j >= N) || !frame_is_valid(&effector.offset) {
                return Err(TreeError::Effector { effector: e });
            }
            // Up the parents from the end effector's joint; each step goes to a lower index, so
            // this ends within N steps. (`get` rather than indexing: the indices were checked
            // above, which the compiler cannot follow, and the MCU build keeps no panic path.)
            let mut at = effector.joint;
            while let Some(k) = at {
                let (Some(on_path), Some(&parent)) = (path.get_mut(k), parents.get(k)) else { break };
                *on_path = true;
                at = parent;
            }
        }
        Ok(Self { joints: checked_joints, parents, effectors, moves })
    }

    /// The joints, in topological order.
    pub fn joints(&self) -> &[Joint<T>; N] {
        &self.joints
    }

    /// Each joint's parent (`None`: the root).
    pub fn parents(&self) -> &[Option<usize>; N] {
        &self.parents
    }

    /// The end effectors.
    pub fn effectors(&self) -> &[Effector<T>; E] {
        &self.effectors
    }

    /// Whether joint `k` moves end effector `e` (it is on the path from the root to it).
    pub fn moves(&self, e: usize, k: usize) -> bool {
        self.moves.get(e).and_then(|p| p.get(k)).copied().unwrap_or(false)
    }

    /// The middle of every joint's range.
    pub fn middle(&self) -> SVector<T, N> {
        SVector::from_fn(|k, _| self.joints[k].limits.middle())
    }

    /// True if every value is admissible for its joint.
    pub fn admits(&self, q: &SVector<T, N>) -> bool {
        self.joints.iter().zip(q.iter()).all(|(j, &v)| j.admits(v))
    }

    /// Forward kinematics of every joint frame and end effector, in one pass from the root.
    pub fn forward(&self, q: &SVector<T, N>) -> TreeFrames<T, N, E> {
        // The parents and the end effectors' joints are looked up with `get`: `new` checked them,
        // which the compiler cannot follow, so indexing would keep a panic path.
        let mut joints = [Pose::identity(); N];
        for k in 0..N {
            let joint = &self.joints[k];
            let local = joint.origin.compose(&joint.motion(q[k]));
            joints[k] = match self.parents[k].and_then(|p| joints.get(p)) {
                Some(parent) => parent.compose(&local),
                None => local,
            };
        }
        let effectors = core::array::from_fn(|e| {
            let effector = &self.effectors[e];
            match effector.joint.and_then(|k| joints.get(k)) {
                Some(frame) => frame.compose(&effector.offset),
                None => effector.offset,
            }
        });
        TreeFrames { joints, effectors }
    }

    /// End effector `e`'s geometric Jacobian (rows linear x, y, z then angular x, y, z, base
    /// frame), zero in the columns of the joints that do not move it.
    pub fn jacobian_of(&self, frames: &TreeFrames<T, N, E>, e: usize) -> SMatrix<T, 6, N> {
        let mut j = SMatrix::<T, 6, N>::zeros();
        let Some(point) = frames.effectors.get(e).map(|p| p.translation) else { return j };
        for k in 0..N {
            if self.moves(e, k) {
                write_column(&mut j, k, &self.joints[k], &frames.joints[k], &point);
            }
        }
        j
    }

    /// Every end effector's Jacobian at `q` (the blocks of the stacked Jacobian).
    pub fn jacobians(&self, q: &SVector<T, N>) -> [SMatrix<T, 6, N>; E] {
        let frames = self.forward(q);
        core::array::from_fn(|e| self.jacobian_of(&frames, e))
    }
}

/// What one end effector should reach.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EffectorTarget<T: Real> {
    /// Position, m, base frame.
    pub position: Vector3<T>,
    /// Orientation (rotation matrix, base frame), or `None` for a position only.
    pub rotation: Option<nalgebra::Matrix3<T>>,
    /// Its weight against the other targets of its priority (> 0).
    pub weight: T,
    /// 0 for the first priority; 1 for a target met only in the null space of the first ones
    /// (the joints they leave free), as far as it can be without disturbing them.
    pub priority: u8,
}

/// The targets of a tree IK problem: one per end effector, `None` where it is free.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TreeProblem<T: Real, const N: usize, const E: usize> {
    /// Per end effector.
    pub targets: [Option<EffectorTarget<T>>; E],
    /// Where the search starts.
    pub seed: SVector<T, N>,
    /// Tolerances, the weight of orientation errors, the iteration budget (over every attempt and
    /// per attempt) and the restarts, as the chain's solvers take them.
    pub config: IkConfig<T>,
}

/// How one end effector came out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EffectorOutcome<T: Real> {
    /// Within both tolerances (checked by forward kinematics on the answer), or no target.
    pub reached: bool,
    /// Position error, m (0 without a target).
    pub position_error: T,
    /// Orientation error, rad (0 without an orientation target).
    pub orientation_error: T,
}

/// Why the whole problem ended as it did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TreeStatus {
    /// Every target reached, every joint within its limits.
    Converged,
    /// The steps stopped shrinking the error before every target was reached (a target out of
    /// reach, or two that pull apart through a shared joint): the closest found.
    Stalled,
    /// The iteration budget ran out while still approaching.
    IterationLimit,
    /// A target, a weight or the seed was not finite (or a weight not positive): nothing solved.
    InvalidInput,
}

/// The answer of [`Tree::solve`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TreeSolution<T: Real, const N: usize, const E: usize> {
    /// Joint values, within the limits.
    pub q: SVector<T, N>,
    /// Overall.
    pub status: TreeStatus,
    /// Per end effector.
    pub effectors: [EffectorOutcome<T>; E],
    /// Iterations taken, over every attempt.
    pub iterations: u32,
    /// Restarts drawn.
    pub restarts: u32,
}

impl<T: Real, const N: usize, const E: usize> Tree<T, N, E> {
    fn outcomes(&self, problem: &TreeProblem<T, N, E>, frames: &TreeFrames<T, N, E>) -> [EffectorOutcome<T>; E] {
        core::array::from_fn(|e| match problem.targets[e] {
            None => EffectorOutcome { reached: true, position_error: T::zero(), orientation_error: T::zero() },
            Some(t) => {
                let p = (t.position - frames.effectors[e].translation).norm();
                let o = t.rotation.map_or(T::zero(), |r| rotation_error(&r, &frames.effectors[e].rotation).norm());
                EffectorOutcome {
                    reached: p <= problem.config.position_tolerance && o <= problem.config.orientation_tolerance,
                    position_error: p,
                    orientation_error: o,
                }
            }
        })
    }

    /// The weighted squared error of the first priority's targets and of the second's.
    fn cost(&self, problem: &TreeProblem<T, N, E>, frames: &TreeFrames<T, N, E>) -> (T, T) {
        let w2 = problem.config.orientation_weight * problem.config.orientation_weight;
        let mut cost = (T::zero(), T::zero());
        for (o, t) in self.outcomes(problem, frames).iter().zip(problem.targets.iter()) {
            let Some(t) = t else { continue };
            let c = t.weight * (o.position_error * o.position_error + w2 * o.orientation_error * o.orientation_error);
            if t.priority == 0 {
                cost.0 += c;
            } else {
                cost.1 += c;
            }
        }
        cost
    }

    /// Whether every target of the first priority is reached.
    fn first_reached(&self, problem: &TreeProblem<T, N, E>, frames: &TreeFrames<T, N, E>) -> bool {
        let outcomes = self.outcomes(problem, frames);
        problem.targets.iter().zip(outcomes.iter()).all(|(t, o)| t.is_none_or(|t| t.priority != 0) || o.reached)
    }

    /// Whether an answer of error `now` is better than one of `before`: the first priority's
    /// error lower, or the second's lower with the first priority's targets still reached.
    fn better(&self, now: (T, T), before: (T, T), first_reached: bool) -> bool {
        now.0 < before.0 || (first_reached && now.1 < before.1)
    }

    fn valid(&self, problem: &TreeProblem<T, N, E>) -> bool {
        let finite = |v: &Vector3<T>| v.iter().all(|x| x.finite());
        problem.seed.iter().all(|x| x.finite())
            && problem.targets.iter().flatten().all(|t| {
                finite(&t.position)
                    && t.weight.finite()
                    && t.weight > T::zero()
                    && t.rotation.is_none_or(|r| r.iter().all(|x| x.finite()))
                    && t.priority <= 1
            })
            && problem.config.position_tolerance > T::zero()
            && problem.config.orientation_tolerance > T::zero()
            && problem.config.orientation_weight > T::zero()
    }

    /// Damped least squares over every target at once (Levenberg-Marquardt: the damping halves
    /// after a step that lowers the weighted error and grows tenfold after one that does not),
    /// each step brought into the joint limits, from the seed and then from random seeds while
    /// a target is missed and the budget lasts. Shared joints serve every end effector below
    /// them, weighed by the targets' weights. The status per end effector is checked by forward
    /// kinematics on the answer, never assumed.
    pub fn solve(&self, problem: &TreeProblem<T, N, E>) -> TreeSolution<T, N, E> {
        let mut q = problem.seed;
        for (k, v) in q.iter_mut().enumerate() {
            *v = self.joints[k].normalise(*v);
        }
        if !self.valid(problem) {
            let frames = self.forward(&q);
            let effectors = self.outcomes(problem, &frames).map(|o| EffectorOutcome { reached: false, ..o });
            return TreeSolution { q, status: TreeStatus::InvalidInput, effectors, iterations: 0, restarts: 0 };
        }
        let mut rng = crate::SplitMix64::new(problem.config.rng_seed);
        let mut iterations = 0;
        let mut restarts = 0;
        let (mut best_q, mut best_cost, mut ran_out) = self.attempt(problem, q, &mut iterations);
        while !self.reached(problem, &best_q)
            && restarts < problem.config.max_restarts
            && iterations < problem.config.max_iterations
        {
            restarts += 1;
            let seed = SVector::from_fn(|k, _| {
                let l = self.joints[k].limits;
                rng.uniform(l.lower, l.upper)
            });
            let (q, cost, out) = self.attempt(problem, seed, &mut iterations);
            // The better answer reaches more targets; among those reaching as many, the one with
            // the smaller weighted error (a target out of reach must not cost the others theirs).
            let (now, before) = (self.reached_count(problem, &q), self.reached_count(problem, &best_q));
            let first = self.first_reached(problem, &self.forward(&q));
            if now > before || (now == before && self.better(cost, best_cost, first)) {
                (best_q, best_cost, ran_out) = (q, cost, out);
            }
        }
        let effectors = self.outcomes(problem, &self.forward(&best_q));
        let status = if effectors.iter().all(|o| o.reached) && self.admits(&best_q) {
            TreeStatus::Converged
        } else if ran_out {
            TreeStatus::IterationLimit
        } else {
            TreeStatus::Stalled
        };
        TreeSolution { q: best_q, status, effectors, iterations, restarts }
    }

    fn reached(&self, problem: &TreeProblem<T, N, E>, q: &SVector<T, N>) -> bool {
        self.reached_count(problem, q) == E
    }

    fn reached_count(&self, problem: &TreeProblem<T, N, E>, q: &SVector<T, N>) -> usize {
        self.outcomes(problem, &self.forward(q)).iter().filter(|o| o.reached).count()
    }

    /// The normal equations of the targets of `priority`: the sum of `J^T W J` and `J^T W r`.
    fn normal_equations(
        &self,
        problem: &TreeProblem<T, N, E>,
        frames: &TreeFrames<T, N, E>,
        priority: u8,
    ) -> (SMatrix<T, N, N>, SVector<T, N>, bool) {
        let w_o = problem.config.orientation_weight;
        let mut a = SMatrix::<T, N, N>::zeros();
        let mut b = SVector::<T, N>::zeros();
        let mut any = false;
        for (e, (target, pose)) in problem.targets.iter().zip(frames.effectors.iter()).enumerate() {
            let Some(t) = target.filter(|t| t.priority == priority) else { continue };
            any = true;
            let mut jw = self.jacobian_of(frames, e);
            let mut r = SVector::<T, 6>::zeros();
            r.fixed_rows_mut::<3>(0).copy_from(&(t.position - pose.translation));
            match t.rotation {
                Some(rot) => {
                    r.fixed_rows_mut::<3>(3).copy_from(&(rotation_error(&rot, &pose.rotation) * w_o));
                    let mut angular = jw.fixed_rows_mut::<3>(3);
                    angular *= w_o;
                }
                None => jw.fixed_rows_mut::<3>(3).fill(T::zero()),
            }
            a += jw.transpose() * jw * t.weight;
            b += jw.transpose() * r * t.weight;
        }
        (a, b, any)
    }

    /// A joint at a limit that `dq` pushes further out takes no part (its clamp would undo its
    /// share of the step and spoil the others'): its row and column of `damped` and its entry of
    /// `b` are set aside. Returns whether any was.
    fn set_aside_blocked(
        &self,
        q: &SVector<T, N>,
        dq: &SVector<T, N>,
        damped: &mut SMatrix<T, N, N>,
        b: &mut SVector<T, N>,
    ) -> bool {
        let mut blocked = false;
        for k in 0..N {
            let (joint, v) = (&self.joints[k], q[k]);
            let at_lower = v <= joint.limits.lower && dq[k] < T::zero();
            let at_upper = v >= joint.limits.upper && dq[k] > T::zero();
            if joint.kind != JointKind::Continuous && (at_lower || at_upper) {
                blocked = true;
                for i in 0..N {
                    damped[(k, i)] = T::zero();
                    damped[(i, k)] = T::zero();
                }
                damped[(k, k)] = T::one();
                b[k] = T::zero();
            }
        }
        blocked
    }

    /// One damped step: toward the first priority's targets, then toward the second's within
    /// the null space the first leave (the damped projector `I - (A1 + l^2 I)^-1 A1`).
    fn step(
        &self,
        problem: &TreeProblem<T, N, E>,
        frames: &TreeFrames<T, N, E>,
        q: &SVector<T, N>,
        lambda: T,
    ) -> Option<SVector<T, N>> {
        let damping = SMatrix::<T, N, N>::identity() * (lambda * lambda);
        let (a1, mut b1, _) = self.normal_equations(problem, frames, 0);
        let mut damped = a1 + damping;
        let mut dq1 = cholesky_solve(&damped, &b1)?;
        if self.set_aside_blocked(q, &dq1, &mut damped, &mut b1) {
            dq1 = cholesky_solve(&damped, &b1)?;
        }
        let (a2, b2, second) = self.normal_equations(problem, frames, 1);
        // One constraint at a time: the second priority moves once the first is met.
        if !second || !self.first_reached(problem, frames) {
            return Some(dq1);
        }
        // The projector onto what the first priority leaves free, column by column, damped only
        // enough to stay defined: P = I - (A1 + d^2 I)^-1 A1. (The step's own damping would let
        // the first priority's directions leak into it.)
        let mut held = a1 + SMatrix::<T, N, N>::identity() * T::of(PROJECTOR_DAMPING * PROJECTOR_DAMPING);
        let mut unused = b1;
        self.set_aside_blocked(q, &dq1, &mut held, &mut unused);
        let mut projector = SMatrix::<T, N, N>::identity();
        for c in 0..N {
            // Entry by entry: nalgebra's `into_owned` of a column view keeps a panic path.
            let column = cholesky_solve(&held, &SVector::from_fn(|r, _| a1[(r, c)]))?;
            let mut target = projector.column_mut(c);
            target -= &column;
        }
        // The second priority's residual after the first step, through the projector:
        // minimise |J2 (dq1 + P y) - r2|^2, i.e. (P^T A2 P + l^2 I) y = P^T (b2 - A2 dq1).
        // Damped more than the first (at least SECOND_DAMPING): directions the first priority
        // holds are only nearly absent from the projector, and a second target far out of reach
        // would otherwise push through what is left of them.
        let rhs = projector.transpose() * (b2 - a2 * dq1);
        let second_damping = lambda.max(T::of(SECOND_DAMPING));
        let lhs =
            projector.transpose() * a2 * projector + SMatrix::<T, N, N>::identity() * (second_damping * second_damping);
        let y = cholesky_solve(&lhs, &rhs)?;
        Some(dq1 + projector * y)
    }

    /// One descent from `seed`, counting its iterations into `iterations`; returns the answer, its
    /// weighted errors (first priority, second), and whether the budget ran out while it was still approaching.
    fn attempt(
        &self,
        problem: &TreeProblem<T, N, E>,
        seed: SVector<T, N>,
        iterations: &mut u32,
    ) -> (SVector<T, N>, (T, T), bool) {
        let mut q = seed;
        let mut frames = self.forward(&q);
        let mut cost = self.cost(problem, &frames);
        let mut lambda = T::of(1e-2);
        let mut own = 0u32;
        loop {
            if self.outcomes(problem, &frames).iter().all(|o| o.reached) {
                return (q, cost, false);
            }
            if *iterations >= problem.config.max_iterations {
                return (q, cost, true);
            }
            if own >= problem.config.attempt_iterations {
                return (q, cost, false);
            }
            *iterations += 1;
            own += 1;
            let Some(dq) = self.step(problem, &frames, &q, lambda) else {
                if lambda >= T::of(1e3) {
                    return (q, cost, false);
                }
                lambda = (lambda * T::of(10.0)).min(T::of(1e3));
                continue;
            };
            let mut next = q + dq;
            for (k, v) in next.iter_mut().enumerate() {
                *v = self.joints[k].normalise(*v);
            }
            let next_frames = self.forward(&next);
            let better = self
                .better(self.cost(problem, &next_frames), cost, self.first_reached(problem, &next_frames))
                .then_some((next, next_frames));
            match better {
                Some((n, f)) => {
                    let moved = (n - q).amax();
                    q = n;
                    frames = f;
                    cost = self.cost(problem, &frames);
                    lambda = (lambda * T::of(0.5)).max(T::of(1e-6));
                    // Steps this small change nothing more: a local minimum (or a target out of
                    // reach, the others reached as well as they can be).
                    if moved <= T::of(1e-9) {
                        return (q, cost, false);
                    }
                }
                // No step lowers the error even when damped to a crawl: stalled.
                None if lambda >= T::of(1e3) => return (q, cost, false),
                None => lambda = (lambda * T::of(10.0)).min(T::of(1e3)),
            }
        }
    }
}
