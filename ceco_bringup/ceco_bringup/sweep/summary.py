"""The sweep's tables: the tidy results table, the per-group summary, dominance, vehicle level.

Pure Python + numpy (Parquet via pyarrow or polars when installed; the vehicle level
via FASTSim, the analysis extra).
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ceco_core.kpis import breaks_air_quality
from ceco_core.metrics import relative_change_pct

from .cells import Cell
from .grid import AXES, DEFAULT_SETTINGS, GROUP_AXES

__all__ = [
    'write_table',
    'write_parquet',
    'SUMMARY_KEYS',
    'CHANGE_KEYS',
    'AIR_QUALITY_SUMMARY_KEYS',
    'summarize',
    'dominance_rows',
    'point_name',
    'vehicle_rows',
    'summary_markdown',
]


def _write_table(path: Path, rows: Sequence[Mapping], columns: Sequence[str]) -> None:
    tmp = path.with_suffix(path.suffix + '.tmp')
    with open(tmp, 'w', newline='', encoding='utf-8') as fh:
        w = csv.DictWriter(fh, fieldnames=list(columns), extrasaction='ignore')
        w.writeheader()
        for r in rows:
            w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in r.items()})
    os.replace(tmp, path)


def _typed(values: Sequence) -> list:
    """One column with one type: int, float or str (None stays missing)."""
    kinds = {type(v) for v in values if v is not None}
    if kinds and (kinds <= {int} or kinds <= {bool}):
        return list(values)
    if kinds and kinds <= {int, float}:
        return [None if v is None else float(v) for v in values]
    return [None if v is None else str(v) for v in values]


def _write_parquet(path: Path, rows: Sequence[Mapping], columns: Sequence[str]) -> str | None:
    """Write the table as Parquet with pyarrow, else polars (a FASTSim dependency).

    Returns the engine used, None if neither is installed.
    """
    data = {c: _typed([r.get(c) for r in rows]) for c in columns}
    tmp = path.with_suffix('.parquet.tmp')
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq

        pq.write_table(pa.table(data), tmp)
        engine = 'pyarrow'
    except ImportError:
        try:
            import polars as pl
        except ImportError:
            return None
        pl.DataFrame(data).write_parquet(tmp)
        engine = 'polars'
    os.replace(tmp, path)
    return engine


SUMMARY_KEYS = (
    'E_tot_kWh',
    'I_pmv',
    'otc_violation_pct',
    'time_to_comfort_s',
    'pmv_max',
    'sim_time_s',
    'E_zone_J',
    'I_pmv_zone',
    'otc_violation_zone_pct',
    'pmv_mean_zone',
)
"""Metrics averaged over seeds in the summary."""

CHANGE_KEYS = ('E_tot_kWh', 'I_pmv', 'E_zone_J', 'I_pmv_zone')
"""Metrics whose change against the baseline [%] the summary gives (``<key>_change_pct``, signed as
measured: + = more); NaN where the point or its baseline broke the air-quality limits (:func:`summarize`)."""

AIR_QUALITY_SUMMARY_KEYS = (
    'co2_limit_ppm',
    'fog_margin_bound_k',
    'co2_max_ppm',
    'co2_above_limit_pct',
    'fog_below_bound_s',
    'air_quality_met',
)
"""Air-quality columns averaged over seeds in the summary (``<key>_mean``; the limits are the scenario's, the
same for every seed): the CO2 limit [ppm], the fog-margin bound [K], the cabin's CO2 maximum [ppm], the share of
the run above the limit [%], the time below the fog bound [s] (``ceco_core.kpis.air_quality_kpis``) and the share
of the seeds whose run met both limits [0-1]; NaN where not recorded."""


def _settings_of(row: Mapping) -> str:
    return str(row.get('settings') or DEFAULT_SETTINGS)  # rows logged before the settings axis: defaults


def summarize(rows: Sequence[Mapping], baseline: str = 'baseline') -> list[dict]:
    """The sweep's summary rows: per-point means over seeds and the change against the group's baseline.

    Per (scenario, drive_cycle, climate, preview, occupant, strategy,
    settings): the mean over seeds of the main metrics (:data:`SUMMARY_KEYS`)
    and of the air quality (:data:`AIR_QUALITY_SUMMARY_KEYS`), the number of seeds,
    and the change against the baseline of the same
    group (scenario, drive_cycle, climate, preview, occupant; means compared,
    :data:`CHANGE_KEYS`). The baseline runs once per group with its default
    settings; every (strategy, settings) of the group is compared with that
    one baseline. Rows keep the order of first appearance.

    Air quality, the rule of every verb (``ceco_core.kpis.breaks_air_quality``; ``ceco sim``'s verdict, the
    benchmark's fronts): ``n_air_quality_broken`` counts the point's seeds whose run broke the scenario's CO2
    limit or fog bound and ``air_quality_broken`` says whether any did. A point that broke the limits claims no
    saving, nor does any point of a group whose baseline broke them (a saving against stale air is no saving):
    its :data:`CHANGE_KEYS` changes are NaN and ``no_saving`` says why ('' where the changes stand). Unknown air
    quality (a log written before the sweep recorded it) is not a break.
    """
    group_axes = [a for a in AXES if a not in ('seed', 'strategy', 'settings')]
    groups: dict = {}
    for r in rows:
        if r.get('status') != 'ok':
            continue
        g = tuple(r[a] for a in group_axes)
        groups.setdefault(g, {}).setdefault((r['strategy'], _settings_of(r)), []).append(r)

    def mean(rs, k):
        vals = [float(x.get(k, float('nan'))) for x in rs]
        return float(np.nanmean(vals)) if any(math.isfinite(v) for v in vals) else float('nan')

    out = []
    for g, by_key in groups.items():
        means = {key: {k: mean(rs, k) for k in SUMMARY_KEYS + AIR_QUALITY_SUMMARY_KEYS} for key, rs in by_key.items()}
        broken = {key: sum(breaks_air_quality(r) for r in rs) for key, rs in by_key.items()}
        base_key = (baseline, DEFAULT_SETTINGS)
        base = means.get(base_key)
        for (s, label), m in means.items():
            row = dict(zip(group_axes, g))
            row['strategy'] = s
            row['settings'] = label
            n = row['n_seeds'] = len(by_key[(s, label)])
            row.update({f'{k}_mean': v for k, v in m.items()})
            row['n_air_quality_broken'] = broken[(s, label)]
            row['air_quality_broken'] = broken[(s, label)] > 0
            if row['air_quality_broken']:
                row['no_saving'] = f'broke the air-quality limits ({broken[(s, label)]} of {n} seeds)'
            elif base is not None and broken[base_key]:
                row['no_saving'] = 'its baseline broke the air-quality limits'
            else:
                row['no_saving'] = ''
            for k in CHANGE_KEYS:  # no baseline in the group, or no saving claimed: NaN
                claim = not row['no_saving']
                row[f'{k}_change_pct'] = relative_change_pct(m[k], base[k]) if base is not None and claim else math.nan
            out.append(row)
    return out


def dominance_rows(summary: Sequence[Mapping], baseline: str = 'baseline') -> list[dict]:
    """Which points of a summary Pareto-dominate the baseline of their group.

    Against the baseline of its group, for every other (strategy,
    settings) of a summary: does it use less energy AND have a lower or equal
    I_PMV (a Pareto-dominating point; ``dominates``), over the whole run and
    in the comfort-zone phase (``dominates_zone``)? The changes are the
    summary's ``E_tot_kWh_change_pct, I_pmv_change_pct, E_zone_J_change_pct, I_pmv_zone_change_pct``
    (NaN where the group has no baseline, or where the point or its baseline broke the air-quality limits:
    ``dominates`` is then False; ``air_quality_broken`` and ``no_saving`` are the summary's, :func:`summarize`).
    """
    out = []
    for r in summary:
        if r['strategy'] == baseline and r.get('settings', DEFAULT_SETTINGS) == DEFAULT_SETTINGS:
            continue
        de, di = float(r['E_tot_kWh_change_pct']), float(r['I_pmv_change_pct'])
        dez, diz = (
            float(r.get('E_zone_J_change_pct', float('nan'))),
            float(r.get('I_pmv_zone_change_pct', float('nan'))),
        )
        out.append(
            {
                **{a: r[a] for a in GROUP_AXES},
                'strategy': r['strategy'],
                'settings': r.get('settings', DEFAULT_SETTINGS),
                'E_tot_kWh_change_pct': de,
                'I_pmv_change_pct': di,
                'otc_violation_pct': r['otc_violation_pct_mean'],
                'E_zone_J_change_pct': dez,
                'I_pmv_zone_change_pct': diz,
                'otc_violation_zone_pct': r.get('otc_violation_zone_pct_mean', float('nan')),
                'dominates': bool(de < 0.0 and di <= 0.0),
                'dominates_zone': bool(dez < 0.0 and diz <= 0.0),
                'air_quality_broken': bool(r.get('air_quality_broken', False)),
                'no_saving': str(r.get('no_saving', '')),
            }
        )
    return out


def point_name(strategy: str, settings: str = DEFAULT_SETTINGS) -> str:
    """``strategy`` for default settings, else ``strategy[label]``."""
    return strategy if settings == DEFAULT_SETTINGS else f'{strategy}[{settings}]'


def _ordered_points(keys) -> list:
    """(strategy, settings) keys: strategies in figures.ordered order, labels in first-appearance order."""
    from ceco_bringup.figures import ordered

    keys = list(keys)
    return [k for s in ordered(list(dict.fromkeys(k[0] for k in keys))) for k in keys if k[0] == s]


def vehicle_rows(rows: Sequence[Mapping], cells: Sequence[Cell], settings=None) -> list[dict]:
    """Vehicle-level energy (FASTSim) of every group of a sweep whose cells are done.

    Computed with :mod:`ceco_bringup.vehicle_energy`. A group is (scenario, cycle,
    climate, preview, occupant); each strategy's A/C load is its mean ``P_mean_w`` over seeds,
    over the group's drive cycle and run length. One row per group, vehicle
    and strategy, with the group's axes (``strategy``: :func:`point_name`,
    e.g. ``ceco-c[g2k]`` for a settings label).
    """
    from ceco_bringup import vehicle_energy as ve
    from ceco_v2x_preview.scenario import scenario_from_dict

    settings = settings or ve.VehicleEnergySettings()
    spec_of = {c.id: c.spec for c in cells}
    groups: dict = {}
    for r in rows:
        if r.get('status') == 'ok' and r['cell_id'] in spec_of:
            groups.setdefault(tuple(r[a] for a in GROUP_AXES), []).append(r)
    out = []
    for g, rs in groups.items():
        p_mean: dict = {}
        for r in rs:
            p_mean.setdefault(point_name(r['strategy'], _settings_of(r)), []).append(float(r['P_mean_w']))
        spec = spec_of[rs[0]['cell_id']]
        sc = scenario_from_dict(spec['scenario'])
        duration_s = float(rs[0]['duration_s'])
        t = np.arange(0.0, math.floor(duration_s) + 1.0)
        v = np.asarray(sc.speed_mps(t), dtype=float)
        from ceco_bringup.figures import ordered

        loads = {s: float(np.mean(p_mean[s])) for s in ordered(list(p_mean))}
        for vr in ve.vehicle_energy_table(loads, t, v, settings):
            out.append({**dict(zip(GROUP_AXES, g)), **vr})
    return out


def _air_quality_cell(r: Mapping) -> str:
    """The summary table's "air quality" cell of a summary row: ``met``, ``BROKE k/n`` or ``n/a`` (not recorded)."""
    if r.get('air_quality_broken'):
        return f"BROKE {r['n_air_quality_broken']}/{r['n_seeds']}"
    met = r.get('air_quality_met_mean')
    return 'met' if met is not None and math.isfinite(float(met)) else 'n/a'


def summary_markdown(
    summary: Sequence[Mapping], timing: Mapping, grid_name: str, vehicle: Sequence[Mapping] = ()
) -> str:
    """The sweep's ``summary.md``: timing, one table row per summary point, dominance and vehicle level.

    Args:
        summary: the rows of :func:`summarize` (energy [kWh], I_PMV [s], changes [%], CO2 [ppm]; the column
            "air quality" says ``met``, ``BROKE k/n`` (k of the n seeds' runs broke the limits) or ``n/a`` (not
            recorded), and a section lists the points that claim no saving and why).
        timing: the sweep's timing record (``cells``, ``ran``, ``skipped``, ``failed``, ``backend``,
            ``workers``, ``wall_s`` [s], ``cells_per_hour``, ``sim_mean_s``, ``sim_median_s``,
            ``cell_mean_s``, ``cell_sum_s`` [s] and ``speedup``).
        grid_name: the grid's name, used in the title.
        vehicle: the rows of :func:`vehicle_rows` (no vehicle-level section when empty).

    Returns:
        The Markdown text, ending with a newline.
    """
    lines = [
        f'# Sweep summary: {grid_name}',
        '',
        f"{timing['cells']} cells ({timing['ran']} run now, {timing['skipped']} already done, "
        f"{timing['failed']} failed) with backend `{timing['backend']}` on {timing['workers']} worker(s). "
        f"Wall time of this invocation {timing['wall_s']:.1f} s ({timing['cells_per_hour']:.0f} cells/h). "
        f"Simulation time per cell (scenario build + closed loop, cells run now): mean "
        f"{timing['sim_mean_s']:.2f} s, median {timing['sim_median_s']:.2f} s; worker time per cell incl. "
        f"imports in a fresh worker {timing['cell_mean_s']:.2f} s (sum {timing['cell_sum_s']:.1f} s, "
        f"{timing['speedup']:.2f}x the wall time).",
        '',
        '| scenario | cycle | climate | preview | occupant | strategy | settings | seeds | E_tot [kWh] | '
        'E change [%] | I_PMV [s] | I_PMV change [%] | OTC viol. [%] | t_comfort [s] | E zone change [%] | '
        'I_PMV zone change [%] | '
        'OTC viol. zone [%] | CO2 max [ppm] | air quality |',
        '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|',
    ]

    def f(x, fmt):
        return 'n/a' if x is None or not math.isfinite(float(x)) else format(float(x), fmt)

    rows = sorted(summary, key=lambda r: (r['scenario'], r['drive_cycle'], r['climate'], r['preview'], r['occupant']))
    groups: dict = {}
    for r in rows:
        groups.setdefault(tuple(r[a] for a in GROUP_AXES), {})[(r['strategy'], r.get('settings', DEFAULT_SETTINGS))] = r
    for g, by in groups.items():
        for key in _ordered_points(by):
            r = by[key]
            lines.append(
                f"| {' | '.join(map(str, g))} | {key[0]} | {key[1]} | {r['n_seeds']} | "
                f"{f(r['E_tot_kWh_mean'], '.4f')} | "
                f"{f(r['E_tot_kWh_change_pct'], '+.1f')} | {f(r['I_pmv_mean'], '.1f')} | "
                f"{f(r['I_pmv_change_pct'], '+.1f')} | {f(r['otc_violation_pct_mean'], '.2f')} | "
                f"{f(r['time_to_comfort_s_mean'], '.0f')} | {f(r.get('E_zone_J_change_pct'), '+.1f')} | "
                f"{f(r.get('I_pmv_zone_change_pct'), '+.1f')} | {f(r.get('otc_violation_zone_pct_mean'), '.2f')} | "
                f"{f(r.get('co2_max_ppm_mean'), '.0f')} | {_air_quality_cell(r)} |"
            )
    no_saving = [
        (g, key, by[key]) for g, by in groups.items() for key in _ordered_points(by) if by[key].get('no_saving')
    ]
    if no_saving:
        lines += [
            '',
            '## Air quality: no saving claimed',
            '',
            "A run that broke its scenario's CO2 limit or fog bound claims no saving "
            '(ceco_core.kpis.breaks_air_quality, the rule of every verb), nor does a point compared with a baseline '
            'that broke them: their changes are n/a and they dominate nothing.',
            '',
        ]
        for g, key, r in no_saving:
            lines.append(
                f"- {'/'.join(map(str, g))} {point_name(*key)}: {r['no_saving']}; CO2 max "
                f"{f(r.get('co2_max_ppm_mean'), '.0f')} ppm (limit {f(r.get('co2_limit_ppm_mean'), '.0f')} ppm), "
                f"fog margin below its {f(r.get('fog_margin_bound_k_mean'), '.1f')} K bound for "
                f"{f(r.get('fog_below_bound_s_mean'), '.0f')} s (means over seeds)"
            )
    dom = dominance_rows(summary)
    if dom:
        lines += [
            '',
            '## Against the baseline: Pareto-dominating points',
            '',
            'A point dominates the baseline of its group when it uses less energy and has a lower or '
            'equal I_PMV (ΔE < 0 and ΔI_PMV <= 0), over the whole run or in the comfort-zone phase.',
            '',
        ]
        for g in groups:
            here = [d for d in dom if tuple(d[a] for a in GROUP_AXES) == g]
            if not here:
                continue
            tot = [point_name(d['strategy'], d['settings']) for d in here if d['dominates']]
            zone = [point_name(d['strategy'], d['settings']) for d in here if d['dominates_zone']]
            lines.append(
                f"- {'/'.join(map(str, g))}: whole run: {', '.join(tot) or 'none'}; "
                f"zone phase: {', '.join(zone) or 'none'}"
            )
    if vehicle:
        lines += [
            '',
            '## Vehicle level (FASTSim 3.1, load-averaged line; see docs/analysis.md)',
            '',
            '| scenario | cycle | climate | preview | occupant | vehicle | strategy | P_A/C [W] | '
            'vehicle energy change [%] | noise 1σ [%] | paper change, SC03 [%] | range lost [km] |',
            '|---|---|---|---|---|---|---|---|---|---|---|---|',
        ]
        for r in vehicle:
            lines.append(
                f"| {' | '.join(str(r[a]) for a in GROUP_AXES)} | {r['vehicle']} | {r['strategy']} | "
                f"{f(r['p_ac_mean_w'], '.0f')} | {f(r['change_fit_pct'], '+.2f')} | "
                f"{f(r['noise_pct'], '.2f')} | {f(r['paper_change_pct'], '+.1f')} | "
                f"{f(r['range_lost_km'], '.1f')} |"
            )
    return '\n'.join(lines) + '\n'


write_table = _write_table
write_parquet = _write_parquet
