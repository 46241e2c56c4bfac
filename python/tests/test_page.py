"""ReportPage reads the pages `armcomp calibrate|evaluate --report` write: its tables and plot
data are report.json's numbers, its figures the commands' --json, its residuals the
--residuals CSV's; its plots draw what the page's plots hold."""

import csv
import json
import math
import sys

import numpy as np
import pytest

from armcomp._page import ReportPage
from conftest import TALOS, TALOS_DATA, cli_json


@pytest.fixture(scope="module")
def pages(tmp_path_factory):
    """Calibrate and evaluate's pages of TALOS, with their --json and the residuals CSV."""
    tmp = tmp_path_factory.mktemp("pages")
    calibrated = cli_json(
        "calibrate", "--robot", TALOS, "--data", TALOS_DATA, "--identify", "base,markers,offsets",
        "--out", tmp / "model.toml", "--report", tmp / "calibrate",
    )
    evaluated = cli_json(
        "evaluate", "--model", tmp / "model.toml", "--data", TALOS_DATA,
        "--residuals", tmp / "residuals.csv", "--report", tmp / "evaluate",
    )
    return {
        "dir": tmp,
        "calibrate": (ReportPage.read(tmp / "calibrate"), calibrated),
        "evaluate": (ReportPage.read(tmp / "evaluate"), evaluated),
        "json": {c: json.loads((tmp / c / "report.json").read_text()) for c in ("calibrate", "evaluate")},
    }


@pytest.fixture
def pyplot():
    """matplotlib's pyplot drawing off screen; the figures closed after the test."""
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    yield plt
    plt.close("all")


def test_read_a_folder_or_its_json(pages):
    raw = pages["json"]["calibrate"]
    page = ReportPage.read(pages["dir"] / "calibrate" / "report.json")
    assert page.to_dict() == raw == pages["calibrate"][0].to_dict()
    assert (page.command, page.robot) == ("calibrate", raw["robot"])
    assert page.joint_columns == raw["joint_columns"] and page.outlier_rows == raw["outlier_rows"]
    assert page.warnings == raw["warnings"] and page.held_out == raw["held_out"]
    assert page.ladder is None and page.plot_names == [p["name"] for p in raw["plots"]]
    n, plots = len(raw["rows"]), len(raw["plots"])
    assert repr(page) == f"ReportPage(calibrate, robot {raw['robot']!r}, {n} rows, {plots} plots)"
    # The page is its own copy: neither the dict it was made from nor to_dict's changes it.
    mine = json.loads(json.dumps(raw))
    copy = ReportPage.from_dict(mine)
    mine["rows"][0]["after_mm"][0] = 1e9
    copy.to_dict()["rows"][0]["after_mm"][0] = 1e9
    assert copy.rows(frame=False)["after_x_mm"][0] != 1e9


def test_a_dict_that_is_no_page_is_refused(pages):
    raw = pages["json"]["evaluate"]
    with pytest.raises(KeyError, match="no rows, plots"):
        ReportPage.from_dict({k: v for k, v in raw.items() if k not in ("rows", "plots")})
    raw = json.loads(json.dumps(raw))
    raw["rows"][3]["joints"].pop()
    with pytest.raises(ValueError, match=f"row 3 has {len(raw['joint_columns']) - 1} joint values"):
        ReportPage.from_dict(raw)


@pytest.mark.parametrize("command", ["calibrate", "evaluate"])
def test_figures_are_the_commands_json(pages, command):
    page, out = pages[command]
    assert page.figures
    for key, value in page.figures.items():
        expected = out
        for part in key.split("."):
            expected = expected[part]
        assert value == pytest.approx(expected, rel=1e-12), key


@pytest.mark.parametrize("command", ["calibrate", "evaluate"])
def test_rows_are_the_json_rows(pages, command):
    page, raw = pages[command][0], pages["json"][command]
    rows = page.rows(frame=False)
    n = len(raw["rows"])
    assert list(rows) == (
        ["row", "point", "station", "kind", *raw["joint_columns"]]
        + [f"{w}_{a}_mm" for w in ("measured", "before", "after") for a in "xyz"]
        + ["after_mm", "before_mm", "temperature", "payload"]
    )
    assert all(len(v) == n for v in rows.values())
    for i, r in enumerate(raw["rows"]):
        assert (rows["row"][i], rows["point"][i], rows["station"][i], rows["kind"][i]) == (
            r["row"], r["point"], r["station"], r["kind"],
        )
        assert [rows[c][i] for c in raw["joint_columns"]] == r["joints"]
        for what in ("measured", "before", "after"):
            got = [rows[f"{what}_{a}_mm"][i] for a in "xyz"]
            if r[f"{what}_mm"] is None:
                assert np.isnan(got).all()
            else:
                assert got == r[f"{what}_mm"]
        assert rows["after_mm"][i] == pytest.approx(math.sqrt(sum(v * v for v in r["after_mm"])), rel=1e-14)
        before = r["before_mm"]
        assert (math.isnan(rows["before_mm"][i]) if before is None
                else rows["before_mm"][i] == pytest.approx(math.sqrt(sum(v * v for v in before)), rel=1e-14))
        for key in ("temperature", "payload"):  # the TALOS data have neither
            assert r[key] is None and math.isnan(rows[key][i])
    # Only a page that fitted a model has the robot as given.
    assert np.isnan(rows["before_mm"]).all() == (command == "evaluate")


def test_residuals_are_evaluates_csv(pages):
    page = pages["evaluate"][0]
    rows = page.rows(frame=False)
    with open(pages["dir"] / "residuals.csv", newline="") as f:
        table = list(csv.DictReader(f))
    assert len(table) == len(rows["row"])
    scale = {"m": 1e3, "mm": 1.0}
    pairs = [("x_err", "after_x_mm"), ("y_err", "after_y_mm"), ("z_err", "after_z_mm"), ("err", "after_mm")]
    for column, ours in pairs:
        header = next(h for h in table[0] if h.startswith(column + "["))
        mm = np.array([float(t[header]) for t in table]) * scale[header.split("[")[1].rstrip("]")]
        np.testing.assert_allclose(rows[ours], mm, rtol=1e-12, atol=1e-12)
    # The CSV writes "name[unit]", the page "name (unit)": the same joint values.
    for column in page.joint_columns:
        name, unit = column.rstrip(")").split(" (")
        np.testing.assert_array_equal(rows[column], [float(t[f"{name}[{unit}]"]) for t in table])
    # The CSV counts samples from 1; with every data row, the page's rows are them from 0.
    assert [int(t["sample"]) - 1 for t in table] == rows["row"].tolist()


def test_evaluate_scores_the_calibrated_model_on_the_same_rows(pages):
    calibrated, evaluated = pages["calibrate"][0].rows(frame=False), pages["evaluate"][0].rows(frame=False)
    np.testing.assert_allclose(evaluated["after_mm"], calibrated["after_mm"], rtol=1e-9)
    rms = math.sqrt(np.mean(evaluated["after_mm"] ** 2))
    (held_out,) = pages["evaluate"][0].held_out
    assert held_out["measured_rms_mm"] == pytest.approx(rms, rel=1e-12)


def test_parameters_are_the_calibration_in_mm_and_degrees(pages):
    page, out = pages["calibrate"]
    params = page.parameters(frame=False)
    assert params["name"].tolist() == [p["name"] for p in out["params"]]
    # --json is SI; the page shows lengths in mm and angles in degrees.
    to_page = {("rad", "deg"): math.degrees(1.0), ("m", "mm"): 1e3}
    for i, p in enumerate(out["params"]):
        factor = to_page[(p["unit"], params["unit"][i])]
        for key in ("initial", "value", "std"):
            assert params[key][i] == pytest.approx(p[key] * factor, rel=1e-9, abs=1e-12), (p["name"], key)
        for key in ("fixed", "at_bound", "plausible"):
            assert params[key][i] == p[key]
    empty = pages["evaluate"][0].parameters(frame=False)
    assert list(empty) == list(params) and all(len(v) == 0 for v in empty.values())


def test_frames_are_the_dicts(pages):
    pytest.importorskip("pandas")
    page = pages["calibrate"][0]
    for table in (page.rows, page.parameters):
        frame, columns = table(), table(frame=False)
        assert list(frame.columns) == list(columns)
        for name, values in columns.items():
            np.testing.assert_array_equal(frame[name].to_numpy(), values)


def test_ladders(pages):
    page = pages["calibrate"][0]
    with pytest.raises(ValueError, match="calibrate's page has no ladder"):
        page.ladder_table()
    raw = page.to_dict()
    candidates = [
        {"label": "registration", "rms_mm": 5.1, "spread_mm": 1.1, "chosen": False, "within_noise": False,
         "not_sound": None},
        {"label": "geometry", "rms_mm": 0.7, "spread_mm": 0.1, "chosen": True, "within_noise": True,
         "not_sound": "a parameter at its bound"},
    ]
    raw["ladder"] = {"candidates": candidates, "chosen": "geometry", "reason": "best", "expected_rms_mm": 0.7,
                     "folds_by": "pose"}
    table = ReportPage.from_dict(raw).ladder_table(frame=False)
    assert table["label"].tolist() == ["registration", "geometry"]
    assert table["rms_mm"].tolist() == [5.1, 0.7] and table["spread_mm"].tolist() == [1.1, 0.1]
    assert table["chosen"].tolist() == [False, True] and table["within_noise"].tolist() == [False, True]
    assert table["not_sound"].tolist() == ["", "a parameter at its bound"]


def test_a_parameter_nothing_determines_has_an_infinite_std(pages):
    raw = pages["calibrate"][0].to_dict()
    raw["parameters"][1]["std"] = None
    std = ReportPage.from_dict(raw).parameters(frame=False)["std"]
    assert std[1] == math.inf and std[0] == raw["parameters"][0]["std"]


def test_series_are_the_plots_points(pages):
    page, raw = pages["calibrate"][0], pages["json"]["calibrate"]
    for plot in raw["plots"]:
        series = page.series(plot["name"])
        assert list(series) == [s["name"] for s in plot["series"]]
        for s in plot["series"]:
            got = series[s["name"]]
            np.testing.assert_array_equal(np.column_stack([got["x"], got["y"]]), np.array(s["points"]))
            assert ("colour" in got) == bool(s["colour_values"]) and ("error" in got) == bool(s["error_bars"])
            assert got.get("categories", []) == plot["categories"]
    # What they show, from the rows: the drift plot is every row's 3-D residual, the map the
    # measured positions coloured by it, the bars each axis' RMS.
    rows = page.rows(frame=False)
    order = page.series("order")
    np.testing.assert_array_equal(order["fitted"]["x"], rows["row"])
    np.testing.assert_allclose(order["fitted"]["y"], rows["after_mm"], rtol=1e-14)
    np.testing.assert_allclose(order["as given"]["y"], rows["before_mm"], rtol=1e-14)
    (measured,) = page.series("map_xy").values()
    np.testing.assert_array_equal(measured["x"], rows["measured_x_mm"])
    np.testing.assert_array_equal(measured["y"], rows["measured_y_mm"])
    np.testing.assert_allclose(measured["colour"], rows["after_mm"], rtol=1e-14)
    axes = page.series("axes")["fitted"]
    assert axes["categories"] == ["x", "y", "z", "3-D"] and axes["x"].tolist() == [0, 1, 2, 3]
    by_hand = [math.sqrt(np.mean(rows[c] ** 2)) for c in ("after_x_mm", "after_y_mm", "after_z_mm", "after_mm")]
    np.testing.assert_allclose(axes["y"], by_hand, rtol=1e-12)


def test_unknown_plots_name_the_plots(pages):
    page = pages["evaluate"][0]
    with pytest.raises(KeyError, match="no plot 'ladder' on this page; it has axes, map_xy"):
        page.series("ladder")
    with pytest.raises(KeyError, match="it has axes"):
        page.plot("ladder")


def test_plot_bars_and_points(pages, pyplot):
    page, raw = pages["calibrate"][0], pages["json"]["calibrate"]
    plots = {p["name"]: p for p in raw["plots"]}
    ax = page.plot("axes")
    (fitted,) = plots["axes"]["series"]
    assert [b.get_height() for b in ax.patches] == [y for _, y in fitted["points"]]
    assert [t.get_text() for t in ax.get_xticklabels()] == plots["axes"]["categories"]
    assert (ax.get_title(), ax.get_xlabel(), ax.get_ylabel()) == (
        plots["axes"]["title"], plots["axes"]["x_label"], plots["axes"]["y_label"],
    )
    assert ax.get_legend() is None, "one series, no legend"

    _, given = pyplot.subplots()
    assert page.plot("order", ax=given) is given
    assert len(given.collections) == 2 and len(given.patches) == 0
    for drawn, s in zip(given.collections, plots["order"]["series"]):
        np.testing.assert_array_equal(drawn.get_offsets(), s["points"])
    assert [t.get_text() for t in given.get_legend().get_texts()] == ["as given", "fitted"]

    ax = page.plot("map_xy")
    (drawn,) = ax.collections
    np.testing.assert_array_equal(drawn.get_array(), plots["map_xy"]["series"][0]["colour_values"])
    assert len(ax.figure.axes) == 2, "the plot and its colour bar"


def test_vertical_bars_of_two_series_stand_side_by_side(pages, pyplot):
    raw = pages["calibrate"][0].to_dict()
    series = [
        {"name": "as given", "points": [[0, 4.0], [1, 6.0]], "colour_values": [], "error_bars": []},
        {"name": "fitted", "points": [[0, 1.0], [1, 2.0]], "colour_values": [], "error_bars": []},
    ]
    raw["plots"] = [{"name": "groups", "title": "per station", "x_label": "", "y_label": "RMS (mm)",
                     "categories": ["station a", "station b"], "horizontal": False, "series": series}]
    ax = ReportPage.from_dict(raw).plot("groups")
    # Each category 0.8 wide, shared by the two series: bars 0.4 wide centred 0.2 either side.
    bars = [(round(b.get_x() + b.get_width() / 2, 12), b.get_width(), b.get_height()) for b in ax.patches]
    assert bars == [(-0.2, 0.4, 4.0), (0.8, 0.4, 6.0), (0.2, 0.4, 1.0), (1.2, 0.4, 2.0)]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["station a", "station b"]
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["as given", "fitted"]


def test_horizontal_bars_with_error_bars(pages, pyplot):
    raw = pages["calibrate"][0].to_dict()
    series = [
        {"name": "not chosen", "points": [[0, 5.0], [2, 3.0]], "colour_values": [], "error_bars": [1.0, 0.5]},
        {"name": "chosen", "points": [[1, 2.0]], "colour_values": [], "error_bars": [0.2]},
    ]
    raw["plots"] = [{"name": "ladder", "title": "candidates", "x_label": "held-out RMS (mm)", "y_label": "",
                     "categories": ["a", "b", "c"], "horizontal": True, "series": series}]
    ax = ReportPage.from_dict(raw).plot("ladder")
    # One bar per candidate, along x, centred on its category; one error bar set per series.
    bars = sorted((b.get_y() + b.get_height() / 2, b.get_width()) for b in ax.patches)
    assert bars == [(0, 5.0), (1, 2.0), (2, 3.0)]
    assert len(ax.collections) == 2
    segments = ax.collections[0].get_segments()
    np.testing.assert_allclose([s[:, 0] for s in segments], [[4.0, 6.0], [2.5, 3.5]])
    assert [t.get_text() for t in ax.get_yticklabels()] == ["a", "b", "c"]
    assert ax.get_xlabel() == "held-out RMS (mm)" and len(ax.get_legend().get_texts()) == 2


def test_every_plot_in_one_figure(pages, pyplot):
    page, raw = pages["evaluate"][0], pages["json"]["evaluate"]
    fig = page.plot()
    coloured = sum(bool(s["colour_values"]) for p in raw["plots"] for s in p["series"])
    assert len(fig.axes) == len(raw["plots"]) + coloured
    titles = [a.get_title() for a in fig.axes if a.get_title()]
    assert titles == [p["title"] for p in raw["plots"]]
    with pytest.raises(ValueError, match="ax is for one plot"):
        page.plot(ax=fig.axes[0])


def test_without_pandas_or_matplotlib(pages, monkeypatch):
    page = pages["calibrate"][0]
    monkeypatch.setitem(sys.modules, "pandas", None)
    assert isinstance(page.rows(), dict) and isinstance(page.parameters(), dict)
    with pytest.raises(ImportError, match="pip install pandas"):
        page.rows(frame=True)
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    monkeypatch.setitem(sys.modules, "matplotlib.pyplot", None)
    with pytest.raises(ImportError, match="pip install matplotlib"):
        page.plot("axes")
