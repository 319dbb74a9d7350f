"""Parameter declaration with full descriptors, from one table per node.

Descriptors carry the unit in the description, declared ranges, choices, read-only or
settable at run time.

Each node module keeps one tuple of :class:`ParamSpec` (in its pure config module); it is
the single source of the declared parameters, of their checks (at start and on
``ros2 param set``) and of the parameter tables in docs/ros.md. Importable without ROS
(rcl_interfaces is imported where a node declares).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import Any, ClassVar, Self

from ceco_core.contracts import CONTROL_PERIOD_RANGE_S, HORIZON_RANGE
from ceco_core.control_grid import TIMING_MODES

__all__ = [
    'CONTROL_PERIOD_RANGE_S',
    'HORIZON_RANGE',
    'NMPC_CONTROL_PERIOD_RANGE_S',
    'NodeConfig',
    'ParamSpec',
    'check_value',
    'declare',
    'declare_all',
    'on_set',
    'sim_time_conflict',
]


@dataclasses.dataclass(frozen=True)
class ParamSpec:
    """One declared parameter."""

    name: str
    """Parameter name (dots group: ``lockstep.command_timeout_s``)."""
    default: Any
    """Default value; its type is the parameter's type."""
    description: str
    """What it sets, with the unit in brackets."""
    float_range: tuple[float, float] | None = None
    """Inclusive range of a float parameter."""
    int_range: tuple[int, int] | None = None
    """Inclusive range of an integer parameter."""
    choices: Sequence[str] | None = None
    """Allowed values of a string parameter."""
    read_only: bool = True
    """False: settable at run time (``ros2 param set``); the node applies it at once."""
    at_configure: bool = False
    """A managed node's configuration: settable while the node is unconfigured, applied on configure."""

    @property
    def when(self) -> str:
        """When ``ros2 param set`` may change it: 'yes' (any time), 'unconfigured' or 'no' (docs table)."""
        return 'yes' if not self.read_only else 'unconfigured' if self.at_configure else 'no'


NMPC_CONTROL_PERIOD_RANGE_S = (5.0, 300.0)
"""Ts of mpc_node [s]: a whole multiple of the control model's step (5 s, the identified model; the
NMPC refuses another Ts at configure, naming it) and above twice its CPU-time budget per solve
(controller.yaml ``max_cpu_time_s`` 1.0 s)."""
INPUT_WINDOW_PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec(
        'inputs.window_s',
        60.0,
        'a state is accepted up to this far ahead of the last accepted scenario time [s]',
        float_range=(0.01, 1e6),
    ),
    ParamSpec(
        'inputs.confirm_count',
        3,
        'consecutive agreeing out-of-window states that establish a new time base (restart, new playback) [-]',
        int_range=(1, 100),
    ),
    ParamSpec(
        'inputs.restart_silence_s',
        3.0,
        'a new time base (key-on or confirmed) is taken only after no state '
        'was accepted for this long (wall clock); longer than the plant step [s]',
        float_range=(0.0, 60.0),
    ),
)
"""The sequence gate's parameters (``ceco_core.sequencing.SequenceGate``), the same in every node that takes
``cabin/state``."""

CLOCK_AHEAD_PARAMETER = ParamSpec(
    'inputs.max_clock_ahead_s',
    1.0,
    'realtime: a stamp may lead the node clock by this much [s]',
    float_range=(0.0, 3600.0),
    read_only=False,
)
"""How far a real-time stamp may lead the node clock."""


def log_throttle_parameter(what: str = 'input') -> ParamSpec:
    """The throttle of the rejection log lines (``what``: the rejected message, for the description)."""
    return ParamSpec(
        'inputs.log_throttle_s',
        2.0,
        f'shortest time between two log lines about one kind of rejected {what} [s]',
        float_range=(0.0, 3600.0),
        read_only=False,
    )


LIVELINESS_LEASE_S = 1.0
"""Default automatic liveliness lease every node offers and requests (``qos.liveliness_lease_s``) [s]."""


def liveliness_parameter(description: str, at_configure: bool = False) -> ParamSpec:
    """The automatic liveliness lease a node offers or requests (``qos.liveliness_lease_s``)."""
    return ParamSpec(
        'qos.liveliness_lease_s',
        LIVELINESS_LEASE_S,
        description,
        float_range=(0.1, CONTROL_PERIOD_RANGE_S[1]),
        at_configure=at_configure,
    )


DIAGNOSTICS_PERIOD_PARAMETER = ParamSpec(
    'diagnostics.period_s', 1.0, '/diagnostics publication period (steady clock) [s]', float_range=(0.05, 60.0)
)
"""The /diagnostics period of every node."""

SHARED_FIELDS = {
    'inputs.window_s': 'window_s',
    'inputs.confirm_count': 'confirm_count',
    'inputs.restart_silence_s': 'restart_silence_s',
    'inputs.max_state_age_s': 'max_state_age_s',
    'inputs.max_clock_ahead_s': 'max_clock_ahead_s',
    'inputs.log_throttle_s': 'log_throttle_s',
    'diagnostics.period_s': 'diagnostics_period_s',
    'qos.liveliness_lease_s': 'liveliness_lease_s',
}
"""Parameter name -> config field of the shared parameters (the nodes' own tables add theirs)."""


class NodeConfig:
    """Base of the nodes' frozen configuration dataclasses: parameter names to fields, validated copies.

    A subclass (a ``@dataclasses.dataclass(frozen=True)`` with a ``timing`` field) sets
    ``PARAM_FIELDS`` (parameter name -> field where they differ; :data:`SHARED_FIELDS` and its
    own), ``POSITIVE`` (fields that must be finite and > 0) and extends :meth:`validate`.
    """

    __dataclass_fields__: ClassVar[dict]
    timing: str
    """lockstep or realtime (every node has it)."""
    PARAM_FIELDS: ClassVar[dict[str, str]] = SHARED_FIELDS
    POSITIVE: ClassVar[tuple[str, ...]] = ()

    @classmethod
    def fields_of(cls, values: dict[str, Any]) -> dict[str, Any]:
        """``{parameter name: value}`` -> ``{field: value}``."""
        return {cls.PARAM_FIELDS.get(k, k): v for k, v in values.items()}

    def replaced(self, values: dict[str, Any]) -> Self:
        """A copy with some parameters (``{name: value}``) changed, validated."""
        cfg = dataclasses.replace(self, **self.fields_of(values))
        cfg.validate()
        return cfg

    def validate(self) -> None:
        """Raise ValueError naming the parameter: the timing mode, every :attr:`POSITIVE` field finite and > 0."""
        if self.timing not in TIMING_MODES:
            raise ValueError(f'invalid parameter timing={self.timing!r}: must be one of {TIMING_MODES}')
        for name in self.POSITIVE:
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f'invalid parameter {name}={v!r}: must be finite and > 0')


SIM_TIME_IN_REALTIME = (
    'use_sim_time is true but timing is realtime: nothing publishes /clock in real time; '
    'use timing lockstep or use_sim_time false'
)
"""Why a ``timing: realtime`` node refuses rclpy's ``use_sim_time: true`` (only a lockstep plant publishes /clock)."""


def sim_time_conflict(timing: str, use_sim_time: Any) -> str | None:
    """Why ``timing`` and rclpy's ``use_sim_time`` cannot go together, or None.

    In real time nothing publishes /clock, so a node on simulation time would never see its clock move
    (a timer on it never fires, every stamp lies ahead of it). Checked at start and on ``ros2 param set``
    of either parameter, in every node that has ``timing``.
    """
    return SIM_TIME_IN_REALTIME if use_sim_time is True and timing == 'realtime' else None


def check_value(spec: ParamSpec, value: Any) -> tuple[Any, str | None]:
    """``(value, None)`` with ints widened for float parameters, or ``(value, reason)``."""
    if isinstance(spec.default, float):
        if isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if not isinstance(value, float) or not math.isfinite(value):
            return value, f'invalid parameter {spec.name}={value!r}: must be a finite number'
    if spec.float_range is not None and not spec.float_range[0] <= value <= spec.float_range[1]:
        return value, (
            f'invalid parameter {spec.name}={value!r}: must lie in [{spec.float_range[0]}, {spec.float_range[1]}]'
        )
    if spec.int_range is not None and not spec.int_range[0] <= value <= spec.int_range[1]:
        return value, (
            f'invalid parameter {spec.name}={value!r}: must lie in [{spec.int_range[0]}, {spec.int_range[1]}]'
        )
    if spec.choices is not None and value not in spec.choices:
        return value, f'invalid parameter {spec.name}={value!r}: must be one of {", ".join(spec.choices)}'
    return value, None


def declare(
    node,
    name: str,
    default: Any,
    description: str,
    *,
    float_range: tuple[float, float] | None = None,
    int_range: tuple[int, int] | None = None,
    choices: Sequence[str] | None = None,
    read_only: bool = True,
) -> Any:
    """Declare one parameter with a full descriptor and return its value.

    `description` carries the unit; `float_range`/`int_range` become the
    descriptor's range (rclpy rejects an out-of-range value at declaration,
    with a message naming the parameter). `choices` is checked here.
    Raises ValueError with the parameter name on any invalid value.
    """
    spec = ParamSpec(name, default, description, float_range, int_range, choices, read_only)
    return _declare(node, spec)


def _declare(node, spec: ParamSpec) -> Any:
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

    name = spec.name
    desc = ParameterDescriptor(
        name=name, description=spec.description, read_only=spec.read_only and not spec.at_configure
    )
    if spec.float_range is not None:
        desc.floating_point_range = [
            FloatingPointRange(from_value=float(spec.float_range[0]), to_value=float(spec.float_range[1]), step=0.0)
        ]
        desc.additional_constraints = f'{spec.float_range[0]} <= {name} <= {spec.float_range[1]}'
    if spec.int_range is not None:
        desc.integer_range = [IntegerRange(from_value=int(spec.int_range[0]), to_value=int(spec.int_range[1]), step=1)]
        desc.additional_constraints = f'{spec.int_range[0]} <= {name} <= {spec.int_range[1]}'
    if spec.choices is not None:
        desc.additional_constraints = f'one of {", ".join(spec.choices)}'
    _widen_int_override(node, spec)
    try:
        value = node.declare_parameter(name, spec.default, desc).value
    except Exception as err:  # rclpy: InvalidParameterValueException, type errors
        raise ValueError(f'invalid parameter {name}: {err}') from None
    value, why = check_value(spec, value)
    if why:
        raise ValueError(why)
    return value


def _widen_int_override(node, spec: ParamSpec) -> None:
    """An integer given for a float parameter (``-p control_period_s:=5``, ``5`` in a YAML file) as that float.

    rclpy types a parameter by its default and refuses an override of another type; the
    overrides (from the command line and parameter files) are read from the node's table of them
    before the declaration, as rclpy itself does (``Node._parameter_overrides``).
    """
    from rclpy.parameter import Parameter

    overrides = getattr(node, '_parameter_overrides', {})
    given = overrides.get(spec.name)
    value = None if given is None else given.value
    if isinstance(spec.default, float) and isinstance(value, int) and not isinstance(value, bool):
        overrides[spec.name] = Parameter(spec.name, Parameter.Type.DOUBLE, float(value))


def declare_all(node, specs: Sequence[ParamSpec]) -> dict[str, Any]:
    """Declare every parameter of the table; ``{name: value}``. ValueError names the first bad one."""
    return {spec.name: _declare(node, spec) for spec in specs}


def on_set(
    node,
    specs: Sequence[ParamSpec],
    apply: Callable[[dict[str, Any]], str | None],
    unconfigured: Callable[[], bool] | None = None,
) -> None:
    """Accept ``ros2 param set`` on the table's settable parameters.

    A configuration parameter (``at_configure``) is accepted only while ``unconfigured()`` is
    true (a managed node in its unconfigured state); otherwise the reason names the lifecycle
    transition to make first.

    An integer for a float parameter is taken as that float (rclpy's pre-set callback). Each
    value is checked against its spec, then ``apply({name: value})`` (returns a reason to refuse, or None)
    makes the change take effect. Read-only parameters are refused by rclpy itself. rclpy's own boolean
    ``use_sim_time`` is passed to ``apply`` too (to be checked against the timing, :func:`sim_time_conflict`);
    this callback runs before rclpy's time source takes it.
    """
    from rcl_interfaces.msg import SetParametersResult
    from rclpy.parameter import Parameter

    by_name = {s.name: s for s in specs if not s.read_only or s.at_configure}
    floats = {s.name for s in specs if isinstance(s.default, float)}

    def widen(parameters):  # `ros2 param set control_period_s 5`: an integer for a double
        from rclpy.parameter import Parameter

        return [
            Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
            if p.name in floats and p.type_ == Parameter.Type.INTEGER
            else p
            for p in parameters
        ]

    node.add_pre_set_parameters_callback(widen)

    def callback(parameters) -> SetParametersResult:
        changes = {}
        for p in parameters:
            if p.name == 'use_sim_time' and p.type_ == Parameter.Type.BOOL:
                changes[p.name] = p.value  # (another type: rclpy's time source refuses it)
                continue
            spec = by_name.get(p.name)
            if spec is None:
                continue  # another parameter (qos_overrides.*): rclpy's own rules
            if spec.read_only and not (unconfigured is not None and unconfigured()):
                name = node.get_fully_qualified_name()
                return SetParametersResult(
                    successful=False,
                    reason=f'{p.name} is a configuration parameter: set it while the node is unconfigured '
                    f'(ros2 lifecycle set {name} deactivate, then cleanup), it applies on configure',
                )
            value, why = check_value(spec, p.value)
            if why:
                return SetParametersResult(successful=False, reason=why)
            changes[p.name] = value
        why = apply(changes) if changes else None
        return SetParametersResult(successful=why is None, reason=why or '')

    node.add_on_set_parameters_callback(callback)


def markdown_table(specs: Sequence[ParamSpec]) -> str:
    """The parameter table of a node for docs/ros.md: name, default, range or choices, run-time, description."""
    rows = ['| parameter | default | range | set at run time | description |', '|---|---|---|---|---|']
    for s in specs:
        if s.float_range is not None or s.int_range is not None:
            lo, hi = s.float_range or s.int_range  # type: ignore[misc]
            allowed = f'{lo} .. {hi}'
        elif s.choices is not None:
            allowed = ', '.join(s.choices)
        else:
            allowed = ''
        default = (
            repr(s.default)
            if isinstance(s.default, str)
            else str(s.default).lower()
            if isinstance(s.default, bool)
            else str(s.default)
        )
        rows.append(f'| `{s.name}` | `{default}` | {allowed} | {s.when} | {s.description} |')
    return '\n'.join(rows)
