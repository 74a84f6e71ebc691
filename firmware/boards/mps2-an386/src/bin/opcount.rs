//! Instruction counts of the firmware's per-tick operations on the Cortex-M4F, under
//! `qemu-system-arm -icount shift=0` (`armctl bench mcu` runs it and prints the table), and of the
//! kinematic tree's in f32 (`kinematics::tree`, not in the firmware yet), with the stack its IK
//! takes, measured by painting.
//!
//! With `-icount shift=0` QEMU runs one guest instruction per virtual nanosecond, and SysTick on the
//! 25 MHz core clock counts one tick per 40 ns, so one tick is 40 instructions, the same on every
//! run and every host. DWT CYCCNT reads 0 under QEMU, which is why SysTick is the counter.
//!
//! Each operation runs `reps` times between two SysTick reads; the host subtracts the cost of a
//! loop of the same shape doing nothing (`op empty`) and divides by `reps`. The inputs go through
//! `black_box`, and so do the results, so the compiler can neither hoist the work out of the loop
//! nor drop it. `op calib_nop` checks the tick-to-instruction factor itself: a loop of a known
//! number of instructions (hand-written, so the compiler cannot change it).
//!
//! Output, one defmt line per operation: `op NAME reps=R ticks=T [more key=value]`, or
//! `op NAME reps=R wrapped` when a batch overran the 24-bit counter (it would then be wrong).
#![no_std]
#![no_main]

use core::hint::black_box;

use board_mps2_an386::{clock, halt, stack};
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use cortex_m_rt::entry;
use firmware::bus::instruction::RecordWriter;
use firmware::bus::master::MAX_GROUP;
use firmware::bus::stream::StreamDecoder;
use firmware::bus::table::{Model, STS3215, XL430_W250};
use firmware::bus::{Id, Instruction, InstructionPacket, Status, BROADCAST};
use firmware::controller::gripper::Gripper;
use firmware::controller::Config;
use firmware::tracking::Tracker;
use kinematics::collision::{Body, Capsule, Part, Scene, Shape};
use kinematics::dynamics::{Dynamics, Inertia};
use kinematics::ik::{DampedLeastSquares, IkConfig, IkMethod, IkStatus, Residual, Target};
use kinematics::nalgebra::{ComplexField, Matrix3, SVector, Vector3};
use kinematics::trajectory::{JointLimits, Player, PlayerKeyframe};
use kinematics::tree::{Effector, EffectorTarget, Tree, TreeProblem, TreeSolution, TreeStatus};
use kinematics::{presets, Joint, Limits, Pose};

/// Guest instructions per SysTick tick: 1 instruction per ns (`-icount shift=0`) over a 25 MHz clock.
const INSTRUCTIONS_PER_TICK: u32 = 1_000_000_000 / clock::SYSCLK_HZ;
/// Repetitions of each operation: enough that the 40-instruction resolution of a tick is below one
/// instruction per operation, few enough that the slowest batch (about 50,000 instructions an IK
/// step) stays far inside the counter's 2^24 ticks (671 million instructions).
const REPS: u32 = 100;
/// Repetitions of the empty loop: more than [`REPS`], so its few instructions are resolved to a
/// hundredth (it is subtracted from every operation).
const EMPTY_REPS: u32 = 10_000;
/// Iterations of the calibration loop (10 instructions each: a million instructions, 25,000 ticks).
const CALIB_ITERATIONS: u32 = 100_000;
/// Instructions in one iteration of the calibration loop.
const CALIB_INSTRUCTIONS: u32 = 10;
/// The joints of the measured arm (the UR5e preset: the 6-joint case).
const J: usize = 6;
/// The bus master's default buffer size (`Master<P, D, C>` without a `BUF`).
const BUF: usize = 256;
/// The joint values the arm sits at: away from the UR5e's singularities (elbow bent, wrist not
/// aligned with the shoulder), as a tracking arm would be.
const SEED: [f32; J] = [0.3, -1.2, 1.4, -1.6, -1.5, 0.2];
/// The joints of the measured tree: the kinematics' two-arm test body, a torso that turns and two
/// five-joint SO-101 arms on it.
const TREE_J: usize = 11;
/// Its joint values: the torso turned a little, each arm as the firmware's tracking test holds it.
const TREE_SEED: [f32; TREE_J] = [0.2, 0.1, -0.4, 0.6, 0.8, 0.0, 0.1, -0.4, 0.6, 0.8, 0.0];

extern "C" {
    /// The initial stack pointer (top of RAM), from cortex-m-rt's linker script.
    static _stack_start: u32;
}

#[entry]
fn main() -> ! {
    let Some(core) = cortex_m::Peripherals::take() else { halt() };
    let mut syst = core.SYST;
    // Free-running over the full 24 bits and without the interrupt: `clock::start` interrupts
    // every millisecond, and its handler's instructions would be counted as the operation's.
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(0x00FF_FFFF);
    syst.clear_current();
    syst.disable_interrupt();
    syst.enable_counter();
    defmt::info!(
        "clock core_hz={=u32} instructions_per_tick={=u32} (-icount shift=0: 1 instruction per ns)",
        clock::SYSCLK_HZ,
        INSTRUCTIONS_PER_TICK
    );

    let ticks = measure(&mut syst, 1, || nops(CALIB_ITERATIONS));
    report_with("calib_nop", CALIB_ITERATIONS, ticks, "expected", CALIB_INSTRUCTIONS);

    report("empty", EMPTY_REPS, measure(&mut syst, EMPTY_REPS, || black_box(0u32)));
    kinematics_ops(&mut syst);
    tree_ops(&mut syst);
    collision_ops(&mut syst);
    bus_ops(&mut syst, &STS3215, "sts");
    bus_ops(&mut syst, &XL430_W250, "dxl2");

    defmt::info!("done");
    cortex_m_semihosting::debug::exit(cortex_m_semihosting::debug::EXIT_SUCCESS);
    halt()
}

/// FK, one DLS iteration, a tracking IK step and a player tick on the 6-joint arm, in `f32` as the
/// firmware's controller runs them.
fn kinematics_ops(syst: &mut SYST) {
    let Ok(chain) = presets::ur5e::<f32>() else { halt() };
    let q = SVector::<f32, J>::from(SEED);
    // `forward`, every joint frame and the tool: the one FK the firmware links.
    report("fk6", REPS, measure(syst, REPS, || chain.forward(black_box(&q))));
    // Inverse dynamics of the same arm (recursive Newton-Euler, gravity included), each link a
    // kilogram 10 cm along its frame's z: what gravity compensation and a servo model run.
    let link = Inertia {
        mass: 1.0,
        com: Vector3::new(0.0, 0.0, 0.1),
        tensor: Matrix3::from_diagonal(&Vector3::new(2e-3, 3e-3, 4e-3)),
    };
    let Ok(dynamics) = Dynamics::<f32, J>::new([link; J]) else { halt() };
    let (qd, qdd) = (SVector::<f32, J>::repeat(0.5), SVector::<f32, J>::repeat(1.0));
    let ticks =
        measure(syst, REPS, || dynamics.inverse(black_box(&chain), black_box(&q), black_box(&qd), black_box(&qdd)));
    report("rnea6", REPS, ticks);
    // FK's sine and cosine of each joint, apart: the kinematics' own f32 version, and libm's
    // `sincosf` for comparison, which computes in f64 (software on the M4F's single-precision FPU).
    let angle = SEED[3];
    report("sincos", REPS, measure(syst, REPS, || kinematics::trig::sin_cos(black_box(angle))));
    report("sincos_libm", REPS, measure(syst, REPS, || <f32 as ComplexField>::sin_cos(black_box(angle))));

    // The tracking goal moves 1 cm (6 mm in x, 8 mm in y), orientation kept: a full-pose target,
    // the harder of the two the tracker takes.
    let here = chain.tool_pose(&q);
    let target =
        Target::Pose(Pose { rotation: here.rotation, translation: here.translation + Vector3::new(0.006, 0.008, 0.0) });

    // One iteration of the default solver's descent, as `Chain::solve` runs it (an FK and the
    // error at the start, the damped step, an FK and the error of the trial), without the
    // solve's validation and final check.
    let residual = Residual::new(target, &IkConfig::default());
    let descent = DampedLeastSquares.descend(&chain, &residual, q, 1);
    let ticks =
        measure(syst, REPS, || DampedLeastSquares.descend(black_box(&chain), black_box(&residual), black_box(q), 1));
    report_with("dls_iter", REPS, ticks, "iterations", descent.iterations);

    // The firmware's tracking step with its own budget (`Config::default().ik_iterations_per_tick`),
    // warm-started from where the arm is; a fresh tracker each time, so every repetition solves
    // the same step.
    let budget = Config::default().ik_iterations_per_tick;
    let solution = Tracker::new(q, budget).step(&chain, target);
    let ticks = measure(syst, REPS, || Tracker::new(black_box(q), budget).step(&chain, black_box(target)));
    report_with("ik_track_1cm", REPS, ticks, "iterations", solution.iterations);
    if solution.status != IkStatus::Converged {
        defmt::warn!("ik_track_1cm did not converge within {=u32} iterations", budget);
    }

    // The player as the controller ticks it: 32 keyframes queued, the clock at 1 kHz inside the
    // first segment (as the host-side criterion bench `player_tick` does).
    let Ok(limits) = JointLimits::<f32, J>::new(
        SVector::repeat(-3.0),
        SVector::repeat(3.0),
        SVector::repeat(2.0),
        SVector::repeat(10.0),
    ) else {
        halt()
    };
    let Ok(mut player) = Player::<f32, J, 32>::new(SVector::zeros(), limits) else { halt() };
    for i in 1..=32u16 {
        let p = SVector::from_fn(|j, _| 0.05 * f32::from((i + j as u16) % 5));
        if player.push(PlayerKeyframe::new(0.5 * f32::from(i), p)).is_err() {
            halt()
        }
    }
    player.tick(0.0);
    let mut now = 0.0f32;
    let ticks = measure(syst, REPS, || {
        now += 0.001;
        player.tick(black_box(now))
    });
    report("hermite6", REPS, ticks);

    // The same tick with the gripper as the controller steps it after the player: its own track
    // of keyframes (one per joint keyframe) sampled on the playback clock, then its ramp.
    let mut gripper = Gripper::<32>::new(firmware::builtin::GRIPPER);
    gripper.observe(gripper.ticks_of(50.0));
    gripper.push(0.5, 100.0, Some(0.0));
    for i in 2..=30u16 {
        gripper.push(0.5 * f32::from(i), f32::from(i % 2) * 100.0, None);
    }
    let ticks = measure(syst, REPS, || {
        now += 0.001;
        let player = player.tick(black_box(now));
        gripper.step(0.001, Some(black_box(now)));
        player
    });
    black_box(gripper.state());
    report("hermite6_gripper", REPS, ticks);
}

/// The kinematics' two-arm test body (`kinematics/tests/suite/tree.rs`): a torso joint turning
/// about z, 0.3 m up, then the left SO-101's five joints, then the right's, each arm 0.2 m to its
/// side of the torso's axis, a hand on each.
fn two_arm_body() -> Option<Tree<f32, TREE_J, 2>> {
    let arm = presets::so101::<f32>().ok()?;
    let torso_origin = Pose::from_xyz_rpy([0.0, 0.0, 0.3], [0.0; 3]);
    let torso = Joint::revolute(torso_origin, [0.0, 0.0, 1.0], Limits::new(-1.5, 1.5));
    let joints = core::array::from_fn(|i| {
        if i == 0 {
            return torso;
        }
        let (side, k) = ((i - 1) / 5, (i - 1) % 5);
        let mut joint = arm.joints()[k];
        if k == 0 {
            let y = if side == 0 { 0.2 } else { -0.2 };
            joint.origin = Pose::from_xyz_rpy([0.0, y, 0.0], [0.0; 3]).compose(&joint.origin);
        }
        joint
    });
    // Each arm's first joint hangs on the torso, every other joint on the one before it.
    let parents = core::array::from_fn(|i| match i {
        0 => None,
        _ if (i - 1) % 5 == 0 => Some(0),
        _ => Some(i - 1),
    });
    let hand = |joint| Effector { joint: Some(joint), offset: *arm.tool() };
    Tree::new(joints, parents, [hand(5), hand(10)]).ok()
}

/// The tree in f32 on the two-arm body: FK of every frame, both hands' Jacobians, and a tracking
/// solve of both hands at once. (`Tree::solve` has no public single step, so there is no
/// per-iteration count as the chain's `dls_iter`.)
fn tree_ops(syst: &mut SYST) {
    let Some(tree) = two_arm_body() else { halt() };
    let q = SVector::<f32, TREE_J>::from(TREE_SEED);
    // The tree goes through `black_box` too: built here, its parents and paths would otherwise be
    // constants the compiler could fold into the code, as they cannot be in a firmware that
    // receives its body at run time.
    report("tree_fk", REPS, measure(syst, REPS, || black_box(&tree).forward(black_box(&q))));

    let frames = tree.forward(&q);
    let ticks = measure(syst, REPS, || {
        let (tree, frames) = (black_box(&tree), black_box(&frames));
        [tree.jacobian_of(frames, 0), tree.jacobian_of(frames, 1)]
    });
    report("tree_jacobian", REPS, ticks);

    // Both hands' goals move 1 cm (6 mm forward, 8 mm outward), positions only, solved from where
    // the body is with the firmware's tracking budget and no restart, as `Tracker` solves a chain.
    let budget = Config::default().ik_iterations_per_tick;
    let config =
        IkConfig { max_iterations: budget, attempt_iterations: budget, max_restarts: 0, ..IkConfig::default() };
    let target = |hand: &Pose<f32>, outward: f32| {
        let position = hand.translation + Vector3::new(0.006, outward, 0.0);
        Some(EffectorTarget { position, rotation: None, weight: 1.0, priority: 0 })
    };
    let [left, right] = frames.effectors;
    let problem = TreeProblem { targets: [target(&left, 0.008), target(&right, -0.008)], seed: q, config };
    // Called through a pointer the compiler cannot see through, so the solve has its own frames
    // below the caller's and the stack it takes is what painting finds below the caller.
    let solve: fn(&Tree<f32, TREE_J, 2>, &TreeProblem<f32, TREE_J, 2>) -> TreeSolution<f32, TREE_J, 2> = Tree::solve;
    let (solution, stack_bytes) = stack_use(|| black_box(solve)(&tree, &problem));
    let ticks = measure(syst, REPS, || black_box(&tree).solve(black_box(&problem)));
    report_with2("tree_ik_track_1cm", REPS, ticks, ("iterations", solution.iterations), ("stack_bytes", stack_bytes));
    if solution.status != TreeStatus::Converged {
        defmt::warn!("tree_ik_track_1cm did not converge within {=u32} iterations", budget);
    }
}

/// What `op` returns, and the bytes of stack it takes below the caller's frame, found by painting
/// the stack first ([`stack`]). Only what `op` calls is below the frame: what the compiler inlines
/// into this function is not counted, so `op` should call through a pointer.
#[inline(never)]
fn stack_use<R>(op: impl FnOnce() -> R) -> (R, u32) {
    stack::paint();
    let sp = cortex_m::register::msp::read() as usize;
    let result = black_box(op());
    // Only the symbol's address is taken, which is safe.
    let top = core::ptr::addr_of!(_stack_start) as usize;
    let below = stack::high_water().saturating_sub(top.saturating_sub(sp));
    (result, u32::try_from(below).unwrap_or(u32::MAX))
}

/// Encoding the sync write of six goals and decoding the six replies of a sync read, for `model`.
fn bus_ops(syst: &mut SYST, model: &'static Model, protocol: &'static str) {
    let ids: [Id; J] = [1, 2, 3, 4, 5, 6];
    let goals: [i32; J] = [1024, 1536, 2048, 2560, 3072, 3584];
    let mut tx = [0u8; BUF];
    let name = if protocol == "sts" { "sync_write6_sts" } else { "sync_write6_dxl2" };
    let bytes = encode_sync_write(model, &ids, &goals, &mut tx).unwrap_or(0);
    let ticks =
        measure(syst, REPS, || encode_sync_write(model, black_box(&ids), black_box(&goals), black_box(&mut tx)));
    report_with(name, REPS, ticks, "bytes", bytes as u32);

    // The replies as the servos send them, back to back, encoded once by the crate's own encoder.
    let mut replies = [0u8; BUF];
    let mut len = 0;
    for (&id, &goal) in ids.iter().zip(&goals) {
        let item = model.items.present_position;
        let mut data = [0u8; 4];
        if item.encode(i64::from(goal), model.endian, &mut data).is_err() {
            halt()
        }
        let Some(params) = data.get(..item.len()) else { halt() };
        let status = Status { id, error: 0, params };
        let Some(free) = replies.get_mut(len..) else { halt() };
        let Ok(n) = model.protocol.encode_status(&status, free) else { halt() };
        len += n;
    }
    let Some(replies) = replies.get(..len) else { halt() };
    let mut decoder = StreamDecoder::<BUF>::new(model.protocol);
    let mut positions = [0i32; J];
    let answered = decode_sync_read(model, &ids, replies, &mut decoder, &mut positions);
    if answered != 0b11_1111 || positions != goals {
        defmt::error!("sync read decoding lost replies: answered {=u32:#b}", answered);
    }
    let name = if protocol == "sts" { "sync_read6_sts" } else { "sync_read6_dxl2" };
    let ticks = measure(syst, REPS, || {
        decode_sync_read(model, black_box(&ids), black_box(replies), &mut decoder, black_box(&mut positions))
    });
    report_with(name, REPS, ticks, "bytes", len as u32);
}

/// What `ServoGroup::write_all` and `Master::send` compute for a sync write of goal positions: the
/// records, then the packet into the transmit buffer. Returns the packet's length.
fn encode_sync_write(model: &Model, ids: &[Id; J], goals: &[i32; J], tx: &mut [u8]) -> Option<usize> {
    let item = model.items.goal_position;
    let mut records = [0u8; MAX_GROUP * 5];
    let mut writer = RecordWriter::new(&mut records);
    let mut value = [0u8; 4];
    for (&id, &goal) in ids.iter().zip(goals) {
        item.encode(i64::from(goal), model.endian, &mut value).ok()?;
        writer.sync_write(id, value.get(..item.len())?).ok()?;
    }
    let len = writer.records().len();
    let instruction =
        Instruction::SyncWrite { address: item.address, length: u16::from(item.size), data: records.get(..len)? };
    model.protocol.encode_instruction(&InstructionPacket { id: BROADCAST, instruction }, tx).ok()
}

/// What `Master::receive` and `ServoGroup::read_all` compute from the bytes of a sync read's
/// replies, without the port and the clock: 32-byte chunks into the stream decoder, each frame
/// parsed and its data booked by id, then the positions decoded. Returns the answered mask.
fn decode_sync_read(
    model: &Model,
    ids: &[Id; J],
    replies: &[u8],
    decoder: &mut StreamDecoder<BUF>,
    positions: &mut [i32; J],
) -> u32 {
    let item = model.items.present_position;
    let len = item.len();
    let mut raw = [0u8; MAX_GROUP * 4];
    let mut answered = 0u32;
    decoder.clear();
    for chunk in replies.chunks(32) {
        let mut rest = chunk;
        while !rest.is_empty() {
            let taken = decoder.extend(rest);
            rest = &rest[taken..];
            while let Some(frame) = decoder.next_frame() {
                let Ok(status) = model.protocol.parse_status(frame) else { continue };
                let Some(i) = ids.iter().position(|&id| id == status.id) else { continue };
                if status.params.len() == len && answered & (1 << i) == 0 {
                    if let Some(slot) = raw.get_mut(i * len..(i + 1) * len) {
                        slot.copy_from_slice(status.params);
                        answered |= 1 << i;
                    }
                }
            }
        }
    }
    for (i, v) in positions.iter_mut().enumerate() {
        if answered & (1 << i) != 0 {
            if let Some(Ok(x)) = raw.get(i * len..(i + 1) * len).map(|bytes| item.decode(bytes, model.endian)) {
                *v = x.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
            }
        }
    }
    answered
}

/// Poses of the SO-101 (rad) the collision check is timed at: across the joint ranges, every one
/// free of contact with the scenes below, so each check runs to the end (a check that finds a
/// contact stops at it, sooner).
const COLLISION_POSES: [[f32; 5]; 9] = [
    [0.0, 0.0, 0.0, 0.0, 0.0],
    [0.5, -0.4, 0.6, 0.3, 0.0],
    [-0.6, 0.3, -0.5, 0.8, 1.0],
    [1.2, -1.0, 1.2, -0.5, -1.5],
    [-1.4, 0.5, 0.3, 0.4, 2.0],
    [0.3, -0.8, -0.6, 1.0, 0.5],
    [-0.2, 0.2, 0.9, -0.9, -0.7],
    [0.9, -0.3, -1.2, 0.6, 1.4],
    [-1.0, -0.6, 0.4, -0.2, -2.0],
];

/// The SO-101's bodies as the host's `CollisionSpec::from_frames` makes them: the base from its
/// origin to the first joint, each link from its joint to the next (the last to the tool), 20 mm
/// radius, cut into `per_link` capsules along it; bodies on neighbouring frames are allowed to
/// touch (they meet at the joint between), and the base's to stand on the table (obstacle 0).
fn so101_bodies<const B: usize, const O: usize>(
    chain: &kinematics::Chain<f32, 5>,
    scene: &mut Scene<f32, B, O>,
    per_link: usize,
) -> Option<()> {
    let origin = Vector3::zeros();
    let ends = |k: usize| chain.joints().get(k + 1).map_or(chain.tool().translation, |j| j.origin.translation);
    let first = chain.joints().first()?.origin.translation;
    let frames = core::iter::once((None, first)).chain((0..5).map(|k| (Some(k as u8), ends(k))));
    // Each body's frame as a number, the base's 0 and joint k's k + 1: neighbours differ by 1.
    let mut rank = [0u8; 32];
    for (frame, end) in frames {
        for i in 0..per_link {
            let (t0, t1) = (i as f32 / per_link as f32, (i + 1) as f32 / per_link as f32);
            let capsule = Capsule { a: origin + end * t0, b: origin + end * t1, radius: 0.02 };
            let index = scene.add_body(Body { frame, capsule }, 5).ok()?;
            *rank.get_mut(usize::from(index))? = frame.map_or(0, |f| f + 1);
        }
    }
    let n = scene.bodies().len() as u8;
    for i in 0..n {
        for j in (i + 1)..n {
            let (a, b) = (*rank.get(usize::from(i))?, *rank.get(usize::from(j))?);
            if a.abs_diff(b) == 1 {
                scene.allow(i, Part::Body(j)).ok()?;
            }
        }
        if *rank.get(usize::from(i))? == 0 {
            scene.allow(i, Part::Obstacle(0)).ok()?;
        }
    }
    Some(())
}

/// One full collision check as the controller runs it per sample of a brake path (forward
/// kinematics of every joint frame, then every checked pair: bounding spheres first, exact
/// distances where they come within the margin), on the SO-101: with its six frame capsules, the
/// table and a box (the case), and at the firmware's capacity (24 bodies, 8 obstacles).
/// Each is timed at every pose of [`COLLISION_POSES`]; the line reports the median pose's count.
fn collision_ops(syst: &mut SYST) {
    let Ok(chain) = presets::so101::<f32>() else { halt() };
    let mut small: Scene<f32, 24, 8> = Scene::new(0.01);
    let table = Shape::table(0.0);
    let cube = Shape::aligned_box(Vector3::new(0.25, -0.2, 0.05), Vector3::repeat(0.1));
    if small.add_obstacle(table).is_err() || small.add_obstacle(cube).is_err() {
        halt()
    }
    if so101_bodies(&chain, &mut small, 1).is_none() {
        halt()
    }
    time_check(syst, "collision_so101", &chain, &mut small);

    // The worst case: four capsules per link and the base (24), the table and seven obstacles
    // around the arm's workspace (boxes, a tilted one, capsules, spheres).
    let mut full: Scene<f32, 24, 8> = Scene::new(0.01);
    let tilted = kinematics::axis_angle_matrix(&Vector3::new(0.0, 0.0, 1.0), 0.5);
    let around = [
        table,
        cube,
        Shape::aligned_box(Vector3::new(-0.2, 0.2, 0.1), Vector3::new(0.1, 0.1, 0.2)),
        Shape::Box { centre: Vector3::new(0.1, 0.3, 0.3), rotation: tilted, half: Vector3::new(0.05, 0.1, 0.02) },
        Shape::Capsule(Capsule { a: Vector3::new(0.4, 0.2, 0.0), b: Vector3::new(0.4, 0.2, 0.4), radius: 0.03 }),
        Shape::Capsule(Capsule { a: Vector3::new(-0.3, -0.3, 0.2), b: Vector3::new(0.0, -0.4, 0.2), radius: 0.02 }),
        Shape::Capsule(Capsule::sphere(Vector3::new(0.0, 0.0, 0.55), 0.05)),
        Shape::Capsule(Capsule::sphere(Vector3::new(0.45, -0.1, 0.3), 0.04)),
    ];
    for shape in around {
        if full.add_obstacle(shape).is_err() {
            halt()
        }
    }
    if so101_bodies(&chain, &mut full, 4).is_none() {
        halt()
    }
    time_check(syst, "collision_24x8", &chain, &mut full);
}

/// Times one check of `scene` at each pose of [`COLLISION_POSES`] free of contact (a check that
/// finds one stops there, sooner) and reports the median, with the poses timed and those left out.
fn time_check<const B: usize, const O: usize>(
    syst: &mut SYST,
    name: &str,
    chain: &kinematics::Chain<f32, 5>,
    scene: &mut Scene<f32, B, O>,
) {
    let mut counts = [0u32; COLLISION_POSES.len()];
    let mut timed = 0;
    for pose in COLLISION_POSES {
        let q = SVector::<f32, 5>::from(pose);
        if scene.first_contact(&chain.forward(&q).joints).is_some() {
            continue;
        }
        let ticks = measure(syst, REPS, || {
            let frames = chain.forward(black_box(&q));
            scene.first_contact(black_box(&frames.joints))
        });
        let Some(ticks) = ticks else { return report(name, REPS, None) };
        if let Some(slot) = counts.get_mut(timed) {
            *slot = ticks;
            timed += 1;
        }
    }
    let Some(free) = counts.get_mut(..timed) else { halt() };
    free.sort_unstable();
    let median = free.get(timed / 2).copied();
    let skipped = (COLLISION_POSES.len() - timed) as u32;
    report_with2(name, REPS, median, ("poses", timed as u32), ("in_contact", skipped));
}

/// SysTick ticks taken by `reps` calls of `op`, or `None` if the 24-bit counter wrapped (the batch
/// took 2^24 ticks or more, and the difference of the two reads would be wrong).
fn measure<R>(syst: &mut SYST, reps: u32, mut op: impl FnMut() -> R) -> Option<u32> {
    // Restarting the counter puts it at the top of its range, so a wrap means an overrun.
    syst.clear_current();
    let start = loop {
        let now = SYST::get_current();
        // Just after the clear the counter reads 0 until it reloads.
        if now != 0 {
            break now;
        }
    };
    // Reading COUNTFLAG clears it: the reload after the clear must not count as a wrap.
    let _ = syst.has_wrapped();
    for _ in 0..reps {
        black_box(op());
    }
    let end = SYST::get_current();
    if syst.has_wrapped() {
        None
    } else {
        Some(start - end)
    }
}

/// Runs a loop of exactly [`CALIB_INSTRUCTIONS`] instructions per iteration `iterations` times
/// (at least once).
#[inline(never)]
fn nops(iterations: u32) {
    // SAFETY: the loop uses only the register it is given (counting it down to zero) and the
    // flags, touches no memory and no stack.
    unsafe {
        core::arch::asm!(
            "2:",
            "nop", "nop", "nop", "nop", "nop", "nop", "nop", "nop",
            "subs {n}, {n}, #1",
            "bne 2b",
            n = inout(reg) iterations.max(1) => _,
            options(nomem, nostack),
        );
    }
}

fn report(name: &str, reps: u32, ticks: Option<u32>) {
    match ticks {
        Some(ticks) => defmt::info!("op {=str} reps={=u32} ticks={=u32}", name, reps, ticks),
        None => defmt::error!("op {=str} reps={=u32} wrapped", name, reps),
    }
}

/// [`report`] with one more `key=value` field.
fn report_with(name: &str, reps: u32, ticks: Option<u32>, key: &str, value: u32) {
    match ticks {
        Some(ticks) => {
            defmt::info!("op {=str} reps={=u32} ticks={=u32} {=str}={=u32}", name, reps, ticks, key, value)
        }
        None => defmt::error!("op {=str} reps={=u32} wrapped", name, reps),
    }
}

/// [`report`] with two more `key=value` fields.
fn report_with2(name: &str, reps: u32, ticks: Option<u32>, first: (&str, u32), second: (&str, u32)) {
    match ticks {
        Some(ticks) => defmt::info!(
            "op {=str} reps={=u32} ticks={=u32} {=str}={=u32} {=str}={=u32}",
            name,
            reps,
            ticks,
            first.0,
            first.1,
            second.0,
            second.1
        ),
        None => defmt::error!("op {=str} reps={=u32} wrapped", name, reps),
    }
}

/// No panic path, as in the firmware (`main.rs`): the release handler calls a function that
/// exists nowhere, so if anything this binary counts could panic (the tree's IK among it), the
/// link fails ("undefined symbol: opcount_reaches_a_panic") and `armctl footprint --elf` on a
/// debug build lists the call sites. Debug builds keep their checks and halt.
#[cfg(not(debug_assertions))]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    extern "C" {
        fn opcount_reaches_a_panic() -> !;
    }
    // SAFETY: never runs: the symbol is undefined, so a binary that could reach this does not link.
    unsafe { opcount_reaches_a_panic() }
}

#[cfg(debug_assertions)]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    halt()
}
