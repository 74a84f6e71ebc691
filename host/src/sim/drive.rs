//! A servo's drive: the servo's own position loop driving a DC motor through its gearbox, against
//! the arm's load, with armature, friction and heat. This is what makes a simulated servo sag
//! under gravity, lag behind its profile, draw current, warm up and stall.
//!
//! The model, everything at the output shaft:
//! - the loop: `duty = clamp(kp · e, ±limit)` with `e` the reference (the servo's own profile,
//!   [`super::motion`]) minus the horn, in radians; `kp` is the P gain register times the model's
//!   scale ([`DriveModel::kp_scale`]); `limit` is the torque limit (STS) or PWM limit (Dynamixel)
//!   register as a fraction, under the electronics' ceiling;
//! - the motor: `τ = τ_stall · (duty − ω / ω_0)`, the DC motor's torque-speed line at the supply
//!   (stall torque at full duty and standing still, no torque at the no-load speed); its current
//!   `i = i_stall · (duty − ω / ω_0)`;
//! - the load: `(J_a + J_link) ω̇ = τ − τ_load − b ω − τ_c sgn ω`, with the gearbox's armature
//!   `J_a`, the inertia of the links the joint moves `J_link` and their torque `τ_load` (gravity and
//!   velocity terms, [`super::physics`]), viscous `b` and Coulomb `τ_c` friction; the horn sticks
//!   while the net torque stays within `τ_c`;
//! - heat: the winding's `i² R` (`R = V / i_stall`) through one thermal resistance and time
//!   constant to a 25 °C room.
//!
//! Integrated with a fixed step ([`STEP_NS`]): the motor's and the viscous damping implicitly (the
//! stiff part: the back-EMF brakes a small armature within a millisecond), the rest explicitly.
//! Not modelled: backlash (the STS3215's and the X series' encoders sit on the output shaft, so the
//! loop closes around the gear play and a steady load shows none of it in the present position),
//! the loop's D and I terms (the identifications were made with both at 0, and no maker publishes
//! the D term's units: LeRobot's D = 32 on the STS3215 is not modelled), the motor's
//! inductance, and any compliance of the links.

use std::f64::consts::PI;

/// The integration step, ns. The damping (the motor's back-EMF and viscous friction) is
/// integrated implicitly, so only the loop's stiffness bounds the step: the stiffest drive on its
/// armature alone (an XM430-W350 at its factory P of 800) rings at about 83 rad/s, 0.08 rad per
/// step, far inside the semi-implicit Euler's limit of 2.
pub const STEP_NS: u64 = 1_000_000;

/// The room the servos stand in, °C.
pub const AMBIENT_C: f64 = 25.0;

/// One servo model at one supply voltage, from published figures (`sources` names them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveModel {
    /// "STS3215 at 12 V".
    pub name: &'static str,
    /// Supply, V.
    pub volts: f64,
    /// Stall torque at the output, N m.
    pub stall_torque: f64,
    /// Stall current, A.
    pub stall_current: f64,
    /// No-load speed at the output, rad/s.
    pub no_load_speed: f64,
    /// Reflected rotor and gear inertia at the output, kg m².
    pub armature: f64,
    /// Coulomb friction at the output, N m.
    pub coulomb: f64,
    /// Viscous friction at the output, N m s/rad.
    pub viscous: f64,
    /// Duty per radian of error per unit of the P gain register.
    pub kp_scale: f64,
    /// The highest duty the servo's electronics give, 0 to 1.
    pub max_duty: f64,
    /// Winding to room, K/W.
    pub thermal_resistance: f64,
    /// The winding's thermal time constant, s.
    pub thermal_time: f64,
    /// Where each figure comes from.
    pub sources: &'static str,
}

/// The state of one drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Drive {
    model: DriveModel,
    /// The horn's own angle, rad (the encoder's frame, before any homing offset).
    angle: f64,
    /// Its speed, rad/s.
    speed: f64,
    /// The last step's duty, -1 to 1.
    duty: f64,
    /// The last step's motor current, A (signed: the direction of its torque).
    current: f64,
    /// The winding's temperature, °C.
    temperature: f64,
    /// Up to when it has been integrated, virtual ns.
    stepped_ns: u64,
}

/// What the loop acts with at a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Loop {
    /// The P gain register.
    pub kp: f64,
    /// The duty limit, 0 to 1 (torque or PWM limit register as a fraction).
    pub limit: f64,
    /// Whether torque is on: off, the motor is open (no duty, no braking).
    pub torque: bool,
}

impl Drive {
    /// A drive of `model` standing at `angle` (rad), at the room's temperature, at `t_ns`.
    pub fn new(model: DriveModel, angle: f64, t_ns: u64) -> Self {
        Self { model, angle, speed: 0.0, duty: 0.0, current: 0.0, temperature: AMBIENT_C, stepped_ns: t_ns }
    }

    /// The same with its winding at `celsius` (a servo that reads warm relaxes to the room).
    pub fn at_temperature(mut self, celsius: f64) -> Self {
        self.temperature = celsius;
        self
    }

    /// The model.
    pub fn model(&self) -> &DriveModel {
        &self.model
    }

    /// The horn's angle (rad, its own frame).
    pub fn angle(&self) -> f64 {
        self.angle
    }

    /// Its speed, rad/s.
    pub fn speed(&self) -> f64 {
        self.speed
    }

    /// The duty the loop last applied, -1 to 1 (the STS3215's `Present_Load` reports it).
    pub fn duty(&self) -> f64 {
        self.duty
    }

    /// The motor current, A.
    pub fn current(&self) -> f64 {
        self.current
    }

    /// The winding's temperature, °C.
    pub fn temperature(&self) -> f64 {
        self.temperature
    }

    /// Up to when it has been integrated.
    pub fn stepped_ns(&self) -> u64 {
        self.stepped_ns
    }

    /// Puts the horn at `angle` moving at `speed` (a hand holds it there), keeping its heat.
    pub fn place(&mut self, angle: f64, speed: f64) {
        self.angle = angle;
        self.speed = speed;
    }

    /// The horn stopped at `angle` (a contact): it stands there.
    pub fn hold_at(&mut self, angle: f64) {
        self.angle = angle;
        self.speed = 0.0;
    }

    /// One step of [`STEP_NS`] with torque off and the horn where a hand holds it (`angle`,
    /// turning at `speed`): no current, the winding cools.
    pub fn follow(&mut self, angle: f64, speed: f64) {
        self.place(angle, speed);
        (self.duty, self.current) = (0.0, 0.0);
        self.heat(STEP_NS as f64 * 1e-9);
        self.stepped_ns += STEP_NS;
    }

    /// The winding's temperature after `dt` seconds at the present current: exact for the
    /// first-order model with the current held.
    fn heat(&mut self, dt: f64) {
        let m = &self.model;
        let resistance = m.volts / m.stall_current;
        let settled = AMBIENT_C + self.current * self.current * resistance * m.thermal_resistance;
        self.temperature += (settled - self.temperature) * (1.0 - (-dt / m.thermal_time).exp());
    }

    /// One step of [`STEP_NS`] toward `reference` (rad) with the loop `control`, the links' torque
    /// `load` (N m, in the horn's direction) and their inertia `inertia` (kg m²).
    pub fn step(&mut self, reference: f64, control: Loop, load: f64, inertia: f64) {
        let m = &self.model;
        let dt = STEP_NS as f64 * 1e-9;
        let j = m.armature + inertia.max(0.0);
        let duty = if control.torque {
            let limit = control.limit.min(m.max_duty);
            (control.kp * m.kp_scale * (reference - self.angle)).clamp(-limit, limit)
        } else {
            0.0
        };
        // Torque off, the winding is open: no back-EMF current, no braking from it.
        let emf_damping = if control.torque { m.stall_torque / m.no_load_speed } else { 0.0 };
        let damping = emf_damping + m.viscous;
        let drive = m.stall_torque * duty - load;
        // Friction acts against the speed the step would reach without it, and can at most
        // bring it to zero: so a horn at rest sticks while the net torque stays within it.
        let free = (self.speed + dt / j * drive) / (1.0 + dt * damping / j);
        let friction = dt / j * m.coulomb / (1.0 + dt * damping / j);
        let speed = if free.abs() <= friction { 0.0 } else { free - friction * free.signum() };
        self.angle += speed * dt;
        self.speed = speed;
        self.duty = duty;
        self.current = if control.torque { m.stall_current * (duty - speed / m.no_load_speed) } else { 0.0 };
        self.heat(dt);
        self.stepped_ns += STEP_NS;
    }
}

/// Radians per encoder tick of a servo with `ticks_per_revolution`.
pub fn radians_per_tick(ticks_per_revolution: u32) -> f64 {
    2.0 * PI / f64::from(ticks_per_revolution)
}

/// Revolutions per minute in rad/s.
pub const fn rpm(value: f64) -> f64 {
    value * 2.0 * PI / 60.0
}

/// Kilogram-force centimetres in N m.
pub const fn kgf_cm(value: f64) -> f64 {
    value * 9.80665 / 100.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::drive_table::{STS3215_12V, STS3215_7V4, XL330_M288, XL430_W250, XM430_W350};

    const TICK: f64 = 2.0 * PI / 4096.0;

    fn full(kp: f64) -> Loop {
        Loop { kp, limit: 1.0, torque: true }
    }

    /// Runs `drive` for `seconds` toward `reference` under `load`.
    fn run(drive: &mut Drive, seconds: f64, reference: f64, control: Loop, load: f64) {
        for _ in 0..(seconds / (STEP_NS as f64 * 1e-9)).round() as u64 {
            drive.step(reference, control, load, 0.0);
        }
    }

    /// SO-ARM100#134 on a 12 V STS3215: 1.5 kg on a 10 cm lever at 45° leaves the horn 20 to 30
    /// ticks short of its goal. At the factory P of 32 the model settles within that band from
    /// either side (friction holds it anywhere within its band, so the side it comes from matters).
    #[test]
    fn the_12v_sts3215_sags_as_so_arm100_134_measured() {
        let load = 1.5 * 9.80665 * 0.10 * (PI / 4.0).cos();
        for start in [-0.2, 0.2] {
            let mut d = Drive::new(STS3215_12V, start, 0);
            run(&mut d, 3.0, 0.0, full(32.0), load);
            let sag = -d.angle() / TICK;
            eprintln!("from {start} rad: sag {sag:.1} ticks");
            assert!((20.0..=30.0).contains(&sag), "from {start} rad: {sag:.1} ticks");
            assert!(d.speed().abs() < 1e-3, "settled");
        }
        // LeRobot's P of 16 doubles it.
        let mut d = Drive::new(STS3215_12V, 0.0, 0);
        run(&mut d, 3.0, 0.0, full(16.0), load);
        assert!(-d.angle() / TICK > 40.0, "{}", -d.angle() / TICK);
    }

    /// Free running at full duty: #134 measured about 46 rev/min on the 12 V STS3215 (Feetech
    /// rates 45); the e-manual's no-load speeds for the Dynamixels. The drive's top speed (full
    /// duty less friction) comes within 15 % of them: the 12 V STS3215's is 41.1 rev/min, 11 %
    /// under #134's.
    #[test]
    fn top_speeds_are_the_published_no_load_speeds() {
        for (model, rpm_published) in [(STS3215_12V, 46.0), (XL330_M288, 103.0), (XL430_W250, 61.0), (XM430_W350, 46.0)]
        {
            let mut d = Drive::new(model, 0.0, 0);
            run(&mut d, 2.0, 1e6, full(1e4), 0.0);
            let rpm = d.speed() * 60.0 / (2.0 * PI);
            assert!((rpm / rpm_published - 1.0).abs() < 0.15, "{}: {rpm:.1} rev/min", model.name);
        }
        // BAM's 7.4 V identification runs faster than the listing's 52 rev/min at 7.4 V (DFRobot):
        // within 15 %.
        let mut d = Drive::new(STS3215_7V4, 0.0, 0);
        run(&mut d, 2.0, 1e6, full(1e4), 0.0);
        let rpm = d.speed() * 60.0 / (2.0 * PI);
        assert!((rpm / 52.0 - 1.0).abs() < 0.15, "{rpm:.1}");
    }

    /// A load within the stall torque is held (the current in proportion, less what friction
    /// takes); one beyond it drags the horn back however far the loop's error grows.
    #[test]
    fn a_load_beyond_the_stall_torque_back_drives_the_horn() {
        // Each at its factory P gain.
        for (model, kp) in [(XL330_M288, 400.0), (XL430_W250, 640.0), (XM430_W350, 800.0), (STS3215_12V, 32.0)] {
            let stall = model.stall_torque * model.max_duty;
            let mut d = Drive::new(model, 0.0, 0);
            run(&mut d, 3.0, 0.0, full(kp), 0.9 * stall);
            assert!(d.angle().abs() < 1.0 && d.speed().abs() < 1e-3, "{}: held at {}", model.name, d.angle());
            // Friction takes up to its Coulomb share of the load.
            let expected = (0.9 * stall - model.coulomb) / model.stall_torque * model.stall_current;
            assert!(
                (d.current() - expected).abs() <= model.coulomb / model.stall_torque * model.stall_current * 2.0 + 1e-9,
                "{}: {} A against {expected} A",
                model.name,
                d.current()
            );
            let mut d = Drive::new(model, 0.0, 0);
            run(&mut d, 1.0, 0.0, full(kp), 1.1 * stall + model.coulomb);
            assert!(d.speed() < 0.0 && d.angle() < -0.01, "{}: back-driven", model.name);
        }
    }

    /// Holding 15 kg cm on the 12 V STS3215 for 10 minutes warms it to #134's 48 °C: the figure the
    /// thermal resistance was fitted to (so this checks the arithmetic, not the model), and the
    /// overheat threshold of 70 °C is not reached that way.
    #[test]
    fn heat_follows_the_current() {
        let mut d = Drive::new(STS3215_12V, 0.0, 0);
        run(&mut d, 600.0, 0.0, full(32.0), kgf_cm(15.0));
        // Friction takes part of the load where the horn sticks: within 2 °C.
        assert!((d.temperature() - 48.0).abs() < 2.0, "{}", d.temperature());
        // Torque off, it cools.
        for _ in 0..(60.0 / (STEP_NS as f64 * 1e-9)) as u64 {
            d.follow(d.angle(), 0.0);
        }
        assert!(d.temperature() < 45.0 && d.current() == 0.0);
    }

    /// q (rad) every 50 ms for 2 s after the goal steps from -0.6 to 0.3 rad, of a 1.5 kg point
    /// mass on a 0.1 m lever (horizontal at 0) on a 12 V STS3215 at P = 32, in MuJoCo 3 with the
    /// drive's figures as a position actuator (host/scripts/servo_step_mujoco.py, "drive": kp
    /// the loop's stiffness, forcerange the stall torque at the duty ceiling, damping the
    /// back-EMF's and the viscous, frictionloss the Coulomb friction; implicitfast, 1 ms).
    const MUJOCO_STEP: [f64; 40] = [
        -0.556332, -0.407426, -0.247751, -0.087937, 0.070856, 0.214175, 0.270826, 0.268327, 0.257365, 0.253025,
        0.252757, 0.252715, 0.252675, 0.252637, 0.252601, 0.252566, 0.252532, 0.252499, 0.252467, 0.252437, 0.252407,
        0.252379, 0.252352, 0.252325, 0.252300, 0.252275, 0.252252, 0.252229, 0.252207, 0.252186, 0.252165, 0.252146,
        0.252127, 0.252108, 0.252090, 0.252073, 0.252057, 0.252041, 0.252026, 0.252011,
    ];

    /// The same step on the drive: the two integrators of one model agree within 0.01 rad at
    /// every sample (0.6°; MuJoCo's friction is a soft constraint that lets the lever creep, the
    /// drive's sticks) and end within 2 ticks.
    #[test]
    fn the_step_response_is_mujocos() {
        let (mass, lever) = (1.5, 0.10);
        let mut d = Drive::new(STS3215_12V, -0.6, 0);
        let control = full(32.0);
        let step = |d: &mut Drive, reference: f64| {
            let load = mass * 9.80665 * lever * d.angle().cos();
            d.step(reference, control, load, mass * lever * lever);
        };
        for _ in 0..1000 {
            step(&mut d, -0.6);
        }
        let mut worst: f64 = 0.0;
        for (k, expected) in MUJOCO_STEP.iter().enumerate() {
            for _ in 0..50 {
                step(&mut d, 0.3);
            }
            worst = worst.max((d.angle() - expected).abs());
            assert!(
                (d.angle() - expected).abs() < 0.01,
                "at {} ms: {} against MuJoCo's {expected}",
                (k + 1) * 50,
                d.angle()
            );
        }
        assert!((d.angle() - MUJOCO_STEP[39]).abs() < 2.0 * TICK, "{} against {}", d.angle(), MUJOCO_STEP[39]);
        eprintln!("largest difference from MuJoCo: {worst:.4} rad");
    }
}
