"""Report dataclasses built from the JSON the native module returns (the command line's
``--json`` output), keeping that JSON for ``to_dict()``."""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import sys
import typing
from typing import Any, Dict, List, Type, TypeVar, Union

T = TypeVar("T")


def _convert(tp: Any, value: Any) -> Any:
    if value is None:
        # JSON has no infinity: a number that is never missing but is infinite (the std of a
        # parameter nothing determines, a singular problem's condition number) comes as null.
        return math.inf if tp is float else None
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin is Union:
        inner = [a for a in args if a is not type(None)]
        return _convert(inner[0], value) if len(inner) == 1 else value
    if origin in (list, List):
        return [_convert(args[0], v) for v in value]
    if origin in (dict, Dict):
        return {k: _convert(args[1], v) for k, v in value.items()}
    if dataclasses.is_dataclass(tp):
        return build(tp, value)
    if tp is float and isinstance(value, int):
        return float(value)
    return value


def build(cls: Type[T], data: Dict[str, Any]) -> T:
    """An instance of the dataclass ``cls`` from ``data``: fields by name (a field ``final_``
    reads ``final``), nested dataclasses converted, the raw dictionary kept for ``to_dict``."""
    hints = typing.get_type_hints(cls, vars(sys.modules[cls.__module__]))
    values = {}
    for f in dataclasses.fields(cls):
        if not f.init or f.name.startswith("_"):
            continue
        key = f.name.rstrip("_")
        if key in data:
            values[f.name] = _convert(hints[f.name], data[key])
    obj = cls(**values)
    object.__setattr__(obj, "_raw", data)
    return obj


def from_json(cls: Type[T], text: str) -> T:
    """``build`` from JSON text."""
    return build(cls, json.loads(text))


def _short(value: Any) -> str:
    """One field in a report's repr: numbers to four significant digits, lists and tables
    by their length, nested reports by their class."""
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, (list, tuple, dict)):
        return f"<{len(value)} items>" if value else repr(value)
    if isinstance(value, Report) and len(repr(value)) <= 160:
        return repr(value)
    if dataclasses.is_dataclass(value):
        return f"{type(value).__name__}(...)"
    if value is not None and type(value).__module__ == "numpy":
        return f"<array {getattr(value, 'shape', '')}>"
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


class Report:
    """Mixin of the report dataclasses: a repr of a few lines (``full_repr()`` gives every
    field), and ``to_dict()`` the command line's JSON."""

    _raw: Dict[str, Any]

    def to_dict(self) -> Dict[str, Any]:
        """The report as a dictionary: exactly what the command line prints with ``--json``."""
        return copy.deepcopy(self._raw)

    def __repr__(self) -> str:
        fields = (f for f in dataclasses.fields(self) if f.repr and not f.name.startswith("_"))
        inner = ", ".join(f"{f.name}={_short(getattr(self, f.name))}" for f in fields)
        return f"{type(self).__name__}({inner})"

    def full_repr(self) -> str:
        """Every field, nested reports and lists in full (a long text for a big model)."""
        fields = (f for f in dataclasses.fields(self) if f.repr and not f.name.startswith("_"))
        inner = ", ".join(f"{f.name}={getattr(self, f.name)!r}" for f in fields)
        return f"{type(self).__name__}({inner})"
