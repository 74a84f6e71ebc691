"""The package's kinematics against the command line's values (the same crates, so equal to the
last bit where the arithmetic is the same), against finite differences, and on bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import armctl

RNG = np.random.default_rng(29)


def random_q(model: armctl.Model, n: int) -> np.ndarray:
    lim = model.limits
    return lim[:, 0] + (lim[:, 1] - lim[:, 0]) * (0.05 + 0.9 * RNG.random((n, model.dof)))


@pytest.mark.parametrize("arm", ["so101", "ur5e", "open-manipulator-x", "planar:3"])
def test_fk_and_jacobian_equal_the_command_line(arm, cli_json):
    model = armctl.Model(arm)
    for q in random_q(model, 3):
        text = ",".join(repr(float(x)) for x in q)
        fk = cli_json("fk", "--arm", arm, "--q", text)
        pose = model.fk(q)
        np.testing.assert_allclose(pose[:3, 3], fk["position"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(pose[:3, :3], fk["rotation"], rtol=0, atol=1e-12)
        np.testing.assert_array_equal(pose[3], [0, 0, 0, 1])
        frames = model.frames(q)
        np.testing.assert_allclose(frames[:, :3, 3], [f["position"] for f in fk["frames"]], atol=1e-12)
        jac = cli_json("jacobian", "--arm", arm, "--q", text)
        np.testing.assert_allclose(model.jacobian(q), jac["jacobian"], rtol=0, atol=1e-12)


def test_jacobian_matches_finite_differences_of_fk():
    model = armctl.Model("ur5e")
    q = random_q(model, 1)[0]
    j = model.jacobian(q)
    h = 1e-6
    for i in range(model.dof):
        dq = np.zeros(model.dof)
        dq[i] = h
        dp = (model.fk(q + dq)[:3, 3] - model.fk(q - dq)[:3, 3]) / (2 * h)
        np.testing.assert_allclose(j[:3, i], dp, atol=1e-7)


@pytest.mark.parametrize("arm", ["so101", "ur5e"])
def test_ik_reaches_reachable_targets_and_equals_the_command_line(arm, cli_json):
    model = armctl.Model(arm)
    for q in random_q(model, 5):
        target = model.fk(q)[:3, 3]
        r = model.solve(target)
        assert r.converged, r
        assert np.linalg.norm(model.fk(r.q)[:3, 3] - target) < 1e-4
        assert np.all(r.q >= model.limits[:, 0] - 1e-12) and np.all(r.q <= model.limits[:, 1] + 1e-12)
        out = cli_json("ik", "--arm", arm, "--target", ",".join(repr(float(x)) for x in target))
        assert out["status"] == "converged"
        assert out["solver"] == r.method
        np.testing.assert_allclose(r.q, out["q"], atol=1e-12)


def test_ik_of_a_pose_and_a_batch():
    model = armctl.Model("ur5e")
    qs = random_q(model, 8)
    poses = model.fk(qs)
    quats = []
    for p in poses:
        r = p[:3, :3]
        w = np.sqrt(max(1e-12, 1 + np.trace(r))) / 2
        quats.append([w, (r[2, 1] - r[1, 2]) / (4 * w), (r[0, 2] - r[2, 0]) / (4 * w), (r[1, 0] - r[0, 1]) / (4 * w)])
    quats = np.array(quats)
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    q = model.ik(poses[:, :3, 3], quats)
    assert q.shape == (8, 6)
    np.testing.assert_allclose(model.fk(q)[:, :3, 3], poses[:, :3, 3], atol=1e-4)
    np.testing.assert_allclose(model.fk(q)[:, :3, :3], poses[:, :3, :3], atol=1e-3)


def test_an_unreachable_target_says_how_far():
    model = armctl.Model("so101")
    r = model.solve([2.0, 0.0, 0.0])
    assert not r.converged and r.position_error > 1.0
    with pytest.raises(armctl.ArmctlError, match="not reached"):
        model.ik([2.0, 0.0, 0.0])


def test_sampling_equals_the_command_line(tmp_path, cli_json):
    times = [0.0, 0.8, 2.0, 2.5]
    q = [[0.0, 0.1], [0.5, -0.2], [0.1, 0.4], [0.0, 0.0]]
    keyframes = tmp_path / "k.csv"
    keyframes.write_text("t,q1,q2\n" + "".join(f"{t},{a},{b}\n" for t, (a, b) in zip(times, q)))
    for method in ["linear", "catmull-rom", "natural", "monotone"]:
        s = armctl.sample(times, q, 50.0, method=method)
        out = cli_json("trajectory", "sample", "--keyframes", str(keyframes), "--method", method, "--rate", "50",
                       "--json")
        rows = out["samples"] if "samples" in out else out["rows"]
        np.testing.assert_allclose(s.t, [r["t"] for r in rows], atol=1e-12)
        np.testing.assert_allclose(s.q, [r["q"] for r in rows], atol=1e-12)
        np.testing.assert_allclose(s.v, [r["v"] for r in rows], atol=1e-12)


def test_models_from_files(tmp_path):
    root = armctl.Model("so101")
    urdf = __import__("pathlib").Path(__file__).resolve().parents[2] / "tests/data/so101_new_calib.urdf"
    from_urdf = armctl.Model(str(urdf), tip="gripper_frame_link")
    assert from_urdf.dof == 5
    assert np.isfinite(from_urdf.fk(np.zeros(5))).all()
    assert root.has_gripper and root.closed_form == "yaw_pitch"
    # The errors about a tip name Python's keyword, not only the command line's option.
    with pytest.raises(armctl.ArmctlError, match=r"tip= in Python\) applies only to .urdf arms"):
        armctl.Model("so101", tip="gripper_frame_link")


TREE = str(Path(__file__).resolve().parents[2] / "tests/data/bimanual_torso.urdf")


def quaternion_wxyz(r: np.ndarray) -> list[float]:
    """A rotation matrix's unit quaternion, w first (the tests' poses are away from w = 0)."""
    w = np.sqrt(max(1e-12, 1 + np.trace(r))) / 2
    q = np.array([w, (r[2, 1] - r[1, 2]) / (4 * w), (r[0, 2] - r[2, 0]) / (4 * w), (r[1, 0] - r[0, 1]) / (4 * w)])
    return (q / np.linalg.norm(q)).tolist()


def text(values) -> str:
    return ",".join(repr(float(x)) for x in values)


def test_a_urdf_with_branches_is_a_tree_whose_effectors_are_the_chains_to_its_leaves(cli_json):
    tree = armctl.Model(TREE)
    assert isinstance(tree, armctl.TreeModel) and isinstance(tree, armctl.Model)
    assert tree.effectors == ["camera_link", "left_tip", "right_tip"]
    assert tree.dof == 11 and tree.closed_form is None and not tree.has_gripper
    chains = {leaf: armctl.Model(TREE, tip=leaf) for leaf in tree.effectors}
    assert not any(isinstance(c, armctl.TreeModel) for c in chains.values())
    for q in random_q(tree, 3):
        poses, jacobians = tree.fk(q), tree.jacobian(q)
        fk = cli_json("fk", "--arm", TREE, "--q", text(q))
        jac = cli_json("jacobian", "--arm", TREE, "--q", text(q))
        for leaf, chain in chains.items():
            path = [tree.joint_names.index(name) for name in chain.joint_names]
            np.testing.assert_allclose(poses[leaf], chain.fk(q[path]), rtol=0, atol=1e-12)
            np.testing.assert_allclose(poses[leaf][:3, 3], fk["effectors"][leaf]["position"], rtol=0, atol=1e-12)
            np.testing.assert_allclose(poses[leaf][:3, :3], fk["effectors"][leaf]["rotation"], rtol=0, atol=1e-12)
            expected = np.zeros((6, tree.dof))
            expected[:, path] = chain.jacobian(q[path])
            np.testing.assert_allclose(jacobians[leaf], expected, rtol=0, atol=1e-12)
            np.testing.assert_allclose(jacobians[leaf], jac["effectors"][leaf]["jacobian"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(tree.frames(q)[:, :3, 3], [f["position"] for f in fk["frames"]], atol=1e-12)
    batch = random_q(tree, 4)
    poses = tree.fk(batch)
    assert poses["left_tip"].shape == (4, 4, 4)
    np.testing.assert_allclose(poses["right_tip"][2], tree.fk(batch[2])["right_tip"], rtol=0, atol=0)


def test_tree_ik_reaches_random_reachable_targets_and_equals_the_command_line(cli_json):
    tree = armctl.Model(TREE)
    for i, q in enumerate(random_q(tree, 4)):
        poses = tree.fk(q)
        left, right = poses["left_tip"], poses["right_tip"]
        # A full pose for the left hand, and the right's position only on every other case.
        targets = {"left_tip": (left[:3, 3], quaternion_wxyz(left[:3, :3])),
                   "right_tip": right[:3, 3] if i % 2 else (right[:3, 3], quaternion_wxyz(right[:3, :3]))}
        r = tree.solve(targets)
        assert r.converged, r
        assert set(r.effectors) == {"left_tip", "right_tip"}
        assert np.all(r.q >= tree.limits[:, 0] - 1e-12) and np.all(r.q <= tree.limits[:, 1] + 1e-12)
        reached = tree.fk(r.q)
        for leaf in targets:
            assert np.linalg.norm(reached[leaf][:3, 3] - poses[leaf][:3, 3]) <= 1e-5
            assert r.effectors[leaf]["reached"]
        np.testing.assert_allclose(reached["left_tip"][:3, :3], left[:3, :3], atol=1e-4)
        assert (r.effectors["right_tip"]["orientation_error"] is None) == bool(i % 2)
        args = ["ik", "--arm", TREE]
        for leaf, target in targets.items():
            values = list(target[0]) + list(target[1]) if isinstance(target, tuple) else list(target)
            args += ["--target", f"{leaf}={text(values)}"]
        out = cli_json(*args)
        assert out["status"] == r.status
        np.testing.assert_allclose(r.q, out["q"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(tree.ik(targets), r.q, rtol=0, atol=0)


def test_tree_priority_keeps_the_first_target():
    tree = armctl.Model(TREE)
    q = random_q(tree, 1)[0]
    left = tree.fk(q)["left_tip"][:3, 3]
    r = tree.solve({"left_tip": left, "right_tip": [2.0, -0.2, 0.3]}, priority="left_tip")
    assert r.status == "best_effort"
    assert r.effectors["left_tip"]["reached"] and r.effectors["left_tip"]["priority"] == 0
    assert not r.effectors["right_tip"]["reached"] and r.effectors["right_tip"]["priority"] == 1
    assert r.effectors["right_tip"]["position_error"] > 1.0
    assert np.linalg.norm(tree.fk(r.q)["left_tip"][:3, 3] - left) <= 1e-5
    with pytest.raises(armctl.ArmctlError, match="not reached: best_effort, right_tip"):
        tree.ik({"left_tip": left, "right_tip": [2.0, -0.2, 0.3]}, priority=["left_tip"])


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: armctl.Model(TREE).fk([0] * 5), "expected 11 values"),
        (lambda: armctl.Model(TREE).jacobian([0] * 10 + [np.nan]), "not a finite number"),
        (lambda: armctl.Model(TREE).solve({"nope": [0.3, 0.2, 0.4]}), "no end effector \"nope\""),
        (lambda: armctl.Model(TREE).solve({"left_tip": [np.nan, 0.2, 0.4]}), "not a finite number"),
        (lambda: armctl.Model(TREE).solve({"left_tip": [0.3, 0.2]}), "expected 3 values"),
        (lambda: armctl.Model(TREE).solve({"left_tip": ([0.3, 0.2, 0.4], [1, 1, 0, 0])}), "not a unit quaternion"),
        (lambda: armctl.Model(TREE).solve({}), "targets: expected a dict"),
        (lambda: armctl.Model(TREE).solve({"left_tip": [0.3, 0.2, 0.4]}, seed=[0, 0]), "expected 11 values"),
        (lambda: armctl.Model(TREE).solve({"left_tip": [0.3, 0.2, 0.4]}, priority="left_tip"), "must leave some"),
        (lambda: armctl.Model(TREE).solve({"left_tip": [0.3, 0.2, 0.4], "right_tip": [0.3, -0.2, 0.4]},
                                          priority="camera_link"), "camera_link has no target"),
        (lambda: armctl.Model(TREE, calibration="my_arm.json"), "is a tree"),
        (lambda: armctl.TreeModel("so101"), "is a chain, not a tree"),
    ],
)
def test_bad_tree_input_raises_one_line(call, message):
    with pytest.raises(armctl.ArmctlError, match=message) as e:
        call()
    assert "\n" not in str(e.value)


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: armctl.Model("no-such-arm"), "unknown arm"),
        (lambda: armctl.Model("/no/such/arm.toml"), "cannot read arm file"),
        (lambda: armctl.Model("so101").fk([0, 1]), "expected 5 values"),
        (lambda: armctl.Model("so101").fk([[0, 0, 0, 0, np.nan]]), "not finite|NaN|finite"),
        (lambda: armctl.Model("so101").solve([0.2, 0, 0.1], solver="magic"), "solver \"magic\""),
        (lambda: armctl.Model("so101").solve([0.2, 0, 0.1], seed=[0, 0]), "expected 5 values"),
        (lambda: armctl.sample([0, 1], [[0], [1]], 10, method="wavy"), "method \"wavy\""),
        (lambda: armctl.sample([0, 0], [[0], [1]], 10), "not later"),
        (lambda: armctl.sample([0, 1], [[0], [np.inf]], 10), "not a finite number"),
        # Checked as the command line checks them (issue 43): non-finite values in every input,
        # types numpy would quietly convert (bools, text, complex), shapes.
        (lambda: armctl.Model("so101").ik([np.nan, 0, 0.1]), "position: value 1 \\(nan\\) is not a finite number"),
        (lambda: armctl.Model("so101").solve([0.2, 0, 0.1], seed=[0, np.inf, 0, 0, 0]),
         "seed: value 2 \\(inf\\) is not a finite number"),
        (lambda: armctl.Model("so101").ik([0.2, 0, 0.1], quaternion_wxyz=[1, 0, np.nan, 0]),
         "quaternion_wxyz: value 3 \\(nan\\) is not a finite number"),
        (lambda: armctl.Model("so101").ik([[0.2, 0, 0.1], [0.2, np.nan, 0.1]]), "position: value 5 \\(nan\\)"),
        (lambda: armctl.Model("so101").fk(["0", "0", "0", "0", "0"]), "q: expected real numbers, got text"),
        (lambda: armctl.Model("so101").fk([True, False, False, False, False]),
         "q: expected real numbers, got booleans"),
        (lambda: armctl.Model("so101").fk([1j, 0, 0, 0, 0]), "q: expected real numbers, got complex numbers"),
        (lambda: armctl.Model("so101").fk([[0, 0], [0, 0, 0]]), "q: expected numbers"),
        (lambda: armctl.Model("so101").fk(np.zeros((2, 4))), "q: expected shape \\(5,\\) or \\(n, 5\\)"),
        (lambda: armctl.Model("so101").jacobian(np.zeros((2, 5, 1))), "q: expected shape"),
        (lambda: armctl.Model("so101").ik(np.zeros((2, 2))), "position: expected shape \\(3,\\) or \\(n, 3\\)"),
    ],
)
def test_bad_input_raises_one_line(call, message):
    with pytest.raises(armctl.ArmctlError, match=message) as e:
        call()
    assert "\n" not in str(e.value)


def test_batches_of_any_length_keep_their_shape():
    """An empty batch has the batch's shape, as a batch of one has; jacobian takes a batch as fk
    and ik do, each row as the single call answers it."""
    m = armctl.Model("so101")
    assert m.fk(np.zeros((0, 5))).shape == (0, 4, 4)
    assert m.jacobian(np.zeros((0, 5))).shape == (0, 6, 5)
    assert m.ik(np.zeros((0, 3))).shape == (0, 5)
    rng = np.random.default_rng(43)
    lo, hi = m.limits[:, 0], m.limits[:, 1]
    q = lo + (hi - lo) * rng.uniform(0.05, 0.95, size=(4, 5))
    assert m.fk(q[:1]).shape == (1, 4, 4)
    batch = m.jacobian(q)
    assert batch.shape == (4, 6, 5)
    for row, j in zip(q, batch):
        np.testing.assert_array_equal(j, m.jacobian(row))
