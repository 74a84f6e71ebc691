//! The safety monitor of a bus served in real time ([`crate::sim::pty::PtyServer`]): every goal a
//! servo receives is checked against its goal range, and its change since the goal before against
//! the velocity limit over the control ticks the firmware ran between them.
//!
//! What it judges is the firmware's contract: each control tick starts with a group read of the
//! present positions and steps every goal by at most the velocity limit times one control period
//! (a late tick steps by its elapsed time, never more than a period: the motion slows down
//! instead of jumping). So a goal write may differ from the servo's previous one by at most the
//! velocity limit times the period times the ticks between them, plus one tick of rounding.
//!
//! Ticks are counted in the byte stream, not timed: the monitor looks at the servos after each
//! instruction frame, in the order the frames came ([`SimBus::receive_observed`]), and counts a
//! tick at each group read of the present position that follows a goal write (the retries of one
//! tick's read, with no goal write between them, count once). Real time cannot judge a goal on a
//! loaded PC: the thread that serves the pty reads what the firmware wrote when it gets round to
//! it, and under load (two busy loops on two cores) one read held up to seven ticks' packets,
//! taken up to a second after the firmware wrote them. Judging the last goal of such a burst
//! against the first over the time between two reads of the pty counted hundreds of violations
//! where the firmware's every goal had kept within one period's step (docs/figures.md).
//!
//! While a servo's torque is off its goals are not checked. When the torque comes back checking
//! starts afresh: the goal the servo then holds, and any goal written in the same control tick
//! (a firmware writes its goals in the tick that turns the torque on), are checked against the
//! range only; the last of them is where the next tick's step counts from.
//!
//! Times in violations are the bus's nanoseconds: on a pty, real time since the server started.

use std::time::Duration;

use crate::sim::bus::Frame;
use crate::sim::SimBus;

use super::collision::{CollisionRule, ContactRecord};
use super::{Violation, MAX_VIOLATIONS};

/// The control period a monitor assumes until told the firmware's: the firmware's default
/// (`firmware::controller::Config`'s 100 Hz, a board's; a core run on the PC may choose a longer
/// one, [`RealTimeMonitor::set_period`]).
pub const DEFAULT_PERIOD: Duration = Duration::from_millis(10);

/// Where one servo's goals must stay.
#[derive(Clone, Debug, PartialEq)]
pub struct GoalLimit {
    /// Servo id.
    pub id: u8,
    /// Lowest and highest goal allowed (ticks): the joint limits mapped to ticks.
    pub goal_range: (i64, i64),
    /// The velocity limit, ticks/s: two consecutive goals may differ by at most this times the
    /// control period times the control ticks between them, plus one tick of rounding.
    pub max_ticks_per_s: f64,
}

/// What one servo holds after an instruction frame, for [`RealTimeMonitor::check`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GoalSample {
    /// Its goal, ticks.
    pub goal: i64,
    /// Where its horn stands (its present position, in the goal's ticks).
    pub present: i64,
    /// Writes that have reached its goal item so far.
    pub writes: u64,
    /// Whether its torque is on.
    pub torque: bool,
}

/// What the monitor found for one servo.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ServoRecord {
    /// Servo id.
    pub id: u8,
    /// Goals checked.
    pub checked: u64,
    /// Violations found.
    pub violations: u64,
    /// Largest goal change seen as a fraction of the change the velocity limit allows.
    pub max_step_ratio: f64,
    /// The last goal checked, ticks.
    pub last_goal: Option<i64>,
}

/// What the monitor found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MonitorReport {
    /// Goals checked.
    pub checked: u64,
    /// Violations in all (also those beyond the first [`MAX_VIOLATIONS`]).
    pub violation_count: u64,
    /// Largest goal change seen as a fraction of the change the velocity limit allows.
    pub max_step_ratio: f64,
    /// Everything wrong, in order (the first [`MAX_VIOLATIONS`]).
    pub violations: Vec<Violation>,
    /// Per servo, in the order of the limits.
    pub servos: Vec<ServoRecord>,
    /// Control ticks counted (group reads of the present position after a goal write).
    pub ticks: u64,
    /// The most control ticks one read of the bus carried ([`RealTimeMonitor::end_burst`]): above 1,
    /// the serving thread fell behind the firmware and took several ticks' packets at once.
    pub max_ticks_per_burst: u64,
    /// Goal configurations within the margin of the arm's geometry (`None`: no geometry, not
    /// judged; [`RealTimeMonitor::with_collision`]).
    pub contacts: Option<ContactRecord>,
}

impl MonitorReport {
    /// One line for people: `4236 goals checked, 0 violations (largest step 48% of the limit)`,
    /// and how far behind the serving thread fell when it took several ticks at once.
    pub fn summary(&self) -> String {
        let mut line = format!(
            "{} goals checked, {} violations (largest step {:.0}% of the limit)",
            self.checked,
            self.violation_count,
            100.0 * self.max_step_ratio
        );
        if let Some(contacts) = &self.contacts {
            line.push_str(&format!("; {}", contacts.summary()));
        }
        if self.max_ticks_per_burst > 1 {
            line.push_str(&format!("; up to {} control ticks read in one burst", self.max_ticks_per_burst));
        }
        line
    }
}

/// Per servo: what was seen of it so far.
#[derive(Clone, Debug, Default)]
struct Track {
    /// Goal writes counted at the last look.
    writes: u64,
    /// The goal last checked, the control tick it came in and when it arrived (ns); `None` while
    /// the torque is off.
    last: Option<(i64, u64, u64)>,
    /// The torque came on at `last`'s tick without a goal write: a write in that same tick is a
    /// fresh start too.
    fresh: bool,
}

/// What a goal step is judged over: the control ticks counted between two goal writes, or, where
/// no position read came between them (a program writing goals on its own), the time (ns).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Over {
    Ticks(u64),
    Time(u64),
}

/// Checks the goals servos receive in real time.
#[derive(Clone, Debug)]
pub struct RealTimeMonitor {
    limits: Vec<GoalLimit>,
    tracks: Vec<Track>,
    period: Duration,
    /// Whether a goal write came since the last group read of the present position: the next
    /// such read starts a tick.
    wrote_since_read: bool,
    /// Ticks counted at the end of the last burst.
    ticks_at_burst: u64,
    report: MonitorReport,
    /// The rule on the arm's geometry, when there is one.
    rule: Option<CollisionRule>,
}

impl RealTimeMonitor {
    /// A monitor of the servos of `limits`, at the firmware's default period ([`DEFAULT_PERIOD`]).
    pub fn new(limits: Vec<GoalLimit>) -> Self {
        let servos = limits.iter().map(|l| ServoRecord { id: l.id, ..ServoRecord::default() }).collect();
        Self {
            tracks: vec![Track::default(); limits.len()],
            limits,
            period: DEFAULT_PERIOD,
            wrote_since_read: true,
            ticks_at_burst: 0,
            report: MonitorReport { servos, ..MonitorReport::default() },
            rule: None,
        }
    }

    /// The same monitor also judging every goal configuration in `world`'s geometry
    /// ([`super::collision`]): a frame that brings a joint's goal judges all the joints' goals.
    pub fn with_collision(mut self, world: crate::sim::World) -> Self {
        let rule = CollisionRule::new(world);
        self.report.contacts = Some(rule.record());
        self.rule = Some(rule);
        self
    }

    /// The limits checked.
    pub fn limits(&self) -> &[GoalLimit] {
        &self.limits
    }

    /// The firmware's control period, once it is known (a core on the PC chooses it after timing
    /// the bus): a goal may step the velocity limit times this per tick.
    pub fn set_period(&mut self, period: Duration) {
        self.period = period;
    }

    /// The control period assumed.
    pub fn period(&self) -> Duration {
        self.period
    }

    /// What it has found so far.
    pub fn report(&self) -> &MonitorReport {
        &self.report
    }

    /// Looks at `bus` after it carried out `frame` ([`SimBus::receive_observed`],
    /// [`SimBus::line_idle_observed`]); a servo of the limits that is not on the bus counts as limp.
    pub fn observe(&mut self, bus: &SimBus, frame: Frame) {
        let item = bus.model().items.goal_position;
        let servos: Vec<Option<GoalSample>> = self
            .limits
            .iter()
            .map(|l| {
                bus.servo(l.id).map(|s| GoalSample {
                    goal: s.get(item),
                    present: s.get(bus.model().items.present_position),
                    writes: s.goal_writes(),
                    torque: s.torque(),
                })
            })
            .collect();
        self.check(frame, &servos);
    }

    /// A read of the bus has been carried out, frame by frame: notes how many control ticks it held.
    pub fn end_burst(&mut self) {
        let held = self.report.ticks - self.ticks_at_burst;
        self.report.max_ticks_per_burst = self.report.max_ticks_per_burst.max(held);
        self.ticks_at_burst = self.report.ticks;
    }

    /// Checks what the servos hold (in the order of the limits; `None`: not on the bus) after
    /// `frame`, the frames coming one by one in the order they arrived.
    pub fn check(&mut self, frame: Frame, servos: &[Option<GoalSample>]) {
        if frame.reads_position && self.wrote_since_read {
            self.report.ticks += 1;
            self.wrote_since_read = false;
        }
        let tick = self.report.ticks;
        let mut any_written = false;
        for (j, sample) in servos.iter().enumerate().take(self.limits.len()) {
            let Some(s) = *sample else {
                self.tracks[j].last = None;
                continue;
            };
            let track = &mut self.tracks[j];
            let written = s.writes > track.writes;
            track.writes = s.writes;
            self.wrote_since_read |= written;
            any_written |= written && s.torque;
            if !s.torque {
                track.last = None;
                continue;
            }
            match track.last {
                // The torque came back (or this is the first look), with a goal written or the
                // one the servo holds: a fresh start, checked against the range only.
                None => {
                    track.last = Some((s.goal, tick, frame.t_ns));
                    track.fresh = !written;
                    self.judge(j, frame.t_ns, s.goal, None);
                }
                // The goals a firmware writes in the tick that turns the torque on (after the
                // torque write) start afresh too; from the next tick on, steps are judged.
                // Once: a program that reads no positions stays in one tick for good.
                Some((_, since, _)) if written && track.fresh && since == tick => {
                    track.last = Some((s.goal, tick, frame.t_ns));
                    track.fresh = false;
                    self.judge(j, frame.t_ns, s.goal, None);
                }
                Some((previous, since, at)) if written => {
                    track.last = Some((s.goal, tick, frame.t_ns));
                    track.fresh = false;
                    // A firmware reads the positions at every tick before it writes: its writes are
                    // judged over the ticks between them. Two writes with no read between them
                    // come from a program that writes goals on its own schedule (LeRobot's
                    // so101_follower replaying actions): judged over the time between them.
                    let over = match tick.saturating_sub(since) {
                        0 => Over::Time(frame.t_ns.saturating_sub(at)),
                        ticks => Over::Ticks(ticks),
                    };
                    self.judge(j, frame.t_ns, s.goal, Some((previous, over, s.present)));
                }
                Some(_) => {}
            }
        }
        if any_written {
            self.judge_configuration(frame.t_ns, servos);
        }
    }

    /// Judges the joints' goals as the servos hold them after a frame that wrote some, when every
    /// joint's servo is on the bus with its torque on.
    fn judge_configuration(&mut self, t_ns: u64, servos: &[Option<GoalSample>]) {
        let (Some(rule), Some(record)) = (&mut self.rule, &mut self.report.contacts) else { return };
        let limits = &self.limits;
        let goal = |id: u8| {
            let j = limits.iter().position(|l| l.id == id)?;
            servos.get(j).copied().flatten().filter(|s| s.torque).map(|s| s.goal)
        };
        let goals: Option<Vec<i64>> = rule.ids().into_iter().map(goal).collect();
        if let Some(goals) = goals {
            rule.judge(record, t_ns as f64 * 1e-9, &goals);
        }
    }

    /// Checks servo `j`'s goal received at `time_ns` against its range, and against the velocity
    /// limit when it follows a goal `(previous, over, present)`, `over` the ticks or the time
    /// between them, the horn standing at `present`.
    fn judge(&mut self, j: usize, time_ns: u64, goal: i64, step: Option<(i64, Over, i64)>) {
        let limit = &self.limits[j];
        let (lo, hi) = limit.goal_range;
        let mut wrong = Vec::new();
        self.report.checked += 1;
        self.report.servos[j].checked += 1;
        self.report.servos[j].last_goal = Some(goal);
        if goal < lo || goal > hi {
            wrong.push(format!("goal {goal} outside {lo}..={hi}"));
        }
        if let Some((previous, over, present)) = step {
            let per_tick = limit.max_ticks_per_s * self.period.as_secs_f64();
            // Over a time, a period more: the serving thread stamps frames when it reads them, up
            // to a period late on a loaded PC, so two stamps can be closer than the writes were.
            let allowed = match over {
                Over::Ticks(ticks) => per_tick * ticks as f64 + 1.0,
                Over::Time(ns) => limit.max_ticks_per_s * ns as f64 * 1e-9 + per_tick + 1.0,
            };
            let change = (goal - previous).abs() as f64;
            // A goal within a tick's step of where the horn stands sets off no chase, however far
            // the goal before it was: a new core adopting an arm holds it where it stands (a
            // gripper stopped on an object, its goal a squeeze past it, gets its goal back at the
            // contact).
            let to_horn = (goal - present).abs() as f64;
            let at_horn = to_horn <= per_tick + 1.0;
            let ratio = if change > allowed && at_horn { to_horn / (per_tick + 1.0) } else { change / allowed };
            self.report.max_step_ratio = self.report.max_step_ratio.max(ratio);
            let servo = &mut self.report.servos[j];
            servo.max_step_ratio = servo.max_step_ratio.max(ratio);
            if change > allowed && !at_horn {
                let periods = match over {
                    Over::Ticks(1) => "1 control period".to_string(),
                    Over::Ticks(ticks) => format!("{ticks} control periods"),
                    Over::Time(ns) => format!("{:.1} ms with no position read between", ns as f64 * 1e-6),
                };
                wrong.push(format!("goal step {change} ticks ({previous} to {goal}) beyond {allowed:.1} in {periods}"));
            }
        }
        for what in wrong {
            self.report.violation_count += 1;
            self.report.servos[j].violations += 1;
            if self.report.violations.len() < MAX_VIOLATIONS {
                self.report.violations.push(Violation { time: time_ns as f64 * 1e-9, id: limit.id, what });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::bus::table::STS3215;
    use firmware::bus::{Instruction, InstructionPacket, BROADCAST};

    const MS: u64 = 1_000_000;

    /// One servo, goals 0..=4095, 1000 ticks/s: at 10 ms, 10 ticks per control period, and 1 of
    /// rounding.
    fn monitor() -> RealTimeMonitor {
        RealTimeMonitor::new(vec![GoalLimit { id: 1, goal_range: (0, 4095), max_ticks_per_s: 1000.0 }])
    }

    /// The group read of the present position a tick starts with, and any other frame.
    fn read(t_ns: u64) -> Frame {
        Frame { t_ns, reads_position: true }
    }

    fn other(t_ns: u64) -> Frame {
        Frame { t_ns, reads_position: false }
    }

    /// A servo fed by hand: its goal write count moves with each goal.
    struct Servo {
        sample: GoalSample,
    }

    impl Servo {
        fn on(goal: i64) -> Self {
            // The horn far from every goal fed: no goal is excused as one at the horn.
            Self { sample: GoalSample { goal, present: -10_000, writes: 0, torque: true } }
        }

        fn write(&mut self, goal: i64) -> Option<GoalSample> {
            self.sample = GoalSample { goal, writes: self.sample.writes + 1, ..self.sample };
            Some(self.sample)
        }

        fn held(&self) -> Option<GoalSample> {
            Some(self.sample)
        }
    }

    /// Ticks of a firmware ramping servo 1 by `step` per tick from 2048, each tick's read and goal
    /// write fed as frames at `at(k)`.
    fn ramp(
        m: &mut RealTimeMonitor,
        s: &mut Servo,
        ticks: std::ops::RangeInclusive<i64>,
        step: i64,
        at: impl Fn(i64) -> u64,
    ) {
        for k in ticks {
            m.check(read(at(k)), &[s.held()]);
            m.check(other(at(k)), &[s.write(2048 + step * k)]);
        }
    }

    #[test]
    fn the_default_period_is_the_firmwares() {
        let config = firmware::controller::Config::default();
        assert_eq!(DEFAULT_PERIOD, Duration::from_micros(u64::from(config.period_us)));
    }

    #[test]
    fn a_ramp_at_the_limit_passes_and_a_jump_of_two_periods_does_not() {
        let mut m = monitor();
        let mut s = Servo::on(2048);
        m.check(other(0), &[s.held()]);
        // 10 ticks a period: the velocity limit exactly, one write per tick, 10 ms apart.
        ramp(&mut m, &mut s, 1..=50, 10, |k| k as u64 * 10 * MS);
        let r = m.report();
        assert_eq!((r.checked, r.violation_count, r.ticks), (51, 0, 50), "{:?}", r.violations);
        assert!((r.max_step_ratio - 10.0 / 11.0).abs() < 1e-9, "{}", r.max_step_ratio);
        // Two periods' worth in one write, one tick after the last.
        m.check(read(510 * MS), &[s.held()]);
        m.check(other(512 * MS), &[s.write(2048 + 500 + 20)]);
        let r = m.report();
        assert_eq!(r.violation_count, 1);
        assert_eq!(r.violations[0].id, 1);
        assert_eq!(r.violations[0].what, "goal step 20 ticks (2548 to 2568) beyond 11.0 in 1 control period");
        assert!((r.violations[0].time - 0.512).abs() < 1e-12);
        assert_eq!(r.servos[0].violations, 1);
        assert_eq!(r.servos[0].last_goal, Some(2568));
        assert!(r.max_step_ratio > 1.8);
    }

    /// The serving thread starved: one read of the pty takes twenty ticks' packets at once, all
    /// stamped alike. Each write is judged against the one before it, a tick apart, however short
    /// the real time between their stamps; a jump inside such a burst is still caught.
    #[test]
    fn a_burst_of_ticks_is_judged_write_by_write() {
        let run = |jump_at: Option<i64>| {
            let mut m = monitor();
            let mut s = Servo::on(2048);
            m.check(other(0), &[s.held()]);
            ramp(&mut m, &mut s, 1..=3, 10, |k| k as u64 * 10 * MS);
            m.end_burst();
            // Ticks 4 to 23 arrive in one burst at 500 ms; the firmware stepped each at the limit.
            let mut goal = 2048 + 30;
            for k in 4..=23 {
                goal += if jump_at == Some(k) { 20 } else { 10 };
                m.check(read(500 * MS), &[s.held()]);
                m.check(other(500 * MS), &[s.write(goal)]);
            }
            m.end_burst();
            m.report().clone()
        };
        let r = run(None);
        assert_eq!((r.checked, r.violation_count), (24, 0), "{:?}", r.violations);
        assert_eq!(r.max_ticks_per_burst, 20);
        assert!(r.summary().ends_with("; up to 20 control ticks read in one burst"), "{}", r.summary());
        let r = run(Some(9));
        assert_eq!(r.violation_count, 1, "{:?}", r.violations);
        assert!(r.violations[0].what.starts_with("goal step 20 ticks"), "{}", r.violations[0].what);
    }

    /// A tick's read retried (a reply lost or late) is still one tick: only a read after a goal
    /// write starts the next. Ticks in which a servo got no goal (another's was written) count.
    #[test]
    fn retried_reads_are_one_tick_and_ticks_without_a_write_count() {
        let mut m = monitor();
        let mut s = Servo::on(2048);
        m.check(other(0), &[s.held()]);
        ramp(&mut m, &mut s, 1..=2, 10, |k| k as u64 * 10 * MS);
        for retry in 0..3 {
            m.check(read(30 * MS + retry * MS), &[s.held()]);
        }
        m.check(other(34 * MS), &[s.write(2048 + 20 + 20)]);
        assert_eq!(m.report().violation_count, 1, "three reads, one tick: {:?}", m.report().violations);

        // Two servos; the second's goal is written, the first's not, for a tick.
        let limit = |id| GoalLimit { id, goal_range: (0, 4095), max_ticks_per_s: 1000.0 };
        let mut m = RealTimeMonitor::new(vec![limit(1), limit(2)]);
        let (mut a, mut b) = (Servo::on(2048), Servo::on(1000));
        m.check(other(0), &[a.held(), b.held()]);
        m.check(read(10 * MS), &[a.held(), b.held()]);
        m.check(other(10 * MS), &[a.write(2058), b.write(1010)]);
        m.check(read(20 * MS), &[a.held(), b.held()]);
        m.check(other(20 * MS), &[a.held(), b.write(1020)]);
        m.check(read(30 * MS), &[a.held(), b.held()]);
        // 20 ticks over two periods for servo 1.
        m.check(other(30 * MS), &[a.write(2078), b.write(1030)]);
        let r = m.report();
        assert_eq!((r.checked, r.violation_count, r.ticks), (7, 0, 3), "{:?}", r.violations);
    }

    #[test]
    fn the_period_told_sets_the_step_per_tick() {
        let mut m = monitor();
        m.set_period(Duration::from_millis(25));
        assert_eq!(m.period(), Duration::from_millis(25));
        let mut s = Servo::on(2048);
        m.check(other(0), &[s.held()]);
        ramp(&mut m, &mut s, 1..=10, 25, |k| k as u64 * 25 * MS);
        assert_eq!(m.report().violation_count, 0, "{:?}", m.report().violations);
        ramp(&mut m, &mut s, 11..=11, 28, |k| k as u64 * 25 * MS);
        assert_eq!(m.report().violation_count, 1, "{:?}", m.report().violations);
    }

    /// A program that writes goals on its own schedule and reads no positions between them
    /// (LeRobot's so101_follower replaying actions at 30 Hz) is judged over the time between its
    /// writes, a period more: 30 ticks in 33 ms passes (43.3 allowed), 50 in 10 ms does not (21).
    #[test]
    fn writes_with_no_read_between_are_judged_over_their_time() {
        let mut m = monitor();
        let mut s = Servo::on(2048);
        m.check(other(0), &[s.held()]);
        for k in 1..=30 {
            m.check(other(k as u64 * 100 * MS / 3), &[s.write(2048 + 30 * k)]);
        }
        let r = m.report();
        assert_eq!((r.checked, r.violation_count, r.ticks), (31, 0, 0), "{:?}", r.violations);
        m.check(other(1010 * MS), &[s.write(2048 + 900 + 50)]);
        let r = m.report();
        assert_eq!(r.violation_count, 1);
        assert_eq!(
            r.violations[0].what,
            "goal step 50 ticks (2948 to 2998) beyond 21.0 in 10.0 ms with no position read between"
        );
    }

    #[test]
    fn a_goal_outside_the_range_is_a_violation() {
        let mut m = RealTimeMonitor::new(vec![GoalLimit { id: 1, goal_range: (1000, 3000), max_ticks_per_s: 1e9 }]);
        let mut s = Servo::on(2048);
        m.check(other(0), &[s.held()]);
        m.check(other(MS), &[s.write(3000)]);
        assert_eq!(m.report().violation_count, 0);
        m.check(other(2 * MS), &[s.write(3001)]);
        let r = m.report();
        assert_eq!(r.violation_count, 1);
        assert_eq!(r.violations[0].what, "goal 3001 outside 1000..=3000");
        assert!((r.violations[0].time - 0.002).abs() < 1e-12);
    }

    #[test]
    fn torque_off_stops_checking_and_torque_on_starts_afresh() {
        let mut m = monitor();
        let mut s = Servo::on(2048);
        m.check(other(0), &[s.held()]);
        m.check(read(10 * MS), &[s.held()]);
        m.check(other(10 * MS), &[s.write(2050)]);
        assert_eq!(m.report().checked, 2);
        s.sample.torque = false;
        m.check(other(20 * MS), &[s.held()]);
        // Limp: any goal, even outside the range, is not checked.
        m.check(read(30 * MS), &[s.write(9000)]);
        m.check(read(40 * MS), &[s.write(100)]);
        assert_eq!((m.report().checked, m.report().violation_count), (2, 0));
        // Torque on where the horn stands; the next goal counts from there, not from 2050.
        s.sample.torque = true;
        m.check(other(50 * MS), &[s.held()]);
        m.check(read(60 * MS), &[s.held()]);
        m.check(other(60 * MS), &[s.write(110)]);
        let r = m.report();
        assert_eq!((r.checked, r.violation_count), (4, 0), "{:?}", r.violations);
        // A servo missing from the bus is as limp as one with torque off.
        m.check(read(70 * MS), &[None]);
        m.check(other(80 * MS), &[s.write(4000)]);
        assert_eq!(m.report().violation_count, 0);
        m.check(read(90 * MS), &[s.held()]);
        m.check(other(90 * MS), &[s.write(4050)]);
        assert_eq!(m.report().violation_count, 1);
    }

    /// A firmware's torque-on tick: its goals, then the torque, then the tick's goals again. The
    /// goal held when the torque came on and those written in that tick start afresh; the next
    /// tick's step counts from the last of them.
    #[test]
    fn the_goals_of_the_tick_that_turns_the_torque_on_start_afresh() {
        let mut m = monitor();
        let mut s = Servo::on(2048);
        s.sample.torque = false;
        m.check(read(10 * MS), &[s.held()]);
        m.check(other(10 * MS), &[s.write(2000)]);
        // The servo holds where its horn stands when the torque comes on.
        s.sample = GoalSample { goal: 2040, torque: true, ..s.sample };
        m.check(other(10 * MS), &[s.held()]);
        m.check(other(10 * MS), &[s.write(2000)]);
        m.check(read(20 * MS), &[s.held()]);
        m.check(other(20 * MS), &[s.write(2011)]);
        let r = m.report();
        assert_eq!((r.checked, r.violation_count), (3, 0), "{:?}", r.violations);
        m.check(read(30 * MS), &[s.held()]);
        m.check(other(30 * MS), &[s.write(2023)]);
        assert_eq!(m.report().violation_count, 1, "{:?}", m.report().violations);
    }

    /// A gripper stopped on an object, its goal a squeeze past the contact; a new core adopts it
    /// and writes its goal back where the horn stands, 38 ticks from the last: no chase, no
    /// violation. The same step away from the horn is one.
    #[test]
    fn a_goal_back_at_the_horn_is_no_jump() {
        let mut m = monitor();
        let mut s = Servo::on(2313);
        s.sample.present = 2351;
        m.check(other(0), &[s.held()]);
        m.check(read(10 * MS), &[s.held()]);
        m.check(other(10 * MS), &[s.write(2313)]);
        m.check(read(900 * MS), &[s.held()]);
        m.check(other(900 * MS), &[s.write(2351)]);
        let r = m.report();
        assert_eq!((r.checked, r.violation_count), (3, 0), "{:?}", r.violations);
        assert_eq!(r.max_step_ratio, 0.0, "the goal is at the horn");
        m.check(read(910 * MS), &[s.held()]);
        m.check(other(910 * MS), &[s.write(2351 + 38)]);
        assert_eq!(m.report().violation_count, 1, "{:?}", m.report().violations);
    }

    fn packet(id: u8, instruction: Instruction<'_>) -> Vec<u8> {
        let mut buf = [0u8; 64];
        let n = STS3215.protocol.encode_instruction(&InstructionPacket { id, instruction }, &mut buf).unwrap();
        buf[..n].to_vec()
    }

    /// The same rules on a simulated bus, fed instruction bytes: the bus hands the monitor each
    /// frame of a burst in turn.
    #[test]
    fn it_watches_a_simulated_bus_frame_by_frame() {
        let items = STS3215.items;
        let mut bus = SimBus::new(STS3215.protocol, &STS3215, &[1], 1_000_000);
        let limit = GoalLimit { id: 1, goal_range: (1000, 3000), max_ticks_per_s: 1000.0 };
        let mut m = RealTimeMonitor::new(vec![limit]);
        let read = |address: u16| packet(BROADCAST, Instruction::SyncRead { address, length: 2, ids: &[1] });
        let position = read(items.present_position.address);
        let goal = |g: i64| {
            let mut data = [0u8; 2];
            items.goal_position.encode(g, STS3215.endian, &mut data).unwrap();
            packet(1, Instruction::Write { address: items.goal_position.address, data: &data })
        };
        let at = |bytes: Vec<u8>, t_ns: u64, bus: &mut SimBus, m: &mut RealTimeMonitor| {
            bus.receive_observed(&bytes, t_ns, &mut |bus, frame| m.observe(bus, frame));
            m.end_burst();
        };
        at(packet(1, Instruction::Write { address: items.torque_enable.address, data: &[1] }), MS, &mut bus, &mut m);
        assert_eq!(m.report().checked, 1);
        // Ten ticks' reads and goals in one burst (a read of another item among them is no tick).
        let mut burst = Vec::new();
        for k in 1..=10 {
            burst.extend_from_slice(&position);
            burst.extend_from_slice(&read(items.torque_enable.address));
            burst.extend_from_slice(&goal(2048 + 10 * k));
        }
        at(burst, 100 * MS, &mut bus, &mut m);
        let r = m.report().clone();
        assert_eq!(
            (r.checked, r.violation_count, r.ticks, r.max_ticks_per_burst),
            (11, 0, 10, 10),
            "{:?}",
            r.violations
        );
        assert_eq!(bus.stats().group_reads, 20);
        // 20 ticks in one tick.
        let mut burst = position.clone();
        burst.extend_from_slice(&goal(2048 + 100 + 20));
        at(burst, 110 * MS, &mut bus, &mut m);
        assert_eq!(m.report().violation_count, 1, "{:?}", m.report().violations);
    }

    /// The collision rule on a served SO-101 whose geometry is its frames as capsules on a table:
    /// a sync write of goals that folds the shoulder through the table is one goal configuration
    /// within the margin, named, and the bus stops the shoulder on the table; the goals back at
    /// the middle are judged free.
    #[test]
    fn goals_through_the_table_are_recorded_and_the_arm_stops_on_it() {
        let mut arm = crate::arm::ArmSpec::load("so101", None).unwrap();
        arm.collision = Some(crate::arm::collision::CollisionSpec::from_frames(&arm, 0.02));
        let config = crate::sim::arm_bus(&arm, crate::sim::Faults::default()).unwrap();
        let world = config.world.clone().expect("the arm's geometry");
        let mut bus = config.build();
        let mut m = RealTimeMonitor::new(config.limits.clone().unwrap()).with_collision(world.clone());
        let items = STS3215.items;
        let goals = |ticks: [i64; 5]| {
            let mut data = Vec::new();
            for (id, g) in (1u8..).zip(ticks) {
                let mut bytes = [0u8; 2];
                items.goal_position.encode(g, STS3215.endian, &mut bytes).unwrap();
                data.push(id);
                data.extend_from_slice(&bytes);
            }
            packet(BROADCAST, Instruction::SyncWrite { address: items.goal_position.address, length: 2, data: &data })
        };
        let at = |bytes: Vec<u8>, t_ns: u64, bus: &mut SimBus, m: &mut RealTimeMonitor| {
            bus.receive_observed(&bytes, t_ns, &mut |bus, frame| m.observe(bus, frame));
            m.end_burst();
        };
        let torque = Instruction::Write { address: items.torque_enable.address, data: &[1] };
        at(packet(BROADCAST, torque), MS, &mut bus, &mut m);
        // Shoulder lift 1.6 rad forward: the wrist below the table.
        at(goals([2048, 3091, 2048, 2048, 2048]), 2 * MS, &mut bus, &mut m);
        at(
            packet(BROADCAST, Instruction::SyncRead { address: items.present_position.address, length: 2, ids: &[1] }),
            1000 * MS,
            &mut bus,
            &mut m,
        );
        let record = m.report().contacts.clone().unwrap();
        assert_eq!((record.checked, record.count), (1, 1), "{}", record.summary());
        assert!(record.contacts[0].bodies.contains(&"table".to_string()), "{}", record.contacts[0]);
        assert!(m.report().summary().contains("1 of 1 goals within the 10 mm margin"), "{}", m.report().summary());
        let stopped = bus.servo(2).unwrap().get(items.present_position);
        assert!(stopped < 3091 - 100, "the shoulder stops on the table, at {stopped}");
        assert_eq!(bus.contact().unwrap().stats().last.as_ref().unwrap().1, [2]);
        at(goals([2048; 5]), 1010 * MS, &mut bus, &mut m);
        let record = m.report().contacts.clone().unwrap();
        assert_eq!((record.checked, record.count), (2, 1), "{}", record.summary());
    }
}
