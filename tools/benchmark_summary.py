#!/usr/bin/env python3
"""Markdown tables for docs/results.md from a ``ceco benchmark`` results file (``ceco-benchmark/1`` or ``/2``).

Usage (repository root)::

    ceco benchmark --out runs/bench --workers 2
    python tools/benchmark_summary.py runs/bench/results.json > /tmp/summary.md

Everything printed is read from results.json or computed from its numbers here, for every scored
controller the file holds (every name in a case's ``matched`` that is not a baseline: the paper's four
strategies first, then ceco-pmv, its twins and any external controller, in the file's order):

* the matched-comfort table of every case (plain and allowance fronts; seed mean, [min, max] over seeds);
* the KPIs of the strategies and of the baselines nearest to them (seed mean, [min, max]);
* the comparison with the paper on ``sc03-paper``: the paper's way (``energy_paper_kwh`` = compressor +
  blower and I_PMV against the 26 degC baseline) next to matched comfort;
* matched comfort on the secondary axes (``matched_by_axis``) and, as an extra reading that is NOT a KPI
  of the benchmark, "matched comfort-phase PMV": the plain family's energy interpolated (piecewise
  linear in the set-point order) at the strategy's band-phase mean PMV, which on a case whose pull-down
  is actuator-limited for every controller separates what the whole-run discomfort axis cannot;
* the sensitivity (tornado): per parameter and strategy the saving at the low and the high end, and the
  range over all ends;
* the timing (wall time, runs; control-step time ratio t_c/Ts and the step time in ms).

Pure Python (json only); no ceco import.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

PAPER_STRATEGIES = ('ceco', 'ceco-e', 'ceco-c', 'ceco-ioch')
"""The paper's four strategies: listed first, in this order, when the file has them."""
COMPENSATED = ('baseline-compensated', 'baseline-compensated-allowance')
PAPER = {'ceco-e': -15.9, 'ceco-c': -4.1, 'ceco-ioch': -7.6}
"""The paper's energy changes against its baseline [%] (Wang et al., DSCC 2019: CECO-E, CECO-C, CECO-IOCH)."""


def scored_controllers(doc) -> tuple:
    """The scored controllers of ``doc``: every non-baseline name in a case's ``matched``.

    The paper's four strategies first (those present), then the others in the order of the file's
    ``settings.strategies`` and of their first appearance in the cases' ``matched``.
    """
    seen = list(doc.get('settings', {}).get('strategies') or [])
    for case in doc['cases']:
        seen += list(case.get('matched', {}))
    found = []
    for name in seen:
        if name in found or name.startswith('baseline'):
            continue
        if any(name in case.get('matched', {}) for case in doc['cases']):
            found.append(name)
    return tuple(n for n in PAPER_STRATEGIES if n in found) + tuple(n for n in found if n not in PAPER_STRATEGIES)


def fmt(v, spec='+.1f', na='n/a'):
    """A number or 'n/a'."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return na
    return format(v, spec)


def spread(values, spec='+.1f'):
    """' [min, max]' over seeds (numbers only; '' for one value)."""
    nums = [v for v in values if v is not None]
    if len(values) <= 1:
        return ''
    if not nums:
        return ' [n/a]'
    extra = '' if len(nums) == len(values) else f'; {len(values) - len(nums)} n/a'
    return f' [{format(min(nums), spec)}, {format(max(nums), spec)}{extra}]'


def short_note(note: str) -> str:
    """The matched note in a few words."""
    out = []
    for part in (note or '').split('; '):
        if part.startswith('more comfortable'):
            out.append('more comfortable than the front')
        elif part.startswith('less comfortable'):
            out.append('less comfortable than the front')
        elif part.startswith('uses more energy'):
            out.append('more energy than the front')
        elif part.startswith('uses less energy'):
            out.append('less energy than the front')
        elif part:
            out.append(part)
    return ', '.join(out)


def runs_by(case):
    """controller -> list of runs (seed order)."""
    out: dict = {}
    for r in case['runs']:
        out.setdefault(r['controller'], []).append(r)
    return out


def mean_kpi(runs, key):
    """Mean over runs of a KPI, and the list."""
    vals = [r['kpis'].get(key) for r in runs if r['status'] == 'ok']
    nums = [v for v in vals if v is not None]
    return (sum(nums) / len(nums) if nums else None), vals


def matched_table(doc):
    """The headline: every case, the scored controllers and the two compensated laws."""
    lines = [
        '| case | controller | ΔE at matched comfort, plain [%] | ΔD at matched energy, plain [%] | '
        'dominated, plain | ΔE at matched comfort, allowance [%] | ΔD at matched energy, allowance [%] | '
        'dominated, allowance | why n/a |',
        '|---|---|---|---|---|---|---|---|---|',
    ]
    for case in doc['cases']:
        for name in scored_controllers(doc) + COMPENSATED:
            m = case['matched'].get(name)
            if m is None:
                continue
            a = m['allowance']
            cells = []
            for x in (m, a):
                cells += [
                    fmt(x['energy_saving_pct']) + spread(x['seeds']['energy_saving_pct']),
                    fmt(x['discomfort_reduction_pct']) + spread(x['seeds']['discomfort_reduction_pct']),
                    ('**yes**' if x['dominated'] else 'no')
                    + (
                        f" ({sum(x['seeds']['dominated'])}/{len(x['seeds']['dominated'])} seeds)"
                        if len(x['seeds']['dominated']) > 1
                        and 0 < sum(x['seeds']['dominated']) < len(x['seeds']['dominated'])
                        else ''
                    ),
                ]
            why = '; '.join(
                f'{lab}: {short_note(x["note"])}' for lab, x in (('plain', m), ('allowance', a)) if x.get('note')
            )
            lines.append(f"| {case['case']} | {name} | " + ' | '.join(cells) + f' | {why} |')
    return '\n'.join(lines)


def stronger_front(m):
    """ΔE against the stronger of the two fronts: the smaller defined saving, dominated by either."""
    vals = [x['energy_saving_pct'] for x in (m, m['allowance']) if x['energy_saving_pct'] is not None]
    return (min(vals) if vals else None), bool(m['dominated'] or m['allowance']['dominated'])


def headline_table(doc):
    """Strategies x cases: ΔE at matched comfort against the stronger front (mean over seeds)."""
    cases = [c['case'] for c in doc['cases']]
    lines = ['| strategy | ' + ' | '.join(cases) + ' |', '|---|' + '---|' * len(cases)]
    for name in scored_controllers(doc) + COMPENSATED:
        cells = []
        for case in doc['cases']:
            m = case['matched'].get(name)
            if m is None:
                cells.append('')
                continue
            v, dom = stronger_front(m)
            cells.append(('n/a' if v is None else f'{v:+.1f}') + (' (dom.)' if dom else ''))
        lines.append(f'| {name} | ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines)


def front_text(case, family):
    """The efficient front as 'S: D / E' items."""
    pts = [p for p in case['fronts'][family] if p['efficient']]
    return ', '.join(f"{p['controller'].split('@')[1]} ({p['discomfort']:.4f} / {p['energy']:.4f})" for p in pts)


def kpi_table(case, names=PAPER_STRATEGIES):
    """KPIs of the scored controllers ``names``, the compensated laws and a few family members."""
    by = runs_by(case)
    keys = [
        ('energy_kwh', '.4f'),
        ('energy_paper_kwh', '.4f'),
        ('discomfort_pmvh', '.4f'),
        ('discomfort_band_pmvh', '.4f'),
        ('pmv_mean_band', '+.3f'),
        ('i_pmv_clipped', '.0f'),
        ('otc_violation_pct', '.1f'),
        ('draught_pct', '.0f'),
        ('fog_margin_min_k', '.1f'),
        ('iso7730_invalid_pct', '.1f'),
        ('actuator_travel', '.2f'),
    ]
    head = (
        '| controller | seeds | E [kWh] | E paper [kWh] | D [PMV·h] | D band [PMV·h] | PMV band mean | '
        'I_PMV clip [s] | OTC viol. [%] | DR>20 % [%] | fog min [K] | ISO invalid [%] | travel [-] |'
    )
    lines = [head, '|' + '---|' * 13]
    fam = sorted((n for n in by if n.startswith('baseline@')), key=lambda n: float(n.split('@')[1]))
    show = [n for n in fam if float(n.split('@')[1]) in (22.0, 23.0, 24.0, 25.0, 26.0, 27.0)]
    for name in show + list(COMPENSATED) + list(names):
        if name not in by:
            continue
        rs = by[name]
        cells = []
        for k, spec in keys:
            m, vals = mean_kpi(rs, k)
            sp = spread(vals, spec.replace('+', '')) if k in ('energy_kwh', 'discomfort_pmvh', 'pmv_mean_band') else ''
            cells.append(fmt(m, spec) + sp)
        lines.append(f'| {name} | {len(rs)} | ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines)


def interp_family(case, x_key, y_key, x):
    """Plain family: y at x by linear interpolation in set-point order (None outside its range)."""
    by = runs_by(case)
    pts = []
    for n, rs in by.items():
        if n.startswith('baseline@') and rs[0]['status'] == 'ok':
            pts.append((float(n.split('@')[1]), rs[0]['kpis'][x_key], rs[0]['kpis'][y_key]))
    pts.sort()
    for (s0, x0, y0), (s1, x1, y1) in zip(pts, pts[1:]):
        if x0 is None or x1 is None:
            continue
        lo, hi = min(x0, x1), max(x0, x1)
        if lo <= x <= hi and x1 != x0:
            w = (x - x0) / (x1 - x0)
            return y0 + w * (y1 - y0), s0 + w * (s1 - s0)
    return None, None


def band_pmv_table(doc):
    """Extra reading: energy against the plain family at the same band-phase mean PMV (not a KPI)."""
    lines = [
        '| case | controller | PMV band mean | family set-point at that PMV [degC] | family E there [kWh] | '
        'E [kWh] | ΔE [%] |',
        '|---|---|---|---|---|---|---|',
    ]
    for case in doc['cases']:
        by = runs_by(case)
        for name in scored_controllers(doc) + COMPENSATED:
            if name not in by:
                continue
            p, _ = mean_kpi(by[name], 'pmv_mean_band')
            e, _ = mean_kpi(by[name], 'energy_kwh')
            if p is None:
                continue
            ef, sp = interp_family(case, 'pmv_mean_band', 'energy_kwh', p)
            d = None if ef is None else 100.0 * (ef - e) / ef
            lines.append(
                f"| {case['case']} | {name} | {p:+.3f} | {fmt(sp, '.2f')} | {fmt(ef, '.4f')} | {e:.4f} | {fmt(d)} |"
            )
    return '\n'.join(lines)


def axis_table(doc):
    """matched_by_axis: the energy saving on the secondary discomfort axes (plain front)."""
    axes = doc['settings'].get('secondary_axes', [])
    lines = [
        '| case | controller | ' + ' | '.join(f'ΔE matched on {a} [%]' for a in axes) + ' |',
        '|---|---|' + '---|' * len(axes),
    ]
    for case in doc['cases']:
        for name in scored_controllers(doc):
            if name not in case['matched']:
                continue
            cells = []
            for a in axes:
                m = case.get('matched_by_axis', {}).get(a, {}).get(name)
                if m is None:
                    cells.append('n/a')
                    continue
                c = fmt(m['energy_saving_pct']) + (' (dominated)' if m['dominated'] else '')
                if m['energy_saving_pct'] is None and m.get('note'):
                    c += f" ({short_note(m['note'])})"
                cells.append(c)
            lines.append(f"| {case['case']} | {name} | " + ' | '.join(cells) + ' |')
    return '\n'.join(lines)


def paper_table(doc):
    """sc03-paper: the paper's way (against 26 degC) and matched comfort."""
    case = next((c for c in doc['cases'] if c['case'] == 'sc03-paper'), None)
    if case is None:
        return '(no sc03-paper case)'
    by = runs_by(case)
    ref = by.get('baseline@26.0')
    if not ref:
        return '(no baseline@26.0)'
    e0, i0 = ref[0]['kpis']['energy_paper_kwh'], ref[0]['kpis']['i_pmv']
    lines = [
        '| strategy | paper: ΔE vs its baseline | here: ΔE_paper vs baseline@26.0 | ΔI_PMV vs baseline@26.0 | '
        'ΔE at matched comfort, plain | ΔE at matched comfort, allowance |',
        '|---|---|---|---|---|---|',
    ]
    for name in scored_controllers(doc):
        if name not in by or name not in case['matched']:
            continue
        e = by[name][0]['kpis']['energy_paper_kwh']
        i = by[name][0]['kpis']['i_pmv']
        m = case['matched'][name]
        cells = []
        for x in (m, m['allowance']):
            v = x['energy_saving_pct']
            c = 'n/a' if v is None else f'{-v:+.1f} %'
            cells.append(
                c
                + (' (dominated)' if x['dominated'] else '')
                + (f" ({short_note(x['note'])})" if v is None and x.get('note') else '')
            )
        paper = PAPER.get(name)
        lines.append(
            f"| {name} | {'–' if paper is None else f'{paper:+.1f} %'} | {100 * (e - e0) / e0:+.1f} % | "
            f"{100 * (i - i0) / i0:+.1f} % | {cells[0]} | {cells[1]} |"
        )
    return '\n'.join(lines)


def value_range(values) -> str:
    """'min … max' of the numbers in ``values`` (and how many are n/a)."""
    nums = [v for v in values if v is not None]
    if not nums:
        return 'n/a'
    missing = len(values) - len(nums)
    return f'{min(nums):+.1f} … {max(nums):+.1f}' + (f' ({missing} n/a)' if missing else '')


def sensitivity_tables(doc):
    """The tornado as numbers."""
    out = []
    for case in doc['cases']:
        sens = case.get('sensitivity')
        if not sens:
            continue
        names = [n for n in scored_controllers(doc) + COMPENSATED if n in case['matched']]
        lines = [
            f"Sensitivity on {case['case']} (energy saving at matched comfort, plain front, low / high end "
            '[%]; nominal: ' + ', '.join(f"{n} {fmt(case['matched'][n]['energy_saving_pct'])}" for n in names) + ')',
            '',
            '| parameter | low | nominal | high | ' + ' | '.join(names) + ' |',
            '|---|---|---|---|' + '---|' * len(names),
        ]
        ranges: dict = {n: [case['matched'][n]['energy_saving_pct']] for n in names}
        for s in sens:
            cells = []
            for n in names:
                lo = s['matched_low'].get(n, {}).get('energy_saving_pct')
                hi = s['matched_high'].get(n, {}).get('energy_saving_pct')
                ranges[n] += [lo, hi]
                cells.append(f'{fmt(lo)} / {fmt(hi)}')
            nominal = 'plant' if s['nominal'] is None else f"{s['nominal']:g}"
            lines.append(f"| {s['parameter']} | {s['low']:g} | {nominal} | {s['high']:g} | " + ' | '.join(cells) + ' |')
        lines.append('| **range over all ends** | | | | ' + ' | '.join(value_range(ranges[n]) for n in names) + ' |')
        failed = sum(s['failed_low'] + s['failed_high'] for s in sens)
        lines.append('')
        lines.append(f'Failed sensitivity runs: {failed}.')
        out.append('\n'.join(lines))
    return '\n\n'.join(out)


def timing_table(doc, log_lines=()):
    """Wall time and the controllers' step times."""
    t = doc['timing']
    inv = [json.loads(x) for x in log_lines if x.strip()]
    lines = [
        f"timing.jsonl invocation {i + 1}: {x['wall_s']:.1f} s wall, {x['ran_now']} runs run" for i, x in enumerate(inv)
    ]
    lines += [
        f"Wall time {t['wall_s']:.1f} s for {t['runs']} runs ({t['ran_now']} run now, {t.get('failed_now', 0)} "
        f"failed) on {t['workers']} worker(s), backend {t['backend']}, host {t.get('host', '?')}; sum of the "
        f"runs' simulation times {t.get('sim_time_sum_s', float('nan')):.0f} s.",
        '',
        '| controller | runs | t_c/Ts mean (mean over runs) | t_c/Ts max (max over runs) | step time mean / max [ms] |',
        '|---|---|---|---|---|',
    ]
    for name in scored_controllers(doc):
        means, maxes, ts = [], [], []
        for case in doc['cases']:
            for r in runs_by(case).get(name, []):
                if r['status'] == 'ok' and r['kpis'].get('time_ratio_mean') is not None:
                    means.append(r['kpis']['time_ratio_mean'])
                    maxes.append(r['kpis']['time_ratio_max'])
                    ts.append(case['control_period_s'])
        if not means:
            continue
        mean_ms = 1000.0 * sum(m * t for m, t in zip(means, ts)) / len(means)
        max_ms = 1000.0 * max(m * t for m, t in zip(maxes, ts))
        lines.append(
            f'| {name} | {len(means)} | {sum(means) / len(means):.2e} | {max(maxes):.2e} | '
            f'{mean_ms:.1f} / {max_ms:.1f} |'
        )
    return '\n'.join(lines)


def main(argv=None) -> int:
    """Print every table."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('results', help='results.json of a ceco benchmark run')
    args = ap.parse_args(argv)
    with open(args.results, encoding='utf-8') as f:
        doc = json.load(f)
    print(
        f"<!-- {args.results}: {doc['schema']}, ceco {doc['ceco_version']}, code {doc['code_fingerprint']}, "
        f"created {doc['created_utc']}, quick {doc['quick']}, command: {doc['command']} -->\n"
    )
    print('## Headline: ΔE at matched comfort against the stronger front [%]\n')
    print(headline_table(doc))
    print('\n## Matched comfort\n')
    print(matched_table(doc))
    print('\n## Fronts (efficient set-points: discomfort [PMV·h] / energy [kWh])\n')
    for case in doc['cases']:
        print(f"- {case['case']}: plain {front_text(case, 'plain')}; allowance {front_text(case, 'allowance')}")
    print('\n## Paper comparison (sc03-paper)\n')
    print(paper_table(doc))
    print('\n## Secondary axes\n')
    print(axis_table(doc))
    print('\n## Matched comfort-phase PMV (extra reading, not a benchmark KPI)\n')
    print(band_pmv_table(doc))
    print('\n## Sensitivity\n')
    print(sensitivity_tables(doc))
    print('\n## Timing\n')
    import pathlib

    log = pathlib.Path(args.results).with_name('timing.jsonl')
    print(timing_table(doc, log.read_text(encoding='utf-8').splitlines() if log.exists() else ()))
    for case in doc['cases']:
        print(f"\n## KPIs {case['case']} ({case['forecast_uncertainty']}, seeds {case['seeds']})\n")
        print(kpi_table(case, scored_controllers(doc)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
