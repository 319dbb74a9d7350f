"""The benchmark report: Markdown and self-contained HTML from a results document.

``write_report(doc, out_dir)`` writes ``report.md``, ``report.html`` (every PNG
embedded, no external reference) and ``figures/*.png`` from a ``ceco-benchmark/2``
document; nothing is recomputed from runs, so the report shows exactly what
results.json holds. Sections: the headline table (energy saving at matched
comfort against the production-gains front and against the strongest family,
the strongest family there, ``headroom_captured``, every case), the strongest
family per case, then per case the energy-discomfort plane (every family, the
oracle's front), the matched-comfort table with the seeds' spread and a KPI
table, then the sensitivity (tornado) and the timing.

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
from . import front as fr

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


DOMINATES_WORDS = 'no: **dominates** every baseline (more comfortable, less energy; no matched saving)'
"""The dominated cell of a controller better on both axes than every efficient baseline (``front.dominates_front``):
its saving has no matched value (no extrapolation), which read as a bare n/a like no result at all."""


def _match_cells(m: Mapping | None) -> list[str]:
    if m is None:
        return ['n/a', 'n/a', 'n/a']
    seeds = m.get('seeds', {})
    dom = m.get('dominated')
    dom_seeds = seeds.get('dominated', [])
    dom_txt = ('**yes**' if dom else DOMINATES_WORDS if fr.dominates_front(m) else 'no') + (
        f' ({sum(dom_seeds)}/{len(dom_seeds)} seeds)' if len(dom_seeds) > 1 else ''
    )
    return [
        _fmt(m.get('energy_saving_pct'), '+.1f') + _spread(seeds.get('energy_saving_pct', [])),
        _fmt(m.get('discomfort_reduction_pct'), '+.1f') + _spread(seeds.get('discomfort_reduction_pct', [])),
        dom_txt,
    ]


def _notes(m: Mapping) -> str:
    subs = (
        ('plain', m),
        ('allowance', m.get('allowance')),
        ('strongest', m.get('strongest')),
        ('headroom', m.get('headroom')),
    )
    return '; '.join(f'{fam}: {sub["note"]}' for fam, sub in subs if sub and sub.get('note'))


def _headroom_cells(m: Mapping) -> list[str]:
    h = m.get('headroom')
    if not h:
        return ['n/a (no oracle)', 'n/a']
    seeds = h.get('seeds', {})
    return [
        _fmt(h.get('headroom_captured'), '.2f') + _spread(seeds.get('headroom_captured', []), '.2f'),
        _fmt(h.get('bound_saving_pct'), '+.1f'),
    ]


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


def _strongest_cells(m: Mapping) -> list[str]:
    st = m.get('strongest') or {}
    seeds = st.get('seeds', {})
    return [
        _fmt(st.get('energy_saving_pct'), '+.1f') + _spread(seeds.get('energy_saving_pct', [])),
        '**yes**' if st.get('dominated') else DOMINATES_WORDS if fr.dominates_front(st) else 'no',
        str(st.get('family') or 'n/a'),
    ]


_HEADLINE_HEADER = (
    'E saving at matched comfort [%] vs production PI',
    'D cut at matched energy [%] vs production PI',
    'dominated (production PI)',
    'E saving at matched comfort [%] vs strongest family',
    'dominated (any family)',
    'strongest family there',
    'headroom_captured [-]',
    "oracle's saving there [%]",
    'note',
)


def _headline(doc: Mapping) -> list:
    rows = []
    for case in doc['cases']:
        for name, m in case['matched'].items():
            rows.append([case['case'], name, *_match_cells(m), *_strongest_cells(m), *_headroom_cells(m), _notes(m)])
    return [
        Table(
            ('case', 'controller', *_HEADLINE_HEADER),
            rows,
            caption='Savings at matched comfort: positive = less energy than the front at the same discomfort / less '
            'discomfort at the same energy; production PI = the plain family with the production gains (the paper\'s '
            'comparison); strongest family = the least energy any baseline family spends at that discomfort; '
            "headroom_captured = the controller's saving over the oracle's, both against the strongest family; "
            '[min … max] over seeds',
        )
    ]


def _strongest_table(doc: Mapping) -> list:
    rows = []
    for case in doc['cases']:
        st, orc = case['strongest'], case['oracle']
        per = ', '.join(f"{x['discomfort']:.4g}: {x['family'] or 'n/a'}" for x in st['levels'])
        rows.append(
            [
                case['case'],
                str(st['family'] or 'n/a'),
                per,
                f"{orc['status']}" + (f" ({orc['note']})" if orc['note'] else ''),
            ]
        )
    return [
        Table(
            ('case', 'strongest family', 'strongest at each level [PMV·h: family]', 'oracle'),
            rows,
            caption='The strongest family per case: the family whose front spends the least energy at the most of '
            "the oracle's discomfort levels (docs/benchmark.md, \"Strongest family\")",
        )
    ]


def _diff(a, b):
    return None if a is None or b is None else a - b


def _phase_blocks(case: Mapping) -> list:
    """Where the savings sit: each controller, the strongest family and the oracle at its discomfort (by_phase)."""
    rows = []
    for name, m in case['matched'].items():
        p = m.get('by_phase')
        if not p:
            continue
        c, s, b = p['controller'], p['strongest'], p['bound']

        def three(key, spec, c=c, s=s, b=b):
            return ' / '.join(_fmt(x.get(key), spec) for x in (c, s, b))

        rows.append(
            [
                name,
                _fmt(_diff(s['energy_kwh'], c['energy_kwh']), '+.4f')
                + ' / '
                + _fmt(_diff(s['energy_band_kwh'], c['energy_band_kwh']), '+.4f'),
                _fmt(_diff(s['energy_kwh'], b['energy_kwh']), '+.4f')
                + ' / '
                + _fmt(_diff(s['energy_band_kwh'], b['energy_band_kwh']), '+.4f'),
                three('pmv_mean_band', '+.3f'),
                three('pmv_above_band_s', '.0f'),
                three('t_evap_sp_mean_band_c', '.2f'),
                three('mdot_bl_mean_band_kgps', '.4f'),
            ]
        )
    if not rows:
        return []
    return [
        Table(
            (
                'controller',
                'its saving vs strongest [kWh]: whole run / band phase',
                "oracle's saving vs strongest [kWh]: whole run / band phase",
                'band phase PMV mean: controller / strongest / oracle',
                'band phase PMV above +0.5 [s]: controller / strongest / oracle',
                'band phase coil set-point mean [degC]: controller / strongest / oracle',
                'band phase blower mean [kg/s]: controller / strongest / oracle',
            ),
            rows,
            caption='Where the savings sit: the strongest family and the oracle read on their fronts at the '
            "controller's discomfort (linear between their two neighbouring points, mean over the seeds; "
            'results.json `matched.<controller>.by_phase`); the band phase runs from the moment the comfort band '
            'applies, the rest of the run is the pull-down',
        )
    ]


_KIND_ORDER = (
    'strategy',
    'external',
    'compensated',
    'compensated-allowance',
    'baseline-tuned',
    'baseline-tuned-allowance',
    'baseline-pmv',
    'baseline-pmv-allowance',
    'baseline',
    'baseline-allowance',
)


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
    for r in errors:  # failed (the controller did not control: KPIs in results.json, not matched) or error
        blocks.append(Warning(f"run {r['controller']} seed {r['seed']} {r['status']}: {r.get('error', '')}"))
    fig = bfig.fig_plane(case, fig_dir / f"plane_{_slug(case['case'])}.png", settings)
    blocks.append(
        Figure(
            fig,
            f"{case['case']}: energy over whole-run discomfort; lines: the baseline families' fronts (efficient "
            "points filled, labelled with the set-point; dashed: with the allowance), red dotted: the whole-drive "
            "optimum (oracle) where available; markers: mean over seeds with min-max whiskers; zoomed on the "
            "controllers and the oracle's levels",
        )
    )
    rows = [
        [
            name,
            *_match_cells(m),
            *_match_cells(m.get('allowance')),
            *_strongest_cells(m),
            *_headroom_cells(m),
            _notes(m),
        ]
        for name, m in case['matched'].items()
    ]
    blocks.append(
        Table(
            (
                'controller',
                'E saving matched comfort, production PI [%]',
                'D cut matched energy, production PI [%]',
                'dominated, production PI',
                'E saving matched comfort, production PI + allowance [%]',
                'D cut matched energy, production PI + allowance [%]',
                'dominated, production PI + allowance',
                'E saving matched comfort, strongest [%]',
                'dominated (any family)',
                'strongest family',
                'headroom_captured [-]',
                "oracle's saving [%]",
                'note',
            ),
            rows,
            caption='Matched comfort',
        )
    )
    blocks += _phase_blocks(case)
    orc = case['oracle']
    blocks.append(
        Paragraph(
            f"Oracle (whole-drive optimum, `{orc['entry_point']}`): **{orc['status']}**"
            + (f" ({orc['note']})" if orc['note'] else '')
            + (f"; levels {', '.join(format(x, '.4g') for x in orc['levels'])} PMV·h" if orc['levels'] else '')
            + '. It is a local optimum of an NLP replayed on the plant: an achievable point, not a proven global bound.'
        )
    )
    kinds = _kind_of(case)
    means = _mean_kpis(case)
    order = sorted(
        means,
        key=lambda n: (
            _KIND_ORDER.index(kinds[n]) if kinds[n] in _KIND_ORDER else len(_KIND_ORDER),
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
                'quick run (one seed, three cases, three set-points per family, no oracle): '
                'a smoke test, not comparable to a full benchmark'
            )
        )
    blocks.append(
        Paragraph(
            f"Front axis `{doc['settings']['front_axis']}` (thermal discomfort: time integral of the distance of PMV, "
            f"clipped to ±3, outside {doc['settings']['band']}), energy axis `{doc['settings']['energy_axis']}`. "
            'Each baseline family is one law at a range of set-points, its front the efficient part: the production '
            f"PI law (gains unchanged) at {', '.join(format(s, 'g') for s in doc['settings']['setpoints_c'])} degC, "
            'the same law with tuned gains, and the tuned PI on the cabin PMV at PMV '
            f"{', '.join(format(s, '+g') for s in doc['settings'].get('setpoints_pmv', []))}; each also with the "
            'allowance (the set-point ramp over the relaxed-bound phase: the permission the CECO strategies have). '
            'Method: docs/benchmark.md.'
        )
    )
    blocks += [Heading(2, 'Savings at matched comfort'), *_headline(doc)]
    blocks += [Heading(2, 'The strongest family'), *_strongest_table(doc)]
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
