"""Figures of the benchmark report: the energy-discomfort plane and the tornado.

Each function takes one case of a results document (``ceco-benchmark/2``), writes
one PNG (200 dpi) and returns its path. Colours: the Okabe-Ito palette of
:mod:`ceco_bringup.figures`, fixed per strategy.

Pure plotting: matplotlib with the Agg backend; no ROS import.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Patch

from ceco_bringup.figures import strategy_style

__all__ = ['fig_plane', 'fig_tornado', 'controller_points']

_DPI = 200
_RC = {'font.size': 8, 'axes.grid': True, 'grid.alpha': 0.3, 'savefig.bbox': 'tight', 'legend.fontsize': 7}
_FAMILY_STYLE = {
    'plain': {'color': '#000000', 'ls': '-', 'label': 'production PI (T_cab at S)'},
    'allowance': {'color': '#0072B2', 'ls': '--', 'label': 'production PI + allowance'},
    # the tuned families in colours outside the strategies' Okabe-Ito palette
    'tuned': {'color': '#7B3294', 'ls': '-', 'label': 'tuned PI (T_cab)'},
    'tuned-allowance': {'color': '#7B3294', 'ls': '--', 'label': 'tuned PI + allowance'},
    'pmv': {'color': '#8C510A', 'ls': '-', 'label': 'tuned PI on PMV'},
    'pmv-allowance': {'color': '#8C510A', 'ls': '--', 'label': 'tuned PI on PMV + allowance'},
}
# the fixed-door families (issue 21, only on the air-quality cases): the tuned laws' hues, lighter, one dash per share
_DOOR_DASH = {0: (0, (1, 1)), 50: '-.', 80: (0, (5, 1)), 100: ':'}
_FAMILY_STYLE.update(
    {
        f'{base}-door{pct}': {'color': color, 'ls': _DOOR_DASH[pct], 'label': f'{label}, door held at {pct / 100:.1f}'}
        for base, color, label in (('tuned', '#C2A5CF', 'tuned PI (T_cab)'), ('pmv', '#DFC27D', 'tuned PI on PMV'))
        for pct in _DOOR_DASH
    }
)
_ORACLE_STYLE = {'color': '#CC0000', 'ls': ':', 'label': 'whole-drive optimum (oracle)'}
_SCORED_KINDS = ('strategy', 'compensated', 'compensated-allowance', 'external')
_AXIS_LABEL = {
    'discomfort_pmvh': 'Thermal discomfort, whole run (PMV outside -0.5..0.5) [PMV·h]',
    'discomfort_band_pmvh': 'Thermal discomfort, band phase [PMV·h]',
    'i_pmv_clipped': 'I_PMV with PMV clipped to ±3 [s]',
    'i_pmv': 'I_PMV [s]',
    'energy_kwh': 'A/C electrical energy (compressor + blower + fan) [kWh]',
}
_LOW, _HIGH = '#56B4E9', '#D55E00'


def controller_points(case: Mapping, fx: str, ex: str) -> dict:
    """The scored controllers' points: ``{controller: (kind, [(discomfort, energy) per seed])}``.

    Finished runs of the scored kinds (strategies, compensated laws, external
    controllers), sorted by seed.
    """
    out: dict = {}
    for r in sorted(case['runs'], key=lambda r: -1 if r['seed'] is None else r['seed']):
        if r['status'] != 'ok' or r['kind'] not in _SCORED_KINDS:
            continue
        d, e = r['kpis'].get(fx), r['kpis'].get(ex)
        if d is None or e is None:
            continue
        out.setdefault(r['controller'], (r['kind'], []))[1].append((float(d), float(e)))
    return out


def _style(name: str, kind: str, index: int) -> dict:
    if kind == 'strategy':
        st = strategy_style(name)
        return {'color': st['color'], 'marker': 'o', 'label': st['label']}
    if kind == 'external':
        return {'color': '#CC79A7', 'marker': '*', 'label': name}
    # the compensated production law: grey squares, hollow for its allowance variant
    return {
        'color': '#7f7f7f',
        'marker': 's',
        'label': name,
        'mfc': 'none' if kind == 'compensated-allowance' else None,
    }


def fig_plane(case: Mapping, path, settings: Mapping, title: str = '') -> Path:
    """Energy over discomfort of one case.

    Every baseline family's front as a line through its efficient points (inefficient family
    members hollow, set-points annotated), the oracle's front(s) when there are any, every
    scored controller at its mean over seeds with min-max whiskers and its seeds as dots. The
    view is zoomed on the strategies and the oracle's levels when they are given (the
    families' warm ends run far beyond them).
    """
    fx, ex = settings['front_axis'], settings['energy_axis']
    with plt.rc_context(_RC):
        fig, ax = plt.subplots(figsize=(6.4, 4.6))
        oracle = case.get('oracle') or {}
        for k, f in enumerate(oracle.get('fronts', []) if fx == 'discomfort_pmvh' else []):
            _front_line(ax, f['front'], _ORACLE_STYLE, 'D', 3, 1.3, _ORACLE_STYLE['label'] if k == 0 else None, 4)
        for family, st in _FAMILY_STYLE.items():
            pts = case['fronts'].get(family) or []
            if not pts:
                continue
            eff = _front_line(ax, pts, st, 'o', 3.5, 1.1, st['label'], 2)
            off = [p for p in pts if not p['efficient']]
            if off:
                ax.plot(
                    [p['discomfort'] for p in off],
                    [p['energy'] for p in off],
                    ls='none',
                    marker='o',
                    ms=3.5,
                    mfc='none',
                    color=st['color'],
                    alpha=0.6,
                )
            for p in eff:
                sp = p['controller'].split('@')[-1]
                ax.annotate(
                    sp,
                    (p['discomfort'], p['energy']),
                    textcoords='offset points',
                    xytext=(3, 2),
                    fontsize=5.5,
                    color=st['color'],
                )
        for i, (name, (kind, pts)) in enumerate(controller_points(case, fx, ex).items()):
            st = _style(name, kind, i)
            arr = np.array(pts)
            m = arr.mean(axis=0)
            one = len(pts) == 1  # no whiskers for a single run
            # min-max whiskers; clipped at 0: the mean of equal seeds can exceed their max by an ulp
            xerr = None if one else [[max(0.0, m[0] - arr[:, 0].min())], [max(0.0, arr[:, 0].max() - m[0])]]
            yerr = None if one else [[max(0.0, m[1] - arr[:, 1].min())], [max(0.0, arr[:, 1].max() - m[1])]]
            ax.errorbar(
                [m[0]],
                [m[1]],
                xerr=xerr,
                yerr=yerr,
                color=st['color'],
                marker=st['marker'],
                ms=6,
                mfc=st.get('mfc') or st['color'],
                lw=0.9,
                capsize=2,
                ls='none',
                label=st['label'] + (f' ({len(pts)} seeds)' if len(pts) > 1 else ''),
                zorder=3,
            )
            if len(pts) > 1:
                ax.plot(arr[:, 0], arr[:, 1], ls='none', marker='.', ms=2.5, color=st['color'], alpha=0.6, zorder=3)
        _zoom(ax, case, fx, ex)
        ax.set_xlabel(_AXIS_LABEL.get(fx, fx))
        ax.set_ylabel(_AXIS_LABEL.get(ex, ex))
        ax.set_title(title or case['case'])
        handles, labels = ax.get_legend_handles_labels()
        fig.legend(handles, labels, loc='upper center', bbox_to_anchor=(0.5, 0.0), ncol=3, frameon=False)
        fig.tight_layout()
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=_DPI)
        plt.close(fig)
    return path


def _front_line(ax, pts, st: Mapping, marker: str, ms: float, lw: float, label, zorder) -> list:
    """Draw a front through its efficient points (sorted by discomfort); return them."""
    eff = sorted((p for p in pts if p['efficient']), key=lambda p: p['discomfort'])
    if eff:
        ax.plot(
            [p['discomfort'] for p in eff],
            [p['energy'] for p in eff],
            color=st['color'],
            ls=st['ls'],
            marker=marker,
            ms=ms,
            lw=lw,
            label=label,
            zorder=zorder,
        )
    return eff


def _zoom(ax, case: Mapping, fx: str, ex: str) -> None:
    """Limit the view to the oracle's levels and the scored controllers.

    The discomfort range of both (plus margins), and the energy range of every front point inside it.
    """
    xs = list((case.get('oracle') or {}).get('levels') or []) if fx == 'discomfort_pmvh' else []
    xs += [d for _, pts in controller_points(case, fx, ex).values() for d, _ in pts]
    if not xs:
        return
    lo, hi = min(xs), max(xs)
    pad = 0.08 * max(hi - lo, 0.05 * max(hi, 1e-9))
    lo, hi = lo - pad, hi + pad
    ys = [p['energy'] for pts in case['fronts'].values() for p in pts if lo <= p['discomfort'] <= hi]
    ys += [
        p['energy']
        for f in (case.get('oracle') or {}).get('fronts', [])
        for p in f['front']
        if lo <= p['discomfort'] <= hi
    ]
    ys += [e for _, pts in controller_points(case, fx, ex).values() for _, e in pts]
    ax.set_xlim(max(lo, 0.0), hi)
    if ys:
        span = max(ys) - min(ys)
        ax.set_ylim(min(ys) - 0.08 * span - 1e-6, max(ys) + 0.08 * span + 1e-6)


def fig_tornado(case: Mapping, path, controllers=None, title: str = '') -> Path:
    """The tornado: how the matched-comfort energy saving moves with each parameter.

    Per controller a panel: for each sensitivity parameter two half-bars from the
    nominal saving [%] (vertical line) to the saving at its low and at its high end,
    parameters sorted by swing. A saving that is undefined at an end (outside the
    front) is marked 'n/a' at the nominal value.
    """
    sens = case.get('sensitivity') or []
    if not sens:
        raise ValueError(f"fig_tornado: case {case.get('case')!r} has no sensitivity results")
    names = list(controllers or [c for c in case['matched']])
    with plt.rc_context(_RC):
        fig, axes = plt.subplots(
            1, len(names), figsize=(2.9 * len(names), 0.32 * len(sens) + 1.6), squeeze=False, sharey=True
        )
        for ax, name in zip(axes[0], names):
            nominal = case['matched'].get(name, {}).get('energy_saving_pct')
            rows = []
            for s in sens:
                lo = s['matched_low'].get(name, {}).get('energy_saving_pct')
                hi = s['matched_high'].get(name, {}).get('energy_saving_pct')
                vals = [v for v in (lo, hi) if v is not None]
                swing = (max(vals) - min(vals)) if len(vals) == 2 else math.inf if vals else -1.0
                rows.append((swing, s['parameter'], lo, hi))
            rows.sort(key=lambda r: r[0])
            ref = nominal if nominal is not None else 0.0
            for k, (_, _label, lo, hi) in enumerate(rows):
                for v, colour, dy in ((lo, _LOW, -0.17), (hi, _HIGH, 0.17)):
                    if v is None:
                        ax.annotate('n/a', (ref, k + dy), ha='center', va='center', fontsize=5.5, color='#666666')
                        continue
                    ax.barh(k + dy, v - ref, left=ref, color=colour, height=0.34, alpha=0.9)
            ax.set_yticks(range(len(rows)), [r[1] for r in rows])
            if nominal is not None:
                ax.axvline(nominal, color='k', lw=0.8)
            else:
                ax.set_title('(nominal saving n/a)', fontsize=6, loc='right')
            st = strategy_style(name)
            ax.set_title(st['label'] if name in ('ceco', 'ceco-e', 'ceco-c', 'ceco-ioch') else name, loc='left')
            ax.set_xlabel('energy saving at matched comfort [%]')
        fig.legend(
            handles=[
                Patch(color=_LOW, label='parameter at its low end'),
                Patch(color=_HIGH, label='parameter at its high end'),
            ],
            loc='upper center',
            bbox_to_anchor=(0.5, 0.0),
            ncol=2,
            frameon=False,
        )
        fig.suptitle(title or f"Sensitivity of the matched-comfort saving, {case['case']}")
        fig.tight_layout()
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=_DPI)
        plt.close(fig)
    return path
