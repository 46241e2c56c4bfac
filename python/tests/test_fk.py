"""Forward kinematics and Jacobians against independent values: trigonometry for a planar
arm, pinocchio's link poses for published URDFs, finite differences for the Jacobian."""

import json
import math

import numpy as np
import pytest

import armcomp
from conftest import ROOT

# The planar two-link arm the Rust tests share (its masses and gravity do not enter FK).
PLANAR_2R = (ROOT / "tests" / "data" / "robots" / "planar-2r.toml").read_text()


def test_planar_two_link_arm_matches_trigonometry():
    robot = armcomp.Robot.from_toml(PLANAR_2R)
    assert robot.joint_names == ["j1", "j2"]
    for q1, q2 in [(0.0, 0.0), (0.3, -1.1), (2.0, 0.5), (-2.9, 3.0)]:
        positions, tool = robot.fk([q1, q2])
        x = 0.7 * math.cos(q1) + 0.4 * math.cos(q1 + q2)
        y = 0.7 * math.sin(q1) + 0.4 * math.sin(q1 + q2)
        np.testing.assert_allclose(positions[robot.points.index("tool")], [x, y, 0.0], atol=1e-12)
        np.testing.assert_allclose(tool[:3, 3], [x, y, 0.0], atol=1e-12)
        # The tool's x axis points along the last link.
        np.testing.assert_allclose(tool[:3, 0], [math.cos(q1 + q2), math.sin(q1 + q2), 0.0], atol=1e-12)


def test_planar_jacobian_is_the_textbook_one():
    robot = armcomp.Robot.from_toml(PLANAR_2R)
    q1, q2 = 0.4, -0.9
    j = robot.jacobian([q1, q2])
    s1, c1 = math.sin(q1), math.cos(q1)
    s12, c12 = math.sin(q1 + q2), math.cos(q1 + q2)
    expected = np.array(
        [
            [-0.7 * s1 - 0.4 * s12, -0.4 * s12],
            [0.7 * c1 + 0.4 * c12, 0.4 * c12],
            [0.0, 0.0],
            [0.0, 0.0],
            [0.0, 0.0],
            [1.0, 1.0],
        ]
    )
    np.testing.assert_allclose(j, expected, atol=1e-12)


def quaternion_matrix(qx, qy, qz, qw):
    return np.array(
        [
            [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
            [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
            [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)],
        ]
    )


@pytest.mark.parametrize("urdf", ["ur5_robot.urdf", "panda.urdf", "tiago.urdf"])
def test_bare_urdf_links_match_pinocchio(urdf):
    reference = json.loads((ROOT / "tests" / "data" / "urdf" / "reference.json").read_text())
    robot = armcomp.Robot.load(ROOT / "tests" / "data" / "urdf" / urdf)
    configurations = reference["robots"][urdf]["configurations"]
    assert configurations
    qs = np.array([[c["q"].get(n, 0.0) for n in robot.joint_names] for c in configurations])
    batch = robot.fk_many(qs)
    assert batch.shape == (len(configurations), len(robot.points), 3)
    for c, q, many in zip(configurations, qs, batch):
        positions, _ = robot.fk(q)
        np.testing.assert_array_equal(many, positions)
        compared = 0
        for name, pose in c["links"].items():
            if name in robot.points:
                np.testing.assert_allclose(positions[robot.points.index(name)], pose[:3], atol=1e-9)
                compared += 1
        assert compared >= len(robot.joint_names)


def test_bare_urdf_orientation_matches_pinocchio():
    reference = json.loads((ROOT / "tests" / "data" / "urdf" / "reference.json").read_text())
    urdf = "ur5_robot.urdf"
    robot = armcomp.Robot.load(ROOT / "tests" / "data" / "urdf" / urdf)
    for c in reference["robots"][urdf]["configurations"]:
        _, tool = robot.fk([c["q"].get(n, 0.0) for n in robot.joint_names])
        pose = c["links"][robot.tool]
        np.testing.assert_allclose(tool[:3, :3], quaternion_matrix(*pose[3:]), atol=1e-9)
        np.testing.assert_allclose(tool[:3, 3], pose[:3], atol=1e-9)


def test_jacobian_matches_central_differences_of_fk():
    robot = armcomp.Robot.load(ROOT / "tests" / "data" / "urdf" / "panda.urdf")
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.0, 1.0, robot.nq)
    j = robot.jacobian(q)
    h = 1e-6
    point = robot.points.index(robot.tool)
    for k in range(robot.nq):
        dq = np.zeros(robot.nq)
        dq[k] = h
        plus, _ = robot.fk(q + dq)
        minus, _ = robot.fk(q - dq)
        np.testing.assert_allclose(j[:3, k], (plus[point] - minus[point]) / (2 * h), atol=1e-7)


def test_fk_many_reads_any_layout_and_dtype():
    robot = armcomp.Robot.from_toml(PLANAR_2R)
    q = np.array([[0.1, 0.2], [0.3, -0.4], [1.0, 2.0]])
    expected = robot.fk_many(q)
    np.testing.assert_array_equal(robot.fk_many(np.asfortranarray(q)), expected)
    np.testing.assert_array_equal(robot.fk_many(q.T.copy().T), expected)
    np.testing.assert_array_equal(robot.fk_many(q.tolist()), expected)
    assert robot.fk_many(np.zeros((0, 2))).shape == (0, len(robot.points), 3)
    np.testing.assert_array_equal(robot.fk_many(np.zeros((2, 2), dtype=np.int64))[0], robot.fk([0, 0])[0])


def test_joint_limits_are_the_urdf_ones_in_si():
    robot = armcomp.Robot.load(ROOT / "tests" / "data" / "urdf" / "panda.urdf")
    # Franka's published range of joint 4 (rad).
    np.testing.assert_allclose(robot.joint_limits[robot.joint_names.index("panda_joint4")], [-3.0718, -0.0698])


def test_fk_rejects_wrong_sizes_and_non_finite_values():
    robot = armcomp.Robot.from_toml(PLANAR_2R)
    with pytest.raises(armcomp.InputError) as e:
        robot.fk([0.1])
    assert "expected 2" in str(e.value)
    with pytest.raises(armcomp.InputError) as e:
        robot.fk_many(np.zeros((3, 3)))
    assert e.value.field == "Q"
    with pytest.raises(armcomp.InputError) as e:
        robot.fk_many([[0.0, 0.0], [0.0, math.nan]])
    assert "configuration 2" in str(e.value)


def test_joint_values_by_name_are_those_by_position_in_any_order():
    robot = armcomp.Robot.from_toml(PLANAR_2R)
    q1, q2 = 0.3, -1.1
    by_position = robot.fk([q1, q2])
    by_name = robot.fk({"j2": q2, "j1": q1})
    for a, b in zip(by_position, by_name):
        np.testing.assert_array_equal(a, b)
    # The textbook planar arm, so a swapped order would show.
    x = 0.7 * math.cos(q1) + 0.4 * math.cos(q1 + q2)
    assert abs(by_name[1][0, 3] - x) < 1e-12
    np.testing.assert_array_equal(robot.jacobian({"j1": q1, "j2": q2}), robot.jacobian([q1, q2]))
    with pytest.raises(armcomp.InputError, match="no joint `j3`; its joints are: j1, j2"):
        robot.fk({"j1": q1, "j2": q2, "j3": 0.0})
    with pytest.raises(armcomp.InputError, match="no value for joint"):
        robot.fk({"j1": q1})


def test_fk_many_gives_the_tool_poses_of_fk():
    robot = armcomp.Robot.load(ROOT / "robots" / "industrial-6dof.toml")
    Q = np.random.default_rng(3).uniform(-1.0, 1.0, (50, robot.nq))
    positions, tools = robot.fk_many(Q, tool=True)
    assert tools.shape == (50, 4, 4)
    np.testing.assert_array_equal(positions, robot.fk_many(Q))
    for q, p, t in zip(Q, positions, tools):
        one_p, one_t = robot.fk(q)
        np.testing.assert_array_equal(p, one_p)
        np.testing.assert_array_equal(t, one_t)
