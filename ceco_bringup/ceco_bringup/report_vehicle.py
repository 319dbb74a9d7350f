"""The vehicle-level part of ``ceco report --vehicle``: FASTSim rows, the section and its figure.

Each strategy's mean A/C electrical power over a run goes to
:func:`ceco_bringup.vehicle_energy.vehicle_energy_table` (docs/analysis.md, "Vehicle-level
energy"); this module turns the rows into report blocks and one PNG.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt
import numpy as np

from ceco_bringup.figures import OKABE_ITO, RC_PARAMS, annotate_bar, ordered, save_png, short_label, strategy_style
from ceco_bringup.report_html import Heading, Paragraph, Table, Warning, fmt_num, fmt_pct, slug
from ceco_bringup.rundata import RunData

__all__ = ['vehicle_rows', 'vehicle_section', 'fig_vehicle']


def vehicle_rows(scenario: str, runs: Mapping[str, RunData], settings):
    """FASTSim rows of one scenario, the drive-cycle note and whether the runs' lengths differ."""
    from ceco_bringup import vehicle_energy as ve

    durations = {r.recomputed['duration_s'] for r in runs.values()}
    duration_s = max(durations)
    p_mean = {
        label: runs[label].recomputed['E_tot_J'] / runs[label].recomputed['duration_s'] for label in ordered(list(runs))
    }
    try:
        t, v = ve.drive_cycle_for_run(scenario, duration_s)
        note = f'drive cycle of scenario `{scenario}` over 0..{duration_s:.0f} s'
    except (ImportError, ValueError, OSError):
        first = next(iter(runs.values())).columns
        t = np.asarray(first['t_s'], dtype=float) - float(first['t_s'][0])
        v = np.asarray(first['speed_mps'], dtype=float)
        note = 'speed trace recorded in the run (scenario not loadable)'
    return ve.vehicle_energy_table(p_mean, t, v, settings), note, len(durations) > 1


def vehicle_section(scenario: str, vrows, note: str, mixed: bool, fig_dir: Path) -> tuple[list, tuple]:
    """The vehicle-level blocks and the (path, caption) of the vehicle figure."""
    blocks: list = [
        Heading(3, 'Vehicle-level energy (FASTSim 3.1)'),
        Paragraph(
            f'Over the {note}. Each strategy\'s mean A/C electrical power is added to the vehicle\'s base '
            'auxiliary load as one constant; every strategy is read off one straight line fitted to FASTSim '
            'runs at several loads around them (fuel versus aux load is not smooth: the fit\'s residual '
            'scatter is given as noise; differences below about twice it are not significant). Hybrid fuel '
            'is charge-corrected. Range: repeating the cycle on the usable battery energy.'
        ),
    ]
    if mixed:
        blocks.append(
            Warning('the runs of this scenario have different lengths; the longest was used for the drive cycle.')
        )
    rows = [
        (
            r['vehicle'],
            r['strategy'],
            fmt_num(r['p_ac_mean_w'], 0),
            fmt_num(r['energy_fit_j'] / 1e6, 3),
            fmt_num(r['energy_direct_j'] / 1e6, 3),
            fmt_pct(r['change_fit_pct']),
            fmt_pct(r['change_direct_pct']),
            fmt_pct(r['paper_change_pct']),
            f"{r['noise_pct']:.2f} %",
            fmt_num(r['ac_share_pct'], 1),
            fmt_num(r['l_per_100km'], 2) if r['powertrain'] != 'BEV' else fmt_num(r['kwh_per_100km'], 2),
            fmt_num(r['range_km'], 0),
            fmt_num(r['range_lost_km'], 1),
            fmt_num(r['range_lost_pct'], 1),
        )
        for r in vrows
    ]
    blocks.append(
        Table(
            (
                'vehicle',
                'strategy',
                'P_A/C mean [W]',
                'E_veh fit [MJ]',
                'E_veh direct [MJ]',
                'change fit [%]',
                'change direct [%]',
                'change paper (SC03) [%]',
                'noise (1σ)',
                'A/C share [%]',
                'L/100 km | kWh/100 km',
                'range [km]',
                'range lost [km]',
                'range lost [%]',
            ),
            rows,
            caption='Vehicle energy per strategy (fuel for the hybrid, battery energy for the electric car); '
            'change: against the baseline as measured (negative = less energy).',
        )
    )
    per_eval = [r['fit_wall_time_s'] / r['n_evals'] for r in vrows]
    blocks.append(
        Paragraph(
            f'FASTSim time per evaluation: {1e3 * min(per_eval):.0f}-'
            f'{1e3 * max(per_eval):.0f} ms (vehicle build + drive, this machine).'
        )
    )
    fig = (
        fig_vehicle(vrows, fig_dir / f'{slug(scenario)}_vehicle.png', f'Vehicle-level energy, {scenario}'),
        'Vehicle energy change against the baseline as measured (negative = less energy; error bars: '
        '±2σ fit noise) next to the paper\'s Prius numbers; range of the electric car lost to the A/C.',
    )
    return blocks, fig


def fig_vehicle(rows: Sequence[Mapping], path, title: str = '') -> Path:
    """Vehicle-level energy change against the baseline per strategy and vehicle.

    Load-averaged fit; error bar = 2x the fit's noise; with the paper's Prius
    numbers; electric car: range lost to the A/C.
    """
    vehicles = list(dict.fromkeys(r['vehicle'] for r in rows))
    strategies = ordered(list(dict.fromkeys(r['strategy'] for r in rows)))
    strategies = [s for s in strategies if s != 'baseline']
    bev = [r for r in rows if r['powertrain'] == 'BEV']
    with plt.rc_context(RC_PARAMS):
        ncols = 2 if bev else 1
        fig, axes = plt.subplots(1, ncols, figsize=(4.8 * ncols, 3.4), squeeze=False)
        ax = axes[0][0]
        x = np.arange(len(strategies))
        width = 0.8 / (len(vehicles) + 1)
        for j, veh in enumerate(vehicles):
            by = {r['strategy']: r for r in rows if r['vehicle'] == veh}
            vals = np.array([by[s]['change_fit_pct'] if s in by else np.nan for s in strategies])
            err = np.array([2 * by[s]['noise_pct'] if s in by else 0 for s in strategies])
            ax.bar(
                x + (j - len(vehicles) / 2) * width,
                vals,
                width,
                yerr=err,
                capsize=2,
                color=OKABE_ITO[(j + 5) % len(OKABE_ITO)],
                edgecolor='k',
                lw=0.5,
                label=veh.replace('_', ' '),
            )
        paper = [
            next(
                (r['paper_change_pct'] for r in rows if r['strategy'] == s and math.isfinite(r['paper_change_pct'])),
                np.nan,
            )
            for s in strategies
        ]
        ax.bar(
            x + (len(vehicles) / 2) * width,
            paper,
            width,
            color='white',
            edgecolor='k',
            hatch='xx',
            lw=0.5,
            label='Paper (2017 Prius HEV, SC03)',
        )
        ax.axhline(0, color='k', lw=0.6)
        fin = [r for r in rows if math.isfinite(r['change_fit_pct'])]
        lows = [r['change_fit_pct'] - 2 * r['noise_pct'] for r in fin]
        highs = [r['change_fit_pct'] + 2 * r['noise_pct'] for r in fin]
        low = min(lows + [p for p in paper if math.isfinite(p)] + [-1.0])
        high = max(highs + [0.0])
        # Room under the bars for the legend; above zero for strategies that cost energy.
        ax.set_ylim(1.7 * low, 1.25 * high + 0.1 * abs(low))
        ax.set_xticks(x, [strategy_style(s)['label'] for s in strategies], rotation=20, ha='right')
        ax.set_ylabel('Vehicle energy change vs baseline [%]\n(negative = less energy)')
        ax.legend(fontsize=7, loc='lower left')
        ax.grid(axis='x', visible=False)
        ax.set_title('Vehicle energy change (+ = more energy)')
        if bev:
            ax = axes[0][1]
            names = ordered(list(dict.fromkeys(r['strategy'] for r in bev)))
            by = {r['strategy']: r for r in bev}
            vals = np.array([by[n]['range_lost_km'] for n in names])
            bars = ax.bar(
                np.arange(len(names)),
                vals,
                color=[strategy_style(n, i)['color'] for i, n in enumerate(names)],
                edgecolor='k',
                lw=0.5,
            )
            for b, n in zip(bars, names):
                annotate_bar(ax, b, f"{by[n]['range_lost_pct']:.1f} %")
            ax.set_xticks(
                np.arange(len(names)),
                [short_label(n) for n in names],
                rotation=20,
                ha='right',
            )
            ax.set_ylabel('Range lost to A/C [km]')
            ax.set_ylim(0, np.nanmax(vals) * 1.15 if np.any(vals > 0) else 1)
            ax.grid(axis='x', visible=False)
            ax.set_title(f"{bev[0]['vehicle'].replace('_', ' ')}: range lost")
        fig.suptitle(title or 'Vehicle level (FASTSim 3.1, mean A/C power as constant aux load)')
        fig.tight_layout()
        return save_png(fig, path)
