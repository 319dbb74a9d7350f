"""``ceco report DIR... [--out REPORT_DIR] [--vehicle]``: the research report.

For every run directory (docs/architecture.md, "Run directory format") given,
or found one level below a ``--strategy all`` parent:

1. Load the time series (``ceco_bringup.rundata.load_run``): from the rosbag2
   bag alone when ``DIR/bag`` exists (any topic naming: relative, fully
   qualified, namespaced; ``--namespace`` for a bag holding several stacks),
   else from ``DIR/timeseries.csv``.
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
import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

from ceco_bringup import figures
from ceco_bringup.report_html import (
    Figure,
    Heading,
    Paragraph,
    Table,
    Warning,
    fmt_num,
    fmt_pct,
    render_html,
    render_markdown,
    slug,
)
from ceco_bringup.report_vehicle import vehicle_rows, vehicle_section
from ceco_bringup.rundata import RunData, discover_runs, load_run, solver_stats
from ceco_core.metrics import relative_change_pct

__all__ = ['PAPER_AC_SAVING_PCT', 'build_report', 'main']

PAPER_AC_SAVING_PCT = {'ceco-e': -15.9, 'ceco-c': -4.1, 'ceco-ioch': -7.6}
"""A/C energy change against the baseline on SC03 [%] (paper, Sec. 5)."""


# ---------------------------------------------------------------- formatting
def _change_pct(x: Mapping, base: RunData | None, key: str) -> str:
    """The change of metric ``key`` against the baseline run, formatted ('n/a' without one)."""
    return fmt_pct(relative_change_pct(x[key], base.recomputed[key])) if base else 'n/a'


def _group(runs: Sequence[RunData]) -> dict:
    """{scenario: {label: RunData}}.

    The label is the strategy, made unique with the directory name when a scenario
    holds a strategy twice.
    """
    groups: dict = {}
    for r in runs:
        g = groups.setdefault(r.scenario, {})
        label = r.strategy if r.strategy not in g else f'{r.strategy} ({r.path.name})'
        g[label] = r
    return groups


def _scenario_text(name: str) -> str:
    try:
        from ceco_v2x_preview.scenario import load_scenario

        sc = load_scenario(name)
    except (ImportError, ValueError, OSError):
        return f'Scenario `{name}` (not found among the bundled scenarios: description unavailable).'
    return (
        f'Scenario `{sc.name}`: {sc.description} Drive cycle `{sc.drive_cycle.name}` '
        f'({sc.drive_cycle.distance_m / 1e3:.2f} km over {sc.drive_cycle.duration_s:.0f} s); run length '
        f'{sc.duration_s:.0f} s; ambient {sc.weather_t_amb_c.min():.1f}..{sc.weather_t_amb_c.max():.1f} °C, '
        f'solar {sc.weather_solar_wm2.min():.0f}..{sc.weather_solar_wm2.max():.0f} W/m², '
        f'RH {100 * sc.weather_rh.min():.0f}..{100 * sc.weather_rh.max():.0f} %; occupant '
        f'{sc.occupant.met} met, {sc.occupant.clo} clo; initial cabin {sc.initial.t_cab_c:.1f} °C.'
    )


# ---------------------------------------------------------------- sections
def _intro(runs: Sequence[RunData], rtol: float, log) -> tuple[list, bool]:
    """Title, provenance paragraph and one warning per run whose metrics differ; (blocks, any mismatch)."""
    blocks: list = [
        Heading(1, 'ceco report: energy and comfort of predictive A/C control'),
        Paragraph(
            f'{len(runs)} run(s) from: ' + ', '.join(f'`{r.path}`' for r in runs) + '. Metrics were recomputed '
            'from each run\'s time series (the rosbag2 bag alone when the run has one, else timeseries.csv) and '
            f'compared with its metrics.json (relative tolerance {rtol:g}; for a timeseries.csv written with d '
            'significant digits, 10^(1-d), the precision the file holds).'
        ),
    ]
    for r in runs:
        if r.mismatches:
            detail = '; '.join(f'{k}: metrics.json {a!r} vs recomputed {b!r}' for k, a, b in r.mismatches)
            msg = f'metrics of {r.path} recomputed from {r.source} differ from metrics.json: {detail}'
            blocks.append(Warning(msg))
            log(f'ceco report: MISMATCH: {msg}', file=sys.stderr)
    return blocks, any(r.mismatches for r in runs)


def _metrics_table(scenario: str, group: Mapping[str, RunData], labels: Sequence[str]) -> tuple[Table, list]:
    """The metrics table of one scenario and its metrics.csv rows."""
    base = group.get('baseline')
    rows, csv_rows = [], []
    for lab in labels:
        r = group[lab]
        x = r.recomputed
        rows.append(
            (
                lab,
                fmt_num(x['E_tot_kWh'], 4),
                _change_pct(x, base, 'E_tot_J'),
                fmt_num(x['E_comp_J'] / 1e3, 1),
                fmt_num(x['E_blower_J'] / 1e3, 1),
                fmt_num(x['P_mean_w'], 0),
                fmt_num(x['I_pmv'], 1),
                _change_pct(x, base, 'I_pmv'),
                fmt_num(x['otc_violation_pct'], 2),
                fmt_num(x['time_to_comfort_s'], 0),
                fmt_num(x['pmv_mean'], 3),
                fmt_num(x['pmv_max'], 3),
                r.source,
                (f'OK (≤ {r.check_rtol:.0e})' if not r.mismatches else f'MISMATCH ({len(r.mismatches)})'),
            )
        )
        csv_rows.append(
            {
                'scenario': scenario,
                'strategy': r.strategy,
                'run_dir': str(r.path),
                'source': r.source,
                'metrics_match': not r.mismatches,
                'max_rel_diff': r.max_rel_diff,
                **x,
            }
        )
    table = Table(
        (
            'strategy',
            'E_tot [kWh]',
            'ΔE_tot',
            'E_comp [kJ]',
            'E_bl [kJ]',
            'P_mean [W]',
            'I_PMV [s]',
            'ΔI_PMV',
            'OTC viol. [%]',
            't_comfort [s]',
            'PMV mean',
            'PMV max',
            'from',
            'vs metrics.json',
        ),
        rows,
        caption='Metrics per strategy (Δ: change against the baseline). I_PMV = ∫PMV² dt; '
        'OTC violation: share of time outside the PMV bounds; t_comfort: first time '
        'PMV stays in -0.5..0.5 for 60 s.',
    )
    return table, csv_rows


def _time_figures(scenario: str, group: Mapping[str, RunData], labels: Sequence[str], fig_dir: Path) -> list:
    """(path, caption) of the time-series, bar and solver figures of one scenario."""
    name = slug(scenario)
    cols = {lab: group[lab].columns for lab in labels}
    metrics = {lab: group[lab].recomputed for lab in labels}
    figs = [
        (
            figures.fig_pmv(cols, fig_dir / f'{name}_pmv.png', f'PMV and its bounds, {scenario}'),
            'PMV of every strategy; grey band: the scenario\'s comfort bounds (relaxed upper bound during the '
            'initial pull-down).',
        ),
        (
            figures.fig_temperatures(
                cols, fig_dir / f'{name}_temperatures.png', f'Cabin and vent air temperatures, {scenario}'
            ),
            'Cabin air temperature (top, with the ambient) and vent (evaporator outlet) air temperature.',
        ),
        (
            figures.fig_powers(cols, fig_dir / f'{name}_powers.png', f'A/C electrical power, {scenario}'),
            'Compressor (top) and blower (bottom) electrical power, means over each 1 s plant step.',
        ),
        (
            figures.fig_inputs(cols, fig_dir / f'{name}_inputs.png', f'Control inputs, {scenario}'),
            'The two inputs: blower air mass flow and evaporator temperature set-point.',
        ),
        (
            figures.fig_bars(metrics, fig_dir / f'{name}_bars.png', f'Energy and comfort, {scenario}'),
            'A/C energy (compressor solid, blower hatched), comfort index I_PMV and bound violation; labels '
            'give the change against the baseline.',
        ),
    ]
    diags = {lab: group[lab].diagnostics for lab in labels if group[lab].diagnostics is not None}
    if any(solver_stats(d)['solver_steps'] for d in diags.values()):
        figs.append(
            (
                figures.fig_solver(diags, fig_dir / f'{name}_solver.png', f'NMPC solve time, {scenario}'),
                'Distribution of the NMPC solve time per control step (log scale) and fallbacks.',
            )
        )
    return figs


def _paper_comparison(scenario: str, group: Mapping[str, RunData], labels: Sequence[str], vrows) -> list:
    """The comparison with the paper's SC03 numbers (A/C and, with --vehicle, Prius energy)."""
    base = group.get('baseline')
    prius = {r['strategy']: r for r in (vrows or []) if r['powertrain'] == 'HEV'}
    rows = []
    for lab in labels:
        if lab == 'baseline':
            continue
        x = group[lab].recomputed
        pr = prius.get(lab)
        rows.append(
            (
                lab,
                _change_pct(x, base, 'E_tot_J'),
                fmt_pct(PAPER_AC_SAVING_PCT.get(lab, float('nan'))),
                fmt_pct(pr['saving_fit_pct']) if pr else 'not computed (use --vehicle)',
                fmt_pct(pr['paper_saving_pct']) if pr else fmt_pct(float('nan')),
                _change_pct(x, base, 'I_pmv'),
                fmt_num(x['otc_violation_pct'], 2),
            )
        )
    blocks = [
        Heading(3, 'Comparison with the paper (SC03, Prius HEV)'),
        Table(
            (
                'strategy',
                'ΔE_A/C (ours)',
                'ΔE_A/C (paper)',
                'Δ vehicle energy (ours, Prius)',
                'Δ vehicle energy (paper)',
                'ΔI_PMV (ours)',
                'OTC viol. [%] (ours)',
            ),
            rows,
            caption='Changes against the baseline. The paper reports A/C energy -15.9 / -4.1 / -7.6 % and vehicle '
            'energy -6.4 / -1.8 / -3.1 % for CECO-E / CECO-C / CECO-IOCH on SC03 (CoolSim plant, 2017 '
            'Prius HEV).',
        ),
    ]
    if scenario != 'sc03':
        blocks.append(Paragraph('The paper\'s numbers are for SC03: they are shown for orientation only.'))
    return blocks


def _solver_table(group: Mapping[str, RunData], labels: Sequence[str]) -> list:
    """The solver statistics of one scenario."""
    rows = []
    for lab in labels:
        s = solver_stats(group[lab].diagnostics)
        status = ', '.join(f'{k}: {v}' for k, v in sorted(s['statuses'].items(), key=lambda kv: -kv[1])[:4])
        kinds = ', '.join(f'{k}: {v}' for k, v in s['fallback_kinds'].items())
        rows.append(
            (
                lab,
                str(s['steps']),
                str(s['solver_steps']),
                fmt_num(s['success_pct'], 1),
                str(s['fallbacks']) + (f' ({kinds})' if kinds else ''),
                fmt_num(s['solve_ms_median'], 1),
                fmt_num(s['solve_ms_p95'], 1),
                fmt_num(s['solve_ms_max'], 1),
                fmt_num(s['iter_median'], 0),
                fmt_num(s['iter_max'], 0),
                status or ('no diagnostics.csv' if group[lab].diagnostics is None else ''),
            )
        )
    return [
        Heading(3, 'Solver statistics'),
        Table(
            (
                'strategy',
                'control steps',
                'solves',
                'success [%]',
                'fallbacks',
                'solve median [ms]',
                'p95 [ms]',
                'max [ms]',
                'iter. median',
                'iter. max',
                'statuses',
            ),
            rows,
            caption='From diagnostics.csv (the baseline has no solver).',
        ),
    ]


def _scenario_section(scenario: str, group: Mapping[str, RunData], fig_dir: Path, vehicle_settings) -> dict:
    """Every block of one scenario: {'blocks', 'figures', 'metric_rows', 'vehicle_rows' (None without --vehicle)}."""
    labels = figures.ordered(list(group))
    table, metric_rows = _metrics_table(scenario, group, labels)
    blocks: list = [Heading(2, f'Scenario {scenario}'), Paragraph(_scenario_text(scenario)), table]
    figs = _time_figures(scenario, group, labels, fig_dir)
    vrows = None
    if vehicle_settings is not None:
        vrows, note, mixed = vehicle_rows(scenario, group, vehicle_settings)
    blocks += _paper_comparison(scenario, group, labels, vrows)
    if vrows is not None:
        vblocks, vfig = vehicle_section(scenario, vrows, note, mixed, fig_dir)
        blocks += vblocks
        figs.append(vfig)
    blocks += _solver_table(group, labels)
    blocks.append(Heading(3, 'Figures'))
    blocks += [Figure(path, cap) for path, cap in figs]
    return {'blocks': blocks, 'figures': [p for p, _ in figs], 'metric_rows': metric_rows, 'vehicle_rows': vrows}


def _write_rows(path: Path, rows: Sequence[Mapping]) -> None:
    keys: list = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    with open(path, 'w', newline='', encoding='utf-8') as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in r.items()})


def build_report(
    run_dirs: Sequence[str | Path],
    out_dir: str | Path,
    *,
    vehicle: bool = False,
    rtol: float = 1e-6,
    vehicle_settings=None,
    namespace: str | None = None,
    log=print,
) -> dict:
    """Build the report.

    Returns ``{'html', 'markdown', 'metrics_csv', 'vehicle_csv', 'figures': [...],
    'runs': [RunData], 'mismatch': bool, 'vehicle_rows': {scenario: rows}}``.
    """
    out = Path(out_dir)
    fig_dir = out / 'figures'
    fig_dir.mkdir(parents=True, exist_ok=True)
    runs = [load_run(d, rtol=rtol, namespace=namespace) for d in discover_runs(run_dirs)]
    blocks, any_mismatch = _intro(runs, rtol, log)
    if vehicle and vehicle_settings is None:
        from ceco_bringup import vehicle_energy as ve

        vehicle_settings = ve.VehicleEnergySettings()
    all_figs: list[Path] = []
    metric_rows: list[dict] = []
    vehicle_all: dict = {}
    for scenario, group in _group(runs).items():
        sec = _scenario_section(scenario, group, fig_dir, vehicle_settings if vehicle else None)
        blocks += sec['blocks']
        all_figs += sec['figures']
        metric_rows += sec['metric_rows']
        if sec['vehicle_rows'] is not None:
            vehicle_all[scenario] = sec['vehicle_rows']
    (out / 'summary.md').write_text(render_markdown(blocks, base_dir=out), encoding='utf-8')
    (out / 'report.html').write_text(render_html(blocks), encoding='utf-8')
    _write_rows(out / 'metrics.csv', metric_rows)
    vehicle_csv = None
    if vehicle_all:
        vehicle_csv = out / 'vehicle.csv'
        _write_rows(vehicle_csv, [{'scenario': s, **r} for s, rows in vehicle_all.items() for r in rows])
    return {
        'html': out / 'report.html',
        'markdown': out / 'summary.md',
        'metrics_csv': out / 'metrics.csv',
        'vehicle_csv': vehicle_csv,
        'figures': all_figs,
        'runs': runs,
        'mismatch': any_mismatch,
        'vehicle_rows': vehicle_all,
    }


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of `ceco report`."""
    parser = argparse.ArgumentParser(
        prog='ceco report',
        description='Recompute the metrics of run directories (from the bag when present) '
        'and write figures, a self-contained HTML report and a Markdown summary.',
    )
    parser.add_argument(
        'dirs', nargs='+', metavar='DIR', help='run directories, or parents holding one run directory per strategy'
    )
    parser.add_argument(
        '--out', default=None, help='report directory (default: DIR/report for one DIR, else ./ceco_report)'
    )
    parser.add_argument(
        '--vehicle',
        action='store_true',
        help='add vehicle-level energy with FASTSim 3.1 (optional extra: requirements/analysis.txt)',
    )
    parser.add_argument(
        '--rtol',
        type=float,
        default=1e-6,
        help='relative tolerance of the metrics.json check (default 1e-6, the stack\'s '
        'agreement criterion; a bag holds float64 and agrees far closer)',
    )
    parser.add_argument(
        '--namespace',
        default=None,
        help='namespace of the recorded stack in the bags (default: the only one in each bag)',
    )
    return parser


def main(argv=None) -> int:
    """`ceco report`: 0 when every run's metrics check, 1 on a mismatch, 2 on an error."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not (math.isfinite(args.rtol) and args.rtol >= 0):
        parser.error(f'--rtol: must be finite and >= 0, got {args.rtol}')
    out = (
        Path(args.out) if args.out else (Path(args.dirs[0]) / 'report' if len(args.dirs) == 1 else Path('ceco_report'))
    )
    try:
        res = build_report(args.dirs, out, vehicle=args.vehicle, rtol=args.rtol, namespace=args.namespace)
    except (ValueError, OSError, ImportError) as exc:
        print(f'ceco report: error: {exc}', file=sys.stderr)
        return 2
    for r in res['runs']:
        state = 'OK' if not r.mismatches else 'MISMATCH'
        print(
            f'{r.path}: {r.strategy} on {r.scenario}, metrics from {r.source}: {state} '
            f'(max rel. diff {r.max_rel_diff:.1e}, tolerance {r.check_rtol:.0e})'
        )
    print(
        f"report: {res['html']}\nsummary: {res['markdown']}\nfigures: {len(res['figures'])} PNG in "
        f"{Path(res['html']).parent / 'figures'}"
    )
    if res['mismatch']:
        print(
            'ceco report: metrics recomputed from the recorded data differ from metrics.json (see above)',
            file=sys.stderr,
        )
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
