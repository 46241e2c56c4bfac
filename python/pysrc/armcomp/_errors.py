"""The exceptions and warnings armcomp raises."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Optional

if TYPE_CHECKING:
    from ._armcomp import Robot


class ArmcompError(Exception):
    """Base class of armcomp's own errors."""


class InputError(ArmcompError, ValueError):
    """A file, array or argument armcomp cannot use.

    ``file``, ``line`` (1-based) and ``field`` (a robot file's field path, a CSV column or an
    argument name) say where, when known.
    """

    def __init__(
        self,
        message: str,
        file: Optional[str] = None,
        line: Optional[int] = None,
        field: Optional[str] = None,
    ) -> None:
        super().__init__(message)
        self.file = file
        self.line = line
        self.field = field


class NotConverged(ArmcompError):
    """Calibration stopped before it converged.

    ``model`` is the best model found (what ``armcomp calibrate`` writes in that case) and
    ``report`` its calibration report.
    """

    def __init__(self, message: str, model: "Robot", report: Any) -> None:
        super().__init__(message)
        self.model = model
        self.report = report


class CalibrationWarning(UserWarning):
    """A calibration that ended far above the declared noise, or what it suggests is wrong."""
