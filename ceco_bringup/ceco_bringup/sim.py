"""``ceco sim``: the closed loop in-process (no ROS), one run directory per strategy, then the verdict.

    ceco sim --scenario sc03 --strategy all --out runs/sim
    ceco sim --scenario my.yaml --strategy baseline,ceco-c --duration-s 300 --out runs/mine
    ceco sim --case hotsoak-pulldown --seed 2 --strategy ceco-pmv --out runs/hs2

The verb parses the shared flags (``ceco_bringup.cli_args``) and calls the pure API,
``ceco_controller.closed_loop.simulate`` and ``write_run``; each run directory also keeps the
scenario file, the command line and the code fingerprint (``ceco_bringup.provenance``). After the
runs it prints the comparison table and the verdict, with the saving at matched comfort against
the production law at several set-points (``ceco_bringup.outputs``).

``--case`` runs a benchmark case's cell as ``ceco benchmark`` runs it (``ceco_bringup.benchmark``):
the case's scenario with its overrides (run length, occupants; written to ``OUT/case_scenario.yaml``
and kept in each run directory), its forecast uncertainty as the preview quality, one of its seeds
(``--seed``, default its first), its Ts and Np, and its baselines' door logic (the baseline run and
the family of the verdict). Flags given explicitly override the case's.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ceco_bringup import cli_args, outputs, provenance
from ceco_core.contracts import NODE_STRATEGIES
from ceco_core.run_status import STATUS_OK

__all__ = ['build_parser', 'main']


def build_parser() -> cli_args.Parser:
    """The ``ceco sim`` parser (``ceco sim --help``)."""
    from ceco_core.contracts import MEASUREMENT_MODES

    p = cli_args.Parser('ceco sim', __doc__.split('\n\n')[0] + '\n\n' + __doc__.split('\n\n')[1])
    cli_args.add_scenario(p, default=None, help_extra=' (default: sc03; not with --case)')
    cli_args.add_case(p)
    cli_args.add_strategy(p, 'all')
    cli_args.add_out(p, 'output directory: one run directory per strategy, and the job\'s tables')
    cli_args.add_preview(p, default=None, help_extra=" (default: perfect; with --case the case's)")
    cli_args.add_control_period(p)
    cli_args.add_horizon(p)
    cli_args.add_duration(p)
    cli_args.add_seed(p)
    p.add_argument('--model-params', default=None, help='identified model parameter file (default: the bundled one)')
    p.add_argument(
        '--controller-config', default=None, help='controller settings file (default: the bundled controller.yaml)'
    )
    p.add_argument(
        '--measurements',
        choices=MEASUREMENT_MODES,
        default='full',
        help='full: the controller reads every modelled state; vehicle: production sensors only, '
        'interior/shell temperatures estimated',
    )
    p.add_argument(
        '--set',
        action='append',
        default=[],
        metavar='FIELD=VALUE',
        help='override a strategy setting (StrategySettings field), e.g. pmv_pa_source=measured; repeatable; '
        'applies to the NMPC strategies (the baseline has no StrategySettings)',
    )
    cli_args.add_baseline_setpoints(p, outputs.vd.FAMILY_SETPOINTS_C)
    cli_args.add_no_progress(p)
    return p


SET_BY_FLAGS = {'name': '--strategy', 'horizon_steps': '--horizon-steps', 'control_period_s': '--control-period-s'}
"""StrategySettings fields ``--set`` may not set: the flag that sets them."""


def _overrides(items) -> tuple:
    out = []
    for item in items:
        key, sep, value = item.partition('=')
        if not sep or not key:
            raise ValueError(f'--set: expected FIELD=VALUE, got {item!r}')
        if key in SET_BY_FLAGS:
            raise ValueError(f'--set {key}: set by {SET_BY_FLAGS[key]}, not by --set')
        try:
            out.append((key, float(value)))
        except ValueError:
            out.append((key, value))
    return tuple(out)


def _check_set_fields(overrides) -> None:
    """ValueError naming a ``--set`` field StrategySettings does not have (before any run; not blamed on a file)."""
    import dataclasses

    from ceco_controller.strategies import StrategySettings

    known = {f.name for f in dataclasses.fields(StrategySettings)}
    for key, _ in overrides:
        if key not in known:
            raise ValueError(f'--set {key}: not a StrategySettings field (its fields: ceco_controller/strategies.py)')


def with_case(settings, case, strategy: str):
    """``settings`` for a run of ``strategy``: the case's own settings, then the ``--set`` overrides.

    The case's: ``cli_args.case_overrides`` (a baseline's door; none without ``--case``). ``--set`` sets
    StrategySettings fields, so it applies to the NMPC strategies only: the baseline has none (``main`` refuses
    ``--set`` when no NMPC strategy runs).
    """
    import dataclasses

    extra = cli_args.case_overrides(case, strategy)
    own = tuple(settings.strategy_overrides) if strategy in NODE_STRATEGIES else ()
    return dataclasses.replace(settings, strategy_overrides=extra + own)


def main(argv=None) -> int:
    """``ceco sim``: the exit status.

    0 when every run finished, 1 when a run failed (its controller did not control it:
    ``ceco_core.run_status``; the others are compared), 2 for a user error (one line, no traceback).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    cli_args.check_out(parser, args.out)
    from ceco_controller.closed_loop import SimSettings, simulate, write_run
    from ceco_plant_sim.scenario_plant import PlantStepError
    from ceco_v2x_preview.preview import parse_quality
    from ceco_v2x_preview.scenario import load_scenario

    out = Path(args.out)
    try:
        case = cli_args.apply_case(args, out)
        scenario = load_scenario(args.scenario)
        quality = parse_quality(args.preview)
        cli_args.check_duration(args.duration_s, scenario, args.control_period_s)
        cli_args.check_control_period(args, scenario, args.model_params)
        settings = SimSettings(
            control_period_s=args.control_period_s,
            horizon_steps=args.horizon_steps,
            preview_quality=quality,
            seed=args.seed,
            duration_s=args.duration_s,
            progress=not args.no_progress,
            model_params_path=args.model_params,
            controller_config_path=args.controller_config,
            strategy_overrides=_overrides(args.set),
            measurements=args.measurements,
        )
        settings.validate()
        cli_args.warn_no_preview('ceco sim', args, scenario, quality)
        if args.set and not set(args.strategy) & set(NODE_STRATEGIES):
            raise ValueError('--set: sets StrategySettings fields of the NMPC strategies; the baseline has none')
        _check_set_fields(settings.strategy_overrides)
    except (ValueError, OSError) as exc:
        parser.error(str(exc))
    metrics, columns, failed = {}, {}, {}
    for s in args.strategy:
        run_dir = out / s
        provenance.start_run(run_dir, 'sim', argv, args.scenario, s)
        try:
            res = simulate(scenario, s, with_case(settings, case, s))
        except (ValueError, OSError) as exc:  # a --set field the strategy lacks, a missing or unfit model file
            provenance.finish_run(run_dir, 'failed', str(exc))
            print(f'ceco sim: error: {s}: {exc}', file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            provenance.finish_run(run_dir, 'interrupted')
            print('ceco sim: interrupted; the finished strategies are kept', file=sys.stderr)
            return 130
        except PlantStepError as exc:  # the plant's refrigerant cycle left its model: the run cannot go on
            res, reason = None, exc.run_error
        else:
            write_run(res, run_dir)  # a failed run too: kept in run_dir, never shown
            reason = res.metrics['status_reason'] if res.metrics['status'] != STATUS_OK else None
        if reason is not None:  # the run stopped, or its controller did not control
            provenance.finish_run(run_dir, 'failed', reason)
            failed[s] = reason
            line = outputs.failed_line(s, reason, run_dir)
        else:
            provenance.finish_run(run_dir, 'complete')
            metrics[s], columns[s] = res.metrics, res.timeseries
            line = outputs.run_line(res.metrics, run_dir)
        (run_dir / 'summary.txt').write_text(line + '\n', encoding='utf-8')
        print(line, flush=True)
    ts, n_p = scenario.control.timing(settings.control_period_s, settings.horizon_steps)
    header = f'scenario {scenario.name}, in-process, Ts {ts:g} s, Np {n_p}, preview {quality.describe()}' + (
        ', measurements vehicle' if settings.measurements == 'vehicle' else ''
    )
    if metrics:
        outputs.finish_job(
            out,
            scenario,
            metrics,
            columns,
            header=header,
            family_setpoints_c=args.baseline_setpoints_c,
            family_overrides=cli_args.case_overrides(case, 'baseline'),
            case=args.case,
            duration_s=settings.duration_s,
            control_period_s=settings.control_period_s,
            failed=failed,
            progress=not args.no_progress,
        )
    outputs.report_failed(out, failed, len(args.strategy))
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
