"""Shared fixtures: the repository, the `armcomp` command, and its outputs to compare with."""

import json
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TALOS = ROOT / "robots" / "talos-left-arm.toml"
TALOS_DATA = ROOT / "data" / "talos-left-arm" / "measurements.csv"


def armcomp_binary() -> Path:
    """The command line built from this checkout (`ARMCOMP_BIN` overrides)."""
    given = os.environ.get("ARMCOMP_BIN")
    path = Path(given) if given else ROOT / "target" / "debug" / "armcomp"
    if not path.exists():
        pytest.fail(f"{path} not found: build it with `cargo build --bin armcomp` first")
    return path


def cli(*args, expect=(0,)):
    """Runs `armcomp ARGS` in the repository; returns stdout, failing on other exit codes."""
    run = subprocess.run(
        [str(armcomp_binary()), *map(str, args)], cwd=ROOT, capture_output=True, text=True
    )
    assert run.returncode in expect, f"armcomp {' '.join(map(str, args))}: {run.stderr}"
    return run.stdout


def cli_json(*args, expect=(0,)):
    """`armcomp ARGS --json` parsed."""
    return json.loads(cli(*args, "--json", expect=expect))


@pytest.fixture
def in_root(monkeypatch):
    """Runs the test in the repository, as the documentation's snippets assume."""
    monkeypatch.chdir(ROOT)
    return ROOT
