//! The published figures of each servo model's drive ([`super::drive::DriveModel`]), with their
//! sources. Where an identification fits the drive's own model (Rhoban's BAM, kscalelabs' sysid:
//! `duty = kp · error_gain · e`, `τ = kt V duty / R − kt² ω / R`, Coulomb and viscous friction),
//! its figures are taken as they are: stall torque `kt V / R`, stall current `V / R`, no-load
//! speed `V / kt`. Where none exists, the datasheet's stall torque, stall current and no-load
//! speed are taken, and what it does not give is said.
//!
//! Sources (read 2026-12-07):
//! - BAM: Rhoban/bam @ 1b5a1ce, `bam/feetech/actuator.py` (error gain 0.166 "determined using an
//!   oscilloscope", max PWM 0.97), `bam/dynamixel/actuator.py` (XL330: error gain
//!   `(4096/2π)/(256·885)`, "256 empirically observed (manual mentions 128)"),
//!   `params/feetech_sts3215_7_4V/m1.json`, `params/xl330/m1.json`;
//! - sysid: kscalelabs/sysid @ f4739df, `feetech/sts3215-12v/README.md` (error gain 0.16489 at
//!   P = 32, measured) and `params/id006-params/m1.json` (the one fit of five whose kt is not at
//!   the optimiser's bound);
//! - e-manual: ROBOTIS-GIT/emanual, `docs/en/dxl/x/xl430-w250.md` @ 486d85b and
//!   `xm430-w350.md` @ 07fe860 (stall torque, current, no-load speed, gear ratio) and
//!   `control_table_position_pid_gain.md` @ 01a2df1 (`KPP = KPP(TBL) / 128`, PWM limit 885 =
//!   100 %);
//! - heat: no servo's maker publishes a thermal resistance. One figure measured on an STS3215
//!   at 12 V (TheRobotStudio/SO-ARM100#134: 48 °C after 10 min holding 15 kg cm) fixes the
//!   resistance with an assumed 300 s time constant; every model gets the same two figures.

use super::drive::{kgf_cm, rpm, DriveModel};

/// Winding to room, K/W: #134's 48 °C after 600 s at 1.47 N m on the 12 V STS3215 below (duty
/// 0.252, 0.575 A, 1.74 W in 5.26 Ω: 23 K) is 0.865 of the settled rise at 300 s.
const THERMAL_RESISTANCE: f64 = 15.3;
/// The winding's time constant, s (assumed).
const THERMAL_TIME: f64 = 300.0;

/// BAM's STS3215 error gain (duty per radian per unit of the P register).
const STS_ERROR_GAIN: f64 = 0.166;
/// BAM's STS3215 duty ceiling, "determined with oscilloscope".
const STS_MAX_DUTY: f64 = 0.97;

/// STS3215 on 7.4 V (C001, 1:345): BAM's m1 identification (kt 1.21164 N m/A, R 2.67617 Ω,
/// armature 0.0284034, friction 0.0523930 N m and 0.0590852 N m s/rad) at 7.4 V.
pub const STS3215_7V4: DriveModel = identified(
    "STS3215 at 7.4 V",
    Identified { volts: 7.4, kt: 1.211_641_35, r: 2.676_166_33, armature: 0.028_403_36 },
    (0.052_392_96, 0.059_085_16),
    (STS_ERROR_GAIN, STS_MAX_DUTY),
    "Rhoban/bam params/feetech_sts3215_7_4V/m1.json and bam/feetech/actuator.py",
);

/// STS3215 on 12 V (C018/C047, 1:345): kscalelabs' id006 m1 identification (kt 2.56475 N m/A,
/// R 5.26871 Ω, error gain ratio 0.955248, armature 0.0261761, friction 0.0909010 N m and
/// 0.0480983 N m s/rad) at 12 V, with its measured error gain 0.16489.
pub const STS3215_12V: DriveModel = identified(
    "STS3215 at 12 V",
    Identified { volts: 12.0, kt: 2.564_753_18, r: 5.268_709_81, armature: 0.026_176_13 },
    (0.090_900_99, 0.048_098_31),
    (0.164_890_9 * 0.955_247_82, STS_MAX_DUTY),
    "kscalelabs/sysid feetech/sts3215-12v params/id006-params/m1.json and README.md",
);

/// XL330-M288 on 5 V (288.4:1): BAM's m1 identification (kt 0.386696 N m/A, R 4.01713 Ω,
/// armature 0.00181417, friction 0.0128327 N m and 0.00366167 N m s/rad) at the e-manual's
/// recommended 5 V, with BAM's error gain (P register / 256 per tick of 885).
pub const XL330_M288: DriveModel = identified(
    "XL330-M288 at 5 V",
    XL330,
    XL330_FRICTION,
    (TICKS_PER_RADIAN / (256.0 * 885.0), 1.0),
    "Rhoban/bam params/xl330/m1.json and bam/dynamixel/actuator.py; e-manual XL330-M288",
);

/// BAM's XL330 friction: Coulomb (N m) and viscous (N m s/rad).
const XL330_FRICTION: (f64, f64) = (0.012_832_72, 0.003_661_67);

/// BAM's XL330 motor at 5 V.
const XL330: Identified = Identified { volts: 5.0, kt: 0.386_695_76, r: 4.017_129_22, armature: 0.001_814_17 };

/// XL430-W250 on 12 V (258.5:1): the e-manual's 1.5 N m at 1.4 A, 61 rev/min (see [`x_series`]).
pub const XL430_W250: DriveModel = x_series(
    "XL430-W250 at 12 V",
    XSeries { stall_torque: 1.5, stall_current: 1.4, no_load_rpm: 61.0, gear_ratio: 258.5 },
    "e-manual XL430-W250 and the X series' position PID gains; armature and friction assumed",
);

/// XM430-W350 on 12 V (353.5:1): the e-manual's 4.1 N m at 2.3 A, 46 rev/min (see [`x_series`]).
pub const XM430_W350: DriveModel = x_series(
    "XM430-W350 at 12 V",
    XSeries { stall_torque: 4.1, stall_current: 2.3, no_load_rpm: 46.0, gear_ratio: 353.5 },
    "e-manual XM430-W350 and the X series' position PID gains; armature and friction assumed",
);

/// What the e-manual gives of an X-series servo at 12 V.
struct XSeries {
    /// N m.
    stall_torque: f64,
    /// A.
    stall_current: f64,
    /// rev/min.
    no_load_rpm: f64,
    /// The gearbox's reduction.
    gear_ratio: f64,
}

/// The XL330-M288's gearbox reduction, which the X series' assumed figures are scaled from.
const XL330_GEAR_RATIO: f64 = 288.4;

/// An X-series drive at 12 V from the e-manual's figures, with its P gain (`KPP = P / 128` PWM
/// units, of 885, per tick). Not published, assumed: the armature is the XL330's identified one
/// scaled by the square of the gear ratios, the friction the XL330's scaled by the stall torques.
const fn x_series(name: &'static str, x: XSeries, sources: &'static str) -> DriveModel {
    let gears = x.gear_ratio / XL330_GEAR_RATIO;
    let strength = x.stall_torque / XL330_STALL;
    DriveModel {
        name,
        volts: 12.0,
        stall_torque: x.stall_torque,
        stall_current: x.stall_current,
        no_load_speed: rpm(x.no_load_rpm),
        armature: XL330.armature * gears * gears,
        coulomb: XL330_FRICTION.0 * strength,
        viscous: XL330_FRICTION.1 * strength,
        kp_scale: TICKS_PER_RADIAN / (128.0 * 885.0),
        max_duty: 1.0,
        thermal_resistance: THERMAL_RESISTANCE,
        thermal_time: THERMAL_TIME,
        sources,
    }
}

/// Every drive, for the manual's table and the tests.
pub const ALL: [DriveModel; 5] = [STS3215_7V4, STS3215_12V, XL330_M288, XL430_W250, XM430_W350];

const TICKS_PER_RADIAN: f64 = 4096.0 / (2.0 * std::f64::consts::PI);

/// The XL330's stall torque in its identification, N m.
const XL330_STALL: f64 = XL330.kt * XL330.volts / XL330.r;

/// An identification of BAM's model: supply (V), torque constant (N m/A), winding resistance (Ω)
/// and armature (kg m²).
struct Identified {
    volts: f64,
    kt: f64,
    r: f64,
    armature: f64,
}

/// The drive of an identified motor: stall torque `kt V / R`, stall current `V / R`, no-load speed
/// `V / kt`, with its `(coulomb, viscous)` friction and its loop's `(kp_scale, max_duty)`.
const fn identified(
    name: &'static str,
    m: Identified,
    (coulomb, viscous): (f64, f64),
    (kp_scale, max_duty): (f64, f64),
    sources: &'static str,
) -> DriveModel {
    DriveModel {
        name,
        volts: m.volts,
        stall_torque: m.kt * m.volts / m.r,
        stall_current: m.volts / m.r,
        no_load_speed: m.volts / m.kt,
        armature: m.armature,
        coulomb,
        viscous,
        kp_scale,
        max_duty,
        thermal_resistance: THERMAL_RESISTANCE,
        thermal_time: THERMAL_TIME,
        sources,
    }
}

/// The 12 V STS3215's rated stall torque (Feetech's C018, 30 kg cm), for the comparison.
pub const STS3215_12V_RATED_STALL: f64 = kgf_cm(30.0);
