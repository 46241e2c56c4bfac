"""Frames beyond the declared points: link poses against pinocchio's, Jacobians in pinocchio's
three reference frames against finite differences of the poses, batches against single calls,
joint values by partial name and by pandas index, and predictions in the measurement frame
against `evaluate`."""

import json
import warnings

import numpy as np
import pytest

import armcomp
from conftest import ROOT, TALOS, TALOS_DATA
from test_fk import quaternion_matrix

PANDA = ROOT / "tests" / "data" / "urdf" / "panda.urdf"


def skew_part(m):
    """The vector of the skew-symmetric part of a 3 × 3 matrix."""
    return np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]]) / 2


def finite_difference_jacobian(robot, q, frame, reference, h=1e-6):
    """Each column from central differences of the frame's pose: the body twist T⁻¹ dT for
    local, the spatial twist dT T⁻¹ for world, the origin's velocity with the spatial angular
    velocity for local_world_aligned."""
    t = robot.pose(q, frame)
    columns = []
    for k in range(robot.nq):
        dq = np.zeros(robot.nq)
        dq[k] = h
        dt = (robot.pose(q + dq, frame) - robot.pose(q - dq, frame)) / (2 * h)
        body, spatial = np.linalg.inv(t) @ dt, dt @ np.linalg.inv(t)
        if reference == "local":
            columns.append(np.r_[body[:3, 3], skew_part(body[:3, :3])])
        elif reference == "world":
            columns.append(np.r_[spatial[:3, 3], skew_part(spatial[:3, :3])])
        else:
            columns.append(np.r_[dt[:3, 3], skew_part(spatial[:3, :3])])
    return np.array(columns).T


@pytest.mark.parametrize("reference", ["local", "world", "local_world_aligned"])
def test_jacobians_in_each_reference_frame_match_finite_differences(reference):
    robot = armcomp.Robot.load(PANDA)
    q = np.random.default_rng(5).uniform(-1.0, 1.0, robot.nq)
    for frame in [robot.tool, "panda_link4"]:
        j = robot.jacobian(q, frame, reference=reference)
        np.testing.assert_allclose(j, finite_difference_jacobian(robot, q, frame, reference), atol=1e-8)


def test_the_reference_frames_are_related_as_pinocchio_relates_them():
    robot = armcomp.Robot.load(PANDA)
    q = np.random.default_rng(6).uniform(-1.0, 1.0, robot.nq)
    t = robot.pose(q)
    r, p = t[:3, :3], t[:3, 3]
    aligned = robot.jacobian(q)
    world = robot.jacobian(q, reference="WORLD")
    local = robot.jacobian(q, reference="local")
    # World: the velocity of the point at the base origin, v - ω × p.
    np.testing.assert_allclose(world[:3], aligned[:3] - np.cross(aligned[3:].T, p).T, atol=1e-12)
    np.testing.assert_allclose(local[:3], r.T @ aligned[:3], atol=1e-12)
    np.testing.assert_allclose(local[3:], r.T @ aligned[3:], atol=1e-12)
    with pytest.raises(armcomp.InputError, match="unknown reference `body`"):
        robot.jacobian(q, reference="body")


def test_link_frames_are_pinocchio_link_poses():
    """A robot file names a URDF's links only through its points; the links are frames too."""
    reference = json.loads((ROOT / "tests" / "data" / "urdf" / "reference.json").read_text())
    robot = armcomp.Robot.load(TALOS)
    talos = reference["robots"].get("talos_full_v2.urdf")
    if talos is None:
        pytest.skip("no pinocchio reference poses of TALOS")
    for c in talos["configurations"]:
        q = {n: v for n, v in c["q"].items() if n in robot.joint_names}
        compared = 0
        for name, pose in c["links"].items():
            if name in robot.frames:
                t = robot.pose(q, name)
                np.testing.assert_allclose(t[:3, 3], pose[:3], atol=1e-9)
                np.testing.assert_allclose(t[:3, :3], quaternion_matrix(*pose[3:]), atol=1e-9)
                compared += 1
        assert compared > 10


def test_links_of_a_bare_urdf_are_its_points_and_match_pinocchio():
    reference = json.loads((ROOT / "tests" / "data" / "urdf" / "reference.json").read_text())
    robot = armcomp.Robot.load(ROOT / "tests" / "data" / "urdf" / "ur5_robot.urdf")
    c = reference["robots"]["ur5_robot.urdf"]["configurations"][1]
    q = [c["q"].get(n, 0.0) for n in robot.joint_names]
    for name, pose in c["links"].items():
        t = robot.pose(q, name)
        np.testing.assert_allclose(t[:3, 3], pose[:3], atol=1e-9)
        np.testing.assert_allclose(t[:3, :3], quaternion_matrix(*pose[3:]), atol=1e-9)
    with pytest.raises(armcomp.InputError, match="no frame `nowhere`"):
        robot.pose(q, "nowhere")


def test_batches_are_the_single_calls():
    robot = armcomp.Robot.load(PANDA)
    Q = np.random.default_rng(7).uniform(-1.0, 1.0, (6, robot.nq))
    frames = [robot.tool, "panda_link3", "panda_link0"]
    poses = robot.poses_many(Q, frames)
    jacobians = robot.jacobians_many(Q, frames, reference="local")
    assert poses.shape == (6, 3, 4, 4) and jacobians.shape == (6, 3, 6, robot.nq)
    for i, q in enumerate(Q):
        for k, f in enumerate(frames):
            np.testing.assert_array_equal(poses[i, k], robot.pose(q, f))
            np.testing.assert_array_equal(jacobians[i, k], robot.jacobian(q, f, reference="local"))
    # Every frame by default, and the tool's pose is fk's.
    assert robot.poses_many(Q).shape == (6, len(robot.frames), 4, 4)
    np.testing.assert_allclose(poses[:, 0], robot.fk_many(Q, tool=True)[1], atol=1e-15)


def test_joints_by_partial_name_hold_the_robot_file_values():
    robot = armcomp.Robot.load(TALOS)
    rng = np.random.default_rng(8)
    q = np.zeros(robot.nq)
    moving = [n for n in robot.joint_names if n.startswith("arm_left") or n.startswith("torso")]
    for n in moving:
        q[robot.joint_names.index(n)] = rng.uniform(-0.5, 0.5)
    # TALOS's file holds every joint that does not move the marker at 0.
    partial = {n: q[robot.joint_names.index(n)] for n in moving}
    np.testing.assert_array_equal(robot.fk(partial)[0], robot.fk(q)[0])
    pandas = pytest.importorskip("pandas")
    series = pandas.Series(partial)
    np.testing.assert_array_equal(robot.pose(series), robot.pose(q))
    frame = pandas.DataFrame([partial, partial])
    np.testing.assert_array_equal(robot.fk_many(frame)[1], robot.fk(q)[0])
    with pytest.raises(armcomp.InputError, match="no joint `elbow`"):
        robot.fk({**partial, "elbow": 0.0})


def test_predictions_are_what_evaluate_compares_with_the_measurements():
    robot = armcomp.Robot.load(TALOS)
    data = armcomp.Measurements.read(TALOS_DATA, robot)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model, _ = armcomp.calibrate(robot, data, identify="base,markers,offsets", prior=None)
    errors = armcomp.evaluate(model, data).errors
    np.testing.assert_array_equal(model.predict_many(data.joints), data.positions - errors)
    np.testing.assert_array_equal(model.predict(data.joints[4]), data.positions[4] - errors[4])
    # The measurement frame turns base-frame positions into the tracker's.
    t = model.measurement_frame
    tool = model.fk(data.joints[4])[0][model.points.index(model.markers[0])]
    np.testing.assert_allclose(t[:3, :3] @ tool + t[:3, 3], model.predict(data.joints[4]), atol=1e-12)
    link, offset = model.marker_offsets[model.markers[0]]
    marker_pose = model.pose(data.joints[4], link) @ np.r_[offset, 1.0]
    np.testing.assert_allclose(marker_pose[:3], tool, atol=1e-12)
    with pytest.raises(armcomp.InputError, match="no station `east`"):
        model.predict(data.joints[4], station="east")
