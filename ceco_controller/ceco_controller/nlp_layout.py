"""Named slices of the NMPC's NLP vectors: parameters ``p``, variables ``w``, constraint rows ``g``.

The transcription (:mod:`ceco_controller.transcription`) declares every parameter and every
stage-wise variable or constraint block here by name, so the rest of the controller reads and
writes them through the layout (``layout.params.get(p, "t_amb")``,
``layout.vars.blocks(w, "u")``), never through hand-computed offsets (the do-mpc template idea).

Parameters (one instance per NLP, :class:`ParamLayout`):

    x0 (T_cab, T_evap) [degC], t_int, t_shell [degC], d_cab, d_evap [K per control step],
    d_ain [K], u_prev (mdot_bl [kg/s], T_evap_sp [degC]), then on the N + 1 grid points:
    t_amb [degC], solar [W/m2], speed [m/s], pmv_lb, pmv_ub [-], then the comfort scalars
    held over the horizon: t_mr (mean radiant temperature) [degC], pa (vapour pressure) [Pa], recirc (the door's
    measured recirculated share [-], the power model's fresh-air share 1 - recirc; unused by the door NLP).
    With the door in the NLP (``door_control`` 'nlp', ``ParamLayout(n_grid, door=True)``) u_prev has a third
    entry, the door's recirculated share [-], and the CO2 parameters follow (:data:`PARAM_DOOR`).

Variables (:class:`VariableLayout`), stage-ordered as the transcription adds them:

    x (4 per stage i = 1..N, multiple shooting only; 7 with the door), u (2 per stage i = 0..N-1; 3 with
    the door), s_lo, s_up (1 per grid point i = 0..N), s_ev (i = 1..N), eps (ceco-ioch, i = 0..N),
    s_co2, s_fog (the door's CO2 and fog slacks, i = 1..N).

Constraint rows (:class:`RowLayout`): ``gap`` (4 per stage, multiple shooting; 7 with the door), ``pmv``
(2 per grid point), ``evap`` (2 per grid point i >= 1), ``co2`` and ``fog`` (1 each per grid point i >= 1,
with the door).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

__all__ = [
    "OcpStructure",
    "ParamLayout",
    "VariableLayout",
    "RowLayout",
    "PARAM_SCALARS",
    "PARAM_SERIES",
    "PARAM_TAIL",
    "PARAM_DOOR",
    "VAR_KEYS",
    "ROW_KINDS",
]

PARAM_SCALARS = (("x0", 2), ("t_int", 1), ("t_shell", 1), ("d_cab", 1), ("d_evap", 1), ("d_ain", 1), ("u_prev", 2))
"""Parameters that are not per grid point: (name, size), in vector order."""

PARAM_SERIES = ("t_amb", "solar", "speed", "pmv_lb", "pmv_ub")
"""Parameters with one value per grid point (N + 1), in vector order after :data:`PARAM_SCALARS`."""

PARAM_TAIL = (("t_mr", 1), ("pa", 1), ("recirc", 1))
"""Scalars held over the horizon, after the series: mean radiant temperature [degC], cabin vapour pressure [Pa], the
door's measured recirculated share [-] (the power model's fresh-air share is 1 - recirc,
:func:`ceco_controller.model.door_fresh_fraction`; the door NLP uses its own share u_i instead)."""

PARAM_DOOR = (
    ("co2_0", 1),
    ("co2_amb", 1),
    ("co2_gen", 1),
    ("co2_max", 1),
    ("leak_0", 1),
    ("leak_v", 1),
    ("m_air", 1),
    ("w_0", 1),
    ("w_amb", 1),
    ("w_gen", 1),
    ("t_glass", 1),
    ("fog_min", 1),
)
"""The door NLP's air-quality parameters after :data:`PARAM_TAIL`: the CO2 estimate at the first grid point [ppm],
the ambient CO2 [ppm], the occupants' generation n g / k [ppm kg/s], the CO2 target limit - margin [ppm], the
leakage at rest [kg/s] and its growth with speed [kg/s per m/s], the cabin's dry-air mass [kg]
(:meth:`ceco_core.co2_door.Co2DoorLaw.nlp_parameters`); then the moisture and fog ones: the cabin humidity ratio
at the first grid point and the ambient's [g/kg], the occupants' moisture [g/s], the inner glass temperature
[degC] (held) and the fog margin the NLP keeps, bound + back-off [K] (``NmpcController``)."""

VAR_KEYS = ("x", "u", "s_lo", "s_up", "s_ev", "eps", "s_co2", "s_fog")
"""Kinds of stage-wise variable blocks."""

ROW_KINDS = ("gap", "pmv", "evap", "co2", "fog")
"""Kinds of stage-wise constraint blocks."""


@dataclasses.dataclass(frozen=True)
class OcpStructure:
    """Stage dimensions of a multiple-shooting NLP: N + 2 stages, as CasADi's hpipm interface reads them.

    Built by :meth:`ceco_controller.transcription.NlpProblem.ocp_structure`.
    """

    nx: tuple[int, ...]
    """States per stage, N + 2 entries (the first and the last 0)."""
    nu: tuple[int, ...]
    """Controls (inputs and slacks) per stage, N + 2 entries (the last 0)."""
    ng: tuple[int, ...]
    """Non-dynamic constraint rows per stage, N + 2 entries (the last 0)."""


class ParamLayout:
    """Named slices of the parameter vector for a horizon of ``n_grid`` = N + 1 grid points.

    ``door``: the door NLP's layout (u_prev of 3 entries, then :data:`PARAM_DOOR` at the end).
    """

    def __init__(self, n_grid: int, door: bool = False):
        self.n_grid = int(n_grid)
        self.door = bool(door)
        self.slices: dict[str, slice] = {}
        off = 0
        scalars = tuple((n, 3 if door and n == "u_prev" else k) for n, k in PARAM_SCALARS)
        tail = PARAM_TAIL + (PARAM_DOOR if door else ())
        for name, size in scalars + tuple((s, self.n_grid) for s in PARAM_SERIES) + tail:
            self.slices[name] = slice(off, off + size)
            off += size
        self.size = off
        """Length of the parameter vector."""

    def names(self) -> tuple:
        """Parameter names in vector order."""
        return tuple(self.slices)

    def get(self, p: np.ndarray, name: str) -> np.ndarray:
        """The entries of parameter ``name`` in ``p`` (a view)."""
        return p[self.slices[name]]

    def scalar(self, p: np.ndarray, name: str) -> float:
        """A one-entry parameter as a float."""
        sl = self.slices[name]
        if sl.stop - sl.start != 1:
            raise ValueError(f"parameter {name!r} has {sl.stop - sl.start} entries, not 1")
        return float(p[sl.start])

    def pack(self, **values) -> np.ndarray:
        """The parameter vector from one value (scalar or array of the right size) per name."""
        if values.keys() != self.slices.keys():  # (compared as sets, in C: the sorted lists only for the message)
            missing = sorted(set(self.slices) - set(values))
            extra = sorted(set(values) - set(self.slices))
            raise ValueError(f"ParamLayout.pack: missing {missing}, unknown {extra}")
        p = np.empty(self.size)
        for name, sl in self.slices.items():
            p[sl] = values[name]
        return p

    def symbols(self, sym) -> tuple[dict, Any]:
        """Symbols per name (``sym(name, size)``, e.g. ``casadi.SX.sym``) and their vertical concatenation."""
        import casadi

        syms = {name: sym(name, sl.stop - sl.start) for name, sl in self.slices.items()}
        return syms, casadi.vertcat(*syms.values())


class VariableLayout:
    """Stage-wise blocks of the NLP variable vector, in the order they were added."""

    def __init__(self):
        self._starts: dict[str, list[int]] = {k: [] for k in VAR_KEYS}
        self._width: dict[str, int] = {}
        self._lb: list[float] = []
        self._ub: list[float] = []
        self._indices: dict[str, np.ndarray] = {}
        self._shift_perm: dict[int, np.ndarray] = {}
        self.n = 0
        """Number of variables."""

    def add(self, key: str, size: int, lb, ub) -> int:
        """Append a block of ``size`` variables of kind ``key``; return its first index."""
        if key not in self._starts:
            raise ValueError(f"unknown variable kind {key!r}")
        if self._width.setdefault(key, size) != size:
            raise ValueError(f"variable kind {key!r} has blocks of {self._width[key]}, not {size}")
        start = self.n
        self._indices.clear()
        self._shift_perm.clear()
        self._starts[key].append(start)
        self._lb.extend(np.broadcast_to(np.asarray(lb, float), (size,)).tolist())
        self._ub.extend(np.broadcast_to(np.asarray(ub, float), (size,)).tolist())
        self.n += size
        return start

    @property
    def lb(self) -> np.ndarray:
        """Lower bounds of all variables."""
        return np.array(self._lb)

    @property
    def ub(self) -> np.ndarray:
        """Upper bounds of all variables."""
        return np.array(self._ub)

    def starts(self, key: str) -> np.ndarray:
        """First index of each block of kind ``key`` (empty if there is none)."""
        return np.array(self._starts[key], dtype=int)

    def width(self, key: str) -> int:
        """Entries per block of kind ``key`` (0 if there is none)."""
        return self._width.get(key, 0)

    def count(self, key: str) -> int:
        """Number of blocks of kind ``key``."""
        return len(self._starts[key])

    def indices(self, key: str) -> np.ndarray:
        """Every index of kind ``key``, block after block (do not modify the returned array)."""
        ix = self._indices.get(key)
        if ix is None:
            w = self.width(key)
            ix = self._indices[key] = np.array([j + i for j in self._starts[key] for i in range(w)], dtype=int)
        return ix

    def blocks(self, vec: np.ndarray, key: str) -> np.ndarray:
        """The blocks of kind ``key`` of ``vec`` as an array (count, width)."""
        return vec[self.indices(key)].reshape(self.count(key), self.width(key))

    def set_blocks(self, vec: np.ndarray, key: str, values) -> None:
        """Write ``values`` (broadcast to (count, width)) into the blocks of kind ``key`` of ``vec``."""
        vals = np.broadcast_to(np.asarray(values, float), (self.count(key), self.width(key)))
        vec[self.indices(key)] = vals.ravel()

    def shift(self, vec: np.ndarray, stages: int = 1) -> np.ndarray:
        """``vec`` (primal or bound multipliers) moved ``stages`` stages forward per kind.

        The last block is repeated into the freed stages.
        """
        perm = self._shift_perm.get(stages)
        if perm is None:  # the gather index of the shift, built once per number of stages
            perm = np.arange(self.n)
            for key in VAR_KEYS:
                m, w = self.count(key), self.width(key)
                if m == 0 or stages <= 0:
                    continue
                ix = self.indices(key).reshape(m, w)
                perm[ix] = ix[np.minimum(np.arange(m) + stages, m - 1)]
            self._shift_perm[stages] = perm
        return np.asarray(vec)[perm].copy()


class RowLayout:
    """Stage-wise blocks of the constraint vector ``g``.

    Constraints are declared with :meth:`add` in any order and sorted by (stage, order,
    declaration) in :meth:`finalize`, so that each stage of the multiple-shooting NLP starts
    with its gap constraint (the optimal-control structure fatrop needs).
    """

    def __init__(self):
        self._pending: list = []
        self.rows: dict[str, list[np.ndarray]] = {k: [] for k in ROW_KINDS}
        """Row indices of each block, per kind, in stage order (after :meth:`finalize`)."""
        self.n = 0
        """Number of constraint rows (after :meth:`finalize`)."""
        self._shift_perm: dict[int, np.ndarray] = {}

    def add(self, stage: int, order: int, kind: str, expr, lo, hi) -> None:
        """Declare a constraint block lo <= expr <= hi of ``kind`` at ``stage``."""
        if kind not in self.rows:
            raise ValueError(f"unknown constraint kind {kind!r}")
        self._pending.append((stage, order, len(self._pending), kind, expr, list(lo), list(hi)))

    def finalize(self) -> tuple[list, list, list]:
        """Sort the blocks; return (expressions, lower bounds, upper bounds) in row order."""
        exprs, lbg, ubg = [], [], []
        r = 0
        for _, _, _, kind, expr, lo, hi in sorted(self._pending, key=lambda c: c[:3]):
            self.rows[kind].append(np.arange(r, r + expr.numel()))
            r += expr.numel()
            exprs.append(expr)
            lbg.extend(lo)
            ubg.extend(hi)
        self.n = r
        self._pending = []
        self._shift_perm.clear()
        return exprs, lbg, ubg

    def indices(self, kind: str) -> np.ndarray:
        """Every row of ``kind``."""
        blocks = self.rows[kind]
        return np.concatenate(blocks) if blocks else np.zeros(0, dtype=int)

    def shift(self, lam_g: np.ndarray, stages: int = 1) -> np.ndarray:
        """Constraint multipliers moved ``stages`` stages forward per kind (the last block kept)."""
        perm = self._shift_perm.get(stages)
        if perm is None:  # the gather index of the shift, built once per number of stages
            perm = np.arange(self.n)
            for blocks in self.rows.values():
                m = len(blocks)
                for i in range(m - 1):
                    perm[blocks[i]] = blocks[min(i + stages, m - 1)]
            self._shift_perm[stages] = perm
        return np.asarray(lam_g)[perm].copy()
