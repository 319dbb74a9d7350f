"""The verdict of a job: energy and comfort of each strategy, and the saving at matched comfort.

Which strategy used how much energy at what comfort, whether the baseline reached the comfort
band, and the energy saved at matched comfort against a family of baseline set-points.

A comparison against the one baseline run (the production law at 26 degC) compares at different
comfort: on SC03 that baseline never reaches the comfort band, every CECO strategy does, so "+10 %
energy" says little. The fair number is the saving at matched comfort (docs/benchmark.md,
"Matched comfort"): the production law and the same law with tuned gains, each at a few
set-points, trace fronts in the discomfort-energy plane, and each strategy is read against the
lower of the two at its own discomfort (their envelope).

* :func:`run_point`: a run's point in the plane and what the verdict says about it, from its
  ``timeseries.csv`` columns (``ceco_core.kpis.compute_kpis``: energy ``energy_kwh`` =
  compressor + blower + condenser fan [kWh], discomfort ``discomfort_pmvh`` = PMV-hours outside
  ISO 7730 category B, -0.5..+0.5, PMV clipped at +-3 [PMV h]);
* :func:`run_family`: the production and the tuned law (:data:`FAMILY_LAWS`) at
  :data:`FAMILY_SETPOINTS_C` with the in-process simulator (``closed_loop.simulate``; the same
  plant and scenario as a DDS run, which equals it: ``python -m ceco_bringup.compare_sim``); with a
  strategy that moves the recirculation door in the job (:func:`moves_door`: ``ceco-pmv-aq``), the same
  laws with its CO2-holding door too (:data:`DOOR_FAMILY_LAWS`): each strategy is read against the laws
  given the same actuators (:func:`comparable_family`);
* :func:`build_verdict` / :func:`verdict_lines`: the numbers and the words; a run that broke the scenario's
  air-quality limits (CO2 limit, fog margin bound: ``ceco_core.kpis.breaks_air_quality``, the benchmark's rule)
  is said to have broken them and is never matched (no saving), and a family member that broke them is on no
  front;
  :func:`write_verdict` / :func:`read_verdict`: ``verdict.json``.

Signs: ``energy_saving_pct`` positive = less energy than the front at the same discomfort;
``energy_change_pct`` / ``discomfort_change_pct`` = signed change against the baseline run as
measured (positive = more).

Pure Python + numpy (the simulator only in :func:`run_family`); no ROS import.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ceco_bringup.benchmark.schema import DOOR_CO2_HOLD, door_family
from ceco_bringup.report_html import fmt_value
from ceco_core.air_quality import AirQualityLimits
from ceco_core.kpis import AIR_QUALITY_KEYS, air_limit_entries, breaks_air_quality
from ceco_core.metrics import COMFORT_HOLD_S, ENERGY_PARTS, relative_change_pct

__all__ = [
    'FAMILY_SETPOINTS_C',
    'FAMILY_LAWS',
    'DOOR_FAMILY_LAWS',
    'family_law',
    'moves_door',
    'family_laws_for',
    'comparable_family',
    'DISCOMFORT_KEY',
    'ENERGY_KEY',
    'VERDICT_SCHEMA',
    'FAILED_KEY',
    'reason_line',
    'run_point',
    'run_family',
    'matched',
    'Verdict',
    'build_verdict',
    'verdict_lines',
    'write_verdict',
    'read_verdict',
]

FAMILY_SETPOINTS_C = (24.0, 24.5, 25.0, 25.5, 26.0, 26.5, 27.0)
"""Cabin set-points of the baseline family run with every job [degC]: the production law's 26 degC
(the paper's baseline) and 0.5-K steps around it, more of them colder because the CECO strategies
hold the cabin cooler than 26 degC does. 0.5 K as the benchmark's grid: on SC03 the front through
1-K steps missed the set-points between them by up to 2.4 % of energy, through 0.5-K steps by up to
0.56 % (:data:`RESOLUTION_PCT`). ``ceco benchmark`` runs 22-29 degC and the allowance variants
(docs/benchmark.md)."""

FAMILY_LAWS = ('baseline', 'baseline-tuned')
"""The laws of the family run with every job, each at :data:`FAMILY_SETPOINTS_C`: the production law
(the paper's baseline, production gains) and the same law with the gains the benchmark tuned
(``ceco_bringup/data/benchmark/baselines.yaml``, family ``tuned``). The sluggish production
gains alone cost 5-10 % of energy on the hot cases (docs/results.md), so a saving against them is
mostly the baseline's tuning: the verdict's headline is against the stronger of the two at each
discomfort (:func:`matched`), the production law's number is shown beside it (the paper's comparison).
``ceco benchmark`` adds the comfort-feedback (PMV) families and the whole-drive optimum."""

DOOR_FAMILY_LAWS = tuple(door_family(law, DOOR_CO2_HOLD) for law in FAMILY_LAWS)
"""The laws of :data:`FAMILY_LAWS` with the CO2-holding recirculation door of ``ceco-pmv-aq`` behind them
(``door_mode: co2_hold``, ``ceco_core.co2_door``; named as the benchmark's ``*-doorco2`` families:
``baseline-doorco2``, ``baseline-tuned-doorco2``): the family a strategy that moves the door is read against, so
that both sides may move it (issue 21)."""

_DOOR_SUFFIX = door_family('', DOOR_CO2_HOLD)
"""Name suffix of a family law with the CO2-holding door (``-doorco2``)."""

RESOLUTION_PCT = 1.0
"""Savings at matched comfort smaller than this are reported as "the same energy" [%]: the front is
linear between set-points 0.5 K apart, and on SC03 the production law at the set-points between
them (24.75-26.75 degC) lay up to 0.56 % below it."""

DISCOMFORT_KEY = 'discomfort_pmvh'
"""The discomfort axis of the plane (a ``compute_kpis`` key) [PMV h]."""

ENERGY_KEY = 'energy_kwh'
"""The energy axis of the plane (a ``compute_kpis`` key) [kWh]."""

VERDICT_SCHEMA = 'ceco-verdict/2'
"""The ``schema`` of ``verdict.json``."""

END_WINDOW_S = 60.0
"""Length of the end of a run whose mean PMV the verdict quotes [s]."""

FAILED_KEY = 'failed'
"""The one key of a family member of :func:`run_family` that has no result: why it failed."""

POINT_KEYS = (
    'energy_kwh',
    'energy_comp_kwh',
    'energy_blower_kwh',
    'energy_fan_kwh',
    'discomfort_pmvh',
    'time_to_comfort_s',
    'i_pmv_clipped',
    'otc_violation_pct',
    'iso7730_invalid_pct',
    'fog_margin_min_k',
    *AIR_QUALITY_KEYS,
)


AFTER_COMFORT_KEYS = ('pmv_out_after_comfort_s', 'pmv_left_band_s')
"""Keys of :func:`run_point` on the PMV after ``time_to_comfort_s`` [s]: the time outside -0.5..+0.5 from then to the
end, and the start (since the run's start) of the stretch outside it the run ends in (None when the run ends inside).
Both None when the PMV never stayed in the band for 60 s. Absent from an older ``verdict.json``."""

ISO_INVALID_SAY_PCT = 10.0
"""A run whose PMV is outside ISO 7730's validity (``iso7730_invalid_pct``: a PMV input or the PMV outside the
standard's Clause 4 ranges) for more than this share of its samples is said to be so in the verdict lines [%]. One
sample in ten: below it the samples outside (the first seconds of a pull-down, a short excursion) weigh little in the
numbers the verdict quotes; above it the discomfort, the time in the band or the end PMV rest on PMV values the
standard does not cover (SC03's hot start: 27 %; a met of 0.01: every sample)."""


def run_point(columns: Mapping, air_limits: AirQualityLimits | None = None) -> dict:
    """A run's point in the plane and what the verdict says about it.

    :data:`POINT_KEYS` of ``compute_kpis`` plus ``pmv_end`` (mean PMV over the last
    :data:`END_WINDOW_S`; the whole run when it is shorter), ``pmv_max_clipped`` (max PMV on the +-3 scale),
    ``duration_s`` and :data:`AFTER_COMFORT_KEYS`.
    The air-quality KPIs are scored against ``air_limits`` (the scenario's); None: not scored (limits unknown).
    """
    from ceco_core.kpis import compute_kpis
    from ceco_core.metrics import PMV_SCALE_LIMIT

    k, _ = compute_kpis(columns, air_limits=air_limits)
    if air_limits is None:
        k.update(dict.fromkeys(AIR_QUALITY_KEYS))
    t = np.asarray(columns['t_s'], dtype=float)
    y = np.asarray(columns['pmv'], dtype=float)
    end = t >= t[-1] - END_WINDOW_S + 1e-9
    out = {key: k[key] for key in POINT_KEYS}
    out['pmv_end'] = float(np.mean(y[end]))
    out['pmv_max_clipped'] = float(min(np.max(y), PMV_SCALE_LIMIT))
    out['duration_s'] = float(k['duration_s'])
    out.update(_after_comfort(t, y, k['time_to_comfort_s']))
    return out


def _after_comfort(t: np.ndarray, y: np.ndarray, ttc: float | None) -> dict:
    """Where the PMV ``y`` went after ``time_to_comfort_s`` ``ttc``: :data:`AFTER_COMFORT_KEYS` (None when ``ttc`` is).

    Outside the band = the discomfort KPI's test (``ceco_core.kpis.pmv_band_distance`` > 0, the band
    ``COMFORT_BAND_PMV``, -0.5..+0.5, that ``time_to_comfort_s`` and ``discomfort_pmvh`` use).
    """
    from ceco_core.kpis import COMFORT_BAND_PMV, pmv_band_distance

    if ttc is None or not math.isfinite(float(ttc)):
        return dict.fromkeys(AFTER_COMFORT_KEYS)
    dt = float(t[1] - t[0])
    i0 = int(np.argmin(np.abs(t - t[0] - float(ttc))))  # the sample time_to_comfort_s names
    outside = pmv_band_distance(y[i0:], COMFORT_BAND_PMV) > 0.0
    left = None
    if outside[-1]:  # the run ends outside: from the sample after its last one inside
        left = float(t[i0 + int(np.flatnonzero(~outside)[-1]) + 1] - t[0])
    return {'pmv_out_after_comfort_s': float(np.count_nonzero(outside) * dt), 'pmv_left_band_s': left}


def family_law(member: str) -> str:
    """The law of a family member's name: ``'baseline-tuned@25.0'`` -> ``'baseline-tuned'``."""
    return member.split('@', 1)[0]


def moves_door(strategy: str) -> bool:
    """Whether ``strategy`` commands the recirculation door.

    A named variant with a door control does (``ceco-pmv-aq``, ``ceco-pmv-door``;
    ``ceco_core.contracts.STRATEGY_VARIANTS``).
    """
    from ceco_core.contracts import strategy_variant

    return dict(strategy_variant(strategy)[1]).get('door_control', 'none') != 'none'


def family_laws_for(strategies: Sequence[str]) -> tuple[str, ...]:
    """The laws a job's family runs.

    :data:`FAMILY_LAWS`, and :data:`DOOR_FAMILY_LAWS` when a strategy of the job moves the door.
    """
    return FAMILY_LAWS + (DOOR_FAMILY_LAWS if any(moves_door(s) for s in strategies) else ())


def comparable_family(family: Mapping[str, Mapping], strategy: str) -> dict:
    """The members of ``family`` whose law has the actuators ``strategy`` has.

    The door laws for a strategy that moves the door, the others else. A family without door laws (kept from an
    older job) is returned whole for a strategy without the door and empty for one with it (no comparison on
    unequal terms).
    """
    door = moves_door(strategy)
    return {n: p for n, p in family.items() if family_law(n).endswith(_DOOR_SUFFIX) == door}


def _law_overrides(law: str) -> tuple:
    """AccSettings and door overrides of a family law besides its set-point.

    The laws: :data:`FAMILY_LAWS`, :data:`DOOR_FAMILY_LAWS`.
    """
    from ceco_bringup.benchmark import runner

    base = law.removesuffix(_DOOR_SUFFIX)
    door = runner.door_overrides(DOOR_CO2_HOLD) if base != law else {}
    if base == 'baseline':
        return tuple(sorted(door.items()))
    if base == 'baseline-tuned':
        return tuple(sorted({**runner.load_baselines().families['tuned'][0], **door}.items()))
    raise ValueError(f'family law: one of {FAMILY_LAWS + DOOR_FAMILY_LAWS}, got {law!r}')


def run_family(
    scenario,
    *,
    duration_s: float | None = None,
    control_period_s: float | None = None,
    setpoints_c: Sequence[float] = FAMILY_SETPOINTS_C,
    laws: Sequence[str] = FAMILY_LAWS,
    progress: bool = True,
    overrides: tuple = (),
) -> dict[str, dict]:
    """Each law of ``laws`` at each set-point on ``scenario``, in-process: ``{'baseline@24.0': point, ...}``.

    ``scenario`` is a Scenario or a bundled name / YAML path; ``duration_s`` and ``control_period_s``
    as the job's (None: the scenario's). Members are named ``LAW@SETPOINT`` (:func:`family_law`).
    ``overrides``: ``((field, value), ...)`` of the baseline's settings every member gets (e.g. a case's door).

    A member whose simulation stopped (the plant left its refrigerant model:
    ``ceco_plant_sim.plant_ops.PlantStepError``) is no point: it is ``{FAILED_KEY: 'why'}``, which
    :func:`build_verdict` keeps off the fronts and names (``Verdict.family_failed``).
    """
    from ceco_controller.closed_loop import SimSettings, simulate
    from ceco_plant_sim.plant_ops import PlantStepError
    from ceco_v2x_preview.scenario import load_scenario

    if isinstance(scenario, str):
        scenario = load_scenario(scenario)
    items = [(law, float(x)) for law in laws for x in setpoints_c]
    law_overrides = {law: _law_overrides(law) for law in laws}
    if progress:
        from tqdm import tqdm

        items = tqdm(items, desc='baseline family (in-process)', unit='run', leave=False)
    out = {}
    for law, sp in items:
        settings = SimSettings(
            control_period_s=control_period_s,
            duration_s=duration_s,
            progress=False,
            strategy_overrides=tuple(sorted({**dict(overrides), **dict(law_overrides[law]), 'setpoint_c': sp}.items())),
        )
        try:
            res = simulate(scenario, 'baseline', settings)
        except PlantStepError as exc:  # the plant left its model: this set-point has no result
            out[f'{law}@{sp:.1f}'] = {FAILED_KEY: exc.run_error}
            continue
        out[f'{law}@{sp:.1f}'] = run_point(res.timeseries, scenario.air_quality.limits)
    return out


def matched(family: Mapping[str, Mapping], point: Mapping, *, law: str | None = None) -> dict:
    """Where ``point`` lies against the family: ``front.Matched.as_dict()``.

    Energy saved at matched comfort [%], discomfort cut at matched energy [%], dominated, note. The
    family's laws (:func:`family_law`) each make a front; ``point`` is read against their envelope
    (at each discomfort the least energy any law spends: ``front.Envelope``), or against the one
    law ``law``.
    """
    from ceco_bringup.benchmark import front

    ceiling = front.saturation_ceiling([point, *family.values()], DISCOMFORT_KEY)
    by_law: dict[str, dict] = {}
    for n, p in family.items():
        by_law.setdefault(family_law(n), {})[n] = (p[DISCOMFORT_KEY], p[ENERGY_KEY])
    if law is not None:
        return front.match(front.build_front(by_law[law], ceiling), point[DISCOMFORT_KEY], point[ENERGY_KEY]).as_dict()
    env = front.Envelope.of({k: front.build_front(v, ceiling) for k, v in by_law.items()})
    return front.match(env, point[DISCOMFORT_KEY], point[ENERGY_KEY]).as_dict()


@dataclasses.dataclass
class Verdict:
    """The numbers behind the verdict lines (and ``verdict.json``)."""

    scenario: str
    """Scenario name."""
    duration_s: float
    """Run length [s]."""
    points: dict
    """{strategy: run_point(...)} of the job's runs, in the job's order."""
    baseline: str | None = None
    """The job's baseline run (``baseline``), None when the job ran none."""
    family: dict = dataclasses.field(default_factory=dict)
    """{'baseline@S': run_point(...)} of the family; empty when not computed."""
    family_source: str = ''
    """How the family was run (e.g. 'in-process simulator')."""
    family_file: str = ''
    """The ``verdict.json`` the family was read from ('' when it was run for this verdict)."""
    partial: dict = dataclasses.field(default_factory=dict)
    """{strategy: 'why'} of runs that did not finish (shown, never matched)."""
    matched: dict = dataclasses.field(default_factory=dict)
    """{strategy: matched(...)} for every complete run (with a family): against the envelope of the family's laws."""
    matched_by_law: dict = dataclasses.field(default_factory=dict)
    """{law: {strategy: matched(..., law=law)}} when the family has more than one law."""
    changes: dict = dataclasses.field(default_factory=dict)
    """{strategy: {'energy_change_pct', 'discomfort_change_pct'}} against the baseline run."""
    air_limits: dict = dataclasses.field(default_factory=dict)
    """The limits the runs' air quality was scored against (``co2_limit_ppm`` [ppm], ``fog_margin_bound_k`` [K];
    ``ceco_core.kpis.AIR_LIMIT_KEYS``); empty: not scored."""
    air_quality_broken: list = dataclasses.field(default_factory=list)
    """The strategies whose run broke the air-quality limits (``air_quality_met`` 0): never matched, no saving."""
    failed: dict = dataclasses.field(default_factory=dict)
    """{strategy: 'why'} of the job's runs that failed (``ceco_core.run_status``; the plant left its model): no
    point, no number, named."""
    family_failed: dict = dataclasses.field(default_factory=dict)
    """{'baseline@S': 'why'} of the family members whose run failed (:func:`run_family`): on no front, named."""

    def as_dict(self) -> dict:
        """Plain data for ``verdict.json``."""
        return {'schema': VERDICT_SCHEMA, 'energy': ENERGY_PARTS, **dataclasses.asdict(self)}


def build_verdict(
    scenario: str,
    points: Mapping[str, Mapping],
    family: Mapping[str, Mapping] | None = None,
    *,
    family_source: str = 'in-process simulator',
    family_file: str = '',
    partial: Mapping[str, str] | None = None,
    air_limits: AirQualityLimits | None = None,
    failed: Mapping[str, str] | None = None,
) -> Verdict:
    """The verdict of a job's runs (``points``: {strategy: run_point}) against a family (or none).

    ``air_limits``: the limits the points' air quality was scored against (:func:`run_point`), recorded in the
    verdict. A run that broke them (``ceco_core.kpis.breaks_air_quality``) is not matched, and a family member
    that broke them is on no front (the benchmark's rule). ``failed``: {strategy: 'why'} of the job's runs that
    failed (no point: named, never a number); a family member that failed (:data:`FAILED_KEY`) is on no front,
    named.
    """
    partial = dict(partial or {})
    base = 'baseline' if 'baseline' in points else None
    family_failed = {k: str(p[FAILED_KEY]) for k, p in (family or {}).items() if FAILED_KEY in p}
    family = {k: p for k, p in (family or {}).items() if FAILED_KEY not in p}
    v = Verdict(
        scenario=scenario,
        duration_s=max((float(p['duration_s']) for p in points.values()), default=0.0),
        points={k: dict(p) for k, p in points.items()},
        baseline=base,
        family={k: dict(p) for k, p in (family or {}).items()},
        family_source=family_source if family else '',
        family_file=family_file if family else '',
        partial=partial,
        air_limits=air_limit_entries(air_limits) if air_limits is not None else {},
        failed=dict(failed or {}),
        family_failed=family_failed,
    )
    v.air_quality_broken = [n for n, p in points.items() if n not in partial and breaks_air_quality(p)]
    for name, p in points.items():
        if name in partial:
            continue
        whole = comparable_family(v.family, name)
        fam = {n: q for n, q in whole.items() if not breaks_air_quality(q)}
        if name in v.air_quality_broken:
            pass  # a saving bought with stale air or a fogged windshield is no saving
        elif whole and not fam:
            v.matched[name] = {
                'energy_saving_pct': None,
                'discomfort_reduction_pct': None,
                'dominated': False,
                'note': 'every set-point of the family broke the air-quality limits',
            }
        elif fam:
            v.matched[name] = matched(fam, p)
            laws = sorted({family_law(n) for n in fam})
            if len(laws) > 1:
                for law in laws:
                    v.matched_by_law.setdefault(law, {})[name] = matched(fam, p, law=law)
        if base is not None and name != base and base not in partial:
            b = points[base]
            v.changes[name] = {
                'energy_change_pct': relative_change_pct(p[ENERGY_KEY], b[ENERGY_KEY]),
                'discomfort_change_pct': relative_change_pct(p[DISCOMFORT_KEY], b[DISCOMFORT_KEY]),
            }
    return v


def law_words(law: str) -> str:
    """How the verdict names a family law, with its gains read from the code and the frozen file."""
    from ceco_core.acc_law import AccSettings

    fields = {f.name for f in dataclasses.fields(AccSettings)}
    g = {**dataclasses.asdict(AccSettings()), **{k: v for k, v in _law_overrides(law) if k in fields}}
    gains = f"gains {g['kp_per_k']:g} 1/K, {g['ti_s']:g} s"
    base = law.removesuffix(_DOOR_SUFFIX)
    words = {'baseline': f'the production law ({gains})', 'baseline-tuned': f'the tuned law ({gains})'}[base]
    return words + (' with the CO2-holding door' if base != law else '')


def _pct(x) -> str:
    return 'n/a' if x is None or (isinstance(x, float) and not math.isfinite(x)) else f'{abs(x):.1f} %'


def _matched_words(m: Mapping, is_baseline: bool = False) -> str:
    from ceco_bringup.benchmark import front

    s = m.get('energy_saving_pct')
    if is_baseline and s is not None:
        return f"on the front ({_signed(s, '+.2f')} % against it: the family holds this same law)"
    if s is None:
        note = m.get('note', '')
        if front.dominates_front(m):
            return (
                'more comfortable than every set-point and less energy than each: it dominates the family '
                '(no matched value without extrapolation; ceco benchmark has colder ones)'
            )
        if 'more comfortable' in note:
            return 'more comfortable than every set-point: no matched value (ceco benchmark has colder ones)'
        if 'less comfortable' in note:
            return 'less comfortable than every set-point: no matched value'
        return f'no matched value ({note or "the front is degenerate"})'
    if abs(s) < RESOLUTION_PCT:
        words = f'same energy as the set-point family at matched comfort ({_signed(s)} %, under {RESOLUTION_PCT:g} %)'
    elif s >= 0:
        words = f'saves {_pct(s)} energy at matched comfort'
    else:
        words = f'uses {_pct(s)} more energy at matched comfort'
    return words + (' (dominated by a set-point)' if m.get('dominated') and abs(s) >= RESOLUTION_PCT else '')


def _signed(x: float, spec: str = '+.1f') -> str:
    """``x`` formatted with ``spec`` (a signed format); a value that rounds to zero as ``+0.0`` (never ``-0.0``)."""
    text = format(x, spec)
    return format(0.0, spec) if float(text) == 0.0 else text


def _band_words(p: Mapping) -> str:
    """Whether and when the PMV came to -0.5..+0.5 and whether it stayed there (:data:`AFTER_COMFORT_KEYS`)."""
    ttc = p.get('time_to_comfort_s')
    if ttc is None or not math.isfinite(float(ttc)):
        dur = p.get('duration_s')
        span = 'over the run' if dur is not None and float(dur) <= END_WINDOW_S else 'over the last minute'
        return f"never stayed in -0.5..+0.5 (PMV {p['pmv_end']:+.2f} {span})"
    end = f"(PMV {p['pmv_end']:+.2f} at the end)"
    out_s, left = p.get('pmv_out_after_comfort_s'), p.get('pmv_left_band_s')
    if 'pmv_out_after_comfort_s' not in p:  # an older verdict.json: whether it stayed was not recorded
        return f'in -0.5..+0.5 for {COMFORT_HOLD_S:g} s from {ttc:.0f} s {end}'
    if not out_s:  # never out again
        return f'in -0.5..+0.5 from {ttc:.0f} s on {end}'
    if left is not None and math.isclose(out_s, p['duration_s'] - left, abs_tol=1e-6):  # in until it left for good
        return f'in -0.5..+0.5 from {ttc:.0f} s to {left:.0f} s {end}'
    last = f', from {left:.0f} s to the end' if left is not None else ''
    after = f"out of it {out_s:.0f} of the {p['duration_s'] - ttc:.0f} s after{last}"
    return f'in -0.5..+0.5 from {ttc:.0f} s, {after} {end}'


def _broke_words(p: Mapping, limits: Mapping) -> str:
    """What a run that broke the air-quality limits did, and what follows."""
    co2, co2_lim = fmt_value(p.get('co2_max_ppm'), '.0f'), fmt_value(limits.get('co2_limit_ppm'), 'g')
    fog_lim, fog_s = fmt_value(limits.get('fog_margin_bound_k'), 'g'), fmt_value(p.get('fog_below_bound_s'), '.0f')
    return (
        f"BROKE the air-quality limits: CO2 max {co2} ppm, above {co2_lim} ppm "
        f"{fmt_value(p.get('co2_above_limit_pct'), '.1f')} % of the time; fog margin below {fog_lim} K {fog_s} s:"
        ' not matched, no saving'
    )


def _iso_line(v: Verdict) -> str:
    """The runs whose PMV is outside ISO 7730's validity too often (:func:`_iso_out`) and how often; '' when none."""
    done = {n: p for n, p in v.points.items() if n not in v.partial}
    out = {n: float(p['iso7730_invalid_pct']) for n, p in done.items() if _iso_out(p)}
    if not out:
        return ''
    if len(out) == len(done) and len(done) > 1:
        lo, hi = f'{min(out.values()):.1f}', f'{max(out.values()):.1f}'
        where = f"{lo if lo == hi else f'{lo}-{hi}'} % of the samples of every run"
    else:
        where = ', '.join(f'{x:.1f} % of the samples of {n}' for n, x in out.items())
    every = all(x >= 100.0 for x in out.values())  # then no PMV number of theirs is inside it
    what = 'every PMV number of theirs above is' if every else 'their PMV numbers above drawn from those samples are'
    return (
        "ISO 7730: the PMV is outside the standard's validity (a PMV input or the PMV outside its Clause 4"
        f' ranges) in {where}, more than {ISO_INVALID_SAY_PCT:g} %: {what} outside it.'
    )


def _iso_out(p: Mapping) -> bool:
    """Whether the PMV of the run ``p`` is outside ISO 7730's validity for more than :data:`ISO_INVALID_SAY_PCT`."""
    x = p.get('iso7730_invalid_pct')
    return x is not None and math.isfinite(float(x)) and float(x) > ISO_INVALID_SAY_PCT


def _air_line(v: Verdict) -> str:
    """The air quality of the job's runs in one line (the runs that broke the limits are named)."""
    lim = v.air_limits
    if not lim:
        return 'Air quality: not scored (the limits the runs were scored against are unknown).'
    co2_lim, fog_lim = f"{lim['co2_limit_ppm']:g}", f"{lim['fog_margin_bound_k']:g}"
    done = {n: p for n, p in v.points.items() if n not in v.partial}
    if not done:
        return f'Air quality (CO2 <= {co2_lim} ppm, fog margin >= {fog_lim} K): no complete run.'
    unknown = [n for n, p in done.items() if p.get('air_quality_met') is None]
    held = [p for n, p in done.items() if n not in v.air_quality_broken and n not in unknown]
    # a run without a CO2 series is judged on its fog margin alone (ceco_core.kpis.air_quality_kpis): not "held CO2"
    no_co2 = [n for n, p in done.items() if p.get('co2_max_ppm') is None and n not in unknown]
    co2 = fmt_value(max((p['co2_max_ppm'] for p in held if p.get('co2_max_ppm') is not None), default=None), '.0f')
    fog = fmt_value(
        min((p['fog_margin_min_k'] for p in held if p.get('fog_margin_min_k') is not None), default=None), '.1f'
    )
    if held and len(held) == len(done) and not no_co2:
        held_words = f'CO2 <= {co2_lim} ppm (max {co2} ppm) and fog margin >= {fog_lim} K (min {fog} K)'
        return f'Air quality: every run held {held_words}.'
    words = []
    if v.air_quality_broken:
        words.append(f"broken by {', '.join(v.air_quality_broken)} (not matched, no saving)")
    if held:
        co2_words = f'CO2 max {co2} ppm, ' if co2 != 'n/a' else ''
        words.append(
            f"{'the others' if v.air_quality_broken else 'the runs'} held them ({co2_words}fog margin min {fog} K)"
        )
    if no_co2:
        words.append(f"no CO2 recorded for {', '.join(no_co2)} (judged on the fog margin alone)")
    if unknown:
        words.append(f"not recorded for {', '.join(unknown)}")
    return f'Air quality (CO2 <= {co2_lim} ppm, fog margin >= {fog_lim} K): ' + '; '.join(words) + '.'


def verdict_lines(v: Verdict, *, pointer: str = '') -> list[str]:
    """The verdict in words, each line at most 100 characters.

    ``pointer``: the command that computes the matched-comfort saving, said when ``v`` has no family.
    """
    lines = [
        f'Verdict on {v.scenario} ({v.duration_s:.0f} s). Energy = {ENERGY_PARTS} [kWh];',
        '  discomfort = PMV-hours outside -0.5..+0.5, PMV clipped at +-3 [PMV h].',
    ]
    width = max([len(n) for n in (*v.points, *v.failed)] + [8])
    for name, p in v.points.items():
        head = f'  {name:<{width}} {p[ENERGY_KEY]:.3f} kWh, {p[DISCOMFORT_KEY]:.3f} PMV h: '
        if name in v.partial:
            lines.append(head + f'partial run ({v.partial[name]}): not compared')
            continue
        lines.append(head + _band_words(p))
        if name in v.air_quality_broken:
            lines.append(f"  {'':<{width}} {_broke_words(p, v.air_limits)}")
        elif name in v.matched:
            fam = comparable_family(v.family, name)
            single = len({family_law(n) for n in fam}) == 1
            words = _matched_words(v.matched[name], name == v.baseline and single)
            door = moves_door(name)
            prod = v.matched_by_law.get('baseline' + (_DOOR_SUFFIX if door else ''), {}).get(name, {})
            if prod.get('energy_saving_pct') is not None and not single:
                words += f"; {_signed(prod['energy_saving_pct'])} % against the production law alone"
            if door:
                words += ' (the laws with the CO2-holding door)'
            lines.append(f"  {'':<{width}} {words}")
        elif name not in v.partial and v.family and moves_door(name):
            lines.append(f"  {'':<{width}} no matched value: the family has no law with the door it moves")
    for name, why in v.failed.items():
        lines.append(f'  {name:<{width}} FAILED ({reason_line(why)}), not compared')
    iso = _iso_line(v)
    if iso:
        lines.append(iso)
    lines.append(_air_line(v))
    if v.family:
        sps = sorted({float(n.split('@')[1]) for n in v.family})
        laws = sorted({family_law(n) for n in v.family if not family_law(n).endswith(_DOOR_SUFFIX)})
        door_laws = sorted({family_law(n) for n in v.family if family_law(n).endswith(_DOOR_SUFFIX)})
        what = ' and '.join(law_words(law) for law in laws)
        lines.append(
            f'Matched comfort: against {what} at {sps[0]:g}-{sps[-1]:g} degC '
            f'({len(v.family)} runs, {v.family_source})'
            + ('; at each discomfort the law that spends least.' if len(laws) > 1 else '.')
        )
        if door_laws:
            lines.append(
                '  A strategy that moves the recirculation door against the same laws with the CO2-holding door '
                'behind them (the same actuators), the others against the laws without it.'
            )
        if v.family_file:
            lines.append(f'  (kept in {v.family_file})')
        n_broke = sum(breaks_air_quality(p) for p in v.family.values())
        if n_broke:
            lines.append(f'  {n_broke} of the {len(v.family)} runs broke the air-quality limits: on no front.')
        if v.family_failed:
            lines.append(f'  {_family_failed_words(v)}: on no front.')
        scored = {n: m for n, m in v.matched.items() if n != v.baseline and m.get('energy_saving_pct') is not None}
        if scored:
            best = max(scored, key=lambda n: scored[n]['energy_saving_pct'])
            s = scored[best]['energy_saving_pct']
            if s >= RESOLUTION_PCT:
                lines.append(f'Headline: {best} saves the most energy at matched comfort, {_pct(s)}.')
            else:
                lines.append(
                    f'Headline: no strategy saves {RESOLUTION_PCT:g} % or more at matched comfort '
                    f'(best: {best}, {_signed(s)} %).'
                )
    elif v.family_failed:
        lines.append(f'Matched comfort: not computed: {_family_failed_words(v)}.')
    else:
        lines.append('Matched comfort: not computed for these runs' + (f'; {pointer}' if pointer else '.'))
    if v.changes:
        de = [c['energy_change_pct'] for c in v.changes.values() if math.isfinite(c['energy_change_pct'])]
        dd = [c['discomfort_change_pct'] for c in v.changes.values() if math.isfinite(c['discomfort_change_pct'])]
        if de and dd:

            def span(xs):
                lo, hi = _signed(min(xs)), _signed(max(xs))
                return f'{lo} %' if lo == hi else f'{lo}..{hi} %'

            # the same discomfort (every change rounds to +0.0 %, none undefined): then no different comfort, unless
            # it is the same because the PMV sat at the +-3 clip the whole run (the discomfort's ceiling)
            same = all(abs(c['discomfort_change_pct']) < 0.05 for c in v.changes.values())
            clipped = same and _at_ceiling(v.points[v.baseline])
            lines.append(f'Against the {v.baseline} run alone the energy changes by {span(de)} and the discomfort')
            if clipped:
                close = "the same discomfort only because every run's PMV sat at the +-3 clip: not a saving."
            elif same:
                close = 'the same discomfort, so a comparison at the same comfort.'
            else:
                close = 'a comparison at different comfort, not a saving.'
            lines.append(f'  by {span(dd)} (+ = more): {close}')
    return _wrapped(lines)


def _at_ceiling(p: Mapping) -> bool:
    """Whether the run ``p``'s discomfort is at its ceiling (PMV at the +-3 clip throughout), as the fronts test it."""
    from ceco_bringup.benchmark import front

    ceiling = front.saturation_ceiling([p], DISCOMFORT_KEY)
    return ceiling is not None and float(p[DISCOMFORT_KEY]) >= ceiling * (1.0 - front.REL_TOL)


def reason_line(text: str) -> str:
    """Why a run failed, on one line: the first line of ``text`` that is not blank (a reason may span several)."""
    return next((x.strip() for x in str(text).splitlines() if x.strip()), 'no reason recorded')


def _family_failed_words(v: Verdict) -> str:
    """The family members that failed and why, members with the same reason together."""
    by_reason: dict[str, list[str]] = {}
    for member, why in v.family_failed.items():
        by_reason.setdefault(reason_line(why), []).append(member)
    total = len(v.family) + len(v.family_failed)
    words = '; '.join(f"{', '.join(ms)}: {why}" for why, ms in by_reason.items())
    return f'{len(v.family_failed)} of the {total} family runs failed ({words})'


def _wrapped(lines: Sequence[str], width: int = 100) -> list[str]:
    """``lines`` with each longer than ``width`` broken at spaces; continuations indented (joined by the report)."""
    import textwrap

    out = []
    for line in lines:
        if len(line) <= width:
            out.append(line)
            continue
        lead = line[: len(line) - len(line.lstrip())]
        out += textwrap.wrap(
            line, width, subsequent_indent=lead + '    ', break_long_words=False, break_on_hyphens=False
        )
    return out


def write_verdict(path: str | Path, v: Verdict) -> Path:
    """``verdict.json`` (non-finite numbers as null)."""

    def clean(x):
        if isinstance(x, float) and not math.isfinite(x):
            return None
        if isinstance(x, dict):
            return {k: clean(y) for k, y in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(y) for y in x]
        return x

    p = Path(path)
    p.write_text(json.dumps(clean(v.as_dict()), indent=1) + '\n', encoding='utf-8')
    return p


def read_verdict(path: str | Path) -> dict:
    """``verdict.json`` as a dict; ValueError when it is not a ``ceco-verdict/2`` (or older ``/1``) file.

    A ``/1`` file's family holds the production law only (its members read the same way).
    """
    data = json.loads(Path(path).read_text(encoding='utf-8'))
    if not isinstance(data, dict) or data.get('schema') not in (VERDICT_SCHEMA, 'ceco-verdict/1'):
        raise ValueError(f'{path}: not a {VERDICT_SCHEMA} file')
    return data
