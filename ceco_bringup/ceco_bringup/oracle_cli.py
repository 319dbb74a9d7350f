"""``ceco oracle``: the whole-drive optimum of a benchmark case at several discomfort levels.

    ceco oracle sc03-paper --out runs/oracle-sc03
    ceco oracle udds-hot --levels 0.103,0.11,0.125,0.15 --out runs/oracle-udds
    ceco oracle sc03-paper --levels 0.1024,0.1040 --hold-edge --out runs/oracle-sc03-held

The optimal control problem with perfect knowledge of the drive (``ceco_controller.oracle``, docs/oracle.md)
is solved at each level [PMV h] and replayed open loop on the plant; every level gets a run directory
(``level-<i>``: timeseries.csv, diagnostics.csv, metrics.json, commands.csv, run.json) that
``ceco report`` reads, and the job writes ``front.csv`` / ``front.json`` (the replayed KPIs, the NLP's own
values, status, iterations, wall time). Without ``--levels`` the levels follow the benchmark's rule
(``runner.oracle_levels``) on the production law's set-point family run here. With ``--hold-edge`` every level is
solved a second time holding the band's upper edge from the time its optimum came to it
(``oracle.solve_levels_holding_edge``; run directories ``level-<i>-held``, rows with ``bound`` ``held``).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ceco_bringup import cli_args, provenance

__all__ = ['build_parser', 'default_levels', 'main']

FRONT_COLUMNS = (
    'level_pmvh',
    'bound',
    'hold_edge_from_s',
    'status',
    'success',
    'certified',
    'iterations',
    'wall_time_s',
    'energy_kwh',
    'discomfort_pmvh',
    'nlp_energy_kwh',
    'nlp_discomfort_pmvh',
    'run_dir',
)
"""Columns of ``front.csv`` (energy and discomfort: the replay's KPIs; nlp_*: the NLP's own values; ``bound``:
``free`` (the oracle) or ``held`` (the oracle that holds the edge from ``hold_edge_from_s`` [s], ``--hold-edge``))."""


def _levels(text: str) -> list[float]:
    """Comma-separated discomfort levels [PMV h], each finite and > 0 (argparse type)."""
    return cli_args.comma_list(cli_args.positive_float)(text)


def build_parser() -> cli_args.Parser:
    """The ``ceco oracle`` parser (``ceco oracle --help``)."""
    p = cli_args.Parser('ceco oracle', __doc__.split('\n\n')[0] + '\n\n' + __doc__.split('\n\n')[1])
    p.add_argument('case', help='benchmark case: a bundled name (ceco benchmark --help lists them) or a case file')
    cli_args.add_out(p, 'output directory: one run directory per level, front.csv and front.json')
    p.add_argument(
        '--levels',
        type=_levels,
        default=None,
        help='discomfort levels [PMV h], comma-separated (default: the benchmark\'s rule on the production '
        'law\'s set-point family)',
    )
    cli_args.add_control_period(p)
    cli_args.add_duration(p)
    p.add_argument(
        '--max-wall-time-s',
        type=cli_args.positive_float,
        default=None,
        help='IPOPT wall-time limit per level [s] (default: 1.5 s per second of drive, at least 900 s)',
    )
    p.add_argument(
        '--compiled',
        choices=('auto', 'yes', 'no'),
        default='auto',
        help='plant steps of the NLP as compiled C, cached on disk (auto: where a C compiler works, else CasADi\'s '
        'virtual machine; docs/oracle.md "Compiled plant steps")',
    )
    p.add_argument(
        '--hold-edge',
        action='store_true',
        help='also solve every level holding the PMV inside the band from the time its optimum came to the band\'s '
        'upper edge (the bound of a controller that never goes back above +0.5; docs/oracle.md)',
    )
    cli_args.add_no_progress(p)
    return p


def default_levels(case, scenario, control_period_s: float | None, n: int = 4) -> list[float]:
    """``n`` levels by the benchmark's rule (``runner.oracle_levels``) on the production law's set-point family.

    The family (``verdict.FAMILY_SETPOINTS_C``, with the case's door logic where its baselines drive the
    door) is run here in-process and scored like benchmark runs. ``oracle.OracleStopped`` when the plant cannot
    simulate a member's run.
    """
    from ceco_bringup.benchmark import runner
    from ceco_bringup.verdict import FAMILY_SETPOINTS_C
    from ceco_controller.closed_loop import SimSettings, simulate
    from ceco_controller.oracle import OracleStopped
    from ceco_core.kpis import compute_kpis
    from ceco_plant_sim.plant_ops import PlantStepError

    runs = []
    for sp in FAMILY_SETPOINTS_C:
        ovr = (('setpoint_c', sp), *case.baseline_door)
        st = SimSettings(control_period_s=control_period_s, progress=False, strategy_overrides=ovr)
        try:
            res = simulate(scenario, 'baseline', st)
        except PlantStepError as exc:
            where = f'the production law\'s run at {sp:g} degC (choosing the levels)'
            raise OracleStopped(f'{where}: {exc.run_error}') from None
        kpis, _ = compute_kpis(res.timeseries, control_period_s=res.metrics['control_period_s'], fallback_steps=0)
        row = {'controller': f'baseline@{sp:g}', 'kind': 'baseline', 'seed': None, 'setpoint_c': sp}
        runs.append(runner._run_entry({**row, 'status': 'ok', 'kpis': kpis}))
    return runner.oracle_levels(runs, n)


def main(argv=None) -> int:
    """``ceco oracle``: 0 when every level was solved and replayed, 1 when some were not, 2 for a user error.

    1 also, with one line, when the plant cannot simulate the production law's run the levels or the start come from.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    cli_args.check_out(parser, args.out)
    from ceco_bringup.benchmark.cases import CaseError, load_case
    from ceco_controller import oracle as orc
    from ceco_controller.closed_loop import write_run
    from ceco_core import rundir
    from ceco_core.codegen import CompileError

    say = (lambda line: None) if args.no_progress else (lambda line: print(line, file=sys.stderr, flush=True))
    try:
        case = load_case(args.case)
        scenario = case.load_scenario()
        if args.duration_s is not None:
            cli_args.check_duration(args.duration_s, scenario, args.control_period_s)
            d = case.scenario_dict()
            d['duration_s'] = float(args.duration_s)
            from ceco_v2x_preview.scenario import scenario_from_dict

            scenario = scenario_from_dict(d, source=scenario.source)
        ts = args.control_period_s or case.control_period_s
        settings = orc.OracleSettings(
            control_period_s=ts,
            max_wall_time_s=args.max_wall_time_s,
            door_logic=tuple(case.baseline_door),
            compiled=args.compiled,
        ).validate()
        levels = args.levels
        if levels is None:
            say(f'ceco oracle: levels from the production law\'s set-point family on {case.name} ...')
            levels = default_levels(case, scenario, ts)
            if not levels:
                raise ValueError('no baseline front on this case to choose levels from; give --levels')
        say(f'ceco oracle: {case.name}, levels {", ".join(f"{x:.4f}" for x in levels)} PMV h')
    except (CaseError, ValueError, OSError) as exc:
        parser.error(str(exc))
    except orc.OracleStopped as exc:  # the plant cannot simulate the case: no levels
        print(f'ceco oracle: {case.name}: {exc}', file=sys.stderr)
        return 1
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    try:
        # (run directory, bound, LevelResult, the time the edge is held from [s] or None)
        results: list[tuple] = []
        missing: list[str] = []  # --hold-edge: the levels without a held point
        if args.hold_edge:
            pairs = orc.solve_levels_holding_edge(scenario, levels, settings, progress=say)
            results = [(f'level-{i}', 'free', r, None) for i, (r, _) in enumerate(pairs)]
            for i, (r, h) in enumerate(pairs):
                if h is None:
                    missing.append(f'{r.level_pmvh:.4f}')
                else:
                    results.append((f'level-{i}-held', 'held', h, orc.edge_arrival_s(r)))
        else:
            free = orc.solve_levels(scenario, levels, settings, progress=say)
            results = [(f'level-{i}', 'free', r, None) for i, r in enumerate(free)]
    except KeyboardInterrupt:
        print('ceco oracle: interrupted', file=sys.stderr)
        return 130
    except CompileError as exc:  # --compiled yes where no compiled plant step can be built
        print(f'ceco oracle: {exc}', file=sys.stderr)
        return 2
    except orc.OracleStopped as exc:  # the plant cannot simulate the oracle's start
        print(f'ceco oracle: {case.name}: {exc}', file=sys.stderr)
        return 1
    rows = []
    for name, bound, r, hold_s in results:
        run_dir = out / name
        row = {
            'level_pmvh': r.level_pmvh,
            'bound': bound,
            'hold_edge_from_s': hold_s,
            'status': r.status,
            'success': r.success,
            'certified': r.certified,
            'iterations': r.iterations,
            'wall_time_s': r.wall_time_s,
            'form': r.form,
            'energy_kwh': None,
            'discomfort_pmvh': None,
            'nlp_energy_kwh': r.nlp_energy_kwh,
            'nlp_discomfort_pmvh': r.nlp_discomfort_pmvh,
            'run_dir': run_dir.name if r.run is not None else '',
        }
        if r.run is not None:
            provenance.start_run(run_dir, 'oracle', argv, case.scenario_path())
            r.run.metrics.update(
                {
                    'oracle_level_pmvh': r.level_pmvh,
                    'oracle_status': r.status,
                    'oracle_certified': r.certified,
                    'oracle_iterations': r.iterations,
                    'oracle_wall_time_s': r.wall_time_s,
                    'oracle_nlp_energy_kwh': r.nlp_energy_kwh,
                    'oracle_nlp_discomfort_pmvh': r.nlp_discomfort_pmvh,
                    'oracle_evaluation': r.evaluation,
                    'oracle_form': r.form,
                    'oracle_bound': bound,
                    'oracle_hold_edge_from_s': row['hold_edge_from_s'],
                    'case': case.name,
                }
            )
            write_run(r.run, run_dir)
            cols = {'k': list(range(len(r.commands)))}
            for j, name in enumerate(r.input_names):
                cols[name] = r.commands[:, j].tolist()
            rundir.write_csv(run_dir / 'commands.csv', ('k', *r.input_names), cols)
            provenance.finish_run(run_dir, 'complete')
            row['energy_kwh'], row['discomfort_pmvh'] = r.kpis['energy_kwh'], r.kpis['discomfort_pmvh']
        rows.append(row)
    rundir.write_csv(
        out / 'front.csv', FRONT_COLUMNS, {c: [('' if x[c] is None else x[c]) for x in rows] for c in FRONT_COLUMNS}
    )
    doc = {
        'case': case.name,
        'control_period_s': scenario.control.timing(settings.control_period_s)[0],
        'note': 'a local optimum of an NLP replayed on the plant: an achievable point, not a proven global bound',
        'evaluation': results[0][2].evaluation if results else '',
        'levels': rows,
    }
    (out / 'front.json').write_text(json.dumps(doc, indent=2) + '\n', encoding='utf-8')
    failed = [f'{x["level_pmvh"]:.4f} ({x["bound"]}, {x["status"]})' for x in rows if not x['success']]
    for x in rows:
        if x['success']:
            held = '' if x['bound'] == 'free' else f' holding the edge from {x["hold_edge_from_s"]:.0f} s'
            print(
                f'oracle {case.name} @ {x["level_pmvh"]:.4f} PMV h{held}: E {x["energy_kwh"]:.4f} kWh, '
                f'D {x["discomfort_pmvh"]:.4f} PMV h -> {out / x["run_dir"]}'
            )
    if missing:
        print(f'ceco oracle: no edge to hold at {", ".join(missing)} (not solved, or never at it)', file=sys.stderr)
    if failed:
        print(f'ceco oracle: not solved: {", ".join(failed)}', file=sys.stderr)
    return 1 if failed or missing else 0


if __name__ == '__main__':
    sys.exit(main())
