//! The path of a Cartesian move, decided in this one place for every front end (`armctl move`,
//! the demo, a rig, the view's live target). Before anything is sent, the straight line is checked
//! by IK as the firmware will track it; where it is blocked the move goes by joints (or, asked for
//! the line only, is refused), with the reason in words. The firmware's IK (f32, a budget sized for
//! its loop) can miss a solution that exists: where it refuses the target as unreachable, the
//! host's solution is sent as a joint move. After the move, [`outcome`] says which way the arm
//! went.
//!
//! An arm with collision geometry is checked first ([`take_checked`]): the target's IK solution
//! must be free (other solutions are tried before the target is refused, naming the pair); the
//! straight line is checked at every IK point; where it is blocked, the arm goes by joints to the
//! free solution, straight or by a planned path ([`super::avoid`]).

use anyhow::Result;
use firmware::link::message::{CartesianTarget, MovePath, NakReason, PathTaken, Status, Timing, MAX_SPEED};
use kinematics::ik::IkStatus;

use super::avoid::{self, NotSent, Sent};
use crate::arm::ArmSpec;
use crate::link::client::LinkError;
use crate::motion::collision::Checker;
use crate::motion::line::{Blocked, Line};
use crate::motion::reach;
use crate::runtime::driver::{check_joints, Driver};

/// Said where the host's solution was sent: why the arm went by joints.
pub const SOLVED_ON_HOST: &str =
    "the firmware's IK found no solution from here, so the arm went by joints to the host's";

/// How a move was sent.
#[derive(Clone, Debug)]
pub struct Route {
    /// The path the firmware was asked to take.
    pub sent: MovePath,
    /// Where the host's check found the straight line blocked, if it did (the arm then goes by
    /// joints from the start).
    pub blocked_ahead: Option<Blocked>,
    /// Whether the host's IK solution went as a joint move, the firmware having found none.
    pub solved_on_host: bool,
    /// How the move went by joints to the host's collision-free solution, for an arm with
    /// collision geometry: straight, or planned around what was in the way.
    pub avoided: Option<Sent>,
}

/// A move that was not sent, or that the firmware refused: nothing moved.
#[derive(Debug)]
pub struct Refused {
    /// Why, in words.
    pub reason: String,
    /// What to try instead ("; --path auto or joint goes there by joints"), or nothing.
    pub hint: &'static str,
    /// Who said no: the host's check, the firmware, or a link that failed.
    pub by: RefusedBy,
}

/// Who refused a move.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RefusedBy {
    /// The host's check, before anything was sent.
    Host,
    /// The firmware (a nak).
    Firmware,
    /// Nobody: the link failed.
    Link,
}

impl Refused {
    fn because(reason: impl std::fmt::Display) -> Self {
        Self { reason: reason.to_string(), hint: "", by: RefusedBy::Host }
    }

    /// The host's own failure (its check, its IK), with its causes.
    fn host(e: anyhow::Error) -> Self {
        Self::because(format!("{e:#}"))
    }

    /// `--path line` with the line blocked: refused before anything is sent.
    fn line_blocked(arm: &ArmSpec, blocked: &Blocked) -> Self {
        Self {
            reason: where_blocked(arm, blocked),
            hint: "; --path auto or joint goes there by joints",
            by: RefusedBy::Host,
        }
    }

    /// A request the link did not carry out; a collision refusal names the pair from `arm`'s
    /// geometry.
    fn link(arm: &ArmSpec, e: LinkError) -> Self {
        let by = if matches!(e, LinkError::Nak(_)) { RefusedBy::Firmware } else { RefusedBy::Link };
        let named = match &e {
            LinkError::Nak(reason) => super::collision::refusal(arm, reason),
            _ => None,
        };
        Self { reason: named.unwrap_or_else(|| e.to_string()), hint: "", by }
    }
}

/// Decides the way to `target` for a move asked to go by `asked`, and sends it from where the arm
/// stands (`start`).
pub fn take(
    driver: &mut Driver,
    start: &Status,
    target: CartesianTarget,
    timing: Timing,
    asked: MovePath,
) -> Result<Route, Refused> {
    if avoid::host_checker(driver).map_err(Refused::host)?.is_some() {
        return take_checked(driver, start, target, timing, asked);
    }
    let mut route = Route { sent: asked, blocked_ahead: None, solved_on_host: false, avoided: None };
    if asked != MovePath::Joint {
        match check_line(driver, start, &target).map_err(Refused::host)? {
            Ok(_) => {}
            Err(blocked) if asked == MovePath::Line => return Err(Refused::line_blocked(driver.arm(), &blocked)),
            Err(blocked) => (route.sent, route.blocked_ahead) = (MovePath::Joint, Some(blocked)),
        }
    }
    match driver.session().move_to(target, timing, route.sent) {
        Ok(()) => Ok(route),
        Err(LinkError::Nak(NakReason::Unreachable)) if route.sent != MovePath::Line => {
            let unreachable = LinkError::Nak(NakReason::Unreachable);
            let solved = host_solution(driver, start, &target).map_err(Refused::host)?;
            let Some(q) = solved else {
                let reason = format!("{unreachable}, and the host's IK finds no solution either");
                return Err(Refused { reason, hint: "", by: RefusedBy::Firmware });
            };
            let positions = check_joints(driver, &q, "the host's solution").map_err(Refused::host)?;
            let sent = driver.session().move_joints(positions, by_joints(timing));
            sent.map_err(|e| Refused::link(driver.arm(), e))?;
            route.solved_on_host = true;
            Ok(route)
        }
        Err(e) => Err(Refused::link(driver.arm(), e)),
    }
}

/// [`take`] for an arm with collision geometry: the host's free solution first, then the line
/// checked at every point, then by joints around what is in the way.
fn take_checked(
    driver: &mut Driver,
    start: &Status,
    target: CartesianTarget,
    timing: Timing,
    asked: MovePath,
) -> Result<Route, Refused> {
    let goal = free_solution(driver, start, &target)?;
    let mut route = Route { sent: asked, blocked_ahead: None, solved_on_host: false, avoided: None };
    if asked != MovePath::Joint {
        let mut checker = avoid::host_checker(driver).map_err(Refused::host)?;
        match check_line_with(driver, start, &target, checker.as_mut()).map_err(Refused::host)? {
            Ok(_) => {
                drop(checker);
                let sent = driver.session().move_to(target, timing, asked);
                sent.map_err(|e| Refused::link(driver.arm(), e))?;
                return Ok(route);
            }
            Err(blocked) if asked == MovePath::Line => return Err(Refused::line_blocked(driver.arm(), &blocked)),
            Err(blocked) => route.blocked_ahead = Some(blocked),
        }
    }
    let from: Vec<f64> = start.measured.iter().map(|&x| f64::from(x)).collect();
    let sent = avoid::send(driver, &from, &goal, by_joints(timing));
    let sent = sent.map_err(|e| match e {
        NotSent::Host(e) => Refused::host(e),
        NotSent::Link(e) => Refused::link(driver.arm(), e),
    })?;
    route.sent = MovePath::Joint;
    route.avoided = Some(sent);
    Ok(route)
}

/// A Cartesian move's timing for the same move by joints: a tool speed means nothing to a joint
/// move, which goes as fast as the limits allow (as `armctl joints` does by default); a duration
/// is kept.
fn by_joints(timing: Timing) -> Timing {
    match timing {
        Timing::MaxSpeed(_) => Timing::MaxSpeed(MAX_SPEED),
        other => other,
    }
}

/// Seeds tried for a free IK solution beyond the one from where the arm is.
const SEEDS: usize = 12;

/// The host's IK solution of `target` that keeps the margin, nearest where the arm is: the one
/// seeded from there, else the closed form's others and ones seeded across the joint ranges
/// (fixed seeds, so a move repeats). Refused naming the pair when every solution found is in
/// collision, or when none is found.
fn free_solution(driver: &Driver, start: &Status, target: &CartesianTarget) -> Result<Vec<f64>, Refused> {
    let host = Refused::host;
    let arm = driver.model();
    let from: Vec<f64> = start.measured.iter().map(|&x| f64::from(x)).collect();
    let position = target.position.map(f64::from);
    let orientation = target.orientation.map(|o| o.map(f64::from));
    let mut checker = Checker::of(arm).map_err(host)?.ok_or_else(|| Refused::because("no collision geometry"))?;
    let mut rng = kinematics::SplitMix64::new(crate::motion::plan::DEFAULT_SEED);
    let mut seeds = vec![from.clone(), arm.middle()];
    seeds.extend((0..SEEDS).map(|_| arm.random_configuration(&mut rng)));
    let mut first_contact: Option<String> = None;
    let mut best: Option<(f64, Vec<f64>)> = None;
    let mut found = 0usize;
    for (i, seed) in seeds.into_iter().enumerate() {
        let solved = reach::solve(arm, position, orientation, Some(seed)).map_err(host)?;
        if solved.status != IkStatus::Converged || !arm.admits(&solved.q) {
            continue;
        }
        found += 1;
        match checker.contact(&solved.q).map_err(host)? {
            Some(contact) => {
                first_contact.get_or_insert_with(|| checker.describe(&contact));
            }
            None => {
                let d = crate::motion::plan::length(&[from.clone(), solved.q.clone()]);
                // The solution from where the arm is wins when it is free: the posture it keeps.
                if i == 0 {
                    return Ok(solved.q);
                }
                if best.as_ref().is_none_or(|(b, _)| d < *b) {
                    best = Some((d, solved.q));
                }
            }
        }
    }
    match (best, first_contact) {
        (Some((_, q)), _) => Ok(q),
        (None, Some(contact)) => Err(Refused {
            reason: format!(
                "the target is in collision: {contact} ({found} IK solutions found from {} seeds, none free)",
                SEEDS + 2
            ),
            hint: "",
            by: RefusedBy::Host,
        }),
        (None, None) => Err(Refused {
            reason: format!("{}: the host's IK finds no solution", LinkError::Nak(NakReason::Unreachable)),
            hint: "",
            by: RefusedBy::Host,
        }),
    }
}

/// Which way a move went, and why it went by joints if it did.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// "line", "line, then joints", "joint" or "planned".
    pub path: &'static str,
    /// Where the straight line was found blocked, m along it: by the host's check before the move,
    /// or by the firmware on the way (its status says where it gave the line up).
    pub blocked_at: Option<f64>,
    /// Why by joints, in words, if so.
    pub why: Option<String>,
}

/// Why a move that went by joints through the collision-aware send (`sent`, of `route`) went so,
/// in words: where the straight line was blocked, and what the joint path met on its way, if
/// anything. One wording for `armctl move`, the view's Go and Python.
pub fn avoided_why(arm: &ArmSpec, route: &Route, sent: &super::avoid::Sent) -> Option<String> {
    let ahead = route.blocked_ahead.as_ref().map(|b| where_blocked(arm, b));
    match (ahead, &sent.why) {
        (Some(ahead), Some(why)) => Some(format!("{ahead}; {why}")),
        (Some(ahead), None) => Some(format!("{ahead}, so the arm went by joints")),
        (None, why) => why.clone(),
    }
}

/// How the move sent by `route` went, by the firmware's own account in the status at rest (`end`:
/// its last move, [`firmware::link::message::MoveOutcome`]), with the tool `error_mm` from the target. A line asked for
/// alone that the firmware stopped where it was blocked, or that ended short, is an error.
pub fn outcome(arm: &ArmSpec, route: &Route, end: &Status, error_mm: f64) -> Result<Outcome, String> {
    let reported = end.last_move;
    let given_up = reported.and_then(|m| m.blocked_at.map(|at| (f64::from(at), f64::from(m.line_length))));
    let along = |(at, length): (f64, f64)| format!(" (blocked {:.0} mm along its {:.0} mm)", at * 1e3, length * 1e3);
    if let Some(why) = super::collision::stopped(arm, end) {
        return Err(why);
    }
    let stopped = reported.is_some_and(|m| m.path == PathTaken::LineStopped);
    if route.sent == MovePath::Line && (stopped || error_mm > 1.0) {
        return Err(format!(
            "the straight line ran into the joint limits{}: stopped {error_mm:.1} mm short{}; \
             --path auto finishes such a move by joints",
            given_up.map(along).unwrap_or_default(),
            at_limits(arm, end.measured.iter().map(|&x| f64::from(x)))
        ));
    }
    if let Some(sent) = &route.avoided {
        let why = avoided_why(arm, route, sent);
        return Ok(Outcome { path: sent.path, blocked_at: route.blocked_ahead.as_ref().map(|b| b.along), why });
    }
    if let Some(b) = &route.blocked_ahead {
        let why = format!("{}, so the arm went by joints", where_blocked(arm, b));
        return Ok(Outcome { path: "joint", blocked_at: Some(b.along), why: Some(why) });
    }
    if route.solved_on_host {
        return Ok(Outcome { path: "joint", blocked_at: None, why: Some(SOLVED_ON_HOST.to_string()) });
    }
    // What was sent, where the firmware says nothing (it always does for a move it took).
    let path = reported.map_or(
        match route.sent {
            MovePath::Joint => PathTaken::Joints,
            _ => PathTaken::Line,
        },
        |m| m.path,
    );
    Ok(match path {
        PathTaken::Joints => Outcome { path: "joint", blocked_at: None, why: None },
        PathTaken::LineThenJoints => Outcome {
            path: "line, then joints",
            blocked_at: given_up.map(|(at, _)| at),
            why: Some(format!(
                "the straight line ran into the joint limits{}, so the arm went the rest of the way by joints",
                given_up.map(along).unwrap_or_default()
            )),
        },
        // A collision stop failed above.
        PathTaken::Line | PathTaken::LineStopped | PathTaken::CollisionStopped => {
            Outcome { path: "line", blocked_at: None, why: None }
        }
    })
}

/// The joints that put the tool on `target`, solved on the host from where the arm is
/// ([`reach::solve`]), or `None` if it finds none within the limits.
pub fn host_solution(driver: &Driver, start: &Status, target: &CartesianTarget) -> Result<Option<Vec<f64>>> {
    let seed = start.measured.iter().map(|&x| f64::from(x)).collect();
    let position = target.position.map(f64::from);
    let solved = reach::solve(driver.model(), position, target.orientation.map(|o| o.map(f64::from)), Some(seed))?;
    Ok((solved.status == IkStatus::Converged).then_some(solved.q))
}

/// The straight line from the tool (at the joints of `start`) to `target`, checked by IK as the
/// firmware will track it ([`Line::follow`]).
pub fn check_line(driver: &Driver, start: &Status, target: &CartesianTarget) -> Result<Result<Vec<f64>, Blocked>> {
    check_line_with(driver, start, target, None)
}

/// [`check_line`], every point also checked against the arm's collision geometry by `checker`.
pub fn check_line_with(
    driver: &Driver,
    start: &Status,
    target: &CartesianTarget,
    checker: Option<&mut Checker<'_>>,
) -> Result<Result<Vec<f64>, Blocked>> {
    let q: Vec<f64> = start.measured.iter().map(|&x| f64::from(x)).collect();
    let line = Line {
        from: driver.tool_position(&start.measured)?,
        to: target.position.map(f64::from),
        orientation: target.orientation.map(|o| o.map(f64::from)),
    };
    line.follow_checked(driver.model(), &q, line.points(), checker)
}

/// Where the host's check found the line blocked, in words ("the straight line is blocked 75 mm
/// along its 145 mm, joint 1 (shoulder_pan) at its upper limit 1.920").
pub fn where_blocked(arm: &crate::arm::ArmSpec, b: &Blocked) -> String {
    let why = match &b.contact {
        Some(contact) => format!(": {contact}"),
        None => at_limits(arm, b.q.iter().copied()),
    };
    format!("the straight line is blocked {:.0} mm along its {:.0} mm{why}", b.along * 1e3, b.length * 1e3)
}

/// The joints within 0.02 rad (or m) of a limit at `q`, in words (", joint 2 (shoulder_lift) at its
/// upper limit 1.745"), or nothing.
pub fn at_limits(arm: &crate::arm::ArmSpec, q: impl IntoIterator<Item = f64>) -> String {
    const NEAR: f64 = 0.02;
    let words: Vec<String> = arm
        .joints
        .iter()
        .zip(q)
        .enumerate()
        .filter(|(_, (spec, _))| spec.kind != kinematics::JointKind::Continuous)
        .filter_map(|(j, (spec, x))| {
            let (which, limit) = if x - spec.lower < NEAR {
                ("lower", spec.lower)
            } else if spec.upper - x < NEAR {
                ("upper", spec.upper)
            } else {
                return None;
            };
            Some(format!("joint {} ({}) at its {which} limit {limit:.3}", j + 1, spec.name))
        })
        .collect();
    match words.is_empty() {
        true => String::new(),
        false => format!(", {}", words.join(", ")),
    }
}

#[cfg(test)]
mod tests {
    use firmware::link::message::{MoveOutcome, RunState};

    use super::*;
    use crate::link::session::tests::status;

    fn at_rest(reported: Option<MoveOutcome>) -> Status {
        let mut s = status(1.0, RunState::Idle, &[0.0; 5], &[0.0; 5]);
        s.last_move = reported;
        s
    }

    fn route(sent: MovePath) -> Route {
        Route { sent, blocked_ahead: None, solved_on_host: false, avoided: None }
    }

    /// The way a move went is the firmware's account, and the words say where the line was given
    /// up; a line asked for alone and stopped is an error that says so.
    #[test]
    fn the_outcome_is_what_the_firmware_reports() {
        let arm = ArmSpec::load("so101", None).unwrap();
        let moved = |path, blocked_at| Some(MoveOutcome { path, blocked_at, line_length: 0.1449 });
        let line = outcome(&arm, &route(MovePath::Auto), &at_rest(moved(PathTaken::Line, None)), 0.2).unwrap();
        assert_eq!(line, Outcome { path: "line", blocked_at: None, why: None });

        let fell_back = at_rest(moved(PathTaken::LineThenJoints, Some(0.0752)));
        let o = outcome(&arm, &route(MovePath::Auto), &fell_back, 0.2).unwrap();
        assert_eq!((o.path, o.blocked_at.map(|b| (b * 1e4).round())), ("line, then joints", Some(752.0)));
        assert_eq!(
            o.why.as_deref(),
            Some(
                "the straight line ran into the joint limits (blocked 75 mm along its 145 mm), so the arm went \
                 the rest of the way by joints"
            )
        );

        let stopped = at_rest(moved(PathTaken::LineStopped, Some(0.0962)));
        let e = outcome(&arm, &route(MovePath::Line), &stopped, 48.7).unwrap_err();
        assert!(
            e.starts_with(
                "the straight line ran into the joint limits (blocked 96 mm along its 145 mm): stopped 48.7 mm short"
            ) && e.ends_with("--path auto finishes such a move by joints"),
            "{e}"
        );
        // Short of the target along the line without a word from the firmware: an error too.
        assert!(outcome(&arm, &route(MovePath::Line), &at_rest(moved(PathTaken::Line, None)), 3.0).is_err());

        let joints = at_rest(Some(MoveOutcome { path: PathTaken::Joints, blocked_at: None, line_length: 0.0 }));
        let by_host = Route { solved_on_host: true, ..route(MovePath::Auto) };
        assert_eq!(outcome(&arm, &by_host, &joints, 0.1).unwrap().why.as_deref(), Some(SOLVED_ON_HOST));
        let ahead = Route {
            sent: MovePath::Joint,
            blocked_ahead: Some(Blocked { along: 0.075, length: 0.145, q: vec![0.0; 5], contact: None }),
            solved_on_host: false,
            avoided: None,
        };
        let o = outcome(&arm, &ahead, &joints, 0.1).unwrap();
        assert_eq!((o.path, o.blocked_at), ("joint", Some(0.075)));
        assert!(o.why.unwrap().starts_with("the straight line is blocked 75 mm along its 145 mm"));
    }
}
