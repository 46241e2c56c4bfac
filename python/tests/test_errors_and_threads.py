"""Errors are Python exceptions naming where the input is wrong; long calls release the GIL
and stop on Ctrl-C; measurements from arrays match a robot by joint and point names."""

import errno
import os
import signal
import threading
import time
import warnings

import numpy as np
import pytest

import armcomp
from conftest import TALOS, TALOS_DATA
from test_fk import PLANAR_2R


@pytest.fixture(scope="module")
def talos():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = armcomp.Robot.load(TALOS)
        return robot, armcomp.Measurements.read(TALOS_DATA, robot, rows="even")


def long_call(robot, data, progress=None):
    """Seconds of work: joint offsets with the prior chosen by cross-validation (many fits,
    each reported to ``progress``)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return armcomp.calibrate(
            robot, data, identify="base,markers,offsets", prior="auto", restarts=0, progress=progress
        )


class CtrlCAtFirstFit:
    """A progress callback that sends this process a Ctrl-C when the first fit is done, so the
    signal arrives while the call runs however fast the machine, and counts the fits reported
    after it."""

    def __init__(self):
        self.sent = False
        self.after = 0
        self.total = None

    def __call__(self, stage, done, total):
        self.total = total
        if self.sent:
            self.after += 1
        else:
            self.sent = True
            os.kill(os.getpid(), signal.SIGINT)


def test_a_robot_file_error_names_file_line_and_field(tmp_path):
    path = tmp_path / "arm.toml"
    path.write_text(PLANAR_2R.replace('a = 0.7', 'a = "long"'))
    with pytest.raises(armcomp.InputError) as e:
        armcomp.Robot.load(path)
    assert e.value.file == str(path)
    assert e.value.line == PLANAR_2R.splitlines().index('a = 0.7') + 1
    assert "kinematics" in e.value.field and "a" in e.value.field
    assert isinstance(e.value, ValueError)


def test_a_missing_file_is_named(tmp_path):
    for read in [armcomp.Measurements.read, armcomp.Robot.load]:
        with pytest.raises(armcomp.InputError) as e:
            read(tmp_path / "missing.toml")
        assert e.value.file == str(tmp_path / "missing.toml") and "does not exist" in str(e.value)


def test_bad_arguments_name_the_argument(talos):
    robot, data = talos
    with pytest.raises(armcomp.InputError) as e:
        armcomp.calibrate(robot, data, prior="sometimes")
    assert e.value.field == "prior"
    with pytest.raises(armcomp.InputError) as e:
        armcomp.compensate(robot, np.zeros((2, 4)))
    assert e.value.field == "targets"


def test_a_measurement_error_names_its_column(tmp_path):
    robot = armcomp.Robot.from_toml(PLANAR_2R)
    path = tmp_path / "bad.csv"
    path.write_text("j1[deg],j2[deg],x[mm],y[mm],z[mm]\n10,20,1,abc,0\n")
    with pytest.raises(armcomp.InputError) as e:
        armcomp.Measurements.read(path, robot)
    assert (e.value.file, e.value.line, e.value.field) == (str(path), 2, "y[mm]")


def test_bad_starts_and_locks_name_the_argument():
    robot = armcomp.Robot.from_toml(PLANAR_2R)
    targets = robot.fk_many(np.array([[0.3, -0.2]] * 3))[:, robot.points.index("tool"), :]
    with pytest.raises(armcomp.InputError) as e:
        armcomp.compensate(robot, targets, start=np.zeros((2, 2)))
    assert e.value.field == "start" and "2 start configurations for 3 targets" in str(e.value)
    with pytest.raises(armcomp.InputError) as e:
        armcomp.compensate(robot, targets, lock=["elbow"])
    assert e.value.field == "lock" and "locked joint `elbow`" in str(e.value)


def test_measurements_from_arrays_follow_joint_and_point_names():
    robot = armcomp.Robot.from_toml(PLANAR_2R)
    q = np.array([[0.3, -0.2], [1.0, 0.5], [-0.7, 1.2]])
    positions = robot.fk_many(q)[:, robot.points.index("tool"), :]
    # Columns in another order than the robot's, named; the tool measured exactly.
    data = armcomp.Measurements(q[:, ::-1], positions, points="tool", joint_names=["j2", "j1"])
    assert armcomp.evaluate(robot, data).max_mm < 1e-9
    # Without names the columns are the robot's joints in order.
    assert armcomp.evaluate(robot, armcomp.Measurements(q, positions, points=["tool"] * 3)).max_mm < 1e-9
    shifted = armcomp.Measurements(q, positions + [0.001, 0.0, 0.0], points="tool")
    report = armcomp.evaluate(robot, shifted)
    np.testing.assert_allclose(report.errors, [[0.001, 0.0, 0.0]] * 3, atol=1e-12)
    assert report.mean_abs_mm.x == pytest.approx(1.0)
    with pytest.raises(armcomp.InputError) as e:
        armcomp.evaluate(robot, armcomp.Measurements(q, positions, joint_names=["j1", "elbow"]))
    assert "elbow" in str(e.value) and e.value.field == "joint_names"


def test_long_calls_release_the_gil(talos):
    worker = threading.Thread(target=long_call, args=talos)
    start = time.perf_counter()
    worker.start()
    # This thread runs on while the calibration goes on: were the GIL held through the call,
    # it would stand still for as long as the call takes (no switch interval applies to native
    # code that does not give the GIL up).
    longest_stall, last = 0.0, time.perf_counter()
    while worker.is_alive():
        now = time.perf_counter()
        longest_stall, last = max(longest_stall, now - last), now
    worker.join()
    took = time.perf_counter() - start
    assert took > 0.2, f"the call took {took:.3f} s: too short to tell"
    assert longest_stall < took / 2, f"stood still {longest_stall:.3f} s of the call's {took:.3f} s"


def test_threads_evaluating_one_robot_get_their_own_values():
    """`fk`, `fk_many` and `jacobian` share one robot's buffers; threads calling them at once
    (`fk_many` without the GIL) neither wait for each other forever nor mix their values."""
    robot = armcomp.Robot.from_toml(PLANAR_2R)
    tool = robot.points.index("tool")

    def tool_xy(q):
        q1, q12 = q[:, 0], q[:, 0] + q[:, 1]
        return 0.7 * np.cos(q1) + 0.4 * np.cos(q12), 0.7 * np.sin(q1) + 0.4 * np.sin(q12)

    failures = []

    def worker(seed):
        rng = np.random.default_rng(seed)
        try:
            for _ in range(30):
                q = rng.uniform(-3.0, 3.0, (2000, 2))
                x, y = tool_xy(q)
                many = robot.fk_many(q)[:, tool, :]
                np.testing.assert_allclose(many[:, 0], x, atol=1e-12)
                np.testing.assert_allclose(many[:, 1], y, atol=1e-12)
                positions, pose = robot.fk(q[0])
                np.testing.assert_allclose(positions[tool, :2], [x[0], y[0]], atol=1e-12)
                np.testing.assert_allclose(pose[:2, 3], [x[0], y[0]], atol=1e-12)
                np.testing.assert_allclose(robot.jacobian(q[1])[5], [1.0, 1.0], atol=1e-12)
        except AssertionError as e:
            failures.append(e)

    threads = [threading.Thread(target=worker, args=(seed,)) for seed in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert not any(t.is_alive() for t in threads), "a thread is stuck"
    assert not failures, failures[0]


def test_ctrl_c_stops_a_long_call_and_the_next_one_runs(talos):
    robot, data = talos
    ctrl_c = CtrlCAtFirstFit()
    with pytest.raises(KeyboardInterrupt):
        long_call(robot, data, progress=ctrl_c)
    # The fits running when the signal came end; no new one starts.
    assert ctrl_c.after < ctrl_c.total // 2, (ctrl_c.after, ctrl_c.total)
    # The stop request is withdrawn: the same call completes afterwards.
    model, report = long_call(robot, data)
    assert report.converged


def test_ctrl_c_stops_only_the_call_of_the_thread_it_was_meant_for(talos):
    robot, data = talos
    expected, _ = long_call(robot, data)
    results = []
    # A call in another thread, running while the main thread's call is stopped.
    other = threading.Thread(target=lambda: results.append(long_call(robot, data)))
    other.start()
    with pytest.raises(KeyboardInterrupt):
        long_call(robot, data, progress=CtrlCAtFirstFit())
    other.join(timeout=120)
    assert not other.is_alive(), "the other thread's call is stuck"
    assert len(results) == 1, "the other thread's call was stopped too"
    model, report = results[0]
    assert report.converged
    np.testing.assert_array_equal(model.parameters[1], expected.parameters[1])


def test_an_output_that_cannot_be_written_says_why(tmp_path):
    robot = armcomp.Robot.from_toml(PLANAR_2R)
    target = tmp_path / "missing" / "model.toml"
    with pytest.raises(OSError) as e:
        robot.save(target)
    assert e.value.filename == str(target)
    # The kind of refusal, not its wording, gives the errno: Python picks the subclass from it.
    assert e.value.errno == errno.ENOENT and isinstance(e.value, FileNotFoundError)
    assert e.value.strerror
    assert "None" not in str(e.value), str(e.value)
    read_only = tmp_path / "kept.toml"
    read_only.write_text("kept")
    read_only.chmod(0o444)
    with pytest.raises(PermissionError) as e:
        robot.save(read_only)
    assert e.value.errno == errno.EACCES and "read-only" in e.value.strerror
    assert read_only.read_text() == "kept"


def test_fk_of_a_two_dimensional_array_names_the_argument_and_fk_many():
    robot = armcomp.Robot.from_toml(PLANAR_2R)
    with pytest.raises(armcomp.InputError) as e:
        robot.fk(np.zeros((2, 2)))
    assert e.value.field == "q"
    assert "[2, 2]" in str(e.value) and "fk_many" in str(e.value)


def test_fk_many_of_a_one_dimensional_array_names_the_argument_and_its_shape():
    robot = armcomp.Robot.from_toml(PLANAR_2R)
    with pytest.raises(armcomp.InputError) as e:
        robot.fk_many(np.zeros(32))
    assert e.value.field == "Q"
    assert "[32]" in str(e.value) and "reshape(1, -1)" in str(e.value)


def test_evaluation_errors_are_typed_as_an_array():
    import typing

    hints = typing.get_type_hints(armcomp.EvaluationReport)
    assert hints["errors"] is np.ndarray


def test_plan_with_an_unknown_method_lists_the_selection_methods():
    robot = armcomp.Robot.from_toml(PLANAR_2R)
    with pytest.raises(armcomp.InputError) as e:
        armcomp.plan(robot, n=3, method="doptimal")
    assert e.value.field == "method"
    assert "d-optimal" in str(e.value) and "uncertainty" in str(e.value)


def test_a_target_out_of_reach_is_listed_and_the_others_are_still_solved():
    robot = armcomp.Robot.from_toml(PLANAR_2R)
    # The planar arm reaches 0.7 + 0.4 = 1.1 m at most: the second target, 3 m out, is not.
    targets = [[0.8, 0.3, 0.0], [3.0, 0.0, 0.0], [0.5, 0.5, 0.0]]
    c = armcomp.compensate(robot, targets, frame="base")
    q, corrected, unconverged = c.q, c.corrected, c.unconverged
    assert q.shape == (3, 2)
    assert [i for i, _ in unconverged] == [1]
    # Its command is the closest found: the arm stretched towards it, 1.9 m short.
    assert abs(unconverged[0][1] - 1.9) < 1e-3
    assert np.allclose(corrected[1], [1.1, 0.0, 0.0], atol=1e-3)
    tool = robot.points.index("tool")
    for k in (0, 2):
        positions, _ = robot.fk(q[k])
        assert np.allclose(positions[tool], targets[k], atol=1e-6)


def test_measurements_never_replace_the_file_they_were_read_from(tmp_path, talos):
    robot, _ = talos
    source = tmp_path / "m.csv"
    text = TALOS_DATA.read_text()
    source.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for data in (
            armcomp.Measurements.read(source, robot),
            armcomp.Measurements.read(source),
            armcomp.Measurements.read(source).for_robot(robot),
        ):
            with pytest.raises(OSError, match="refusing to overwrite an input"):
                data.save(source, robot)
            assert source.read_text() == text
        # Elsewhere it writes.
        armcomp.Measurements.read(source, robot).save(tmp_path / "copy.csv", robot)
    assert (tmp_path / "copy.csv").exists()


def _calibrate_in_child(queue):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = armcomp.Robot.load(TALOS)
        data = armcomp.Measurements.read(TALOS_DATA, robot, rows="even")
        _, report = armcomp.calibrate(robot, data, identify="base,markers,offsets", restarts=0)
    queue.put(report.converged)


def test_a_forked_child_calibrates_after_its_parent_did(talos):
    # A fork copies one thread: a pool the parent's calibration started has no workers in
    # the child, which must not wait for them.
    import multiprocessing

    robot, data = talos
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        armcomp.calibrate(robot, data, identify="base,markers,offsets", restarts=0)
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    child = context.Process(target=_calibrate_in_child, args=(queue,))
    child.start()
    child.join(120)
    hung = child.is_alive()
    if hung:
        child.kill()
    assert not hung, "the forked child did not return from calibrate"
    assert child.exitcode == 0
    assert queue.get(timeout=5) is True
