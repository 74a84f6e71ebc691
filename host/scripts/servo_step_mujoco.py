"""A servo's step response in MuJoCo, for the simulator's servo model (docs/servo-model.md).

One hinge (axis y) turns a lever with a point mass at its end, under gravity (the lever is
horizontal at q = 0), driven by a position actuator. Two parameter sets:

- "menagerie": mujoco_menagerie's robotstudio_so101 `sts3215` class as it is (position kp 998.22,
  kv 2.731, forcerange 2.94, joint damping 0.60, frictionloss 0.052, armature 0.028);
- "drive": the same structure with the simulator's drive figures for the STS3215 at 12 V and P = 32
  (kscalelabs' id006 identification, host/src/sim/drive_table.rs): kp the loop's stiffness
  P * error_gain * stall torque, forcerange the stall torque at the 0.97 duty ceiling, damping the
  back-EMF's kt^2/R plus the viscous friction, frictionloss the Coulomb friction. This is the drive's
  own model integrated by another program: the Rust test `sim::drive::tests::
  the_step_response_is_mujocos` checks the simulator against these values.

Prints, per set, q (rad) every 50 ms for 2 s after the goal steps from -0.6 to 0.3 rad, and the
figures of the manual's table (final error in ticks, 10-90 % rise time, overshoot).

    python3 -m venv /tmp/mj && /tmp/mj/bin/pip install mujoco numpy
    /tmp/mj/bin/python host/scripts/servo_step_mujoco.py
"""

import math

import mujoco

MASS, LEVER = 1.5, 0.10  # kg, m: SO-ARM100#134's rig
START, GOAL = -0.6, 0.3  # rad
TICK = 2 * math.pi / 4096

# The drive of an STS3215 at 12 V (kscalelabs/sysid id006 m1) at P = 32.
KT, R, VOLTS = 2.564_753_18, 5.268_709_81, 12.0
ERROR_GAIN = 0.164_890_9 * 0.955_247_82
STALL = KT * VOLTS / R
DRIVE = dict(
    kp=32 * ERROR_GAIN * STALL,
    kv=0.0,
    force=STALL * 0.97,
    damping=KT * KT / R + 0.048_098_31,
    friction=0.090_900_99,
    armature=0.026_176_13,
)
MENAGERIE = dict(kp=998.22, kv=2.731, force=2.94, damping=0.60, friction=0.052, armature=0.028)


def model(p):
    xml = f"""
<mujoco>
  <option timestep="0.001" integrator="implicitfast" gravity="0 0 -9.80665"/>
  <worldbody>
    <body name="lever">
      <joint name="hinge" type="hinge" axis="0 -1 0" damping="{p['damping']}"
             frictionloss="{p['friction']}" armature="{p['armature']}"/>
      <inertial pos="{LEVER} 0 0" mass="{MASS}" diaginertia="1e-9 1e-9 1e-9"/>
    </body>
  </worldbody>
  <actuator>
    <position joint="hinge" kp="{p['kp']}" kv="{p['kv']}" forcerange="{-p['force']} {p['force']}"
              forcelimited="true"/>
  </actuator>
</mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


def run(p):
    m = model(p)
    d = mujoco.MjData(m)
    # Settle at the start under the goal START first (1 s), then step.
    d.qpos[0] = START
    d.ctrl[0] = START
    for _ in range(1000):
        mujoco.mj_step(m, d)
    start = d.qpos[0]
    d.ctrl[0] = GOAL
    samples, trace = [], []
    for k in range(1, 2001):
        mujoco.mj_step(m, d)
        trace.append(d.qpos[0])
        if k % 50 == 0:
            samples.append(d.qpos[0])
    return start, samples, trace


def figures(start, trace):
    final = trace[-1]
    span = final - start
    t10 = next(k for k, q in enumerate(trace) if (q - start) >= 0.1 * span) + 1
    t90 = next(k for k, q in enumerate(trace) if (q - start) >= 0.9 * span) + 1
    overshoot = max(0.0, (max(trace) - final) / span)
    return (GOAL - final) / TICK, (t90 - t10) * 1e-3, overshoot


for name, p in [("drive", DRIVE), ("menagerie", MENAGERIE)]:
    start, samples, trace = run(p)
    error, rise, overshoot = figures(start, trace)
    print(f"{name}: start {start:.6f} rad ({(START - start) / TICK:.1f} ticks below its goal)")
    print(f"{name}: final error {error:.1f} ticks, rise 10-90 % {rise * 1e3:.0f} ms, overshoot {overshoot * 100:.1f} %")
    print(f"{name}: q every 50 ms = [{', '.join(f'{q:.6f}' for q in samples)}]")
