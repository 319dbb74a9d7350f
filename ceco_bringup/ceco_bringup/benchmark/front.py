"""Savings at matched comfort: the baseline front and where a controller lies against it.

A baseline *family* (the production law at a range of set-points) traces points
(D_j, E_j) in the discomfort-energy plane (D: e.g. ``discomfort_pmvh`` [PMV h],
E: ``energy_kwh`` [kWh]). Method (docs/benchmark.md, "Matched comfort"):

1. Efficient set: the family points no other family point dominates (another
   point with D <= and E <=, one of them strictly). A set-point family traces a
   U (too cold costs energy AND comfort), so its cold branch drops out. Sorted by
   D, the efficient points have strictly decreasing E.
2. Front E_f(D): piecewise-linear interpolation through the efficient points on
   [D_min, D_max] (the set-point is continuous; the segments stand for the
   set-points between the grid). Its inverse D_f(E) on [E_min, E_max].
3. For a controller at (D_c, E_c):

   * ``energy_saving_pct = 100 (E_f(D_c) - E_c) / E_f(D_c)`` (matched comfort),
     defined for D_min <= D_c <= D_max;
   * ``discomfort_reduction_pct = 100 (D_f(E_c) - D_c) / D_f(E_c)`` (matched
     energy), defined for E_min <= E_c <= E_max and D_f(E_c) > 0;
   * ``dominated``: some point of the front has D <= D_c and E <= E_c, one of
     them strictly (relative tolerance :data:`REL_TOL`).

   Outside the ranges nothing is extrapolated: the value is None and ``note``
   says why.

Pure Python + numpy; no ROS, no simulator.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

__all__ = ["REL_TOL", "FrontPoint", "Front", "Matched", "build_front", "match", "match_seeds"]

REL_TOL = 1e-9
"""Relative tolerance of the comparisons (a point on the front is on it, not above)."""

NOTE_MORE_COMFORTABLE = "more comfortable than every efficient baseline (no extrapolation)"
NOTE_LESS_COMFORTABLE = "less comfortable than every efficient baseline (no extrapolation)"
NOTE_MORE_ENERGY = "uses more energy than every efficient baseline (no extrapolation)"
NOTE_LESS_ENERGY = "uses less energy than every efficient baseline (no extrapolation)"
NOTE_ZERO_DISCOMFORT = "the front has zero discomfort at this energy (a reduction in % is undefined)"


@dataclasses.dataclass(frozen=True)
class FrontPoint:
    """One member of a baseline family in the plane."""

    name: str
    """The controller's name, e.g. ``baseline@25.0``."""
    discomfort: float
    """Discomfort D (the front axis' unit, e.g. PMV h)."""
    energy: float
    """Energy E [kWh]."""
    efficient: bool = True
    """True when no other family point dominates it (it is a vertex of the front)."""


@dataclasses.dataclass(frozen=True)
class Front:
    """The efficient baseline front: vertices sorted by increasing D (and decreasing E)."""

    points: tuple
    """All family points (:class:`FrontPoint`), efficient or not, in the order given."""

    @property
    def vertices(self) -> tuple:
        """The efficient points sorted by D (ties in E removed)."""
        return tuple(sorted((p for p in self.points if p.efficient), key=lambda p: (p.discomfort, p.energy)))

    @property
    def d(self) -> np.ndarray:
        """Discomfort of the vertices, increasing."""
        return np.array([p.discomfort for p in self.vertices], dtype=float)

    @property
    def e(self) -> np.ndarray:
        """Energy of the vertices, decreasing."""
        return np.array([p.energy for p in self.vertices], dtype=float)

    def energy_at(self, discomfort: float) -> float | None:
        """E_f(D) by linear interpolation; None outside [D_min, D_max]."""
        d, e = self.d, self.e
        x = float(discomfort)
        if not (_ge(x, d[0]) and _le(x, d[-1])):
            return None
        return float(np.interp(min(max(x, d[0]), d[-1]), d, e))

    def discomfort_at(self, energy: float) -> float | None:
        """D_f(E), the inverse; None outside [E_min, E_max]."""
        d, e = self.d, self.e
        x = float(energy)
        if not (_ge(x, e[-1]) and _le(x, e[0])):
            return None
        # e decreases along the front: interpolate on the reversed arrays
        return float(np.interp(min(max(x, e[-1]), e[0]), e[::-1], d[::-1]))


@dataclasses.dataclass(frozen=True)
class Matched:
    """A controller against a front (module docstring)."""

    energy_saving_pct: float | None
    """Energy saved at matched comfort [%] (positive: less energy than the front); None outside its range."""
    discomfort_reduction_pct: float | None
    """Discomfort reduction at matched energy [%] (positive: more comfortable); None outside its range."""
    dominated: bool
    """True when some point of the front is at least as good on both axes and better on one."""
    note: str = ""
    """Why a value is None ('' when both are defined)."""

    def as_dict(self) -> dict:
        """Plain data for results.json."""
        return dataclasses.asdict(self)


def _close(a: float, b: float) -> bool:
    return abs(a - b) <= REL_TOL * max(abs(a), abs(b), 1e-300)


def _le(a: float, b: float) -> bool:
    return a <= b or _close(a, b)


def _ge(a: float, b: float) -> bool:
    return a >= b or _close(a, b)


def _lt(a: float, b: float) -> bool:
    return a < b and not _close(a, b)


def _finite_point(name, d, e):
    d, e = float(d), float(e)
    if not (math.isfinite(d) and math.isfinite(e)):
        raise ValueError(f"build_front: point {name!r} is not finite (discomfort {d}, energy {e})")
    if d < 0.0 or e < 0.0:
        raise ValueError(f"build_front: point {name!r} is negative (discomfort {d}, energy {e})")
    return d, e


def build_front(points: Mapping[str, tuple] | Iterable[tuple]) -> Front:
    """The front of a family.

    ``points`` is ``{name: (discomfort, energy)}`` or an iterable of ``(name,
    discomfort, energy)``: at least one point, every value finite and >= 0
    (ValueError naming the point). Points equal to an earlier one on both axes are
    kept but only the first is a vertex.
    """
    items = [(k, *v) for k, v in points.items()] if isinstance(points, Mapping) else list(points)
    if not items:
        raise ValueError("build_front: the family has no points")
    pts = [(str(n), *_finite_point(n, d, e)) for n, d, e in items]
    out = []
    for i, (name, d, e) in enumerate(pts):
        dominated = False
        for j, (_, d2, e2) in enumerate(pts):
            if j == i:
                continue
            better_or_equal = _le(d2, d) and _le(e2, e)
            strictly = _lt(d2, d) or _lt(e2, e)
            # an identical earlier point makes this one a duplicate, not a vertex
            if better_or_equal and (strictly or j < i):
                dominated = True
                break
        out.append(FrontPoint(name=name, discomfort=d, energy=e, efficient=not dominated))
    return Front(points=tuple(out))


def _pct(front_value: float, value: float) -> float:
    return 100.0 * (front_value - value) / front_value


def match(front: Front, discomfort: float, energy: float) -> Matched:
    """Where the point (``discomfort``, ``energy``) lies against ``front``."""
    dc, ec = float(discomfort), float(energy)
    if not (math.isfinite(dc) and math.isfinite(ec)):
        raise ValueError(f"match: the controller's point is not finite (discomfort {dc}, energy {ec})")
    d, e = front.d, front.e
    notes = []
    e_f = front.energy_at(dc)
    if e_f is None:
        saving = None
        notes.append(NOTE_MORE_COMFORTABLE if dc < d[0] else NOTE_LESS_COMFORTABLE)
    else:
        saving = _pct(e_f, ec) if e_f > 0.0 else None
    d_f = front.discomfort_at(ec)
    if d_f is None:
        reduction = None
        notes.append(NOTE_MORE_ENERGY if ec > e[0] else NOTE_LESS_ENERGY)
    elif d_f <= 0.0:
        reduction = 0.0 if dc <= 0.0 else None
        if reduction is None:
            notes.append(NOTE_ZERO_DISCOMFORT)
    else:
        reduction = _pct(d_f, dc)
    # dominated: a front point with D <= dc and E <= ec, one strictly
    if _lt(dc, d[0]):
        dominated = False
    else:
        e_ref = front.energy_at(min(dc, d[-1])) if _le(dc, d[-1]) else float(e[-1])
        if _le(dc, d[-1]):
            dominated = _lt(e_ref, ec)
        else:  # beyond the least comfortable vertex: it has strictly less discomfort
            dominated = _le(e_ref, ec)
    return Matched(
        energy_saving_pct=saving, discomfort_reduction_pct=reduction, dominated=bool(dominated), note="; ".join(notes)
    )


def match_seeds(front: Front, points: Sequence[tuple]) -> dict:
    """A controller with one point per seed against a front.

    The match of the mean point (means of discomfort and energy over ``points`` =
    [(discomfort, energy), ...]) and, per seed, the same three quantities. Returns
    ``Matched.as_dict()`` of the mean plus ``seeds``: {energy_saving_pct: [...],
    discomfort_reduction_pct: [...], dominated: [...]} in the order given, and ``n_seeds``.
    """
    if not points:
        raise ValueError("match_seeds: no points")
    arr = np.array([(float(a), float(b)) for a, b in points])
    mean = match(front, float(arr[:, 0].mean()), float(arr[:, 1].mean())).as_dict()
    per = [match(front, a, b) for a, b in arr]
    mean["seeds"] = {
        "energy_saving_pct": [m.energy_saving_pct for m in per],
        "discomfort_reduction_pct": [m.discomfort_reduction_pct for m in per],
        "dominated": [m.dominated for m in per],
    }
    mean["n_seeds"] = len(per)
    return mean
