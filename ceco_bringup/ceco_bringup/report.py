"""``ceco report DIR... [--out REPORT_DIR] [--vehicle]``: the research report.

For every run directory (docs/architecture.md, "Run directory format") given,
or found one level below a ``--strategy all`` parent:

1. Load the time series: from the rosbag2 bag alone when ``DIR/bag`` exists
   (``ceco_bringup.bagio.load_run_timeseries``), else from
   ``DIR/timeseries.csv``.
2. Recompute the metrics with ``ceco_core.metrics.compute_metrics`` and
   check they equal ``DIR/metrics.json`` (relative tolerance ``--rtol``,
   NaN equals NaN). A mismatch is printed to stderr, shown as a red warning
   in the report, and makes the command exit with status 1.
3. Per scenario: the paper's figures (PMV with bounds, cabin and vent
   temperatures, compressor and blower power, the two inputs, energy and
   comfort bars, solver solve times, and with ``--vehicle`` the vehicle-level
   savings from FASTSim), the metrics table, the solver statistics from
   ``diagnostics.csv`` and the comparison with the paper's numbers.

Writes ``REPORT_DIR/report.html`` (self-contained), ``REPORT_DIR/summary.md``,
``REPORT_DIR/metrics.csv`` (one row per run), ``REPORT_DIR/vehicle.csv``
(with ``--vehicle``) and the PNGs under ``REPORT_DIR/figures/``.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
import sys
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ceco_bringup import figures
from ceco_core.metrics import relative_change_pct
from ceco_core.rundir import TIMESERIES_COLUMNS, read_csv_columns
from ceco_bringup.report_html import Figure, Heading, Paragraph, Table, Warning, render_html, render_markdown

__all__ = ['PAPER_AC_SAVING_PCT', 'TIMESERIES_COLUMNS', 'RunData', 'discover_runs', 'read_csv_columns',
           'recompute_metrics', 'compare_metrics', 'load_run', 'solver_stats', 'build_report', 'main']

PAPER_AC_SAVING_PCT = {'ceco-e': -15.9, 'ceco-c': -4.1, 'ceco-ioch': -7.6}
"""A/C energy change against the baseline on SC03 [%] (paper, Sec. 5)."""

_METRIC_INPUTS = ('t_s', 'p_comp_w', 'p_blower_w', 'pmv', 'pmv_lb', 'pmv_ub')


@dataclasses.dataclass
class RunData:
    """One run directory, loaded and checked."""

    path: Path
    """The run directory."""
    strategy: str
    """From metrics.json (else the directory name)."""
    scenario: str
    """From metrics.json (else 'unknown')."""
    stored: dict
    """metrics.json as read."""
    columns: dict
    """Time series: name -> 1-D array (``timeseries.csv`` names)."""
    source: str
    """'bag' or 'timeseries.csv': where ``columns`` came from."""
    recomputed: dict
    """compute_metrics over ``columns``."""
    mismatches: list
    """(key, stored, recomputed) for every metric that differs."""
    max_rel_diff: float
    """Largest relative difference over the compared metrics."""
    diagnostics: dict | None
    """diagnostics.csv columns (or the bag's diagnostics), or None when absent."""
    check_rtol: float = 0.0
    """Relative tolerance the check used (looser than asked when
    timeseries.csv was written with fewer significant digits)."""


def discover_runs(paths: Sequence[str | Path]) -> list[Path]:
    """Run directories among ``paths``: a directory holding ``metrics.json``
    is a run; otherwise its immediate subdirectories holding one are (a
    ``--strategy all`` parent). Raises ValueError for a path that is neither."""
    runs: list[Path] = []
    for p in map(Path, paths):
        if not p.is_dir():
            raise ValueError(f'{p}: not a directory')
        if (p / 'metrics.json').is_file():
            runs.append(p)
            continue
        subs = sorted(d for d in p.iterdir() if d.is_dir() and (d / 'metrics.json').is_file())
        if not subs:
            raise ValueError(f'{p}: no metrics.json in it nor in its subdirectories: not a run directory')
        runs.extend(subs)
    return runs


def csv_precision_digits(path: str | Path, columns: Sequence[str] = _METRIC_INPUTS[1:]) -> int:
    """Significant digits the writer of a CSV file used for ``columns``: the
    largest count found in any cell (``%g`` drops trailing zeros, so the
    maximum is the format's precision; 17 for Python's ``repr``)."""
    best = 0
    with open(path, newline='', encoding='utf-8') as fh:
        reader = csv.reader(fh)
        header = [h.strip() for h in next(reader)]
        idx = [header.index(c) for c in columns if c in header]
        for row in reader:
            for i in idx:
                mant = row[i].strip().lstrip('+-').lower().split('e')[0].replace('.', '').lstrip('0')
                best = max(best, len(mant))
    return best


def recompute_metrics(columns: Mapping, count_aux: bool = False) -> dict:
    """``compute_metrics`` over the run's time series columns; with
    ``count_aux`` the condenser fan (column ``p_cond_fan_w``) is counted in
    ``E_tot`` as the other A/C auxiliary (``E_aux_J``)."""
    from ceco_core.metrics import compute_metrics  # noqa: PLC0415

    missing = [c for c in _METRIC_INPUTS if c not in columns]
    if count_aux and 'p_cond_fan_w' not in columns:
        missing.append('p_cond_fan_w')
    if missing:
        raise ValueError(f'time series: missing columns {missing}')
    args = [np.asarray(columns[c], dtype=float) for c in _METRIC_INPUTS]
    if count_aux:
        return compute_metrics(*args, p_aux_w=np.asarray(columns['p_cond_fan_w'], dtype=float))
    return compute_metrics(*args)


def compare_metrics(stored: Mapping, recomputed: Mapping, rtol: float = 1e-9, atol: float = 1e-9):
    """Compare every numeric metric present in both. Returns ``(mismatches,
    max_rel_diff)``; NaN equals NaN; ``|a - b| <= atol + rtol |b|`` passes."""
    mism, worst = [], 0.0
    for key, new in recomputed.items():
        if key not in stored or isinstance(stored[key], (str, bool)) or stored[key] is None:
            continue
        old, new = float(stored[key]), float(new)
        if math.isnan(old) and math.isnan(new):
            continue
        if math.isnan(old) != math.isnan(new):
            mism.append((key, old, new))
            worst = math.inf
            continue
        diff = abs(old - new)
        worst = max(worst, diff / abs(new) if new != 0 else (0.0 if diff == 0 else math.inf))
        if diff > atol + rtol * abs(new):
            mism.append((key, old, new))
    return mism, worst


def _load_bag(bag_dir: Path) -> dict:
    from ceco_bringup import bagio  # noqa: PLC0415 (needs rosbags only; imported when a bag exists)

    try:
        cols = {k: np.asarray(v) for k, v in bagio.load_run_timeseries(bag_dir).items()}
    except Exception as exc:  # noqa: BLE001 (rosbags raises its own types; say which bag)
        raise ValueError(f'{bag_dir}: cannot read the bag: {type(exc).__name__}: {exc}') from exc
    if not len(cols.get('t_s', ())) >= 2:
        raise ValueError(f'{bag_dir}: the bag holds fewer than 2 complete plant steps')
    return cols


def load_run(run_dir: str | Path, rtol: float = 1e-6) -> RunData:
    """Load one run directory, recompute its metrics and check them."""
    run_dir = Path(run_dir)
    stored = json.loads((run_dir / 'metrics.json').read_text(encoding='utf-8'))
    if (run_dir / 'bag').is_dir():
        columns, source = _load_bag(run_dir / 'bag'), 'bag'
    elif (run_dir / 'timeseries.csv').is_file():
        columns, source = read_csv_columns(run_dir / 'timeseries.csv'), 'timeseries.csv'
    else:
        raise ValueError(f'{run_dir}: neither bag/ nor timeseries.csv')
    # The run counted the condenser fan in E_tot if its metrics.json says so
    # (E_aux_J > 0); the recomputation follows and E_aux_J itself is checked.
    count_aux = bool(stored.get('E_aux_J')) and float(stored.get('E_aux_J') or 0.0) != 0.0
    recomputed = recompute_metrics(columns, count_aux=count_aux)
    check_rtol = rtol
    if source == 'timeseries.csv':
        # A value written with d significant digits is off by up to
        # 0.5e(1-d) relative; the sums and extrema of the metrics inherit
        # that bound, so the check cannot be tighter than the file.
        digits = csv_precision_digits(run_dir / 'timeseries.csv')
        if digits:
            check_rtol = max(rtol, 10.0 ** (1 - digits))
    mism, worst = compare_metrics(stored, recomputed, rtol=check_rtol)
    diag = None
    if (run_dir / 'diagnostics.csv').is_file():
        diag = read_csv_columns(run_dir / 'diagnostics.csv')
    elif source == 'bag':
        from ceco_bringup import bagio  # noqa: PLC0415

        diag = {k: np.asarray(v) for k, v in bagio.load_diagnostics(run_dir / 'bag').items()} or None
    return RunData(path=run_dir, strategy=str(stored.get('strategy') or run_dir.name),
                   scenario=str(stored.get('scenario') or 'unknown'), stored=stored, columns=columns,
                   source=source, recomputed=recomputed, mismatches=mism, max_rel_diff=worst, diagnostics=diag,
                   check_rtol=check_rtol)


def fallback_mask(column) -> np.ndarray:
    """Which control steps fell back: the ``fallback`` column is the fallback
    kind ('' = none, 'shifted_plan', 'baseline', ...) or a 0/1 flag."""
    col = np.asarray(column)
    if col.dtype.kind in 'fiub':
        f = col.astype(float)
        return np.isfinite(f) & (f != 0.0)
    text = np.char.lower(np.char.strip(col.astype(str)))
    return ~np.isin(text, ('', '0', '0.0', 'false', 'none', 'no', 'nan'))


def solver_stats(diag: Mapping | None) -> dict:
    """Summary of one run's ``diagnostics.csv``: ``steps``, ``solver_steps``
    (rows with a solve time), ``success_pct``, ``fallbacks`` (count),
    ``fallback_kinds`` ({kind: count}),
    ``solve_ms_median/p95/max/mean``, ``iter_median/max``, ``statuses``
    ({status: count}). Empty solver columns (baseline) give NaN."""
    nan = float('nan')
    out = {'steps': 0, 'solver_steps': 0, 'success_pct': nan, 'fallbacks': 0, 'solve_ms_median': nan,
           'solve_ms_p95': nan, 'solve_ms_max': nan, 'solve_ms_mean': nan, 'iter_median': nan,
           'iter_max': nan, 'statuses': {}, 'fallback_kinds': {}}
    if not diag:
        return out
    n = len(next(iter(diag.values())))
    out['steps'] = n
    st = np.asarray(diag.get('solve_time_ms', np.full(n, nan)), dtype=float)
    ok = np.isfinite(st)
    out['solver_steps'] = int(ok.sum())
    if 'fallback' in diag:
        mask = fallback_mask(diag['fallback'])
        out['fallbacks'] = int(mask.sum())
        kinds = np.asarray(diag['fallback']).astype(str)[mask] if np.asarray(diag['fallback']).dtype.kind in 'US' \
            else np.array([])
        vals, counts = np.unique(kinds, return_counts=True)
        out['fallback_kinds'] = {str(v): int(c) for v, c in zip(vals, counts)}
    if ok.any():
        out.update(solve_ms_median=float(np.median(st[ok])), solve_ms_p95=float(np.percentile(st[ok], 95)),
                   solve_ms_max=float(np.max(st[ok])), solve_ms_mean=float(np.mean(st[ok])))
        if 'success' in diag:
            sc = diag['success']
            sc = np.asarray(sc, dtype=float) if sc.dtype.kind == 'f' else np.array(
                [str(x).strip().lower() in ('1', 'true', 'yes') for x in sc], dtype=float)
            out['success_pct'] = 100.0 * float(np.nansum(sc[ok])) / int(ok.sum())
        it = np.asarray(diag.get('iterations', np.full(n, nan)), dtype=float)[ok]
        if np.any(np.isfinite(it)):
            out['iter_median'] = float(np.nanmedian(it))
            out['iter_max'] = float(np.nanmax(it))
    if 'status' in diag:
        vals, counts = np.unique(np.asarray(diag['status']).astype(str), return_counts=True)
        out['statuses'] = {str(v): int(c) for v, c in zip(vals, counts) if v and v != 'nan'}
    return out


# ---------------------------------------------------------------- formatting
def _f(x, digits=3) -> str:
    try:
        x = float(x)
    except (TypeError, ValueError):
        return str(x)
    if math.isnan(x):
        return 'n/a'
    if abs(x) >= 1000:
        return f'{x:,.0f}'
    if abs(x) >= 100:
        return f'{x:.1f}'
    return f'{x:.{digits}g}' if abs(x) < 1e-3 and x != 0 else f'{x:.{digits}f}'


def _pct(x) -> str:
    x = float(x)
    return 'n/a' if math.isnan(x) else f'{x:+.1f} %'


_change = relative_change_pct


def _group(runs: Sequence[RunData]) -> dict:
    """{scenario: {label: RunData}}; the label is the strategy, made unique
    with the directory name when a scenario holds a strategy twice."""
    groups: dict = {}
    for r in runs:
        g = groups.setdefault(r.scenario, {})
        label = r.strategy if r.strategy not in g else f'{r.strategy} ({r.path.name})'
        g[label] = r
    return groups


def _scenario_text(name: str) -> str:
    try:
        from ceco_v2x_preview.scenario import load_scenario  # noqa: PLC0415

        sc = load_scenario(name)
    except (ImportError, ValueError, OSError):
        return f'Scenario `{name}` (not found among the bundled scenarios: description unavailable).'
    w = sc
    return (f'Scenario `{sc.name}`: {sc.description} Drive cycle `{sc.drive_cycle.name}` '
            f'({sc.drive_cycle.distance_m / 1e3:.2f} km over {sc.drive_cycle.duration_s:.0f} s); run length '
            f'{sc.duration_s:.0f} s; ambient {w.weather_t_amb_c.min():.1f}..{w.weather_t_amb_c.max():.1f} °C, '
            f'solar {w.weather_solar_wm2.min():.0f}..{w.weather_solar_wm2.max():.0f} W/m², '
            f'RH {100 * w.weather_rh.min():.0f}..{100 * w.weather_rh.max():.0f} %; occupant '
            f'{sc.occupant.met} met, {sc.occupant.clo} clo; initial cabin {sc.initial.t_cab_c:.1f} °C.')


def _slug(text: str) -> str:
    return ''.join(c if c.isalnum() or c in '-_' else '_' for c in text)


def _vehicle_rows(scenario: str, runs: Mapping[str, RunData], settings):
    from ceco_bringup import vehicle_energy as ve  # noqa: PLC0415

    durations = {r.recomputed['duration_s'] for r in runs.values()}
    duration_s = max(durations)
    p_mean = {label: runs[label].recomputed['E_tot_J'] / runs[label].recomputed['duration_s']
              for label in figures.ordered(list(runs))}
    try:
        t, v = ve.drive_cycle_for_run(scenario, duration_s)
        note = f'drive cycle of scenario `{scenario}` over 0..{duration_s:.0f} s'
    except (ImportError, ValueError, OSError):
        first = next(iter(runs.values())).columns
        t = np.asarray(first['t_s'], dtype=float) - float(first['t_s'][0])
        v = np.asarray(first['speed_mps'], dtype=float)
        note = 'speed trace recorded in the run (scenario not loadable)'
    return ve.vehicle_energy_table(p_mean, t, v, settings), note, len(durations) > 1


def build_report(run_dirs: Sequence[str | Path], out_dir: str | Path, *, vehicle: bool = False,
                 rtol: float = 1e-6, vehicle_settings=None, log=print) -> dict:
    """Build the report. Returns ``{'html', 'markdown', 'metrics_csv',
    'vehicle_csv', 'figures': [...], 'runs': [RunData], 'mismatch': bool,
    'vehicle_rows': {scenario: rows}}``."""
    out = Path(out_dir)
    fig_dir = out / 'figures'
    fig_dir.mkdir(parents=True, exist_ok=True)
    runs = [load_run(d, rtol=rtol) for d in discover_runs(run_dirs)]
    any_mismatch = False
    blocks: list = [Heading(1, 'ceco report: energy and comfort of predictive A/C control')]
    blocks.append(Paragraph(
        f'{len(runs)} run(s) from: ' + ', '.join(f'`{r.path}`' for r in runs) + '. Metrics were recomputed '
        'from each run\'s time series (the rosbag2 bag alone when the run has one, else timeseries.csv) and '
        f'compared with its metrics.json (relative tolerance {rtol:g}; for a timeseries.csv written with d '
        'significant digits, 10^(1-d), the precision the file holds).'))
    for r in runs:
        if r.mismatches:
            any_mismatch = True
            detail = '; '.join(f'{k}: metrics.json {a!r} vs recomputed {b!r}' for k, a, b in r.mismatches)
            msg = f'metrics of {r.path} recomputed from {r.source} differ from metrics.json: {detail}'
            blocks.append(Warning(msg))
            log(f'ceco report: MISMATCH: {msg}', file=sys.stderr)
    all_figs: list[Path] = []
    vehicle_all: dict = {}
    metric_rows: list[dict] = []
    for scenario, group in _group(runs).items():
        labels = figures.ordered(list(group))
        slug = _slug(scenario)
        blocks.append(Heading(2, f'Scenario {scenario}'))
        blocks.append(Paragraph(_scenario_text(scenario)))
        base = group.get('baseline')
        m = {lab: group[lab].recomputed for lab in labels}
        # metrics table
        rows = []
        for lab in labels:
            r, x = group[lab], m[lab]
            b = base.recomputed if base else None
            rows.append((lab, _f(x['E_tot_kWh'], 4), _pct(_change(x['E_tot_J'], b['E_tot_J'])) if b else 'n/a',
                         _f(x['E_comp_J'] / 1e3, 1), _f(x['E_blower_J'] / 1e3, 1), _f(x['P_mean_w'], 0),
                         _f(x['I_pmv'], 1), _pct(_change(x['I_pmv'], b['I_pmv'])) if b else 'n/a',
                         _f(x['otc_violation_pct'], 2), _f(x['time_to_comfort_s'], 0), _f(x['pmv_mean'], 3),
                         _f(x['pmv_max'], 3), r.source,
                         (f'OK (≤ {r.check_rtol:.0e})' if not r.mismatches else f'MISMATCH ({len(r.mismatches)})')))
            metric_rows.append({'scenario': scenario, 'strategy': r.strategy, 'run_dir': str(r.path),
                                'source': r.source, 'metrics_match': not r.mismatches,
                                'max_rel_diff': r.max_rel_diff, **x})
        blocks.append(Table(('strategy', 'E_tot [kWh]', 'ΔE_tot', 'E_comp [kJ]', 'E_bl [kJ]', 'P_mean [W]',
                             'I_PMV [s]', 'ΔI_PMV', 'OTC viol. [%]', 't_comfort [s]', 'PMV mean', 'PMV max',
                             'from', 'vs metrics.json'), rows,
                            caption='Metrics per strategy (Δ: change against the baseline). I_PMV = ∫PMV² dt; '
                                    'OTC violation: share of time outside the PMV bounds; t_comfort: first time '
                                    'PMV stays in -0.5..0.5 for 60 s.'))
        # figures
        cols = {lab: group[lab].columns for lab in labels}
        figs = [
            (figures.fig_pmv(cols, fig_dir / f'{slug}_pmv.png', f'PMV and its bounds, {scenario}'),
             'PMV of every strategy; grey band: the scenario\'s comfort bounds (relaxed upper bound during the '
             'initial pull-down).'),
            (figures.fig_temperatures(cols, fig_dir / f'{slug}_temperatures.png',
                                      f'Cabin and vent air temperatures, {scenario}'),
             'Cabin air temperature (top, with the ambient) and vent (evaporator outlet) air temperature.'),
            (figures.fig_powers(cols, fig_dir / f'{slug}_powers.png', f'A/C electrical power, {scenario}'),
             'Compressor (top) and blower (bottom) electrical power, means over each 1 s plant step.'),
            (figures.fig_inputs(cols, fig_dir / f'{slug}_inputs.png', f'Control inputs, {scenario}'),
             'The two inputs: blower air mass flow and evaporator temperature set-point.'),
            (figures.fig_bars(m, fig_dir / f'{slug}_bars.png', f'Energy and comfort, {scenario}'),
             'A/C energy (compressor solid, blower hatched), comfort index I_PMV and bound violation; labels '
             'give the change against the baseline.'),
        ]
        diags = {lab: group[lab].diagnostics for lab in labels if group[lab].diagnostics is not None}
        stats = {lab: solver_stats(group[lab].diagnostics) for lab in labels}
        if any(s['solver_steps'] for s in stats.values()):
            figs.append((figures.fig_solver(diags, fig_dir / f'{slug}_solver.png', f'NMPC solve time, {scenario}'),
                         'Distribution of the NMPC solve time per control step (log scale) and fallbacks.'))
        # comparison with the paper
        blocks.append(Heading(3, 'Comparison with the paper (SC03, Prius HEV)'))
        vrows = None
        if vehicle:
            from ceco_bringup import vehicle_energy as ve  # noqa: PLC0415

            vrows, note, mixed = _vehicle_rows(scenario, group, vehicle_settings or ve.VehicleEnergySettings())
            vehicle_all[scenario] = vrows
        prius = {r['strategy']: r for r in (vrows or []) if r['powertrain'] == 'HEV'}
        crow = []
        for lab in labels:
            if lab == 'baseline':
                continue
            x = m[lab]
            pr = prius.get(lab)
            crow.append((lab, _pct(_change(x['E_tot_J'], base.recomputed['E_tot_J'])) if base else 'n/a',
                         _pct(PAPER_AC_SAVING_PCT.get(lab, float('nan'))),
                         _pct(pr['saving_fit_pct']) if pr else 'not computed (use --vehicle)',
                         _pct(pr['paper_saving_pct']) if pr else _pct(float('nan')),
                         _pct(_change(x['I_pmv'], base.recomputed['I_pmv'])) if base else 'n/a',
                         _f(x['otc_violation_pct'], 2)))
        blocks.append(Table(('strategy', 'ΔE_A/C (ours)', 'ΔE_A/C (paper)', 'Δ vehicle energy (ours, Prius)',
                             'Δ vehicle energy (paper)', 'ΔI_PMV (ours)', 'OTC viol. [%] (ours)'), crow,
                            caption='Changes against the baseline. The paper reports A/C energy -15.9 / -4.1 / '
                                    '-7.6 % and vehicle energy -6.4 / -1.8 / -3.1 % for CECO-E / CECO-C / '
                                    'CECO-IOCH on SC03 (CoolSim plant, 2017 Prius HEV).'))
        if scenario != 'sc03':
            blocks.append(Paragraph('The paper\'s numbers are for SC03: they are shown for orientation only.'))
        if vrows is not None:
            blocks.append(Heading(3, 'Vehicle-level energy (FASTSim 3.1)'))
            blocks.append(Paragraph(
                f'Over the {note}. Each strategy\'s mean A/C electrical power is added to the vehicle\'s base '
                'auxiliary load as one constant; every strategy is read off one straight line fitted to FASTSim '
                'runs at several loads around them (fuel versus aux load is not smooth: the fit\'s residual '
                'scatter is given as noise; differences below about twice it are not significant). Hybrid fuel '
                'is charge-corrected. Range: repeating the cycle on the usable battery energy.'))
            if mixed:
                blocks.append(Warning('the runs of this scenario have different lengths; the longest was used '
                                      'for the drive cycle.'))
            vt = []
            for r in vrows:
                vt.append((r['vehicle'], r['strategy'], _f(r['p_ac_mean_w'], 0), _f(r['energy_fit_j'] / 1e6, 3),
                           _f(r['energy_direct_j'] / 1e6, 3), _pct(r['saving_fit_pct']),
                           _pct(r['saving_direct_pct']), _pct(r['paper_saving_pct']), f"{r['noise_pct']:.2f} %",
                           _f(r['ac_share_pct'], 1),
                           _f(r['l_per_100km'], 2) if r['powertrain'] != 'BEV' else _f(r['kwh_per_100km'], 2),
                           _f(r['range_km'], 0), _f(r['range_lost_km'], 1), _f(r['range_lost_pct'], 1)))
            blocks.append(Table(('vehicle', 'strategy', 'P_A/C mean [W]', 'E_veh fit [MJ]', 'E_veh direct [MJ]',
                                 'Δ fit', 'Δ direct', 'Δ paper (SC03)', 'noise (1σ)', 'A/C share [%]',
                                 'L/100 km | kWh/100 km', 'range [km]', 'range lost [km]', 'range lost [%]'),
                                vt, caption='Vehicle energy per strategy (fuel for the hybrid, battery energy '
                                            'for the electric car).'))
            per_eval = [r['fit_wall_time_s'] / r['n_evals'] for r in vrows]
            blocks.append(Paragraph(f'FASTSim time per evaluation: {1e3 * min(per_eval):.0f}-'
                                    f'{1e3 * max(per_eval):.0f} ms (vehicle build + drive, this machine).'))
            figs.append((figures.fig_vehicle(vrows, fig_dir / f'{slug}_vehicle.png',
                                             f'Vehicle-level energy, {scenario}'),
                         'Vehicle energy change against the baseline (error bars: ±2σ fit noise) next to the '
                         'paper\'s Prius numbers; range of the electric car lost to the A/C.'))
        # solver statistics
        blocks.append(Heading(3, 'Solver statistics'))
        srows = []
        for lab in labels:
            s = stats[lab]
            status = ', '.join(f'{k}: {v}' for k, v in sorted(s['statuses'].items(), key=lambda kv: -kv[1])[:4])
            kinds = ', '.join(f'{k}: {v}' for k, v in s['fallback_kinds'].items())
            srows.append((lab, str(s['steps']), str(s['solver_steps']), _f(s['success_pct'], 1),
                          str(s['fallbacks']) + (f' ({kinds})' if kinds else ''), _f(s['solve_ms_median'], 1), _f(s['solve_ms_p95'], 1),
                          _f(s['solve_ms_max'], 1), _f(s['iter_median'], 0), _f(s['iter_max'], 0),
                          status or ('no diagnostics.csv' if group[lab].diagnostics is None else '')))
        blocks.append(Table(('strategy', 'control steps', 'solves', 'success [%]', 'fallbacks',
                             'solve median [ms]', 'p95 [ms]', 'max [ms]', 'iter. median', 'iter. max',
                             'statuses'), srows, caption='From diagnostics.csv (the baseline has no solver).'))
        blocks.append(Heading(3, 'Figures'))
        for path, cap in figs:
            blocks.append(Figure(path, cap))
            all_figs.append(path)
    md = render_markdown(blocks, base_dir=out)
    (out / 'summary.md').write_text(md, encoding='utf-8')
    (out / 'report.html').write_text(render_html(blocks), encoding='utf-8')
    _write_rows(out / 'metrics.csv', metric_rows)
    vehicle_csv = None
    if vehicle_all:
        vehicle_csv = out / 'vehicle.csv'
        _write_rows(vehicle_csv, [{'scenario': s, **r} for s, rows in vehicle_all.items() for r in rows])
    return {'html': out / 'report.html', 'markdown': out / 'summary.md', 'metrics_csv': out / 'metrics.csv',
            'vehicle_csv': vehicle_csv, 'figures': all_figs, 'runs': runs, 'mismatch': any_mismatch,
            'vehicle_rows': vehicle_all}


def _write_rows(path: Path, rows: Sequence[Mapping]) -> None:
    keys: list = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    with open(path, 'w', newline='', encoding='utf-8') as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in r.items()})


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog='ceco report', description='Recompute the metrics of run directories (from the bag when present) '
        'and write figures, a self-contained HTML report and a Markdown summary.')
    parser.add_argument('dirs', nargs='+', metavar='DIR',
                        help='run directories, or parents holding one run directory per strategy')
    parser.add_argument('--out', default=None, help='report directory (default: DIR/report for one DIR, '
                        'else ./ceco_report)')
    parser.add_argument('--vehicle', action='store_true',
                        help='add vehicle-level energy with FASTSim 3.1 (optional extra: requirements/analysis.txt)')
    parser.add_argument('--rtol', type=float, default=1e-6,
                        help='relative tolerance of the metrics.json check (default 1e-6, the stack\'s '
                             'agreement criterion; a bag holds float64 and agrees far closer)')
    args = parser.parse_args(argv)
    if not (math.isfinite(args.rtol) and args.rtol >= 0):
        parser.error(f'--rtol: must be finite and >= 0, got {args.rtol}')
    out = Path(args.out) if args.out else (Path(args.dirs[0]) / 'report' if len(args.dirs) == 1
                                          else Path('ceco_report'))
    try:
        res = build_report(args.dirs, out, vehicle=args.vehicle, rtol=args.rtol)
    except (ValueError, OSError) as exc:
        print(f'ceco report: error: {exc}', file=sys.stderr)
        return 2
    except ImportError as exc:
        print(f'ceco report: error: {exc}', file=sys.stderr)
        return 2
    for r in res['runs']:
        state = 'OK' if not r.mismatches else 'MISMATCH'
        print(f'{r.path}: {r.strategy} on {r.scenario}, metrics from {r.source}: {state} '
              f'(max rel. diff {r.max_rel_diff:.1e}, tolerance {r.check_rtol:.0e})')
    print(f"report: {res['html']}\nsummary: {res['markdown']}\nfigures: {len(res['figures'])} PNG in "
          f"{Path(res['html']).parent / 'figures'}")
    if res['mismatch']:
        print('ceco report: metrics recomputed from the recorded data differ from metrics.json (see above)',
              file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
