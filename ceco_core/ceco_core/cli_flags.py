"""The flags the ``ceco`` verbs share, declared once, and the verbs' argument parser.

Every verb builds its parser with :class:`Parser` and adds the shared settings with the
``add_*`` functions here, so the same setting has the same flag name, type check, unit and
help text in ``run``, ``sim``, ``benchmark``, ``sweep``, ``play``, ``report``, ``oracle``,
``identify`` and ``bench`` (docs/architecture.md, "The ceco command"). It lives in ceco_core so
that the verbs of ceco_controller (``identify``, ``bench``) use it too; ``ceco_bringup.cli_args``
adds the benchmark cases' ``--case``:

==========================  ===============================================  ====================
flag                        setting                                          old name (deprecated)
==========================  ===============================================  ====================
``--scenario``              bundled scenario name or YAML path
``--strategy``              ``all`` or a comma-separated list of strategies
``--out``                   output directory (existing or makeable)
``--preview``               preview quality (``perfect``, ``noisy``, ...)     ``--preview-quality``
``--control-period-s``      control period Ts [s], 0.1..300 (the nodes')     ``--control-period``
``--horizon-steps``         prediction horizon Np [steps], 1..60             ``--horizon``
``--duration-s``            run length [s], whole plant steps                ``--duration``
``--seed``                  seed of the preview noise, >= 0
``--workers``               parallel worker processes
``--backend``/``--address`` local process pool or Ray
``--namespace``             ROS namespace of the recorded stack
``--domain-id``             ROS_DOMAIN_ID, 0..232
``--no-progress``           no progress bar
==========================  ===============================================  ====================

A bad value is one line on stderr naming the flag, the value and what is accepted, and exit
status 2 (never a traceback): :meth:`Parser.error`. An old flag name still works for one
release and prints one deprecation line; an old and a new name of one setting together are refused
(``--duration 60 --duration-s 120`` kept the last without a word). ``--help`` shows every default.

Pure Python (argparse); no ROS import.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
from collections.abc import Sequence

__all__ = [
    'Parser',
    'UserError',
    'finite_float',
    'positive_float',
    'nonnegative_float',
    'positive_int',
    'nonnegative_int',
    'strategy_list',
    'comma_list',
    'control_period_s',
    'horizon_steps',
    'domain_id',
    'nonempty',
    'out_dir_error',
    'check_out',
    'add_scenario',
    'add_strategy',
    'add_out',
    'add_preview',
    'add_control_period',
    'add_horizon',
    'add_duration',
    'add_seed',
    'add_workers',
    'add_backend',
    'add_namespace',
    'add_domain_id',
    'add_no_progress',
    'add_baseline_setpoints',
    'setpoint_list',
    'check_duration',
    'DEPRECATED_FLAGS',
]


class UserError(Exception):
    """A mistake of the user's (a bad value, a missing file): one line with the fix, exit status 2."""


class _Formatter(argparse.RawDescriptionHelpFormatter):
    """Keeps the description's layout and appends ``(default: X)`` to every option that has one."""

    def _get_help_string(self, action):
        text = action.help or ''
        default = action.default
        if (
            '(default' in text
            or default is None
            or default is False
            or default is argparse.SUPPRESS
            or not action.option_strings
            or isinstance(action, _Deprecated)
        ):
            return text
        shown = ','.join(map(str, default)) if isinstance(default, (list, tuple)) else default
        return f'{text} (default: {shown})'


class Parser(argparse.ArgumentParser):
    """The parser of a ``ceco`` verb: defaults in ``--help``, errors as one line and exit status 2."""

    def __init__(self, prog: str, description: str = '', **kw):
        super().__init__(prog=prog, description=description, formatter_class=_Formatter, **kw)

    def error(self, message: str):
        """Print ``PROG: error: MESSAGE (PROG --help lists the options)`` and exit with status 2."""
        self.exit(2, f'{self.prog}: error: {message} ({self.prog} --help lists the options)\n')


# ------------------------------------------------------------------------------------- value types
def finite_float(text: str) -> float:
    """A finite number (argparse type); the message says what was given."""
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'must be a number, got {text!r}') from None
    if not math.isfinite(x):
        raise argparse.ArgumentTypeError(f'must be a finite number, got {text!r}')
    return x


def positive_float(text: str) -> float:
    """A finite number > 0 (argparse type)."""
    x = finite_float(text)
    if x <= 0.0:
        raise argparse.ArgumentTypeError(f'must be a finite number > 0, got {text!r}')
    return x


def nonnegative_float(text: str) -> float:
    """A finite number >= 0 (argparse type)."""
    x = finite_float(text)
    if x < 0.0:
        raise argparse.ArgumentTypeError(f'must be a finite number >= 0, got {text!r}')
    return x


def _whole_number(text: str, lo: int, hi: int | None = None) -> int:
    """``int(text)`` within ``lo``..``hi`` (no upper bound for None); ArgumentTypeError saying the range."""
    accepted = f'>= {lo}' if hi is None else f'in {lo}..{hi}'
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'must be a whole number {accepted}, got {text!r}') from None
    if n < lo or (hi is not None and n > hi):
        raise argparse.ArgumentTypeError(f'must be a whole number {accepted}, got {text!r}')
    return n


def positive_int(text: str) -> int:
    """An integer >= 1 (argparse type)."""
    return _whole_number(text, 1)


def nonnegative_int(text: str) -> int:
    """An integer >= 0 (argparse type)."""
    return _whole_number(text, 0)


def control_period_s(text: str) -> float:
    """Ts [s] within :data:`~ceco_core.contracts.CONTROL_PERIOD_RANGE_S`, the nodes' range (argparse type)."""
    from ceco_core.contracts import CONTROL_PERIOD_RANGE_S

    x = finite_float(text)
    lo, hi = CONTROL_PERIOD_RANGE_S
    if not lo <= x <= hi:
        raise argparse.ArgumentTypeError(f'must be a number of seconds in {lo:g}..{hi:g}, got {text!r}')
    return x


def horizon_steps(text: str) -> int:
    """Np [steps] within :data:`~ceco_core.contracts.HORIZON_RANGE`, the nodes' range (argparse type)."""
    from ceco_core.contracts import HORIZON_RANGE

    return _whole_number(text, *HORIZON_RANGE)


def domain_id(text: str) -> int:
    """A ROS_DOMAIN_ID in 0..:data:`~ceco_core.contracts.DOMAIN_ID_MAX` (argparse type)."""
    from ceco_core.contracts import DOMAIN_ID_MAX

    return _whole_number(text, 0, DOMAIN_ID_MAX)


def nonempty(text: str) -> str:
    """A non-empty string (argparse type): ``--scenario ''`` or ``--out ''`` is a mistake, not the default."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f'must not be empty, got {text!r}')
    return text


def comma_list(item_type, allow_empty: bool = False):
    """An argparse type: a comma-separated list of ``item_type`` values ('' an empty list where allowed)."""

    def parse(text: str) -> list:
        parts = [t.strip() for t in text.split(',') if t.strip()]
        if not parts and not allow_empty:
            raise argparse.ArgumentTypeError(f'expected a comma-separated list, got {text!r}')
        return [item_type(t) for t in parts]

    return parse


def strategy_list(text: str) -> list[str]:
    """``all`` or a comma-separated list of strategies, as a list without repeats (argparse type).

    ``all``: the baseline and the CECO strategies; a list may also name a variant such as ``ceco-pmv-aq``.
    """
    from ceco_core.contracts import NAMED_STRATEGIES, STRATEGIES

    if text.strip() == 'all':
        return list(STRATEGIES)
    names = [s.strip() for s in text.split(',') if s.strip()]
    if 'all' in names:
        raise argparse.ArgumentTypeError(
            f'all stands alone (it names every strategy the verb runs), got {text!r}: give all or a list of names'
        )
    bad = [s for s in names if s not in NAMED_STRATEGIES]
    if not names or bad:
        raise argparse.ArgumentTypeError(
            f"unknown strategy {', '.join(bad) or repr(text)}: use all or a comma-separated list of "
            f"{', '.join(NAMED_STRATEGIES)}"
        )
    return list(dict.fromkeys(names))


# ------------------------------------------------------------------------------------- deprecated names
DEPRECATED_FLAGS = {
    '--preview-quality': '--preview',
    '--control-period': '--control-period-s',
    '--horizon': '--horizon-steps',
    '--duration': '--duration-s',
}
"""Old flag name -> the shared name (accepted for one release with a deprecation line)."""


class _Deprecated(argparse.Action):
    """An old flag name: stores into the new flag's destination and says so once on stderr."""

    def __init__(self, option_strings, dest, new_flag='', value_type=None, **kw):
        self.new_flag = new_flag
        self.value_type = value_type
        super().__init__(option_strings, dest, help=argparse.SUPPRESS, **kw)

    def __call__(self, parser, namespace, values, option_string=None):
        if self.value_type is not None:
            try:
                values = self.value_type(values)
            except argparse.ArgumentTypeError as exc:
                parser.error(f'argument {option_string}: {exc}')
        print(
            f'{parser.prog}: {option_string} is deprecated and goes in the next release: use {self.new_flag}',
            file=sys.stderr,
        )
        setattr(namespace, self.dest, values)


def _add(p, flag: str, *, dest: str, type_=None, deprecated: Sequence[str] = (), **kw) -> None:
    """Add ``flag``, with its old names in one mutually exclusive group.

    argparse then refuses two names of one setting together (``--duration 60 --duration-s 120`` kept the last
    without a word).
    """
    group = p.add_mutually_exclusive_group() if deprecated else p
    group.add_argument(flag, dest=dest, type=type_, **kw)
    for old in deprecated:
        group.add_argument(
            old, dest=dest, action=_Deprecated, new_flag=flag, value_type=type_, default=argparse.SUPPRESS
        )


# ------------------------------------------------------------------------------------- shared flags
BUNDLED_SCENARIOS = (
    'sc03',
    'udds',
    'hwfet',
    'us06',
    'hwfet_udds',
    'sc03_mild',
    'sc03_hotsoak',
    'sc03_idle',
    'sc03_stop',
    'sun_shade',
    'tunnel',
    'udds_humid',
)
"""The scenarios shipped with ceco_v2x_preview, as ``--scenario``'s help names them (equal to
``ceco_v2x_preview.scenario.list_scenarios()``: tests/test_outputs.py)."""


def add_scenario(p, default: str | None = 'sc03', help_extra: str = '') -> None:
    """``--scenario``: a bundled scenario name or a scenario YAML path."""
    p.add_argument(
        '--scenario',
        type=nonempty,
        default=default,
        help=f"bundled scenario name ({', '.join(BUNDLED_SCENARIOS)}) or YAML path" + help_extra,
    )


def add_strategy(p, default: str | None, help_extra: str = '', deprecated: Sequence[str] = ()) -> None:
    """``--strategy``: ``all`` or a comma-separated list of strategies, parsed into a list.

    ``deprecated``: a verb's own old names for it (``ceco bench``'s ``--strategies``).
    """
    from ceco_core.contracts import NAMED_STRATEGIES, STRATEGIES

    _add(
        p,
        '--strategy',
        dest='strategy',
        type_=strategy_list,
        default=default if default is None else strategy_list(default),
        deprecated=deprecated,
        help=f"all ({', '.join(STRATEGIES)}), or one or a comma-separated list of {', '.join(NAMED_STRATEGIES)}"
        + help_extra,
    )


def out_dir_error(path: str) -> str | None:
    """Why ``path`` cannot be the output directory (None when it can).

    An existing file, an ancestor that is a file, or a place where no directory can be made (tried with a
    temporary directory that is removed again, so nothing is left behind).
    """
    import tempfile
    from pathlib import Path

    p = Path(path)
    if p.exists():
        return None if p.is_dir() else f'{path} exists and is not a directory'
    parent = p.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        return f'{path} cannot be made: {parent} is not a directory'
    try:
        os.rmdir(tempfile.mkdtemp(prefix='.ceco-out-check-', dir=parent))
    except OSError as exc:
        return f'{path} cannot be made in {parent}: {exc.strerror or exc}'
    return None


def check_out(parser, path: str | None) -> None:
    """``parser.error`` (one line, exit status 2) when ``--out`` cannot be the output directory."""
    if path is not None and (why := out_dir_error(path)) is not None:
        parser.error(f'argument --out: {why}')


def add_out(p, help_: str, *, required: bool = True, default: str | None = None) -> None:
    """``--out``: the output directory."""
    p.add_argument('--out', type=nonempty, required=required, default=default, help=help_)


def add_preview(p, default: str | None = 'perfect', help_extra: str = '') -> None:
    """``--preview`` (old name ``--preview-quality``): the preview quality grammar."""
    _add(
        p,
        '--preview',
        dest='preview',
        type_=nonempty,
        default=default,
        deprecated=('--preview-quality',),
        help='V2X preview quality: perfect | noisy[:KEY=V,...] | delayed:S | missing:A-B[,...] | '
        'uncertain:LEVEL, joined by + (docs/scenarios.md)' + help_extra,
    )


def add_control_period(
    p, default_text: str = "the scenario's, 5 s for the bundled ones", deprecated: Sequence[str] = ('--control-period',)
) -> None:
    """``--control-period-s`` (old name ``--control-period``): Ts [s] in 0.1..300; None when not given."""
    _add(
        p,
        '--control-period-s',
        dest='control_period_s',
        type_=control_period_s,
        default=None,
        deprecated=deprecated,
        help=f'control period Ts [s] (default: {default_text})',
    )


def add_horizon(
    p, default_text: str = "the scenario's, 6 for the bundled ones", deprecated: Sequence[str] = ('--horizon',)
) -> None:
    """``--horizon-steps`` (old name ``--horizon``): Np [steps] in 1..60; None when not given."""
    _add(
        p,
        '--horizon-steps',
        dest='horizon_steps',
        type_=horizon_steps,
        default=None,
        deprecated=deprecated,
        help=f'prediction horizon Np [steps] (default: {default_text})',
    )


def add_duration(p, default_text: str = "the scenario's length") -> None:
    """``--duration-s`` (old name ``--duration``): run only the first seconds of the scenario [s], > 0."""
    _add(
        p,
        '--duration-s',
        dest='duration_s',
        type_=positive_float,
        default=None,
        deprecated=('--duration',),
        help=f'run only the first DURATION seconds of the scenario [s] (default: {default_text})',
    )


def noise_seed(text: str) -> int:
    """A preview-noise seed within :data:`~ceco_core.contracts.NOISE_SEED_RANGE`, preview_node's (argparse type)."""
    from ceco_core.contracts import NOISE_SEED_RANGE

    return _whole_number(text, *NOISE_SEED_RANGE)


def add_seed(p) -> None:
    """``--seed``: the seed of the preview noise (:func:`noise_seed`)."""
    p.add_argument(
        '--seed',
        type=noise_seed,
        default=None,
        help="seed of the preview noise (default: the preview's seed=, else with --case the case's first, "
        "else the scenario's)",
    )


def add_workers(p) -> None:
    """``--workers``: parallel worker processes, >= 1."""
    p.add_argument(
        '--workers', type=positive_int, default=None, help=f'parallel workers (default: all cores, {os.cpu_count()})'
    )


def add_backend(p) -> None:
    """``--backend`` and ``--address``: the local process pool or Ray."""
    p.add_argument('--backend', choices=('local', 'ray'), default='local', help='local process pool or Ray')
    p.add_argument(
        '--address', default=None, help='Ray cluster address, e.g. auto or ray://host:10001 (needs --backend ray)'
    )


def normalize_namespace(namespace: str | None) -> str:
    """A ROS namespace in its canonical form: '' / None -> '' (the root namespace); 'veh1', '/veh1/' -> '/veh1'.

    Raises ValueError for a name ROS 2 would reject (tokens of letters,
    digits and underscores, not starting with a digit).
    """
    if not namespace or namespace.strip('/') == '':
        return ''
    ns = '/' + namespace.strip('/')
    if not re.fullmatch(r'(/[A-Za-z_][A-Za-z0-9_]*)+', ns) or '__' in ns:
        raise ValueError(
            f'invalid namespace {namespace!r}: tokens of letters, digits and '
            'underscores, not starting with a digit, separated by /'
        )
    return ns


def namespace(text: str) -> str:
    """A ROS namespace as given, checked by :func:`normalize_namespace` (argparse type)."""
    try:
        normalize_namespace(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def add_namespace(p, help_: str, default: str | None = None) -> None:
    """``--namespace``: a ROS namespace (an invalid one is refused when the command line is read)."""
    p.add_argument('--namespace', type=namespace, default=default, help=help_)


def add_domain_id(p, help_: str) -> None:
    """``--domain-id``: a ROS_DOMAIN_ID."""
    p.add_argument('--domain-id', type=domain_id, default=None, help=help_)


def setpoint_list(text: str) -> tuple[float, ...]:
    """``--baseline-setpoints-c``: 2 or more comma-separated set-points in 15..35 degC, or ``none`` (argparse type)."""
    if text.strip().lower() == 'none':
        return ()
    try:
        vals = tuple(float(x) for x in text.split(',') if x.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected set-points like 23,24,25 or none, got {text!r}') from None
    if len(set(vals)) < 2 or not all(math.isfinite(x) and 15.0 <= x <= 35.0 for x in vals):
        raise argparse.ArgumentTypeError(f'need 2 or more different set-points within 15..35 degC, got {text!r}')
    return tuple(sorted(set(vals)))


def add_baseline_setpoints(p, default: Sequence[float]) -> None:
    """``--baseline-setpoints-c``: the set-points of the job's baseline family [degC] (``ceco_bringup.verdict``)."""
    p.add_argument(
        '--baseline-setpoints-c',
        type=setpoint_list,
        default=tuple(default),
        help='set-points of the baseline family run in-process for the saving at matched comfort [degC], '
        'comma-separated; none: skip it',
    )


def check_duration(
    duration_s: float | None, scenario, control_period_s: float | None = None, name: str = '--duration-s'
) -> None:
    """ValueError when ``--duration-s`` cannot be run as given (never clamped or rounded silently).

    It must fit in the scenario, be a whole number of plant steps
    (:data:`~ceco_core.contracts.PLANT_STEP_S`), at least two of them (a run's metrics need two samples), and
    at least one control period (``control_period_s``, the scenario's when None). ``name``: what the message
    calls the setting (a sweep grid's ``duration_s``).
    """
    from ceco_core.contracts import PLANT_STEP_S
    from ceco_core.control_grid import STEP_TOL, floor_steps, whole_steps

    if duration_s is None:
        return
    if duration_s > scenario.duration_s + 1e-9:
        raise ValueError(
            f'{name}: {duration_s:g} s exceeds the length of scenario {scenario.name} '
            f'({scenario.duration_s:g} s): give at most {scenario.duration_s:g}'
        )
    if duration_s / PLANT_STEP_S < 2 - STEP_TOL:
        raise ValueError(f'{name}: {duration_s:g} s is less than two plant steps: give at least {2 * PLANT_STEP_S:g}')
    if whole_steps(duration_s, PLANT_STEP_S) is None:
        raise ValueError(
            f'{name}: {duration_s:g} s is not a whole number of plant steps ({PLANT_STEP_S:g} s): '
            f'give e.g. {floor_steps(duration_s, PLANT_STEP_S) * PLANT_STEP_S:g}'
        )
    if control_period_s is None:
        control_period_s = scenario.control.control_period_s
    if duration_s < control_period_s - 1e-9:
        raise ValueError(
            f'{name}: {duration_s:g} s is shorter than one control period ({control_period_s:g} s): '
            f'give at least {control_period_s:g}'
        )


def add_no_progress(p) -> None:
    """``--no-progress``: no progress bar."""
    p.add_argument('--no-progress', action='store_true', help='no progress bar')
