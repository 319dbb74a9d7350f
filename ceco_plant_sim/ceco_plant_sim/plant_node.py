"""plant_node: the cabin + A/C plant as a node. Publishes ``cabin/state`` (one
CabinState per plant step), ``cabin/comfort`` (modified PMV, computed here),
``hvac/power`` and the simulation time on ``/clock``; takes ``hvac/command``.

Per plant step n (t_n = n * dt) it calls the same core as the closed-loop
simulator (ceco_controller.closed_loop.simulate):
``ceco_plant_sim.scenario_plant.ScenarioPlant`` (key-on state and command,
PMV at t_n from the measurements at t_n and the command held over
[t_n, t_n + dt), plant.step over dt with the truth environment at t_n; the
outputs become the measurements at t_{n+1}).

Timing (parameter ``timing``):
* ``lockstep``: once its subscribers are matched, the plant publishes the
  state at t_k = k * Ts and waits for the AcCommand with step_index k; then
  it advances Ts / dt plant steps. A command for any other step is rejected
  as stale/future, so no step is lost or duplicated however slow a process
  is. If no command arrives within ``lockstep.command_timeout_s`` (wall
  clock), the plant applies the production ACC law (ceco_core.acc_law)
  for that control period, logs it, and keeps waiting for commands at every
  following step, so a restarted controller takes over again.
* ``realtime``: a timer every dt on the node clock steps the plant with the
  latest valid command; when the latest command is older than
  ``fallback.command_timeout_periods`` control periods, the ACC law takes
  over until commands resume.
"""
from __future__ import annotations

import dataclasses

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg

from ceco_core.acc_law import AccLaw
from ceco_core.contracts import AcInput
from ceco_msgs.msg import AcCommand, AcPower, CabinState, Comfort
from ceco_plant_sim.scenario_plant import ScenarioPlant, n_plant_steps, steps_per_control
from ceco_ros import conversions, interfaces, params
from ceco_ros.node_main import run_node
from ceco_v2x_preview.scenario import load_scenario_param

TIMING_MODES = interfaces.TIMING_MODES


@dataclasses.dataclass(frozen=True)
class PlantNodeConfig:
    """Validated parameters of plant_node."""

    scenario: str
    """Scenario name or YAML path (environment truth, initial state, occupant, bounds)."""
    timing: str
    """lockstep or realtime."""
    plant_dt_s: float
    """Plant step [s]."""
    control_period_s: float
    """Control period Ts [s]; a whole multiple of plant_dt_s."""
    duration_s: float
    """Run length [s]; 0 = the scenario's."""
    command_timeout_s: float
    """lockstep: wall-clock wait for a command before the fallback law [s]."""
    min_state_subscribers: int
    """lockstep: start once cabin/state has this many subscribers."""
    min_output_subscribers: int
    """lockstep: ... and every other output this many (a recorder)."""
    min_command_subscribers: int
    """lockstep: ... and hvac/command this many subscriptions in the graph (plant + recorder)."""
    command_timeout_periods: float
    """realtime: command age (in control periods) after which the fallback law applies."""

    def validate(self) -> None:
        if self.timing not in TIMING_MODES:
            raise ValueError(f'invalid parameter timing={self.timing!r}: must be one of {TIMING_MODES}')
        try:
            steps_per_control(self.control_period_s, self.plant_dt_s)
        except ValueError as err:
            raise ValueError(f'invalid parameter control_period_s={self.control_period_s}: {err}') from None


class PlantNode(Node):
    """Cabin + A/C plant simulation."""

    def __init__(self):
        super().__init__('plant_node')
        cfg = self.config = self._read_config()
        self.scenario = sc = load_scenario_param(cfg.scenario)
        self.sp = ScenarioPlant(sc, cfg.plant_dt_s)
        self.dt = cfg.plant_dt_s
        self.m = steps_per_control(cfg.control_period_s, cfg.plant_dt_s)
        duration = cfg.duration_s if cfg.duration_s > 0 else sc.duration_s
        self.n_steps = n_plant_steps(min(duration, sc.duration_s), self.dt)
        self.e_comp_j = 0.0
        self.e_blower_j = 0.0
        self.acc = AccLaw()
        self.in_fallback = False
        self.started = False
        self.finished = False
        self._latest_cmd = None      # realtime: (AcInput, strategy, receipt time [s])
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._wait_start = None
        self.pub_state = self.create_publisher(CabinState, interfaces.TOPIC_STATE, interfaces.QOS_STATE)
        self.pub_comfort = self.create_publisher(Comfort, interfaces.TOPIC_COMFORT, interfaces.QOS_STATE)
        self.pub_power = self.create_publisher(AcPower, interfaces.TOPIC_POWER, interfaces.QOS_STATE)
        self.pub_clock = self.create_publisher(ClockMsg, interfaces.TOPIC_CLOCK, interfaces.QOS_CLOCK)
        self.sub_cmd = self.create_subscription(AcCommand, interfaces.TOPIC_COMMAND, self._on_command, interfaces.QOS_COMMAND)
        if cfg.timing == 'lockstep':
            self.create_timer(0.02, self._on_watchdog, clock=self._steady)
        else:
            self.create_timer(self.dt, self._on_tick)
        self.get_logger().info(f'scenario {sc.name}: {self.n_steps} plant steps of {self.dt} s, '
                               f'Ts {cfg.control_period_s} s, timing {cfg.timing}')

    def _read_config(self) -> PlantNodeConfig:
        d = params.declare
        cfg = PlantNodeConfig(
            scenario=d(self, 'scenario', 'sc03', 'scenario name or YAML path (environment, initial state, '
                       'occupant, PMV bounds)'),
            timing=d(self, 'timing', 'lockstep', 'lockstep (advance a control period per command) or '
                     'realtime (timer every plant step on the node clock)', choices=TIMING_MODES),
            plant_dt_s=d(self, 'plant_dt_s', 1.0, 'plant step and recording interval [s]',
                         float_range=(0.01, 60.0)),
            control_period_s=d(self, 'control_period_s', 5.0, 'control period Ts [s], a whole multiple of '
                               'plant_dt_s', float_range=(0.01, 3600.0)),
            duration_s=d(self, 'duration_s', 0.0, 'run length [s]; 0 = the scenario\'s',
                         float_range=(0.0, 1e7)),
            command_timeout_s=d(self, 'lockstep.command_timeout_s', 5.0, 'lockstep: wall-clock wait for the '
                                'command of a step before the fallback ACC law applies [s]',
                                float_range=(0.01, 3600.0)),
            min_state_subscribers=d(self, 'lockstep.min_state_subscribers', 2, 'lockstep: cabin/state '
                                    'subscribers to wait for before step 0 [-]', int_range=(0, 100)),
            min_output_subscribers=d(self, 'lockstep.min_output_subscribers', 0, 'lockstep: subscribers of '
                                     'every other output to wait for before step 0 [-]', int_range=(0, 100)),
            min_command_subscribers=d(self, 'lockstep.min_command_subscribers', 1, 'lockstep: hvac/command '
                                      'subscriptions (this node included) to see in the graph before '
                                      'step 0 [-]', int_range=(0, 100)),
            command_timeout_periods=d(self, 'fallback.command_timeout_periods', 2.0, 'realtime: command '
                                      'age after which the fallback ACC law applies [control periods]',
                                      float_range=(0.1, 1000.0)),
        )
        cfg.validate()
        return cfg

    # ---------------------------------------------------------------- helpers
    @property
    def n(self) -> int:
        """Current plant step index (measurements at t_n)."""
        return self.sp.n

    def _t(self, n: int) -> float:
        return n * self.dt

    def _stamp(self, n: int):
        if self.config.timing == 'lockstep':
            return conversions.stamp_from_s(self._t(n))
        return self.get_clock().now().to_msg()

    def _publish_state(self) -> None:
        n = self.n
        t = self._t(n)
        stamp = self._stamp(n)
        if self.config.timing == 'lockstep':
            self.pub_clock.publish(ClockMsg(clock=stamp))
        self.pub_state.publish(conversions.state_msg(n, t, stamp, self.sp.meas, self.scenario.env_at(t),
                                                  self.sp.cmd, self.in_fallback))

    def _plant_step(self, u: AcInput, fallback: bool) -> None:
        """One plant step n with u held (the simulator's core step), then publish comfort and power."""
        stamp = self._stamp(self.n)
        r = self.sp.step(u)
        out, meas = r.out, r.meas
        self.e_comp_j += out.e_comp_j
        self.e_blower_j += out.e_blower_j
        c = self.sp.comfort
        self.pub_comfort.publish(conversions.comfort_msg(r.n, stamp, r.pmv, r.ppd, r.pmv_lb, r.pmv_ub, meas, u,
                                                      r.env.solar_wm2, c.met, c.clo, r.comfort.iso7730_valid,
                                                      series=r.comfort))
        self.pub_power.publish(conversions.power_msg(r.n, stamp, self.dt, u, out, self.e_comp_j,
                                                  self.e_blower_j, fallback))

    def _finish(self) -> None:
        self.finished = True
        self.get_logger().info(f'scenario complete: {self.n} plant steps, E_comp {self.e_comp_j:.0f} J, '
                               f'E_blower {self.e_blower_j:.0f} J')

    def _fallback_command(self) -> AcInput:
        a = self.acc.step(self.sp.meas['t_cab_c'], self.config.control_period_s)
        return AcInput(mdot_bl_kgps=a.mdot_bl_kgps, t_evap_sp_c=a.t_evap_sp_c)

    def _enter_fallback(self, why: str) -> None:
        if not self.in_fallback:
            self.in_fallback = True
            self.acc.reset()
            self.get_logger().warn(f'FALLBACK at step {self.n} (t={self._t(self.n):.1f} s): {why}; '
                                   'applying the production ACC law until commands resume')

    def _leave_fallback(self, k: int, strategy: str) -> None:
        if self.in_fallback:
            self.in_fallback = False
            self.get_logger().info(f'commands resumed at control step {k} from {strategy}: leaving fallback')

    # ---------------------------------------------------------------- lockstep
    def _control_period(self, u: AcInput, fallback: bool) -> None:
        """Advance one control period (Ts / dt plant steps) with u held."""
        for _ in range(self.m):
            self._plant_step(u, fallback)
            if self.n >= self.n_steps:
                self._finish()
                return
            self._publish_state()
        self._wait_start = self._steady.now()

    def _ready(self) -> bool:
        cfg = self.config
        if self.pub_state.get_subscription_count() < cfg.min_state_subscribers:
            return False
        outs = (self.pub_comfort, self.pub_power, self.pub_clock)
        if any(p.get_subscription_count() < cfg.min_output_subscribers for p in outs):
            return False
        if self.count_subscribers(interfaces.TOPIC_COMMAND) < cfg.min_command_subscribers:
            return False
        return self.sub_cmd.get_publisher_count() >= 1 or cfg.min_state_subscribers == 0

    def _on_watchdog(self) -> None:
        if self.finished:
            return
        if not self.started:
            if self._ready():
                self.started = True
                self.get_logger().info('subscribers matched: starting at step 0')
                self._publish_state()
                self._wait_start = self._steady.now()
            return
        waited = (self._steady.now() - self._wait_start).nanoseconds * 1e-9
        if waited > self.config.command_timeout_s:
            k = self.n // self.m
            self._enter_fallback(f'no command for control step {k} within {self.config.command_timeout_s} s '
                                 '(wall clock)')
            self._control_period(self._fallback_command(), True)

    def _on_command(self, msg: AcCommand) -> None:
        try:
            u = conversions.command_input(msg)
        except ValueError as err:
            self.get_logger().error(f'rejected hvac/command step {msg.step_index}: {err}')
            return
        if self.config.timing == 'realtime':
            self._latest_cmd = (u, msg.strategy, self.get_clock().now().nanoseconds * 1e-9)
            return
        if self.finished or not self.started:
            return
        k = self.n // self.m
        if msg.step_index != k:
            what = 'stale' if msg.step_index < k else 'future'
            self.get_logger().warn(f'rejected hvac/command step {msg.step_index}: {what} '
                                   f'(waiting for step {k})')
            return
        self._leave_fallback(k, msg.strategy)
        self._control_period(u, False)

    # ---------------------------------------------------------------- realtime
    def _on_tick(self) -> None:
        if self.finished:
            return
        if not self.started:
            if self._ready():
                self.started = True
                self._publish_state()
            return
        now = self.get_clock().now().nanoseconds * 1e-9
        limit = self.config.command_timeout_periods * self.config.control_period_s
        latest = self._latest_cmd
        fresh = latest is not None and now - latest[2] <= limit
        # a new command is taken at control steps; a stale one is dropped at once
        if self.n % self.m == 0 or (not fresh and not self.in_fallback):
            if fresh:
                self._leave_fallback(self.n // self.m, latest[1])
                self._rt_cmd, self._rt_fb = latest[0], False
            else:
                age = 'none yet' if latest is None else f'{now - latest[2]:.1f} s old'
                self._enter_fallback(f'no fresh command (latest {age}, limit {limit:.1f} s)')
                self._rt_cmd, self._rt_fb = self._fallback_command(), True
        self._plant_step(self._rt_cmd, self._rt_fb)
        if self.n >= self.n_steps:
            self._finish()
            return
        self._publish_state()


def main(args=None) -> int:
    return run_node(PlantNode, args, 'plant_node')


if __name__ == '__main__':
    raise SystemExit(main())
