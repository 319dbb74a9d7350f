"""What mpc_node and baseline_node do with their inputs and how they report, without ROS.

The parameter table, the validated configuration, the input handling (field checks, the
sequence gate, the lockstep buffer, the real-time latest inputs) and the health rules
behind /diagnostics.

Pure logic: message objects are read by attribute only (ceco_msgs messages in the node,
``types.SimpleNamespace`` in the tests); times are floats the node passes in.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import ceco_ros.checks as checks
from ceco_core.control_grid import control_step_index, control_step_of
from ceco_core.sequencing import LockstepBuffer, SequenceGate
from ceco_core.supervision import Health, Rejections, reason_kind
from ceco_core.units import s_from_stamp
from ceco_ros.topics import TOPIC_STATE, TOPIC_TRAFFIC, TOPIC_WEATHER

__all__ = [
    'controller_parameters',
    'ControllerNodeConfig',
    'ControllerInputs',
    'StepInputs',
    'ControllerRecord',
    'controller_health',
    'DYNAMIC',
]

from .controller_params import DYNAMIC, ControllerNodeConfig, controller_parameters  # noqa: F401 - re-exported (__all__)

_PREVIEW_TOPIC = {'weather': TOPIC_WEATHER, 'traffic': TOPIC_TRAFFIC}


@dataclasses.dataclass
class StepInputs:
    """The inputs of one control step: the state and the previews (None: solve without)."""

    k: int
    state: Any
    weather: Any = None
    traffic: Any = None
    note: str = ''
    """Why previews are missing (empty when both are here)."""


class ControllerInputs:
    """Every input of a controller node, checked field by field, then ordered.

    States pass :func:`ceco_ros.checks.check_state`, a stamp check (lockstep: the stamp is
    the scenario time; real time: not older than ``max_state_age_s`` nor ahead of the clock)
    and the :class:`SequenceGate` on the scenario time. Previews pass
    :func:`ceco_ros.checks.check_preview`; lockstep: their start is t_k of their step and the
    :class:`LockstepBuffer` window; real time: they must cover the latest state time. Every
    rejection is counted in ``rejections`` and logged (throttled) through ``log``; a new time
    base calls ``on_reset``.

    Args:
        cfg: the node's configuration.
        log: ``log(level, text)`` with level 'info', 'warn' or 'error'.
        on_reset: called when the gate adopts a new time base (restart, new playback).
    """

    def __init__(self, cfg: ControllerNodeConfig, log: Callable[[str, str], None], on_reset: Callable[[], None]):
        self.cfg = cfg
        self._log = log
        self._on_reset = on_reset
        self.rejections = Rejections(cfg.log_throttle_s)
        self.gate = SequenceGate(cfg.window_s, cfg.confirm_count, silence_s=cfg.restart_silence_s)
        self.buffer = LockstepBuffer(cfg.window_steps)
        self.latest: dict[str, Any] = {'state': None, 'weather': None, 'traffic': None}
        """realtime: the newest accepted message of each input."""
        self.received_s: dict[str, float | None] = {'state': None, 'weather': None, 'traffic': None}
        """Wall-clock time each input was last accepted [s] (for the input ages)."""
        self.n_resets = 0
        self.last_rt_k: int | None = None
        """realtime: the control step of the last step handed out."""
        self.rt_due = False

    def configure(self, cfg: ControllerNodeConfig) -> None:
        """Apply run-time parameter changes (the throttle; the other limits are read per message)."""
        self.cfg = cfg
        self.rejections.throttle_s = cfg.log_throttle_s

    def clear(self) -> None:
        """Forget every input (a new drive, or activation after an inactive span)."""
        self.gate.reset()
        self.buffer.reset()
        self.latest = dict.fromkeys(self.latest)
        self.last_rt_k, self.rt_due = None, False

    def reject(self, topic: str, what: str, reason: str, now_s: float) -> None:
        """Count a rejected message (``what``: e.g. 'step 12') and log it unless throttled."""
        line = self.rejections.add(topic, reason_kind(reason), f'rejected {topic} {what}: {reason}', now_s)
        if line:
            self._log('warn', line)

    # ----------------------------------------------------------------- states
    def offer_state(self, msg, wall_s: float, clock_s: float) -> bool:
        """A CabinState; True when accepted (lockstep: then see :meth:`ready`)."""
        cfg = self.cfg
        what = f'step {msg.step_index}'
        why = checks.check_state(msg)
        if why is None:
            if cfg.timing == 'lockstep':
                why = checks.check_stamp_equals('header.stamp', msg.header.stamp, msg.scenario_time_s)
            else:
                why = checks.check_stamp_age(
                    'header.stamp', msg.header.stamp, clock_s, cfg.max_state_age_s, cfg.max_clock_ahead_s
                )
        if why:
            self.reject(TOPIC_STATE, what, why, wall_s)
            return False
        verdict = self.gate.offer(msg.scenario_time_s, wall_s)
        if not verdict.accepted:
            self.reject(TOPIC_STATE, what, verdict.reason, wall_s)
            return False
        if verdict.reset:
            self.n_resets += 1
            self._log('warn', f'cabin/state {what}: {verdict.reason}: inputs and controller state reset')
            self.buffer.reset()
            self.latest = dict.fromkeys(self.latest)
            self.last_rt_k, self.rt_due = None, False
            self._on_reset()
        self.received_s['state'] = wall_s
        if cfg.timing == 'realtime':
            self.latest['state'] = msg
            return True
        k = control_step_index(msg.scenario_time_s, cfg.control_period_s)
        if k is None:
            return True  # between control steps
        why = self.buffer.put_state(k, msg, wall_s)
        if why:
            self.reject(TOPIC_STATE, what, why, wall_s)
            return False
        return True

    # --------------------------------------------------------------- previews
    def offer_preview(self, kind: str, msg, wall_s: float) -> bool:
        """A WeatherPreview ('weather') or TrafficPreview ('traffic'); True when accepted."""
        cfg = self.cfg
        topic = _PREVIEW_TOPIC[kind]
        what = f'step {msg.step_index}'
        why = checks.check_preview(msg, kind, cfg.horizon_steps + 1, cfg.control_period_s)
        if why is None and cfg.timing == 'lockstep':
            why = checks.check_stamp_equals('start', msg.start, msg.step_index * cfg.control_period_s)
        if why is None and cfg.timing == 'realtime':
            why = self._covers_latest_state(msg)
        if why is None and cfg.timing == 'lockstep':
            why = self.buffer.put_preview(kind, int(msg.step_index), msg)
        if why:
            self.reject(topic, what, why, wall_s)
            return False
        self.received_s[kind] = wall_s
        if cfg.timing == 'realtime':
            self.latest[kind] = msg
            return True
        return True

    def _covers_latest_state(self, msg) -> str | None:
        state = self.latest['state']
        if state is None:
            return None
        t, ts = state.scenario_time_s, self.cfg.control_period_s
        start = s_from_stamp(msg.start)
        if start > t + self.cfg.window_s:
            return f'future: starts at {start:.9g} s, beyond the latest state time {t:.9g} s + {self.cfg.window_s} s'
        if start + (len(msg.valid) - 1) * ts < t:
            return f'stale: ends at {start + (len(msg.valid) - 1) * ts:.9g} s, before the latest state time {t:.9g} s'
        return None

    # ------------------------------------------------------------------ steps
    def ready(self) -> StepInputs | None:
        """lockstep: the waiting step with both previews, taken out of the buffer (call only when it is computed)."""
        k = self.buffer.ready()
        if k is None:
            return None
        state, w, s = self.buffer.take(k)
        why = checks.check_preview_pair(w, s)
        return StepInputs(k, state, None, None, f'previews rejected: {why}') if why else StepInputs(k, state, w, s)

    def overdue(self, wall_s: float) -> StepInputs | None:
        """lockstep: the waiting step when its previews did not come within ``preview_timeout_s``."""
        k = self.buffer.overdue(wall_s, self.cfg.preview_timeout_s)
        if k is None:
            return None
        state, w, s = self.buffer.take(k)
        missing = ' and '.join(kind for kind, m in (('weather', w), ('traffic', s)) if m is None)
        return StepInputs(k, state, None, None, f'no {missing} preview within {self.cfg.preview_timeout_s} s')

    def realtime_step(self, clock_s: float) -> tuple[StepInputs | None, str]:
        """realtime: the inputs of the step at ``clock_s`` [s, node clock], or (None, why not).

        One command per control step k = floor(t / Ts) of the latest state: when the timer fires
        while the latest state still belongs to the step already commanded (the timer is not
        synchronised with the plant), the step is *due* and is computed on the first state of
        the next control step (:meth:`due`).
        """
        state = self.latest['state']
        if state is None:
            return None, 'no valid cabin/state received yet'
        age = clock_s - s_from_stamp(state.header.stamp)
        if age > self.cfg.max_state_age_s:
            return None, f'the latest cabin/state is {age:.1f} s old (limit {self.cfg.max_state_age_s} s)'
        k = self._k(state)
        if self.last_rt_k is not None and k <= self.last_rt_k:
            self.rt_due = True
            return None, ''
        self.last_rt_k, self.rt_due = k, False
        w, s = self.latest['weather'], self.latest['traffic']
        if w is None or s is None:
            missing = ' and '.join(kind for kind in ('weather', 'traffic') if self.latest[kind] is None)
            return StepInputs(k, state, None, None, f'no valid {missing} preview received'), ''
        why = checks.check_preview_pair(w, s)
        if why:
            return StepInputs(k, state, None, None, why), ''
        return StepInputs(k, state, w, s), ''

    def due(self) -> bool:
        """realtime: a timer tick is waiting for the first state of a new control step, which is here."""
        state = self.latest['state']
        return self.rt_due and state is not None and (self.last_rt_k is None or self._k(state) > self.last_rt_k)

    def _k(self, state) -> int:
        return control_step_of(state.scenario_time_s, self.cfg.control_period_s)

    def ages_s(self, wall_s: float) -> dict[str, float | None]:
        """Wall-clock age of each input's last accepted message [s] (None: none yet)."""
        return {k: (None if t is None else wall_s - t) for k, t in self.received_s.items()}


class ControllerRecord:
    """What the controller node reports: its last step, counts, QoS events (pure bookkeeping)."""

    def __init__(self):
        self.last: dict | None = None
        """The last step (see :func:`controller_health`), None before the first."""
        self.counts = dict.fromkeys(('steps', 'fallback_steps', 'steps_without_previews', 'step_errors'), 0)
        self.events = {'incompatible_qos': 0}
        self._reported = 0

    def step(self, k: int, step_time_ms: float, diag, no_previews: str) -> None:
        """A computed step (``diag``: the core's Diagnostics)."""
        self.counts['steps'] += 1
        self.counts['fallback_steps'] += bool(diag.fallback)
        self.counts['steps_without_previews'] += bool(no_previews)
        self.last = {
            'k': k,
            'step_time_ms': step_time_ms,
            'solve_time_ms': diag.solve_time_ms,
            'fallback': diag.fallback,
            'reason': diag.message,
            'no_previews': no_previews,
        }

    def error(self, k: int, err: Exception) -> None:
        """A step that raised."""
        self.counts['step_errors'] += 1
        self.last = {'k': k, 'error': repr(err)}

    def health(
        self,
        lifecycle: str,
        cfg: ControllerNodeConfig,
        inputs: ControllerInputs,
        wall_s: float,
        deadline_s: float | None = None,
    ) -> Health:
        """:func:`controller_health` of now; the rejections since the previous call are the new ones."""
        rej = inputs.rejections
        new, self._reported = rej.total - self._reported, rej.total
        return controller_health(
            lifecycle=lifecycle,
            cfg=cfg,
            last=self.last,
            counts=dict(self.counts, resets=inputs.n_resets),
            ages_s=inputs.ages_s(wall_s),
            rejections=rej,
            new_rejections=new,
            events=self.events,
            deadline_s=deadline_s,
        )


def controller_health(
    *,
    lifecycle: str,
    cfg: ControllerNodeConfig,
    last: dict | None,
    counts: dict,
    ages_s: dict,
    rejections: Rejections,
    new_rejections: int,
    events: dict,
    deadline_s: float | None = None,
) -> Health:
    """The controller's status for /diagnostics.

    Args:
        lifecycle: 'unconfigured', 'inactive', 'active' or 'finalized'.
        cfg: the configuration.
        last: the last step: ``k``, ``step_time_ms`` (whole step), ``solve_time_ms``, ``fallback``
            ('' / 'shifted_plan' / 'baseline'), ``reason``, ``no_previews`` (why, or ''); None before the first.
        counts: ``steps``, ``fallback_steps``, ``steps_without_previews``, ``resets``.
        ages_s: wall-clock age of the last accepted state/weather/traffic [s] (None: none yet).
        rejections: the rejection counts.
        new_rejections: rejections since the previous report [-].
        events: QoS event counts (``incompatible_qos``).
        deadline_s: the whole step's deadline [s]: the controller's own step budget (the NMPC's
            ``SolverSettings.step_budget_s``) when it has one, else (None) the control period.
    """
    h = Health()
    h.set('lifecycle', lifecycle).set('strategy', cfg.strategy).set('timing', cfg.timing)
    deadline_ms = (cfg.control_period_s if deadline_s is None else min(deadline_s, cfg.control_period_s)) * 1e3
    h.set('deadline_ms', deadline_ms)
    if lifecycle != 'active':
        h.warn(f'{lifecycle}: not commanding (the plant\'s fallback law drives)')
    elif last is None:
        h.warn(
            'active, no step computed yet (waiting for a valid cabin/state'
            + (' and previews)' if cfg.timing == 'lockstep' else ')')
        )
    if last is not None:
        h.set('last_step', last['k']).set('step_time_ms', last.get('step_time_ms'))
        h.set('solve_time_ms', last.get('solve_time_ms')).set('fallback', last.get('fallback') or 'none')
        step_ms = last.get('step_time_ms')
        if step_ms is not None and step_ms > deadline_ms:
            h.error(f'step {last["k"]} took {step_ms:.1f} ms, beyond the step deadline ({deadline_ms:.4g} ms)')
        elif step_ms is not None and step_ms > cfg.solve_time_warn_fraction * deadline_ms:
            h.warn(
                f'step {last["k"]} took {step_ms:.1f} ms, above {cfg.solve_time_warn_fraction:.0%} of '
                f'the step deadline ({deadline_ms:.4g} ms)'
            )
        if last.get('fallback') == 'baseline':
            h.error(f'fallback at step {last["k"]}: production ACC law applied ({last.get("reason", "")})')
        elif last.get('fallback'):
            h.warn(f'fallback at step {last["k"]}: {last["fallback"]} ({last.get("reason", "")})')
        if last.get('error'):
            h.error(f'step {last["k"]} failed: {last["error"]}: no command')
        if last.get('no_previews'):
            h.warn(f'step {last["k"]} planned without previews: {last["no_previews"]}')
    for key in ('steps', 'fallback_steps', 'steps_without_previews', 'step_errors', 'resets'):
        h.set(key, counts.get(key, 0))
    for name, age in ages_s.items():
        h.set(f'{name}_age_s', age)
    if lifecycle == 'active' and cfg.timing == 'realtime':
        age = ages_s.get('state')
        if age is not None and age > cfg.max_state_age_s:
            h.error(f'no valid cabin/state for {age:.1f} s (limit {cfg.max_state_age_s} s)')
    h.set('rejected_total', rejections.total)
    for topic, n in sorted(rejections.by_topic.items()):
        h.set(f'rejected {topic}', n)
    if new_rejections:
        h.warn(f'{new_rejections} input messages rejected since the last report ({rejections.summary()} in all)')
    for name, n in events.items():
        h.set(f'qos_{name}', n)
    if events.get('incompatible_qos'):
        h.error(f'{events["incompatible_qos"]} incompatible QoS events (a peer does not match)')
    return h


def warm_up(core, scenario, control_period_s: float, horizon_steps: int) -> str:
    """The one-time costs of a first solve, paid before the node takes control; returns how.

    The NMPC's own key-on API when the core has it (``NmpcController.warm_up``: a nominal
    instance through every solver of its chain, also through the estimator wrapper), else one
    throw-away step on the scenario's key-on state (perfect previews); then ``core.reset()``, so
    no state of it survives. Called in the lifecycle configure transition. A nominal NMPC solve that
    was not usable is said in the answer (the node's "configured" line): the first steps then solve
    cold, or fall back, as any step whose solve fails.
    """
    if callable(getattr(core, 'warm_up', None)):
        core.warm_up()
        core.reset()
        problem = getattr(core, 'warm_up_problem', None)
        return 'NmpcController.warm_up' + ('' if problem is None else f' (its nominal solve not usable: {problem})')
    from ceco_core.contracts import MDOT_BL_MAX_KGPS, T_EVAP_SP_MIN_C, AcInput
    from ceco_v2x_preview.preview import PreviewQuality, make_previews

    from .observation import observation

    ini = scenario.initial
    meas = {
        't_cab_c': ini.t_cab_c,
        't_int_c': ini.t_int_c,
        't_shell_c': ini.t_shell_c,
        't_glass_c': ini.t_glass_c,
        't_evap_c': ini.t_evap_c,
        't_vent_c': ini.t_evap_c,
        'rh_cab': ini.rh_cab,
    }
    prev = AcInput(mdot_bl_kgps=MDOT_BL_MAX_KGPS, t_evap_sp_c=T_EVAP_SP_MIN_C)
    previews = make_previews(scenario, 0.0, control_period_s, horizon_steps + 1, PreviewQuality())
    core.compute(observation(0, 0.0, meas, scenario.env_at(0.0), prev, previews, scenario))
    core.reset()
    return 'a key-on step'
