"""What ``ceco run`` and ``ceco sim`` print and keep: run lines, the comparison table, the verdict.

One vocabulary in every output (docs/metrics.md, "Signs and units"):

* energy ``E`` = compressor + blower + condenser fan, always in kWh (the parts beside it);
* ``change`` = signed as measured against the baseline run (+ = more); ``saving`` = energy saved
  (+ = less energy), here at matched comfort against the baseline family (``verdict``);
* discomfort ``D`` = PMV-hours outside -0.5..+0.5 with PMV clipped at +-3;
* a number outside a model's validity says so where it is printed (PMV beyond the +-3 scale,
  the share of samples outside ISO 7730, the draught rating in the vent jets);
* air quality is scored against the scenario's limits (CO2 limit, fog margin bound) as the benchmark scores it
  (``ceco_core.kpis.air_quality_kpis``): a run that broke them is said to have broken them and claims no saving.

The console table fits in :data:`CONSOLE_WIDTH` characters; the full table (every column, with
a legend) goes to ``DIR/comparison.txt`` and ``DIR/comparison.csv``, the verdict to
``DIR/verdict.json``, and everything printed to ``DIR/summary.txt``.

Pure Python; the simulator runs only for the baseline family (:func:`finish_job`).
"""

from __future__ import annotations

import csv
import math
import shlex
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from ceco_bringup import verdict as vd
from ceco_bringup.provenance import command_line, read_run
from ceco_bringup.report_html import fmt_value
from ceco_core.metrics import ENERGY_PARTS, J_PER_KWH, PMV_SCALE_LIMIT, relative_change_pct

__all__ = [
    'CONSOLE_WIDTH',
    'run_line',
    'air_quality_words',
    'failed_line',
    'failed_lines',
    'report_failed',
    'pmv_scale_cell',
    'table_rows',
    'console_table',
    'full_table',
    'write_comparison_csv',
    'finish_job',
    'FAMILY_FLAG',
    'family_skipped',
    'matched_comfort_hint',
    'hinted_verdict_lines',
]

CONSOLE_WIDTH = 100
"""Widest console line of a table or the verdict [characters]."""

CONSOLE_LEGEND = (
    f'E: energy, {ENERGY_PARTS}. E change: against the baseline run, as measured',
    '(+ = more). D: discomfort, PMV-hours outside -0.5..+0.5 (PMV clipped at +-3). saving: energy',
    'saved at matched comfort against the baseline family (+ = less energy; n/a outside its range).',
    "viol.: time outside the scenario's PMV bounds. t_comf: first time PMV stays in -0.5..+0.5 for",
    '60 s (n/a: never). PMV max on the +-3 scale (">3": clipped); ISO out: samples outside ISO 7730.',
)

FULL_COLUMNS = (
    ('strategy', 'strategy', 's'),
    ('energy_kwh', 'E [kWh]', '.4f'),
    ('energy_comp_kwh', 'E comp [kWh]', '.4f'),
    ('energy_blower_kwh', 'E blower [kWh]', '.4f'),
    ('energy_fan_kwh', 'E fan [kWh]', '.4f'),
    ('energy_change_pct', 'E change [%]', '+.1f'),
    ('energy_saving_matched_pct', 'E saving matched [%]', '+.1f'),
    ('dominated', 'dominated', 's'),
    ('discomfort_pmvh', 'D [PMV h]', '.4f'),
    ('discomfort_change_pct', 'D change [%]', '+.1f'),
    ('discomfort_band_pmvh', 'D band [PMV h]', '.4f'),
    ('i_pmv', 'I_PMV [s]', '.1f'),
    ('i_pmv_clipped', 'I_PMV clipped [s]', '.1f'),
    ('otc_violation_pct', 'viol. [%]', '.1f'),
    ('time_to_comfort_s', 't_comf [s]', '.0f'),
    ('pmv_mean_band', 'PMV mean band', '+.3f'),
    ('pmv_above_band_s', 'above +0.5 band [s]', '.0f'),
    ('pmv_max', 'PMV max (raw)', '+.2f'),
    ('iso7730_invalid_pct', 'ISO out [%]', '.1f'),
    ('draught_pct', 'DR>20% [%]', '.1f'),
    ('draught_mean_pct', 'DR mean [%]', '.1f'),
    ('fog_margin_min_k', 'fog margin min [K]', '.1f'),
    ('fog_below_bound_s', 'fog<bound [s]', '.0f'),
    ('co2_max_ppm', 'CO2 max [ppm]', '.0f'),
    ('co2_above_limit_pct', 'CO2>limit [%]', '.1f'),
    ('co2_exposure_ppmh', 'CO2 exposure [ppm h]', '.1f'),
    ('air_quality_met', 'air quality met', 's'),
    ('fallback_steps', 'fallbacks', '.0f'),
    ('solve_time_median_ms', 'solve med. [ms]', '.1f'),
    ('solve_time_max_ms', 'solve max [ms]', '.1f'),
)
"""(key, header with unit, format) of the full table (``comparison.txt`` and ``comparison.csv``)."""

FULL_LEGEND = (
    f'E: A/C electrical energy, {ENERGY_PARTS} (the paper counts compressor + blower; add the',
    '  comp and blower columns for its number). E change / D change: against the baseline run, as',
    '  measured (+ = more). E saving matched: energy saved at the discomfort of the run against the',
    '  production and the tuned law at several set-points, the one that spends less there (+ = less',
    '  energy; empty outside the family; dominated: a set-point is at least as good on both axes).',
    '  docs/benchmark.md, "Matched comfort".',
    'D: discomfort, integral of the PMV distance outside -0.5..+0.5 (ISO 7730 category B) with PMV',
    '  clipped at +-3, whole run; D band: from the time the bounds reach the band. I_PMV: the paper\'s',
    '  integral of PMV^2 (raw, and clipped at +-3: beyond +-3 PMV is no vote). PMV mean band, above',
    '  +0.5 band: the mean PMV and the seconds of PMV above +0.5 from the time the bounds reach the band.',
    'PMV max (raw): PMV beyond +-3 is off ISO 7730\'s scale; ISO out: share of samples whose PMV or',
    '  its inputs lie outside ISO 7730 Clause 4 (the hot pull-down); comfort numbers there are',
    '  extrapolations.',
    'DR>20%: share of time the ISO 7730 draught rating at the occupant exceeds 20 % (category B).',
    '  With the vents aimed at the occupant the jet (over 1 m/s at any admissible flow) is outside',
    '  the draught model\'s range (< 0.5 m/s): 100 % there is a statement about the jet, not a vote',
    '  (docs/comfort.md, "Draught").',
    'fog margin: inner glazing minus cabin dew point (< 0: the windscreen fogs); fog<bound: time with it',
    "  below the scenario's fog margin bound. CO2 max, CO2>limit (share of time above the scenario's CO2",
    '  limit), CO2 exposure (time integral of the CO2 above it): the cabin CO2. air quality met: no: the',
    '  run broke a limit, and is not matched (no saving; docs/metrics.md, "Air quality"). n/a: not recorded.',
)


def run_line(m: Mapping, run_dir: Path | str) -> str:
    """One finished run on one line: energy [kWh] and its parts, discomfort, violation, wall time.

    A run that broke its scenario's air-quality limits (``ceco_core.kpis.breaks_air_quality`` on its
    metrics.json) says so, with the limit it broke (:func:`air_quality_words`); within them the line says nothing
    of air quality.
    """
    from ceco_core.kpis import breaks_air_quality

    parts = (m['E_comp_J'] / J_PER_KWH, m['E_blower_J'] / J_PER_KWH, m['E_fan_J'] / J_PER_KWH)
    text = (
        f"{m['strategy']:>10}: E {m['E_tot_J'] / J_PER_KWH:.4f} kWh (comp {parts[0]:.4f}, blower "
        f"{parts[1]:.4f}, fan {parts[2]:.4f}), viol. {m['otc_violation_pct']:.1f} %"
    )
    if 'wall_time_s' in m:
        text += f", wall {m['wall_time_s']:.1f} s"
    if breaks_air_quality(m):
        text += f'; BROKE air quality: {air_quality_words(m)}'
    return text + f' -> {run_dir}'


def air_quality_words(m: Mapping) -> str:
    """Which air-quality limit a run broke, short: ``CO2 max 1650 ppm > 1500 ppm, fog margin min 1.2 K < 3 K``.

    ``m``: a metrics.json (``ceco_core.metrics.run_metrics`` with the limits: ``co2_limit_ppm``, ``co2_max_ppm``,
    ``co2_above_limit_pct``; ``fog_margin_bound_k``, ``fog_margin_min_k``, ``fog_below_bound_s``). A limit is
    named when the run passed it (time above the CO2 limit, time below the fog margin bound), as
    ``ceco_core.kpis.air_quality_kpis`` scores it.
    """
    words = []
    if (m.get('co2_above_limit_pct') or 0.0) > 0.0:
        words.append(
            f"CO2 max {fmt_value(m.get('co2_max_ppm'), '.0f')} ppm > {fmt_value(m.get('co2_limit_ppm'), 'g')} ppm"
        )
    if (m.get('fog_below_bound_s') or 0.0) > 0.0:
        words.append(
            f"fog margin min {fmt_value(m.get('fog_margin_min_k'), '.1f')} K < "
            f"{fmt_value(m.get('fog_margin_bound_k'), 'g')} K"
        )
    return ', '.join(words)


def failed_line(strategy: str, reason: str, run_dir: Path | str) -> str:
    """A failed run on one line: its reason, no number (``ceco_core.run_status``: no result)."""
    return f'{strategy:>10}: FAILED: {reason} -> {run_dir}'


def failed_lines(failed: Mapping[str, str], n_runs: int) -> list[str]:
    """The failed runs of a job (``failed``: {name: reason}) of ``n_runs``: a head line, then one per run.

    ``N of M runs failed (not compared):`` and ``  name: reason`` (``verdict.reason_line``); the words of ``ceco sim``,
    ``ceco run`` (:func:`report_failed`) and ``ceco report``. No line when none failed.
    """
    if not failed:
        return []
    return [f'{len(failed)} of {n_runs} runs failed (not compared):'] + [
        f'  {name}: {vd.reason_line(reason)}' for name, reason in failed.items()
    ]


def report_failed(out: Path | str, failed: Mapping[str, str], n_runs: int, echo: Callable[[str], None] = print) -> None:
    """After a job with failed runs (``failed``: {strategy: reason}): say which, and add it to ``out/summary.txt``.

    Nothing is printed or written when no run failed.
    """
    if not failed:
        return
    lines = failed_lines(failed, n_runs)
    for line in lines:
        echo(line)
    path = Path(out) / 'summary.txt'
    old = path.read_text(encoding='utf-8') if path.is_file() and n_runs > 1 else ''
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(old + '\n'.join(lines) + '\n', encoding='utf-8')


def table_rows(metrics: Mapping[str, Mapping], kpis: Mapping[str, Mapping], v: vd.Verdict | None = None) -> list[dict]:
    """One flat row per strategy (job order): the metrics, the KPIs and the verdict's numbers."""
    rows = []
    base = kpis.get('baseline')
    for name, k in kpis.items():
        m = metrics.get(name, {})
        r = {
            'strategy': name,
            **{key: k.get(key) for key, _, _ in FULL_COLUMNS if key in k},
            'pmv_max': m.get('pmv_max'),
            'solve_time_median_ms': m.get('solve_time_median_ms'),
            'solve_time_max_ms': m.get('solve_time_max_ms'),
        }
        if base is not None:
            r['energy_change_pct'] = relative_change_pct(k['energy_kwh'], base['energy_kwh'])
            r['discomfort_change_pct'] = relative_change_pct(k['discomfort_pmvh'], base['discomfort_pmvh'])
        met = k.get('air_quality_met')
        r['air_quality_met'] = None if met is None else bool(met)
        mt = (v.matched.get(name) if v is not None else None) or {}
        r['energy_saving_matched_pct'] = mt.get('energy_saving_pct')
        r['dominated'] = mt.get('dominated') if mt else None
        rows.append(r)
    return rows


def pmv_scale_cell(x) -> str:
    """A PMV as printed: ``>3`` / ``<-3`` beyond ISO 7730's seven-point scale (clipped: no vote there)."""
    if x is None or not math.isfinite(float(x)):
        return 'n/a'
    if x > PMV_SCALE_LIMIT:
        return '>3'
    if x < -PMV_SCALE_LIMIT:
        return '<-3'
    return f'{x:+.2f}'


def _aligned(header: Sequence[str], body: Sequence[Sequence[str]]) -> list[str]:
    widths = [max(len(r[i]) for r in [header, *body]) for i in range(len(header))]

    def fmt(row):
        return '  '.join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(row, widths)))

    return [fmt(header), '  '.join('-' * w for w in widths), *(fmt(r) for r in body)]


def console_table(rows: Sequence[Mapping]) -> str:
    """The comparison a person reads, the legend under it.

    At most :data:`CONSOLE_WIDTH` characters wide, one unit per quantity.
    """
    header = (
        'strategy',
        'E [kWh]',
        'E change [%]',
        'D [PMV h]',
        'saving [%]',
        'viol. [%]',
        't_comf [s]',
        'PMV max',
        'ISO out [%]',
    )
    body = [
        (
            r['strategy'],
            fmt_value(r.get('energy_kwh'), '.3f'),
            fmt_value(r.get('energy_change_pct'), '+.1f'),
            fmt_value(r.get('discomfort_pmvh'), '.3f'),
            fmt_value(r.get('energy_saving_matched_pct'), '+.1f'),
            fmt_value(r.get('otc_violation_pct'), '.1f'),
            fmt_value(r.get('time_to_comfort_s'), '.0f'),
            pmv_scale_cell(r.get('pmv_max')),
            fmt_value(r.get('iso7730_invalid_pct'), '.1f'),
        )
        for r in rows
    ]
    return '\n'.join([*_aligned(header, body), *CONSOLE_LEGEND])


def full_table(rows: Sequence[Mapping]) -> str:
    """Every column of :data:`FULL_COLUMNS`, aligned, with its legend (``comparison.txt``)."""
    header = [h for _, h, _ in FULL_COLUMNS]
    body = [[fmt_value(r.get(k), f) for k, _, f in FULL_COLUMNS] for r in rows]
    return '\n'.join([*_aligned(header, body), '', *FULL_LEGEND])


def write_comparison_csv(path: str | Path, rows: Sequence[Mapping]) -> None:
    """``comparison.csv``: the full table's columns by key (empty cell = not defined)."""
    keys = [k for k, _, _ in FULL_COLUMNS]
    with open(path, 'w', newline='', encoding='utf-8') as fh:
        w = csv.writer(fh)
        w.writerow(keys)
        for r in rows:
            cells = []
            for k in keys:
                x = r.get(k)
                ok = x is not None and not (isinstance(x, float) and not math.isfinite(x))
                cells.append(repr(float(x)) if ok and isinstance(x, float) else ('' if not ok else str(x)))
            w.writerow(cells)


FAMILY_FLAG = '--baseline-setpoints-c'
"""The flag of ``ceco sim`` and ``ceco run`` whose value ``none`` skips the baseline family (no matched comfort)."""


def _is_family_flag(option: str) -> bool:
    """Whether ``option`` (``--x``, before any ``=``) is :data:`FAMILY_FLAG` as argparse took it.

    Whole, or abbreviated (``--baseline-setpoints``). No other flag of ``ceco sim`` or ``ceco run`` starts with ``--b``
    (``tests/test_outputs.py`` checks their parsers), so every prefix of it down to ``--b`` is that flag.
    """
    return len(option) >= 3 and FAMILY_FLAG.startswith(option)


def _without_family_off(argv: Sequence[str] | None) -> list[str] | None:
    """``argv`` without :data:`FAMILY_FLAG` (or its abbreviation) when its (last) value is ``none``.

    None otherwise (or without ``argv``).
    """
    if not argv:
        return None
    rest: list[str] = []
    value = None
    args = list(argv)
    i = 0
    while i < len(args):
        a = str(args[i])
        if _is_family_flag(a) and i + 1 < len(args):
            value, i = str(args[i + 1]), i + 2
            continue
        if '=' in a and _is_family_flag(a.split('=', 1)[0]):
            value, i = a.split('=', 1)[1], i + 1
            continue
        rest.append(a)
        i += 1
    return rest if value is not None and value.strip().lower() == 'none' else None


def family_skipped(argv: Sequence[str] | None) -> bool:
    """Whether the arguments ``argv`` (``run.json``'s) skipped the baseline family: ``--baseline-setpoints-c none``."""
    return _without_family_off(argv) is not None


def matched_comfort_hint(
    verb: str,
    scenario: str,
    *,
    argv: Sequence[str] | None = None,
    skipped: bool = False,
    case: str | None = None,
    cwd: str | None = None,
) -> tuple[str, str]:
    """``(pointer, command)``: what a verdict without a baseline family says, and the command that computes it.

    The pointer follows "Matched comfort: not computed for these runs; " (:func:`hinted_verdict_lines` puts the
    command on a line of its own after it, whole, so that it can be copied). ``verb``: ``sim`` or ``run``, the verb
    the runs were made with; ``scenario``: the scenario as that verb is given it (a bundled name or a YAML path;
    never a file's ``name:``, which ``--scenario`` does not take); ``case``: the benchmark case (``--case``)
    instead. ``argv``: the job's arguments (``run.json``) when known; ``skipped``: the family was skipped by
    ``--baseline-setpoints-c none`` (also when ``argv`` holds it). Then that is named as the cause, and the command
    is the same one without the flag (``cwd``: the directory it was typed in, said when it is not this one); else
    the command that runs the strategies with the family.
    """
    if verb not in ('sim', 'run'):  # a run of `ceco benchmark` (an external cell) or `ceco oracle`: no --scenario
        verb, argv = 'run', None
    rest = _without_family_off(argv)
    target = f'--case {shlex.quote(case)}' if case else f'--scenario {shlex.quote(scenario)}'
    command = f'ceco {verb} {target} --strategy all --out DIR'
    if rest is not None:
        where = f' (in {cwd})' if cwd and Path(cwd).resolve() != Path.cwd().resolve() else ''
        return f'`{FAMILY_FLAG} none` skipped the baseline family; the same command without it computes it{where}:', (
            command_line(verb, rest)
        )
    if skipped:
        return (
            f'`{FAMILY_FLAG} none` skipped the baseline family; the command without it computes it, as does:',
            command,
        )
    bench = f'ceco benchmark {shlex.quote(case)}' if case else 'ceco benchmark'
    return f'this runs the strategies with the baseline family (`{bench}`: its test cases):', command


def hinted_verdict_lines(v: vd.Verdict, hint: tuple[str, str]) -> list[str]:
    """``verdict.verdict_lines`` with the pointer of ``hint`` (:func:`matched_comfort_hint`) and its command.

    The command goes on a line of its own, indented two spaces, after the "Matched comfort: not computed" line
    (when there is one), whole: the verdict's lines are wrapped at 100 characters.
    """
    pointer, command = hint
    lines = vd.verdict_lines(v, pointer=pointer)
    for i, line in enumerate(lines):
        if line.startswith('Matched comfort: not computed for these runs;'):
            j = i + 1
            while j < len(lines) and lines[j].startswith('    '):  # its continuation lines
                j += 1
            return [*lines[:j], f'  {command}', *lines[j:]]
    return lines


def _job_record(out: Path, names: Sequence[str]) -> dict:
    """``run.json`` of one of the job's runs (``out/<strategy>``, or ``out`` for one ``ceco run``); {} without one."""
    for d in (*(out / n for n in names), out):
        try:
            rec = read_run(d)
        except (ValueError, OSError):
            continue
        if rec:
            return rec
    return {}


def finish_job(
    out: Path,
    scenario,
    metrics: Mapping[str, Mapping],
    columns: Mapping[str, Mapping],
    *,
    header: str,
    family_setpoints_c: Sequence[float] = vd.FAMILY_SETPOINTS_C,
    family_overrides: tuple = (),
    case: str | None = None,
    duration_s: float | None = None,
    control_period_s: float | None = None,
    partial: Mapping[str, str] | None = None,
    failed: Mapping[str, str] | None = None,
    progress: bool = True,
    echo: Callable[[str], None] = print,
) -> vd.Verdict:
    """The end of a job: the baseline family, the table, the verdict; printed and written to ``out``.

    ``metrics``/``columns``: {strategy: metrics.json dict / timeseries columns} of the job's runs.
    With an empty ``family_setpoints_c`` (``--baseline-setpoints-c none``) the family is not run and the verdict
    says so, with the job's command without that flag (from its runs' ``run.json``; :func:`matched_comfort_hint`).
    ``family_overrides``: ``((field, value), ...)`` every member also gets (a benchmark
    case's baseline door, ``ceco sim --case``); ``case``: the benchmark case the runs are of (``--case``),
    named in that pointer. ``failed``: {strategy: why} of the job's runs that failed, named in the verdict (no
    number). Writes ``out/comparison.txt``, ``comparison.csv``, ``verdict.json`` and
    ``summary.txt`` (everything printed here); returns the verdict.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    kpis = {}
    from ceco_core.kpis import compute_kpis

    limits = scenario.air_quality.limits
    for name, cols in columns.items():
        fallbacks = metrics.get(name, {}).get('fallback_steps')
        kpis[name], _ = compute_kpis(cols, fallback_steps=fallbacks, air_limits=limits)
    points = {name: vd.run_point(cols, limits) for name, cols in columns.items()}
    family = {}
    if family_setpoints_c:
        family = vd.run_family(
            scenario,
            duration_s=duration_s,
            control_period_s=control_period_s,
            setpoints_c=family_setpoints_c,
            laws=vd.family_laws_for(list(points)),
            progress=progress,
            overrides=family_overrides,
        )
    v = vd.build_verdict(scenario.name, points, family, partial=partial, air_limits=limits, failed=failed)
    rows = table_rows(metrics, kpis, v)
    rec = _job_record(out, list(metrics))  # the verb and arguments as typed (provenance.start_run wrote it)
    hint = matched_comfort_hint(
        str(rec.get('verb') or 'sim'),
        str(rec.get('scenario_source') or scenario.name),
        argv=rec.get('argv'),
        skipped=not family_setpoints_c,
        case=case,
    )
    text = '\n'.join(
        [header, console_table(rows), '', *hinted_verdict_lines(v, hint), f'Full table: {out}/comparison.txt']
    )
    echo('')
    echo(text)
    (out / 'comparison.txt').write_text(header + '\n' + full_table(rows) + '\n', encoding='utf-8')
    write_comparison_csv(out / 'comparison.csv', rows)
    vd.write_verdict(out / 'verdict.json', v)
    (out / 'summary.txt').write_text(text + '\n', encoding='utf-8')
    sys.stdout.flush()
    return v
