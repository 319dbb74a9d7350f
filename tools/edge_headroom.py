"""What the bound's crossings of the band's edge are worth: headroom_captured against the oracle that holds it.

    python tools/edge_headroom.py RESULTS.json CASE [CASE ...] [--strategy ceco-pmv] [--margin 0.01]
                                    [--with-margin] [--terminal] [--pointwise] [--co2-margin-ppm PPM]

The benchmark's oracle (docs/oracle.md) bounds the integrated discomfort only: once its pull-down has come to the
band's upper edge (+0.5) it may go back above it where that saves energy (10-75 s per drive on the standard
cycles). The issue asks a strategy to hold the PMV under the edge without crossing it. Per case this script
solves, at two discomfort levels bracketing the strategy's seeds (the benchmark's own oracle levels around their
least and greatest discomfort; without them, that range widened by ``--margin``), the oracle and the oracle that
holds the edge (``oracle.solve_levels_holding_edge``: the same problem with the PMV kept inside the band from the
time the free optimum came to the edge), replays both on the plant, and scores the strategy's runs stored in
RESULTS.json (a ``ceco benchmark`` output of the same simulator code: its families' runs and the strategy's; a note on
stderr when its code fingerprint is not this checkout's) with
the benchmark's own matching (``front.headroom_seeds`` against the strongest family's envelope) against each
two-level bound. The two-level free bound is printed beside the benchmark's four-level one as a check of the reading
between levels. ``--with-margin``: also the oracle that holds the edge with its band-phase mean PMV at most the
strategy's (``OracleSettings.band_mean_pmv``: the margin the strategy keeps under the edge on average, kept by the
bound too; what is left between the strategy and that bound is not the margin). ``--terminal``: also the free bound
and (with ``--with-margin``) the margin bound with the cabin's heat stores (air, interior, shell, glazing) ending no
warmer than the strategy leaves them (``OracleSettings.terminal_max``, the strategy's seed mean + 0.02 K): the
whole-drive optimum may spend the cold stored in them in its last minute, which pays only because the drive ends
there (docs/oracle.md "The drive's end"). ``--pointwise`` (with ``--with-margin``): also the margin bound with the
strategy's band-phase mean PMV as a cap on every plant step from the time the strategy first came down to it, its
latest seed (``OracleSettings.band_cap_pmv``): the margin held at every step, as a back-off holds it, not only on
average. ``--co2-margin-ppm``: every bound keeps this margin under the case's CO2 limit instead of the oracle's 10 ppm
(``OracleSettings.co2_margin_ppm``; 150 is the margin of the CO2-holding door of ``ceco-pmv-aq`` and the ``*-doorco2``
families, ``Co2DoorSettings.margin_ppm``: the CO2 sensor's accuracy, which the whole-drive optimum, knowing the true
CO2, does not need).

What it prints is a study, not a benchmark result: results.json is not changed. Last line per case: one JSON
object.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys

from benchmark_summary import fmt  # tools/: "n/a" for a missing number
from variant_headroom import load_results  # tools/


def _bound(pairs, which: int, fx: str, ex: str):
    """The front of the free (``which`` 0) or held (1) oracle points of ``pairs``, or None without two points."""
    from ceco_bringup.benchmark import front as fr

    ok = [p[which] for p in pairs if p[which] is not None and p[which].success]
    pts = [(f'oracle@{r.level_pmvh:.5f}', r.kpis[fx], r.kpis[ex]) for r in ok]
    return fr.build_front(pts) if len(pts) >= 2 else None


def bracket(levels, ds, margin: float) -> list[float]:
    """The discomfort levels [PMV h] to solve at: of the benchmark's oracle ``levels``, the largest at or below the
    least of the strategy's discomforts ``ds`` and the smallest at or above their greatest (the benchmark's own
    vertices, so the free two-level bound reads as its four-level one there); without such levels, the range of
    ``ds`` widened by ``margin``."""
    lo = [x for x in levels if x <= min(ds)]
    hi = [x for x in levels if x >= max(ds)]
    if lo and hi:
        return [max(lo), min(hi)]
    return [min(ds) * (1.0 - margin), max(ds) * (1.0 + margin)]


def _point(r) -> dict | None:
    """A level's replay: energy, discomfort, band-phase PMV mean and seconds above the edge, the solver's account."""
    if r is None or not r.success:
        return None if r is None else {'status': r.status}
    k = r.kpis
    keys = ('energy_kwh', 'discomfort_pmvh', 'pmv_mean_band', 'pmv_above_band_s', 'energy_band_kwh')
    return {
        'status': r.status,
        'iterations': r.iterations,
        'wall_time_s': r.wall_time_s,
        **{x: k.get(x) for x in keys},
        't_evap_sp_mean_band_c': k.get('t_evap_sp_mean_band_c'),
        'mdot_bl_mean_band_kgps': k.get('mdot_bl_mean_band_kgps'),
    }


TERMINAL_STATES = ('t_cab_c', 't_int_c', 't_shell_c', 't_glass_c')
"""The cabin's heat stores whose end temperatures ``--terminal`` bounds: its air, interior, shell and glazing (not
the evaporator wall, part of the A/C)."""

TERMINAL_TOL_K = 0.02
"""Added to the strategy's end temperatures [K]: the NLP's smooth plant ends within about 0.01 K of the replay's."""


def oracle_settings(case, co2_margin_ppm: float | None = None):
    """The bounds' ``OracleSettings`` for ``case``: its control period and door logic, as the benchmark's oracle,
    and with ``co2_margin_ppm`` [ppm] (None: the oracle's own 10) the margin under the CO2 limit. Validated."""
    from ceco_controller import oracle as orc

    settings = orc.OracleSettings(control_period_s=case.control_period_s, door_logic=tuple(case.baseline_door))
    if co2_margin_ppm is not None:
        settings = dataclasses.replace(settings, co2_margin_ppm=co2_margin_ppm)
    return settings.validate()


def strategy_runs(case, strategy: str) -> list:
    """The strategy's runs on the case's seeds (``RunResult``): each seed's benchmark cell
    (``variant_headroom.strategy_cells``) simulated as ``ceco benchmark`` runs it (``settings_from_spec``)."""
    from variant_headroom import strategy_cells  # tools/

    from ceco_bringup.sweep import cells as sweep_cells
    from ceco_controller.closed_loop import simulate
    from ceco_v2x_preview.scenario import scenario_from_dict

    runs = [
        simulate(scenario_from_dict(c.spec['scenario']), c.spec['strategy'], sweep_cells.settings_from_spec(c.spec))
        for c in strategy_cells(case, strategy)
    ]
    if not runs:
        raise SystemExit(f'edge_headroom: {case.name}: no cell of {strategy!r}')
    return runs


def end_state(runs) -> dict:
    """The runs' last recorded temperatures of :data:`TERMINAL_STATES` [degC], their mean."""
    return {n: sum(float(r.timeseries[n][-1]) for r in runs) / len(runs) for n in TERMINAL_STATES}


def first_at_or_below_s(runs, cap: float, t_from: float) -> float | None:
    """The latest over the runs of the first time [s] from ``t_from`` on at which the scored PMV is at or below
    ``cap`` (None if a run never comes there)."""
    times = []
    for r in runs:
        t, pmv = r.timeseries['t_s'], r.timeseries['pmv']
        hit = [float(x) for x, y in zip(t, pmv) if x >= t_from and y <= cap]
        if not hit:
            return None
        times.append(hit[0])
    return max(times)


def study(
    results: dict,
    case_name: str,
    strategy: str,
    margin: float,
    progress=None,
    with_margin: bool = False,
    terminal: bool = False,
    pointwise: bool = False,
    co2_margin_ppm: float | None = None,
) -> dict:
    """The strategy's headroom_captured on one case against the free and the edge-holding oracle (and, with
    ``terminal``, those that leave the cabin's heat stores no warmer than the strategy leaves them)."""
    from ceco_bringup.benchmark import front as fr
    from ceco_bringup.benchmark import runner
    from ceco_bringup.benchmark.cases import load_case
    from ceco_controller import oracle as orc

    case = load_case(case_name)  # a bundled name or a case YAML path (then its name)
    entry = next((c for c in results['cases'] if c['case'] == case.name), None)
    if entry is None:
        raise SystemExit(f'edge_headroom: {case_name!r} is not in the results')
    fx, ex = runner.FRONT_AXIS, runner.ENERGY_AXIS
    rows = [r for r in entry['runs'] if r['controller'] == strategy and r.get('kpis')]
    if not rows:
        raise SystemExit(f'edge_headroom: {case_name}: no scored run of {strategy!r} in the results')
    baselines = [r for r in entry['runs'] if r['kind'].startswith('baseline')]
    env = runner.envelope_of(runner.fronts_of(baselines, fx, ex))
    pts = [(r['seed'], r['kpis'][fx], r['kpis'][ex]) for r in rows]
    levels = bracket(entry['oracle'].get('levels') or [], [d for _, d, _ in pts], margin)
    settings = oracle_settings(case, co2_margin_ppm)
    pairs = orc.solve_levels_holding_edge(case.load_scenario(), levels, settings, progress)
    out = {'case': case_name, 'strategy': strategy, 'levels': levels, 'n_seeds': len(rows)}
    out['co2_margin_ppm'] = settings.co2_margin_ppm
    out['edge_s'] = [orc.edge_arrival_s(f) if f.success else None for f, _ in pairs]
    k = [r['kpis'] for r in rows]
    out['strategy_band'] = {
        'pmv_mean_band': sum(x['pmv_mean_band'] for x in k) / len(k),
        'pmv_above_band_s': sum(x['pmv_above_band_s'] or 0.0 for x in k) / len(k),
    }

    def scored(pairs_, which):
        """The strategy's seeds against the bound of ``pairs_``' points ``which`` (0 the first of each pair)."""
        b = _bound(pairs_, which, fx, ex)
        h = fr.headroom_seeds(env, {None: b}, pts) if b is not None else {}
        return {
            'headroom_captured': h.get('headroom_captured'),
            'headroom_captured_seeds': (h.get('seeds') or {}).get('headroom_captured'),
            'bound_saving_pct': h.get('bound_saving_pct'),
            'saving_pct': h.get('saving_pct'),
            'note': h.get('note', '') if b is not None else 'fewer than two points',
            'points': [_point(p[which]) for p in pairs_],
        }

    for name, which in (('free', 0), ('held', 1)):
        out[name] = scored(pairs, which)

    terminal_max: tuple = ()
    runs = strategy_runs(case, strategy) if terminal or pointwise else []
    if terminal:
        end = end_state(runs)
        out['strategy_end'] = end
        terminal_max = tuple((n, v + TERMINAL_TOL_K) for n, v in end.items())
        st = dataclasses.replace(settings, terminal_max=terminal_max)
        ends = []
        for f, _ in pairs:  # the free oracle's level, its end state bounded, from its commands
            if not f.success:
                ends.append((f, None))
                continue
            (r,) = orc.solve_levels(case.load_scenario(), [f.level_pmvh], st, progress, start_commands=f.commands)
            if not r.success:  # not solved from the free optimum: once more from the production law's run
                (r,) = orc.solve_levels(case.load_scenario(), [f.level_pmvh], st, progress)
            ends.append((f, r))
        out['terminal'] = scored(ends, 1)
        out['oracle_end'] = [
            {n: float(f.run.timeseries[n][-1]) for n in TERMINAL_STATES} if f.success and f.run else None
            for f, _ in pairs
        ]
    if with_margin:
        # the oracle that keeps the strategy's margin: held as above, and its band-phase mean PMV at most the
        # strategy's (seed mean; the band phase from the free replay's band_start_s, the scenario's)
        cap = round(out['strategy_band']['pmv_mean_band'], 3)
        kept, kept_end = [], []
        for (f, h), t_edge in zip(pairs, out['edge_s']):
            if h is None or t_edge is None or not h.success:
                kept.append((f, None))
                kept_end.append((f, None))
                continue
            band = (float(f.kpis['band_start_s']), cap)
            st = dataclasses.replace(settings, hold_edge_from_s=t_edge, band_mean_pmv=band)
            (r,) = orc.solve_levels(case.load_scenario(), [f.level_pmvh], st, progress, start_commands=h.commands)
            kept.append((f, r))
            if terminal:  # and also leaving the heat stores as cool as the strategy does
                st = dataclasses.replace(st, terminal_max=terminal_max)
                start = r.commands if r.success else h.commands
                (r2,) = orc.solve_levels(case.load_scenario(), [f.level_pmvh], st, progress, start_commands=start)
                kept_end.append((f, r2))
        out['margin'] = {'band_mean_pmv': cap, **scored(kept, 1)}
        if terminal:
            out['margin_terminal'] = {'band_mean_pmv': cap, **scored(kept_end, 1)}
        band_start = next((float(f.kpis['band_start_s']) for f, _ in pairs if f.success), None)
        t_cap = first_at_or_below_s(runs, cap, band_start) if pointwise and band_start is not None else None
        if pointwise and t_cap is not None:
            # the margin at every step from the time the strategy first came to it (the latest seed), not on average
            pw = []
            for (f, _), t_edge, (_, r) in zip(pairs, out['edge_s'], kept_end if terminal else kept):
                if r is None or not r.success:
                    pw.append((f, None))
                    continue
                st = dataclasses.replace(
                    settings,
                    hold_edge_from_s=t_edge,
                    band_mean_pmv=(float(f.kpis['band_start_s']), cap),
                    band_cap_pmv=(t_cap, cap),
                    terminal_max=terminal_max,
                )
                (r2,) = orc.solve_levels(case.load_scenario(), [f.level_pmvh], st, progress, start_commands=r.commands)
                pw.append((f, r2))
            out['pointwise'] = {'band_cap_pmv': [t_cap, cap], 'terminal': terminal, **scored(pw, 1)}
    bench = (entry.get('matched', {}).get(strategy) or {}).get('headroom') or {}
    out['benchmark'] = {k: bench.get(k) for k in ('headroom_captured', 'bound_saving_pct', 'saving_pct')}
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('results', help='a ceco benchmark results.json with the cases (its families and the strategy)')
    p.add_argument('cases', nargs='+', help='case names in the results')
    p.add_argument('--strategy', default='ceco-pmv', help='the strategy to score (default ceco-pmv)')
    p.add_argument(
        '--margin',
        type=float,
        default=0.01,
        help='without the benchmark oracle levels: the seeds discomfort range widened by this',
    )
    p.add_argument(
        '--with-margin',
        action='store_true',
        help='also the oracle that holds the edge with a band-phase mean PMV at most the strategy\'s (its margin)',
    )
    p.add_argument(
        '--pointwise',
        action='store_true',
        help='with --with-margin: also the margin bound with the strategy\'s band-phase mean PMV as a cap at every '
        'step from the time the strategy first came to it (with --terminal: also ending as cool)',
    )
    p.add_argument(
        '--terminal',
        action='store_true',
        help='also the bounds whose cabin heat stores end no warmer than the strategy\'s (seed mean + 0.02 K)',
    )
    p.add_argument(
        '--co2-margin-ppm',
        type=float,
        default=None,
        help='every bound keeps this margin under the CO2 limit [ppm] (default: the oracle\'s 10; 150: the '
        'CO2-holding door\'s)',
    )
    args = p.parse_args(argv)
    if args.co2_margin_ppm is not None:  # the oracle's own check, before any results file is read
        from ceco_controller.oracle import OracleSettings

        try:
            OracleSettings(co2_margin_ppm=args.co2_margin_ppm).validate()
        except ValueError as err:
            p.error(f'--co2-margin-ppm: {err}')
    if not (0.0 <= args.margin < 0.5):
        p.error(f'--margin: must be in [0, 0.5), got {args.margin}')
    if args.pointwise and not args.with_margin:
        p.error('--pointwise: needs --with-margin (it tightens the margin bound)')
    results = load_results(args.results)
    for name in args.cases:
        say = lambda line: print(line, file=sys.stderr, flush=True)  # noqa: E731
        r = study(
            results,
            name,
            args.strategy,
            args.margin,
            say,
            args.with_margin,
            args.terminal,
            args.pointwise,
            args.co2_margin_ppm,
        )
        fr_, he = r['free'], r['held']

        def band(pts):
            return '; '.join(
                'n/a'
                if x is None or 'energy_kwh' not in x
                else f'PMV {fmt(x["pmv_mean_band"], "+.3f")} above {fmt(x["pmv_above_band_s"], ".0f")} s '
                f'{fmt(x["energy_kwh"], ".4f")} kWh'
                for x in pts
            )

        print(
            f'{name}: {args.strategy} saves {fmt(fr_["saving_pct"], "+.2f")} % vs the strongest family; '
            f'oracle {fmt(fr_["bound_saving_pct"], "+.2f")} % (captured {fmt(fr_["headroom_captured"], ".2f")}, the '
            f'benchmark\'s 4 levels {fmt(r["benchmark"]["headroom_captured"], ".2f")}), holding the edge '
            f'{fmt(he["bound_saving_pct"], "+.2f")} % (captured {fmt(he["headroom_captured"], ".2f")})'
            + ('' if args.co2_margin_ppm is None else f'; every bound {r["co2_margin_ppm"]:g} ppm under the CO2 limit')
        )
        print(f'  free: {band(fr_["points"])}\n  held: {band(he["points"])}')
        if 'margin' in r:
            mg = r['margin']
            print(
                f'  held at the strategy\'s band-phase mean PMV {mg["band_mean_pmv"]:+.3f}: '
                f'{fmt(mg["bound_saving_pct"], "+.2f")} % (captured {fmt(mg["headroom_captured"], ".2f")}); '
                f'{band(mg["points"])}'
            )
        cool = ', ending no warmer than the strategy'
        for key, what in (
            ('terminal', 'free' + cool),
            ('margin_terminal', 'held at the strategy\'s margin' + cool),
            ('pointwise', 'held at the strategy\'s margin at every step' + (cool if args.terminal else '')),
        ):
            if key in r:
                t = r[key]
                print(
                    f'  {what}: {fmt(t["bound_saving_pct"], "+.2f")} % '
                    f'(captured {fmt(t["headroom_captured"], ".2f")}); {band(t["points"])}'
                )
        print(json.dumps(r))
    return 0


if __name__ == '__main__':
    sys.exit(main())
