"""The command line's options in the package: the same reports as the command with the same
flags (outliers excluded, several stations, registration, folds by group, report pages), the
parameter covariance against the standard deviations, and measurements from DataFrames, file
objects, slices and row lists."""

import json
import warnings

import numpy as np
import pytest

import armcomp
from conftest import TALOS, TALOS_DATA, cli_json
from test_same_as_cli import GEOMETRY, TRUTH, simulated  # noqa: F401 (a fixture)


@pytest.fixture(scope="module")
def talos():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = armcomp.Robot.load(TALOS)
        return robot, armcomp.Measurements.read(TALOS_DATA, robot)


def quiet(f, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return f(*args, **kwargs)


def test_outliers_excluded_as_the_command_line_excludes_them(talos, tmp_path):
    robot, data = talos
    expected = cli_json(
        "calibrate", "--robot", TALOS, "--data", TALOS_DATA, "--identify", "base,markers,offsets",
        "--exclude-outliers", "--out", tmp_path / "cli.toml",
    )
    model, report = quiet(armcomp.calibrate, robot, data, identify="base,markers,offsets", exclude_outliers=True)
    _, first = quiet(armcomp.calibrate, robot, data, identify="base,markers,offsets")
    assert first.outlier_rows, "TALOS's data have gross errors to exclude"
    assert report.to_dict() == expected
    # The second fit is on the rows the first did not find gross.
    assert report.n_samples == len(data) - len(first.outlier_rows)
    model.save(tmp_path / "py.toml")
    assert (tmp_path / "py.toml").read_bytes() == (tmp_path / "cli.toml").read_bytes()


def test_covariance_holds_the_standard_deviations_and_the_correlations(talos):
    robot, data = talos
    _, report = quiet(armcomp.calibrate, robot, data, identify="base,markers,offsets")
    free = [p for p in report.params if not p.fixed]
    assert report.covariance_names == [p.name for p in free]
    cov = report.covariance
    np.testing.assert_array_equal(cov, cov.T)
    std = np.array([p.std for p in free])
    finite = np.isfinite(np.diag(cov))
    np.testing.assert_allclose(np.sqrt(np.diag(cov))[finite], std[finite], rtol=1e-12)
    corr = report.correlation
    np.testing.assert_allclose(np.diag(corr)[finite], 1.0)
    assert np.nanmax(np.abs(corr)) <= 1.0 + 1e-12
    np.testing.assert_allclose(corr[0, 1], cov[0, 1] / (std[0] * std[1]), rtol=1e-12)


def test_several_stations_as_several_data_files(simulated, tmp_path):
    tmp, data = simulated
    truth = armcomp.Robot.load(TRUTH)
    east, west = data[:20], data[20:]
    east.save(tmp_path / "east.csv", truth)
    west.save(tmp_path / "west.csv", truth)
    expected = cli_json(
        "calibrate", "--robot", TRUTH, "--data", tmp_path / "east.csv", "--data", tmp_path / "west.csv",
        "--noise-mm", 0.05, "--identify", GEOMETRY, "--out", tmp_path / "cli.toml",
    )
    pair = [armcomp.Measurements.read(tmp_path / f"{s}.csv", truth) for s in ("east", "west")]
    model, report = armcomp.calibrate(truth, pair, noise_mm=0.05, identify=GEOMETRY)
    assert report.to_dict() == expected
    assert sorted(model.stations) == ["east", "west"]
    # Each station's frame is its own: the model predicts each file's positions from it.
    for name, part in zip(("east", "west"), pair):
        predicted = model.predict_many(part.joints, station=name)
        assert np.sqrt(np.mean(np.sum((predicted - part.positions) ** 2, axis=1))) < 2e-4
    evaluated = armcomp.evaluate(model, pair, register=True)
    assert evaluated.to_dict() == cli_json(
        "evaluate", "--model", tmp_path / "cli.toml", "--data", tmp_path / "east.csv", "--data",
        tmp_path / "west.csv", "--register",
    )


def test_registering_keeps_the_models_fitted_predictor(simulated, tmp_path):
    tmp, data = simulated
    truth = armcomp.Robot.load(TRUTH)
    model, _ = armcomp.calibrate(truth, data, noise_mm=0.05, identify=GEOMETRY)
    learned, _ = quiet(armcomp.learn, model, data, predictor="ridge")
    learned.save(tmp_path / "learned.toml")
    expected = cli_json("evaluate", "--model", tmp_path / "learned.toml", "--data", tmp / "cli.csv", "--register")
    registered = armcomp.evaluate(learned, data, register=True)
    assert registered.to_dict() == expected
    # The predictor still counts: without it the errors are larger.
    assert registered.rms_mm < armcomp.evaluate(model, data, register=True).rms_mm


def test_report_pages_hold_what_the_command_line_writes(talos, tmp_path):
    robot, data = talos
    cli_json(
        "calibrate", "--robot", TALOS, "--data", TALOS_DATA, "--identify", "base,markers,offsets",
        "--out", tmp_path / "cli.toml", "--report", tmp_path / "cli-page",
    )
    model, report = quiet(
        armcomp.calibrate, robot, data, identify="base,markers,offsets", report=tmp_path / "py-page"
    )
    written = json.loads((tmp_path / "cli-page" / "report.json").read_text())
    assert report.page.to_dict() == written
    assert (tmp_path / "py-page" / "report.json").read_text() == (tmp_path / "cli-page" / "report.json").read_text()
    evaluated = armcomp.evaluate(model, data, report=tmp_path / "evaluate-page")
    np.testing.assert_allclose(
        [r["after_mm"] for r in evaluated.page.to_dict()["rows"]], evaluated.errors * 1e3, rtol=1e-12
    )
    with pytest.raises(OSError, match="the report replaces the folder"):
        armcomp.evaluate(model, data, report=TALOS_DATA.parent)


def test_groups_fold_learn_and_diagnose_by_whole_groups(simulated, tmp_path):
    _, data = simulated
    sessions = [f"s{i % 4}" for i in range(len(data))]
    truth = armcomp.Robot.load(TRUTH)
    model, _ = armcomp.calibrate(truth, data, noise_mm=0.05, identify=GEOMETRY)
    _, by_pose = quiet(armcomp.learn, model, data, predictor="ridge")
    _, by_group = quiet(armcomp.learn, model, data, predictor="ridge", groups=sessions)
    folding = by_group.to_dict()["cross_validation"]
    assert folding != by_pose.to_dict()["cross_validation"], folding
    assert "groups" in json.dumps(folding), folding
    with pytest.raises(armcomp.InputError, match="one label per data row"):
        armcomp.learn(model, data, predictor="ridge", groups=sessions[:5])
    _, diagnosis = armcomp.diagnose(
        truth, data, predictor=None, max_steps=1, groups=sessions, exhaustive=True, report=tmp_path / "diagnosis"
    )
    assert diagnosis.to_dict()["grouped_by"] == "groups"
    assert (tmp_path / "diagnosis" / "index.html").exists()


def test_group_by_reads_the_csv_column_as_the_command_line(simulated, tmp_path):
    tmp, data = simulated
    rows = (tmp / "cli.csv").read_text().splitlines()
    sessions = [f"s{i // 10}" for i in range(len(rows) - 1)]
    (tmp_path / "sessions.csv").write_text(
        "\n".join([rows[0] + ",session"] + [r + "," + s for r, s in zip(rows[1:], sessions)]) + "\n"
    )
    truth = armcomp.Robot.load(TRUTH)
    with_sessions = armcomp.Measurements.read(tmp_path / "sessions.csv", truth)
    args = ["calibrate", "--robot", TRUTH, "--data", tmp_path / "sessions.csv", "--noise-mm", 0.05,
            "--identify", GEOMETRY, "--prior", "auto", "--out", tmp_path / "cli.toml"]
    # A set-up column folds by itself; group_by names it; groups gives the labels.
    expected = cli_json(*args)
    assert expected["prior_choice"]["grouped_by"] == "session"
    for how in [{}, {"group_by": "session"}]:
        _, report = armcomp.calibrate(truth, with_sessions, noise_mm=0.05, identify=GEOMETRY, prior="auto", **how)
        assert report.to_dict() == expected
    _, by_labels = armcomp.calibrate(truth, data, noise_mm=0.05, identify=GEOMETRY, prior="auto", groups=sessions)
    assert by_labels.to_dict()["prior_choice"]["scores"] == expected["prior_choice"]["scores"]
    blocks = cli_json(*args, "--group-by", "x:2")
    _, report = armcomp.calibrate(
        truth, with_sessions, noise_mm=0.05, identify=GEOMETRY, prior="auto", group_by="x:2"
    )
    assert report.to_dict() == blocks
    assert blocks["prior_choice"]["grouped_by"] == "`x` in 2 blocks"
    with pytest.raises(armcomp.InputError, match="data row 0, column `session`: `s0` is not a number"):
        armcomp.calibrate(truth, with_sessions, prior="auto", group_by="session:2")
    with pytest.raises(armcomp.InputError, match="arrays"):
        armcomp.learn(truth, armcomp.simulate(truth, n=10), predictor="ridge", group_by="session")
    with pytest.raises(armcomp.InputError, match="prior=\"auto\""):
        armcomp.calibrate(truth, with_sessions, group_by="session")


def test_plugin_libraries_load_only_when_allowed(simulated):
    from conftest import ROOT

    library = ROOT / "target" / "debug" / "cable_sag"
    if not (ROOT / "target" / "debug" / "libcable_sag.so").exists():
        pytest.skip("the example plugin library is built by `cargo test` (tests/runtime_plugins.rs)")
    _, data = simulated
    truth = armcomp.Robot.load(TRUTH)
    with pytest.raises(armcomp.InputError, match="library"):
        armcomp.diagnose(truth, data, predictor=None, max_steps=0, library=library)
    assert "cable_sag" not in [p["type"] for p in armcomp.plugins()]
    armcomp.allow_plugins()
    try:
        armcomp.diagnose(truth, data, predictor=None, max_steps=0, library=library)
    finally:
        armcomp.allow_plugins(False)
    assert "cable_sag" in [p["type"] for p in armcomp.plugins()]


def test_measurements_from_dataframes_file_objects_slices_and_row_lists(talos):
    robot, data = talos
    with open(TALOS_DATA) as f:
        from_file = armcomp.Measurements.read(f, robot)
    np.testing.assert_array_equal(from_file.positions, data.positions)
    picked = armcomp.Measurements.read(TALOS_DATA, robot, rows=[3, 10, 11])
    assert picked.rows == [3, 10, 11]
    np.testing.assert_array_equal(picked.joints, data.joints[[3, 10, 11]])
    np.testing.assert_array_equal(data[[3, 10, 11]].positions, picked.positions)
    assert data[-2:].rows == [len(data) - 2, len(data) - 1]
    assert data[::20].rows == list(range(0, len(data), 20))
    with pytest.raises(IndexError):
        data[len(data)]
    pytest.importorskip("pandas")
    frame = data.to_dataframe(robot)
    assert len(frame) == len(data)
    again = armcomp.Measurements.read(frame, robot)
    np.testing.assert_allclose(again.joints, data.joints, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(again.positions, data.positions, rtol=1e-12, atol=1e-15)
