"""Type stubs of the native module (``armcomp._armcomp``); use it through ``armcomp``."""

from os import PathLike
from typing import Any, Callable, Dict, List, Literal, Mapping, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

_Path = Union[str, PathLike]
_Array = npt.ArrayLike
# Joint values in the robot's order, or by joint name.
_Joints = Union[npt.ArrayLike, Mapping[str, float]]
# One set of measurements, or one per station.
_Data = Union["Measurements", Sequence["Measurements"]]

__version__: str

class Robot:
    """A robot: kinematics, points, error models and (for a model) identified values and a
    fitted predictor. Values are SI (m, rad) in and out."""

    @staticmethod
    def load(path: _Path) -> Robot:
        """Reads a robot or model file (TOML, JSON) or a bare URDF."""
    @staticmethod
    def from_toml(text: str, base_dir: Optional[_Path] = None) -> Robot:
        """Builds a robot from robot-file TOML text; relative paths resolve against ``base_dir``."""
    @property
    def name(self) -> str: ...
    @property
    def joint_names(self) -> List[str]:
        """The independent joints: the columns of ``q``, in order."""
    @property
    def nq(self) -> int: ...
    @property
    def joint_limits(self) -> np.ndarray:
        """nq × 2: lower and upper limit of each joint (SI; ±inf where none)."""
    @property
    def points(self) -> List[str]:
        """The points, in the order ``fk`` returns them."""
    @property
    def tool(self) -> str: ...
    @property
    def markers(self) -> List[str]: ...
    @property
    def warnings(self) -> List[str]: ...
    @property
    def parameters(self) -> Tuple[List[str], np.ndarray, List[str]]:
        """``(names, values, units)`` of the identifiable parameters, values in SI units, as a
        calibration of this model starts from them. Marker offsets and a URDF joint's small
        rotations and ``offset`` are corrections on the stored marker positions and joint
        origins, so they read 0 on every model, calibrated or not; what a calibration changed
        is in its report (``initial`` and ``value`` of each parameter)."""
    def fk(self, q: _Joints) -> Tuple[np.ndarray, np.ndarray]:
        """Positions of every point (points × 3, m, base frame) and the tool pose (4 × 4)."""
    @overload
    def fk_many(self, q: _Array) -> np.ndarray: ...
    @overload
    def fk_many(self, q: _Array, tool: Literal[True]) -> Tuple[np.ndarray, np.ndarray]: ...
    def fk_many(self, q: _Array, tool: bool = False) -> Union[np.ndarray, Tuple[np.ndarray, np.ndarray]]:
        """``n × nq`` configurations → ``n × points × 3`` positions (m), in one call; with
        ``tool=True`` also the ``n × 4 × 4`` tool poses."""
    @property
    def frames(self) -> List[str]:
        """Every frame ``pose`` and ``jacobian`` take: the points, then the links."""
    def pose(self, q: _Joints, frame: Optional[str] = None) -> np.ndarray:
        """4 × 4 ``t_base_frame`` of a point or link (default the tool), full model."""
    def poses_many(self, q: _Array, frames: Optional[Sequence[str]] = None) -> np.ndarray:
        """``n × frames × 4 × 4`` poses (default every frame)."""
    def jacobian(self, q: _Joints, frame: Optional[str] = None, reference: Optional[object] = None) -> np.ndarray:
        """6 × nq: linear (rows 0–2) and angular (rows 3–5) velocity of the tool or ``frame``, in
        ``reference``: ``local_world_aligned`` (default), ``world`` or ``local`` (or pinocchio's
        ``ReferenceFrame``)."""
    def jacobians_many(
        self, q: _Array, frames: Optional[Sequence[str]] = None, reference: Optional[object] = None
    ) -> np.ndarray:
        """``n × frames × 6 × nq`` Jacobians (default the tool)."""
    def predict(
        self,
        q: _Joints,
        point: Optional[str] = None,
        station: Optional[str] = None,
        temperature: Optional[float] = None,
        payload: Optional[float] = None,
    ) -> np.ndarray:
        """The modelled position (3, m) of ``point`` in the measurement frame, predictor included."""
    def predict_many(
        self,
        q: _Array,
        point: Optional[str] = None,
        station: Optional[str] = None,
        temperature: Optional[float] = None,
        payload: Optional[float] = None,
    ) -> np.ndarray:
        """``predict`` for each row of ``Q``: n × 3 (m)."""
    @property
    def measurement_frame(self) -> np.ndarray:
        """4 × 4 ``t_measurement_base``: the base's pose in the tracker's frame."""
    @property
    def stations(self) -> Dict[str, np.ndarray]:
        """Each station's ``t_measurement_base`` by name (empty for one frame)."""
    @property
    def marker_offsets(self) -> Dict[str, Tuple[str, np.ndarray]]:
        """``{marker: (link, position in the link frame, m)}``."""
    def to_text(self, format: str = "toml") -> str:
        """The robot file with this robot's values (``toml`` or ``json``)."""
    def save(self, path: _Path) -> None:
        """Writes the robot (model) file atomically; JSON for a ``.json`` extension."""
    def to_urdf(self, path: _Path, rigid_only: bool = False, data: Optional[Measurements] = None) -> Optional[float]:
        """Writes the model's URDF with the identified joints; returns what ``rigid_only`` drops (m)."""

class Measurements:
    """Measured positions (m, measurement frame) and the joint values (SI) they were measured at."""

    def __init__(
        self,
        joints: _Array,
        positions: _Array,
        points: Union[None, str, Sequence[str]] = None,
        joint_names: Optional[Sequence[str]] = None,
    ) -> None: ...
    @classmethod
    def read(
        cls, source: Union[_Path, Any], robot: Optional[Robot] = None, rows: Union[None, str, Sequence[int]] = None
    ) -> Measurements:
        """Reads a measurement CSV from a path, a file object or a DataFrame (against ``robot``
        now, or when first used)."""
    @classmethod
    def parse(
        cls, text: str, robot: Optional[Robot] = None, rows: Union[None, str, Sequence[int]] = None,
        name: Optional[str] = None,
    ) -> Measurements:
        """Measurements from a CSV's text."""
    def to_dataframe(self, robot: Robot) -> Any:
        """The CSV ``save`` writes, as a ``pandas.DataFrame``."""
    def __getitem__(self, index: Union[int, slice, Sequence[int]]) -> Measurements: ...
    @property
    def rows(self) -> List[int]:
        """The data rows of the samples (0-based)."""
    def for_robot(self, robot: Robot) -> Measurements: ...
    @property
    def joints(self) -> np.ndarray: ...
    @property
    def positions(self) -> np.ndarray: ...
    @property
    def points(self) -> Optional[List[str]]: ...
    @property
    def joint_names(self) -> Optional[List[str]]: ...
    def save(self, path: _Path, robot: Robot) -> None:
        """Writes a measurement CSV in ``robot``'s joints and units."""
    def __len__(self) -> int: ...

def calibrate(
    robot: Robot,
    data: _Data,
    identify: Optional[List[str]] = None,
    noise_mm: Optional[float] = None,
    prior: Union[None, float, str] = None,
    max_iterations: int = 100,
    restarts: int = 2,
    seed: int = 0,
    progress: Optional[Callable[[str, int, int], None]] = None,
    loss: str = "squared",
    noise_deg: Optional[float] = None,
    exclude_outliers: bool = False,
    report: Optional[_Path] = None,
    groups: Optional[List[str]] = None,
    group_by: Optional[str] = None,
) -> Tuple[Robot, str, bool, Tuple[List[str], np.ndarray], Optional[str]]: ...
def evaluate(
    model: Robot,
    data: _Data,
    register: bool = False,
    register_on: Union[None, str, Sequence[int]] = None,
    report: Optional[_Path] = None,
) -> Tuple[str, np.ndarray, Optional[str]]: ...
def fit(
    robot: Robot,
    data: _Data,
    noise_mm: Optional[float] = None,
    folds: int = 5,
    seed: int = 0,
    groups: Optional[List[str]] = None,
    predictor: Optional[str] = "gp",
    progress: Optional[Callable[[str, int, int], None]] = None,
    noise_deg: Optional[float] = None,
    repeats: Optional[int] = None,
    report: Optional[_Path] = None,
    group_by: Optional[str] = None,
) -> Tuple[Robot, str, Tuple[List[str], np.ndarray], Optional[str]]: ...
def simulate(
    truth: Robot,
    poses: Optional[_Array] = None,
    n: int = 100,
    sampler: str = "sobol",
    noise_mm: float = 0.0,
    seed: int = 0,
    stations: Optional[int] = None,
    tilt_deg: float = 0.0,
    tilt_per: str = "row",
    grounds: Optional[Dict[str, Union[float, Tuple[float, float]]]] = None,
) -> Measurements: ...
def diagnose(
    robot: Robot,
    data: Measurements,
    seed: int = 0,
    folds: int = 3,
    max_steps: int = 5,
    min_reduction_percent: float = 5.0,
    noise_mm: Optional[float] = None,
    identify: Optional[List[str]] = None,
    predictor: Optional[str] = "gp",
    progress: Optional[Callable[[str, int, int], None]] = None,
    keep_outliers: bool = False,
    groups: Optional[List[str]] = None,
    exhaustive: bool = False,
    report: Optional[_Path] = None,
    group_by: Optional[str] = None,
    library: Optional[List[_Path]] = None,
) -> Tuple[Robot, str]: ...
def learn(
    model: Robot,
    data: Measurements,
    predictor: Optional[str] = None,
    progress: Optional[Callable[[str, int, int], None]] = None,
    groups: Optional[List[str]] = None,
    group_by: Optional[str] = None,
) -> Tuple[Robot, str]: ...
def compensate(
    model: Robot,
    targets: _Array,
    mode: str = "exact",
    frame: str = "measurement",
    start: Optional[_Array] = None,
    lock: List[str] = ...,
    sensors: Optional[Mapping[str, List[float]]] = None,
) -> Tuple[np.ndarray, np.ndarray, Optional[np.ndarray], List[Tuple[int, float]]]: ...
def plan(
    robot: Robot,
    n: int = 100,
    method: Optional[str] = None,
    space: str = "joint",
    pool: Union[None, int, _Array, Measurements] = None,
    pool_sampler: str = "sobol",
    identify: Optional[List[str]] = None,
    next: Optional[int] = None,
    measured: Optional[Measurements] = None,
    noise_mm: float = 0.1,
    exchange_passes: int = 10,
    trajectory: Optional[_Array] = None,
    trajectory_points: int = 50,
    per_point: int = 10,
    seed: int = 0,
) -> Tuple[np.ndarray, str, Optional[List[int]], Optional[str]]: ...
def validate(path: _Path) -> str: ...
def check_pose(robot: Robot, q: _Joints) -> str: ...
def schema() -> str: ...
def allow_plugins(allow: bool = True) -> None: ...
