//! The safety monitor of the SIL harness: after every control tick, on its virtual clock, it
//! checks every goal a servo received against the joint limits, and its change since the goal
//! received before against the velocity limit over the control periods between them. It looks at
//! the simulated servos, not at the firmware, so it judges whatever reached the bus. A goal write
//! lost on a noisy bus is no violation: the next goal that arrives may then cover the time of both.
//!
//! It lives in the simulator, beneath `runtime`, so that any host of simulated servos can use it.
//!
//! - [`realtime`]: the same checks for a bus served in real time (a pty), judged goal write by
//!   goal write over the control ticks counted between them in the byte stream.
//! - [`arm_limits`]: an arm's goal limits as its firmware maps them, for [`realtime`].
//! - [`collision`]: both monitors' rule on the arm's geometry: goals whose bodies come closer than
//!   the margin are recorded with the two bodies and their distance.

pub mod arm_limits;
pub mod collision;
pub mod realtime;

pub use arm_limits::limits_of;
pub use collision::{CollisionRule, ContactRecord, GoalContact};
pub use realtime::{GoalLimit, GoalSample, MonitorReport, RealTimeMonitor, ServoRecord, DEFAULT_PERIOD};

/// Violations kept in full; those beyond are only counted.
pub const MAX_VIOLATIONS: usize = 100;

/// What a monitor sees of one servo's joint: where goals must stay.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointBounds {
    /// Servo id.
    pub id: u8,
    /// Lowest and highest goal allowed (ticks): the joint limits mapped to ticks.
    pub goal_range: (i64, i64),
    /// Largest goal change allowed in one control period (ticks): the velocity limit times the
    /// period, plus one tick of rounding.
    pub max_step: i64,
}

/// A goal the servos should never have received.
#[derive(Clone, Debug, PartialEq)]
pub struct Violation {
    /// When, s: virtual time in the SIL harness, real time since the server started on a pty.
    pub time: f64,
    /// Servo id.
    pub id: u8,
    /// What was wrong.
    pub what: String,
}

impl std::fmt::Display for Violation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "servo {} at {:.3} s: {}", self.id, self.time, self.what)
    }
}

/// What a servo holds after a tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GoalState {
    /// Its goal, ticks.
    pub goal: i64,
    /// Writes that have reached its goal item so far.
    pub writes: u64,
    /// Whether the last of them came in a packet the simulated line corrupted and the protocol's
    /// checksum let through (Feetech's 8-bit sum misses about one corrupted packet in 256): a goal
    /// the firmware never sent.
    pub corrupted: bool,
}

/// Checks every tick's goals.
#[derive(Clone, Debug, Default)]
pub struct SafetyMonitor {
    /// Per servo: the goal last received, when, and the write count then.
    last: Vec<Option<(i64, f64, u64)>>,
    /// Goals checked.
    pub checked: u64,
    /// Largest goal change seen as a fraction of the change the velocity limit allows.
    pub max_step_ratio: f64,
    /// Everything wrong, in order (the first [`MAX_VIOLATIONS`]).
    pub violations: Vec<Violation>,
    /// Violations in all (also those beyond the first [`MAX_VIOLATIONS`]).
    pub violation_count: u64,
    /// Goals not judged because the line corrupted them on the way (see [`GoalState::corrupted`]).
    pub corrupted: u64,
    /// Goal configurations within the margin of the arm's geometry (`None`: no geometry, not
    /// judged; [`SafetyMonitor::with_collision`]).
    pub contacts: Option<ContactRecord>,
    rule: Option<CollisionRule>,
}

impl SafetyMonitor {
    /// A monitor that also judges every goal configuration in `world`'s geometry
    /// ([`collision`]).
    pub fn with_collision(world: crate::sim::World) -> Self {
        let rule = CollisionRule::new(world);
        Self { contacts: Some(rule.record()), rule: Some(rule), ..Self::default() }
    }

    /// Checks what the servos hold after a tick at `time` (s) of a loop with `period` (s); `None`
    /// while the torque is off (limp servos may hold any goal; checking starts afresh).
    pub fn check(&mut self, time: f64, period: f64, bounds: &[JointBounds], servos: Option<Vec<GoalState>>) {
        let Some(servos) = servos else {
            self.last.clear();
            return;
        };
        self.last.resize(servos.len(), None);
        let mut any_received = false;
        for (j, (b, s)) in bounds.iter().zip(&servos).enumerate() {
            let received = self.last[j].is_none_or(|(_, _, writes)| s.writes > writes);
            if !received {
                continue;
            }
            any_received = true;
            if s.corrupted {
                // Not the firmware's goal: the next one is judged against the last one it sent.
                self.corrupted += 1;
                self.last[j] = Some(self.last[j].map_or((s.goal, time, s.writes), |(g, t, _)| (g, t, s.writes)));
                continue;
            }
            self.checked += 1;
            if s.goal < b.goal_range.0 || s.goal > b.goal_range.1 {
                self.report(time, b.id, format!("goal {} outside {}..={}", s.goal, b.goal_range.0, b.goal_range.1));
            }
            if let Some((previous, since, _)) = self.last[j] {
                let periods = ((time - since) / period).round().max(1.0);
                let allowed = b.max_step as f64 * periods;
                let step = (s.goal - previous).abs() as f64;
                self.max_step_ratio = self.max_step_ratio.max(step / allowed);
                if step > allowed {
                    self.report(time, b.id, format!("goal step {step} ticks beyond {allowed} in {periods} periods"));
                }
            }
            self.last[j] = Some((s.goal, time, s.writes));
        }
        if let (true, Some(rule), Some(record)) = (any_received, &mut self.rule, &mut self.contacts) {
            // Every joint's goal as the servos hold them, none corrupted on the line.
            let goal = |id: u8| {
                let k = bounds.iter().position(|b| b.id == id)?;
                servos.get(k).filter(|s| !s.corrupted).map(|s| s.goal)
            };
            let goals: Option<Vec<i64>> = rule.ids().into_iter().map(goal).collect();
            if let Some(goals) = goals {
                rule.judge(record, time, &goals);
            }
        }
    }

    fn report(&mut self, time: f64, id: u8, what: String) {
        self.violation_count += 1;
        if self.violations.len() < MAX_VIOLATIONS {
            self.violations.push(Violation { time, id, what });
        }
    }
}
