"""Shared fixtures: the armctl binary the package's answers are checked against, and whether the
run must not skip what it cannot run (CI=true: everything the tests need is installed there)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "host" / "scripts"))


def armctl_binary() -> str:
    for candidate in (os.environ.get("ARMCTL"), ROOT / "target/debug/armctl", ROOT / "target/release/armctl"):
        if candidate and Path(candidate).is_file():
            return str(candidate)
    if os.environ.get("CI") == "true":
        raise RuntimeError("no armctl binary (cargo build -p armctl)")
    pytest.skip("no armctl binary: cargo build -p armctl")


@pytest.fixture(scope="session")
def armctl_bin() -> str:
    return armctl_binary()


@pytest.fixture(scope="session")
def cli(armctl_bin):
    """Runs `armctl ARGS`; returns (exit code, stdout, stderr)."""

    def run(*args: str, stdin: str | None = None) -> tuple[int, str, str]:
        p = subprocess.run([armctl_bin, *args], input=stdin, capture_output=True, text=True, timeout=120)
        return p.returncode, p.stdout, p.stderr

    return run


@pytest.fixture(scope="session")
def cli_json(cli):
    def run(*args: str) -> dict:
        code, out, err = cli(*args)
        assert code == 0, err
        return json.loads(out.strip().splitlines()[-1])

    return run


def need_lerobot():
    """LeRobot, or a skip outside CI (in CI it is installed, and missing it fails)."""
    try:
        import lerobot  # noqa: F401
    except ImportError:
        if os.environ.get("CI") == "true":
            raise
        pytest.skip("lerobot is not installed")
