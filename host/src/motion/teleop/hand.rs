//! A simulated leader: the leader arm's servos simulated on a pseudo-terminal, limp, and turned by
//! a scripted hand along a joint keyframe file (`t,q1,...,qN[,gripper]`, as `armctl play` reads),
//! straight from one keyframe to the next at a steady speed, as a person's hand would move a
//! horn. Teleoperation reads it as it reads a real leader: through the port, by sync read.
//!
//! Two keyframes a few milliseconds apart make the leader jump, which is how the tests check the
//! follower's clamp and limits.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};

use crate::arm::servos::{servos_of, ServoSetup};
use crate::arm::ArmSpec;
use crate::motion::trajectory::{read_keyframes, Keyframes};
use crate::sim::PtyServer;

/// The hand's script in each servo's own ticks: one row per keyframe, the joints' servos then the
/// gripper's.
struct Script {
    times: Vec<f64>,
    ticks: Vec<Vec<i64>>,
}

impl Script {
    /// `keyframes` as ticks of `servos`: each angle through its joint's mapping, the gripper's
    /// opening through its range. Fails, naming the line, for a value the servo cannot reach.
    fn of(keyframes: &Keyframes, arm: &ArmSpec, servos: &ServoSetup, path: &Path) -> Result<Self> {
        let shown = path.display();
        if keyframes.joints != arm.dof() {
            bail!("{shown}: {} joints, but the leader arm {} has {}", keyframes.joints, arm.name, arm.dof());
        }
        if keyframes.gripper.is_some() && servos.gripper.is_none() {
            bail!("{shown}: the file has a gripper column, but the leader arm {} has no gripper", arm.name);
        }
        let mut ticks = Vec::with_capacity(keyframes.times.len());
        for (i, q) in keyframes.positions.iter().enumerate() {
            let line = keyframes.lines[i];
            let mut row = Vec::with_capacity(q.len() + 1);
            for (j, &angle) in q.iter().enumerate() {
                let mapping = servos
                    .mapping(j)
                    .ok_or_else(|| anyhow!("leader arm {}: joint {} has no servo", arm.name, j + 1))?;
                let t = mapping
                    .to_ticks(angle)
                    .map_err(|e| anyhow!("{shown}: line {line}: joint {} at {angle} rad: {e:?}", j + 1))?;
                row.push(i64::from(t));
            }
            if let Some(g) = servos.gripper {
                // Without a gripper column the trigger rests half open.
                let pct = keyframes.gripper.as_ref().map_or(50.0, |c| c[i]);
                row.push(i64::from(g.ticks(pct)));
            }
            ticks.push(row);
        }
        Ok(Self { times: keyframes.times.clone(), ticks })
    }
}

/// Simulated leader servos and the hand that turns them.
pub struct SimLeader {
    server: PtyServer,
    ids: Vec<u8>,
    script: Arc<Script>,
    stop: Arc<AtomicBool>,
    hand: Option<JoinHandle<()>>,
}

impl SimLeader {
    /// Serves the leader `arm`'s servos on a pty (replies held by a `burst` latency timer, as
    /// through a USB adapter) with the horns at the script's first keyframe.
    pub fn spawn(arm: &ArmSpec, script: &Path, burst: Option<Duration>) -> Result<Self> {
        let servos = servos_of(arm)
            .ok_or_else(|| anyhow!("leader arm {} has no servo mapping: add a [servos] table", arm.name))?;
        let keyframes = read_keyframes(script)?;
        let script = Script::of(&keyframes, arm, &servos, script)?;
        let config = crate::sim::SimConfig {
            limits: None,
            burst,
            fixed_baud: false,
            ..crate::sim::arm_bus(arm, crate::sim::Faults::default())?
        };
        let server = PtyServer::spawn(config).context("cannot serve the simulated leader on a pseudo-terminal")?;
        let ids = servos.bus_ids();
        if let Some(first) = script.ticks.first() {
            for (&id, &t) in ids.iter().zip(first) {
                server.place(id, t);
            }
        }
        Ok(Self { server, ids, script: Arc::new(script), stop: Arc::new(AtomicBool::new(false)), hand: None })
    }

    /// The pty the leader's servos answer on.
    pub fn path(&self) -> &str {
        self.server.path()
    }

    /// How long the script runs.
    pub fn duration(&self) -> Duration {
        Duration::from_secs_f64(self.script.times.last().copied().unwrap_or(0.0).max(0.0))
    }

    /// Starts the hand: from now, each servo moves from keyframe to keyframe at the script's times.
    pub fn start(&mut self) -> Result<()> {
        let (script, ids, stop) = (self.script.clone(), self.ids.clone(), self.stop.clone());
        let hand = self.server.hand_handle();
        let thread = std::thread::Builder::new().name("sim-leader-hand".into()).spawn(move || {
            let started = Instant::now();
            for k in 1..script.times.len() {
                let (t0, t1) = (script.times[k - 1], script.times[k]);
                // Wait for the segment's start; the stop flag is looked at every 10 ms.
                loop {
                    if stop.load(Ordering::Relaxed) {
                        return;
                    }
                    let left = t0 - started.elapsed().as_secs_f64();
                    if left <= 0.0 {
                        break;
                    }
                    std::thread::sleep(Duration::from_secs_f64(left.min(0.01)));
                }
                for (s, &id) in ids.iter().enumerate() {
                    hand.turn(id, script.ticks[k - 1][s], script.ticks[k][s], t1 - t0);
                }
            }
        })?;
        self.hand = Some(thread);
        Ok(())
    }
}

impl Drop for SimLeader {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.hand.take() {
            let _ = t.join();
        }
    }
}
