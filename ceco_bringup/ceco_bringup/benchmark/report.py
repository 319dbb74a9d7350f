"""The benchmark report: Markdown and self-contained HTML from a results document.

``write_report(doc, out_dir)`` writes ``report.md``, ``report.html`` (every PNG
embedded, no external reference) and ``figures/*.png`` from a ``ceco-benchmark/1``
document; nothing is recomputed from runs, so the report shows exactly what
results.json holds. Sections: the headline table (energy saving at matched
comfort and discomfort reduction at matched energy, against the plain and the
allowance baseline fronts, every case), then per case the energy-discomfort
plane, the matched-comfort table with the seeds' spread and a KPI table, then
the sensitivity (tornado) and the timing.

Pure Python; no ROS import.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ceco_bringup.report_html import Figure, Heading, Paragraph, Table, Warning, render_html, render_markdown

from . import figures as bfig

__all__ = ['write_report', 'report_blocks', 'KPI_COLUMNS']

KPI_COLUMNS = (
    ('energy_kwh', 'E [kWh]', '.4f'),
    ('energy_comp_kwh', 'E comp [kWh]', '.4f'),
    ('discomfort_pmvh', 'D [PMV·h]', '.4f'),
    ('discomfort_band_pmvh', 'D band [PMV·h]', '.4f'),
    ('i_pmv', 'I_PMV [s]', '.0f'),
    ('i_pmv_clipped', 'I_PMV clip [s]', '.0f'),
    ('otc_violation_pct', 'OTC viol. [%]', '.1f'),
    ('draught_pct', 'DR>20 % [%]', '.1f'),
    ('fog_margin_min_k', 'fog margin min [K]', '.2f'),
    ('iso7730_invalid_pct', 'ISO invalid [%]', '.1f'),
    ('actuator_travel', 'travel [-]', '.2f'),
    ('peak_comp_kw', 'peak comp [kW]', '.2f'),
    ('time_ratio_mean', 't_c/Ts mean', '.1e'),
    ('time_ratio_max', 't_c/Ts max', '.1e'),
    ('fallback_steps', 'fallbacks', '.0f'),
)
"""(KPI key, column title, format) of the per-case KPI table (means over seeds)."""


def _fmt(v, spec: str) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return 'n/a'
    return format(float(v), spec)


def _slug(text: str) -> str:
    return re.sub(r'[^A-Za-z0-9._-]+', '_', text)


def _spread(values: Sequence, spec: str = '+.1f') -> str:
    vals = [v for v in values if v is not None]
    if len(values) <= 1:
        return ''
    if not vals:
        return ' (seeds: n/a)'
    missing = f', {len(values) - len(vals)} n/a' if len(vals) < len(values) else ''
    return f' [{format(min(vals), spec)} … {format(max(vals), spec)}{missing}]'


def _match_cells(m: Mapping) -> list[str]:
    seeds = m.get('seeds', {})
    dom = m.get('dominated')
    dom_seeds = seeds.get('dominated', [])
    dom_txt = ('**yes**' if dom else 'no') + (
        f' ({sum(dom_seeds)}/{len(dom_seeds)} seeds)' if len(dom_seeds) > 1 else ''
    )
    return [
        _fmt(m.get('energy_saving_pct'), '+.1f') + _spread(seeds.get('energy_saving_pct', [])),
        _fmt(m.get('discomfort_reduction_pct'), '+.1f') + _spread(seeds.get('discomfort_reduction_pct', [])),
        dom_txt,
    ]


def _notes(m: Mapping) -> str:
    parts = [
        f'{fam}: {sub["note"]}' for fam, sub in (('plain', m), ('allowance', m.get('allowance', {}))) if sub.get('note')
    ]
    return '; '.join(parts)


def _kind_of(case: Mapping) -> dict:
    return {r['controller']: r['kind'] for r in case['runs']}


def _mean_kpis(case: Mapping) -> dict:
    by: dict = {}
    for r in case['runs']:
        if r['status'] == 'ok':
            by.setdefault(r['controller'], []).append(r['kpis'])
    out = {}
    for name, ks in by.items():
        row = {}
        for key, _, _ in KPI_COLUMNS:
            vals = [k.get(key) for k in ks if k.get(key) is not None]
            row[key] = float(np.mean(vals)) if vals else None
        row['n'] = len(ks)
        out[name] = row
    return out


def _headline(doc: Mapping) -> list:
    rows = []
    for case in doc['cases']:
        for name, m in case['matched'].items():
            rows.append([case['case'], name, *_match_cells(m), *_match_cells(m.get('allowance', {})), _notes(m)])
    header = (
        'case',
        'controller',
        'E saving at matched comfort [%] (plain)',
        'D cut at matched energy [%] (plain)',
        'dominated (plain)',
        'E saving at matched comfort [%] (allowance)',
        'D cut at matched energy [%] (allowance)',
        'dominated (allowance)',
        'note',
    )
    return [
        Table(
            header,
            rows,
            caption='Savings at matched comfort: positive = less energy than the baseline '
            'front at the same discomfort / less discomfort at the same energy; '
            '[min … max] over seeds',
        )
    ]


def _case_blocks(case: Mapping, settings: Mapping, fig_dir: Path) -> list:
    blocks: list = [Heading(2, f"Case {case['case']} (v{case['version']})")]
    blocks.append(
        Paragraph(
            f"Scenario `{case['scenario']}`, {case['duration_s']:.0f} s, forecast uncertainty "
            f"**{case['forecast_uncertainty']}**, seeds {case['seeds']}, Ts {case.get('control_period_s')} s, "
            f"Np {case.get('horizon_steps')}; case sha `{case['case_sha']}`."
            + (f" {case['description']}" if case.get('description') else '')
        )
    )
    errors = [r for r in case['runs'] if r['status'] != 'ok']
    for r in errors:
        blocks.append(Warning(f"run {r['controller']} seed {r['seed']} failed: {r.get('error', '')}"))
    fig = bfig.fig_plane(case, fig_dir / f"plane_{_slug(case['case'])}.png", settings)
    blocks.append(
        Figure(
            fig,
            f"{case['case']}: energy over whole-run discomfort; black: baseline front (PI at "
            "set-point S, efficient points filled, labelled with S), blue dashed: the allowance "
            "baselines; markers: mean over seeds with min-max whiskers",
        )
    )
    rows = [
        [name, *_match_cells(m), *_match_cells(m.get('allowance', {})), _notes(m)]
        for name, m in case['matched'].items()
    ]
    blocks.append(
        Table(
            (
                'controller',
                'E saving matched comfort, plain [%]',
                'D cut matched energy, plain [%]',
                'dominated, plain',
                'E saving matched comfort, allowance [%]',
                'D cut matched energy, allowance [%]',
                'dominated, allowance',
                'note',
            ),
            rows,
            caption='Matched comfort',
        )
    )
    kinds = _kind_of(case)
    means = _mean_kpis(case)
    order = sorted(
        means,
        key=lambda n: (
            ('strategy', 'external', 'compensated', 'compensated-allowance', 'baseline', 'baseline-allowance').index(
                kinds[n]
            ),
            n,
        ),
    )
    rows = [[name, str(means[name]['n']), *[_fmt(means[name][k], f) for k, _, f in KPI_COLUMNS]] for name in order]
    blocks.append(
        Table(
            ('controller', 'runs', *[t for _, t, _ in KPI_COLUMNS]),
            rows,
            caption='KPIs (mean over seeds; definitions in docs/metrics.md)',
        )
    )
    notes = sorted({f'{k}: {v}' for r in case['runs'] if r['status'] == 'ok' for k, v in r['kpi_notes'].items()})
    if notes:
        blocks.append(Paragraph('KPIs not available: ' + '; '.join(notes) + '.'))
    if case.get('sensitivity'):
        fig = bfig.fig_tornado(case, fig_dir / f"tornado_{_slug(case['case'])}.png")
        blocks.append(Heading(3, f"Sensitivity ({case['case']})"))
        blocks.append(
            Figure(
                fig,
                'How the energy saving at matched comfort (plain front) moves when one plant '
                'or comfort parameter of the simulated car goes to the end of its documented '
                'range (controllers keep their nominal models)',
            )
        )
        rows = [
            [
                s['parameter'],
                _fmt(s.get('low'), 'g'),
                _fmt(s['nominal'], 'g') if s.get('nominal') is not None else 'plant',  # p_a: the moisture balance
                _fmt(s.get('high'), 'g'),
                s.get('source', ''),
            ]
            for s in case['sensitivity']
        ]
        blocks.append(Table(('parameter', 'low', 'nominal', 'high', 'range source'), rows))
    return blocks


def report_blocks(doc: Mapping, fig_dir: Path) -> list:
    """The report as :mod:`ceco_bringup.report_html` blocks."""
    t = doc['timing']
    blocks: list = [
        Heading(1, 'ceco benchmark' + (' (quick)' if doc['quick'] else '')),
        Paragraph(
            f"Schema `{doc['schema']}`, benchmark version {doc['benchmark_version']}, ceco "
            f"{doc['ceco_version']}, code `{doc['code_fingerprint']}`, created {doc['created_utc']}. "
            f"{t['runs']} runs ({t['ran_now']} run now) in {t['wall_s']:.1f} s wall"
            + (f" on {t.get('workers')} worker(s), backend {t.get('backend')}" if 'workers' in t else '')
            + '.'
        ),
    ]
    if doc['quick']:
        blocks.append(
            Warning(
                'quick run (one seed, three cases, set-points 24/25/26 degC only): a smoke test, '
                'not comparable to a full benchmark'
            )
        )
    blocks.append(
        Paragraph(
            f"Front axis `{doc['settings']['front_axis']}` (thermal discomfort: time integral of the distance of PMV, "
            f"clipped to ±3, outside {doc['settings']['band']}), energy axis `{doc['settings']['energy_axis']}`. "
            'The baseline front is the efficient part of the production PI law at the set-points '
            f"{', '.join(format(s, 'g') for s in doc['settings']['setpoints_c'])} degC; the allowance front the same "
            'law with the set-point ramp over the relaxed-bound phase (the permission the CECO strategies have). '
            'Method: docs/benchmark.md.'
        )
    )
    blocks += [Heading(2, 'Savings at matched comfort'), *_headline(doc)]
    for case in doc['cases']:
        blocks += _case_blocks(case, doc['settings'], fig_dir)
    return blocks


def write_report(doc: Mapping, out_dir) -> dict:
    """Write ``report.md``, ``report.html`` and ``figures/`` into ``out_dir``; return their paths."""
    out = Path(out_dir)
    fig_dir = out / 'figures'
    fig_dir.mkdir(parents=True, exist_ok=True)
    blocks = report_blocks(doc, fig_dir)
    md = out / 'report.md'
    md.write_text(render_markdown(blocks, base_dir=out), encoding='utf-8')
    html = out / 'report.html'
    html.write_text(render_html(blocks, title='ceco benchmark'), encoding='utf-8')
    return {'markdown': md, 'html': html, 'figures': fig_dir}
