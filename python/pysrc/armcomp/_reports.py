"""What the operations return: reports as dataclasses (lengths in mm where the name says so,
SI otherwise), each with ``to_dict()`` giving the command line's ``--json`` output."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from ._convert import Report


@dataclass(frozen=True)
class AxisErrors:
    """Mean absolute error per axis of the measurement frame (mm)."""

    x: float
    y: float
    z: float


@dataclass(frozen=True, repr=False)
class ErrorStats(Report):
    """Statistics of 3-D position errors (mm)."""

    n: int
    mean_mm: float
    std_mm: float
    rms_mm: float
    max_mm: float
    mean_abs_mm: AxisErrors
    _raw: Dict[str, Any] = field(default_factory=dict, repr=False, compare=False)


@dataclass(frozen=True, repr=False)
class StationErrors(ErrorStats):
    """:class:`ErrorStats` of one station's samples (``per_station`` in ``evaluate --json``)."""

    station: str = ""


@dataclass(frozen=True)
class Parameter:
    """One calibrated parameter before and after, in its SI ``unit``."""

    name: str
    unit: str
    initial: float
    value: float
    std: float
    fixed: bool
    at_bound: bool
    plausible: bool = True


@dataclass(frozen=True)
class Deficiency:
    """A combination of parameters the data cannot determine, and what was done about it."""

    combination: List[Tuple[str, float]]
    action: str
    fixed: Optional[str] = None


@dataclass(frozen=True)
class Identifiability:
    """How well the selected parameters are determined by the data."""

    n_equations: int
    n_params: int
    rank: int
    condition_number: Optional[float]
    condition_number_free: Optional[float]
    deficiencies: List[Deficiency]
    held_by_priors: List[str]
    message: str


@dataclass(frozen=True)
class PriorScaleScore:
    """A prior scale tried by cross-validation (None: no priors) and its held-out RMS (mm)."""

    scale: Optional[float]
    held_out_rms_mm: float


@dataclass(frozen=True)
class PriorChoice:
    """The prior scale cross-validation chose (``prior="auto"``)."""

    scale: Optional[float]
    folds: int
    seed: int
    scores: List[PriorScaleScore]


@dataclass(frozen=True)
class GroupScale:
    """One group's prior scale chosen by the evidence (``prior="evidence"``)."""

    group: Dict[str, Any]
    label: str
    scale: float
    n_params: int
    determined: float


@dataclass(frozen=True)
class Evidence:
    """The noise and prior scales chosen by the evidence of the data (type-II maximum
    likelihood): ``noise_mm`` with its standard error and the equations it was measured on
    (``noise_dof``, below one: not determined by the rows), how many parameters the data
    determine, and the log evidence."""

    noise_estimated: bool
    noise_mm: float
    noise_std_mm: float
    noise_dof: float
    rms_per_axis_mm: List[float]
    determined: float
    n_free: int
    n_equations: int
    groups: List[GroupScale]
    log_evidence: float
    rounds: int
    converged: bool


@dataclass(frozen=True, repr=False)
class CalibrationReport(Report):
    """What calibration did and how well it fits (``armcomp calibrate --json``). Beside the
    JSON: ``covariance`` of the free parameters ``covariance_names`` (SI units; their
    ``std`` squared on its diagonal), ``correlation``, and ``page``, the report page's data
    (``ReportPage``) when ``report=`` wrote one."""

    n_samples: int
    measured_chain: List[str]
    csv_joints: List[str]
    registered: bool
    prior_scale: Optional[float]
    identifiability: Identifiability
    params: List[Parameter]
    iterations: int
    restarts_rms_mm: List[float]
    converged: bool
    stop_reason: str
    before: ErrorStats
    after: ErrorStats
    rms_over_noise: Optional[float]
    units_mislabelled: bool
    warnings: List[str]
    prior_choice: Optional[PriorChoice] = None
    evidence: Optional[Evidence] = None
    outliers: List[Dict[str, Any]] = field(default_factory=list)
    drift: Optional[Dict[str, Any]] = None
    outlier_rows: List[int] = field(default_factory=list)
    loss: str = "squared"
    downweighted: int = 0
    far_above_noise: bool = False
    # Set by `armcomp.calibrate` and `armcomp.fit`; empty for a report built from JSON alone.
    covariance_names: List[str] = field(default_factory=list, repr=False, compare=False)
    covariance: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), repr=False, compare=False)
    page: Optional[Any] = field(default=None, repr=False, compare=False)
    _raw: Dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @property
    def parameters(self) -> Dict[str, Parameter]:
        """The parameters by name."""
        return {p.name: p for p in self.params}

    @property
    def correlation(self) -> np.ndarray:
        """The correlation matrix of the free parameters (``covariance_names``' order): the
        covariance over the product of the standard deviations; NaN where a parameter is not
        determined (infinite variance)."""
        std = np.sqrt(np.diag(self.covariance))
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = self.covariance / np.outer(std, std)
        corr[~np.isfinite(corr)] = np.nan
        np.fill_diagonal(corr, np.where(np.isfinite(std) & (std > 0), 1.0, np.nan))
        return corr


@dataclass(frozen=True)
class Candidate:
    """One candidate model of the ladder: the level (``registration``, ``joint_offsets``,
    ``geometry``, ``error_models``), the prior scheme (``{"evidence": "per_parameter"}``,
    ``{"evidence": "groups"}``, ``{"file": 0.3}`` or ``"none"``) and whether a residual
    predictor learns what it leaves."""

    rung: str
    prior: Any
    predictor: bool


@dataclass(frozen=True)
class CandidateScore:
    """One candidate's cross-validated held-out RMS (mm, pooled over every fold of every
    repeat), per repeat and per fold, its excess over the best on equal folds with that
    excess's standard error over the repeats, whether it is within the noise of the best, its
    effective parameters and why it is not sound (None when it is)."""

    candidate: Candidate
    label: str
    rms_mm: float
    repeat_rms_mm: List[float]
    fold_rms_mm: List[float]
    spread_mm: float
    excess_mm: float
    excess_std_error_mm: float
    within_noise: bool
    effective_params: float
    not_sound: Optional[str]
    seconds: float


@dataclass(frozen=True)
class StackMember:
    """A member of a stacked model: a prior scheme of the chosen level and its weight (the
    weights sum to one; every parameter of the model is their weighted mean)."""

    prior: Any
    label: str
    weight: float


@dataclass(frozen=True, repr=False)
class FitReport(Report):
    """The model ladder (``armcomp fit --json``): every candidate's score, the candidate chosen
    and why (``warning`` when it is not sound), the members of a stack when the model is a
    weighted mean of the chosen level's prior schemes (empty otherwise), the held-out error to
    expect (the cross-validated score of the choice itself), and the chosen candidate's
    evidence and calibration on all rows."""

    candidates: List[CandidateScore]
    chosen: Candidate
    stack: List[StackMember]
    reason: str
    warning: Optional[str]
    expected_rms_mm: float
    folds: int
    repeats: int
    folds_by: str
    evidence: Evidence
    calibration: CalibrationReport
    page: Optional[Any] = field(default=None, repr=False, compare=False)
    _raw: Dict[str, Any] = field(default_factory=dict, repr=False, compare=False)


@dataclass(frozen=True, repr=False)
class EvaluationReport(Report):
    """Errors of a model on measurements (``armcomp evaluate --json``), and per sample the
    measured minus modelled position (``errors``, n × 3, m, measurement frame)."""

    n: int
    mean_mm: float
    std_mm: float
    rms_mm: float
    max_mm: float
    mean_abs_mm: AxisErrors
    per_point: Dict[str, ErrorStats] = field(default_factory=dict)
    # With several stations: each one's errors, and those registered on these data.
    per_station: List[StationErrors] = field(default_factory=list)
    registered_stations: List[str] = field(default_factory=list)
    # Always set by `armcomp.evaluate`; empty only for a report built from JSON alone.
    errors: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)), repr=False, compare=False)
    page: Optional[Any] = field(default=None, repr=False, compare=False)
    _raw: Dict[str, Any] = field(default_factory=dict, repr=False, compare=False)


@dataclass(frozen=True)
class RankedCandidate:
    """One candidate effect as scored in a round of the diagnosis."""

    effect: str
    location: str
    label: str
    n_params: int
    identified_params: int
    heldout: Optional[ErrorStats]
    heldout_bic: Optional[float]
    share_removed: Optional[float]
    at_neutral: bool
    earns_parameters: bool
    indistinguishable_from_best: bool
    error: Optional[str] = None
    implausible_values: bool = False
    verdict: str = ""
    predicted_share: Optional[float] = None
    refitted: bool = True


@dataclass(frozen=True)
class IdentifiedValue:
    """A value an accepted effect was identified with, in its SI ``unit``."""

    value: float
    unit: str


@dataclass(frozen=True)
class DiagnosisStep:
    """One effect the diagnosis accepted."""

    effect: str
    location: str
    label: str
    summary: str
    params: Dict[str, IdentifiedValue]
    heldout_before: ErrorStats
    heldout_after: ErrorStats
    share_removed: float
    equivalent: List[str]
    ranking: List[RankedCandidate]
    implausible: List[str] = field(default_factory=list)


@dataclass(frozen=True)
class FinalModel:
    """The model at the end of the diagnosis: its effects, held-out errors and residuals."""

    effects: List[str]
    heldout: ErrorStats
    residuals: Dict[str, Any]
    ranking: List[RankedCandidate]


@dataclass(frozen=True)
class LearnableResidual:
    """How much of what remains a residual predictor learns on held-out poses."""

    predictor: str
    heldout_before: ErrorStats
    heldout_after: ErrorStats
    share_learnable: float


@dataclass(frozen=True, repr=False)
class DiagnosisReport(Report):
    """The diagnosis (``armcomp diagnose --json``): effects found step by step."""

    n_samples: int
    folds: int
    initial: ErrorStats
    initial_residuals: Dict[str, Any]
    steps: List[DiagnosisStep]
    final_: FinalModel
    learnable_residual: Optional[LearnableResidual] = None
    interrupted: bool = False
    gross_errors: List[Dict[str, Any]] = field(default_factory=list)
    gross_errors_excluded: bool = False
    gross_error_rows: List[int] = field(default_factory=list)
    drift: Optional[Dict[str, Any]] = None
    _raw: Dict[str, Any] = field(default_factory=dict, repr=False, compare=False)


@dataclass(frozen=True)
class Refitted:
    """Held-out errors with the physical model fitted again in every fold."""

    model: ErrorStats
    with_predictor: ErrorStats


@dataclass(frozen=True, repr=False)
class LearnReport(Report):
    """A fitted residual predictor: fitting time (s), training errors without and with it, and
    the errors with it on rows it was not fitted on (5-fold cross-validation; None with fewer
    than five poses). For a model ``fit`` wrote, ``refitted`` holds the same folds with the
    physical model fitted again in each one, from where ``fit`` started (``model`` alone and
    ``with_predictor``): the figures ``fit`` scored the model by."""

    seconds: float
    before: ErrorStats
    after: ErrorStats
    cross_validated: Optional[ErrorStats] = None
    refitted: Optional[Refitted] = None
    warnings: List[str] = field(default_factory=list)
    _raw: Dict[str, Any] = field(default_factory=dict, repr=False, compare=False)


@dataclass(frozen=True)
class Compensation:
    """Joint commands for a batch of targets.

    ``q``: n × joints (SI); ``corrected``: n × 3 (m), where the model without its predictor
    puts the tool, in the targets' frame; ``std``: n × 3 (m, measurement frame), the
    predictor's standard deviation, or None; ``unconverged``: ``(row, miss in m)`` for the
    targets exact mode could not meet (their commands are the closest found).
    """

    q: np.ndarray
    corrected: np.ndarray
    std: Optional[np.ndarray]
    unconverged: List[Tuple[int, float]]


@dataclass(frozen=True)
class Plan:
    """Planned measurement poses (n × joints, SI) and how they were found. For the optimal
    methods ``selection`` is ``armcomp plan --json``'s report (criterion values,
    identifiability, parameter standard deviations before and after); with measured rows as
    the pool ``rows`` are the data rows chosen."""

    poses: np.ndarray
    note: str
    rows: Optional[List[int]] = None
    selection: Optional[Dict[str, Any]] = None
