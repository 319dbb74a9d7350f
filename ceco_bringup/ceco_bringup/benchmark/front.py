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

4. Saturation (docs/benchmark.md, "Saturated discomfort"): PMV enters the
   discomfort clipped to +-3, so a run at or beyond the clip the whole time scores
   the ceiling (:func:`ceco_core.kpis.discomfort_ceiling`, e.g. duration x 2.5 PMV
   for ``discomfort_pmvh``) whatever it does. A front built with that ``ceiling``
   keeps its members at it (within :data:`REL_TOL`) off the vertices (``saturated``:
   they carry no comfort information, so they anchor no match), and a controller at
   it is not matched: both values None, ``note`` :data:`NOTE_SATURATED` (``dominated``
   is still read: a vertex below the ceiling with no more energy beats it). A
   controller with several seeds is not matched at its mean when any seed is
   saturated. A family whose every member is saturated has no vertex: nothing is
   matched against it (:data:`NOTE_NO_VERTEX`).

The strongest of several families (docs/benchmark.md, "Strongest family"): an
:class:`Envelope` of the families' fronts, E_env(D) = min over the families with
D_min,f <= D of E_f(min(D, D_max,f)): the least energy any family spends at a
discomfort of at most D (each family is interpolated only within itself; past its
least comfortable vertex a family keeps that vertex's energy, which meets any looser
level), on [min D_min,f, max D_max,f]; D_env(E) the same for the inverse. A point
is dominated by the envelope exactly when some family's front dominates it. :func:`match` takes a :class:`Front` or an
:class:`Envelope`. :func:`headroom` divides a controller's saving at matched
comfort by the saving of a bound (the whole-drive optimum's front) at the same
discomfort, both against the envelope.

Pure Python + numpy; no ROS, no simulator.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

__all__ = [
    "REL_TOL",
    "NOTE_SATURATED",
    "NOTE_NO_VERTEX",
    "FrontPoint",
    "Front",
    "Envelope",
    "Matched",
    "Headroom",
    "build_front",
    "saturation_ceiling",
    "saturated",
    "match",
    "match_seeds",
    "strongest_by_level",
    "headroom",
    "headroom_seeds",
    "PHASE_KEYS",
    "value_at",
    "by_phase",
]

REL_TOL = 1e-9
"""Relative tolerance of the comparisons (a point on the front is on it, not above)."""

NOTE_MORE_COMFORTABLE = "more comfortable than every efficient baseline (no extrapolation)"
NOTE_LESS_COMFORTABLE = "less comfortable than every efficient baseline (no extrapolation)"
NOTE_MORE_ENERGY = "uses more energy than every efficient baseline (no extrapolation)"
NOTE_LESS_ENERGY = "uses less energy than every efficient baseline (no extrapolation)"
NOTE_ZERO_DISCOMFORT = "the front has zero discomfort at this energy (a reduction in % is undefined)"
NOTE_NO_BOUND = "the bound's front does not cover this discomfort (no extrapolation)"
NOTE_NO_HEADROOM = "the bound saves nothing against the strongest family here (a share of it is undefined)"
NOTE_SATURATED = "not matched: discomfort saturated (PMV at the +-3 clip for the whole run)"
NOTE_NO_VERTEX = "not matched: every baseline's discomfort is saturated (the front has no vertex)"


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
    """True when it is a vertex of the front: not saturated, and no other family point dominates it."""
    saturated: bool = False
    """True when its discomfort is at the front's ``ceiling`` (it carries no comfort information)."""


@dataclasses.dataclass(frozen=True)
class Front:
    """The efficient baseline front: vertices sorted by increasing D (and decreasing E)."""

    points: tuple
    """All family points (:class:`FrontPoint`), efficient or not, in the order given."""
    ceiling: float | None = None
    """The discomfort at which the metric saturates (module docstring, 4.); None: no saturation rule."""

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
        if not d.size or not (_ge(x, d[0]) and _le(x, d[-1])):
            return None
        return float(np.interp(min(max(x, d[0]), d[-1]), d, e))

    def discomfort_at(self, energy: float) -> float | None:
        """D_f(E), the inverse; None outside [E_min, E_max]."""
        d, e = self.d, self.e
        x = float(energy)
        if not e.size or not (_ge(x, e[-1]) and _le(x, e[0])):
            return None
        # e decreases along the front: interpolate on the reversed arrays
        return float(np.interp(min(max(x, e[-1]), e[0]), e[::-1], d[::-1]))

    @property
    def d_range(self) -> tuple[float, float]:
        """(D_min, D_max) of the vertices."""
        d = self.d
        return float(d[0]), float(d[-1])

    @property
    def e_range(self) -> tuple[float, float]:
        """(E_min, E_max) of the vertices."""
        e = self.e
        return float(e[-1]), float(e[0])

    def dominates(self, discomfort: float, energy: float) -> bool:
        """True when a point of the front has D <= ``discomfort`` and E <= ``energy``, one strictly."""
        dc, ec = float(discomfort), float(energy)
        d, e = self.d, self.e
        if not d.size or _lt(dc, d[0]):
            return False
        if _le(dc, d[-1]):
            return _lt(float(self.energy_at(min(dc, d[-1]))), ec)
        return _le(float(e[-1]), ec)  # beyond the least comfortable vertex: it has strictly less discomfort


@dataclasses.dataclass(frozen=True)
class Envelope:
    """The strongest of several families: at each discomfort D the least energy any family spends at <= D.

    E_env(D) = min over the families with D_min,f <= D of E_f(min(D, D_max,f)) on [min D_min,f, max D_max,f]
    (None outside); D_env(E) = min over the families with E_min,f <= E of D_f(min(E, E_max,f)) on
    [min E_min,f, max E_max,f]. Families are interpolated only within themselves (a segment between two
    laws' points stands for no law). Same interface as :class:`Front` for :func:`match`.
    """

    fronts: tuple
    """((family name, :class:`Front`), ...) in a fixed order (ties go to the first); empty when every family's
    members are saturated."""
    ceiling: float | None = None
    """The least ``ceiling`` of the families' fronts (module docstring, 4.); None: no saturation rule."""

    @classmethod
    def of(cls, fronts: Mapping[str, Front | None]) -> Envelope:
        """The envelope of ``{family: Front or None}`` (None and vertex-less fronts are left out).

        ValueError when every value is None; fronts whose every member is saturated give an envelope with no
        family (nothing is matched against it, and its ``d_range`` and ``e_range`` raise).
        """
        given = [f for f in fronts.values() if f is not None]
        if not given:
            raise ValueError("Envelope: no family has a front")
        items = tuple((str(k), f) for k, f in fronts.items() if f is not None and f.vertices)
        ceilings = [f.ceiling for f in given if f.ceiling is not None]
        return cls(fronts=items, ceiling=min(ceilings) if ceilings else None)

    def energy_at(self, discomfort: float) -> float | None:
        """E_env(D); None outside the envelope's discomfort range."""
        best = self._best_energy(discomfort)
        return None if best is None else best[1]

    def family_at(self, discomfort: float) -> str | None:
        """The family whose energy is least at D (the strongest there); None outside the range."""
        best = self._best_energy(discomfort)
        return None if best is None else best[0]

    def _best_energy(self, discomfort):
        x = float(discomfort)
        if not self.fronts or not _le(x, self.d_range[1]):
            return None
        best = None
        for name, f in self.fronts:
            lo, hi = f.d_range
            if not _ge(x, lo):
                continue
            e = f.energy_at(min(max(x, lo), hi))
            if e is not None and (best is None or _lt(e, best[1])):
                best = (name, e)
        return best

    def discomfort_at(self, energy: float) -> float | None:
        """D_env(E); None outside the envelope's energy range."""
        x = float(energy)
        if not self.fronts or not _le(x, self.e_range[1]):
            return None
        vals = []
        for _, f in self.fronts:
            lo, hi = f.e_range
            if _ge(x, lo):
                d = f.discomfort_at(min(max(x, lo), hi))
                if d is not None:
                    vals.append(d)
        return min(vals) if vals else None

    @property
    def d_range(self) -> tuple[float, float]:
        """(least, greatest) discomfort of any family's vertices (ValueError when it has no family)."""
        self._some_family()
        return min(f.d_range[0] for _, f in self.fronts), max(f.d_range[1] for _, f in self.fronts)

    @property
    def e_range(self) -> tuple[float, float]:
        """(least, greatest) energy of any family's vertices (ValueError when it has no family)."""
        self._some_family()
        return min(f.e_range[0] for _, f in self.fronts), max(f.e_range[1] for _, f in self.fronts)

    def _some_family(self) -> None:
        if not self.fronts:
            raise ValueError("Envelope: every family's members are saturated (no vertex)")

    def dominates(self, discomfort: float, energy: float) -> bool:
        """True when some family's front dominates the point."""
        return any(f.dominates(discomfort, energy) for _, f in self.fronts)

    def front_of(self, family: str) -> Front:
        """The front of ``family`` (KeyError if the envelope has none of that name)."""
        for name, f in self.fronts:
            if name == family:
                return f
        raise KeyError(family)


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


def build_front(points: Mapping[str, tuple] | Iterable[tuple], ceiling: float | None = None) -> Front:
    """The front of a family.

    ``points`` is ``{name: (discomfort, energy)}`` or an iterable of ``(name,
    discomfort, energy)``: at least one point, every value finite and >= 0
    (ValueError naming the point). Points equal to an earlier one on both axes are
    kept but only the first is a vertex. ``ceiling``: the discomfort at which the
    metric saturates (:func:`saturation_ceiling`; finite, > 0); the points at it are
    ``saturated`` and never vertices (module docstring, 4.).
    """
    items = [(k, *v) for k, v in points.items()] if isinstance(points, Mapping) else list(points)
    if not items:
        raise ValueError("build_front: the family has no points")
    if ceiling is not None:
        ceiling = float(ceiling)
        if not (math.isfinite(ceiling) and ceiling > 0.0):
            raise ValueError(f"build_front: the ceiling must be finite and > 0, got {ceiling}")
    pts = [(str(n), *_finite_point(n, d, e)) for n, d, e in items]
    sat = [ceiling is not None and _ge(d, ceiling) for _, d, _ in pts]
    out = []
    for i, (name, d, e) in enumerate(pts):
        dominated = sat[i]
        for j, (_, d2, e2) in enumerate(pts):
            if dominated:
                break
            if j == i:
                continue
            better_or_equal = _le(d2, d) and _le(e2, e)
            strictly = _lt(d2, d) or _lt(e2, e)
            # an identical earlier point makes this one a duplicate, not a vertex
            if better_or_equal and (strictly or j < i):
                dominated = True
                break
        out.append(FrontPoint(name=name, discomfort=d, energy=e, efficient=not dominated, saturated=sat[i]))
    return Front(points=tuple(out), ceiling=ceiling)


def saturation_ceiling(runs_kpis: Iterable[Mapping], axis: str) -> float | None:
    """The ceiling of the discomfort KPI ``axis`` for a case's runs (``runs_kpis``: their kpis dicts).

    The least :func:`ceco_core.kpis.discomfort_ceiling` over the runs that have one (a case's runs share a
    length; a shorter run's ceiling is the stricter); None when none has (no saturation rule).
    """
    from ceco_core.kpis import discomfort_ceiling

    got = [c for c in (discomfort_ceiling(k, axis) for k in runs_kpis) if c is not None and c > 0.0]
    return min(got) if got else None


def saturated(front: Front | Envelope, discomfort: float) -> bool:
    """True when ``discomfort`` is at (or, within :data:`REL_TOL`, beyond) the ceiling of ``front``."""
    return front.ceiling is not None and _ge(float(discomfort), front.ceiling)


def _pct(front_value: float, value: float) -> float:
    return 100.0 * (front_value - value) / front_value


def match(front: Front | Envelope, discomfort: float, energy: float) -> Matched:
    """Where the point (``discomfort``, ``energy``) lies against ``front`` (:class:`Front` or :class:`Envelope`)."""
    dc, ec = float(discomfort), float(energy)
    if not (math.isfinite(dc) and math.isfinite(ec)):
        raise ValueError(f"match: the controller's point is not finite (discomfort {dc}, energy {ec})")
    if saturated(front, dc):
        return Matched(None, None, dominated=bool(front.dominates(dc, ec)), note=NOTE_SATURATED)
    if not _has_vertex(front):
        return Matched(None, None, dominated=False, note=NOTE_NO_VERTEX)
    d_lo, e_hi = front.d_range[0], front.e_range[1]
    notes = []
    e_f = front.energy_at(dc)
    if e_f is None:
        saving = None
        notes.append(NOTE_MORE_COMFORTABLE if dc < d_lo else NOTE_LESS_COMFORTABLE)
    else:
        saving = _pct(e_f, ec) if e_f > 0.0 else None
    d_f = front.discomfort_at(ec)
    if d_f is None:
        reduction = None
        notes.append(NOTE_MORE_ENERGY if ec > e_hi else NOTE_LESS_ENERGY)
    elif d_f <= 0.0:
        reduction = 0.0 if dc <= 0.0 else None
        if reduction is None:
            notes.append(NOTE_ZERO_DISCOMFORT)
    else:
        reduction = _pct(d_f, dc)
    return Matched(
        energy_saving_pct=saving,
        discomfort_reduction_pct=reduction,
        dominated=bool(front.dominates(dc, ec)),
        note="; ".join(dict.fromkeys(notes)),
    )


def dominates_front(m: Mapping | None) -> bool:
    """Whether a match (:meth:`Matched.as_dict`) is of a point better on both axes than every efficient point.

    More comfortable *and* using less energy than each: the best outcome, yet with no matched value (no
    extrapolation); the words of the verdict and the benchmark report say so instead of a bare n/a.
    """
    note = str((m or {}).get("note") or "")
    return NOTE_MORE_COMFORTABLE in note and NOTE_LESS_ENERGY in note


def _has_vertex(front: Front | Envelope) -> bool:
    return bool(front.fronts if isinstance(front, Envelope) else front.vertices)


def _saturated_mean(front: Front | Envelope, arr: np.ndarray) -> Matched | None:
    """The mean point's match when a seed is saturated (its discomfort is only a lower bound), else None."""
    if not any(saturated(front, d) for d in arr[:, 0]):
        return None
    return Matched(
        None,
        None,
        dominated=bool(front.dominates(float(arr[:, 0].mean()), float(arr[:, 1].mean()))),
        note=NOTE_SATURATED,
    )


def match_seeds(front: Front | Envelope, points: Sequence[tuple]) -> dict:
    """A controller with one point per seed against a front.

    The match of the mean point (means of discomfort and energy over ``points`` =
    [(discomfort, energy), ...]; not matched, :data:`NOTE_SATURATED`, when a seed is
    saturated) and, per seed, the same three quantities. Returns
    ``Matched.as_dict()`` of the mean plus ``seeds``: {energy_saving_pct: [...],
    discomfort_reduction_pct: [...], dominated: [...]} in the order given, and ``n_seeds``.
    """
    if not points:
        raise ValueError("match_seeds: no points")
    arr = np.array([(float(a), float(b)) for a, b in points])
    mean = (_saturated_mean(front, arr) or match(front, float(arr[:, 0].mean()), float(arr[:, 1].mean()))).as_dict()
    return _with_seeds(
        mean, [match(front, a, b) for a, b in arr], ("energy_saving_pct", "discomfort_reduction_pct", "dominated")
    )


def _with_seeds(mean: dict, per: Sequence, keys: Sequence[str]) -> dict:
    """``mean`` plus ``seeds`` ({key: [the per-seed values]}) and ``n_seeds``."""
    mean["seeds"] = {k: [getattr(m, k) for m in per] for k in keys}
    mean["n_seeds"] = len(per)
    return mean


def strongest_by_level(envelope: Envelope, levels: Sequence[float]) -> dict:
    """Which family is the strongest at each discomfort level, and overall.

    Returns ``{'levels': [{'discomfort', 'family', 'energy'}, ...], 'family': name}``: per level the
    family whose front is lowest there (``None`` where no front covers it), and the family that is the
    strongest at the most levels (ties: the envelope's order); ``family`` is None when no level is covered.
    """
    rows = []
    counts: dict = {}
    for x in levels:
        fam = envelope.family_at(x)
        rows.append({"discomfort": float(x), "family": fam, "energy": envelope.energy_at(x)})
        if fam is not None:
            counts[fam] = counts.get(fam, 0) + 1
    order = [name for name, _ in envelope.fronts]
    best = max(order, key=lambda n: (counts.get(n, 0), -order.index(n))) if counts else None
    return {"levels": rows, "family": best}


@dataclasses.dataclass(frozen=True)
class Headroom:
    """A controller's saving as a share of a bound's saving, both at its discomfort against the envelope."""

    headroom_captured: float | None
    """(E_env(D_c) - E_c) / (E_env(D_c) - E_bound(D_c)) [-]: 1 = all the bound's saving, 0 = none,
    < 0 = more energy than the strongest family; None where undefined (``note``)."""
    saving_pct: float | None
    """The controller's energy saving against the envelope at D_c [%]."""
    bound_saving_pct: float | None
    """The bound's energy saving against the envelope at D_c [%]."""
    strongest: str | None
    """The family the envelope takes its energy from at D_c."""
    note: str = ""
    """Why a value is None ('' when all are defined)."""

    def as_dict(self) -> dict:
        """Plain data for results.json."""
        return dataclasses.asdict(self)


def headroom(envelope: Envelope, bound: Front | Sequence[Front], discomfort: float, energy: float) -> Headroom:
    """``headroom_captured`` of the point (``discomfort``, ``energy``) (module docstring).

    ``bound`` is the optimum's front, or several (one per seed of an uncertain case): then
    E_bound(D) is their mean at D (None unless every one covers D). The ratio is undefined (None,
    with a note) outside the envelope's or the bound's range, and where the bound saves nothing
    (E_bound(D_c) >= E_env(D_c)), and at the envelope's ceiling (:data:`NOTE_SATURATED`).
    """
    dc, ec = float(discomfort), float(energy)
    if not (math.isfinite(dc) and math.isfinite(ec)):
        raise ValueError(f"headroom: the controller's point is not finite (discomfort {dc}, energy {ec})")
    bounds = [bound] if isinstance(bound, Front) else list(bound)
    if not bounds:
        raise ValueError("headroom: no bound front")
    if saturated(envelope, dc):
        return Headroom(None, None, None, None, NOTE_SATURATED)
    if not envelope.fronts:
        return Headroom(None, None, None, None, NOTE_NO_VERTEX)
    e_env = envelope.energy_at(dc)
    fam = envelope.family_at(dc)
    if e_env is None or e_env <= 0.0:
        note = NOTE_MORE_COMFORTABLE if dc < envelope.d_range[0] else NOTE_LESS_COMFORTABLE
        return Headroom(None, None, None, fam, note)
    saving = _pct(e_env, ec)
    e_b = [b.energy_at(dc) for b in bounds]
    if any(x is None for x in e_b):
        return Headroom(None, saving, None, fam, NOTE_NO_BOUND)
    e_bound = float(np.mean(e_b))
    bound_saving = _pct(e_env, e_bound)
    if not _lt(e_bound, e_env):
        return Headroom(None, saving, bound_saving, fam, NOTE_NO_HEADROOM)
    return Headroom((e_env - ec) / (e_env - e_bound), saving, bound_saving, fam, "")


def headroom_seeds(envelope: Envelope, bounds: Mapping, points: Sequence[tuple]) -> dict:
    """``headroom_captured`` of a controller with one point per seed.

    ``bounds`` maps a seed to the bound's front (key None: one bound for every seed); ``points`` =
    [(seed, discomfort, energy), ...], seed None for a seed-invariant controller, which is compared with
    the mean of every bound. The mean entry is the controller's seed-mean point against the mean of the
    bounds of its seeds (not matched, :data:`NOTE_SATURATED`, when a seed is saturated); ``seeds`` lists
    :func:`headroom` per point. A seed without a bound gives None with a note.
    """
    if not points:
        raise ValueError("headroom_seeds: no points")
    used = [_bounds_of(bounds, s) for s, _, _ in points]
    per = [
        headroom(envelope, b, d, e) if b else Headroom(None, None, None, None, f"no bound for seed {seed}")
        for (seed, d, e), b in zip(points, used)
    ]
    arr = np.array([(float(d), float(e)) for _, d, e in points])
    if any(saturated(envelope, d) for _, d, _ in points):
        mean = Headroom(None, None, None, None, NOTE_SATURATED).as_dict()
    elif all(used):
        every = [f for b in used for f in b]
        mean = headroom(envelope, every, float(arr[:, 0].mean()), float(arr[:, 1].mean())).as_dict()
    else:
        mean = Headroom(None, None, None, None, "a seed has no bound").as_dict()
    return _with_seeds(mean, per, ("headroom_captured", "saving_pct", "bound_saving_pct"))


def _bounds_of(bounds: Mapping, seed) -> list:
    """The bound fronts a point of ``seed`` is read against (:func:`_seeded`)."""
    return [b for _, b in _seeded(bounds, seed)]


PHASE_KEYS = (
    "energy_kwh",
    "energy_band_kwh",
    "pmv_mean_band",
    "pmv_above_band_s",
    "t_evap_sp_mean_band_c",
    "mdot_bl_mean_band_kgps",
)
"""The KPIs :func:`by_phase` reads (ceco_core.kpis: the whole run's energy, and the band phase's energy, mean
and time above the band of PMV, mean coil set-point and blower flow)."""


def value_at(front: Front, discomfort: float, values: Mapping[str, float | None]) -> float | None:
    """A quantity known at the front's vertices (``values``: vertex name -> value), read at D as the energy is.

    Linear between the two vertices around D, with D held to the front's range (as the envelope holds a
    family past its least comfortable vertex); None when one of those two has no value (a vertex farther
    away does not matter).
    """
    d, names = front.d, [p.name for p in front.vertices]
    x = min(max(float(discomfort), d[0]), d[-1])
    if d.size == 1:
        v = values.get(names[0])
        return None if v is None else float(v)
    i = int(np.clip(np.searchsorted(d, x, side="right") - 1, 0, d.size - 2))
    a, b = values.get(names[i]), values.get(names[i + 1])
    if a is None or b is None:
        return None
    return float(a + (x - d[i]) / (d[i + 1] - d[i]) * (b - a))


def _mean_or_none(xs: Sequence) -> float | None:
    return None if not xs or any(x is None for x in xs) else float(np.mean(xs))


def by_phase(
    envelope: Envelope,
    bounds: Mapping,
    points: Sequence[tuple],
    member_kpis: Mapping[str, Mapping],
    bound_kpis: Mapping,
    keys: Sequence[str] = PHASE_KEYS,
) -> dict:
    """Where a controller's and the bound's savings sit: the band phase against the whole run.

    ``points`` = [(seed, discomfort, the controller's kpis), ...]; ``member_kpis`` maps every family member (the
    envelope's vertex names) to its kpis; ``bound_kpis`` maps a seed (as ``bounds``) to {vertex name: kpis} of
    its bound. At each point's discomfort D the strongest family's front and the bound's (the mean over the
    seed's bounds, as :func:`headroom`) are read by :func:`value_at` for each of ``keys``: what the strongest
    law and the optimum do at the controller's comfort. Returns ``{'controller', 'strongest', 'bound'}``
    ({key: mean over the points}, a mean None where a point's value is None: outside a front, or a KPI
    undefined), ``families`` (the strongest family at each point) and ``n_seeds``.
    """
    if not points:
        raise ValueError("by_phase: no points")
    rows: dict = {"controller": [], "strongest": [], "bound": []}
    families = []
    for seed, d, kpis in points:
        fam = envelope.family_at(d)
        families.append(fam)
        rows["controller"].append({k: kpis.get(k) for k in keys})
        if fam is None:
            rows["strongest"].append(dict.fromkeys(keys))
        else:
            front = envelope.front_of(fam)
            rows["strongest"].append(
                {k: value_at(front, d, {n: (member_kpis.get(n) or {}).get(k) for n in member_kpis}) for k in keys}
            )
        got = dict.fromkeys(keys)
        pairs = [(b, bound_kpis.get(s)) for s, b in _seeded(bounds, seed)]
        if pairs and all(b.energy_at(d) is not None and kp is not None for b, kp in pairs):
            got = {
                k: _mean_or_none([value_at(b, d, {n: v.get(k) for n, v in kp.items()}) for b, kp in pairs])
                for k in keys
            }
        rows["bound"].append(got)
    out: dict = {who: {k: _mean_or_none([r[k] for r in rs]) for k in keys} for who, rs in rows.items()}
    out["families"] = families
    out["n_seeds"] = len(points)
    return out


def _seeded(bounds: Mapping, seed) -> list:
    """(key, front) of the bounds a point of ``seed`` is read against.

    Its seed's, else the seed-invariant one (key None); a seed-invariant point (seed None) against every bound.
    """
    if seed in bounds:
        return [(seed, bounds[seed])]
    if None in bounds:
        return [(None, bounds[None])]
    return list(bounds.items()) if seed is None else []
