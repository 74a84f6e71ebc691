//! Closed-form inverse kinematics, chosen from the chain's geometry rather than from an arm's name.
//!
//! [`ClosedForm::of`] looks for one of three shapes in the axes (with the tolerances of
//! [`geometry`]): a [`Shape::SphericalWrist`] (PUMA 560 and most industrial arms), three parallel
//! axes after the base ([`Shape::ThreeParallel`], the UR family) and the hobby arm's base yaw and
//! pitch joints ([`Shape::YawPitch`]: SO-101, OpenManipulator-X). Where it finds one, every
//! solution comes at once from the subproblems of Paden and Kahan; each is fitted into the joint
//! limits nearest the seed (whole turns), checked by forward kinematics on the chain itself and,
//! where the chain only nearly has the shape, polished by a few damped least-squares iterations.
//! [`Chain::solve_auto`] takes the solution nearest the seed and falls back to the numerical
//! solver where there is no shape, no solution within the limits, or none that reaches.

pub mod geometry;
mod spherical_wrist;
pub mod subproblems;
mod three_parallel;
mod yaw_pitch;

use super::{DampedLeastSquares, IkMethod, IkProblem, IkSolution, IkStatus, Residual, Target};
use crate::{wrap_angle, Chain, JointKind, Real};
use geometry::Axes;
use nalgebra::SVector;
use spherical_wrist::SphericalWrist;
use three_parallel::ThreeParallel;
use yaw_pitch::YawPitch;

/// The most solutions any of the shapes has.
pub const MAX_SOLUTIONS: usize = 8;

/// Iterations of damped least squares that polish an answer of a chain that only nearly has its
/// shape (within the tolerances of [`geometry`]); a chain that has it exactly needs none.
const POLISH_ITERATIONS: u32 = 20;

/// The shapes with a closed form.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    /// Six joints; the last three axes meet in a point, the second and third are parallel.
    SphericalWrist,
    /// Six joints; axes 2, 3 and 4 are parallel, axes 5 and 6 meet.
    ThreeParallel,
    /// Four or five joints: a base yaw, three parallel pitch axes, then perhaps a roll.
    YawPitch,
}

impl Shape {
    /// The name used in text formats.
    pub fn as_str(&self) -> &'static str {
        match self {
            Shape::SphericalWrist => "spherical_wrist",
            Shape::ThreeParallel => "three_parallel",
            Shape::YawPitch => "yaw_pitch",
        }
    }

    /// True if the shape answers a position target too (not only a full pose).
    pub fn answers_position(&self) -> bool {
        *self == Shape::YawPitch
    }
}

/// Where a solution sits at a singularity, leaving an angle free (filled from the seed) or two
/// solutions coinciding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Singularity {
    /// The target (or wrist centre) on the first axis: the base angle is free.
    Shoulder,
    /// The arm fully stretched or folded: the elbow's two solutions are one.
    Elbow,
    /// Two wrist axes lined up: only the sum of their angles is defined.
    Wrist,
}

impl Singularity {
    /// The name used in text formats.
    pub fn as_str(&self) -> &'static str {
        match self {
            Singularity::Shoulder => "shoulder",
            Singularity::Elbow => "elbow",
            Singularity::Wrist => "wrist",
        }
    }
}

/// The raw solutions of a shape: up to [`MAX_SOLUTIONS`] joint vectors (six slots; a shorter
/// chain uses the first N), each marked exact or least squares, and singular or not.
#[derive(Clone, Copy, Debug)]
pub struct Candidates<T: Real> {
    q: [[T; 6]; MAX_SOLUTIONS],
    exact: [bool; MAX_SOLUTIONS],
    singular: [Option<Singularity>; MAX_SOLUTIONS],
    len: usize,
}

impl<T: Real> Candidates<T> {
    fn new() -> Self {
        Self {
            q: [[T::zero(); 6]; MAX_SOLUTIONS],
            exact: [false; MAX_SOLUTIONS],
            singular: [None; MAX_SOLUTIONS],
            len: 0,
        }
    }

    fn push(&mut self, q: [T; 6], exact: bool, singular: Option<Singularity>) {
        if let (Some(slot), Some(e), Some(s)) =
            (self.q.get_mut(self.len), self.exact.get_mut(self.len), self.singular.get_mut(self.len))
        {
            (*slot, *e, *s) = (q, exact, singular);
            self.len += 1;
        }
    }

    /// The number of solutions.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True if there are none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Each solution's six slots (a shorter chain's first N), whether it is exact, and its
    /// singularity.
    pub fn iter(&self) -> impl Iterator<Item = (&[T; 6], bool, Option<Singularity>)> {
        self.q.iter().zip(self.exact).zip(self.singular).take(self.len).map(|((q, e), s)| (q, e, s))
    }
}

#[derive(Clone, Copy, Debug)]
enum Solver<T: Real> {
    SphericalWrist(SphericalWrist<T>),
    ThreeParallel(ThreeParallel<T>),
    YawPitch(YawPitch<T>),
}

/// A chain's closed form, found once from its geometry.
#[derive(Clone, Copy, Debug)]
pub struct ClosedForm<T: Real, const N: usize> {
    solver: Solver<T>,
}

/// One closed-form solution, fitted and checked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosedFormSolution<T: Real, const N: usize> {
    /// The joint values: within the limits by whole turns nearest the seed where possible.
    pub q: SVector<T, N>,
    /// True if every value is within its joint's limits.
    pub within_limits: bool,
    /// True if the shape's equations have this solution; false for the least-squares answer of a
    /// branch that cannot reach the target.
    pub exact: bool,
    /// True if forward kinematics at `q` reaches the target within both tolerances.
    pub reaches: bool,
    /// Distance of the tool from the target at `q` (m).
    pub position_error: T,
    /// Rotation angle to the target at `q` (rad); zero for a position target.
    pub orientation_error: T,
    /// The singularity the solution sits at, if any.
    pub singular: Option<Singularity>,
    /// Polishing iterations spent (only where the chain nearly has the shape).
    pub polish_iterations: u32,
}

/// All the solutions of one target.
pub type Solutions<T, const N: usize> = heapless::Vec<ClosedFormSolution<T, N>, MAX_SOLUTIONS>;

impl<T: Real, const N: usize> ClosedForm<T, N> {
    /// The closed form of `chain`, if its geometry has one of the shapes.
    pub fn of(chain: &Chain<T, N>) -> Option<Self> {
        let axes = Axes::of(chain)?;
        let solver = if let Some(s) = SphericalWrist::detect(&axes) {
            Solver::SphericalWrist(s)
        } else if let Some(s) = ThreeParallel::detect(&axes) {
            Solver::ThreeParallel(s)
        } else {
            Solver::YawPitch(YawPitch::detect(&axes)?)
        };
        Some(Self { solver })
    }

    /// The shape found.
    pub fn shape(&self) -> Shape {
        match self.solver {
            Solver::SphericalWrist(_) => Shape::SphericalWrist,
            Solver::ThreeParallel(_) => Shape::ThreeParallel,
            Solver::YawPitch(_) => Shape::YawPitch,
        }
    }

    /// True if the closed form answers this kind of target: a six-joint shape needs the full
    /// pose; the yaw-pitch shape takes a position too. None answers a [`Target::Tilt`] (the yaw
    /// it leaves free moves the tool's offset, a one-dimensional search the closed forms do not
    /// make): [`Chain::solve_auto`] hands it to the numerical solver.
    pub fn answers(&self, target: &Target<T>) -> bool {
        match target {
            Target::Pose(_) => true,
            Target::Position(_) => self.shape().answers_position(),
            Target::Tilt(_) => false,
        }
    }

    /// The shape's own solutions of `problem`, before they are fitted into the limits or checked:
    /// exact for the idealised shape (or least squares, and marked so). Empty for a target this
    /// shape does not answer or an invalid problem.
    pub fn candidates(&self, chain: &Chain<T, N>, problem: &IkProblem<T, N>) -> Candidates<T> {
        let mut raw = Candidates::new();
        if problem.validate().is_err() || !self.answers(&problem.target) {
            return raw;
        }
        let seed: [T; 6] = core::array::from_fn(|i| problem.seed.get(i).copied().unwrap_or_else(T::zero));
        match (&self.solver, &problem.target) {
            (Solver::SphericalWrist(s), Target::Pose(pose)) => s.solve(pose, &seed, &mut raw),
            (Solver::ThreeParallel(s), Target::Pose(pose)) => s.solve(pose, &seed, &mut raw),
            (Solver::YawPitch(s), target) => {
                let cost = |q: &[T; 6]| {
                    let (fitted, within) = fit(chain, q, &problem.seed);
                    within.then(|| distance_from(chain, &fitted, &problem.seed))
                };
                s.solve(target, &seed, &cost, &mut raw);
            }
            _ => {}
        }
        raw
    }

    /// Every solution of `problem` (its seed fills angles a singular pose leaves free), fitted into
    /// the limits nearest the seed and checked by forward kinematics. Empty for a target this
    /// shape does not answer or an invalid problem.
    pub fn solutions(&self, chain: &Chain<T, N>, problem: &IkProblem<T, N>) -> Solutions<T, N> {
        let residual = Residual::new(problem.target, &problem.config);
        checked_all(chain, &residual, &problem.seed, &self.candidates(chain, problem))
    }
}

impl<T: Real, const N: usize> ClosedFormSolution<T, N> {
    /// This solution as the answer to the problem, with `status`.
    fn answer(&self, status: IkStatus) -> IkSolution<T, N> {
        IkSolution {
            q: self.q,
            status,
            iterations: self.polish_iterations,
            restarts: 0,
            position_error: self.position_error,
            orientation_error: self.orientation_error,
        }
    }
}

/// Every candidate of `raw` fitted into the limits nearest `seed` and [`checked`].
fn checked_all<T: Real, const N: usize>(
    chain: &Chain<T, N>,
    residual: &Residual<T>,
    seed: &SVector<T, N>,
    raw: &Candidates<T>,
) -> Solutions<T, N> {
    let mut all = Solutions::new();
    for (q, exact, singular) in raw.iter() {
        let (q, within_limits) = fit(chain, q, seed);
        let _ = all.push(checked(chain, residual, q, within_limits, exact, singular));
    }
    all
}

/// The squared joint-space distance of `q` from `seed` (continuous joints by the shorter way).
fn distance_from<T: Real, const N: usize>(chain: &Chain<T, N>, q: &SVector<T, N>, seed: &SVector<T, N>) -> T {
    q.iter().zip(seed.iter()).zip(chain.joints()).fold(T::zero(), |sum, ((a, b), j)| {
        let d = if j.kind == JointKind::Continuous { wrap_angle(*a - *b) } else { *a - *b };
        sum + d * d
    })
}

/// A fitted solution checked by forward kinematics on the chain, and polished where an exact
/// answer of the idealised shape misses on the chain itself (the chain only nearly has the shape,
/// and the answer is a few iterations from its own).
fn checked<T: Real, const N: usize>(
    chain: &Chain<T, N>,
    residual: &Residual<T>,
    mut q: SVector<T, N>,
    mut within_limits: bool,
    exact: bool,
    singular: Option<Singularity>,
) -> ClosedFormSolution<T, N> {
    let mut error = residual.error(&chain.tool_pose(&q));
    let mut polish_iterations = 0;
    if exact && within_limits && !residual.converged(&error) {
        let polished = DampedLeastSquares.polish(chain, residual, q, POLISH_ITERATIONS);
        polish_iterations = polished.iterations;
        if polished.error.cost < error.cost {
            (q, error) = (polished.q, polished.error);
            within_limits = chain.admits(&q);
        }
    }
    ClosedFormSolution {
        q,
        within_limits,
        exact,
        reaches: residual.converged(&error),
        position_error: error.position,
        orientation_error: error.orientation,
        singular,
        polish_iterations,
    }
}

/// `q` (six slots; the first N used) with each angle moved by whole turns to the value nearest the
/// seed within the joint's limits, continuous joints wrapped; and whether every value is within
/// its limits (within a rounding's width outside, the value is set on the limit).
fn fit<T: Real, const N: usize>(chain: &Chain<T, N>, q: &[T; 6], seed: &SVector<T, N>) -> (SVector<T, N>, bool) {
    let mut within = true;
    let fitted = SVector::from_fn(|i, _| {
        let (joint, value, near) = (&chain.joints()[i], q.get(i).copied().unwrap_or_else(T::zero), seed[i]);
        if joint.kind == JointKind::Continuous {
            return wrap_angle(value);
        }
        let (lower, upper) = (joint.limits.lower, joint.limits.upper);
        let slack = T::EPSILON.sqrt() * T::of(1e-2);
        // The whole-turn shift that brings the value nearest the seed, then the nearest turn
        // either side that is within the limits.
        let base = value + ((near - value) / T::two_pi()).round() * T::two_pi();
        let mut best: Option<T> = None;
        for turns in [0.0, 1.0, -1.0, 2.0, -2.0] {
            let v = base + T::of(turns) * T::two_pi();
            let v = if v < lower && v > lower - slack {
                lower
            } else if v > upper && v < upper + slack {
                upper
            } else {
                v
            };
            if v >= lower && v <= upper && best.is_none_or(|b| (v - near).abs() < (b - near).abs()) {
                best = Some(v);
            }
        }
        best.unwrap_or_else(|| {
            within = false;
            wrap_angle(value)
        })
    });
    (fitted, within)
}

impl<T: Real, const N: usize> Chain<T, N> {
    /// The closed form's solution nearest the seed that is within the limits and reaches the
    /// target ([`IkStatus::Converged`]). Where none does: the candidate within the limits that
    /// comes closest (else the closest of all, fitted as near the limits as whole turns allow),
    /// as [`IkStatus::BestEffort`] with its errors; the seed if the shape gave none (a target it
    /// does not answer). An invalid problem is refused as by [`Chain::solve`].
    pub fn solve_closed_form(&self, closed: &ClosedForm<T, N>, problem: &IkProblem<T, N>) -> IkSolution<T, N> {
        if let Err(reason) = problem.validate() {
            return IkSolution::refused(problem.seed, reason);
        }
        let residual = Residual::new(problem.target, &problem.config);
        // The candidates once (a position target's pitch search is most of their cost), for the
        // reaching answer and, failing it, the closest miss.
        let raw = closed.candidates(self, problem);
        if let Some(solution) = self.nearest_reaching(&raw, &residual, &problem.seed) {
            return solution;
        }
        let all = checked_all(self, &residual, &problem.seed, &raw);
        let weight = problem.config.orientation_weight;
        let miss = |s: &ClosedFormSolution<T, N>| s.position_error + weight * s.orientation_error;
        let nearest = |keep: &dyn Fn(&ClosedFormSolution<T, N>) -> bool,
                       key: &dyn Fn(&ClosedFormSolution<T, N>) -> T| {
            all.iter().filter(|s| keep(s)).fold(None, |best: Option<&ClosedFormSolution<T, N>>, s| match best {
                Some(b) if key(b) <= key(s) => Some(b),
                _ => Some(s),
            })
        };
        // None reaches: the closest within the limits, else the closest of all.
        match nearest(&|s| s.within_limits, &miss).or_else(|| nearest(&|_| true, &miss)) {
            Some(s) => s.answer(IkStatus::BestEffort),
            None => {
                let error = residual.error(&self.tool_pose(&problem.seed));
                IkSolution {
                    q: problem.seed,
                    status: IkStatus::BestEffort,
                    iterations: 0,
                    restarts: 0,
                    position_error: error.position,
                    orientation_error: error.orientation,
                }
            }
        }
    }

    /// The closed form where `closed` gives a solution within the limits that reaches, else the
    /// numerical solver ([`Chain::solve`]). The second value is true if the closed form answered.
    pub fn solve_auto(&self, closed: Option<&ClosedForm<T, N>>, problem: &IkProblem<T, N>) -> (IkSolution<T, N>, bool) {
        if let Some(closed) = closed.filter(|c| c.answers(&problem.target)) {
            // Only a reaching answer is wanted here: a miss goes to the numerical solver, so the
            // closed form's closest miss is not worked out. (An invalid problem has no
            // candidates, and `solve` refuses it.)
            let residual = Residual::new(problem.target, &problem.config);
            if let Some(solution) = self.nearest_reaching(&closed.candidates(self, problem), &residual, &problem.seed) {
                return (solution, true);
            }
        }
        (self.solve(problem), false)
    }

    /// Of the exact candidates within the limits, nearest `seed` first, the first that reaches by
    /// FK: usually the first, so one FK instead of eight.
    fn nearest_reaching(
        &self,
        raw: &Candidates<T>,
        residual: &Residual<T>,
        seed: &SVector<T, N>,
    ) -> Option<IkSolution<T, N>> {
        let mut order: heapless::Vec<(T, SVector<T, N>, Option<Singularity>), MAX_SOLUTIONS> = heapless::Vec::new();
        for (q, exact, singular) in raw.iter() {
            let (q, within) = fit(self, q, seed);
            if exact && within {
                let _ = order.push((distance_from(self, &q, seed), q, singular));
            }
        }
        order.sort_unstable_by(|a, b| a.0.partial_cmp(&b.0).unwrap_or(core::cmp::Ordering::Equal));
        order
            .iter()
            .map(|(_, q, singular)| checked(self, residual, *q, true, true, *singular))
            .find(|s| s.within_limits && s.reaches)
            .map(|s| s.answer(IkStatus::Converged))
    }
}

#[cfg(test)]
mod tests;
