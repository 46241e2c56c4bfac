"""The package and the `armcomp` command give the same results on the same inputs: the same
model bytes, the same JSON reports, the same measurements, poses and joint commands."""

import csv
import math
import pickle
import warnings

import numpy as np
import pytest

import armcomp
from conftest import ROOT, TALOS, TALOS_DATA, cli, cli_json

TRUTH = ROOT / "robots" / "industrial-6dof-truth.toml"
NOMINAL = ROOT / "robots" / "industrial-6dof.toml"
GEOMETRY = "base,markers,geometry"


def read_table(path):
    """A CSV written by the command line: header and rows of floats (strings kept)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def to_si(header, column):
    """A joint column's values in SI, from the unit in its header."""
    unit = header.split("[")[1].rstrip("]") if "[" in header else ""
    scale = {"deg": math.pi / 180, "mm": 1e-3, "rad": 1.0, "m": 1.0}[unit]
    return np.array([float(v) for v in column]) * scale


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """40 measurements of the industrial truth, by the command line and by the package."""
    tmp = tmp_path_factory.mktemp("sim")
    cli("simulate", "--robot", TRUTH, "--n", 40, "--noise-mm", 0.05, "--seed", 3, "--out", tmp / "cli.csv")
    # Both read the command line's file: the same inputs to the last bit (a file in mm and
    # degrees does not hold the simulation's SI values exactly).
    return tmp, armcomp.Measurements.read(tmp / "cli.csv", armcomp.Robot.load(TRUTH))


def test_simulate_writes_the_same_bytes(simulated):
    tmp, _ = simulated
    truth = armcomp.Robot.load(TRUTH)
    data = armcomp.simulate(truth, n=40, noise_mm=0.05, seed=3)
    data.save(tmp / "py.csv", truth)
    assert (tmp / "py.csv").read_bytes() == (tmp / "cli.csv").read_bytes()
    assert len(data) == 40 and data.positions.shape == (40, 3)
    # The noise is what was asked for: the same poses without noise, 0.05 mm per axis apart.
    exact = armcomp.simulate(truth, poses=data.joints)
    assert 0.03 < np.std(data.positions - exact.positions) * 1e3 < 0.07


@pytest.mark.parametrize("ext", ["toml", "json"])
def test_calibrate_writes_the_same_model_and_report(simulated, ext):
    tmp, data = simulated
    expected = cli_json(
        "calibrate", "--robot", TRUTH, "--data", tmp / "cli.csv", "--noise-mm", 0.05, "--identify", GEOMETRY,
        "--out", tmp / f"cli.{ext}",
    )
    model, report = armcomp.calibrate(armcomp.Robot.load(TRUTH), data, noise_mm=0.05, identify=GEOMETRY)
    model.save(tmp / f"py.{ext}")
    assert (tmp / f"py.{ext}").read_bytes() == (tmp / f"cli.{ext}").read_bytes()
    assert report.to_dict() == expected
    assert report.converged and not report.far_above_noise
    assert report.parameters["base.x"].unit == "m"


def test_not_converged_carries_the_model_the_command_line_writes(simulated):
    """The nominal arm lacks the truth's reducers and payload, and three iterations are not
    enough: the fit stops unconverged far above the noise (exit 3), and the best model is
    still written."""
    tmp, data = simulated
    args = ["--noise-mm", 0.05, "--max-iterations", 3]
    expected = cli_json("calibrate", "--robot", NOMINAL, "--data", tmp / "cli.csv", *args, "--out", tmp / "nc.toml", expect=(3,))
    with pytest.warns(armcomp.CalibrationWarning), pytest.raises(armcomp.NotConverged) as e:
        armcomp.calibrate(armcomp.Robot.load(NOMINAL), data, noise_mm=0.05, max_iterations=3)
    assert not e.value.report.converged and e.value.report.to_dict() == expected
    assert e.value.report.far_above_noise
    e.value.model.save(tmp / "nc-py.toml")
    assert (tmp / "nc-py.toml").read_bytes() == (tmp / "nc.toml").read_bytes()


def test_talos_levels_match_the_command_line(tmp_path):
    """The TALOS levels of docs/reproductions/talos.md: registration with a declared 0.1 mm noise
    (which it ends far above: exit 3 and a warning) and joint offsets without priors, the noise
    estimated, trained on the even rows."""
    robot = armcomp.Robot.load(TALOS)
    train = armcomp.Measurements.read(TALOS_DATA, rows="even")
    for identify, prior, noise, code in [("base,markers", "1", 0.1, 3), ("base,markers,offsets", "none", None, 0)]:
        declared = [] if noise is None else ["--noise-mm", noise]
        expected = cli_json(
            "calibrate", "--robot", TALOS, "--data", TALOS_DATA, "--rows", "even", "--identify", identify,
            "--prior", prior, *declared, "--out", tmp_path / "cli.toml", expect=(code,),
        )
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            model, report = armcomp.calibrate(
                robot, train, identify=identify, prior=None if prior == "none" else 1.0, noise_mm=noise
            )
        far = [w for w in caught if issubclass(w.category, armcomp.CalibrationWarning)]
        assert bool(far) == (code == 3) == report.far_above_noise
        model.save(tmp_path / "py.toml")
        assert (tmp_path / "py.toml").read_bytes() == (tmp_path / "cli.toml").read_bytes()
        assert report.to_dict() == expected
    # Evaluation on the held-out rows, and the identified URDF.
    assert armcomp.evaluate(model, armcomp.Measurements.read(TALOS_DATA, rows="odd")).to_dict() == cli_json(
        "evaluate", "--model", tmp_path / "cli.toml", "--data", TALOS_DATA, "--rows", "odd"
    )
    # Pickled robots and models (multiprocessing) compute the same bits.
    for original in (robot, model):
        copy = pickle.loads(pickle.dumps(original))
        q = np.linspace(-0.3, 0.3, original.nq)
        for a, b in zip(original.fk(q), copy.fk(q)):
            np.testing.assert_array_equal(a, b)
    # A report's repr is a few lines; every field is one call away.
    short, full = repr(report), report.full_repr()
    assert len(short) < 1500 and f"params=<{len(report.params)} items>" in short, short
    assert all(p.name in full for p in report.params)
    assert f"after={report.after!r}" in short and "mean_mm=" in repr(report.after)
    cli("export-urdf", "--model", tmp_path / "cli.toml", "--out", tmp_path / "cli.urdf")
    assert model.to_urdf(tmp_path / "py.urdf") is None
    assert (tmp_path / "py.urdf").read_bytes() == (tmp_path / "cli.urdf").read_bytes()


def test_evaluate_reports_per_point_as_the_command_line(simulated):
    tmp, data = simulated
    nominal = armcomp.Robot.load(NOMINAL)
    report = armcomp.evaluate(nominal, data)
    assert report.to_dict() == cli_json("evaluate", "--model", NOMINAL, "--data", tmp / "cli.csv")
    # The errors are measured minus modelled positions.
    np.testing.assert_allclose(
        np.sqrt(np.mean(np.sum(report.errors**2, axis=1))) * 1e3, report.rms_mm, rtol=1e-12
    )


def test_learn_writes_the_same_model(simulated, tmp_path):
    tmp, data = simulated
    model, _ = armcomp.calibrate(armcomp.Robot.load(TRUTH), data, noise_mm=0.05, identify=GEOMETRY)
    with_predictor = tmp_path / "model.toml"
    with_predictor.write_text(model.to_text() + '\n[predictor]\ntype = "ridge"\n')
    cli("learn", "--model", with_predictor, "--data", tmp / "cli.csv", "--out", tmp_path / "cli.toml")
    fitted, report = armcomp.learn(armcomp.Robot.load(with_predictor), data)
    # A pickled model (multiprocessing) predicts as the original, its predictor included.
    copy = pickle.loads(pickle.dumps(fitted))
    assert armcomp.evaluate(copy, data).to_dict() == armcomp.evaluate(fitted, data).to_dict()
    assert armcomp.evaluate(copy, data).rms_mm < armcomp.evaluate(model, data).rms_mm
    fitted.save(tmp_path / "py.toml")
    assert (tmp_path / "py.toml").read_bytes() == (tmp_path / "cli.toml").read_bytes()
    assert report.after.mean_mm <= report.before.mean_mm
    # Without a table, the predictor named in the call; the same bytes as with the table.
    bare = tmp_path / "bare.toml"
    model.save(bare)
    cli("learn", "--model", bare, "--data", tmp / "cli.csv", "--predictor", "ridge", "--out", tmp_path / "cli-named.toml")
    named, _ = armcomp.learn(model, data, predictor="ridge")
    named.save(tmp_path / "py-named.toml")
    assert (tmp_path / "py-named.toml").read_bytes() == (tmp_path / "cli-named.toml").read_bytes()
    assert (tmp_path / "cli-named.toml").read_bytes() == (tmp_path / "cli.toml").read_bytes()


def test_compensate_gives_the_command_line_joint_commands(simulated, tmp_path):
    tmp, data = simulated
    cli(
        "calibrate", "--robot", TRUTH, "--data", tmp / "cli.csv", "--noise-mm", 0.05, "--identify", GEOMETRY,
        "--out", tmp_path / "m.toml",
    )
    model = armcomp.Robot.load(tmp_path / "m.toml")
    targets = data.positions[:6] + np.array([0.01, -0.02, 0.005])
    (tmp_path / "targets.csv").write_text(
        "x[m],y[m],z[m]\n" + "".join(f"{float(x)!r},{float(y)!r},{float(z)!r}\n" for x, y, z in targets)
    )
    cli("compensate", "--model", tmp_path / "m.toml", "--targets", tmp_path / "targets.csv", "--out", tmp_path / "q.csv")
    header, rows = read_table(tmp_path / "q.csv")
    result = armcomp.compensate(model, targets)
    assert result.q.shape == (6, model.nq) and result.std is None and result.unconverged == []
    for k, name in enumerate(model.joint_names):
        np.testing.assert_allclose(result.q[:, k], to_si(header[k], [r[k] for r in rows]), rtol=1e-12, atol=1e-15)
    corrected = np.array([[float(v) for v in r[model.nq : model.nq + 3]] for r in rows]) * 1e-3
    np.testing.assert_allclose(result.corrected, corrected, rtol=1e-12, atol=1e-15)
    # The commands put the model's tool on the targets, as measured.
    check = armcomp.simulate(model, poses=result.q)
    np.testing.assert_allclose(check.positions, targets, atol=1e-6)


def test_plan_gives_the_command_line_poses(tmp_path):
    cli("plan", "--robot", NOMINAL, "--n", 12, "--method", "halton", "--seed", 5, "--out", tmp_path / "p.csv")
    header, rows = read_table(tmp_path / "p.csv")
    planned = armcomp.plan(armcomp.Robot.load(NOMINAL), n=12, method="halton", seed=5)
    assert planned.poses.shape == (12, 6)
    for k in range(6):
        np.testing.assert_allclose(planned.poses[:, k], to_si(header[k], [r[k] for r in rows]), rtol=1e-12)


def test_plan_picks_the_command_line_rows_and_next_poses(simulated, tmp_path):
    """Retrospective D-optimal selection from measured rows, and the next poses to measure
    after them: the same rows, report and poses as the command line."""
    tmp, data = simulated
    robot = armcomp.Robot.load(NOMINAL)
    args = ["--robot", NOMINAL, "--identify", GEOMETRY, "--noise-mm", 0.05]
    expected = cli_json("plan", *args, "--method", "d-optimal", "--n", 8, "--pool", tmp / "cli.csv", "--out", tmp_path / "rows.csv")
    picked = armcomp.plan(robot, n=8, method="d-optimal", pool=data, identify=GEOMETRY, noise_mm=0.05)
    assert picked.rows == expected["rows"] and len(set(picked.rows)) == 8
    assert picked.selection == expected
    # The chosen rows' joint values are those rows of the data.
    np.testing.assert_allclose(picked.poses, data.joints[picked.rows], rtol=1e-12)
    cli_json("plan", *args, "--next", 4, "--measured", tmp / "cli.csv", "--pool", 60, "--out", tmp_path / "next.csv")
    header, rows = read_table(tmp_path / "next.csv")
    proposed = armcomp.plan(robot, next=4, measured=data, pool=60, identify=GEOMETRY, noise_mm=0.05)
    assert proposed.poses.shape == (4, 6) and proposed.rows is None
    for k in range(6):
        np.testing.assert_allclose(proposed.poses[:, k], to_si(header[k], [r[k] for r in rows]), rtol=1e-12)


def test_diagnose_reports_as_the_command_line(simulated):
    tmp, data = simulated
    args = ["--folds", 3, "--max-steps", 1, "--predictor", "none", "--noise-mm", 0.05, "--seed", 2, "--identify", "base"]
    expected = cli_json("diagnose", "--robot", NOMINAL, "--data", tmp / "cli.csv", *args)
    calls = []
    model, report = armcomp.diagnose(
        armcomp.Robot.load(NOMINAL), data, folds=3, max_steps=1, predictor=None, noise_mm=0.05, seed=2, identify="base",
        progress=lambda stage, done, total: calls.append((stage, done, total)),
    )
    assert report.to_dict() == expected
    # Progress: every stage counts from 0 to its total once each, the model as given first (3 folds).
    assert calls[0] == ("model as given", 0, 3)
    stages = list(dict.fromkeys(stage for stage, _, _ in calls))
    assert stages[:2] == ["model as given", "effect 1"]
    for stage in stages:
        counts = [(done, total) for s, done, total in calls if s == stage]
        # Candidates are refitted in parallel: the counts may arrive out of order.
        total = counts[0][1]
        assert sorted(d for d, _ in counts) == list(range(total + 1)), stage
    assert len(report.steps) == len(expected["steps"]) == 1
    for step, raw in zip(report.steps, expected["steps"]):
        assert isinstance(step, armcomp.DiagnosisStep) and step.label == raw["label"]
        assert step.heldout_after.rms_mm == raw["heldout_after"]["rms_mm"]
    assert report.final_.heldout.n == len(data)


def test_fit_chooses_and_writes_what_the_command_line_does(simulated):
    """The model ladder from Python: the same ladder and the same model bytes as `armcomp fit`."""
    tmp, data = simulated
    expected = cli_json(
        "fit", "--robot", NOMINAL, "--data", tmp / "cli.csv", "--predictor", "none", "--folds", 3,
        "--out", tmp / "fit_cli.toml",
    )
    calls = []
    model, report = armcomp.fit(
        armcomp.Robot.load(NOMINAL), data, folds=3, predictor=None,
        progress=lambda stage, done, total: calls.append((stage, done, total)),
    )
    # Every fit reported once (in parallel, so in any order), up to the total.
    assert {stage for stage, _, _ in calls} == {"model choice"}
    total = calls[0][2]
    assert sorted(done for _, done, _ in calls) == list(range(1, total + 1))
    assert {t for _, _, t in calls} == {total} and total >= 3 * 3
    model.save(tmp / "fit_py.toml")
    assert (tmp / "fit_py.toml").read_bytes() == (tmp / "fit_cli.toml").read_bytes()
    # Everything but the run times.
    got = report.to_dict()
    for candidates in (got["candidates"], expected["candidates"]):
        for c in candidates:
            c.pop("seconds")
    assert got == expected
    assert [c.candidate.rung for c in report.candidates[::8]] == ["registration", "joint_offsets", "geometry"]
    assert report.candidates[0].label == "registration, evidence per parameter"
    assert report.chosen in [c.candidate for c in report.candidates] and report.expected_rms_mm > 0


def test_fit_and_diagnose_score_fixed_points_as_the_command_line(tmp_path):
    """The robot alone (a ball put into two sockets): the ladder and the diagnosis score a
    held-out contact by its distance from where the training contacts put its socket, from
    Python as from the command line."""
    robot_path = ROOT / "robots" / "panda-sockets.toml"
    data_path = tmp_path / "sockets.csv"
    cli(
        "simulate", "--robot", robot_path, "--fixed-point", "hole_0=500,0,300", "--fixed-point", "hole_1=500,50,300",
        "--n", 30, "--joint-noise-deg", 0.01, "--seed", 5, "--out", data_path,
    )
    robot = armcomp.Robot.load(robot_path)
    data = armcomp.Measurements.read(data_path, robot)
    expected = cli_json("fit", "--robot", robot_path, "--data", data_path, "--folds", 3, "--out", tmp_path / "fit.toml")
    _, report = armcomp.fit(robot, data, folds=3)
    got = report.to_dict()
    for candidates in (got["candidates"], expected["candidates"]):
        for c in candidates:
            c.pop("seconds")
    assert got == expected
    assert got["scored_by"] == "fixed-point distance" and "no 3-D error" in got["predictor_not_tried"]
    # Joint noise of 0.01° moves the ball by about 0.1 mm: what a held-out contact is off by.
    assert 0.02 < got["expected_rms_mm"] < 0.5
    args = ["--folds", 3, "--max-steps", 1, "--predictor", "none", "--seed", 2]
    expected = cli_json("diagnose", "--robot", robot_path, "--data", data_path, *args)
    _, report = armcomp.diagnose(robot, data, folds=3, max_steps=1, predictor=None, seed=2)
    assert report.to_dict() == expected
    assert expected["scored_by"] == "fixed-point distance"


def test_simulate_on_grounds_and_evaluate_registered_on_stationing_points(tmp_path):
    """The telescopic twin on two grounds: the same file as ``simulate --ground``, its two
    accelerometers' columns included, and ``register_on`` gives ``evaluate --register-on``'s
    report."""
    truth_path = ROOT / "robots" / "telescopic-arm-truth.toml"
    model_path = ROOT / "robots" / "telescopic-arm.toml"
    cli(
        "simulate", "--robot", truth_path, "--n", 60, "--noise-mm", 0.05, "--seed", 4,
        "--ground", "flat=0,0.004", "--ground", "soft=0.5,0.03", "--out", tmp_path / "cli.csv",
    )
    truth = armcomp.Robot.load(truth_path)
    data = armcomp.simulate(
        truth, n=60, noise_mm=0.05, seed=4, grounds={"flat": (0.0, 0.004), "soft": (0.5, 0.03)}
    )
    data.save(tmp_path / "py.csv", truth)
    assert (tmp_path / "py.csv").read_bytes() == (tmp_path / "cli.csv").read_bytes()
    header, rows = read_table(tmp_path / "py.csv")
    assert "station" in header and any("acc" in h or "sensor" in h or "[m/s^2]" in h for h in header)
    assert {r[header.index("station")] for r in rows} == {"flat", "soft"}
    with pytest.raises(armcomp.InputError):
        armcomp.simulate(truth, n=10, grounds={"flat": (-1.0, 0.0)})
    with pytest.raises(armcomp.InputError):
        armcomp.simulate(truth, n=10, grounds={"flat": 1.0}, stations=2)

    model = armcomp.Robot.load(model_path)
    # The file both read: the same inputs to the last bit.
    data = armcomp.Measurements.read(tmp_path / "cli.csv", model)
    report = armcomp.evaluate(model, data, register_on="0..6,30..36")
    expected = cli_json(
        "evaluate", "--model", model_path, "--data", tmp_path / "cli.csv", "--register-on", "0..6,30..36"
    )
    assert report.to_dict() == expected
    assert report.n == 48 and report.errors.shape == (48, 3)
    assert report.registered_stations == ["flat", "soft"]
    assert [s.station for s in report.per_station] == ["flat", "soft"]
    with pytest.raises(armcomp.InputError):
        armcomp.evaluate(model, data, register=True, register_on="0..6,30..36")
    # The soft ground's rows are evaluated, but none of them registers its frame.
    with pytest.raises(armcomp.InputError, match="station soft has none"):
        armcomp.evaluate(model, data, register_on="0..6")
