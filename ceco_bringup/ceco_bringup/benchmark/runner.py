"""Cases -> cells -> KPIs -> the results document (``ceco-benchmark/1``).

Every run of the benchmark is a cell of the sweep machinery
(:mod:`ceco_bringup.sweep.backends`: the resumable ``cells.jsonl`` log, the local
process pool or Ray): its id is the SHA-256 of its spec (the resolved scenario,
the controller and its settings, the preview quality and seed, the plant/comfort
overrides of a sensitivity run, the benchmark version and the simulator's code
fingerprint), so a rerun of the same command runs nothing and a changed
simulator reruns everything. Each cell runs ``closed_loop.simulate`` and scores
the run with ``ceco_core.kpis.compute_kpis`` in the worker; the driver then
builds the fronts and the matched-comfort results (:mod:`.front`).

Pure Python (no ROS import; the DDS path for external controllers is :mod:`.external`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from importlib import resources
from pathlib import Path

import yaml

from ceco_bringup.sweep.cells import Cell, cell_id

from . import front as fr
from .cases import Case
from .schema import BENCHMARK_VERSION, FAMILIES

__all__ = [
    'SETPOINTS_C',
    'QUICK_SETPOINTS_C',
    'FRONT_AXIS',
    'ENERGY_AXIS',
    'SECONDARY_AXES',
    'STRATEGY_NAMES',
    'BaselineConstants',
    'load_baselines',
    'new_row',
    'Sensitivity',
    'load_sensitivity',
    'ControllerSpec',
    'controllers',
    'case_cells',
    'run_benchmark_cell',
    'assemble_case',
]

SETPOINTS_C = tuple(22.0 + 0.5 * i for i in range(15))
"""Set-points of the baseline family [degC]: 22.0 ... 29.0 in 0.5 K steps (docs/benchmark.md, "Baselines")."""

QUICK_SETPOINTS_C = (24.0, 25.0, 26.0)
"""The family of ``--quick`` [degC]."""

FRONT_AXIS = 'discomfort_pmvh'
"""KPI of the front's discomfort axis."""

ENERGY_AXIS = 'energy_kwh'
"""KPI of the front's energy axis."""

SECONDARY_AXES = ('i_pmv_clipped', 'discomfort_band_pmvh')
"""Other discomfort KPIs the matched comfort is also computed on (plain front; shown in the report)."""

STRATEGY_NAMES = ('ceco', 'ceco-e', 'ceco-c', 'ceco-ioch')
"""The NMPC strategies scored by the benchmark (defaults, ``ceco_controller/config/controller.yaml``)."""

SEED_INVARIANT = ('baseline', 'baseline-allowance', 'compensated', 'compensated-allowance')
SCORED_KINDS = ('strategy', 'compensated', 'compensated-allowance', 'external')


@dataclasses.dataclass(frozen=True)
class BaselineConstants:
    """The frozen constants of the baseline variants (``data/benchmark/baselines.yaml``)."""

    allowance_k_per_pmv: float
    """Set-point rise per PMV of relaxation of the upper bound [K/PMV] (AccSettings.allowance_k_per_pmv)."""
    compensation: Mapping
    """AccSettings overrides of the compensated law (set-point, sun/ambient gains, filter)."""
    tuned_on: str = ''
    """The case the constants were tuned on."""
    sha: str = ''
    """SHA-256 (16 hex digits) of the file."""


def load_baselines(path: str | Path | None = None) -> BaselineConstants:
    """Read the frozen baseline constants (default: the bundled file)."""
    import hashlib

    if path is None:
        text = resources.files('ceco_bringup').joinpath('data', 'benchmark', 'baselines.yaml').read_text('utf-8')
    else:
        text = Path(path).read_text(encoding='utf-8')
    d = yaml.safe_load(text)
    if not isinstance(d, Mapping) or d.get('schema') != 'ceco-benchmark-baselines/1':
        raise ValueError('baselines: not a ceco-benchmark-baselines/1 file')
    from ceco_core.acc_law import AccSettings

    comp = dict(d['compensation'])
    AccSettings(**comp, allowance_k_per_pmv=float(d['allowance_k_per_pmv'])).validate()
    return BaselineConstants(
        allowance_k_per_pmv=float(d['allowance_k_per_pmv']),
        compensation=comp,
        tuned_on=str(d.get('tuned_on', '')),
        sha=hashlib.sha256(text.encode('utf-8')).hexdigest()[:16],
    )


@dataclasses.dataclass(frozen=True)
class Sensitivity:
    """One parameter of the tornado: plant or comfort overrides at its two ends."""

    parameter: str
    """Name shown, e.g. ``comfort.a2``."""
    target: str
    """'plant' (PlantParams) or 'comfort' (ComfortParams of the scored PMV)."""
    nominal: Mapping
    """Fields and their default values (checked against the code)."""
    low: Mapping
    """Fields at the low end."""
    high: Mapping
    """Fields at the high end."""
    source: str = ''
    """Where the range comes from."""


def _default_value(target: str, name: str):
    """The code's default of a sensitivity field: PlantParams / ComfortParams (dotted parts), or pa_pa."""
    from ceco_core.cabin_comfort import ComfortParams
    from ceco_plant_sim.plant_params import PlantParams
    from ceco_plant_sim.scenario_plant import SCORED_PA_OVERRIDE

    if target == 'comfort' and name == SCORED_PA_OVERRIDE:
        return None  # default: the plant's moisture balance, no fixed value
    obj = ComfortParams() if target == 'comfort' else PlantParams()
    for part in name.split('.'):
        obj = getattr(obj, part)
    return obj


def load_sensitivity(path: str | Path | None = None) -> tuple[str, list[Sensitivity]]:
    """The tornado's case and parameters.

    Field names are PlantParams fields (target ``plant``) or ComfortParams fields with nested parts
    by dotted name, e.g. ``air.jet_body_fraction`` (target ``comfort``), or ``pa_pa`` (a fixed scored
    vapour pressure; its nominal is ``null``: the plant's moisture balance). ValueError naming the
    parameter and the field when a field is unknown, an end is not usable
    (``ceco_plant_sim.scenario_plant.check_overrides``), the nominal fields differ from the ends'
    fields, or a nominal value is not the code's default (the table must follow the code).
    """
    if path is None:
        text = resources.files('ceco_bringup').joinpath('data', 'benchmark', 'sensitivity.yaml').read_text('utf-8')
    else:
        text = Path(path).read_text(encoding='utf-8')
    d = yaml.safe_load(text)
    from ceco_plant_sim.scenario_plant import check_overrides

    if not isinstance(d, Mapping) or d.get('schema') != 'ceco-benchmark-sensitivity/1':
        raise ValueError('sensitivity: not a ceco-benchmark-sensitivity/1 file')
    out = []
    for i, p in enumerate(d['parameters']):
        where = f"sensitivity.parameters[{i}] ({p.get('parameter')!r})"
        if p.get('target') not in ('plant', 'comfort'):
            raise ValueError(f"{where}.target: must be plant or comfort, got {p.get('target')!r}")
        for end in ('nominal', 'low', 'high'):
            if not isinstance(p.get(end), Mapping) or not p[end]:
                raise ValueError(f'{where}.{end}: must be a non-empty mapping of fields to values')
        s = Sensitivity(
            parameter=p['parameter'],
            target=p['target'],
            nominal=dict(p['nominal']),
            low=dict(p['low']),
            high=dict(p['high']),
            source=' '.join(str(p.get('source', '')).split()),
        )
        if not set(s.low) == set(s.high) == set(s.nominal):
            raise ValueError(f'{where}: nominal, low and high must set the same fields')
        for end in ('low', 'high'):
            kw = {'plant_overrides': getattr(s, end)} if s.target == 'plant' else {'comfort_overrides': getattr(s, end)}
            try:
                check_overrides(**kw)
            except ValueError as exc:
                raise ValueError(f'{where}.{end}: {exc}') from exc
        for k, v in s.nominal.items():
            try:
                default = _default_value(s.target, k)
            except AttributeError as exc:
                raise ValueError(f'{where}.nominal: no field {k!r} ({exc})') from exc
            same = (v is None and default is None) or (
                v is not None and default is not None and math.isclose(float(default), float(v), rel_tol=1e-12)
            )
            if not same:
                raise ValueError(
                    f"{where}.nominal: {k} = {v} differs from the code's default {default}: "
                    'update data/benchmark/sensitivity.yaml'
                )
        if s.low == s.high:
            raise ValueError(f'{where}: low and high are the same')
        out.append(s)
    return str(d['case']), out


@dataclasses.dataclass(frozen=True)
class ControllerSpec:
    """A controller of the benchmark."""

    name: str
    """Its name in results.json (``baseline@25.0``, ``ceco-c``, ...)."""
    kind: str
    """strategy | baseline | baseline-allowance | compensated | compensated-allowance | external."""
    strategy: str
    """The simulator's strategy (``baseline`` for every baseline variant)."""
    overrides: tuple = ()
    """((field, value), ...) of the strategy's settings (AccSettings for the baselines)."""
    setpoint_c: float | None = None
    """Nominal cabin set-point of a baseline [degC]."""

    @property
    def seeded(self) -> bool:
        """True when the controller sees previews (one run per seed); baselines are seed-invariant."""
        return self.kind not in SEED_INVARIANT


def controllers(
    baselines: BaselineConstants, setpoints_c: Sequence[float] = SETPOINTS_C, strategies: Sequence[str] = STRATEGY_NAMES
) -> list[ControllerSpec]:
    """The benchmark's controllers: both baseline families, both compensated laws, the strategies."""
    out = []
    k = float(baselines.allowance_k_per_pmv)
    for sp in setpoints_c:
        sp = float(sp)
        out.append(ControllerSpec(f'baseline@{sp:.1f}', 'baseline', 'baseline', (('setpoint_c', sp),), sp))
    for sp in setpoints_c:
        sp = float(sp)
        out.append(
            ControllerSpec(
                f'baseline-allowance@{sp:.1f}',
                'baseline-allowance',
                'baseline',
                (('allowance_k_per_pmv', k), ('setpoint_c', sp)),
                sp,
            )
        )
    comp = tuple(sorted((str(a), float(b)) for a, b in baselines.compensation.items()))
    sp_c = float(dict(comp).get('setpoint_c', 26.0))
    out.append(ControllerSpec('baseline-compensated', 'compensated', 'baseline', comp, sp_c))
    out.append(
        ControllerSpec(
            'baseline-compensated-allowance',
            'compensated-allowance',
            'baseline',
            tuple(sorted(comp + (('allowance_k_per_pmv', k),))),
            sp_c,
        )
    )
    out += [ControllerSpec(s, 'strategy', s) for s in strategies]
    return out


def _preview(case: Case) -> str:
    return 'perfect' if case.forecast_uncertainty == 'none' else f'uncertain:{case.forecast_uncertainty}'


def case_cells(
    case: Case,
    specs: Sequence[ControllerSpec],
    code: str,
    *,
    seeds: Sequence[int] | None = None,
    variant: str = 'nominal',
    plant_overrides: Mapping | None = None,
    comfort_overrides: Mapping | None = None,
) -> list[Cell]:
    """The cells of one case (one per controller, and per seed for the seeded ones)."""
    scenario = case.scenario_dict()
    sha = case.sha()
    out = []
    for c in specs:
        for seed in list(seeds if seeds is not None else case.seeds) if c.seeded else [None]:
            spec = {
                'benchmark_version': BENCHMARK_VERSION,
                'code': code,
                'case': case.name,
                'case_sha': sha,
                'scenario': scenario,
                'strategy': c.strategy,
                'strategy_overrides': dict(c.overrides),
                'preview': _preview(case) if c.seeded else 'perfect',
                'seed': seed,
                'duration_s': case.duration_s,
                'control_period_s': case.control_period_s,
                'horizon_steps': case.horizon_steps,
                'plant_overrides': dict(plant_overrides or {}),
                'comfort_overrides': dict(comfort_overrides or {}),
            }
            axes = {
                'case': case.name,
                'controller': c.name,
                'kind': c.kind,
                'seed': seed,
                'variant': variant,
                'setpoint_c': c.setpoint_c,
            }
            out.append(Cell(id=cell_id(spec), axes=axes, spec=spec))
    return out


def new_row(cell: Mapping, source: str) -> dict:
    """The ``cells.jsonl`` row of a cell before it runs: status ok, no KPIs yet; ``source`` simulator or dds."""
    return {
        'cell_id': cell['id'],
        **cell['axes'],
        'status': 'ok',
        'error': '',
        'kpis': None,
        'kpi_notes': {},
        'source': source,
        'sim_time_s': math.nan,
    }


def run_benchmark_cell(cell: Mapping, runs_dir: str | None = None, controller_cache=None) -> dict:
    """Run one benchmark cell in this process and score it; never raises (errors are data).

    ``controller_cache``: the worker's :class:`ceco_controller.factory.ControllerCache` (a warm
    worker reuses its controllers; the results are the same).

    Returns the row logged in ``cells.jsonl``: ``cell_id``, the axes, ``status``, ``error``,
    ``kpis``, ``kpi_notes``, ``code``, ``sim_time_s``, ``wall_time_s``, ``source``.
    """
    import os
    import socket
    import time

    t0 = time.perf_counter()
    row = new_row(cell, 'simulator')
    try:
        from ceco_bringup.sweep import cells as sweep_cells
        from ceco_controller.closed_loop import simulate, write_run
        from ceco_core.kpis import compute_kpis
        from ceco_v2x_preview.scenario import scenario_from_dict

        spec = cell['spec']
        row['code'] = sweep_cells.check_code(spec, 'benchmark')
        t_sim = time.perf_counter()
        settings = sweep_cells.settings_from_spec(spec)
        res = simulate(
            scenario_from_dict(spec['scenario']), spec['strategy'], settings, controller_cache=controller_cache
        )
        m = res.metrics
        kpis, notes = compute_kpis(
            res.timeseries,
            step_time_s=res.step_time_s,
            control_period_s=m['control_period_s'],
            fallback_steps=m['n_fallback_shifted'] + m['n_fallback_baseline'],
        )
        row['sim_time_s'] = time.perf_counter() - t_sim
        row['kpis'], row['kpi_notes'] = kpis, notes
        if runs_dir:
            write_run(res, Path(runs_dir) / cell['id'])
    except Exception as exc:  # a failed run is data, the benchmark goes on
        row['status'], row['error'] = 'error', f'{type(exc).__name__}: {exc}'
    row['wall_time_s'] = time.perf_counter() - t0
    row['host'], row['pid'] = socket.gethostname(), os.getpid()
    return row


def _run_entry(row: Mapping) -> dict:
    kpis = row.get('kpis') or {}
    from .schema import REQUIRED_KPIS

    if row['status'] != 'ok':
        kpis = {k: None for k in REQUIRED_KPIS}
        notes = {k: 'the run failed' for k in REQUIRED_KPIS}
    else:
        notes = dict(row.get('kpi_notes') or {})
    clean = {
        k: (None if v is None or (isinstance(v, float) and not math.isfinite(v)) else float(v)) for k, v in kpis.items()
    }
    for k, v in kpis.items():
        if v is not None and clean[k] is None:
            notes.setdefault(k, 'not finite')
    return {
        'controller': row['controller'],
        'kind': row['kind'],
        'seed': row['seed'],
        'setpoint_c': row.get('setpoint_c'),
        'source': row.get('source', 'simulator'),
        'status': row['status'],
        'error': row.get('error', ''),
        'kpis': clean,
        'kpi_notes': notes,
    }


def _fronts(runs: Sequence[Mapping], fx: str, ex: str) -> dict:
    out = {}
    for family, kind in FAMILIES.items():
        pts = [
            (r['controller'], r['kpis'][fx], r['kpis'][ex])
            for r in runs
            if r['kind'] == kind
            and r['status'] == 'ok'
            and r['kpis'].get(fx) is not None
            and r['kpis'].get(ex) is not None
        ]
        out[family] = fr.build_front(pts) if pts else None
    return out


def _points(runs: Sequence[Mapping], fx: str, ex: str) -> dict:
    pts: dict = {}
    for r in sorted(runs, key=lambda r: -1 if r['seed'] is None else r['seed']):
        if r['kind'] in SCORED_KINDS and r['status'] == 'ok':
            d, e = r['kpis'].get(fx), r['kpis'].get(ex)
            if d is not None and e is not None:
                pts.setdefault(r['controller'], []).append((d, e))
    return pts


def _matched(runs: Sequence[Mapping], fx: str, ex: str) -> dict:
    fronts = _fronts(runs, fx, ex)
    out = {}
    if fronts['plain'] is None or fronts['allowance'] is None:
        return out
    for name, pts in _points(runs, fx, ex).items():
        out[name] = {**fr.match_seeds(fronts['plain'], pts), 'allowance': fr.match_seeds(fronts['allowance'], pts)}
    return out


def assemble_case(case: Case, rows: Sequence[Mapping], sensitivity: Sequence[tuple] = ()) -> dict:
    """One case of results.json.

    From its finished rows (nominal variant) and, optionally, ``sensitivity`` =
    [(Sensitivity, low rows, high rows), ...].
    """
    runs = [_run_entry(r) for r in rows]
    runs.sort(key=lambda r: (r['controller'], -1 if r['seed'] is None else r['seed']))
    fronts = _fronts(runs, FRONT_AXIS, ENERGY_AXIS)
    sc = case.load_scenario()
    out = {
        'case': case.name,
        'version': case.version,
        'case_sha': case.sha(),
        'description': case.description,
        'scenario': case.scenario,
        'forecast_uncertainty': case.forecast_uncertainty,
        'seeds': list(case.seeds),
        'duration_s': float(sc.duration_s),
        'control_period_s': float(case.control_period_s or sc.control.control_period_s),
        'horizon_steps': int(case.horizon_steps or sc.control.horizon_steps),
        'runs': runs,
        'fronts': {
            fam: []
            if f is None
            else [
                {'controller': p.name, 'discomfort': p.discomfort, 'energy': p.energy, 'efficient': p.efficient}
                for p in f.points
            ]
            for fam, f in fronts.items()
        },
        'matched': _matched(runs, FRONT_AXIS, ENERGY_AXIS),
    }
    out['matched_by_axis'] = {
        ax: {
            n: {k: m[k] for k in ('energy_saving_pct', 'discomfort_reduction_pct', 'dominated', 'note')}
            for n, m in _matched(runs, ax, ENERGY_AXIS).items()
        }
        for ax in SECONDARY_AXES
    }
    if sensitivity:
        out['sensitivity'] = []
        for s, low_rows, high_rows in sensitivity:
            entry = {
                'parameter': s.parameter,
                'target': s.target,
                'source': s.source,
                'nominal': _scalar(s.nominal),
                'low': _scalar(s.low),
                'high': _scalar(s.high),
            }
            for end, rs in (('low', low_rows), ('high', high_rows)):
                m = _matched([_run_entry(r) for r in rs], FRONT_AXIS, ENERGY_AXIS)
                entry[f'matched_{end}'] = {
                    n: {k: v[k] for k in ('energy_saving_pct', 'discomfort_reduction_pct', 'dominated', 'note')}
                    for n, v in m.items()
                }
                entry[f'failed_{end}'] = sum(r['status'] != 'ok' for r in rs)
            out['sensitivity'].append(entry)
    return out


def _scalar(fields: Mapping):
    """The first field's value: the parameter itself (coupled fields such as a second angle factor follow it).

    None where the nominal is "no fixed value" (the scored p_a from the plant's moisture balance).
    """
    v = next(iter(fields.values()))
    return None if v is None else float(v)
