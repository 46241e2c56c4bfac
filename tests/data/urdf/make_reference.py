"""Reference kinematics of the URDF corpus, computed by pinocchio, independently of armcomp.

Writes reference.json next to this script: per robot, three seeded configurations, each with
the value of every moving joint by name and the world pose of every link frame by name.

    python -m venv venv && venv/bin/pip install pin==4.1.0 numpy
    venv/bin/python make_reference.py

Joint values are drawn uniformly within the URDF's <limit> (revolute, prismatic) or in
[-pi, pi] (continuous). pinocchio's default reader moves every joint independently, so a
<mimic> joint's value is set here from its relation (value = multiplier * followed + offset,
as the URDF specifies; a <mimic> on a fixed joint is ignored, as urdfdom does), and checked
against pinocchio's own mimic support (mimic=True) where it builds. Continuous joints are
(cos, sin) pairs in pinocchio's q; the angle is written. Poses are pinocchio's oMf of the BODY
frames (one per URDF link): [x, y, z, qx, qy, qz, qw], metres, rounded to 1e-12.
"""

import json
import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin

HERE = Path(__file__).resolve().parent
ROBOTS = [
    "ur5_robot.urdf",
    "panda.urdf",
    "baxter.urdf",
    "romeo.urdf",
    "romeo_laas_small.urdf",
    "tiago.urdf",
    "talos_full_v2.urdf",
]
CONFIGURATIONS = 3
SEED = 20240


def urdf_joints(path):
    """Per joint name: (type, (lower, upper) or None, (followed, multiplier, offset) or None)."""
    joints = {}
    for j in ET.parse(path).getroot().findall("joint"):
        kind = j.get("type")
        limit = j.find("limit")
        bounds = None
        if kind in ("revolute", "prismatic") and limit is not None:
            bounds = (float(limit.get("lower", 0)), float(limit.get("upper", 0)))
        m = j.find("mimic")
        mimic = None
        if m is not None and kind != "fixed":
            mimic = (m.get("joint"), float(m.get("multiplier", 1)), float(m.get("offset", 0)))
        joints[j.get("name")] = (kind, bounds, mimic)
    return joints


def joint_values(joints, moving, rng):
    """Values of the moving joints: independent ones drawn, mimic ones from their relation."""
    values = {}
    for name in moving:
        kind, bounds, mimic = joints[name]
        if mimic is not None and mimic[0] in moving:
            continue
        if kind == "continuous":
            values[name] = rng.uniform(-math.pi, math.pi)
        elif bounds is not None:
            values[name] = rng.uniform(*bounds)
        else:
            raise ValueError(f"joint {name}: {kind} without <limit>, which urdfdom refuses")

    def value(name, depth=0):
        if name not in values:
            followed, k, offset = joints[name][2]
            assert depth < len(joints), f"mimic loop at {name}"
            values[name] = k * value(followed, depth + 1) + offset
        return values[name]

    for name in moving:
        value(name)
    return values


def configuration(model, values):
    """pinocchio's q for joint values by name."""
    q = pin.neutral(model)
    for name, joint in zip(model.names[1:], model.joints[1:]):
        if joint.nq == 0:  # a mimic joint of a mimic=True model
            continue
        v = values[name]
        if joint.nq == 1:
            q[joint.idx_q] = v
        elif joint.nq == 2:  # unbounded revolute: (cos, sin)
            q[joint.idx_q : joint.idx_q + 2] = (math.cos(v), math.sin(v))
        else:
            raise ValueError(f"joint {name}: {joint.shortname()} is not a one-degree-of-freedom joint")
    return q


def link_poses(model, values):
    data = model.createData()
    pin.framesForwardKinematics(model, data, configuration(model, values))
    poses = {}
    for i, frame in enumerate(model.frames):
        if frame.type == pin.FrameType.BODY:
            placement = data.oMf[i]
            poses[frame.name] = (placement.translation.copy(), placement.rotation.copy())
    return poses


def rounded(v):
    r = round(float(v), 12)
    return 0.0 if r == 0 else r


def robot_reference(path):
    joints = urdf_joints(path)
    model = pin.buildModelFromUrdf(str(path))
    moving = list(model.names[1:])
    try:
        with_mimic = pin.buildModelFromUrdf(str(path), mimic=True)
    except (RuntimeError, ValueError):
        with_mimic = None
    rng = np.random.default_rng(SEED)
    configurations = []
    for _ in range(CONFIGURATIONS):
        values = joint_values(joints, moving, rng)
        poses = link_poses(model, values)
        assert len(poses) == len(ET.parse(path).getroot().findall("link")), "one BODY frame per link"
        if with_mimic is not None:
            for name, (p, r) in link_poses(with_mimic, values).items():
                assert np.linalg.norm(p - poses[name][0]) < 1e-12, (path.name, name)
                assert np.linalg.norm(r - poses[name][1]) < 1e-12, (path.name, name)
        links = {}
        for name, (p, r) in poses.items():
            quat = pin.Quaternion(r).coeffs()  # x, y, z, w
            links[name] = [rounded(v) for v in (*p, *quat)]
        configurations.append(
            {"q": {n: rounded(v) for n, v in values.items()}, "links": links}
        )
    mimic = sorted(n for n in moving if joints[n][2] is not None and joints[n][2][0] in moving)
    return {"mimic_joints": mimic, "configurations": configurations}


def main():
    reference = {
        "generator": f"make_reference.py, pinocchio {pin.__version__}, numpy {np.__version__}",
        "link_pose": "[x, y, z, qx, qy, qz, qw] of the link frame in the root link's frame (m)",
        "robots": {name: robot_reference(HERE / name) for name in ROBOTS},
    }
    text = json.dumps(reference, indent=1)
    # One line per number list.
    text = re.sub(r"\[\s+([^\[\]{}]*?)\s+\]", lambda m: "[" + re.sub(r"\s+", " ", m.group(1)) + "]", text)
    (HERE / "reference.json").write_text(text + "\n")


if __name__ == "__main__":
    main()
