"""JointMap puts joint vectors in armcomp's order and back: by name for a list of names, and
with pinocchio's layout (continuous joints as cos, sin; free-flyers skipped) for a Model."""

import math
import warnings

import numpy as np
import pytest

import armcomp
from armcomp._joint_map import JointMap

class DuckJoint:
    def __init__(self, nq, nv, idx_q):
        self.nq, self.nv, self.idx_q = nq, nv, idx_q


class DuckModel:
    """What JointMap reads of a pinocchio.Model: ``names`` from "universe", ``joints`` (each
    with nq, nv, idx_q), ``nqs``, ``nvs`` and ``idx_qs`` (``lists=False`` leaves out ``nqs``
    and ``nvs``), ``nq``. Joints are (name, nq, nv), laid out in order."""

    def __init__(self, joints, lists=True):
        self.names = ["universe"]
        # pinocchio's universe: no coordinates.
        self.joints = [DuckJoint(0, 0, 0)]
        self.idx_qs = [0]
        idx = 0
        for name, nq, nv in joints:
            self.names.append(name)
            self.joints.append(DuckJoint(nq, nv, idx))
            self.idx_qs.append(idx)
            idx += nq
        if lists:
            self.nqs = [j.nq for j in self.joints]
            self.nvs = [j.nv for j in self.joints]
        self.nq = idx


# A free-flyer first, then the arm in another order than armcomp's, with a continuous wheel
# and a universal joint (two angles) armcomp lacks: q is
# [x y z qx qy qz qw | j3 | cos j1, sin j1 | cos, sin wheel | universal × 2 | j2], 15 values.
PIN_JOINTS = [("root_joint", 7, 6), ("j3", 1, 1), ("j1", 2, 1), ("wheel", 2, 1), ("universal", 2, 2), ("j2", 1, 1)]
NQ = 15
ARM = ["j1", "j2", "j3"]


@pytest.fixture(params=[True, False], ids=["nqs lists", "joints only"])
def duck(request):
    return DuckModel(PIN_JOINTS, lists=request.param)


def test_layout_of_a_pinocchio_model(duck):
    m = JointMap(ARM, duck)
    assert m.nq == NQ
    assert m.indices.tolist() == [8, 14, 7]
    assert m.continuous == ["j1"]
    assert m.skipped == ["root_joint", "wheel", "universal"]
    assert m.held == []
    assert "skipped: root_joint" in repr(m) and "continuous: j1" in repr(m)


def test_continuous_joints_are_cos_sin_and_the_free_flyer_neutral(duck):
    m = JointMap(ARM, duck)
    q = m.from_armcomp([0.5, -0.3, 0.2])
    # By hand: translation 0, identity quaternion (x, y, z, w), j3, cos/sin of j1, the
    # wheel's neutral angle 0 as (1, 0), the universal joint's 0, 0, and j2.
    expected = [0, 0, 0, 0, 0, 0, 1, 0.2, math.cos(0.5), math.sin(0.5), 1, 0, 0, 0, -0.3]
    np.testing.assert_allclose(q, expected, rtol=0, atol=1e-15)
    np.testing.assert_allclose(m.to_armcomp(q), [0.5, -0.3, 0.2], rtol=0, atol=1e-15)


def test_to_armcomp_ignores_the_free_flyer_and_wraps_continuous_angles(duck):
    m = JointMap(ARM, duck)
    q = np.array([1, 2, 3, 0.5, 0.5, 0.5, 0.5, 0.2, math.cos(4.0), math.sin(4.0), 0, 1, 5, 6, -0.3])
    # atan2 gives the angle in (-π, π]: 4 rad comes back as 4 − 2π.
    np.testing.assert_allclose(m.to_armcomp(q), [4.0 - 2 * math.pi, -0.3, 0.2], atol=1e-14)
    # A continuous joint's (cos, sin) need not be of norm 1: the angle is atan2's.
    q[8:10] = [0.0, 2.0]
    assert m.to_armcomp(q)[0] == pytest.approx(math.pi / 2)


def test_from_armcomp_keeps_the_base_configuration(duck):
    m = JointMap(ARM, duck)
    base = np.arange(NQ) + 10.0
    q = m.from_armcomp([0.5, -0.3, 0.2], base=base)
    np.testing.assert_array_equal(q[:7], base[:7])
    np.testing.assert_array_equal(q[10:14], base[10:14])
    np.testing.assert_allclose(q[[7, 8, 9, 14]], [0.2, math.cos(0.5), math.sin(0.5), -0.3])
    assert base[7] == 17.0, "the base is not changed"


def test_batches(duck):
    m = JointMap(ARM, duck)
    rng = np.random.default_rng(1)
    qs = rng.uniform(-3, 3, size=(5, 3))
    other = m.from_armcomp(qs)
    assert other.shape == (5, NQ)
    for row, q in zip(other, qs):
        np.testing.assert_array_equal(row, m.from_armcomp(q))
    np.testing.assert_allclose(m.to_armcomp(other), qs, atol=1e-14)
    # One base for every row, or one per row.
    bases = rng.normal(size=(5, NQ))
    np.testing.assert_array_equal(m.from_armcomp(qs, base=bases)[:, :7], bases[:, :7])
    np.testing.assert_array_equal(m.from_armcomp(qs[0], base=bases)[:, 7], np.full(5, qs[0, 2]))
    with pytest.raises(ValueError, match="4 rows and base 5"):
        m.from_armcomp(qs[:4], base=bases)


def test_wrong_shapes_say_what_was_expected(duck):
    m = JointMap(ARM, duck)
    with pytest.raises(ValueError, match="expected 15 values"):
        m.to_armcomp(np.zeros(11))
    with pytest.raises(ValueError, match="expected 3 values"):
        m.from_armcomp(np.zeros((2, 4)))
    with pytest.raises(ValueError, match="expected 15 values"):
        m.from_armcomp(np.zeros(3), base=np.zeros(7))


def test_armcomp_joints_missing_there_are_named_or_held(duck):
    with pytest.raises(ValueError, match="j4"):
        JointMap(["j1", "j2", "j3", "j4"], duck)
    # A joint of several degrees of freedom there is no armcomp coordinate, and is said so.
    with pytest.raises(ValueError, match=r"root_joint \(nq 7, nv 6\), universal \(nq 2, nv 2\)"):
        JointMap(["root_joint", "universal", "j1"], duck)
    m = JointMap(["j4", "j1", "j2", "j3"], duck, missing="hold", hold={"j4": 0.7})
    assert m.held == ["j4"] and m.indices.tolist() == [-1, 8, 14, 7]
    q = m.from_armcomp([0.1, 0.5, -0.3, 0.2])
    np.testing.assert_allclose(m.to_armcomp(q), [0.7, 0.5, -0.3, 0.2], atol=1e-15)
    assert JointMap(["j4", "j1"], duck, missing="hold").to_armcomp(q)[0] == 0.0, "hold's default"
    by_position = JointMap(["j4", "j1", "j2", "j3"], duck, missing="hold", hold=[0.7, 9, 9, 9])
    np.testing.assert_allclose(by_position.to_armcomp(q), [0.7, 0.5, -0.3, 0.2], atol=1e-15)
    with pytest.raises(ValueError, match="expected 2 values"):
        JointMap(["j4", "j1"], duck, missing="hold", hold=[0.7])
    with pytest.raises(ValueError, match="not held joints: j1"):
        JointMap(["j4", "j1"], duck, missing="hold", hold={"j1": 1.0})
    with pytest.raises(ValueError, match="only used with missing='hold'"):
        JointMap(ARM, duck, hold={"j1": 1.0})
    with pytest.raises(ValueError, match="'raise' or 'hold'"):
        JointMap(ARM, duck, missing="zero")


def test_name_lists():
    m = JointMap(["a", "b", "c"], ["c", "x", "a", "b"])
    assert m.indices.tolist() == [2, 3, 0] and m.nq == 4 and m.skipped == ["x"]
    np.testing.assert_array_equal(m.from_armcomp([1.0, 2.0, 3.0]), [3.0, 0.0, 1.0, 2.0])
    np.testing.assert_array_equal(m.to_armcomp([3.0, 9.0, 1.0, 2.0]), [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="named twice: a"):
        JointMap(["a"], ["a", "b", "a"])
    with pytest.raises(TypeError, match="joint names or a pinocchio Model"):
        JointMap(["a"], "a")
    with pytest.raises(ValueError, match="b, c"):
        JointMap(["a", "b", "c"], ["a"])


def test_a_real_robot_and_its_joints_reversed(in_root):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the TALOS meshes the checkout does not hold
        robot = armcomp.Robot.load("robots/talos-left-arm.toml")
    names = robot.joint_names
    n = len(names)
    m = JointMap(names, names[::-1])
    assert m.indices.tolist() == list(range(n - 1, -1, -1)) and m.skipped == []
    q = np.linspace(-0.5, 0.5, n)
    np.testing.assert_array_equal(m.from_armcomp(q), q[::-1])
    # The joints found by name move the robot as armcomp's own vector does.
    np.testing.assert_array_equal(robot.fk_many(m.to_armcomp(q[::-1])[None]), robot.fk_many(q[None]))


INERTIAL = '<inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>'
TINY_URDF = f"""<robot name="tiny">
  <link name="base"/>
  <link name="l1">{INERTIAL}</link>
  <link name="l2">{INERTIAL}</link>
  <link name="l3">{INERTIAL}</link>
  <joint name="shoulder" type="continuous"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/></joint>
  <joint name="elbow" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.5 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="l2"/><child link="l3"/><origin xyz="0.4 0 0"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.3" effort="1" velocity="1"/></joint>
</robot>"""


def test_a_real_pinocchio_model():
    pinocchio = pytest.importorskip("pinocchio")
    model = pinocchio.buildModelFromXML(TINY_URDF, pinocchio.JointModelFreeFlyer())
    m = JointMap(["slide", "elbow", "shoulder"], model)
    assert m.skipped == ["root_joint"] and m.continuous == ["shoulder"] and m.nq == model.nq == 11
    # pinocchio's own configuration for these angles: its neutral moved by the velocities.
    angles = {"slide": 0.1, "elbow": -0.4, "shoulder": 2.5}
    v = np.zeros(model.nv)
    for name, value in angles.items():
        v[model.joints[model.getJointId(name)].idx_v] = value
    q = pinocchio.integrate(model, pinocchio.neutral(model), v)
    np.testing.assert_allclose(m.from_armcomp(list(angles.values())), q, atol=1e-12)
    np.testing.assert_allclose(m.to_armcomp(q), list(angles.values()), atol=1e-12)
