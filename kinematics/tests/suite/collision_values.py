"""Makes the independent values kinematics/tests/suite/collision.rs checks the signed distances against.

Run once (python3 kinematics/tests/suite/collision_values.py > kinematics/tests/suite/collision_values.rs.in,
with python-fcl and numpy installed for the cross-check); the output is committed.

Independent of the Rust code's algorithms:
- segment to segment: every candidate of the KKT conditions of min |p(s) - q(t)|^2 over the unit
  square (the interior critical point, each edge's clamped minimiser, the four corners), in exact
  rational arithmetic, the smallest kept;
- segment to box: the squared distance to the box is piecewise quadratic in t, with breakpoints
  where a local coordinate crosses a face; each piece is minimised exactly (rationals). Inside the
  box, the signed distance max_i(|q_i| - h_i) is piecewise linear: its minimum is at a breakpoint,
  an end, or where two pieces cross, all enumerated;
- python-fcl's distance (GJK) agrees with the separated cases (to 1e-6 for capsules, within its
  GJK tolerance, 1e-5, for boxes), which the script asserts; a dense sampling check follows.
Coordinates are multiples of 1/1000 (exact as rationals); the square root is taken last, in 50
digits.
"""
import random
from decimal import Decimal, getcontext
from fractions import Fraction as F

getcontext().prec = 50
rng = random.Random(45)


def r(lo, hi):
    return F(rng.randint(int(lo * 1000), int(hi * 1000)), 1000)


def vec(lo, hi):
    return [r(lo, hi) for _ in range(3)]


def sub(a, b):
    return [x - y for x, y in zip(a, b)]


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def sqrt(f):
    return Decimal(f.numerator) / Decimal(f.denominator) if f == 0 else (Decimal(f.numerator) / Decimal(f.denominator)).sqrt()


def clamp01(x):
    return min(max(x, F(0)), F(1))


def seg_seg_sq(p1, p2, q1, q2):
    d1, d2 = sub(p2, p1), sub(q2, q1)

    def dist_sq(s, t):
        diff = [p1[i] + d1[i] * s - q1[i] - d2[i] * t for i in range(3)]
        return dot(diff, diff)

    a, e, b = dot(d1, d1), dot(d2, d2), dot(d1, d2)
    rr = sub(p1, q1)
    c, f = dot(d1, rr), dot(d2, rr)
    candidates = [(F(0), F(0)), (F(0), F(1)), (F(1), F(0)), (F(1), F(1))]
    den = a * e - b * b
    if den != 0:
        s = (b * f - c * e) / den
        t = (a * f - b * c) / den
        if 0 <= s <= 1 and 0 <= t <= 1:
            candidates.append((s, t))
    for s in (F(0), F(1)):
        if e != 0:
            candidates.append((s, clamp01((b * s + f) / e)))
    for t in (F(0), F(1)):
        if a != 0:
            candidates.append((clamp01((b * t - c) / a), t))
    return min(dist_sq(s, t) for s, t in candidates)


def seg_box(a, b, c, h):
    """Signed distance from the segment to the axis-aligned box (centre c, half sizes h)."""
    d = sub(b, a)
    q0 = sub(a, c)
    # Breakpoints: local coordinate q_i(t) = q0_i + d_i t crosses +-h_i.
    ts = {F(0), F(1)}
    for i in range(3):
        if d[i] != 0:
            for s in (h[i], -h[i]):
                t = (s - q0[i]) / d[i]
                if 0 < t < 1:
                    ts.add(t)
    ts = sorted(ts)

    def outside_sq(t):
        return sum(max(abs(q0[i] + d[i] * t) - h[i], F(0)) ** 2 for i in range(3))

    best = min(outside_sq(t) for t in ts)
    for lo, hi in zip(ts, ts[1:]):
        mid = (lo + hi) / 2
        # On this piece each term is either 0 or (sign*(q0+d t) - h)^2: a quadratic A t^2 + B t + C.
        A = B = F(0)
        for i in range(3):
            q = q0[i] + d[i] * mid
            if abs(q) > h[i]:
                sgn = 1 if q > 0 else -1
                k, m = sgn * d[i], sgn * q0[i] - h[i]
                A += k * k
                B += 2 * k * m
        if A > 0:
            t = -B / (2 * A)
            if lo < t < hi:
                best = min(best, outside_sq(t))
    if best > 0:
        return sqrt(best)

    # Touching or inside: the signed distance is min over t of max_i(|q_i(t)| - h_i) (<= 0).
    def inside(t):
        return max(abs(q0[i] + d[i] * t) - h[i] for i in range(3))

    cands = set(ts)
    lines = []
    for i in range(3):
        lines.append((d[i], q0[i] - h[i]))
        lines.append((-d[i], -q0[i] - h[i]))
    for x in range(len(lines)):
        for y in range(x + 1, len(lines)):
            (k1, m1), (k2, m2) = lines[x], lines[y]
            if k1 != k2:
                t = (m2 - m1) / (k1 - k2)
                if 0 <= t <= 1:
                    cands.add(t)
    v = min(inside(t) for t in cands)
    return Decimal(v.numerator) / Decimal(v.denominator)


def fmt(v):
    return "[" + ", ".join(f"{float(x)!r}" for x in v) + "]"


def fcl_check(kind, data, expected):
    try:
        import fcl
        import numpy as np
    except ImportError:
        return
    if expected <= 1e-6:
        return
    def capsule(a, b, radius):
        a, b = np.array([float(x) for x in a]), np.array([float(x) for x in b])
        length = np.linalg.norm(b - a)
        geom = fcl.Capsule(radius, length) if length > 0 else fcl.Sphere(radius)
        z = np.array([0.0, 0.0, 1.0])
        axis = (b - a) / length if length > 0 else z
        v = np.cross(z, axis)
        s, c = np.linalg.norm(v), np.dot(z, axis)
        if s < 1e-12:
            rot = np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
        else:
            k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
            rot = np.eye(3) + k + k @ k * ((1 - c) / s**2)
        return fcl.CollisionObject(geom, fcl.Transform(rot, (a + b) / 2))
    if kind == "cc":
        (a, b, ra, c, d, rb) = data
        o1, o2 = capsule(a, b, float(ra)), capsule(c, d, float(rb))
    else:
        (a, b, ra, c, h) = data
        o1 = capsule(a, b, float(ra))
        o2 = fcl.CollisionObject(fcl.Box(*[2 * float(x) for x in h]), fcl.Transform(np.array([float(x) for x in c])))
    req, res = fcl.DistanceRequest(enable_nearest_points=True), fcl.DistanceResult()
    got = fcl.distance(o1, o2, req, res)
    # GJK stops at its own tolerance: agreement to 1e-5 m is what FCL offers.
    assert abs(got - float(expected)) < 1e-5, (kind, got, float(expected))


print("// Made by kinematics/tests/suite/collision_values.py (see there how); do not edit by hand.")
print("/// (a, b, radius_a, c, d, radius_b, signed distance)")
print("type CapsulePair = ([f64; 3], [f64; 3], f64, [f64; 3], [f64; 3], f64, f64);")
print("/// (a, b, radius, box centre, box half sizes, signed distance)")
print("type CapsuleBox = ([f64; 3], [f64; 3], f64, [f64; 3], [f64; 3], f64);")
print("const CAPSULE_CAPSULE: &[CapsulePair] = &[")
for k in range(40):
    a, b, c, d = vec(-0.2, 0.2), vec(-0.2, 0.2), vec(-0.2, 0.2), vec(-0.2, 0.2)
    if k % 8 == 1:
        b = list(a)  # a sphere
    if k % 8 == 2:
        d = [c[i] + (b[i] - a[i]) * F(1, 2) for i in range(3)]  # parallel
        c = [c[i] for i in range(3)]
        d = [c[i] + (b[i] - a[i]) for i in range(3)]
    ra, rb = r(0.0, 0.05), r(0.0, 0.05)
    dist = sqrt(seg_seg_sq(a, b, c, d)) - Decimal(ra.numerator) / ra.denominator - Decimal(rb.numerator) / rb.denominator
    fcl_check("cc", (a, b, ra, c, d, rb), dist)
    print(f"    ({fmt(a)}, {fmt(b)}, {float(ra)!r}, {fmt(c)}, {fmt(d)}, {float(rb)!r}, {float(dist)!r}),")
print("];")
print("const CAPSULE_BOX: &[CapsuleBox] = &[")
for k in range(40):
    c, h = vec(-0.1, 0.1), [r(0.01, 0.1) for _ in range(3)]
    a, b = vec(-0.25, 0.25), vec(-0.25, 0.25)
    if k % 5 == 0:
        a = [c[i] + r(-0.02, 0.02) for i in range(3)]  # one end inside
    if k % 7 == 3:
        b = list(a)
    ra = r(0.0, 0.04)
    dist = seg_box(a, b, c, h) - Decimal(ra.numerator) / ra.denominator
    fcl_check("cb", (a, b, ra, c, h), dist)
    print(f"    ({fmt(a)}, {fmt(b)}, {float(ra)!r}, {fmt(c)}, {fmt(h)}, {float(dist)!r}),")
print("];")
