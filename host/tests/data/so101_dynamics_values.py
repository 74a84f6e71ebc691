"""Recorded inverse dynamics of the SO-101 from Pinocchio (https://github.com/stack-of-tasks/pinocchio,
PyPI `pin`), for `armctl_arm::urdf_inertials`'s test: so101_new_calib.urdf loaded by Pinocchio's
own URDF parser, the gripper joint locked at zero (the chain carries the moving jaw rigidly there),
gravity 9.80665 m/s² along -z; random states within the joint limits (fixed seed), RNEA's torques
and CRBA's mass matrix printed as Rust literals.

    python3 -m venv /tmp/pin && /tmp/pin/bin/pip install pin==4.1.0
    /tmp/pin/bin/python host/tests/data/so101_dynamics_values.py
"""

import os

import numpy as np
import pinocchio as pin

here = os.path.dirname(os.path.abspath(__file__))
full = pin.buildModelFromUrdf(os.path.join(here, "so101_new_calib.urdf"))
gripper = full.getJointId("gripper")
model = pin.buildReducedModel(full, [gripper], pin.neutral(full))
model.gravity.linear = np.array([0.0, 0.0, -9.80665])
data = model.createData()
assert [model.names[i] for i in range(1, model.njoints)] == [
    "shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"
], list(model.names)

rng = np.random.default_rng(39)
rows = []
for _ in range(8):
    q = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit)
    v = rng.uniform(-2.0, 2.0, model.nv)
    a = rng.uniform(-5.0, 5.0, model.nv)
    tau = pin.rnea(model, data, q, v, a)
    rows.append((q, v, a, tau))

def vec(x):
    return "[" + ", ".join(repr(float(e)) for e in x) + "]"

print(f"// Pinocchio {pin.__version__}, host/tests/data/so101_dynamics_values.py")
print("/// Joint positions, velocities, accelerations, and the torques they take.")
print("type State = ([f64; 5], [f64; 5], [f64; 5], [f64; 5]);")
print("const PINOCCHIO_RNEA: [State; 8] = [")
for q, v, a, tau in rows:
    print(f"    ({vec(q)}, {vec(v)}, {vec(a)}, {vec(tau)}),")
print("];")
q = rows[0][0]
m = pin.crba(model, data, q)
m = np.triu(m) + np.triu(m, 1).T
print("const PINOCCHIO_CRBA: [[f64; 5]; 5] = [")
for row in m:
    print(f"    {vec(row)},")
print("];")
