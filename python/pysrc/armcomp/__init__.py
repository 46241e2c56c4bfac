"""armcomp: calibration and compensation of long, heavy, flexible robot arms.

The same engine as the ``armcomp`` command, with numpy arrays in and out. Values are SI
(m, rad) unless a name says otherwise (``noise_mm``, ``*_mm`` report fields).

>>> import armcomp
>>> robot = armcomp.Robot.load("robots/talos-left-arm.toml")
>>> data = armcomp.Measurements.read("data/talos-left-arm/measurements.csv")
>>> model, report = armcomp.calibrate(robot, data, identify=["base", "markers"])

Long calls release the GIL and stop on Ctrl-C (``KeyboardInterrupt``).
"""

from __future__ import annotations

import json
import os
import warnings
from typing import Any, Callable, Dict, Iterable, Optional, Sequence, Tuple, Union

import numpy as np

from . import _armcomp as _native
from ._armcomp import Measurements, Robot
from ._armcomp import __version__
from ._convert import from_json
from ._errors import ArmcompError, CalibrationWarning, InputError, NotConverged
from ._joint_map import JointMap
from ._page import ReportPage
from ._reports import (
    AxisErrors,
    CalibrationReport,
    Compensation,
    Deficiency,
    DiagnosisReport,
    DiagnosisStep,
    ErrorStats,
    EvaluationReport,
    Evidence,
    FitReport,
    GroupScale,
    FinalModel,
    Identifiability,
    IdentifiedValue,
    LearnableResidual,
    LearnReport,
    Parameter,
    Plan,
    PriorChoice,
    PriorScaleScore,
    RankedCandidate,
    StationErrors,
    CandidateScore,
    Candidate,
)

__all__ = [
    "__version__",
    "ArmcompError",
    "AxisErrors",
    "CalibrationReport",
    "CalibrationWarning",
    "Compensation",
    "Deficiency",
    "DiagnosisReport",
    "DiagnosisStep",
    "ErrorStats",
    "EvaluationReport",
    "Evidence",
    "FitReport",
    "GroupScale",
    "FinalModel",
    "Identifiability",
    "IdentifiedValue",
    "InputError",
    "JointMap",
    "LearnReport",
    "LearnableResidual",
    "Measurements",
    "NotConverged",
    "Parameter",
    "Plan",
    "PriorChoice",
    "PriorScaleScore",
    "RankedCandidate",
    "ReportPage",
    "StationErrors",
    "CandidateScore",
    "Candidate",
    "Robot",
    "calibrate",
    "compensate",
    "diagnose",
    "evaluate",
    "fit",
    "learn",
    "plan",
    "simulate",
    "validate",
    "check_pose",
    "schema",
    "plugins",
    "allow_plugins",
]


def _labels(groups: Optional[Iterable[Any]]) -> Optional[list]:
    """One group label per data row as text (a pandas column's values too)."""
    return None if groups is None else [str(g) for g in groups]


def _names(value: Union[None, str, Iterable[str]]) -> Optional[list]:
    """``"base,markers"`` or ``["base", "markers"]`` as a list."""
    if value is None:
        return None
    if isinstance(value, str):
        return [v.strip() for v in value.split(",")]
    return list(value)


def calibrate(
    robot: Robot,
    data: Measurements,
    identify: Union[None, str, Sequence[str]] = None,
    noise_mm: Optional[float] = None,
    prior: Union[None, float, str] = 1.0,
    max_iterations: int = 100,
    restarts: int = 2,
    seed: int = 0,
    progress: Optional[Callable[[str, int, int], None]] = None,
    loss: str = "squared",
    noise_deg: Optional[float] = None,
    exclude_outliers: bool = False,
    report: Union[None, str, "os.PathLike[str]"] = None,
    groups: Optional[Sequence[str]] = None,
    group_by: Optional[str] = None,
) -> Tuple[Robot, CalibrationReport]:
    """Identifies a model of ``robot`` from ``data`` (Levenberg–Marquardt with priors), as
    ``armcomp calibrate`` does.

    ``identify``: what to identify (base, markers, geometry, offsets, errors, all, an error
    model's type or a parameter pattern such as ``"j2.*"``); default base, markers, geometry
    and errors. ``noise_mm``: the tracker noise per axis (mm); None estimates it from the
    data with the fit (``report.evidence``). ``prior``: a factor on the robot file's prior
    standard deviations, ``"evidence"`` (one factor per group of parameters, chosen by the
    evidence of the data), ``"auto"`` (5-fold cross-validation) or None (no priors). ``restarts``: fits from perturbed starts (seeded by ``seed``) when the fit ends
    more than 1.5 times above the noise; the lowest cost is kept. ``progress("prior scale",
    done, total)`` is called after every fit of ``prior="auto"``'s cross-validation.
    ``loss``: ``"squared"`` (least squares) or ``"huber"`` (squared up to 3 robust noises per
    axis, linear beyond, so that a few gross errors pull the fit little; ``report.downweighted``
    counts the rows weighed less). ``noise_deg``: the orientation noise of poses and plane
    contacts' tilts (degrees), declared with ``noise_mm``. ``exclude_outliers``: fit again
    without the rows of gross errors (``report.outlier_rows``), as ``--exclude-outliers``.
    ``data`` may be a list of ``Measurements``, one station each (named by its file's name), as
    several ``--data`` files are. ``report``: a folder for the report page (``--report``);
    ``report.page`` then holds its data (``ReportPage``). ``groups`` (a label per data row) or
    ``group_by`` (a CSV column; ``"COLUMN:N"`` cuts a numeric one into N blocks) fold
    ``prior="auto"``'s cross-validation by whole groups, as ``--group-by``; by default a set-up
    column of the CSV (``session``, ...).

    Returns ``(model, report)``; ``model.save(path)`` writes the model file. The report's
    warnings, and a fit far above the declared noise, are issued as ``CalibrationWarning``.
    Raises ``NotConverged`` (with ``.model`` and ``.report``) when the fit did not converge.
    """
    model, text, far, covariance, page = _native.calibrate(
        robot,
        data,
        identify=_names(identify),
        noise_mm=noise_mm,
        prior="none" if prior is None else prior,
        max_iterations=max_iterations,
        restarts=restarts,
        seed=seed,
        progress=progress,
        loss=loss,
        noise_deg=noise_deg,
        exclude_outliers=exclude_outliers,
        report=report,
        groups=_labels(groups),
        group_by=group_by,
    )
    report = from_json(CalibrationReport, text)
    object.__setattr__(report, "far_above_noise", far)
    _attach(report, covariance, page)
    for w in report.warnings:
        warnings.warn(w, CalibrationWarning, stacklevel=2)
    if far:
        warnings.warn(
            f"the fit ends far above the declared noise ({report.rms_over_noise:.1f} times what "
            f"{noise_mm} mm per axis gives); check the data and the model",
            CalibrationWarning,
            stacklevel=2,
        )
    if not report.converged:
        raise NotConverged(
            f"calibration did not converge ({report.stop_reason}); .model is the best found",
            model=model,
            report=report,
        )
    return model, report


def _attach(report: CalibrationReport, covariance, page: Optional[str]) -> None:
    """The covariance and the page the native call returned beside the JSON."""
    names, matrix = covariance
    object.__setattr__(report, "covariance_names", list(names))
    object.__setattr__(report, "covariance", matrix)
    object.__setattr__(report, "page", _page_of(page))


def _page_of(text: Optional[str]) -> Optional[ReportPage]:
    return None if text is None else ReportPage.from_dict(json.loads(text))


def evaluate(
    model: Robot,
    data: Union[Measurements, Sequence[Measurements]],
    register: bool = False,
    report: Union[None, str, "os.PathLike[str]"] = None,
    register_on: Union[None, str, Sequence[int]] = None,
) -> EvaluationReport:
    """Position errors of ``model`` (with its fitted predictor) on ``data``, as
    ``armcomp evaluate`` reports them. ``register``: register every station's measurement
    frame on these data first (``--register``); a station the model does not know always is.
    ``register_on``: register the stations on these rows only (each station's stationing
    points: a selection such as ``"0..40"`` or row indices) and evaluate on the others
    (``--register-on``). ``data`` may be a list of ``Measurements``, one station each.
    ``report``: a folder for the report page; ``report.page`` then holds its data."""
    text, errors, page = _native.evaluate(
        model, data, register=register, register_on=register_on, report=report
    )
    result = from_json(EvaluationReport, text)
    object.__setattr__(result, "errors", errors)
    object.__setattr__(result, "page", _page_of(page))
    return result


def simulate(
    truth: Robot,
    poses: Optional[np.ndarray] = None,
    n: int = 100,
    sampler: str = "sobol",
    noise_mm: float = 0.0,
    seed: int = 0,
    stations: Optional[int] = None,
    tilt_deg: float = 0.0,
    tilt_per: str = "row",
    grounds: Optional[Dict[str, Union[float, Tuple[float, float]]]] = None,
) -> Measurements:
    """Measurements of ``truth`` at ``poses`` (n × joints, SI) or at ``n`` poses drawn by
    ``sampler`` (sobol, halton, random, grid), with ``noise_mm`` of noise per axis, as
    ``armcomp simulate`` makes them; the same seed gives the same values. ``stations``: measured
    from that many stations (``--stations``); ``tilt_deg``, ``tilt_per`` ("row" or "station"):
    the base's tilt (``--tilt-deg``, ``--tilt-per``); ``grounds``: ground name → tilt in degrees
    or (tilt, rocking) in degrees, one station each (``--ground``). The truth's sensors are
    read on every row; ``truth`` itself is left as it was."""
    return _native.simulate(
        truth,
        poses=poses,
        n=n,
        sampler=sampler,
        noise_mm=noise_mm,
        seed=seed,
        stations=stations,
        tilt_deg=tilt_deg,
        tilt_per=tilt_per,
        grounds=grounds,
    )


def diagnose(
    robot: Robot,
    data: Measurements,
    seed: int = 0,
    folds: int = 3,
    max_steps: int = 5,
    min_reduction_percent: float = 5.0,
    noise_mm: Optional[float] = None,
    identify: Union[None, str, Sequence[str]] = None,
    predictor: Optional[str] = "gp",
    progress: Optional[Callable[[str, int, int], None]] = None,
    keep_outliers: bool = False,
    groups: Optional[Sequence[str]] = None,
    exhaustive: bool = False,
    report: Union[None, str, "os.PathLike[str]"] = None,
    group_by: Optional[str] = None,
    library: Union[None, str, "os.PathLike[str]", Sequence[Union[str, "os.PathLike[str]"]]] = None,
) -> Tuple[Robot, DiagnosisReport]:
    """Finds the effects ``robot`` misses, one by one, scored on held-out poses, as
    ``armcomp diagnose`` does. Returns the improved model and the report, whose ``steps``
    are the accepted effects. ``predictor`` (gp, ridge or None) scores what remains
    learnable; without ``noise_mm`` the noise is the model's fit record's (``fit`` writes one),
    else estimated for the model as given, and candidates are judged against the held-out
    error above its floor. ``progress(stage, done, total)`` is called after every fold calibration
    (stage: "model as given", "effect N", "learnable residual"). When the final model leaves
    samples far beyond the noise (a broken line of sight), the search is made again without
    them unless ``keep_outliers``; ``report.gross_errors`` lists them either way, ``report.drift`` a
    residual drifting with the row order. ``groups``: a label per data row, or ``group_by`` a
    column of the CSV (``"COLUMN:N"``: N blocks of a numeric one), so that folds hold out whole
    groups (``--group-by``; by default a set-up column of the CSV); ``exhaustive``: refit every
    candidate on the folds (``--exhaustive``); ``report``: a folder for the diagnosis page
    (``--report``); ``library``: run-time plugin libraries whose error models join the
    candidates (``--library``), loaded only after ``armcomp.allow_plugins()``."""
    model, text = _native.diagnose(
        robot,
        data,
        seed=seed,
        folds=folds,
        max_steps=max_steps,
        min_reduction_percent=min_reduction_percent,
        noise_mm=noise_mm,
        identify=_names(identify),
        predictor=predictor,
        progress=progress,
        keep_outliers=keep_outliers,
        groups=_labels(groups),
        exhaustive=exhaustive,
        report=report,
        group_by=group_by,
        library=None if library is None else [library] if isinstance(library, (str, os.PathLike)) else list(library),
    )
    return model, from_json(DiagnosisReport, text)


def fit(
    robot: Robot,
    data: Measurements,
    noise_mm: Optional[float] = None,
    folds: int = 5,
    seed: int = 0,
    groups: Optional[Sequence[str]] = None,
    predictor: Optional[str] = "gp",
    progress: Optional[Callable[[str, int, int], None]] = None,
    noise_deg: Optional[float] = None,
    repeats: Optional[int] = None,
    report: Union[None, str, "os.PathLike[str]"] = None,
    group_by: Optional[str] = None,
) -> Tuple[Robot, FitReport]:
    """Chooses the model from ``data`` alone, as ``armcomp fit`` does: registration, joint
    offsets, geometry and the robot file's error models, each under several prior schemes
    (the evidence, the file's priors at five scales, none) and each with and without
    ``predictor`` (None for none), scored by cross-validation over ``folds`` folds drawn
    ``repeats`` times (None: 3, or 1 from 2,000 rows; whole groups held out when ``groups`` gives a label per data row
    or ``group_by`` names a CSV column, ``"COLUMN:N"`` for N blocks of a numeric one; by default a set-up column of the CSV);
    returns the chosen model fitted on all of ``data`` and the ladder.
    ``progress("model choice", done, total)`` is called after every fit. ``noise_mm`` and
    ``noise_deg`` (orientation noise of poses and plane contacts' tilts, degrees) declare the
    noises instead of estimating them, as ``armcomp fit --noise-mm --noise-deg`` do.
    ``report``: a folder for the report page (``--report``); ``report.page`` then holds its
    data, and ``report.calibration.covariance`` the chosen fit's parameter covariance."""
    model, text, covariance, page = _native.fit(
        robot,
        data,
        noise_mm=noise_mm,
        noise_deg=noise_deg,
        folds=folds,
        repeats=repeats,
        seed=seed,
        groups=_labels(groups),
        predictor=predictor,
        progress=progress,
        report=report,
        group_by=group_by,
    )
    result = from_json(FitReport, text)
    _attach(result.calibration, covariance, None)
    object.__setattr__(result, "page", _page_of(page))
    return model, result


def learn(
    model: Robot,
    data: Measurements,
    predictor: Optional[str] = None,
    progress: Optional[Callable[[str, int, int], None]] = None,
    groups: Optional[Sequence[str]] = None,
    group_by: Optional[str] = None,
) -> Tuple[Robot, LearnReport]:
    """Fits ``predictor`` (gp, mlp, ssa_bp, ridge or knn with default settings), or else the
    residual predictor ``model``'s ``[predictor]`` table describes, on ``data``, as
    ``armcomp learn`` does; returns the model with it, the training errors and the
    cross-validated ones. A predictor that memorises its rows, or does not help on rows it was
    not fitted on, is warned about (``CalibrationWarning``). ``progress(stage, done, total)``
    is called after every step of the training (stage ``gp``, ``adam``, ``lm`` or
    ``sparrows``) and every fold of the cross-validation (``folds``). ``groups``: a label per
    data row, or ``group_by`` a CSV column (``"COLUMN:N"``: N blocks of a numeric one), so that
    the cross-validation holds out whole groups (``--group-by``; by default a set-up column)."""
    fitted, text = _native.learn(
        model,
        data,
        predictor=predictor,
        progress=progress,
        groups=_labels(groups),
        group_by=group_by,
    )
    report = from_json(LearnReport, text)
    for w in report.warnings:
        warnings.warn(w, CalibrationWarning, stacklevel=2)
    return fitted, report


def compensate(
    model: Robot,
    targets: np.ndarray,
    mode: str = "exact",
    frame: str = "measurement",
    start: Optional[np.ndarray] = None,
    lock: Union[None, str, Sequence[str]] = None,
    sensors: Optional[Dict[str, Sequence[float]]] = None,
) -> Compensation:
    """Joint commands that put ``model``'s tool on ``targets`` (n × 3 positions in m, or
    n × 7 with a tool orientation ``qw, qx, qy, qz`` to keep), in one call, as
    ``armcomp compensate`` computes them. ``mode``: ``exact`` (the model with its predicted
    residual) or ``paper`` (the two-step of the deflection paper); ``frame``: ``measurement``
    or ``base``. Only the joints that move the tool change; the others keep ``start`` (one
    configuration for all targets or one per target, SI; default: the robot file's ``hold``
    values), and so do the joints named in ``lock`` (``"j1,j2"`` or a list). ``sensors`` maps
    a sensor of the robot file to its reading now, as its columns hold it in SI (an
    accelerometer's x, y, z in m/s²; an inclinometer's roll, pitch in rad): the tilt it
    stands at turns and loads the model as a measured row's does."""
    q, corrected, std, unconverged = _native.compensate(
        model,
        np.atleast_2d(np.asarray(targets, dtype=float)),
        mode=mode,
        frame=frame,
        start=None if start is None else np.atleast_2d(np.asarray(start, dtype=float)),
        lock=_names(lock) or [],
        sensors=None if sensors is None else {k: [float(v) for v in c] for k, c in sensors.items()},
    )
    return Compensation(q=q, corrected=corrected, std=std, unconverged=list(unconverged))


def plan(
    robot: Robot,
    n: int = 100,
    method: Optional[str] = None,
    space: str = "joint",
    pool: Union[None, int, np.ndarray, Measurements] = None,
    pool_sampler: str = "sobol",
    identify: Union[None, str, Sequence[str]] = None,
    next: Optional[int] = None,
    measured: Optional[Measurements] = None,
    noise_mm: float = 0.1,
    exchange_passes: int = 10,
    trajectory: Optional[np.ndarray] = None,
    trajectory_points: int = 50,
    per_point: int = 10,
    seed: int = 0,
) -> Plan:
    """Measurement poses for ``robot``, never in collision, as ``armcomp plan`` plans them.

    ``method``: sobol, halton, random or grid (even sets in ``space`` joint or cartesian);
    d-optimal, a-optimal or uncertainty (the best ``n`` of a ``pool`` for identifying
    ``identify``: a number of poses to sample, an array of configurations, or
    ``Measurements`` to pick the rows worth calibrating on); or trajectory (pool poses nearest
    to a task ``trajectory``, n × joints). Default: sobol, or uncertainty with ``next``.
    ``next=K`` proposes the K poses to measure after ``measured``."""
    poses, note, rows, selection = _native.plan(
        robot,
        n=n,
        method=method,
        space=space,
        pool=pool,
        pool_sampler=pool_sampler,
        identify=_names(identify),
        next=next,
        measured=measured,
        noise_mm=noise_mm,
        exchange_passes=exchange_passes,
        trajectory=trajectory,
        trajectory_points=trajectory_points,
        per_point=per_point,
        seed=seed,
    )
    return Plan(
        poses=poses,
        note=note,
        rows=None if rows is None else list(rows),
        selection=None if selection is None else json.loads(selection),
    )


def validate(path: Union[str, "os.PathLike[str]"]) -> list:
    """The problems of a robot file as ``armcomp validate --json`` lists them (``file``,
    ``line``, the field ``path``, ``message``): syntax and types, semantics, the JSON Schema.
    An empty list means the file is valid."""
    return json.loads(_native.validate(path))


def check_pose(robot: Robot, q) -> list:
    """Self-collisions and collisions with fixtures at one configuration ``q`` (SI, by position
    or a dict by joint name), as ``armcomp check-pose --json`` lists its ``contacts``: ``first``,
    ``second``, ``fixture``, ``distance`` (m, negative for an overlap) and the closest points
    ``point_first``, ``point_second`` (m, base frame). An empty list means no collision."""
    return json.loads(_native.check_pose(robot, q))


def schema() -> str:
    """The JSON Schema of robot files (JSON text), as ``armcomp schema`` prints it."""
    return _native.schema()


def allow_plugins(allow: bool = True) -> None:
    """Lets robot files load the run-time plugin libraries they name inside their own folder,
    and ``diagnose(library=...)`` the ones it names, for the rest of the process (``False``
    stops it), as ``--allow-plugins`` does for one command. Loading a library runs its code:
    allow it only for files you trust. Libraries in the user config's ``plugin_dirs`` load
    without it."""
    _native.allow_plugins(allow)


def plugins() -> list:
    """The plugin types robot files can name, as ``armcomp plugins --json`` lists them: one
    dict per type with its ``type``, ``role``, ``doc`` and ``diagnosis_candidate``."""
    return json.loads(_native.plugins())
