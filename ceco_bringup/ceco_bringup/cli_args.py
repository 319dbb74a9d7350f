"""The ``ceco`` verbs' argument parser: the shared flags (``ceco_core.cli_flags``) and the benchmark cases' ``--case``.

The shared flags, their types, their deprecated names and the one-line errors are declared once in
:mod:`ceco_core.cli_flags` (also used by ``ceco identify`` and ``ceco bench``) and re-exported here;
``--case`` needs the benchmark's cases (:mod:`ceco_bringup.benchmark.cases`), so it lives here.

Pure Python (argparse); no ROS import.
"""

from __future__ import annotations

from ceco_core import cli_flags as _flags
from ceco_core.cli_flags import *  # noqa: F403 (the shared flags, re-exported: __all__ below)

__all__ = [
    *_flags.__all__,
    'add_case',
    'CASE_SCENARIO_FILE',
    'apply_case',
    'case_overrides',
    'warn_no_preview',
    'check_control_period',
]


def add_case(p) -> None:
    """``--case``: a benchmark case run as ``ceco benchmark`` runs it (with :func:`apply_case`)."""
    p.add_argument(
        '--case',
        default=None,
        help='a benchmark case (bundled name, e.g. hotsoak-pulldown, or case YAML path): its scenario, forecast '
        "uncertainty, seed (--seed, default its first), Ts, Np and baselines' door, as `ceco benchmark` runs it",
    )


CASE_SCENARIO_FILE = 'case_scenario.yaml'
"""Where ``--case`` writes the case's scenario (its overrides applied) in the output directory."""


def apply_case(args, out):
    """Resolve ``--case`` into ``args``; return the :class:`~ceco_bringup.benchmark.cases.Case` (None without it).

    The case's scenario (its overrides applied) is written to ``out/case_scenario.yaml`` and becomes
    ``args.scenario``; the case's preview quality, first seed, Ts and Np fill the flags not given (the
    seed only where neither ``--seed`` nor a ``seed=`` in ``--preview`` gives one). Without ``--case``:
    ``args.scenario`` defaults to sc03 and ``args.preview`` to perfect. ValueError for ``--case`` beside
    ``--scenario`` or a bad case or preview.
    """
    from pathlib import Path

    from ceco_bringup.benchmark.cases import load_case
    from ceco_v2x_preview.preview import parse_quality

    case = None
    if args.case is not None:
        if args.scenario is not None:
            raise ValueError('--case and --scenario: give one (the case names its scenario)')
        case = load_case(args.case)
        args.scenario = str(case.write_scenario(Path(out) / CASE_SCENARIO_FILE))
        if args.seed is None and (args.preview is None or parse_quality(args.preview).seed is None):
            args.seed = case.seeds[0]
        args.preview = args.preview or case.preview
        args.control_period_s = args.control_period_s or case.control_period_s
        args.horizon_steps = args.horizon_steps or case.horizon_steps
    args.scenario = args.scenario or 'sc03'
    args.preview = args.preview or 'perfect'
    return case


def case_overrides(case, strategy: str) -> tuple:
    """``((field, value), ...)`` a run of ``strategy`` takes from ``case`` (none without ``--case``).

    :meth:`~ceco_bringup.benchmark.cases.Case.strategy_overrides`: the case's door for a baseline.
    """
    return tuple(case.strategy_overrides(strategy).items()) if case is not None else ()


def warn_no_preview(prog: str, args, scenario, quality) -> None:
    """One line on stderr (``PROG: warning: ...``) when an NMPC strategy runs without any usable preview.

    :func:`ceco_v2x_preview.preview.no_preview_warning`: ``delayed:40`` at Np = 6, or previews dropped over the
    whole run, make a "ceco" run one without any preview.
    """
    import sys

    from ceco_core.contracts import NODE_STRATEGIES
    from ceco_v2x_preview.preview import no_preview_warning

    if set(args.strategy) & set(NODE_STRATEGIES):
        ts, n_p = scenario.control.timing(args.control_period_s, args.horizon_steps)
        warning = no_preview_warning(quality, args.duration_s or scenario.duration_s, ts, n_p)
        if warning:
            print(f'{prog}: warning: {warning}', file=sys.stderr)


def check_control_period(args, scenario, model_params_path=None) -> None:
    """ValueError, before any run, when a strategy of ``args.strategy`` cannot run at the job's Ts.

    Ts (``--control-period-s``, else the scenario's) must be a whole number of plant steps
    (:data:`~ceco_core.contracts.PLANT_STEP_S`: the simulator and plant_node step the plant that way) and, for an
    NMPC strategy, of its control model's step (``ts_s`` of ``model_params_path``, the package's model when None).
    Without this the job stopped at the first strategy that could not, after running the ones before it.
    """
    from ceco_core.contracts import NODE_STRATEGIES, PLANT_STEP_S
    from ceco_plant_sim.scenario_plant import steps_per_control

    ts = scenario.control.timing(args.control_period_s)[0]
    if not args.control_period_s:
        name = f'scenario {scenario.name}: control.control_period_s'
    elif getattr(args, 'case', None) is not None:
        name = f'Ts {ts:g} s (--control-period-s, else the case\'s control_period_s)'
    else:
        name = '--control-period-s'
    try:
        steps_per_control(ts, PLANT_STEP_S)
    except ValueError as exc:
        raise ValueError(f'{name}: {exc}') from None
    nmpc = [s for s in args.strategy if s in NODE_STRATEGIES]
    if nmpc:
        from ceco_controller.model import load_params, substeps

        params = load_params(model_params_path)  # a bad file says so itself, not as a control-period error
        try:
            substeps(params, ts)
        except ValueError as exc:
            raise ValueError(f'{name}: {exc} (the NMPC strategies: {", ".join(nmpc)})') from None
