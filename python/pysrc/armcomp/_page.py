"""The data of a report page (``armcomp fit|calibrate|evaluate --report DIR``, its
``report.json``) as numpy arrays or pandas frames, and its plots drawn again with matplotlib.

Lengths are in mm, as the keys ending ``_mm`` say; joint values are in the robot file's units,
as ``joint_columns`` names them (``"q2 (deg)"``). pandas and matplotlib are optional.
"""

from __future__ import annotations

import copy
import json
import math
import os
from pathlib import Path
from typing import Any, Dict, List, Optional, Union

import numpy as np

_KEYS = (
    "command", "robot", "figures", "warnings", "held_out", "ladder", "parameters", "rows",
    "outlier_rows", "joint_columns", "plots",
)


def _table(columns: Dict[str, np.ndarray], frame: Optional[bool]) -> Any:
    """``columns`` as a pandas.DataFrame (``frame`` True, or None and pandas importable), else
    as they are."""
    if frame is False:
        return columns
    try:
        import pandas
    except ImportError:
        if frame:
            raise ImportError("a DataFrame needs pandas: pip install pandas") from None
        return columns
    return pandas.DataFrame(columns)


def _strings(values: List[str]) -> np.ndarray:
    return np.array(values, dtype=str)


def _numbers(values: List[Optional[float]], null: float = math.nan) -> np.ndarray:
    return np.array([null if v is None else v for v in values], dtype=float)


def _vectors(values: List[Optional[List[float]]]) -> np.ndarray:
    """n × 3, NaN where the JSON has null (a contact measures no position)."""
    return np.array([[math.nan] * 3 if v is None else v for v in values], dtype=float).reshape(-1, 3)


class ReportPage:
    """One report page's data: the figures, parameters, per-row residuals and plot points
    of ``report.json``. Tables come as a pandas.DataFrame when pandas is importable, else as
    a dict of numpy arrays (``frame=False`` forces the dict, ``frame=True`` pandas)."""

    def __init__(self, data: Dict[str, Any]) -> None:
        missing = [k for k in _KEYS if k not in data]
        if missing:
            raise KeyError(f"not a report page's JSON: no {', '.join(missing)}")
        n = len(data["joint_columns"])
        for r in data["rows"]:
            if len(r["joints"]) != n:
                raise ValueError(
                    f"row {r['row']} has {len(r['joints'])} joint values, joint_columns names {n}"
                )
        self._data = data

    @classmethod
    def from_dict(cls, data: Dict[str, Any]) -> ReportPage:
        """The page of a parsed ``report.json`` (copied: later changes to ``data`` are not seen)."""
        return cls(copy.deepcopy(data))

    @classmethod
    def read(cls, path: Union[str, "os.PathLike[str]"]) -> ReportPage:
        """The page in a ``--report`` folder, or in the ``report.json`` file ``path`` names."""
        path = Path(path)
        if path.is_dir():
            path = path / "report.json"
        with open(path, encoding="utf-8") as f:
            return cls(json.load(f))

    def to_dict(self) -> Dict[str, Any]:
        """The JSON of the page (a copy)."""
        return copy.deepcopy(self._data)

    @property
    def command(self) -> str:
        """The command that wrote the page: ``fit``, ``calibrate`` or ``evaluate``."""
        return self._data["command"]

    @property
    def robot(self) -> str:
        return self._data["robot"]

    @property
    def warnings(self) -> List[str]:
        return list(self._data["warnings"])

    @property
    def outlier_rows(self) -> List[int]:
        """The data rows (0-based, as ``--rows`` counts them) of the gross errors, largest first."""
        return list(self._data["outlier_rows"])

    @property
    def joint_columns(self) -> List[str]:
        """The joints of the rows, each with its unit: ``"name (unit)"``."""
        return list(self._data["joint_columns"])

    @property
    def figures(self) -> Dict[str, float]:
        """The headline figures by their key in the command's ``--json`` (``after.rms_mm``)."""
        return {f["json_key"]: f["value"] for f in self._data["figures"]}

    @property
    def held_out(self) -> List[Dict[str, Any]]:
        """Held-out RMS (mm) beside the one cross-validation expected (None when not known)."""
        return copy.deepcopy(self._data["held_out"])

    @property
    def ladder(self) -> Optional[Dict[str, Any]]:
        """``fit``'s candidates, choice and reason; None on other pages."""
        return copy.deepcopy(self._data["ladder"])

    @property
    def plot_names(self) -> List[str]:
        return [p["name"] for p in self._data["plots"]]

    def rows(self, frame: Optional[bool] = None) -> Any:
        """One row per sample: ``row`` (0-based data row), ``point``, ``station``, ``kind``, a
        column per joint (named as ``joint_columns``), the measured position and the residuals
        (measured minus modelled) as given and of the model, per axis of the measurement frame
        (``measured_x_mm`` .. ``before_x_mm`` .. ``after_x_mm`` ..) and as 3-D norms
        (``after_mm``, ``before_mm``), ``temperature`` (°C) and ``payload`` (kg). NaN where the
        page has none: no measured position for a contact, no ``before`` on ``evaluate``'s."""
        rows = self._data["rows"]
        columns: Dict[str, np.ndarray] = {
            "row": np.array([r["row"] for r in rows], dtype=int),
            "point": _strings([r["point"] for r in rows]),
            "station": _strings([r["station"] for r in rows]),
            "kind": _strings([r["kind"] for r in rows]),
        }
        joints = np.array([r["joints"] for r in rows], dtype=float).reshape(len(rows), -1)
        for k, name in enumerate(self._data["joint_columns"]):
            columns[name] = joints[:, k]
        kinds = ("measured", "before", "after")
        vectors = {key: _vectors([r[f"{key}_mm"] for r in rows]) for key in kinds}
        for key, v in vectors.items():
            for k, axis in enumerate("xyz"):
                columns[f"{key}_{axis}_mm"] = v[:, k]
        columns["after_mm"] = np.linalg.norm(vectors["after"], axis=1)
        columns["before_mm"] = np.linalg.norm(vectors["before"], axis=1)
        columns["temperature"] = _numbers([r["temperature"] for r in rows])
        columns["payload"] = _numbers([r["payload"] for r in rows])
        return _table(columns, frame)

    def parameters(self, frame: Optional[bool] = None) -> Any:
        """One row per identified parameter: ``name``, ``unit`` (of the three values),
        ``initial``, ``value``, ``std`` (inf when nothing in the data or the priors fixes it),
        ``fixed``, ``at_bound``, ``plausible``. Empty on ``evaluate``'s page."""
        params = self._data["parameters"]
        columns: Dict[str, np.ndarray] = {
            "name": _strings([p["name"] for p in params]),
            "unit": _strings([p["unit"] for p in params]),
        }
        for key in ("initial", "value"):
            columns[key] = _numbers([p[key] for p in params])
        columns["std"] = _numbers([p["std"] for p in params], null=math.inf)
        for key in ("fixed", "at_bound", "plausible"):
            columns[key] = np.array([p[key] for p in params], dtype=bool)
        return _table(columns, frame)

    def ladder_table(self, frame: Optional[bool] = None) -> Any:
        """``fit``'s candidates in the ladder's order: ``label``, ``rms_mm`` (pooled held-out
        RMS), ``spread_mm`` (the folds' standard deviation), ``chosen``, ``within_noise``,
        ``not_sound`` (why not, "" when sound)."""
        ladder = self._data["ladder"]
        if ladder is None:
            raise ValueError(f"{self.command}'s page has no ladder: only fit's has one")
        rows = ladder["candidates"]
        columns = {
            "label": _strings([c["label"] for c in rows]),
            "rms_mm": _numbers([c["rms_mm"] for c in rows]),
            "spread_mm": _numbers([c["spread_mm"] for c in rows]),
            "chosen": np.array([c["chosen"] for c in rows], dtype=bool),
            "within_noise": np.array([c["within_noise"] for c in rows], dtype=bool),
            "not_sound": _strings([c["not_sound"] or "" for c in rows]),
        }
        return _table(columns, frame)

    def _plot(self, name: str) -> Dict[str, Any]:
        for p in self._data["plots"]:
            if p["name"] == name:
                return p
        raise KeyError(f"no plot {name!r} on this page; it has {', '.join(self.plot_names)}")

    def series(self, name: str) -> Dict[str, Dict[str, Any]]:
        """Plot ``name``'s data by series name: arrays ``x`` and ``y``, ``colour`` (the value
        each point's colour shows) and ``error`` (each bar's error half-length) when the plot
        has them. A bar plot's ``x`` are indices into its series' ``categories`` list and its
        ``y`` the bars' lengths, horizontal bars included."""
        plot = self._plot(name)
        out = {}
        for s in plot["series"]:
            points = np.array(s["points"], dtype=float).reshape(-1, 2)
            data: Dict[str, Any] = {"x": points[:, 0], "y": points[:, 1]}
            if s["colour_values"]:
                data["colour"] = np.array(s["colour_values"], dtype=float)
            if s["error_bars"]:
                data["error"] = np.array(s["error_bars"], dtype=float)
            if plot["categories"]:
                data["categories"] = list(plot["categories"])
            out[s["name"]] = data
        return out

    def plot(self, name: Optional[str] = None, ax: Any = None) -> Any:
        """Draws plot ``name`` on ``ax`` (a new figure's without) and returns the Axes; with
        ``name`` None, every plot of the page in a grid of one new figure, returned."""
        try:
            import matplotlib.pyplot as plt
        except ImportError:
            raise ImportError("ReportPage.plot needs matplotlib: pip install matplotlib") from None
        if name is not None:
            if ax is None:
                _, ax = plt.subplots()
            _draw(self._plot(name), ax)
            return ax
        if ax is not None:
            raise ValueError("ax is for one plot: the grid of all plots makes its own figure")
        plots = self._data["plots"]
        if not plots:
            raise ValueError("the page has no plots")
        ncols = min(3, len(plots))
        nrows = math.ceil(len(plots) / ncols)
        fig, axes = plt.subplots(nrows, ncols, figsize=(5.5 * ncols, 4 * nrows), squeeze=False)
        for plot, a in zip(plots, axes.flat):
            _draw(plot, a)
        for a in axes.flat[len(plots):]:
            fig.delaxes(a)
        fig.tight_layout()
        return fig

    def __repr__(self) -> str:
        d = self._data
        return (
            f"ReportPage({d['command']}, robot {d['robot']!r}, {len(d['rows'])} rows, "
            f"{len(d['plots'])} plots)"
        )


def _draw(plot: Dict[str, Any], ax: Any) -> None:
    """One plot as the page draws it: bars over categories, or points."""
    series = plot["series"]
    categories = plot["categories"]
    # As on the page: vertical bars of several series stand side by side; horizontal ones
    # (one series per category) take the category's whole width.
    width = 0.8 if plot["horizontal"] else 0.8 / max(len(series), 1)
    for i, s in enumerate(series):
        points = np.array(s["points"], dtype=float).reshape(-1, 2)
        x, y = points[:, 0], points[:, 1]
        error = s["error_bars"] or None
        if not categories:
            if s["colour_values"]:
                # coolwarm: blue for the least, red for the most, as the page's titles say.
                drawn = ax.scatter(x, y, s=14, c=s["colour_values"], cmap="coolwarm", label=s["name"])
                ax.figure.colorbar(drawn, ax=ax)
            else:
                ax.scatter(x, y, s=14, label=s["name"])
        elif plot["horizontal"]:
            ax.barh(x, y, height=width, xerr=error, label=s["name"], alpha=0.7)
        else:
            at = x - 0.4 + width * (i + 0.5)
            ax.bar(at, y, width=width, yerr=error, label=s["name"], alpha=0.7)
    if categories:
        ticks = range(len(categories))
        if plot["horizontal"]:
            ax.set_yticks(ticks, categories)
        else:
            ax.set_xticks(ticks, categories)
    ax.set_title(plot["title"], fontsize="medium")
    ax.set_xlabel(plot["x_label"])
    ax.set_ylabel(plot["y_label"])
    if len(series) > 1:
        ax.legend(fontsize="small")
