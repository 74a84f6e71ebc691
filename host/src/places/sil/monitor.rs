//! The safety monitor: after every control tick it looks at the goal each simulated servo holds
//! and checks every goal a servo received against the joint limits, and its change since the goal
//! received before against the velocity limit over the time between them. It looks at the
//! servos, not at the firmware, so it judges whatever reached the bus. A goal write lost on a noisy
//! bus is no violation: the next goal that arrives may then cover the time of both.

use super::board::JointBounds;

/// A goal the servos should never have received.
#[derive(Clone, Debug, PartialEq)]
pub struct Violation {
    /// Virtual time, s.
    pub time: f64,
    /// Servo id.
    pub id: u8,
    /// What was wrong.
    pub what: String,
}

/// What a servo holds after a tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GoalState {
    /// Its goal, ticks.
    pub goal: i64,
    /// Writes that have reached its goal item so far.
    pub writes: u64,
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
    /// Everything wrong, in order (the first 100).
    pub violations: Vec<Violation>,
    /// Violations in all (also those beyond the first 100).
    pub violation_count: u64,
}

impl SafetyMonitor {
    /// Checks what the servos hold after a tick at `time` (s) of a loop with `period` (s); `None`
    /// while the torque is off (limp servos may hold any goal; checking starts afresh).
    pub fn check(&mut self, time: f64, period: f64, bounds: &[JointBounds], servos: Option<Vec<GoalState>>) {
        let Some(servos) = servos else {
            self.last.clear();
            return;
        };
        self.last.resize(servos.len(), None);
        for (j, (b, s)) in bounds.iter().zip(&servos).enumerate() {
            let received = self.last[j].is_none_or(|(_, _, writes)| s.writes > writes);
            if !received {
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
    }

    fn report(&mut self, time: f64, id: u8, what: String) {
        self.violation_count += 1;
        if self.violations.len() < 100 {
            self.violations.push(Violation { time, id, what });
        }
    }
}
