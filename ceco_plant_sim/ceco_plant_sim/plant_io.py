"""What plant_node does with its input and how it reports, without ROS.

The parameter table, the validated configuration, the command policy (field checks, which
control step a command may be for, its stamp) and the health rules behind /diagnostics.

Pure logic: commands are read by attribute (ceco_msgs/AcCommand in the node,
``types.SimpleNamespace`` in the tests); times are floats the node passes in.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import ceco_ros.checks as checks
from ceco_core.contracts import PLANT_STEP_S
from ceco_core.control_grid import TIMING_MODES, control_step_of
from ceco_core.supervision import FallbackSupervisor, Health, Liveliness, Rejections, SourceGate, Watchdog, reason_kind
from ceco_core.units import s_from_stamp
from ceco_ros.params import (
    CONTROL_PERIOD_RANGE_S,
    DIAGNOSTICS_PERIOD_PARAMETER,
    SHARED_FIELDS,
    NodeConfig,
    ParamSpec,
    liveliness_parameter,
    log_throttle_parameter,
)
from ceco_ros.topics import TOPIC_COMMAND

from .compiled_plant import PLANT_EVALUATIONS

__all__ = [
    'PLANT_PARAMETERS',
    'PlantNodeConfig',
    'CommandPolicy',
    'RealtimeCommands',
    'start_gate',
    'STARTED',
    'plant_health',
    'DYNAMIC',
]

PLANT_PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec('scenario', 'sc03', 'scenario name or YAML path (environment, initial state, occupant, PMV bounds)'),
    ParamSpec(
        'timing',
        'lockstep',
        'lockstep (advance a control period per command) or realtime (timer every plant step on the node clock)',
        choices=TIMING_MODES,
    ),
    ParamSpec('plant_dt_s', PLANT_STEP_S, 'plant step and recording interval [s]', float_range=(0.01, 60.0)),
    ParamSpec(
        'control_period_s',
        5.0,
        'control period Ts [s], a whole multiple of plant_dt_s',
        float_range=CONTROL_PERIOD_RANGE_S,
    ),
    ParamSpec('duration_s', 0.0, "run length [s]; 0 = the scenario's", float_range=(0.0, 1e7)),
    ParamSpec(
        'plant_evaluation',
        'compiled',
        'compiled (the plant step as generated C, cached; the Python evaluation with one warning where no '
        'C compiler works) or python (the numeric evaluation); equal to 1e-9 relative (docs/plant.md)',
        choices=PLANT_EVALUATIONS,
    ),
    ParamSpec(
        'lockstep.command_timeout_s',
        5.0,
        'lockstep: wall-clock wait for the command of a step before the fallback ACC law applies; from '
        '0.5 s, ten times a controller\'s usual answer (a control period of a lockstep run: 20-45 ms) [s]',
        float_range=(0.5, 3600.0),
        read_only=False,
    ),
    ParamSpec(
        'lockstep.min_state_subscribers',
        2,
        'lockstep (realtime only with realtime.start_gate): cabin/state subscribers to wait for before step 0; '
        'above 0 step 0 also waits for a hvac/command publisher [-]',
        int_range=(0, 100),
    ),
    ParamSpec(
        'lockstep.min_output_subscribers',
        0,
        'lockstep (realtime only with realtime.start_gate): subscribers of every other output to wait for '
        'before step 0 [-]',
        int_range=(0, 100),
    ),
    ParamSpec(
        'lockstep.min_command_subscribers',
        1,
        'lockstep (realtime only with realtime.start_gate): hvac/command data readers (this node included, '
        'liveliness probes not) to see in the graph before step 0 [-]',
        int_range=(0, 100),
    ),
    ParamSpec(
        'realtime.start_gate',
        False,
        'realtime: false (a vehicle): step 0 at once, the ACC law drives until a controller commands; true: '
        'step 0 waits, unbounded, for the lockstep.min_*_subscribers and a hvac/command publisher, as in '
        'lockstep (ceco run, record:=true: so the recorder gets step 0); ignored in lockstep',
    ),
    ParamSpec(
        'fallback.command_timeout_periods',
        1.0,
        'realtime: the fallback ACC law applies when the latest command is older than this many control '
        'periods plus one plant step (1: a missing command is noticed one plant step after it was due) '
        '[control periods]',
        float_range=(1.0, 10.0),
    ),
    liveliness_parameter(
        'automatic liveliness lease requested of the hvac/command publishers: the ACC law takes over '
        'within it (plus a plant step) when the controller\'s process dies; at least the controller\'s '
        'qos.liveliness_lease_s, at most Ts [s]'
    ),
    ParamSpec(
        'commands.require_sequence',
        True,
        'refuse commands without a source epoch and sequence (AcCommand.epoch 0: an older or '
        'third-party controller that does not set them), as foreign; false accepts one such source '
        '(a warning says what it should set)',
    ),
    log_throttle_parameter('command'),
    DIAGNOSTICS_PERIOD_PARAMETER,
)
"""The parameter table of plant_node."""

DYNAMIC = {s.name for s in PLANT_PARAMETERS if not s.read_only}
"""Parameters that ``ros2 param set`` changes at run time."""

_FIELDS = {
    'plant_evaluation': 'plant_evaluation',
    'lockstep.command_timeout_s': 'command_timeout_s',
    'lockstep.min_state_subscribers': 'min_state_subscribers',
    'lockstep.min_output_subscribers': 'min_output_subscribers',
    'lockstep.min_command_subscribers': 'min_command_subscribers',
    'realtime.start_gate': 'realtime_start_gate',
    'fallback.command_timeout_periods': 'command_timeout_periods',
    'commands.require_sequence': 'require_sequence',
    **SHARED_FIELDS,
}


@dataclasses.dataclass(frozen=True)
class PlantNodeConfig(NodeConfig):
    """Validated parameters of plant_node."""

    scenario: str
    """Scenario name or YAML path (environment truth, initial state, occupant, bounds)."""
    timing: str
    """lockstep or realtime."""
    plant_dt_s: float
    """Plant step [s]."""
    control_period_s: float
    """Control period Ts [s]; a whole multiple of plant_dt_s."""
    duration_s: float = 0.0
    """Run length [s]; 0 = the scenario's."""
    plant_evaluation: str = 'compiled'
    """How the plant step is evaluated: compiled (generated C) or python."""
    command_timeout_s: float = 5.0
    """lockstep: wall-clock wait for a command before the fallback law [s]."""
    min_state_subscribers: int = 2
    """lockstep: start once cabin/state has this many subscribers."""
    min_output_subscribers: int = 0
    """lockstep: ... and every other output this many (a recorder)."""
    min_command_subscribers: int = 1
    """lockstep: ... and hvac/command this many subscriptions in the graph (plant + recorder)."""
    realtime_start_gate: bool = False
    """realtime: step 0 waits for the min_*_subscribers and a command publisher too (else it starts at once)."""
    command_timeout_periods: float = 1.0
    """realtime: command age (in control periods, plus one plant step) after which the fallback law applies."""
    liveliness_lease_s: float = 1.0
    """Liveliness lease requested of the hvac/command publishers [s]."""
    require_sequence: bool = True
    """Refuse commands without epoch/sequence."""
    log_throttle_s: float = 2.0
    """Shortest time between two log lines about one kind of rejected command [s]."""
    diagnostics_period_s: float = 1.0
    """/diagnostics period [s]."""

    PARAM_FIELDS = _FIELDS

    @classmethod
    def from_params(cls, values: dict[str, Any]) -> PlantNodeConfig:
        """From the declared parameters (``{name: value}``), validated."""
        cfg = cls(**cls.fields_of(values))
        cfg.validate()
        return cfg

    def validate(self) -> None:
        """Raise ValueError naming the parameter."""
        from .scenario_plant import steps_per_control

        super().validate()
        try:
            steps_per_control(self.control_period_s, self.plant_dt_s)
        except ValueError as err:
            raise ValueError(f'invalid parameter control_period_s={self.control_period_s}: {err}') from None
        if self.liveliness_lease_s > self.control_period_s:
            raise ValueError(
                f'invalid parameter qos.liveliness_lease_s={self.liveliness_lease_s!r}: must be at most '
                f'control_period_s={self.control_period_s!r} (a dead controller is to be noticed within a period)'
            )

    @property
    def command_timeout_rt_s(self) -> float:
        """realtime: the command age limit [s]: ``command_timeout_periods`` control periods plus one plant step."""
        return self.command_timeout_periods * self.control_period_s + self.plant_dt_s

    @property
    def max_lag_steps(self) -> int:
        """realtime: how many control steps a command may lag the plant's current one [-]."""
        return int(math.ceil(self.command_timeout_periods)) + 1


class CommandPolicy:
    """Which AcCommand the plant applies.

    Every field is checked (:func:`ceco_ros.checks.check_command`: known strategy, Ts, bounds,
    stamp well formed). Lockstep: only the command of the awaited control step k, stamped t_k.
    Real time: the stamp must be that of a state the plant published recently (a controller
    stamps its command with the state it computed from), the step index the control step of
    that state, and that step at most ``max_lag_steps`` behind the plant's. Then its source:
    :class:`~ceco_core.supervision.SourceGate` (one epoch at a time; others are foreign, a
    sequence not above the last a duplicate). A command marked ``fallback`` (the controller's
    own fallback) is applied and counted. Rejections are counted and logged (throttled) through
    ``log(level, text)``.
    """

    def __init__(self, cfg: PlantNodeConfig, log: Callable[[str, str], None]):
        self.cfg = cfg
        self._log = log
        self.rejections = Rejections(cfg.log_throttle_s)
        self.source = SourceGate(cfg.require_sequence)
        """The command source the plant is bound to (epoch/sequence)."""
        self.liveliness = Liveliness()
        """Liveliness of the hvac/command publishers that offer a lease (the node's probe)."""
        self.n_controller_fallback = 0
        """Accepted commands marked fallback=true [-]."""
        self.last_fallback_flag = False
        self._published: dict[tuple[int, int], float] = {}  # realtime: state stamp -> scenario time [s]
        from .scenario_plant import steps_per_control

        steps_per_period = steps_per_control(cfg.control_period_s, cfg.plant_dt_s)
        self._keep = (self.cfg.max_lag_steps + 2) * steps_per_period

    def published(self, stamp, t_s: float) -> None:
        """realtime: the plant published a state stamped ``stamp`` for scenario time ``t_s`` [s]."""
        self._published[(stamp.sec, stamp.nanosec)] = t_s
        while len(self._published) > self._keep:
            del self._published[next(iter(self._published))]

    def accept(self, msg, k_now: int, wall_s: float) -> bool:
        """True when the command applies to control step ``k_now`` (``wall_s``: for the log throttle)."""
        cfg, k = self.cfg, int(msg.step_index)
        why = checks.check_command(msg, cfg.control_period_s)
        if why is None and cfg.timing == 'lockstep':
            if k != k_now:
                why = f'{"stale" if k < k_now else "future"}: waiting for step {k_now}'
            else:
                why = checks.check_stamp_equals('header.stamp', msg.header.stamp, k * cfg.control_period_s)
        elif why is None:
            why = self._check_realtime(msg, k, k_now)
        if why is None:
            why = self.source.check(int(msg.epoch), int(msg.sequence))
        if why:
            line = self.rejections.add(
                TOPIC_COMMAND, reason_kind(why), f'rejected hvac/command step {k}: {why}', wall_s
            )
            if line:
                self._log('warn', line)
            return False
        self.last_fallback_flag = bool(msg.fallback)
        self.n_controller_fallback += bool(msg.fallback)
        line = self.source.accepted(int(msg.epoch), int(msg.sequence))
        if line:
            self._log('warn' if msg.epoch == 0 else 'info', f'hvac/command from {msg.strategy}: {line}')
        return True

    def _check_realtime(self, msg, k: int, k_now: int) -> str | None:
        cfg = self.cfg
        t_s = self._published.get((msg.header.stamp.sec, msg.header.stamp.nanosec))
        if t_s is None:
            return (
                f'header.stamp={s_from_stamp(msg.header.stamp):.9g} s is not the stamp of a recent '
                'cabin/state of this plant'
            )
        k_state = control_step_of(t_s, cfg.control_period_s)
        if k != k_state:
            return f'step_index {k} is not the control step {k_state} of the state it is stamped with'
        if k < k_now - cfg.max_lag_steps:
            return f'stale: the plant is at control step {k_now} (a command may lag {cfg.max_lag_steps} steps)'
        return None


def plant_health(
    *,
    cfg: PlantNodeConfig,
    started: bool,
    finished: bool,
    n: int,
    t_s: float,
    supervisor: FallbackSupervisor,
    command_age_s: float | None,
    policy: CommandPolicy,
    new_rejections: int,
    events: dict,
    waiting_for: str = '',
    clock_publishers: int = 1,
) -> Health:
    """The plant's status for /diagnostics.

    ``command_age_s``: since the last accepted command (wall clock in lockstep, node clock in
    real time); None: none yet. ``clock_publishers``: publishers on /clock in the domain (lockstep).
    """
    h = Health().set('timing', cfg.timing).set('plant_step', n).set('t_s', t_s)
    if cfg.timing == 'lockstep':
        h.set('clock_publishers', clock_publishers)
        if clock_publishers > 1:
            h.error(clock_conflict(clock_publishers))
    h.set('control_step', control_step_of(t_s, cfg.control_period_s))
    if finished:
        h.set('state', 'finished')
    elif not started:
        h.warn(f'waiting for subscribers before step 0{": " + waiting_for if waiting_for else ""}')
    h.set('in_fallback', supervisor.in_fallback).set('fallback_entries', supervisor.n_entered)
    h.set('fallback_periods', supervisor.n_fallback_periods).set('command_age_s', command_age_s)
    if supervisor.in_fallback and not finished:
        h.warn(f'fallback: the production ACC law drives ({supervisor.reason})')
    h.set('controller_fallback_commands', policy.n_controller_fallback)
    if policy.last_fallback_flag and not supervisor.in_fallback:
        h.warn('the controller reports its own fallback in its last command')
    h.set('rejected_total', policy.rejections.total)
    src = policy.source
    h.set('command_source_epoch', None if src.epoch is None else f'{src.epoch:#018x}')
    h.set('command_sources_bound', src.n_bound).set('unsequenced_commands', src.n_unsequenced)
    foreign = policy.rejections.by_kind.get((TOPIC_COMMAND, 'foreign'), 0)
    h.set('rejected_foreign', foreign)
    if foreign:
        h.warn(f'{foreign} hvac/command messages from a source other than the bound controller rejected')
    live = policy.liveliness
    h.set('command_publishers_alive', live.alive if live.seen else None)
    if new_rejections:
        h.warn(
            f'{new_rejections} hvac/command messages rejected since the last report ({policy.rejections.total} in all)'
        )
    for name, count in events.items():
        h.set(f'qos_{name}', count)
    if events.get('incompatible_qos'):
        h.error(f'{events["incompatible_qos"]} incompatible QoS events on hvac/command (a controller does not match)')
    return h


def clock_conflict(publishers: int) -> str:
    """What a lockstep plant says when it is not alone on /clock (one simulation clock per domain)."""
    return (
        f'{publishers} publishers on /clock in this ROS domain: another lockstep plant drives the same '
        'simulation clock, so every use_sim_time node here follows both; run each lockstep vehicle in a '
        'ROS_DOMAIN_ID of its own (ceco run picks a free one), or several vehicles in real time (docs/ros.md)'
    )


def start_gate(
    cfg: PlantNodeConfig, state_subs: int, output_subs: tuple[int, ...], command_subs: int, command_pubs: int
) -> str:
    """What step 0 still waits for ('' when the plant may start).

    The matched subscribers of cabin/state and of every other output, the hvac/command
    data readers in the graph (the plant's own liveliness probe not counted) and a matched
    command publisher (unless no state subscriber is required). In real time only with
    ``realtime_start_gate``: a real-time plant stands for the vehicle and starts at once (its
    ACC law drives until a controller commands).
    """
    if cfg.timing == 'realtime' and not cfg.realtime_start_gate:
        return ''
    missing = []
    if state_subs < cfg.min_state_subscribers:
        missing.append(f'cabin/state subscribers {state_subs}/{cfg.min_state_subscribers}')
    if min(output_subs, default=0) < cfg.min_output_subscribers:
        missing.append(f'output subscribers {min(output_subs)}/{cfg.min_output_subscribers}')
    if command_subs < cfg.min_command_subscribers:
        missing.append(f'hvac/command subscriptions {command_subs}/{cfg.min_command_subscribers}')
    if command_pubs < 1 and cfg.min_state_subscribers > 0:
        missing.append('a hvac/command publisher')
    return ', '.join(missing)


STARTED = 'subscribers matched: starting at step 0'
"""The log line of a plant whose start gate opened: it publishes the state of step 0 (``ceco run`` watches for it)."""

CONTROLLER_LOST = (
    "the controller's liveliness was lost (its process is gone or frozen, or its node was deactivated or shut down)"
)
"""Why the ACC law drives after a liveliness loss of the command publisher."""


class RealtimeCommands:
    """realtime: which input drives each plant tick.

    The latest accepted command while it is fresh (younger than the command timeout by the
    watchdog, and its publisher's liveliness not lost since it came); a new command is taken at
    control step boundaries only; a stale one is dropped at once (the ACC law takes over).
    """

    def __init__(self, timeout_s: float):
        self.watchdog = Watchdog(timeout_s)
        self.latest = None
        """The latest accepted command (an AcInput), None before the first."""
        self.controller_lost = False
        """The controller's liveliness was lost after its latest command."""
        self.applied: tuple[Any, bool] = (None, True)
        """(input, from the fallback law) applied at the last tick."""

    def accepted(self, u, now_s: float) -> None:
        """A command was accepted at ``now_s`` [s, node clock]."""
        self.latest, self.controller_lost = u, False
        self.watchdog.kick(now_s)

    def fresh(self, now_s: float) -> bool:
        """True while the latest command may drive the plant."""
        return self.latest is not None and not self.watchdog.expired(now_s) and not self.controller_lost

    def why_stale(self, now_s: float) -> str:
        """Why the ACC law drives (for the log and /diagnostics)."""
        if self.controller_lost:
            return CONTROLLER_LOST
        age = self.watchdog.age(now_s)
        latest = 'none yet' if age == math.inf else f'{age:.1f} s old'
        return f'no fresh command (latest {latest}, limit {self.watchdog.timeout_s:.1f} s)'

    def must_choose(self, at_boundary: bool, now_s: float, in_fallback: bool) -> bool:
        """True when this tick picks its input anew: at a control step, or when the command went stale."""
        return at_boundary or (not self.fresh(now_s) and not in_fallback)
