"""Tune the baseline variants once, on one case, by a fixed rule; write the frozen constants.

``python -m ceco_bringup.benchmark.tuning [--case sc03-paper] [--out FILE]`` writes
``ceco_bringup/data/benchmark/baselines.yaml`` (default) with the values and the table
of every run the rule looked at. The rules (docs/benchmark.md, "Baselines"), all on the
tuning case, in-process runs of the production law:

0. **Neutral set-point** S_0 [degC]: the set-point at which the plain law's band-phase mean
   PMV is 0 (bisection in 18..32 degC, rounded to 1 mK): the comfort-neutral calibration of
   the production law on this case.
1. **Allowance** ``k_allow`` [K/PMV]: the largest of 0.5, 1.0, ..., 4.0 for which the law
   at S_0 with the allowance violates the scenario's bounds no longer than the plain law at
   S_0: it uses the permission without breaking it. (At a set-point whose plain law
   violates the band all through the comfort phase, as 26 degC does under the comfort model
   of issue 9, "no longer than the plain law" says nothing about the allowance.)
2. **Set-point sensitivity** g [PMV/K]: band-phase mean PMV of the plain law at
   S_d + 0.5 K minus that at S_d - 0.5 K, at the law's default set-point S_d
   (``AccSettings().setpoint_c``, 26 degC), where the law regulates. (Near S_0 the law
   runs at its actuator limit for much of the comfort phase, so local gains there measure
   the limit, not the law: on sc03-paper g = 0.073 PMV/K at S_0 against 0.32 at 26 degC,
   which would make k_sun 18.6 K/(kW/m2) and saturate the compensated law at every
   set-point.)
3. **Sun-load gain** ``k_sun`` [K/(kW/m2)]: the case's irradiance scaled by 0.9 and 1.1 (law
   at S_d); the set-point change that cancels the band-phase mean PMV change:
   ``k_sun = 1000 (dPMV/dS) / g`` with dS the change of the band-phase mean irradiance.
4. **Ambient gain** ``k_amb`` [K/K]: the same with the ambient temperature -1 K and +1 K.
5. **Blower gain and set-point**: for ``k_bl`` in 0, 0.01, 0.02, 0.03 (kg/s)/(kW/m2) the
   compensated law's set-point for which its band-phase mean PMV is 0 (bisection; the
   calibration target of an ACC: comfort-neutral); the ``k_bl`` with the least band-phase
   energy is kept (ties: the smaller).

6. **Gains of the tuned families** (schema ``ceco-benchmark-baselines/2``): for each family -- the
   production law with tuned gains (``tuned``), the same with the allowance k_allow of step 1
   (``tuned-allowance``), the comfort-feedback PI on the sensors' PMV (``pmv``) and the same with its
   allowance (``pmv-allowance``) -- every (K_p, T_i) of :data:`GAIN_GRID` x :data:`TI_GRID_S` runs at the
   tuning set-points (:data:`TUNING_SETPOINTS`); anti-windup (T_t), limits, pull-down and demand map
   are kept. The objective is the family front's mean energy over :data:`N_LEVELS` discomfort levels
   on [D_a, D_b] whose excess over D_a doubles from one to the next (:func:`front_objective`; D_a =
   the largest of the candidates' least discomforts, D_b = 1.5 x the smallest; candidates that cannot
   come within 10 % of the smallest are out). The least objective
   wins. The comfort-feedback allowance k_allow,PMV is the largest of :data:`PMV_ALLOWANCE_GRID` for
   which the tuned ``pmv`` law at PMV set-point 0 with it violates the bounds no longer than without
   (the rule of step 1). The chosen gains and their grid neighbours are rerun on a held-out case (the
   fronts are in the file and in ``docs/figures/baseline_tuning.png``).

Nothing here looks at a CECO strategy.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import yaml

from ceco_core import yamlio

__all__ = [
    'tune',
    'tune_gains',
    'front_objective',
    'main',
    'ALLOWANCE_GRID',
    'BLOWER_GRID',
    'GAIN_GRID',
    'TI_GRID_S',
    'TUNING_SETPOINTS',
    'PMV_ALLOWANCE_GRID',
    'N_LEVELS',
]

ALLOWANCE_GRID = tuple(0.5 * i for i in range(1, 9))
"""Candidates of k_allow [K/PMV]."""

BLOWER_GRID = (0.0, 0.01, 0.02, 0.03)
"""Candidates of k_bl [(kg/s)/(kW/m2)]."""

GAIN_GRID = {'cabin_temperature': (0.25, 0.5, 1.0), 'pmv': (0.4, 0.8, 1.6)}
"""Candidates of K_p: [1/K] on the cabin temperature (production 0.25), [1/PMV] on the PMV (0.8 ~ 0.25 1/K
through the plant's 0.32 PMV/K)."""

TI_GRID_S = (15.0, 30.0, 60.0, 120.0)
"""Candidates of the integral time T_i [s] (production 120 s)."""

TUNING_SETPOINTS = {
    'cabin_temperature': (24.0, 25.0, 26.0, 27.0),
    'pmv': (-0.1, 0.1, 0.3, 0.5),
}
"""Set-points each candidate runs at on the tuning case ([degC]: 24..27 in 1 K, which span the objective's
discomfort levels on sc03-paper, 0.102..0.154 PMV h; [-]: -0.1..+0.5 in 0.2)."""

PMV_ALLOWANCE_GRID = (0.25, 0.5, 0.75, 1.0)
"""Candidates of the comfort-feedback law's allowance k_allow,PMV [PMV/PMV]."""

N_LEVELS = 11
"""Discomfort levels of the tuning objective."""

LEVEL_RANGE = 1.5
"""D_b of the objective = LEVEL_RANGE x the least discomfort of any candidate."""

REACH = 1.1
"""A candidate whose least discomfort exceeds REACH x the least of all is out of the objective."""

HELD_OUT_CASE = 'us06-hot'
"""The case the chosen gains and their neighbours are checked on (never used to choose)."""

_FILTER_TAU_S = 20.0
_AMBIENT_REF_C = 25.0


def _run(scenario, overrides: dict) -> dict:
    from ceco_controller.closed_loop import SimSettings, simulate
    from ceco_core.kpis import band_phase
    from ceco_core.metrics import J_PER_KWH

    settings = SimSettings(
        progress=False,
        strategy_overrides=tuple(sorted(overrides.items())),
        measurements=_measurements(overrides.get('feedback', 'cabin_temperature')),
    )
    r = simulate(scenario, 'baseline', settings)
    ts = r.timeseries
    band = band_phase(ts['pmv_lb'], ts['pmv_ub'])
    e = ts['p_comp_w'] + ts['p_blower_w'] + ts['p_cond_fan_w']
    j_per_kwh_sample = J_PER_KWH / float(ts['t_s'][1] - ts['t_s'][0])  # powers held over each plant step
    return {
        'pmv_band': float(np.mean(ts['pmv'][band])),
        'violation_pct': float(r.metrics['otc_violation_pct']),
        'energy_band_kwh': float(np.sum(e[band])) / j_per_kwh_sample,
        'solar_band_wm2': float(np.mean(ts['solar_wm2'][band])),
        't_amb_band_c': float(np.mean(ts['t_amb_c'][band])),
        'energy_kwh': float(np.sum(e)) / j_per_kwh_sample,
    }


def _scaled(case, solar: float = 1.0, d_amb_k: float = 0.0):
    from ceco_v2x_preview.scenario import scenario_from_dict

    d = case.scenario_dict()
    d['weather'] = dict(d['weather'])
    d['weather']['solar_wm2'] = [solar * x for x in d['weather']['solar_wm2']]
    d['weather']['t_amb_c'] = [x + d_amb_k for x in d['weather']['t_amb_c']]
    return scenario_from_dict(d)


def tune(case_name: str = 'sc03-paper', log=print, workers: int = 2, work_dir=None, reuse=None) -> dict:
    """Apply the rules of the module docstring; return the baselines document.

    ``reuse``: a previous baselines file (schema 1 or 2) whose steps 0-5 (the production family's
    constants and their runs) are taken as they are when it was tuned on the same case (same case sha);
    step 6 always runs. The document says so (``constants_from``).
    """
    from .cases import load_case

    t0 = time.perf_counter()
    if reuse is not None:
        prev = yamlio.safe_load(Path(reuse).read_text(encoding='utf-8'))
        case = load_case(case_name)
        if prev.get('tuned_on') != case.name or prev.get('tuned_on_sha') != case.sha():
            raise ValueError(f'{reuse}: tuned on another case or case version; rerun steps 0-5')
        keep = ('neutral_setpoint_c', 'allowance_k_per_pmv', 'gain_setpoint_c', 'setpoint_sensitivity_pmv_per_k')
        families = tune_gains(
            case.name, k_allow=float(prev['allowance_k_per_pmv']), workers=workers, work_dir=work_dir, log=log
        )
        return _document(
            case,
            {k: prev[k] for k in keep},
            prev['compensation'],
            prev['runs'],
            families,
            t0,
            workers,
            f'steps 0-5 reused from {Path(reuse).name} ({prev["schema"]}, same case sha)',
        )

    case = load_case(case_name)
    sc = case.load_scenario()
    table: list = []

    def run(label, scenario, overrides):
        r = _run(scenario, overrides)
        table.append({'run': label, **{k: float(v) for k, v in overrides.items()}, **r})
        log(
            f"  {label}: PMV_band {r['pmv_band']:+.4f}, violation {r['violation_pct']:.2f} %, "
            f"E_band {r['energy_band_kwh']:.4f} kWh"
        )
        return r

    def neutral(label, overrides):
        """Set-point in 18..32 degC at which the band-phase mean PMV is 0 (bisection to ~1 mK)."""
        a, b = 18.0, 32.0
        for _ in range(14):
            mid = 0.5 * (a + b)
            r = run(f'{label} at {mid:.4f}', sc, {**overrides, 'setpoint_c': mid})
            a, b = (mid, b) if r['pmv_band'] < 0.0 else (a, mid)
        sp = round(0.5 * (a + b), 3)
        r = run(f'{label} neutral', sc, {**overrides, 'setpoint_c': sp})
        if abs(r['pmv_band']) > 0.01:
            raise RuntimeError(
                f'{label}: no set-point in 18..32 degC gives a band-phase mean PMV of 0 '
                f"(at {sp} degC: {r['pmv_band']:+.3f}); the law is saturated on this case"
            )
        return sp, r

    s0, plain = neutral('plain', {})
    k_allow = 0.0
    for k in ALLOWANCE_GRID:
        r = run(f'allowance {k:g} at S_0', sc, {'setpoint_c': s0, 'allowance_k_per_pmv': k})
        if r['violation_pct'] <= plain['violation_pct'] + 1e-9:
            k_allow = k
    from ceco_core.acc_law import AccSettings

    s_d = float(AccSettings().setpoint_c)
    g = (
        run(f'plain {s_d + 0.5:g}', sc, {'setpoint_c': s_d + 0.5})['pmv_band']
        - run(f'plain {s_d - 0.5:g}', sc, {'setpoint_c': s_d - 0.5})['pmv_band']
    )
    lo, hi = (
        run('solar x0.9', _scaled(case, solar=0.9), {'setpoint_c': s_d}),
        run('solar x1.1', _scaled(case, solar=1.1), {'setpoint_c': s_d}),
    )
    k_sun = 1000.0 * (hi['pmv_band'] - lo['pmv_band']) / (hi['solar_band_wm2'] - lo['solar_band_wm2']) / g
    lo, hi = (
        run('ambient -1 K', _scaled(case, d_amb_k=-1.0), {'setpoint_c': s_d}),
        run('ambient +1 K', _scaled(case, d_amb_k=1.0), {'setpoint_c': s_d}),
    )
    k_amb = (hi['pmv_band'] - lo['pmv_band']) / (hi['t_amb_band_c'] - lo['t_amb_band_c']) / g
    best = None
    for k_bl in BLOWER_GRID:
        comp = {
            'sun_gain_k_per_kwm2': k_sun,
            'ambient_gain_k_per_k': k_amb,
            'ambient_ref_c': _AMBIENT_REF_C,
            'sun_blower_gain_kgps_per_kwm2': k_bl,
            'sun_filter_tau_s': _FILTER_TAU_S,
        }
        sp, r = neutral(f'compensated k_bl {k_bl:g}', comp)
        if best is None or r['energy_band_kwh'] < best[0] - 1e-12:
            best = (r['energy_band_kwh'], {**comp, 'setpoint_c': sp})
    comp = {k: float(v) for k, v in best[1].items()}
    AccSettings(**comp, allowance_k_per_pmv=k_allow).validate()
    families = tune_gains(case.name, k_allow=k_allow, workers=workers, work_dir=work_dir, log=log)
    values = {
        'neutral_setpoint_c': float(s0),
        'allowance_k_per_pmv': float(k_allow),
        'gain_setpoint_c': s_d,
        'setpoint_sensitivity_pmv_per_k': float(g),
    }
    return _document(case, values, comp, table, families, t0, workers, 'steps 0-5 run now')


def _document(case, values, comp, table, families, t0, workers, constants_from) -> dict:
    """The baselines file's mapping (schema :data:`runner.BASELINES_SCHEMA`)."""
    n_runs = sum(
        len(f['grid']) * len(TUNING_SETPOINTS[f['settings'].get('feedback', 'cabin_temperature')])
        + len(f['held_out']['candidates']) * len(TUNING_SETPOINTS[f['settings'].get('feedback', 'cabin_temperature')])
        + len(f.get('allowance_rule', []))
        for f in families.values()
    )
    from .runner import BASELINES_SCHEMA

    return {
        'schema': BASELINES_SCHEMA,
        'constants_from': constants_from,
        'tuning_cost': {
            'runs_step6': int(n_runs),
            'runs_steps0_5': len(table),
            'wall_s': round(time.perf_counter() - t0, 1),
            'workers': int(workers),
        },
        'objective': (
            'per family: least mean energy of the family front over 11 discomfort levels on [D_a, 1.5 D_min] '
            'whose excess over D_a doubles from level to level (tuning.front_objective), over the grid '
            'GAIN_GRID x TI_GRID_S, on the tuning case only'
        ),
        'families': families,
        'tuned_on': case.name,
        'tuned_on_sha': case.sha(),
        'rules': 'ceco_bringup/benchmark/tuning.py (docs/benchmark.md, "Baselines")',
        **values,
        'compensation': comp,
        'runs': table,
    }


def front_objective(fronts: Mapping, n_levels: int = N_LEVELS) -> tuple[list[float], dict]:
    """The tuning objective of candidate fronts ``{key: Front}`` (pure; module docstring, step 6).

    The levels: D_a + (D_b - D_a) (2^j - 1) / (2^(n-1) - 1), j = 0..n-1, i.e. the excess over D_a doubles
    from level to level (fractions 0, 0.001, 0.003, ..., 0.25, 0.5, 1 of the range for n = 11): they
    concentrate where the comfort phase is kept in the band and the comparisons are made (the strategies
    and the oracle's levels sit within a few per cent of D_a), yet reach the warm end.
    Returns (levels, ``{key: J or None}``): J [kWh] = the mean over the levels of E(L), the front's
    energy at L (E at its least comfortable vertex beyond it: a more comfortable point meets a looser
    discomfort level); None for a candidate that cannot come within :data:`REACH` of the least
    discomfort of all. ValueError without fronts.
    """
    if not fronts:
        raise ValueError('front_objective: no candidate fronts')
    d_min = {k: f.d_range[0] for k, f in fronts.items()}
    lowest = min(d_min.values())
    ok = [k for k in fronts if d_min[k] <= REACH * lowest]
    d_a = max(d_min[k] for k in ok)
    d_b = LEVEL_RANGE * lowest
    levels = [d_a + (d_b - d_a) * (2.0**j - 1.0) / (2.0 ** (n_levels - 1) - 1.0) for j in range(n_levels)]
    out: dict = {}
    for k, f in fronts.items():
        if k not in ok:
            out[k] = None
            continue
        hi = f.d_range[1]
        e = [f.energy_at(x) if x <= hi else f.energy_at(hi) for x in levels]
        out[k] = float(np.mean(e))
    return levels, out


def _family_cells(case, fam_overrides: Mapping, setpoints, code):
    """{(kp, ti): [cells]} of one family's gain grid on ``case``."""
    from . import runner

    feedback = fam_overrides.get('feedback', 'cabin_temperature')
    kp_name = 'kp_per_pmv' if feedback == 'pmv' else 'kp_per_k'
    out = {}
    for kp in GAIN_GRID[feedback]:
        for ti in TI_GRID_S:
            fam = runner.FamilySpec(
                'tuned', {**fam_overrides, kp_name: float(kp), 'ti_s': float(ti)}, _measurements(feedback)
            )
            if feedback == 'pmv':
                specs = runner.family_members(fam, setpoints_pmv=setpoints)
            else:
                specs = runner.family_members(fam, setpoints_c=setpoints)
            out[(kp, ti)] = runner.case_cells(case, specs, code, seeds=[0])
    return out


def _measurements(feedback: str) -> str:
    """The comfort-feedback law reads the PMV through the estimator (the sensors a car has); the others 'full'."""
    return 'vehicle' if feedback == 'pmv' else 'full'


def _run_cells(cells, workers: int, work_dir: Path, log) -> dict:
    """Run (or reuse from ``work_dir/cells.jsonl``) benchmark cells; ``{cell_id: row}``."""
    from ceco_bringup.sweep import backends

    from . import runner

    work_dir.mkdir(parents=True, exist_ok=True)
    log_path = work_dir / 'cells.jsonl'
    done = backends.read_done(log_path)
    todo = [dict(id=c.id, axes=c.axes, spec=c.spec) for c in cells if c.id not in done]
    log(f'  {len(cells)} runs, {len(cells) - len(todo)} reused, {len(todo)} to run')

    def on_done(row):
        backends.append_row(log_path, row)
        if row['status'] != 'ok':
            log(f"  run failed: {row['controller']}: {row['error']}")

    if todo:
        backends.run_local(todo, max(1, min(workers, len(todo))), on_done, runner.run_benchmark_cell)
    return backends.read_done(log_path)


def _front_of(rows):
    from . import front as fr
    from .runner import ENERGY_AXIS, FRONT_AXIS

    pts = [(r['controller'], r['kpis'][FRONT_AXIS], r['kpis'][ENERGY_AXIS]) for r in rows if r and r['kpis']]
    return fr.build_front(pts) if pts else None


def _neighbours(feedback: str, key: tuple) -> list[tuple]:
    kps, tis = list(GAIN_GRID[feedback]), list(TI_GRID_S)
    i, j = kps.index(key[0]), tis.index(key[1])
    out = [key]
    for di, dj in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        if 0 <= i + di < len(kps) and 0 <= j + dj < len(tis):
            out.append((kps[i + di], tis[j + dj]))
    return out


def tune_gains(
    case_name: str = 'sc03-paper',
    *,
    k_allow: float,
    held_out: str = HELD_OUT_CASE,
    workers: int = 2,
    work_dir: str | Path | None = None,
    log=print,
) -> dict:
    """Step 6 of the module docstring: the gains of the four tuned families; ``{family: entry}``.

    Each entry: ``settings`` (the AccSettings overrides the benchmark runs the family with), ``objective_kwh``,
    ``levels_pmvh``, ``grid`` (every candidate's objective on the tuning case), ``held_out`` (the chosen gains
    and their grid neighbours: objective and front on the held-out case) and ``fronts`` (the tuning case's
    fronts of the same candidates: (D [PMV h], E [kWh]) of the efficient points).
    """
    import tempfile

    from ceco_bringup.sweep.cells import code_fingerprint

    from .cases import load_case

    code = code_fingerprint()
    case, other = load_case(case_name), load_case(held_out)
    work = Path(work_dir) if work_dir else Path(tempfile.mkdtemp(prefix='ceco-tuning-'))
    out = {}

    def tune_family(name: str, base: Mapping) -> dict:
        feedback = base.get('feedback', 'cabin_temperature')
        kp_name = 'kp_per_pmv' if feedback == 'pmv' else 'kp_per_k'
        log(f'family {name}: {len(GAIN_GRID[feedback]) * len(TI_GRID_S)} gain pairs on {case.name}')
        plan = _family_cells(case, base, TUNING_SETPOINTS[feedback], code)
        done = _run_cells([c for cs in plan.values() for c in cs], workers, work, log)
        fronts = {k: _front_of([done.get(c.id) for c in cs]) for k, cs in plan.items()}
        failed = sorted(k for k, f in fronts.items() if f is None)
        if failed:
            raise RuntimeError(f'family {name}: no finished run for the gains {failed}')
        levels, obj = front_objective(fronts)
        ranked = sorted((v, k) for k, v in obj.items() if v is not None)
        best = ranked[0][1]
        log(f'  chosen K_p {best[0]:g}, T_i {best[1]:g} s: {ranked[0][0]:.5f} kWh mean over {len(levels)} levels')
        near = _neighbours(feedback, best)
        plan2 = _family_cells(other, base, TUNING_SETPOINTS[feedback], code)
        done2 = _run_cells([c for k in near for c in plan2[k]], workers, work, log)
        fronts2 = {k: _front_of([done2.get(c.id) for c in plan2[k]]) for k in near}
        levels2, obj2 = front_objective(fronts2)

        def pts(f):
            return [[p.discomfort, p.energy] for p in f.vertices]

        return {
            'settings': {**dict(base), kp_name: float(best[0]), 'ti_s': float(best[1])},
            'measurements': _measurements(feedback),
            'objective_kwh': float(ranked[0][0]),
            'levels_pmvh': [float(x) for x in levels],
            'grid': [
                {'kp': float(k[0]), 'ti_s': float(k[1]), 'objective_kwh': obj[k], 'd_min_pmvh': fronts[k].d_range[0]}
                for k in sorted(plan)
            ],
            'fronts': {f'{k[0]:g}/{k[1]:g}': pts(fronts[k]) for k in near},
            'held_out': {
                'case': other.name,
                'case_sha': other.sha(),
                'levels_pmvh': [float(x) for x in levels2],
                'candidates': [
                    {'kp': float(k[0]), 'ti_s': float(k[1]), 'objective_kwh': obj2[k], 'front': pts(fronts2[k])}
                    for k in near
                ],
            },
        }

    out['tuned'] = tune_family('tuned', {})
    out['tuned-allowance'] = tune_family('tuned-allowance', {'allowance_k_per_pmv': float(k_allow)})
    out['pmv'] = tune_family('pmv', {'feedback': 'pmv'})
    # the comfort-feedback allowance: the rule of step 1 with the tuned pmv gains at PMV set-point 0
    pmv_settings = {**out['pmv']['settings'], 'setpoint_pmv': 0.0}
    sc = case.load_scenario()
    plain = _run(sc, pmv_settings)
    k_pmv = 0.0
    rows = [{'allowance_pmv_per_pmv': 0.0, 'violation_pct': plain['violation_pct']}]
    for k in PMV_ALLOWANCE_GRID:
        r = _run(sc, {**pmv_settings, 'allowance_pmv_per_pmv': k})
        rows.append({'allowance_pmv_per_pmv': k, 'violation_pct': r['violation_pct']})
        if r['violation_pct'] <= plain['violation_pct'] + 1e-9:
            k_pmv = k
    log(f'  k_allow,PMV = {k_pmv:g} (violation at PMV 0 without it {plain["violation_pct"]:.2f} %)')
    out['pmv-allowance'] = tune_family('pmv-allowance', {'feedback': 'pmv', 'allowance_pmv_per_pmv': k_pmv})
    out['pmv-allowance']['allowance_rule'] = rows
    return out


def main(argv=None) -> int:
    """CLI: tune and write the baselines file."""
    ap = argparse.ArgumentParser(prog='python -m ceco_bringup.benchmark.tuning', description=__doc__.split('\n\n')[0])
    ap.add_argument('--case', default='sc03-paper', help='tuning case (default sc03-paper)')
    default = Path(__file__).resolve().parent.parent / 'data' / 'benchmark' / 'baselines.yaml'
    ap.add_argument('--out', default=str(default), help=f'output file (default {default})')
    ap.add_argument('--workers', type=int, default=2, help='parallel runs of the gain grid (default 2)')
    ap.add_argument('--work', default=None, help='directory of the runs log (reuse it to resume; default: a temp dir)')
    ap.add_argument('--figure', default=None, help='also draw the tuning fronts to this PNG')
    ap.add_argument(
        '--reuse-constants',
        default=None,
        metavar='FILE',
        help='take steps 0-5 from this earlier baselines file (same case sha) and run step 6 only',
    )
    args = ap.parse_args(argv)
    doc = tune(
        args.case,
        log=lambda *a: print(*a, file=sys.stderr),
        workers=args.workers,
        work_dir=args.work,
        reuse=args.reuse_constants,
    )
    header = (
        '# Frozen constants of the benchmark baselines (docs/benchmark.md, "Baselines").\n'
        '# Written by `python -m ceco_bringup.benchmark.tuning`; do not edit by hand: rerun the rule.\n'
    )
    Path(args.out).write_text(header + yaml.safe_dump(doc, sort_keys=False, width=110), encoding='utf-8')
    if args.figure:
        plot_tuning(doc, args.figure)
    gains = {k: v['settings'] for k, v in doc['families'].items()}
    print(
        f"k_allow {doc['allowance_k_per_pmv']:g} K/PMV; compensation {doc['compensation']}; "
        f'families {gains} -> {args.out}'
    )
    return 0


def plot_tuning(doc: Mapping, path) -> None:
    """The fronts of each family's chosen gains and their grid neighbours, tuning case above, held-out below."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fams = list(doc['families'])
    fig, axes = plt.subplots(2, len(fams), figsize=(4.2 * len(fams), 7.5), squeeze=False)
    for j, name in enumerate(fams):
        f = doc['families'][name]
        kp = 'kp_per_pmv' if f['settings'].get('feedback') == 'pmv' else 'kp_per_k'
        chosen = f"{f['settings'][kp]:g}/{f['settings']['ti_s']:g}"
        rows = (
            (doc['tuned_on'], f['fronts']),
            (f['held_out']['case'], {f"{c['kp']:g}/{c['ti_s']:g}": c['front'] for c in f['held_out']['candidates']}),
        )
        for i, (case, fronts) in enumerate(rows):
            ax = axes[i][j]
            for key, pts in fronts.items():
                d, e = zip(*pts) if pts else ((), ())
                ax.plot(
                    d,
                    e,
                    '-o' if key == chosen else '--',
                    lw=2.2 if key == chosen else 1.0,
                    ms=3,
                    label=f'K_p/T_i {key}' + (' (chosen)' if key == chosen else ''),
                )
            ax.set_title(f'{name} on {case}', fontsize=9)
            ax.set_xlabel('discomfort [PMV h]')
            ax.set_ylabel('energy [kWh]')
            lv = f['levels_pmvh'] if i == 0 else f['held_out']['levels_pmvh']
            ax.set_xlim(0.98 * lv[0], 1.02 * lv[-1])
            ax.legend(fontsize=7)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == '__main__':
    sys.exit(main())
