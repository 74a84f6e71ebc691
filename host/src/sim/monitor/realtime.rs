//! The safety monitor of a bus served in real time ([`crate::sim::pty::PtyServer`]): every goal a
//! servo receives is checked against its goal range, and its change since the goal before against
//! the velocity limit over the real time that passed between them.
//!
//! Which time a goal is judged at: a firmware's control tick starts with a group read of the
//! present positions, where its time step counts from, and writes the goals once the replies are
//! in. Behind a USB serial adapter the replies reach the PC in bursts (an FTDI chip holds what it
//! receives until its latency timer expires, 16 ms by default), so the goal writes arrive anywhere
//! up to a burst period into the tick, while the read requests arrive at the ticks' starts. So a
//! goal write is timed by the first group read that arrived since that servo's previous goal
//! write, or by its own arrival when no group read came in between.
//!
//! While a servo's torque is off its goals are not checked. When the torque comes back checking
//! starts afresh: the goal the servo then holds is checked against the range only and is where the
//! next step counts from, timed by the last group read before it (the read of the tick that turned
//! the torque on).
//!
//! Times are the bus's nanoseconds: on a pty, real time since the server started.

use crate::sim::SimBus;

use super::{Violation, MAX_VIOLATIONS};

/// An allowance for the scheduling of the thread that serves the bus: it stamps each burst when it
/// gets round to reading it, which on a loaded PC can be milliseconds after the bytes came, so the
/// time between two stamps can be shorter than the time between the firmware's ticks.
///
/// One control period at the firmware's 100 Hz: a firmware steps a goal at most one period's worth
/// per tick, so a tick's read stamped up to a period late still passes, while two periods' worth
/// at once (a made-up tick, a jump) still fails. 5 ms was too little on a CI machine running two
/// tests per core: a read stamped 9 ms late made a 13-tick gripper step look like 1.3 times its
/// speed.
pub const SLACK: std::time::Duration = std::time::Duration::from_millis(10);

/// Where one servo's goals must stay, in real time.
#[derive(Clone, Debug, PartialEq)]
pub struct GoalLimit {
    /// Servo id.
    pub id: u8,
    /// Lowest and highest goal allowed (ticks): the joint limits mapped to ticks.
    pub goal_range: (i64, i64),
    /// The velocity limit, ticks/s: two consecutive goals may differ by at most this times the time
    /// between them (plus [`SLACK`]), plus one tick of rounding.
    pub max_ticks_per_s: f64,
}

/// What one servo holds after a burst of instructions, for [`RealTimeMonitor::check`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GoalSample {
    /// Its goal, ticks.
    pub goal: i64,
    /// Writes that have reached its goal item so far.
    pub writes: u64,
    /// When the last of them arrived, ns.
    pub written_ns: u64,
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
}

impl MonitorReport {
    /// One line for people: `4236 goals checked, 0 violations (largest step 48% of the limit)`.
    pub fn summary(&self) -> String {
        format!(
            "{} goals checked, {} violations (largest step {:.0}% of the limit)",
            self.checked,
            self.violation_count,
            100.0 * self.max_step_ratio
        )
    }
}

/// Per servo: what was seen of it so far.
#[derive(Clone, Debug, Default)]
struct Track {
    /// Goal writes counted at the last look.
    writes: u64,
    /// The first group read since its last goal write, ns.
    read_since_write: Option<u64>,
    /// The goal last checked and the time it is judged at, ns; `None` while the torque is off.
    last: Option<(i64, u64)>,
}

/// Checks the goals servos receive in real time.
#[derive(Clone, Debug)]
pub struct RealTimeMonitor {
    limits: Vec<GoalLimit>,
    tracks: Vec<Track>,
    /// The last group read seen, ns.
    last_read: Option<u64>,
    report: MonitorReport,
}

impl RealTimeMonitor {
    /// A monitor of the servos of `limits`.
    pub fn new(limits: Vec<GoalLimit>) -> Self {
        let servos = limits.iter().map(|l| ServoRecord { id: l.id, ..ServoRecord::default() }).collect();
        Self {
            tracks: vec![Track::default(); limits.len()],
            limits,
            last_read: None,
            report: MonitorReport { servos, ..MonitorReport::default() },
        }
    }

    /// The limits checked.
    pub fn limits(&self) -> &[GoalLimit] {
        &self.limits
    }

    /// What it has found so far.
    pub fn report(&self) -> &MonitorReport {
        &self.report
    }

    /// Looks at `bus` after it received a burst at `at_ns` ([`SimBus::receive`] or
    /// [`SimBus::line_idle`]); a servo of the limits that is not on the bus counts as limp.
    pub fn observe(&mut self, bus: &SimBus, at_ns: u64) {
        let item = bus.model().items.goal_position;
        let servos: Vec<Option<GoalSample>> = self
            .limits
            .iter()
            .map(|l| {
                bus.servo(l.id).map(|s| GoalSample {
                    goal: s.get(item),
                    writes: s.goal_writes(),
                    written_ns: s.goal_written_ns(),
                    torque: s.torque(),
                })
            })
            .collect();
        self.check(at_ns, bus.last_group_reads_ns(), &servos);
    }

    /// Checks what the servos hold (in the order of the limits; `None`: not on the bus) after a
    /// burst at `at_ns` that carried group reads arriving at `group_reads_ns` (in order).
    pub fn check(&mut self, at_ns: u64, group_reads_ns: &[u64], servos: &[Option<GoalSample>]) {
        for (j, sample) in servos.iter().enumerate().take(self.limits.len()) {
            let Some(s) = *sample else {
                self.tracks[j].last = None;
                continue;
            };
            let track = &mut self.tracks[j];
            let written = s.writes > track.writes;
            // This burst's reads before and after the servo's last goal write (all after it when
            // none came in this burst).
            let split = if written { group_reads_ns.partition_point(|&r| r <= s.written_ns) } else { 0 };
            let (before, after) = group_reads_ns.split_at(split);
            // A new goal: when it is judged at, and the last read before it (for a fresh start).
            let new = written.then(|| {
                let stamp = track.read_since_write.or(before.first().copied()).unwrap_or(s.written_ns);
                let last_read = before.last().copied().or(self.last_read).unwrap_or(s.written_ns);
                track.writes = s.writes;
                track.read_since_write = None;
                (stamp, last_read)
            });
            track.read_since_write = track.read_since_write.or(after.first().copied());
            if !s.torque {
                track.last = None;
                continue;
            }
            let time = if written { s.written_ns } else { at_ns };
            match (track.last, new) {
                // The torque came back (or this is the first look): a fresh start.
                (None, Some((_, last_read))) => {
                    track.last = Some((s.goal, last_read));
                    self.judge(j, time, s.goal, None);
                }
                // Torque on without a goal write (the goal is where the horn stood): the next
                // goal counts from the last read, and reads up to now are behind it.
                (None, None) => {
                    let latest = group_reads_ns.last().copied().or(self.last_read).unwrap_or(at_ns);
                    track.last = Some((s.goal, latest));
                    track.read_since_write = None;
                    self.judge(j, time, s.goal, None);
                }
                (Some((previous, since)), Some((stamp, _))) => {
                    track.last = Some((s.goal, stamp));
                    self.judge(j, time, s.goal, Some((previous, stamp.saturating_sub(since))));
                }
                (Some(_), None) => {}
            }
        }
        if let Some(&r) = group_reads_ns.last() {
            self.last_read = Some(r);
        }
    }

    /// Checks servo `j`'s goal received at `time_ns` against its range, and against the velocity
    /// limit when it follows a goal `(previous, elapsed_ns)` earlier.
    fn judge(&mut self, j: usize, time_ns: u64, goal: i64, step: Option<(i64, u64)>) {
        let limit = &self.limits[j];
        let (lo, hi) = limit.goal_range;
        let mut wrong = Vec::new();
        self.report.checked += 1;
        self.report.servos[j].checked += 1;
        self.report.servos[j].last_goal = Some(goal);
        if goal < lo || goal > hi {
            wrong.push(format!("goal {goal} outside {lo}..={hi}"));
        }
        if let Some((previous, elapsed_ns)) = step {
            let seconds = elapsed_ns as f64 * 1e-9 + SLACK.as_secs_f64();
            let allowed = limit.max_ticks_per_s * seconds + 1.0;
            let change = (goal - previous).abs() as f64;
            let ratio = change / allowed;
            self.report.max_step_ratio = self.report.max_step_ratio.max(ratio);
            let servo = &mut self.report.servos[j];
            servo.max_step_ratio = servo.max_step_ratio.max(ratio);
            if change > allowed {
                wrong.push(format!(
                    "goal step {change} ticks ({previous} to {goal}) beyond {allowed:.1} in {:.1} ms",
                    elapsed_ns as f64 * 1e-6
                ));
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

    /// One servo, goals 0..=4095, 1000 ticks/s: 1 tick per ms, 5 ticks of slack, 1 of rounding.
    fn monitor() -> RealTimeMonitor {
        RealTimeMonitor::new(vec![GoalLimit { id: 1, goal_range: (0, 4095), max_ticks_per_s: 1000.0 }])
    }

    /// A servo fed by hand: its goal write count and time move with each goal.
    struct Servo {
        sample: GoalSample,
    }

    impl Servo {
        fn on(goal: i64) -> Self {
            Self { sample: GoalSample { goal, writes: 0, written_ns: 0, torque: true } }
        }

        fn write(&mut self, goal: i64, at_ns: u64) -> Option<GoalSample> {
            self.sample = GoalSample { goal, writes: self.sample.writes + 1, written_ns: at_ns, ..self.sample };
            Some(self.sample)
        }

        fn held(&self) -> Option<GoalSample> {
            Some(self.sample)
        }
    }

    #[test]
    fn a_slow_ramp_passes_and_a_jump_does_not() {
        let mut m = monitor();
        let mut s = Servo::on(2048);
        m.check(0, &[], &[s.held()]);
        // 9 ticks every 10 ms: 900 ticks/s, each write in a burst of its own 2 ms after its read.
        for k in 1..=50u64 {
            m.check(k * 10 * MS, &[k * 10 * MS], &[s.held()]);
            m.check(k * 10 * MS + 2 * MS, &[], &[s.write(2048 + 9 * k as i64, k * 10 * MS + 2 * MS)]);
        }
        let r = m.report();
        assert_eq!((r.checked, r.violation_count), (51, 0), "{:?}", r.violations);
        assert!(r.max_step_ratio > 0.4 && r.max_step_ratio < 1.0, "{}", r.max_step_ratio);
        // 25 ticks in 10 ms: beyond 10 + 10 + 1.
        m.check(510 * MS, &[510 * MS], &[s.held()]);
        m.check(512 * MS, &[], &[s.write(2048 + 9 * 50 + 25, 512 * MS)]);
        let r = m.report();
        assert_eq!(r.violation_count, 1);
        assert_eq!(r.violations[0].id, 1);
        assert!(r.violations[0].what.starts_with("goal step 25 ticks"), "{}", r.violations[0].what);
        assert_eq!(r.servos[0].violations, 1);
        assert_eq!(r.servos[0].last_goal, Some(2048 + 9 * 50 + 25));
        assert!(r.max_step_ratio > 1.0);
    }

    #[test]
    fn a_goal_outside_the_range_is_a_violation() {
        let mut m = RealTimeMonitor::new(vec![GoalLimit { id: 1, goal_range: (1000, 3000), max_ticks_per_s: 1e9 }]);
        let mut s = Servo::on(2048);
        m.check(0, &[], &[s.held()]);
        m.check(MS, &[], &[s.write(3000, MS)]);
        assert_eq!(m.report().violation_count, 0);
        m.check(2 * MS, &[], &[s.write(3001, 2 * MS)]);
        let r = m.report();
        assert_eq!(r.violation_count, 1);
        assert_eq!(r.violations[0].what, "goal 3001 outside 1000..=3000");
        assert!((r.violations[0].time - 0.002).abs() < 1e-12);
    }

    #[test]
    fn goals_arriving_late_behind_a_read_are_judged_from_the_reads_time() {
        // Reads 20 ms apart; the first tick's goal arrives 15 ms after its read, the second 1 ms
        // after: 6 ms apart by arrival, but 20 ms of the firmware's time.
        let run = |step: i64| {
            let mut m = monitor();
            let mut s = Servo::on(2048);
            m.check(0, &[], &[s.held()]);
            m.check(MS, &[MS], &[s.held()]);
            m.check(16 * MS, &[], &[s.write(2048, 16 * MS)]);
            m.check(21 * MS, &[21 * MS], &[s.held()]);
            m.check(22 * MS, &[], &[s.write(2048 + step, 22 * MS)]);
            m.report().clone()
        };
        // 20 ms allows 20 + 10 + 1 ticks; by arrival it would be 6 + 10 + 1.
        let r = run(31);
        assert_eq!(r.violation_count, 0, "{:?}", r.violations);
        assert!((r.max_step_ratio - 1.0).abs() < 1e-9, "{}", r.max_step_ratio);
        assert_eq!(run(32).violation_count, 1);

        // A read that came before a goal write in the same burst counts for it; one that came
        // after counts for the next; only the first read since a goal write counts.
        let run = |step2: i64, step3: i64| {
            let mut m = monitor();
            let mut s = Servo::on(2048);
            m.check(0, &[], &[s.held()]);
            // Judged at 9 ms.
            m.check(10 * MS, &[9 * MS], &[s.write(2048, 10 * MS)]);
            m.check(20 * MS, &[19 * MS], &[s.held()]);
            // Judged at 19 ms, 10 ms after the last: the read after it is the next tick's.
            m.check(30 * MS, &[30 * MS], &[s.write(2048 + step2, 30 * MS - 1000)]);
            m.check(35 * MS, &[35 * MS], &[s.held()]);
            // Judged at 30 ms, 11 ms after the last (16 ms if the read at 35 ms counted).
            m.check(45 * MS, &[], &[s.write(2048 + step2 + step3, 45 * MS)]);
            m.report().clone()
        };
        // 10 ms allow 10 + 10 + 1 ticks, 11 ms 22.
        let r = run(21, 22);
        assert_eq!(r.violation_count, 0, "{:?}", r.violations);
        assert_eq!(run(22, 22).violation_count, 1);
        let r = run(21, 23);
        assert_eq!(r.violation_count, 1);
        assert!(r.violations[0].what.ends_with("in 11.0 ms"), "{}", r.violations[0].what);
    }

    #[test]
    fn torque_off_stops_checking_and_torque_on_starts_afresh() {
        let mut m = monitor();
        let mut s = Servo::on(2048);
        m.check(0, &[], &[s.held()]);
        m.check(10 * MS, &[], &[s.write(2050, 10 * MS)]);
        assert_eq!(m.report().checked, 2);
        s.sample.torque = false;
        m.check(20 * MS, &[], &[s.held()]);
        // Limp: any goal, even outside the range, is not checked.
        m.check(30 * MS, &[30 * MS], &[s.write(9000, 30 * MS)]);
        m.check(40 * MS, &[40 * MS], &[s.write(100, 40 * MS)]);
        assert_eq!((m.report().checked, m.report().violation_count), (2, 0));
        // Torque on where the horn stands; the next goal counts from there, not from 2050.
        s.sample.torque = true;
        m.check(50 * MS, &[50 * MS], &[s.held()]);
        m.check(60 * MS, &[60 * MS], &[s.write(110, 60 * MS)]);
        let r = m.report();
        assert_eq!((r.checked, r.violation_count), (4, 0), "{:?}", r.violations);
        // A servo missing from the bus is as limp as one with torque off.
        m.check(70 * MS, &[70 * MS], &[None]);
        m.check(80 * MS, &[80 * MS], &[s.write(4000, 80 * MS)]);
        assert_eq!(m.report().violation_count, 0);
        m.check(90 * MS, &[90 * MS], &[s.write(4050, 90 * MS)]);
        assert_eq!(m.report().violation_count, 1);
    }

    fn packet(id: u8, instruction: Instruction<'_>) -> Vec<u8> {
        let mut buf = [0u8; 64];
        let n = STS3215.protocol.encode_instruction(&InstructionPacket { id, instruction }, &mut buf).unwrap();
        buf[..n].to_vec()
    }

    /// The same rules on a simulated bus, fed instruction bytes: the bus tells the group reads and
    /// goal writes of one burst apart.
    #[test]
    fn it_watches_a_simulated_bus() {
        let items = STS3215.items;
        let mut bus = SimBus::new(STS3215.protocol, &STS3215, &[1], 1_000_000);
        let limit = GoalLimit { id: 1, goal_range: (1000, 3000), max_ticks_per_s: 1000.0 };
        let mut m = RealTimeMonitor::new(vec![limit]);
        let read =
            packet(BROADCAST, Instruction::SyncRead { address: items.present_position.address, length: 2, ids: &[1] });
        let goal = |g: i64| {
            let mut data = [0u8; 2];
            items.goal_position.encode(g, STS3215.endian, &mut data).unwrap();
            packet(1, Instruction::Write { address: items.goal_position.address, data: &data })
        };
        let at = |bytes: Vec<u8>, t_ns: u64, bus: &mut SimBus, m: &mut RealTimeMonitor| {
            bus.receive(&bytes, t_ns);
            m.observe(bus, t_ns);
        };
        at(packet(1, Instruction::Write { address: items.torque_enable.address, data: &[1] }), MS, &mut bus, &mut m);
        assert_eq!(m.report().checked, 1);
        // The firmware's ticks overrun: each goal write goes out 16 ms after its read, in one
        // burst with the next tick's read.
        at(read.clone(), 10 * MS, &mut bus, &mut m);
        for k in 1..=10 {
            let mut burst = goal(2048 + 14 * k);
            burst.extend_from_slice(&read);
            at(burst, (10 + 16 * k as u64) * MS, &mut bus, &mut m);
        }
        let r = m.report().clone();
        assert_eq!((r.checked, r.violation_count), (11, 0), "{:?}", r.violations);
        assert!(r.max_step_ratio > 0.5, "{}", r.max_step_ratio);
        assert_eq!(bus.stats().group_reads, 11);
        // 40 ticks in 16 ms.
        at(goal(2048 + 140 + 40), (10 + 16 * 11) * MS, &mut bus, &mut m);
        assert_eq!(m.report().violation_count, 1, "{:?}", m.report().violations);
    }
}
