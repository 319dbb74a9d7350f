"""The paper's figures from run time series (matplotlib, Agg backend, PNG).

Each function takes the runs of ONE scenario as ``{strategy: columns}``
(``columns`` = dict of 1-D arrays with the ``timeseries.csv`` names, see
docs/architecture.md), writes one PNG and returns its path. Colours are the
Okabe-Ito colour-blind-safe palette, fixed per strategy so every figure of a
report agrees; time axes are shared within a figure and labelled in seconds.

Pure plotting: no ROS import; matplotlib is imported with the Agg backend so
it never needs a display.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Patch

from ceco_bringup.rundata import fallback_mask
from ceco_core.contracts import NAMED_STRATEGIES
from ceco_core.metrics import relative_change_pct

__all__ = [
    'STRATEGY_ORDER',
    'ordered',
    'strategy_style',
    'short_label',
    'fig_pmv',
    'fig_temperatures',
    'fig_powers',
    'fig_inputs',
    'fig_bars',
    'OKABE_ITO',
    'RC_PARAMS',
    'save_png',
    'annotate_bar',
    'fig_solver',
    'fig_plane',
]

STRATEGY_ORDER = NAMED_STRATEGIES
"""Order in which strategies appear in legends, tables and bars."""

OKABE_ITO = ('#000000', '#E69F00', '#56B4E9', '#009E73', '#D55E00', '#0072B2', '#CC79A7', '#F0E442')
_LABEL = {
    'baseline': 'Baseline (PI, 26 °C)',
    'ceco': 'CECO',
    'ceco-e': 'CECO-E',
    'ceco-c': 'CECO-C',
    'ceco-ioch': 'CECO-IOCH',
    'ceco-pmv': 'CECO-PMV',
    'ceco-pmv-aq': 'CECO-PMV-AQ',
    'ceco-pmv-door': 'CECO-PMV-DOOR',
}
_DPI = 200
RC_PARAMS = {  # matplotlib rc of every ceco figure
    'font.size': 9,
    'axes.labelsize': 9,
    'axes.titlesize': 10,
    'legend.fontsize': 8,
    'xtick.labelsize': 8,
    'ytick.labelsize': 8,
    'axes.grid': True,
    'grid.alpha': 0.3,
    'grid.linewidth': 0.5,
    'lines.linewidth': 1.3,
    'savefig.bbox': 'tight',
    'figure.dpi': _DPI,
}


def ordered(names: Sequence[str]) -> list[str]:
    """Strategies in :data:`STRATEGY_ORDER`, unknown names after, sorted."""
    known = [s for s in STRATEGY_ORDER if s in names]
    return known + sorted(n for n in names if n not in STRATEGY_ORDER)


TOL_MUTED = ('#332288', '#88CCEE', '#44AA99', '#117733', '#999933', '#DDCC77', '#CC6677', '#882255', '#AA4499')
"""Paul Tol's muted qualitative scheme: the colours of names ceco does not know (a user's controller, a second run
of a strategy), apart from the Okabe-Ito colours its own strategies hold."""


def strategy_style(name: str, index: int | None = None) -> dict:
    """Colour, label and line style of a strategy (stable across figures).

    A name ceco does not know takes ``TOL_MUTED[index]`` (its position among the plotted names), never the colour
    of one of ceco's strategies: a report's 'ceco-c (runs/b/ceco-c)' beside 'ceco-c' took ceco-c's own.
    """
    dashes = '--' if name == 'baseline' else '-'
    if name in STRATEGY_ORDER:
        color = OKABE_ITO[STRATEGY_ORDER.index(name) % len(OKABE_ITO)]
    else:
        color = TOL_MUTED[(index or 0) % len(TOL_MUTED)]
    return {'color': color, 'label': _LABEL.get(name, name), 'linestyle': dashes}


def short_label(name: str) -> str:
    """A strategy's label without its parenthesis ('Baseline' for 'Baseline (PI, 26 °C)'), for bar axes.

    A name ceco does not know, as a report's 'baseline (runs/b/baseline)' for a second baseline run, stays whole.
    """
    return _LABEL[name].split(' (')[0] if name in _LABEL else name


def save_png(fig, path: Path) -> Path:
    """Write ``fig`` as a PNG at ``path`` (parents created) and close it; returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=_DPI)
    plt.close(fig)
    return path


def _time_axis(ax, runs: Mapping[str, Mapping]) -> None:
    t_end = max(float(np.asarray(c['t_s'])[-1]) for c in runs.values())
    ax.set_xlim(0.0, t_end)
    ax.set_xlabel('Time t [s]')


def _lines(ax, runs, key, scale=1.0, steps=False):
    for i, name in enumerate(ordered(list(runs))):
        c = runs[name]
        if key not in c:
            continue
        st = strategy_style(name, i)
        ax.plot(
            c['t_s'],
            np.asarray(c[key], dtype=float) * scale,
            color=st['color'],
            ls=st['linestyle'],
            label=st['label'],
            drawstyle='steps-post' if steps else 'default',
        )


def _title_legend(fig, ax, title: str) -> None:
    """Title on top and the legend in one band under the time axis (never over data)."""
    handles, labels = ax.get_legend_handles_labels()
    fig.suptitle(title)
    fig.legend(handles, labels, loc='outside lower center', ncol=min(len(labels), 3), frameon=False)


def fig_pmv(runs: Mapping[str, Mapping], path, title: str = '') -> Path:
    """PMV of every strategy with the scenario's lower/upper PMV bounds."""
    with plt.rc_context(RC_PARAMS):
        fig, ax = plt.subplots(figsize=(6.5, 3.9), layout='constrained')
        first = runs[ordered(list(runs))[0]]
        t = np.asarray(first['t_s'])
        lb, ub = np.asarray(first['pmv_lb']), np.asarray(first['pmv_ub'])
        ax.fill_between(t, lb, ub, color='0.85', alpha=0.6, lw=0, label='Comfort bounds (PMV$_{LB}$..PMV$_{UB}$)')
        ax.plot(t, ub, color='0.35', lw=0.9, ls=':')
        ax.plot(t, lb, color='0.35', lw=0.9, ls=':')
        _lines(ax, runs, 'pmv')
        ax.axhline(0.0, color='0.5', lw=0.6)
        ymax = max(float(np.max(c['pmv'])) for c in runs.values())
        ymin = min(float(np.min(c['pmv'])) for c in runs.values())
        top = max(1.0, min(ymax, 3.5) + 0.2)
        ax.set_ylim(min(-1.0, ymin - 0.2), top)
        if ymax > top:  # the hot-soaked start is off the PMV scale; say so instead of squashing the plot
            ax.text(
                0.99,
                0.97,
                f'axis cut at {top:.1f}; max PMV {ymax:.1f} (hot-soaked start)',
                transform=ax.transAxes,
                ha='right',
                va='top',
                fontsize=7,
                color='0.3',
            )
        ax.set_ylabel('PMV [-]')
        _time_axis(ax, runs)
        _title_legend(fig, ax, title or 'Thermal comfort (PMV) and its bounds')
        return save_png(fig, path)


def fig_temperatures(runs: Mapping[str, Mapping], path, title: str = '') -> Path:
    """Cabin air temperature (top) and vent air temperature (bottom)."""
    with plt.rc_context(RC_PARAMS):
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(6.5, 5.4), sharex=True, layout='constrained')
        _lines(a1, runs, 't_cab_c')
        first = runs[ordered(list(runs))[0]]
        if 't_amb_c' in first:
            a1.plot(first['t_s'], first['t_amb_c'], color='0.5', lw=0.9, ls='-.', label='Ambient')
        a1.set_ylabel('Cabin air T$_{cab}$ [°C]')
        _lines(a2, runs, 't_vent_c')
        a2.set_ylabel('Vent air T$_{ain}$ [°C]')
        _time_axis(a2, runs)
        _title_legend(fig, a1, title or 'Cabin and vent air temperatures')
        fig.align_ylabels()
        return save_png(fig, path)


def fig_powers(runs: Mapping[str, Mapping], path, title: str = '') -> Path:
    """Compressor (top) and blower (bottom) electrical power [kW, W]."""
    with plt.rc_context(RC_PARAMS):
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(6.5, 5.4), sharex=True, layout='constrained')
        _lines(a1, runs, 'p_comp_w', 1e-3)
        a1.set_ylabel('Compressor P$_{comp}$ [kW]')
        a1.set_ylim(bottom=0.0)
        _lines(a2, runs, 'p_blower_w')
        a2.set_ylabel('Blower P$_{bl}$ [W]')
        a2.set_ylim(bottom=0.0)
        _time_axis(a2, runs)
        _title_legend(fig, a1, title or 'A/C electrical power')
        fig.align_ylabels()
        return save_png(fig, path)


def fig_inputs(runs: Mapping[str, Mapping], path, title: str = '') -> Path:
    """The two control inputs: blower air flow (top), evaporator set-point (bottom)."""
    with plt.rc_context(RC_PARAMS):
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(6.5, 5.4), sharex=True, layout='constrained')
        _lines(a1, runs, 'mdot_bl_kgps', steps=True)
        a1.set_ylabel('Blower air flow $\\dot m_{bl}$ [kg/s]')
        _lines(a2, runs, 't_evap_sp_c', steps=True)
        a2.set_ylabel('Evaporator set-point T$_{evap,sp}$ [°C]')
        _time_axis(a2, runs)
        _title_legend(fig, a1, title or 'Control inputs (held over each control period)')
        fig.align_ylabels()
        return save_png(fig, path)


def annotate_bar(ax, bar, text: str) -> None:
    """Write ``text`` just above the top of ``bar`` (a matplotlib Rectangle)."""
    ax.annotate(
        text,
        (bar.get_x() + bar.get_width() / 2, bar.get_height()),
        ha='center',
        va='bottom',
        fontsize=7,
        xytext=(0, 2),
        textcoords='offset points',
    )


def _bar_labels(ax, bars, values, base, fmt='{:+.1f} %'):
    for b, v in zip(bars, values):
        change = math.nan if base is None else relative_change_pct(v, base)
        if math.isfinite(change):
            annotate_bar(ax, b, fmt.format(change))


def fig_bars(metrics: Mapping[str, Mapping], path, title: str = '', baseline: str = 'baseline') -> Path:
    """A/C energy (compressor + blower + condenser fan, stacked, kWh), I_PMV and OTC violation per strategy.

    Each bar is annotated with its change against the baseline, as measured (+ = more).
    """
    names = ordered(list(metrics))
    x = np.arange(len(names))
    labels = [short_label(n) for n in names]
    colors = [strategy_style(n, i)['color'] for i, n in enumerate(names)]
    with plt.rc_context(RC_PARAMS):
        fig, axes = plt.subplots(1, 3, figsize=(9.0, 3.3))
        e_comp = np.array([metrics[n]['E_comp_J'] for n in names]) / 3.6e6
        e_bl = np.array([metrics[n]['E_blower_J'] for n in names]) / 3.6e6
        e_fan = np.array([metrics[n].get('E_fan_J', 0.0) for n in names]) / 3.6e6
        ax = axes[0]
        ax.bar(x, e_comp, color=colors, edgecolor='k', lw=0.5, label='Compressor')
        ax.bar(
            x,
            e_bl,
            bottom=e_comp,
            color=colors,
            edgecolor='k',
            lw=0.5,
            hatch='///',
            alpha=0.6,
            label='Blower (hatched)',
        )
        ax.bar(
            x,
            e_fan,
            bottom=e_comp + e_bl,
            color=colors,
            edgecolor='k',
            lw=0.5,
            hatch='...',
            alpha=0.35,
            label='Condenser fan (dotted)',
        )
        tot = e_comp + e_bl + e_fan
        base_tot = tot[names.index(baseline)] if baseline in names else None
        for xi, v in zip(x, tot):
            change = math.nan if base_tot is None else relative_change_pct(v, base_tot)
            if math.isfinite(change):
                ax.annotate(
                    f'{change:+.1f} %',
                    (xi, v),
                    ha='center',
                    va='bottom',
                    fontsize=7,
                    xytext=(0, 2),
                    textcoords='offset points',
                )
        ax.set_ylabel('A/C energy E (comp. + blower + fan) [kWh]')
        ax.set_ylim(0, tot.max() * 1.32)
        ax.legend(
            handles=[
                Patch(facecolor='white', edgecolor='k', lw=0.5, label='Compressor'),
                Patch(facecolor='white', edgecolor='k', lw=0.5, hatch='///', label='Blower'),
                Patch(facecolor='white', edgecolor='k', lw=0.5, hatch='...', label='Fan'),
            ],
            loc='upper center',
            ncol=3,
            fontsize=7,
        )
        for ax, key, ylab in (
            (axes[1], 'I_pmv', 'Comfort index I$_{PMV}$ = ∫PMV² dt [s]'),
            (axes[2], 'otc_violation_pct', 'Comfort-bound violation [% of time]'),
        ):
            vals = np.array([float(metrics[n][key]) for n in names])
            bars = ax.bar(x, vals, color=colors, edgecolor='k', lw=0.5)
            if key == 'I_pmv':
                _bar_labels(ax, bars, vals, vals[names.index(baseline)] if baseline in names else None)
            else:
                for b, v in zip(bars, vals):
                    ax.annotate(
                        f'{v:.1f}',
                        (b.get_x() + b.get_width() / 2, v),
                        ha='center',
                        va='bottom',
                        fontsize=7,
                        xytext=(0, 2),
                        textcoords='offset points',
                    )
            ax.set_ylabel(ylab)
            top = np.nanmax(vals) if np.any(np.isfinite(vals)) else 1.0
            ax.set_ylim(0, max(top, 1e-9) * 1.15 if top > 0 else 1.0)
        for ax in axes:
            ax.set_xticks(x, labels, rotation=30, ha='right')
            ax.grid(axis='x', visible=False)
        fig.suptitle(title or 'Energy and comfort per strategy (labels: change vs baseline, + = more)')
        fig.tight_layout()
        return save_png(fig, path)


def fig_solver(diags: Mapping[str, Mapping], path, title: str = '') -> Path:
    """Solve-time distribution per NMPC strategy (box plot, log scale) with the number of fallbacks."""
    names = [
        n
        for n in ordered(list(diags))
        if np.any(np.isfinite(np.asarray(diags[n].get('solve_time_ms', []), dtype=float)))
    ]
    with plt.rc_context(RC_PARAMS):
        fig, ax = plt.subplots(figsize=(6.5, 3.2))
        data = []
        for n in names:
            st = np.asarray(diags[n]['solve_time_ms'], dtype=float)
            data.append(st[np.isfinite(st)])
        if data:
            bp = ax.boxplot(
                data,
                whis=(5, 95),
                showfliers=True,
                patch_artist=True,
                flierprops={'markersize': 2},
                medianprops={'color': 'k', 'linewidth': 1.2},
            )
            for i, (patch, n) in enumerate(zip(bp['boxes'], names)):
                patch.set_facecolor(strategy_style(n, i)['color'])
                patch.set_alpha(0.6)
            labels = []
            for n in names:
                fb = diags[n].get('fallback')
                nfb = int(fallback_mask(fb).sum()) if fb is not None else 0
                labels.append(f"{strategy_style(n)['label']}\n{nfb} fallback{'s' if nfb != 1 else ''}")
            ax.set_xticks(np.arange(1, len(names) + 1), labels)
            ax.set_yscale('log')
        else:
            ax.text(0.5, 0.5, 'no solver data', ha='center', va='center', transform=ax.transAxes)
        ax.set_ylabel('Solve time per control step [ms]')
        ax.set_title(title or 'NMPC solve time (box 25-75 %, whiskers 5-95 %)')
        return save_png(fig, path)


def fig_plane(points: Mapping[str, Mapping], family: Mapping[str, Mapping], path, title: str = '') -> Path:
    """The energy-discomfort plane: the baseline family's front and every run.

    ``points``: {strategy: point} and ``family``: {'LAW@S': point} (one front per law: ``baseline``,
    ``baseline-tuned``), each point a mapping with
    ``discomfort_pmvh`` [PMV h] and ``energy_kwh`` [kWh] (``ceco_bringup.verdict.run_point``). The
    front is drawn through the family's efficient points (inefficient ones hollow), every
    set-point annotated; each run is a marker in its strategy colour. Below the front at the same
    discomfort = energy saved at matched comfort. Writes a PNG and returns its path.
    """
    from ceco_bringup.benchmark import front as fr

    with plt.rc_context(RC_PARAMS):
        fig, ax = plt.subplots(figsize=(6.0, 4.2))
        from ceco_bringup.verdict import FAILED_KEY, family_law

        family = {n: p for n, p in family.items() if FAILED_KEY not in p}  # a failed member has no point
        laws: dict[str, dict] = {}
        for n, p in family.items():
            laws.setdefault(family_law(n), {})[n] = (p['discomfort_pmvh'], p['energy_kwh'])
        law_style = {
            'baseline': ('#7f7f7f', '-', 'production PI at set-point S'),
            'baseline-tuned': ('#2b2b2b', '--', 'tuned PI at set-point S'),
            'baseline-doorco2': ('#a6761d', '-', 'production PI, CO2-holding door, at set-point S'),
            'baseline-tuned-doorco2': ('#6b4c11', '--', 'tuned PI, CO2-holding door, at set-point S'),
        }
        # the verdict's rule (verdict.matched): members at the discomfort ceiling are no vertices
        ceiling = fr.saturation_ceiling([*points.values(), *family.values()], 'discomfort_pmvh')
        for law, members in laws.items():
            color, ls, label = law_style.get(law, ('#7f7f7f', ':', f'{law} at set-point S'))
            f = fr.build_front(members, ceiling)
            ax.plot(f.d, f.e, ls, color=color, lw=1.2, label=label)
            for fp in f.points:
                ax.plot([fp.discomfort], [fp.energy], 'o', ms=4, color=color, mfc=color if fp.efficient else 'none')
                ax.annotate(
                    fp.name.split('@')[-1] + ' °C',
                    (fp.discomfort, fp.energy),
                    textcoords='offset points',
                    xytext=(4, 2),
                    fontsize=7,
                    color=color,
                )
        for i, name in enumerate(ordered(list(points))):
            st = strategy_style(name, i)
            p = points[name]
            ax.plot(
                [p['discomfort_pmvh']],
                [p['energy_kwh']],
                marker='s' if name == 'baseline' else 'o',
                ms=7,
                ls='none',
                color=st['color'],
                label=st['label'],
            )
        ax.set_xlabel('Thermal discomfort: PMV outside -0.5..+0.5, clipped at ±3 [PMV·h]')
        ax.set_ylabel('A/C energy: compressor + blower + condenser fan [kWh]')
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc='best', fontsize=7)
        ax.set_title(title or 'Energy against discomfort (lower left is better)')
        return save_png(fig, path)


def front_figure(
    summary: Sequence[Mapping], path: str | os.PathLike, baseline: str = 'baseline', zoom_pct: tuple | None = (4.0, 8.0)
) -> Path:
    """The energy-comfort plane of every group of a summary, against its baseline; one column per group.

    Top row the whole run (ΔE_tot vs ΔI_PMV [%]), middle row the
    same near the baseline (half-widths ``zoom_pct`` = (energy, I_PMV) [%];
    None: no such row), bottom row the comfort-zone phase (ΔE_zone vs
    ΔI_PMV,zone [%]).
    The baseline is the origin (black cross); the shaded lower-left quadrant
    is where a point dominates it (less energy, lower or equal I_PMV). The
    points of a strategy with settings labels are joined in label order (the
    grid's order) and annotated with the label; strategies with default
    settings are single markers. Writes a PNG (200 dpi) and returns its path.
    """
    from ceco_bringup.sweep.grid import DEFAULT_SETTINGS, GROUP_AXES

    groups: dict = {}
    for r in summary:
        groups.setdefault(tuple(r[a] for a in GROUP_AXES), []).append(r)
    if not groups:
        raise ValueError('front_figure: the summary has no rows')
    n = len(groups)
    panels = [
        ('E_tot_kWh_change_pct', 'I_pmv_change_pct', 'whole run', 'ΔE_tot [%]', 'ΔI_PMV [%]', None),
        ('E_zone_J_change_pct', 'I_pmv_zone_change_pct', 'comfort-zone phase', 'ΔE_zone [%]', 'ΔI_PMV,zone [%]', None),
    ]
    if zoom_pct is not None:
        panels.insert(
            1,
            (
                'E_tot_kWh_change_pct',
                'I_pmv_change_pct',
                'whole run, near the baseline',
                'ΔE_tot [%]',
                'ΔI_PMV [%]',
                (float(zoom_pct[0]), float(zoom_pct[1])),
            ),
        )
    with plt.rc_context({'font.size': 8, 'axes.grid': True, 'grid.alpha': 0.3, 'savefig.bbox': 'tight'}):
        fig, axes = plt.subplots(len(panels), n, figsize=(3.6 * n, 3.2 * len(panels)), squeeze=False)
        for j, (g, rs) in enumerate(groups.items()):
            name = ' / '.join(
                str(x) for x, a in zip(g, GROUP_AXES) if x not in ('scenario', 'perfect') or a == 'scenario'
            )
            for i, (kx, ky, phase, xl, yl, zoom) in enumerate(panels):
                ax = axes[i][j]
                pts = [r for r in rs if not (r['strategy'] == baseline and r.get('settings') == DEFAULT_SETTINGS)]
                xs = [float(r.get(kx, float('nan'))) for r in pts] + [0.0]
                ys = [float(r.get(ky, float('nan'))) for r in pts] + [0.0]
                fin = [(x, y) for x, y in zip(xs, ys) if math.isfinite(x) and math.isfinite(y)]
                if zoom:
                    fin = [(-zoom[0], -zoom[1]), (zoom[0], zoom[1])]
                x0 = min(x for x, _ in fin)
                y0 = min(y for _, y in fin)
                pad_x = 0.08 * (max(x for x, _ in fin) - x0 or 1.0)
                pad_y = 0.08 * (max(y for _, y in fin) - y0 or 1.0)
                ax.fill_between(
                    [min(x0, 0.0) - 2 * pad_x, 0.0],
                    min(y0, 0.0) - 2 * pad_y,
                    0.0,
                    color='#009E73',
                    alpha=0.12,
                    lw=0,
                    label='dominates the baseline',
                )
                ax.axhline(0.0, color='k', lw=0.6)
                ax.axvline(0.0, color='k', lw=0.6)
                ax.plot([0.0], [0.0], 'kx', ms=8, mew=2, label=strategy_style(baseline)['label'])
                by_strategy: dict = {}
                for r in pts:
                    by_strategy.setdefault(r['strategy'], []).append(r)
                for k, (st, srs) in enumerate(by_strategy.items()):
                    style = strategy_style(st, k)
                    x = [float(r.get(kx, float('nan'))) for r in srs]
                    y = [float(r.get(ky, float('nan'))) for r in srs]
                    labelled = len(srs) > 1 or srs[0].get('settings') != DEFAULT_SETTINGS
                    ax.plot(
                        x,
                        y,
                        marker='o',
                        ms=4,
                        color=style['color'],
                        lw=1.0 if labelled else 0,
                        label=style['label'] + (' (settings labels)' if labelled else ''),
                    )
                    if labelled:  # labels of points closer than 4 % of the axes to the last labelled one are left out
                        span_x = (max(x for x, _ in fin) - min(x0, 0.0)) or 1.0
                        span_y = (max(y for _, y in fin) - min(y0, 0.0)) or 1.0
                        last = None
                        for r, xv, yv in zip(srs, x, y):
                            if not (math.isfinite(xv) and math.isfinite(yv)):
                                continue
                            if last and math.hypot((xv - last[0]) / span_x, (yv - last[1]) / span_y) < 0.04:
                                continue
                            last = (xv, yv)
                            ax.annotate(
                                str(r.get('settings')),
                                (xv, yv),
                                textcoords='offset points',
                                xytext=(3, 3),
                                fontsize=6.5,
                                color=style['color'],
                            )
                ax.set_xlim(min(x0, 0.0) - pad_x, max(x for x, _ in fin) + pad_x)
                ax.set_ylim(min(y0, 0.0) - pad_y, max(y for _, y in fin) + pad_y)
                ax.set_xlabel(xl + ' vs baseline')
                ax.set_ylabel(yl + ' vs baseline')
                ax.set_title(f'{name}: {phase}')
        handles, labels = axes[0][0].get_legend_handles_labels()
        fig.legend(handles, labels, loc='lower center', ncol=len(labels), frameon=False, bbox_to_anchor=(0.5, -0.04))
        fig.tight_layout()
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=200)
        plt.close(fig)
    return path
