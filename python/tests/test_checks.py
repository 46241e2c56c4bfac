"""`validate` and `check_pose` from Python: the command line's checks, against files whose
problems and contacts are known by construction."""

import json
import math

import armcomp
from conftest import ROOT, cli_json

# The two-link arm the Rust check-pose test uses (box base, capsule forearm of radius 40 mm).
ARM = ROOT / "tests" / "data" / "robots" / "two-link-collision.urdf"


def test_validate_lists_the_problems_of_a_file_by_line_and_field(tmp_path):
    assert armcomp.validate(ROOT / "robots" / "rock-drill.toml") == []
    text = (ROOT / "robots" / "rock-drill.toml").read_text()
    # The first joint's limits reversed, on a line we know.
    lines = text.splitlines()
    i = next(k for k, l in enumerate(lines) if l.strip().startswith("limits"))
    lines[i] = "limits = [90, -90]"
    bad = tmp_path / "bad.toml"
    bad.write_text("\n".join(lines))
    problems = armcomp.validate(bad)
    assert problems, "reversed limits are a problem"
    assert problems[0]["file"].endswith("bad.toml")
    assert problems[0]["line"] == i + 1
    assert "limits" in problems[0]["path"]


def test_check_pose_finds_the_contact_the_geometry_gives():
    robot = armcomp.Robot.load(ARM)
    assert armcomp.check_pose(robot, [0.0, 0.0]) == []
    # Upper arm horizontal, elbow folded back: the lower capsule (radius 40 mm) lies with its
    # axis on the base box's top face, so they overlap by its radius.
    contacts = armcomp.check_pose(robot, {"shoulder": math.pi / 2, "elbow": math.pi / 2})
    assert [(c["first"], c["second"], c["fixture"]) for c in contacts] == [("base", "lower", False)]
    assert abs(contacts[0]["distance"] + 0.04) < 1e-9


def test_schema_is_the_committed_one():
    committed = json.loads((ROOT / "schemas" / "robot.schema.json").read_text())
    assert json.loads(armcomp.schema()) == committed


def test_plugins_are_the_command_lines_list():
    listed = armcomp.plugins()
    assert listed == cli_json("plugins")
    # Every role is there, and the diagnosis' candidates are physical effects.
    assert {p["role"] for p in listed} == {"kinematics", "error_model", "predictor"}
    assert any(p["type"] == "gp" and p["role"] == "predictor" for p in listed)
    assert all(p["role"] == "error_model" for p in listed if p["diagnosis_candidate"])
