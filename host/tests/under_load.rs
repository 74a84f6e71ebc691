//! The safety monitor under load (issue 43, item 5): with two busy loops beside it on this
//! two-core machine, the firmware core run on the PC drives simulated servos on a pty in real
//! time through the three ways there are to run it, random joint moves each followed by a status:
//!
//! 1. `armctl serve --sim`, driven by `armctl --port` commands, each a process of its own;
//! 2. `--bus` on the simulator: the core of a `--bus` connection (`Target::Bus`) on servos served
//!    on a pty, in this process;
//! 3. Python's `Arm(sim=True)`: the same calls its binding makes (`Place::target`,
//!    `Target::in_real_time`, `Driver::open`, `joints::joints`, `state::status`).
//!
//! Each counts 0 violations, and reports the late ticks, the monitor's figures and how many
//! control ticks the serving thread read at once. The busy loops start once the arm is connected
//! and stop before it is let go: connecting under them (finding the servos with 100 ms reply
//! margins, three tries) can fail when the serving thread is held up longer than that, which is
//! not what is measured here. Before the monitor judged goal writes one by one
//! over the ticks counted between them, such runs counted hundreds of violations where the
//! firmware's goals had all kept to one period's step (docs/figures.md).
//!
//! Each part runs `ARMCTL_LOAD_SECONDS` seconds (30 unless set): about two minutes in all.

use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

mod support;

use armctl::arm::servos::servos_of;
use armctl::arm::ArmSpec;
use armctl::commands::drive::joints::{self, JointsRequest};
use armctl::commands::drive::state;
use armctl::runtime::connection::{Place, Target};
use armctl::runtime::driver::Driver;
use armctl::runtime::pc::PcOptions;
use armctl::sim::{MonitorReport, PtyServer};

/// Busy loops beside the arm: as many as the machine the issue measured on has cores.
const BUSY_LOOPS: usize = 2;

/// How long each part runs.
fn seconds() -> Duration {
    let s = std::env::var("ARMCTL_LOAD_SECONDS").ok().and_then(|s| s.parse::<f64>().ok()).unwrap_or(30.0);
    Duration::from_secs_f64(s)
}

/// Threads that spin until dropped.
struct BusyLoops {
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

impl BusyLoops {
    fn start(n: usize) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let threads = (0..n)
            .map(|_| {
                let stop = stop.clone();
                std::thread::spawn(move || {
                    let mut x = 0u64;
                    while !stop.load(Ordering::Relaxed) {
                        x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
                    }
                })
            })
            .collect();
        Self { stop, threads }
    }
}

impl Drop for BusyLoops {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// Joint values drawn at random (xorshift, a fixed seed) inside the middle of each joint's range.
struct Targets {
    state: u64,
    ranges: Vec<(f64, f64)>,
    /// The arm's model, to keep only targets clear of its collision geometry (the table and its
    /// own links): the others would be refused, which is not what is measured here.
    model: Box<dyn armctl::arm::dof::DynArm>,
    last: Option<Vec<f64>>,
}

impl Targets {
    fn of(arm: &ArmSpec) -> Self {
        Self {
            state: 0x9E37_79B9_7F4A_7C15,
            ranges: arm.joints.iter().map(|j| (j.lower, j.upper)).collect(),
            model: armctl::arm::dof::build(arm.clone()).unwrap(),
            last: None,
        }
    }

    /// The next target: clear, and joined to the last (the arm's zero at first, where it starts)
    /// by a straight joint path that is clear too, so that no move needs planning around.
    fn next(&mut self) -> Vec<f64> {
        loop {
            let q = self.draw();
            let from = self.last.clone().unwrap_or_else(|| vec![0.0; q.len()]);
            let free = match armctl::motion::collision::Checker::of(self.model.as_ref()).unwrap() {
                Some(mut checker) => checker.is_free(&q) && checker.straight_free(&from, &q),
                None => true,
            };
            if free {
                self.last = Some(q.clone());
                return q;
            }
        }
    }

    fn draw(&mut self) -> Vec<f64> {
        let ranges = self.ranges.clone();
        ranges
            .iter()
            .map(|&(lo, hi)| {
                self.state ^= self.state << 13;
                self.state ^= self.state >> 7;
                self.state ^= self.state << 17;
                let u = (self.state >> 11) as f64 / (1u64 << 53) as f64;
                let (mid, half) = (0.5 * (lo + hi), 0.4 * (hi - lo));
                mid + (2.0 * u - 1.0) * half
            })
            .collect()
    }
}

fn join(values: &[f64]) -> String {
    values.iter().map(|v| format!("{v:.4}")).collect::<Vec<_>>().join(",")
}

/// What one part measured.
struct Part {
    name: &'static str,
    cycles: u32,
    checked: u64,
    violations: u64,
    line: String,
}

impl Part {
    fn assert_safe(&self) {
        eprintln!(
            "{} under {BUSY_LOOPS} busy loops, {} s, {} moves: {}",
            self.name,
            seconds().as_secs(),
            self.cycles,
            self.line
        );
        assert!(self.cycles > 0 && self.checked > 0, "{}: nothing was moved or checked: {}", self.name, self.line);
        assert_eq!(self.violations, 0, "{}: {}", self.name, self.line);
    }

    fn from_monitor(name: &'static str, cycles: u32, report: &MonitorReport, late: u32) -> Self {
        let mut line = format!("safety monitor: {}; {late} late ticks", report.summary());
        for v in report.violations.iter().take(5) {
            line.push_str(&format!("\n  {v}"));
        }
        Part { name, cycles, checked: report.checked, violations: report.violation_count, line }
    }
}

/// Drives `driver` with random joint moves, each followed by a status, for [`seconds`], busy
/// loops beside it; returns the moves made and the late ticks the last status counted.
fn drive(driver: &mut Driver, arm: &ArmSpec) -> (u32, u32) {
    let _busy = BusyLoops::start(BUSY_LOOPS);
    let mut targets = Targets::of(arm);
    let started = Instant::now();
    let (mut cycles, mut late, mut stops) = (0, 0, Vec::new());
    let mut notes = Vec::new();
    while started.elapsed() < seconds() {
        let request = JointsRequest::new(targets.next(), None, None, 60.0).unwrap();
        match joints::joints(driver, &request, &mut notes) {
            Ok(_) => {}
            Err(e) if stopped_safely(&e.to_string()) => stops.push(e.to_string()),
            Err(e) => panic!("joints: {e}"),
        }
        late = state::status(driver).unwrap_or_else(|e| panic!("status: {e}")).status.timing.overruns;
        cycles += 1;
    }
    println!("{} of {cycles} moves stopped short of their targets: {stops:#?}", stops.len());
    assert!(stops.len() * 4 <= cycles as usize, "{} of {cycles} moves stopped short: {stops:#?}", stops.len());
    (cycles, late)
}

/// Whether a move's error is one of the ways the arm stops safely short of its target: the
/// firmware's brake lookahead, which on a loaded PC (late ticks, a 25 ms period chosen from slow
/// reads) reaches further, stopping a path that grazes the margin ("the firmware stopped the arm
/// short of a collision"), or a joint found resting far from its setpoint and held there. Not a
/// violation, which is what is measured here. Seen on this machine under the busy loops: the
/// brake's stop ("gripper.2 and table are 9.8 mm apart (margin 10 mm)") and joints taken for
/// blocked far from their setpoints (shoulder_pan 0.975 rad, wrist_flex 0.4 rad), which the same
/// moves without the loops are not: a false stop of the blocked-joint check on a loaded PC, not
/// understood yet (docs/collisions.md). At most a quarter of the moves may stop so.
fn stopped_safely(error: &str) -> bool {
    error.contains("the firmware stopped the arm short of a collision")
        || (error.contains("short of its setpoint") && error.contains("every joint is now held where it stands"))
}

/// `armctl serve --sim`, driven by `armctl --port` processes.
fn serve_sim(arm: &ArmSpec) -> Part {
    let armctl = env!("CARGO_BIN_EXE_armctl");
    let (mut child, pty, errors) = support::serve(&["--sim", "--arm", "so101"]);
    let busy = BusyLoops::start(BUSY_LOOPS);
    let mut targets = Targets::of(arm);
    let started = Instant::now();
    let (mut cycles, mut stops) = (0, 0);
    let mut failed = None;
    while started.elapsed() < seconds() && failed.is_none() {
        for args in [vec!["joints".to_string(), format!("--q={}", join(&targets.next()))], vec!["status".to_string()]] {
            let out = Command::new(armctl).arg("--port").arg(&pty).args(&args).stdin(Stdio::null()).output().unwrap();
            let stderr = String::from_utf8_lossy(&out.stderr);
            if !out.status.success() && stopped_safely(&stderr) {
                stops += 1;
            } else if !out.status.success() {
                failed = Some(format!("{args:?}: {stderr}"));
            }
        }
        cycles += 1;
    }
    drop(busy);
    end(&mut child);
    let errors = errors.join().unwrap();
    if let Some(failed) = failed {
        panic!("serve --sim: {failed}\nserve's stderr: {errors}");
    }
    println!("serve --sim: {stops} of {cycles} moves stopped safely short of their targets");
    assert!(stops * 4 <= cycles, "{stops} of {cycles} moves stopped short: {errors}");
    // "safety monitor: N goals checked, V violations (...)" and "bus: ... L late".
    let monitor = errors.lines().find_map(|l| l.strip_prefix("safety monitor: ")).unwrap_or_else(|| panic!("{errors}"));
    let number = |text: &str, after: &str| -> u64 {
        let words: Vec<&str> = text.split_whitespace().collect();
        let at = words.iter().position(|w| w.trim_matches(',') == after).unwrap_or_else(|| panic!("{after}: {text}"));
        words[at - 1].parse().unwrap_or_else(|_| panic!("{after}: {text}"))
    };
    let bus =
        errors.lines().find(|l| l.starts_with("bus: ") && l.contains(" late")).unwrap_or_else(|| panic!("{errors}"));
    let line = format!("safety monitor: {monitor}; {} late ticks", number(bus, "late"));
    Part {
        name: "serve --sim",
        cycles,
        checked: number(monitor, "goals"),
        violations: number(monitor, "violations"),
        line,
    }
}

/// Stops `serve` with SIGTERM (the arm decelerates and holds), at most 60 s.
fn end(child: &mut Child) {
    let pid = child.id().to_string();
    let _ = Command::new("kill").args(["-TERM", &pid]).status();
    let asked = Instant::now();
    while asked.elapsed() < Duration::from_secs(60) {
        if let Some(status) = child.try_wait().unwrap() {
            assert!(status.success(), "serve ended with {status}");
            return;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let _ = child.kill();
    let _ = child.wait();
    panic!("serve did not stop within 60 s of SIGTERM");
}

/// `--bus` on simulated servos: the core of a `--bus` connection in this process.
fn bus_on_simulator(arm: &ArmSpec) -> Part {
    let servos = servos_of(arm).unwrap();
    let server =
        armctl::sim::serve_arm(arm, servos.baud, None, Default::default(), armctl::arm::collision::collision_of(arm))
            .unwrap();
    let options = PcOptions {
        path: server.path().to_string(),
        protocol: servos.model.protocol,
        baud: servos.baud,
        arm: arm.clone(),
        calibration_file: None,
        monitor: server.monitor_handle(),
        gravity: None,
    };
    let mut log = Vec::new();
    let mut driver = Driver::open(Target::Bus(Box::new(options)), Some("so101"), &mut log)
        .unwrap_or_else(|e| panic!("--bus: {e:#}\n{}", String::from_utf8_lossy(&log)));
    let (cycles, late) = drive(&mut driver, arm);
    drop(driver);
    Part::from_monitor("--bus on the simulator", cycles, &server.monitor().unwrap(), late)
}

/// Python's `Arm(sim=True)`, through the calls its binding makes.
fn python_arm_sim(arm: &ArmSpec) -> Part {
    let place = Place { sim: true, arm: Some("so101".into()), ..Place::default() };
    let mut said = Vec::new();
    let (target, servos) = place.target().unwrap().in_real_time().unwrap();
    let servos: PtyServer = servos.expect("Arm(sim) serves its servos on a pty");
    let mut driver = Driver::open(target, place.arm_name(), &mut said)
        .unwrap_or_else(|e| panic!("Arm(sim): {e:#}\n{}", String::from_utf8_lossy(&said)));
    let (cycles, late) = drive(&mut driver, arm);
    drop(driver);
    Part::from_monitor("Arm(sim)", cycles, &servos.monitor().unwrap(), late)
}

#[test]
fn busy_loops_beside_the_arm_cost_late_ticks_and_no_violation() {
    let arm = ArmSpec::load("so101", None).unwrap();
    let parts = [serve_sim(&arm), bus_on_simulator(&arm), python_arm_sim(&arm)];
    for part in &parts {
        part.assert_safe();
    }
}
