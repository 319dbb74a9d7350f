"""``ceco report DIR... [--out REPORT_DIR] [--vehicle]``: the research report.

For every run directory (docs/architecture.md, "Run directory format") given,
or found one level below a parent of several strategies, and for any rosbag2 bag
with the ceco topics (``ros2 bag record``; scenario and strategy from the bag's
metadata, the recorded parameters, the messages or ``--scenario``/``--strategy``):

1. Load the time series (``ceco_bringup.rundata.load_run``): from the rosbag2
   bag alone when ``DIR/bag`` exists or DIR is a bag (any topic naming: relative, fully
   qualified, namespaced; ``--namespace`` for a bag holding several stacks),
   else from ``DIR/timeseries.csv``. A bag that cannot be read (damaged, or an .mcap without
   metadata.yaml) gives way to ``DIR/timeseries.csv`` with one line saying so (stderr, and a note in the
   report); without a timeseries.csv it is the error (exit status 2, one line naming the bag).
2. Recompute the metrics with ``ceco_core.metrics.run_metrics`` and
   check they equal ``DIR/metrics.json`` (relative tolerance ``--rtol``,
   NaN equals NaN). A mismatch is printed to stderr, shown as a red warning
   in the report, and makes the command exit with status 1. A run a stop left
   without metrics.json (Ctrl-C of ``ceco run``) is reported from its bag, marked
   partial, and never matched against a baseline.
3. Per scenario, first the verdict (``ceco_bringup.verdict``: energy and
   discomfort of each strategy, whether the baseline reached the comfort band,
   the saving at matched comfort against the baseline family the job kept in
   ``verdict.json``, or the command that computes it) and the
   energy-discomfort plane with the baseline front; then the paper's figures (PMV
   with bounds, cabin and vent temperatures, compressor and blower power, the two
   inputs, energy and comfort bars, solver solve times, and with ``--vehicle`` the
   vehicle-level energy change from FASTSim), the metrics table, the solver
   statistics from ``diagnostics.csv`` and the comparison with the paper's numbers.

A failed run (``run.json`` says ``failed``, or ``metrics.json`` has ``status: failed``: its controller did not
control it, or it stopped; ``ceco_bringup.rundata.failed_reason``) shows no number: the report names it with its
reason in the words of ``ceco sim`` (``N of M runs failed (not compared):``, ``ceco_bringup.outputs.failed_lines``)
on the console, in a red box of the report and in its scenario's verdict, and the command exits with status 1;
a directory of failed runs only is reported as such (the same words, no table, exit status 1).

Refused (exit status 2, one line): runs of one scenario name whose scenario copies hash differently
(``provenance.scenario_sha256``: they drove different scenarios; a run without a copy uses ``run.json``'s
stored hash, and one with neither, an older run or a bare bag, is compared as before), complete runs of one
scenario that differ in length (their energies
are not comparable; a partial run is shown, never compared), a ``--scenario``/``--strategy`` that
contradicts what a run records (the flags name what a bag does not say), a run that records no
strategy (without ``--strategy``) and the same run given twice.

Signs: "change" is signed as measured (+ = more), "saving" is energy saved (+ = less
energy); energy counts compressor + blower + condenser fan (docs/metrics.md).

Writes ``REPORT_DIR/report.html`` (self-contained), ``REPORT_DIR/summary.md``,
``REPORT_DIR/metrics.csv`` (one row per run), ``REPORT_DIR/vehicle.csv``
(with ``--vehicle``) and the PNGs under ``REPORT_DIR/figures/``.
"""

from __future__ import annotations

import csv
import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

from ceco_bringup import cli_args, figures
from ceco_bringup import verdict as vd
from ceco_bringup.outputs import (
    failed_lines,
    family_skipped,
    hinted_verdict_lines,
    matched_comfort_hint,
    pmv_scale_cell,
)
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
from ceco_bringup.rundata import UNKNOWN_SCENARIO, FailedRun, RunData, discover_runs, load_runs, solver_stats
from ceco_core.contracts import PLANT_STEP_S
from ceco_core.metrics import ENERGY_PARTS, J_PER_KWH, relative_change_pct

__all__ = ['PAPER_AC_CHANGE_PCT', 'build_report', 'main']

PAPER_AC_CHANGE_PCT = {'ceco-e': -15.9, 'ceco-c': -4.1, 'ceco-ioch': -7.6}
"""A/C energy (compressor + blower) change against the baseline on SC03 [%], negative = less
energy (paper, Sec. 5)."""

VERDICT_FILE = 'verdict.json'

SAME_LENGTH_S = 0.5 * PLANT_STEP_S
"""Runs whose lengths differ by less than this [s] (half a plant step) ran the same length."""


# ---------------------------------------------------------------- formatting
def _met_cell(met) -> str:
    """``air_quality_met`` (1.0 / 0.0 / NaN) as a table cell.

    Not ``report_html.fmt_value`` (which says 'yes' / 'no' for a flag, as comparison.txt does): the report's cell
    says what a 'no' means, 'no: BROKE a limit', and takes the metric's 1.0 / 0.0 / NaN rather than a bool.
    """
    return 'n/a' if met is None or not math.isfinite(float(met)) else ('yes' if met else 'no: BROKE a limit')


def _change_pct(x: Mapping, base: RunData | None, key: str) -> str:
    """The change of metric ``key`` against the baseline run, formatted ('n/a' without one)."""
    return fmt_pct(relative_change_pct(x[key], base.recomputed[key])) if base else 'n/a'


def _paper_energy_change(x: Mapping, base: RunData | None) -> str:
    """The change of compressor + blower energy (the paper's E_tot) against the baseline run."""
    if not base:
        return 'n/a'
    b = base.recomputed
    return fmt_pct(relative_change_pct(x['E_comp_J'] + x['E_blower_J'], b['E_comp_J'] + b['E_blower_J']))


def _reference(group: Mapping[str, RunData], run: RunData) -> RunData | None:
    """The baseline run ``run`` is compared with: None without one or when either is partial (shorter)."""
    base = group.get('baseline')
    return None if base is None or base.partial or run.partial else base


def _group(runs: Sequence[RunData]) -> dict:
    """{scenario: {label: RunData}}.

    The label is the strategy, made unique with the run's path when a scenario holds a
    strategy twice: relative to the directory all runs share ('ceco-c (b/ceco-c)' for runs/a
    and runs/b), so that figure axes do not carry whole absolute paths. Raises ValueError for
    a run given twice.
    """
    import os

    groups: dict = {}
    where = [r.path.resolve() for r in runs]
    common = Path(os.path.commonpath(where)) if where else Path('.')
    for i, r in enumerate(runs):
        if where[i] in where[:i]:
            raise ValueError(f'{r.path}: the same run given twice')
        g = groups.setdefault(r.scenario, {})
        g[r.strategy if r.strategy not in g else f'{r.strategy} ({where[i].relative_to(common)})'] = r
    return groups


def _check_identity(runs: Sequence[RunData], flags: Mapping[str, str | None]) -> None:
    """Every run shown under the scenario and strategy it records.

    ``flags``: {'scenario', 'strategy'} given by the user (None: not given), which only name what a run does
    not record. Raises ValueError for a flag that contradicts a run and for a run that records no strategy
    and gets none (it would be labelled by its directory name).
    """
    for r in runs:
        rec = r.info['recorded']  # (rundata: metrics.json, run.json, else the bag, read once)
        for key, flag in flags.items():
            value, where = rec.get(key, (None, ''))
            if flag is not None and value is not None and value != flag:
                raise ValueError(
                    f'{r.path} records {key} {value!r} ({where}), not --{key} {flag!r}: --{key} names only a run '
                    f'that records none'
                )
        if flags['strategy'] is None and rec['strategy'][0] is None:
            raise ValueError(
                f'{r.path} records no strategy (neither metrics.json, run.json nor a bag names one): name it with '
                '--strategy'
            )


def _scenario_hash(run: RunData) -> str | None:
    """The content hash of the scenario ``run`` drove (``provenance.scenario_sha256``).

    Of the run's scenario copy when it has one (so runs written before the hash was of the content, which
    ``run.json`` holds as a hash of the copy's bytes, compare too), else ``run.json``'s ``scenario_sha256``;
    None when the run records neither (an older run directory, a bare bag).
    """
    from ceco_bringup import provenance

    if run.scenario_path is not None:
        try:
            return provenance.scenario_sha256(run.scenario_path)
        except (OSError, ValueError):  # (a copy that cannot be read: the stored hash, if any)
            pass
    value = run.info.get('scenario_sha256')
    return str(value) if value else None


def _check_content(groups: Mapping[str, Mapping[str, RunData]]) -> None:
    """Raise ValueError when runs of one scenario name drove different scenario files (:func:`_scenario_hash`).

    Two files may share a name (a copy of ``tropical.yaml`` with hotter air): their runs are not comparable.
    Runs that record no hash are left out of this check (older runs, bare bags): they are compared as before.
    """
    for sc, g in groups.items():
        by_hash: dict[str, list[RunData]] = {}
        for r in g.values():
            h = _scenario_hash(r)
            if h is not None:
                by_hash.setdefault(h, []).append(r)
        if len(by_hash) > 1:
            runs = '; '.join(f"{', '.join(str(r.path) for r in rs)} {h}" for h, rs in by_hash.items())
            raise ValueError(
                f'the runs of {sc} drove different scenario files (content hash of each scenario copy: {runs}): '
                'runs are compared only on the same scenario; report each scenario file on its own'
            )


def _same_length(a: float, b: float) -> bool:
    return abs(a - b) < SAME_LENGTH_S


def _check_lengths(groups: Mapping[str, Mapping[str, RunData]]) -> None:
    """Raise ValueError when complete runs of one scenario differ in length: their energies are not comparable.

    Also when several runs record no scenario (``unknown``, rundata): they would be compared as if they had
    driven one.
    """
    unknown = groups.get(UNKNOWN_SCENARIO, {})
    if len(unknown) > 1:
        raise ValueError(
            f"{', '.join(str(r.path) for r in unknown.values())} record no scenario: name it with --scenario "
            '(runs whose scenario is unknown are not compared with each other)'
        )
    for sc, g in groups.items():
        complete = [r for r in g.values() if not r.partial]
        lengths = [r.recomputed['duration_s'] for r in complete]
        if any(not _same_length(x, lengths[0]) for x in lengths):
            runs = ', '.join(f'{r.path} {x:g} s' for r, x in zip(complete, lengths))
            raise ValueError(
                f'the runs of {sc} differ in length ({runs}): energy is compared only over the same length; '
                'report each length on its own'
            )


def _scenario_text(name: str, path: Path | None = None) -> str:
    """The scenario in words, from the run's copy of its file when it kept one."""
    try:
        from ceco_v2x_preview.scenario import load_scenario

        sc = load_scenario(path or name)
    except (ImportError, ValueError, OSError):
        return (
            f'Scenario `{name}`: the run directory keeps no copy of its scenario file (older run) and it is not '
            'among the bundled scenarios: description unavailable.'
        )
    return (
        ('From the run\'s copy of its scenario file. ' if path else '')
        + f'Scenario `{sc.name}`: {sc.description} Drive cycle `{sc.drive_cycle.name}` '
        f'({sc.drive_cycle.distance_m / 1e3:.2f} km over {sc.drive_cycle.duration_s:.0f} s); run length '
        f'{sc.duration_s:.0f} s; ambient {sc.weather_t_amb_c.min():.1f}..{sc.weather_t_amb_c.max():.1f} °C, '
        f'solar {sc.weather_solar_wm2.min():.0f}..{sc.weather_solar_wm2.max():.0f} W/m², '
        f'RH {100 * sc.weather_rh.min():.0f}..{100 * sc.weather_rh.max():.0f} %; occupant '
        f'{sc.occupant.met} met, {sc.occupant.clo} clo; initial cabin {sc.initial.t_cab_c:.1f} °C.'
    )


MISMATCH_REASON = 'its metrics.json does not recompute from its data, {n} MISMATCH above'
"""Why a run whose stored metrics disagree with its time series is left out of the verdict (``{n}``: how many)."""


def _failed_names(failed: Sequence[FailedRun], *, with_path: bool = False) -> dict[str, str]:
    """{name: reason} of the failed runs for ``outputs.failed_lines``.

    The name is the strategy, with the run's path when ``with_path`` (as code) or when two failed runs have the
    same strategy.
    """
    seen = [f.strategy for f in failed]
    out = {}
    for f in failed:
        name = f.strategy
        if with_path:
            name += f' (`{f.path}`)'
        elif seen.count(f.strategy) > 1:
            name += f' ({f.path})'
        out[name] = f.reason
    return out


# ---------------------------------------------------------------- sections
def _intro(runs: Sequence[RunData], rtol: float, log, failed: Sequence[FailedRun] = ()) -> tuple[list, bool]:
    """Title, provenance paragraph, the failed runs and one warning per run whose metrics differ.

    (blocks, any mismatch).
    """
    blocks: list = [
        Heading(1, 'ceco report: energy and comfort of predictive A/C control'),
        Paragraph(
            f'{len(runs)} run(s) from: ' + ', '.join(f'`{r.path}`' for r in runs) + '. Metrics were recomputed '
            'from each run\'s time series (the rosbag2 bag alone when the run has a readable one, else '
            'timeseries.csv; a run whose bag could not be read says so below) and '
            f'compared with its metrics.json (relative tolerance {rtol:g}; for a timeseries.csv written with d '
            'significant digits, 10^(1-d), the precision the file holds).'
        ),
    ]
    if not runs:
        blocks[1] = Paragraph('No run to report: every run found failed (below); a failed run shows no number.')
    lines = failed_lines(_failed_names(failed, with_path=True), len(runs) + len(failed))
    if lines:  # a failed run shows no number, but it is named with its reason
        blocks.append(Warning(lines[0] + ' ' + '; '.join(line.strip() for line in lines[1:])))
    for r in runs:
        if r.partial:
            msg = (
                f'{r.path} is a partial run ({r.partial}): its metrics cover what was recorded, and it is not '
                'compared with complete runs at matched comfort'
            )
            blocks.append(Warning(msg))
            log(f'ceco report: PARTIAL: {msg}', file=sys.stderr)
        for note in r.notes:
            blocks.append(Paragraph(f'Note on `{r.path}`: {note}.'))
        if r.bag_unread:  # a damaged bag beside intact data: reported from the data, said once on the console
            log(f'ceco report: {r.path}: {r.bag_unread}', file=sys.stderr)
        if r.mismatches:
            detail = '; '.join(f'{k}: metrics.json {a!r} vs recomputed {b!r}' for k, a, b in r.mismatches)
            msg = f'metrics of {r.path} recomputed from {r.source} differ from metrics.json: {detail}'
            blocks.append(Warning(msg))
            log(f'ceco report: MISMATCH: {msg}', file=sys.stderr)
    return blocks, any(r.mismatches for r in runs)


def _metrics_table(
    scenario: str, group: Mapping[str, RunData], labels: Sequence[str], kpis: Mapping[str, Mapping]
) -> tuple[Table, list]:
    """The metrics table of one scenario and its metrics.csv rows.

    Energy in kWh with its parts, discomfort, and the validity beside the comfort numbers.
    """
    rows, csv_rows = [], []
    for lab in labels:
        r = group[lab]
        base = _reference(group, r)
        x = r.recomputed
        k = kpis[lab]
        rows.append(
            (
                lab + (' (partial)' if r.partial else ''),
                fmt_num(x['E_tot_kWh'], 4),
                fmt_num(x['E_comp_J'] / J_PER_KWH, 4),
                fmt_num(x['E_blower_J'] / J_PER_KWH, 4),
                fmt_num(x['E_fan_J'] / J_PER_KWH, 4),
                _change_pct(x, base, 'E_tot_J'),
                fmt_num(k['discomfort_pmvh'], 3),
                fmt_num(x['I_pmv'], 1),
                fmt_num(x['otc_violation_pct'], 1),
                fmt_num(x['time_to_comfort_s'], 0),
                fmt_num(x['pmv_mean'], 3),
                pmv_scale_cell(x['pmv_max']),
                fmt_num(k['iso7730_invalid_pct'] if k['iso7730_invalid_pct'] is not None else math.nan, 1),
                fmt_num(x.get('co2_max_ppm', math.nan), 0),
                fmt_num(x.get('co2_above_limit_pct', math.nan), 1),
                fmt_num(x.get('fog_below_bound_s', math.nan), 0),
                _met_cell(x.get('air_quality_met', math.nan)),
                r.source,
                'no metrics.json'
                if not r.stored
                else (f'OK (≤ {r.check_rtol:.0e})' if not r.mismatches else f'MISMATCH ({len(r.mismatches)})'),
            )
        )
        csv_rows.append(
            {
                'scenario': scenario,
                'strategy': r.strategy,
                'run_dir': str(r.path),
                'source': r.source,
                'partial': r.partial,
                'metrics_match': not r.mismatches,
                'max_rel_diff': r.max_rel_diff,
                **x,
                'energy_change_pct': relative_change_pct(x['E_tot_J'], base.recomputed['E_tot_J'])
                if base
                else math.nan,
                'discomfort_pmvh': k['discomfort_pmvh'],
                'iso7730_invalid_pct': k['iso7730_invalid_pct'],
            }
        )
    table = Table(
        (
            'strategy',
            'E [kWh]',
            'E comp [kWh]',
            'E blower [kWh]',
            'E fan [kWh]',
            'E change [%]',
            'D [PMV h]',
            'I_PMV [s]',
            'viol. [%]',
            't_comfort [s]',
            'PMV mean',
            'PMV max',
            'ISO out [%]',
            'CO2 max [ppm]',
            'CO2>limit [%]',
            'fog<bound [s]',
            'air quality met',
            'from',
            'vs metrics.json',
        ),
        rows,
        caption=f'Metrics per strategy. E: A/C energy, {ENERGY_PARTS}. E change: against the baseline run, as '
        'measured (+ = more energy; n/a for a partial run). D: discomfort, PMV-hours outside -0.5..+0.5 with '
        'PMV clipped at ±3. I_PMV = ∫PMV² dt (the paper\'s). viol.: share of time outside the scenario\'s PMV '
        'bounds; t_comfort: first time PMV stays in -0.5..+0.5 for 60 s. PMV beyond ±3 is off ISO 7730\'s '
        'scale (shown >3: clipped); ISO out: share of samples whose PMV or its inputs lie outside ISO 7730 '
        'validity (comfort numbers there are extrapolations). Air quality against the scenario\'s limits '
        '(docs/metrics.md, "Air quality"): CO2 max, CO2>limit (share of time above the CO2 limit), fog<bound (time '
        'with the fog margin below its bound); air quality met: no when the run broke a limit (it is then not '
        'matched: no saving); n/a: not recorded, or the limits are unknown.',
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
            'A/C energy (compressor solid, blower hatched, condenser fan dotted), comfort index I_PMV and bound '
            'violation; labels give the change against the baseline as measured (+ = more).',
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
    prius = {r['strategy']: r for r in (vrows or []) if r['powertrain'] == 'HEV'}
    rows = []
    for lab in labels:
        if lab == 'baseline':
            continue
        x = group[lab].recomputed
        base = _reference(group, group[lab])
        pr = prius.get(lab)
        rows.append(
            (
                lab,
                _paper_energy_change(x, base),
                fmt_pct(PAPER_AC_CHANGE_PCT.get(lab, float('nan'))),
                _change_pct(x, base, 'E_tot_J'),
                fmt_pct(pr['change_fit_pct']) if pr else 'not computed (use --vehicle)',
                fmt_pct(pr['paper_change_pct']) if pr else fmt_pct(float('nan')),
                _change_pct(x, base, 'I_pmv'),
                fmt_num(x['otc_violation_pct'], 2),
            )
        )
    blocks = [
        Heading(3, 'Comparison with the paper (SC03, Prius HEV)'),
        Table(
            (
                'strategy',
                'E comp+blower change (ours)',
                'E comp+blower change (paper)',
                'E change with fan (ours)',
                'vehicle energy change (ours, Prius)',
                'vehicle energy change (paper)',
                'I_PMV change (ours)',
                'viol. [%] (ours)',
            ),
            rows,
            caption='Changes against the baseline run, as measured (negative = less). The paper counts compressor '
            '+ blower and reports A/C energy -15.9 / -4.1 / -7.6 % and vehicle energy -6.4 / -1.8 / -3.1 % for '
            'CECO-E / CECO-C / CECO-IOCH on SC03 (CoolSim plant, 2017 Prius HEV), each at a different comfort '
            'than the baseline; the verdict above gives the saving at matched comfort.',
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


def _family_for(scenario: str, group: Mapping[str, RunData]) -> tuple[dict, str, str]:
    """The baseline family a job kept for these runs: (family, how it was run, the file).

    From ``verdict.json`` in a run directory or its parent, same scenario and length; ({}, '', '')
    when there is none.
    """
    duration = max(r.recomputed['duration_s'] for r in group.values())
    seen = set()
    for r in group.values():
        for d in (r.path, r.path.parent):
            f = d / VERDICT_FILE
            if f in seen or not f.is_file():
                continue
            seen.add(f)
            try:
                data = vd.read_verdict(f)
            except (ValueError, OSError):
                continue
            if data.get('scenario') == scenario and _same_length(float(data.get('duration_s', -1)), duration):
                if data.get('family') or data.get('family_failed'):
                    # the members that failed come back as build_verdict takes them: named, on no front
                    failed = {k: {vd.FAILED_KEY: str(why)} for k, why in dict(data.get('family_failed') or {}).items()}
                    return {**dict(data.get('family') or {}), **failed}, str(data.get('family_source', '')), str(f)
    return {}, '', ''


def _verdict_paragraphs(lines: Sequence[str]) -> list:
    """The verdict lines as paragraphs (a continuation line, indented, joins the line before it)."""
    paras: list[str] = []
    for line in lines:
        if paras and line.startswith('   '):
            paras[-1] += ' ' + line.strip()
        else:
            paras.append(line.strip())
    return [Paragraph(p) for p in paras]


def _scenario_as_given(scenario: str, runs: Sequence[RunData]) -> str:
    """The scenario as ``--scenario`` takes it, never a file's ``name:`` (which it does not take).

    What the runs were given (``run.json``'s ``scenario_source``) when it is a bundled name or a file here, else a
    run's copy of its scenario file, else the name (a bag's).
    """
    from ceco_core.cli_flags import BUNDLED_SCENARIOS

    for r in runs:
        src = str(r.info.get('scenario_source') or '')
        if src and (src in BUNDLED_SCENARIOS or Path(src).is_file()):
            return src
    copies = [r.scenario_path for r in runs if r.scenario_path is not None]
    return str(copies[0]) if copies else scenario


def _matched_comfort_hint(scenario: str, runs: Sequence[RunData]) -> tuple[str, str]:
    """``outputs.matched_comfort_hint`` for runs shown without a baseline family.

    The cause when their ``run.json`` say ``--baseline-setpoints-c none`` (the command without it when they are
    one job's), the verb they were made with (``ceco run`` when unknown) and the scenario as given.
    """
    known = [r.info for r in runs if r.info.get('verb')]
    every = bool(known) and len(known) == len(runs)
    verbs = sorted({str(i['verb']) for i in known})
    jobs = sorted({(str(i['verb']), str(i.get('cwd') or ''), *(str(a) for a in i.get('argv') or ())) for i in known})
    one_job = every and len(jobs) == 1  # one job's runs: its command, where it was typed
    return matched_comfort_hint(
        verbs[0] if len(verbs) == 1 else 'run',
        _scenario_as_given(scenario, runs),
        argv=list(jobs[0][2:]) if one_job else None,
        skipped=every and all(family_skipped(i.get('argv')) for i in known),
        cwd=jobs[0][1] if one_job else None,
    )


def _verdict_section(
    scenario: str, group: Mapping[str, RunData], fig_dir: Path, failed: Mapping[str, str] | None = None
) -> tuple[list, Path, list]:
    """The verdict of one scenario in words and the energy-discomfort plane: (blocks, figure, console lines).

    ``failed``: {name: reason} of the scenario's failed runs, named in the verdict.
    """
    labels = figures.ordered(list(group))
    points = {lab: vd.run_point(group[lab].columns, group[lab].air_limits) for lab in labels}
    family, source, kept_in = _family_for(scenario, group)
    limits = next((group[lab].air_limits for lab in labels if group[lab].air_limits is not None), None)
    v = vd.build_verdict(
        scenario,
        points,
        family,
        family_source=source,
        family_file=kept_in,
        partial={lab: group[lab].partial for lab in labels if group[lab].partial},
        air_limits=limits,
        failed=failed,
    )
    hint = _matched_comfort_hint(scenario, [group[lab] for lab in labels])
    lines = hinted_verdict_lines(v, hint)
    fig = figures.fig_plane(
        {lab: p for lab, p in points.items() if lab not in v.partial},
        family,
        fig_dir / f'{slug(scenario)}_plane.png',
        f'Energy against discomfort, {scenario}',
    )
    caption = 'Energy against discomfort of every run' + (
        ' with the baseline fronts (the production law and the tuned law at several set-points; hollow: not'
        ' efficient). A run below both fronts at its discomfort uses less energy than either law at the same'
        ' comfort.'
        if family
        else '; no baseline family was kept for these runs, so no front is drawn.'
    )
    paras = [Paragraph(f'`{hint[1]}`') if p.text == hint[1] else p for p in _verdict_paragraphs(lines)]
    blocks = [Heading(2, f'Verdict: {scenario}'), *paras, Figure(fig, caption)]
    return blocks, fig, lines


def _scenario_section(scenario: str, group: Mapping[str, RunData], fig_dir: Path, vehicle_settings) -> dict:
    """Every block of one scenario: {'blocks', 'figures', 'metric_rows', 'vehicle_rows' (None without --vehicle)}."""
    from ceco_core.kpis import compute_kpis

    labels = figures.ordered(list(group))
    kpis = {lab: compute_kpis(group[lab].columns, air_limits=group[lab].air_limits)[0] for lab in labels}
    table, metric_rows = _metrics_table(scenario, group, labels, kpis)
    paths = [group[lab].scenario_path for lab in labels if group[lab].scenario_path is not None]
    blocks: list = [
        Heading(2, f'Scenario {scenario}'),
        Paragraph(_scenario_text(scenario, paths[0] if paths else None)),
        table,
    ]
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
    scenario: str | None = None,
    strategy: str | None = None,
    log=print,
) -> dict:
    """Build the report.

    ``scenario``/``strategy`` name the run of a bag that does not say which it is.
    Returns ``{'html', 'markdown', 'metrics_csv', 'vehicle_csv', 'figures': [...],
    'runs': [RunData], 'failed': [FailedRun], 'mismatch': bool, 'vehicle_rows': {scenario: rows},
    'verdict': [lines]}``. Failed runs (``rundata.load_runs``) are named, never loaded.
    """
    out = Path(out_dir)
    fig_dir = out / 'figures'
    found = discover_runs(run_dirs)
    log(f'ceco report: loading {len(found)} run(s)', file=sys.stderr)
    runs, failed = load_runs(found, rtol=rtol, namespace=namespace, scenario=scenario, strategy=strategy)
    _check_identity(runs, {'scenario': scenario, 'strategy': strategy})
    groups = _group(runs)
    _check_content(groups)
    _check_lengths(groups)
    fig_dir.mkdir(parents=True, exist_ok=True)
    blocks, any_mismatch = _intro(runs, rtol, log, failed)
    if vehicle and vehicle_settings is None:
        from ceco_bringup import vehicle_energy as ve

        vehicle_settings = ve.VehicleEnergySettings()
    all_figs: list[Path] = []
    metric_rows: list[dict] = []
    vehicle_all: dict = {}
    verdict_lines: list[str] = []
    for sc, group in groups.items():  # the verdicts first: the top of the report
        here = _failed_names([f for f in failed if f.scenario == sc])
        # a run whose metrics.json does not recompute from its data is no result: named, never in the verdict
        here.update({lab: MISMATCH_REASON.format(n=len(r.mismatches)) for lab, r in group.items() if r.mismatches})
        kept = {lab: r for lab, r in group.items() if not r.mismatches}
        if not kept:
            blocks.append(Paragraph(f'No verdict on {sc}: ' + '; '.join(f'{k}: {w}' for k, w in here.items())))
            verdict_lines += [f'No verdict on {sc}: every run\'s metrics.json disagrees with its data (MISMATCH)']
            continue
        vblocks, vfig, lines = _verdict_section(sc, kept, fig_dir, here)
        blocks += vblocks
        all_figs.append(vfig)
        verdict_lines += lines
    for sc, group in groups.items():
        log(f'ceco report: {sc}: figures and tables' + (' (FASTSim)' if vehicle else ''), file=sys.stderr)
        sec = _scenario_section(sc, group, fig_dir, vehicle_settings if vehicle else None)
        blocks += sec['blocks']
        all_figs += sec['figures']
        metric_rows += sec['metric_rows']
        if sec['vehicle_rows'] is not None:
            vehicle_all[sc] = sec['vehicle_rows']
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
        'failed': failed,
        'mismatch': any_mismatch,
        'vehicle_rows': vehicle_all,
        'verdict': verdict_lines,
    }


def build_parser() -> cli_args.Parser:
    """The argument parser of `ceco report`."""
    parser = cli_args.Parser(
        'ceco report',
        'Recompute the metrics of run directories or rosbag2 bags (from the bag when present) and write the '
        'verdict, figures, a self-contained HTML report and a Markdown summary.',
    )
    parser.add_argument(
        'dirs',
        nargs='+',
        metavar='DIR',
        help='run directories, parents holding one run directory per strategy, or rosbag2 bags',
    )
    cli_args.add_out(parser, 'report directory (default: DIR/report for one DIR, else ./ceco_report)', required=False)
    parser.add_argument(
        '--vehicle',
        action='store_true',
        help='add vehicle-level energy with FASTSim 3.1 (optional extra: requirements/analysis.txt)',
    )
    parser.add_argument(
        '--rtol',
        type=cli_args.positive_float,
        default=1e-6,
        help='relative tolerance (> 0) of the metrics.json check (the stack\'s agreement criterion; a bag holds '
        'float64 and agrees far closer; for a timeseries.csv never tighter than the precision it was written '
        'with, and the run\'s line says so)',
    )
    cli_args.add_namespace(parser, 'namespace of the recorded stack in the bags (default: the only one in each bag)')
    cli_args.add_scenario(
        parser, default=None, help_extra=' of a bag that does not name it (default: its metadata or parameters)'
    )
    parser.add_argument(
        '--strategy',
        default=None,
        help='strategy of a bag that does not name it (default: its metadata, parameters or messages)',
    )
    return parser


def _tolerance(run: RunData, rtol: float) -> str:
    """The tolerance the check of ``run`` used, and why when it is looser than ``rtol``."""
    used = f'{run.check_rtol:.0e}'
    return used if run.check_rtol <= rtol else f'{used}: the precision of {run.source}, looser than --rtol {rtol:g}'


def main(argv=None) -> int:
    """`ceco report`: 0 when every run's metrics check, 1 on a mismatch or a failed run, 2 on an error (one line)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    cli_args.check_out(parser, args.out)
    out = (
        Path(args.out) if args.out else (Path(args.dirs[0]) / 'report' if len(args.dirs) == 1 else Path('ceco_report'))
    )
    try:
        res = build_report(
            args.dirs,
            out,
            vehicle=args.vehicle,
            rtol=args.rtol,
            namespace=args.namespace,
            scenario=args.scenario,
            strategy=args.strategy,
        )
    except (ValueError, OSError, ImportError) as exc:
        print(f'ceco report: error: {exc}', file=sys.stderr)
        return 2
    for line in res['verdict']:
        print(line)
    for r in res['runs']:
        state = 'no metrics.json' if not r.stored else ('OK' if not r.mismatches else 'MISMATCH')
        print(
            f'{r.path}: {r.strategy} on {r.scenario}, metrics from {r.source}: {state}'
            + (f' (max rel. diff {r.max_rel_diff:.1e}, tolerance {_tolerance(r, args.rtol)})' if r.stored else '')
            + (f'; PARTIAL ({r.partial})' if r.partial else '')
        )
    for f in res['failed']:
        print(f'{f.path}: {f.strategy} on {f.scenario}: FAILED, not compared')
    for line in failed_lines(_failed_names(res['failed']), len(res['runs']) + len(res['failed'])):
        print(line)
    print(
        f"report: {res['html']}\nsummary: {res['markdown']}\nfigures: {len(res['figures'])} PNG in "
        f"{Path(res['html']).parent / 'figures'}"
    )
    if res['mismatch']:
        print(
            'ceco report: metrics recomputed from the recorded data differ from metrics.json (see above)',
            file=sys.stderr,
        )
    if res['failed']:
        print(
            'ceco report: '
            + ('every run failed: nothing to compare' if not res['runs'] else 'failed runs are not compared')
            + ' (see above)',
            file=sys.stderr,
        )
    return 1 if res['mismatch'] or res['failed'] else 0


if __name__ == '__main__':
    sys.exit(main())
