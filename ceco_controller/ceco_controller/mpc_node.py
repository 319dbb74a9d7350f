"""mpc_node: a CECO NMPC strategy (ceco, ceco-e, ceco-c, ceco-ioch) as a node;
baseline_node reuses this node class with the production ACC law.

Inputs: ``cabin/state`` (CabinState), ``v2x/weather_preview``,
``v2x/traffic_preview``. Outputs: ``hvac/command`` (AcCommand, tagged with
the control step index k) and ``controller/diagnostics``.

Timing (parameter ``timing``):
* ``lockstep``: event driven. When the state for t_k = k * Ts *and* both
  previews issued for step k are at hand, compute once and publish command k.
  No clock is involved, so the run is deterministic however slow a process
  is. If the previews of step k do not come within ``preview_timeout_s``
  (wall clock), the step is solved without previews (the core degrades to
  the measured values), with a warning.
* ``realtime``: a timer every Ts on the node clock computes from the latest
  state (rejected when older than ``max_state_age_s``) and previews.

Glue only: the observation is built by the same core function as in the
closed-loop simulator (``ceco_controller.observation.observation``, from the
messages via ``conversions.previews``), and the same core object
(``ceco_controller.factory.make_controller``) computes the command.
"""
from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from ceco_controller.observation import observation
from ceco_core.contracts import CECO_STRATEGIES, AcInput
from ceco_core.control_grid import control_step_index
from ceco_msgs.msg import AcCommand, CabinState, ControllerDiagnostics, TrafficPreview, WeatherPreview
from ceco_ros import conversions, interfaces, params
from ceco_ros.node_main import run_node
from ceco_v2x_preview.scenario import load_scenario_param

TIMING_MODES = interfaces.TIMING_MODES


@dataclasses.dataclass(frozen=True)
class ControllerNodeConfig:
    """Validated parameters of mpc_node / baseline_node."""

    strategy: str
    """baseline, ceco, ceco-e, ceco-c or ceco-ioch."""
    scenario: str
    """Scenario: the occupant (met, clo) and the PMV comfort bounds (the occupant's settings)."""
    timing: str
    """lockstep or realtime."""
    control_period_s: float
    """Control period Ts [s]."""
    horizon_steps: int
    """Prediction horizon Np [steps]."""
    preview_timeout_s: float
    """lockstep: wall-clock wait for the previews of a step before solving without them [s]."""
    max_state_age_s: float
    """realtime: oldest usable state [s]."""
    controller_config: str = ''
    """NMPC settings file ('' : the package's config/controller.yaml)."""

    def validate(self) -> None:
        allowed = CECO_STRATEGIES + ('baseline',)
        if self.strategy not in allowed:
            raise ValueError(f'invalid parameter strategy={self.strategy!r}: unknown strategy, '
                             f'must be one of {", ".join(CECO_STRATEGIES)}')
        if self.timing not in TIMING_MODES:
            raise ValueError(f'invalid parameter timing={self.timing!r}: must be one of {TIMING_MODES}')


class ControllerNode(Node):
    """Supervisory A/C controller node (one strategy)."""

    def __init__(self, node_name: str = 'mpc_node', fixed_strategy: str | None = None):
        super().__init__(node_name)
        self.config = self._read_config(fixed_strategy)
        cfg = self.config
        self.scenario = load_scenario_param(cfg.scenario)
        self.core = make_core(cfg.strategy, self.scenario, cfg.control_period_s, cfg.horizon_steps,
                              cfg.controller_config or None)
        self.n_grid = cfg.horizon_steps + 1
        self._states: dict[int, CabinState] = {}
        self._weather: dict[int, WeatherPreview] = {}
        self._traffic: dict[int, TrafficPreview] = {}
        self._state_wall: dict[int, float] = {}
        self._last_k = -1
        self._prev_cmd = None
        self._latest_state = None
        self._k_rt = 0
        # publishers/subscriptions last: once they are discovered the node is ready
        self._pub_cmd = self.create_publisher(AcCommand, interfaces.TOPIC_COMMAND, interfaces.QOS_COMMAND)
        self._pub_diag = self.create_publisher(ControllerDiagnostics, interfaces.TOPIC_DIAGNOSTICS, interfaces.QOS_COMMAND)
        self.create_subscription(CabinState, interfaces.TOPIC_STATE, self._on_state, interfaces.QOS_STATE)
        self.create_subscription(WeatherPreview, interfaces.TOPIC_WEATHER, self._on_weather, interfaces.QOS_PREVIEW)
        self.create_subscription(TrafficPreview, interfaces.TOPIC_TRAFFIC, self._on_traffic, interfaces.QOS_PREVIEW)
        if cfg.timing == 'lockstep':
            self._steady = Clock(clock_type=ClockType.STEADY_TIME)
            self.create_timer(0.05, self._on_watchdog, clock=self._steady)
        else:
            self.create_timer(cfg.control_period_s, self._on_timer)
        self.get_logger().info(f'strategy {cfg.strategy}, Ts {cfg.control_period_s} s, Np {cfg.horizon_steps}, '
                               f'timing {cfg.timing}, scenario {self.scenario.name}')

    def _read_config(self, fixed_strategy) -> ControllerNodeConfig:
        d = params.declare
        if fixed_strategy is None:
            strategy = d(self, 'strategy', 'ceco-ioch',
                         'CECO strategy: ceco (general), ceco-e (energy), ceco-c (comfort), '
                         'ceco-ioch (speed-aware slack)')
            if strategy not in CECO_STRATEGIES:
                raise ValueError(f'invalid parameter strategy={strategy!r}: unknown strategy, '
                                 f'must be one of {", ".join(CECO_STRATEGIES)}')
        else:
            strategy = fixed_strategy
        cfg = ControllerNodeConfig(
            strategy=strategy,
            scenario=d(self, 'scenario', 'sc03', 'scenario name or YAML path: occupant (met, clo) and '
                       'PMV comfort bounds'),
            timing=d(self, 'timing', 'lockstep', 'lockstep (event driven, deterministic) or realtime '
                     '(timer every Ts on the node clock)', choices=TIMING_MODES),
            control_period_s=d(self, 'control_period_s', 5.0, 'control period Ts [s]',
                               float_range=(0.1, 3600.0)),
            horizon_steps=d(self, 'horizon_steps', 6, 'prediction horizon Np [steps]', int_range=(1, 200)),
            preview_timeout_s=d(self, 'preview_timeout_s', 2.0, 'lockstep: wall-clock wait for the previews '
                                'of a step before solving without them [s]', float_range=(0.01, 600.0)),
            max_state_age_s=d(self, 'max_state_age_s', 10.0, 'realtime: oldest usable cabin state [s]',
                              float_range=(0.01, 3600.0)),
            controller_config=d(self, 'controller_config', '', 'NMPC settings file (solver, weights, '
                                'bounds; empty: the package\'s config/controller.yaml)'),
        )
        cfg.validate()
        return cfg

    # ---------------------------------------------------------------- inputs
    def _on_state(self, msg: CabinState) -> None:
        err = conversions.check_state(msg)
        if err:
            self.get_logger().error(f'rejected cabin/state step {msg.step_index}: {err}')
            return
        if self.config.timing == 'realtime':
            self._latest_state = msg
            return
        k = control_step_index(msg.scenario_time_s, self.config.control_period_s)
        if k is None:
            return  # between control steps
        if k <= self._last_k:
            self.get_logger().warn(f'rejected cabin/state for step {k}: stale (step {self._last_k} done)')
            return
        self._states[k] = msg
        self._state_wall[k] = time.monotonic()
        self._try(k)

    def _check_preview(self, msg, kind: str) -> str | None:
        arrays = (msg.t_amb_c, msg.solar_wm2, msg.rh, msg.valid) if kind == 'weather' else (msg.speed_mps, msg.valid)
        lengths = {len(a) for a in arrays}
        if lengths != {self.n_grid}:
            return f'arrays of lengths {sorted(lengths)}, expected {self.n_grid} (Np + 1) each'
        ts = self.config.control_period_s
        if not (math.isfinite(msg.step_s) and abs(msg.step_s - ts) <= 1e-9 * ts):
            return f'step_s={msg.step_s!r}, expected the control period {ts}'
        valid = np.asarray(msg.valid, dtype=bool)
        for a in arrays[:-1]:
            x = np.asarray(a, dtype=float)
            if np.any(np.isinf(x)) or np.any(np.isnan(x[valid])):
                return 'non-finite value where marked valid'
        return None

    def _on_preview(self, msg, kind: str, store: dict) -> None:
        err = self._check_preview(msg, kind)
        if err:
            self.get_logger().error(f'rejected v2x/{kind}_preview step {msg.step_index}: {err}')
            return
        if self.config.timing == 'realtime':
            store.clear()
            store[0] = msg
            return
        k = int(msg.step_index)
        if k <= self._last_k:
            self.get_logger().warn(f'rejected v2x/{kind}_preview for step {k}: stale (step {self._last_k} done)')
            return
        store[k] = msg
        self._try(k)

    def _on_weather(self, msg: WeatherPreview) -> None:
        self._on_preview(msg, 'weather', self._weather)

    def _on_traffic(self, msg: TrafficPreview) -> None:
        self._on_preview(msg, 'traffic', self._traffic)

    # ----------------------------------------------------------------- steps
    def _try(self, k: int) -> None:
        if k in self._states and k in self._weather and k in self._traffic:
            self._step(k, self._states[k], self._weather[k], self._traffic[k])

    def _on_watchdog(self) -> None:
        now = time.monotonic()
        for k in sorted(self._states):
            if k > self._last_k and now - self._state_wall[k] > self.config.preview_timeout_s:
                self.get_logger().warn(f'no previews for step {k} within {self.config.preview_timeout_s} s: '
                                       'solving without previews')
                self._step(k, self._states[k], None, None)

    def _on_timer(self) -> None:
        s = self._latest_state
        if s is None:
            return
        age = (self.get_clock().now().nanoseconds * 1e-9) - conversions.s_from_stamp(s.header.stamp)
        if age > self.config.max_state_age_s:
            self.get_logger().warn(f'rejected cabin/state step {s.step_index}: stale ({age:.1f} s old)')
            return
        w, t = self._weather.get(0), self._traffic.get(0)
        self._step(self._k_rt, s, w, t)
        self._k_rt += 1

    def _step(self, k: int, state: CabinState, w, s) -> None:
        ts = self.config.control_period_s
        t_s = state.scenario_time_s  # n * dt, exactly the simulator's t
        if w is not None and s is not None:
            err = conversions.check_previews(w, s, self.n_grid, ts)
            if err:
                self.get_logger().error(f'rejected previews for step {k}: {err}')
                w = s = None
        if w is not None and s is not None and self.config.timing == 'realtime':
            aligned = conversions.align_previews(w, s, t_s, ts)
            if aligned is None:
                self.get_logger().warn(f'previews starting at {conversions.s_from_stamp(w.start):.1f} s do not cover '
                                       f't = {t_s:.1f} s: solving without previews')
            w, s = aligned if aligned is not None else (None, None)
        if w is None or s is None:
            w, s = conversions.empty_previews(self.n_grid, ts)
        # the previous command: the plant's (key-on command) until this node has commanded
        prev = self._prev_cmd or AcInput(mdot_bl_kgps=state.mdot_bl_kgps, t_evap_sp_c=state.t_evap_sp_c)
        meas = conversions.state_measurements(state)
        obs = observation(k, t_s, meas, state, prev, conversions.previews(w, s, t_s, ts), self.scenario)
        cmd, diag = self.core.compute(obs)
        self._prev_cmd = cmd
        stamp = state.header.stamp
        fallback = bool(diag.fallback)
        self._pub_cmd.publish(conversions.command_msg(cmd, k, stamp, ts, self.config.strategy, fallback))
        self._pub_diag.publish(conversions.diagnostics_msg(diag, stamp, self.config.strategy, ts))
        if fallback:
            self.get_logger().warn(f'step {k}: fallback {diag.fallback}: {diag.message}')
        self._last_k = max(self._last_k, k)
        for store in (self._states, self._weather, self._traffic, self._state_wall):
            for old in [j for j in store if j <= self._last_k]:
                del store[old]


def make_core(strategy: str, scenario, control_period_s: float, horizon_steps: int,
              config_path: str | None = None):
    """The controller core, built as the closed-loop simulator builds it."""
    from ceco_controller import factory
    return factory.make_controller(strategy, scenario, control_period_s=control_period_s,
                                       horizon_steps=horizon_steps, config_path=config_path)


def main(args=None) -> int:
    return run_node(ControllerNode, args, 'mpc_node')


if __name__ == '__main__':
    raise SystemExit(main())
