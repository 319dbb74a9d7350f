"""What preview_node does with its input and how it reports, without ROS.

The parameter table, the validated configuration, the state input (field checks, stamp, the
sequence gate on the scenario time) and the health rules behind /diagnostics.

Pure logic: states are read by attribute (ceco_msgs/CabinState in the node,
``types.SimpleNamespace`` in the tests); times are floats the node passes in.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import ceco_ros.checks as checks
from ceco_core.control_grid import TIMING_MODES
from ceco_core.sequencing import SequenceGate, Verdict
from ceco_core.supervision import Health, Rejections, reason_kind
from ceco_ros.params import (
    CLOCK_AHEAD_PARAMETER,
    CONTROL_PERIOD_RANGE_S,
    DIAGNOSTICS_PERIOD_PARAMETER,
    HORIZON_RANGE,
    INPUT_WINDOW_PARAMETERS,
    NodeConfig,
    ParamSpec,
    liveliness_parameter,
    log_throttle_parameter,
)
from ceco_ros.topics import TOPIC_STATE

from . import forecast_error
from .preview import FAULT_RANGES, SEED_RANGE, PreviewQuality

__all__ = ['PREVIEW_PARAMETERS', 'PreviewNodeConfig', 'PreviewInputs', 'preview_health', 'held_previews', 'DYNAMIC']

PREVIEW_PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec('scenario', 'sc03', 'scenario name (bundled) or path of a scenario YAML file'),
    ParamSpec(
        'timing',
        'lockstep',
        'lockstep (accelerated simulation, driven by cabin/state) or realtime (timer on the node clock)',
        choices=TIMING_MODES,
    ),
    ParamSpec(
        'control_period_s', 5.0, 'preview grid step = controller period Ts [s]', float_range=CONTROL_PERIOD_RANGE_S
    ),
    ParamSpec('horizon_steps', 6, 'prediction horizon Np [steps]; the grid has Np + 1 points', int_range=HORIZON_RANGE),
    ParamSpec(
        'publish_period_s',
        5.0,
        'publication period in realtime mode; at most Ts (a controller expects a preview every control period) [s]',
        float_range=(0.01, CONTROL_PERIOD_RANGE_S[1]),
    ),
    ParamSpec(
        'lockstep.min_preview_subscribers',
        1,
        'lockstep: matched data readers on each preview topic (the controller; ceco run and record:=true: '
        'controller and recorder) before the first previews are sent; until then they are held, so no '
        'reader misses step 0; afterwards they go out at once; 0: no wait [-]',
        int_range=(0, 100),
        read_only=False,
    ),
    ParamSpec(
        'faults.missing_spans_s',
        [0.0],
        'spans of issue time without a new forecast, flattened [start, end, start, end, ...] [s]; [0.0] = none',
    ),
    ParamSpec('faults.seed', -1, 'preview noise seed; -1 uses the scenario seed [-]', int_range=(-1, SEED_RANGE[1])),
    ParamSpec(
        'faults.noise_std_t_amb_c',
        0.0,
        'std of the ambient-temperature forecast error at the reference lead [K]',
        float_range=FAULT_RANGES['noise_std_t_amb_c'],
    ),
    ParamSpec(
        'faults.noise_std_solar_wm2',
        0.0,
        'std of the solar forecast error at the reference lead [W/m^2]',
        float_range=FAULT_RANGES['noise_std_solar_wm2'],
    ),
    ParamSpec(
        'faults.noise_std_speed_mps',
        0.0,
        'std of the speed forecast error at the reference lead [m/s]',
        float_range=FAULT_RANGES['noise_std_speed_mps'],
    ),
    ParamSpec(
        'faults.noise_std_rh',
        0.0,
        'std of the relative-humidity forecast error at the reference lead [-]',
        float_range=FAULT_RANGES['noise_std_rh'],
    ),
    ParamSpec(
        'faults.noise_ref_lead_s',
        30.0,
        'lead time at which the error std equals noise_std_* [s]',
        float_range=FAULT_RANGES['noise_ref_lead_s'],
    ),
    ParamSpec('faults.delay_s', 0.0, 'age of the forecast when received [s]', float_range=FAULT_RANGES['delay_s']),
    ParamSpec(
        'faults.missing_policy',
        'hold_last',
        'while missing: hold_last (keep the last forecast) or drop',
        choices=('hold_last', 'drop'),
    ),
    ParamSpec(
        'faults.uncertainty_level',
        'none',
        'benchmark forecast-uncertainty level (AR(1) errors, ceco_v2x_preview.forecast_error)',
        choices=forecast_error.LEVELS,
    ),
    *INPUT_WINDOW_PARAMETERS,
    ParamSpec(
        'inputs.max_state_age_s',
        10.0,
        'realtime: oldest usable cabin state, by its stamp; at least Ts [s]',
        float_range=(0.1, 3600.0),
        read_only=False,
    ),
    CLOCK_AHEAD_PARAMETER,
    log_throttle_parameter(),
    liveliness_parameter(
        'automatic liveliness lease offered on the previews: a controller knows within it that this node is '
        "gone; at most the controller's qos.liveliness_lease_s [s]"
    ),
    DIAGNOSTICS_PERIOD_PARAMETER,
)
"""The parameter table of preview_node."""

DYNAMIC = {s.name for s in PREVIEW_PARAMETERS if not s.read_only}
"""Parameters that ``ros2 param set`` changes at run time."""


@dataclasses.dataclass(frozen=True)
class PreviewNodeConfig(NodeConfig):
    """Validated parameters of preview_node."""

    scenario: str
    """Scenario name or YAML path."""
    timing: str
    """'lockstep' or 'realtime'."""
    control_period_s: float
    """Preview grid step = control period Ts [s]."""
    horizon_steps: int
    """Prediction horizon Np; the grid has Np + 1 points [-]."""
    publish_period_s: float
    """Publication period in realtime mode [s]."""
    quality: PreviewQuality
    """Preview faults."""
    window_s: float = 60.0
    """How far ahead of the last accepted scenario time a state is accepted [s]."""
    confirm_count: int = 3
    """Consecutive agreeing out-of-window states that establish a new time base [-]."""
    restart_silence_s: float = 3.0
    """A new time base only after no state was accepted for this long [s, wall clock]."""
    max_state_age_s: float = 10.0
    """realtime: oldest usable state [s]."""
    max_clock_ahead_s: float = 1.0
    """realtime: how far a stamp may lead the node clock [s]."""
    log_throttle_s: float = 2.0
    """Shortest time between two log lines about one kind of rejection [s]."""
    diagnostics_period_s: float = 1.0
    """/diagnostics period [s]."""
    liveliness_lease_s: float = 1.0
    """Automatic liveliness lease offered on the previews [s]."""
    min_preview_subscribers: int = 1
    """lockstep: matched data readers on each preview topic before the first previews are sent [-]."""
    hold_warning_s: float = 5.0
    """lockstep: previews held this long [s, wall clock] are reported (a warning, the diagnostics)."""

    PARAM_FIELDS = {**NodeConfig.PARAM_FIELDS, 'lockstep.min_preview_subscribers': 'min_preview_subscribers'}
    POSITIVE = ('control_period_s', 'publish_period_s', 'window_s', 'max_state_age_s')

    @classmethod
    def from_params(cls, v: dict[str, Any]) -> PreviewNodeConfig:
        """From the declared parameters (``{name: value}``), validated."""
        spans = list(v['faults.missing_spans_s'])
        if len(spans) == 1 and spans[0] == 0.0:
            spans = []
        if len(spans) % 2:
            raise ValueError(
                f'invalid parameter faults.missing_spans_s={spans!r}: needs an even number of values (start, end pairs)'
            )
        q = {k.split('.', 1)[1]: v[k] for k in v if k.startswith('faults.noise') or k == 'faults.delay_s'}
        quality = PreviewQuality(
            **q,
            missing_spans_s=tuple(zip(spans[0::2], spans[1::2])),
            missing_policy=v['faults.missing_policy'],
            seed=None if v['faults.seed'] < 0 else int(v['faults.seed']),
            uncertainty=v['faults.uncertainty_level'],
        )
        cfg = cls(
            scenario=v['scenario'],
            timing=v['timing'],
            control_period_s=v['control_period_s'],
            horizon_steps=v['horizon_steps'],
            publish_period_s=v['publish_period_s'],
            quality=quality,
            **{f: v[p] for p, f in cls.PARAM_FIELDS.items() if p in v},
        )
        cfg.validate()
        return cfg

    def validate(self) -> None:
        """Raise ValueError naming the parameter."""
        super().validate()
        self.quality.validate()
        ts = self.control_period_s
        # Ranges derived from the others: values that would keep the node from publishing a preview per period.
        for name, value, ok, rule in (
            ('publish_period_s', self.publish_period_s, self.publish_period_s <= ts, 'at most'),
            ('inputs.max_state_age_s', self.max_state_age_s, self.max_state_age_s >= ts, 'at least'),
            ('inputs.window_s', self.window_s, self.window_s >= ts, 'at least'),
        ):
            if not ok:
                raise ValueError(f'invalid parameter {name}={value!r}: must be {rule} control_period_s={ts!r}')


class PreviewInputs:
    """The cabin/state input of preview_node: field checks, the stamp, the sequence gate.

    The stamp: lockstep, the scenario time; real time, age and lead against the node clock.
    Then the :class:`SequenceGate` on the scenario time (a far-future or stale state is rejected
    without moving it; a restart is followed). ``log(level, text)`` gets the (throttled)
    rejection lines.
    """

    def __init__(self, cfg: PreviewNodeConfig, log: Callable[[str, str], None]):
        self.cfg = cfg
        self._log = log
        self.rejections = Rejections(cfg.log_throttle_s)
        self.gate = SequenceGate(cfg.window_s, cfg.confirm_count, silence_s=cfg.restart_silence_s)
        self.n_resets = 0
        self.received_s: float | None = None
        """Wall-clock time of the last accepted state [s]."""

    def offer_state(self, msg, wall_s: float, clock_s: float) -> Verdict | None:
        """The gate's verdict when the state is accepted (``reset``: a new time base), None when not."""
        cfg = self.cfg
        why = checks.check_state(msg)
        if why is None and cfg.timing == 'lockstep':
            why = checks.check_stamp_equals('header.stamp', msg.header.stamp, msg.scenario_time_s)
        elif why is None:
            why = checks.check_stamp_age(
                'header.stamp', msg.header.stamp, clock_s, cfg.max_state_age_s, cfg.max_clock_ahead_s
            )
        verdict = self.gate.offer(msg.scenario_time_s, wall_s) if why is None else None
        if verdict is not None and not verdict.accepted:
            why = verdict.reason
        if why or verdict is None:
            line = self.rejections.add(
                TOPIC_STATE, reason_kind(why), f'rejected cabin/state step {msg.step_index}: {why}', wall_s
            )
            if line:
                self._log('warn', line)
            return None
        if verdict.reset:
            self.n_resets += 1
            self._log('warn', f'cabin/state step {msg.step_index}: {verdict.reason}: previews restart from it')
        self.received_s = wall_s
        return verdict


def preview_health(
    *,
    cfg: PreviewNodeConfig,
    inputs: PreviewInputs,
    last_k: int | None,
    n_published: int,
    n_failed: int,
    last_error: str,
    wall_s: float,
    new_rejections: int,
    held: str = '',
) -> Health:
    """The preview node's status for /diagnostics.

    ``held``: lockstep, what a step's previews have waited for longer than ``cfg.hold_warning_s``
    ('' when nothing waits that long), from :func:`held_previews`.
    """
    h = Health().set('timing', cfg.timing).set('quality', cfg.quality.describe())
    h.set('last_step', last_k).set('published', n_published).set('failed', n_failed)
    if held:
        h.warn(held)
    age = None if inputs.received_s is None else wall_s - inputs.received_s
    h.set('state_age_s', age).set('resets', inputs.n_resets).set('rejected_total', inputs.rejections.total)
    if inputs.gate.last is None:
        h.warn('no valid cabin/state received yet')
    elif cfg.timing == 'realtime' and age is not None and age > cfg.max_state_age_s:
        h.warn(f'no valid cabin/state for {age:.1f} s: previews for an old time')
    if last_error:
        h.error(f'preview generation failed: {last_error}')
    if new_rejections:
        h.warn(
            f'{new_rejections} cabin/state messages rejected since the last report ({inputs.rejections.total} in all)'
        )
    return h


def held_previews(k: int, waited_s: float, readers: dict[str, int], needed: int, last_k: int | None = None) -> str:
    """The line that says a step's previews wait for their readers, e.g. for the log and diagnostics.

    ``k``: the oldest held step, ``last_k`` the newest (None: ``k``); ``readers``: matched data readers per
    preview topic; ``needed``: ``lockstep.min_preview_subscribers``.
    """
    counts = ', '.join(f'{topic} {n}/{needed}' for topic, n in readers.items())
    steps = f'step {k}' if last_k is None or last_k == k else f'steps {k}-{last_k}'
    return (
        f'previews of {steps} held for {waited_s:.1f} s: matched readers {counts} '
        '(lockstep.min_preview_subscribers; a controller or recorder that never comes keeps them back)'
    )
