"""Joint vectors between armcomp's order (``Robot.joint_names``, the columns of ``q``) and
another library's: a list of joint names, or a pinocchio ``Model``."""

from __future__ import annotations

from typing import Any, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

# (name, idx_q, nq, nv) of one joint of the other library.
_Joint = Tuple[str, int, int, int]


def _model_joints(model: Any) -> List[_Joint]:
    """The joints of a pinocchio ``Model`` (duck-typed), the universe left out."""
    names = list(model.names)
    if not names or names[0] != "universe":
        raise ValueError("expected a pinocchio Model, whose names start with 'universe'")
    # pinocchio.Model has both; a stand-in may give either.
    nqs = list(model.nqs) if hasattr(model, "nqs") else [j.nq for j in model.joints]
    nvs = list(model.nvs) if hasattr(model, "nvs") else [j.nv for j in model.joints]
    idx_qs = list(model.idx_qs)
    if not len(names) == len(nqs) == len(nvs) == len(idx_qs):
        raise ValueError("expected a pinocchio Model: names, nqs, nvs and idx_qs of one length")
    return [(names[j], int(idx_qs[j]), int(nqs[j]), int(nvs[j])) for j in range(1, len(names))]


def _batch(values: Any, n: int, what: str) -> np.ndarray:
    a = np.asarray(values, dtype=float)
    if a.ndim not in (1, 2) or a.shape[-1] != n:
        raise ValueError(f"{what}: expected {n} values or rows of {n}, got shape {a.shape}")
    return a


class JointMap:
    """Maps joint vectors between armcomp's joint order and another library's.

    ``other``: the other library's joint names in its order (each one coordinate), or a
    pinocchio ``Model``, whose revolute and prismatic joints are one coordinate and whose
    continuous (unbounded revolute) joints two, ``(cos θ, sin θ)``. Joints of more than one
    degree of freedom there (free-flyer, planar, spherical) are no armcomp coordinate: they are
    ``skipped``, their configuration left to the caller, as are the other's joints armcomp
    lacks. An armcomp joint the other lacks is an error, unless ``missing="hold"``:
    ``to_armcomp`` then gives it its ``hold`` value (a dict by joint name, or one value per
    armcomp joint; default 0).

    Values pass unchanged: armcomp's Python API and pinocchio both use SI (rad, m).

    Attributes: ``joint_names`` (armcomp's), ``other_names`` (the other's joints, pinocchio's
    universe left out), ``nq`` (the size of the other's configuration), ``indices`` (armcomp
    column k -> its position in the other's q: a continuous joint's cos θ, -1 for a held
    joint), ``continuous``, ``skipped`` and ``held`` (joint names).
    """

    def __init__(
        self,
        robot_joint_names: Sequence[str],
        other: Any,
        missing: str = "raise",
        hold: Union[None, Mapping[str, float], Sequence[float]] = None,
    ) -> None:
        if missing not in ("raise", "hold"):
            raise ValueError(f"missing: expected 'raise' or 'hold', got {missing!r}")
        if hold is not None and missing != "hold":
            raise ValueError("hold is only used with missing='hold'")
        self.joint_names = list(robot_joint_names)
        if hasattr(other, "names") and hasattr(other, "idx_qs"):
            joints = _model_joints(other)
            self.nq = int(other.nq)
        else:
            names = [] if isinstance(other, str) else list(other)
            if not names or not all(isinstance(n, str) for n in names):
                raise TypeError(f"other: expected joint names or a pinocchio Model, got {other!r}")
            joints = [(name, i, 1, 1) for i, name in enumerate(names)]
            self.nq = len(joints)
        self.other_names = [j[0] for j in joints]
        twice = sorted({n for n in self.other_names if self.other_names.count(n) > 1})
        if twice:
            raise ValueError(f"other: joints named twice: {', '.join(twice)}")

        # pinocchio's neutral configuration: zeros but a continuous joint's cos θ and a
        # free-flyer's quaternion w (stored x, y, z, w after the translation).
        self._neutral = np.zeros(self.nq)
        coordinates = {}
        multi = {}
        for name, idx, nq, nv in joints:
            if nv == 1 and nq in (1, 2):
                coordinates[name] = (idx, nq == 2)
                if nq == 2:
                    self._neutral[idx] = 1.0
            else:
                multi[name] = f"{name} (nq {nq}, nv {nv})"
                if nq == 7 and nv == 6:
                    self._neutral[idx + 6] = 1.0

        self.held = [n for n in self.joint_names if n not in coordinates]
        if self.held and missing == "raise":
            why = [multi.get(n, n) for n in self.held]
            raise ValueError(
                f"armcomp joints the other model has no coordinate for: {', '.join(why)} "
                "(missing='hold' holds them at hold's values)"
            )
        mapped = set(self.joint_names)
        self.skipped = [n for n in self.other_names if n in multi or n not in mapped]
        where = [coordinates.get(n, (-1, False)) for n in self.joint_names]
        self.indices = np.array([idx for idx, _ in where], dtype=int)
        self.continuous = [n for n, (_, c) in zip(self.joint_names, where) if c]

        k = np.arange(len(self.joint_names))
        cont = np.array([c for _, c in where], dtype=bool)
        plain = (self.indices >= 0) & ~cont
        self._plain_k, self._plain_i = k[plain], self.indices[plain]
        self._cont_k, self._cont_i = k[cont], self.indices[cont]
        self._held_k = k[self.indices < 0]
        self._hold = self._hold_values(hold)

    def _hold_values(self, hold: Union[None, Mapping[str, float], Sequence[float]]) -> np.ndarray:
        """One value per armcomp joint (only the held ones' are used)."""
        values = np.zeros(len(self.joint_names))
        if isinstance(hold, Mapping):
            unknown = [n for n in hold if n not in self.held]
            if unknown:
                raise ValueError(
                    f"hold: not held joints: {', '.join(unknown)}; held: {', '.join(self.held)}"
                )
            for name, v in hold.items():
                values[self.joint_names.index(name)] = float(v)
        elif hold is not None:
            values = np.array(hold, dtype=float)
            n = len(self.joint_names)
            if values.shape != (n,):
                raise ValueError(f"hold: expected {n} values in armcomp's order, got shape {values.shape}")
        return values

    def to_armcomp(self, q_other: Any) -> np.ndarray:
        """``q_other`` (the other's ``nq`` values, or n × nq) in armcomp's order: a continuous
        joint's angle is atan2(sin θ, cos θ), in (-π, π]; a held joint has its hold value."""
        q = _batch(q_other, self.nq, "q_other (the other library's configuration)")
        out = np.empty(q.shape[:-1] + (len(self.joint_names),))
        out[..., self._plain_k] = q[..., self._plain_i]
        out[..., self._cont_k] = np.arctan2(q[..., self._cont_i + 1], q[..., self._cont_i])
        out[..., self._held_k] = self._hold[self._held_k]
        return out

    def from_armcomp(self, q: Any, base: Optional[Any] = None) -> np.ndarray:
        """``q`` (armcomp's order, one configuration or n × joints) as the other's ``nq``
        values. The ``skipped`` joints' entries are ``base``'s (one configuration of the
        other, or one per row), else pinocchio's neutral: 0, but (1, 0) for a continuous
        joint and a free-flyer's (nq 7) quaternion w = 1; for other joints of several degrees
        of freedom pass ``base=pinocchio.neutral(model)``. Held joints have no entry."""
        q = _batch(q, len(self.joint_names), "q (armcomp's joint order)")
        start = self._neutral if base is None else _batch(base, self.nq, "base (the other's order)")
        try:
            lead = np.broadcast_shapes(q.shape[:-1], start.shape[:-1])
        except ValueError:
            raise ValueError(
                f"q has {q.shape[0]} rows and base {start.shape[0]}: give one base or one per row"
            ) from None
        out = np.broadcast_to(start, lead + (self.nq,)).copy()
        q = np.broadcast_to(q, lead + q.shape[-1:])
        out[..., self._plain_i] = q[..., self._plain_k]
        out[..., self._cont_i] = np.cos(q[..., self._cont_k])
        out[..., self._cont_i + 1] = np.sin(q[..., self._cont_k])
        return out

    def __repr__(self) -> str:
        parts = [f"{len(self.joint_names)} armcomp joints -> nq {self.nq} of {len(self.other_names)}"]
        lists = (("continuous", self.continuous), ("skipped", self.skipped), ("held", self.held))
        for what, names in lists:
            if names:
                parts.append(f"{what}: {', '.join(names)}")
        return f"JointMap({'; '.join(parts)})"
