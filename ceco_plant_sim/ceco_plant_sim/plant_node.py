"""plant_node: the cabin + A/C plant as a node.

Publishes ``cabin/state`` (one per plant step),
``cabin/comfort``, ``hvac/power``, ``/clock`` (lockstep) and ``/diagnostics``; takes
``hvac/command``.

Per plant step it calls the simulator's own core (``ScenarioPlant.step``: PMV at t_n from the
measurements at t_n and the command held over [t_n, t_n + dt), plant step with the truth
environment at t_n), so a DDS run equals ``closed_loop.simulate``.

Timing: ``lockstep``: once its subscribers are matched it publishes the state at t_k and waits
for the command of step k, then advances Ts / dt plant steps; without a command within
``lockstep.command_timeout_s`` (wall clock) the production ACC law drives that period.
``realtime``: a timer every dt of the node clock applies the latest command; when it is older
than ``fallback.command_timeout_periods`` control periods (watchdog) or the requested QoS
deadline on hvac/command is missed, the ACC law takes over until commands resume. Which
command applies, and the health rules: the pure :mod:`ceco_plant_sim.plant_io`.
"""
from __future__ import annotations

from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg

from ceco_core.acc_law import AccLaw
from ceco_core.comfort import iso7730_validity
from ceco_core.contracts import AcInput
from ceco_core.supervision import FallbackSupervisor, Watchdog
from ceco_msgs.msg import AcCommand, AcPower, CabinState, Comfort
from ceco_plant_sim.plant_io import PLANT_PARAMETERS, CommandPolicy, PlantNodeConfig, plant_health
from ceco_plant_sim.scenario_plant import ScenarioPlant, n_plant_steps, steps_per_control
from ceco_ros import conversions, interfaces, params
from ceco_ros.diagnostics import DiagnosticsTimer
from ceco_ros.node_base import NodeTools
from ceco_ros.node_main import run_node
from ceco_v2x_preview.scenario import load_scenario_param


class PlantNode(NodeTools, Node):
    """Cabin + A/C plant simulation."""

    def __init__(self):
        super().__init__('plant_node')
        cfg = self.config = PlantNodeConfig.from_params(params.declare_all(self, PLANT_PARAMETERS))
        params.on_set(self, PLANT_PARAMETERS, self._set_params)
        self.setup_tools(cfg.log_throttle_s)
        self.scenario = sc = load_scenario_param(cfg.scenario)
        self.sp, self.dt = ScenarioPlant(sc, cfg.plant_dt_s), cfg.plant_dt_s
        self.m = steps_per_control(cfg.control_period_s, cfg.plant_dt_s)
        self.n_steps = n_plant_steps(min(cfg.duration_s or sc.duration_s, sc.duration_s), self.dt)
        self.e_comp_j = self.e_blower_j = 0.0
        self.acc, self.fallback = AccLaw(), FallbackSupervisor()
        self.policy = CommandPolicy(cfg, self.log)
        rt = cfg.timing == 'realtime'
        self.cmd_wd = Watchdog(cfg.command_timeout_rt_s if rt else cfg.command_timeout_s)
        self.started = self.finished = False
        self._latest, self._u, self._u_fb, self._deadline_missed, self._reported = None, None, True, False, 0
        self._events = {'deadline_missed': 0, 'incompatible_qos': 0}
        out_qos = interfaces.state_qos(cfg.timing)
        self.pub_state = self.create_publisher(CabinState, interfaces.TOPIC_STATE, out_qos,
                                               qos_overriding_options=interfaces.qos_overrides())
        self.pub_comfort = self.create_publisher(Comfort, interfaces.TOPIC_COMFORT, out_qos)
        self.pub_power = self.create_publisher(AcPower, interfaces.TOPIC_POWER, out_qos)
        self.pub_clock = self.create_publisher(ClockMsg, interfaces.TOPIC_CLOCK, interfaces.QOS_CLOCK)
        self.sub_cmd = self.create_subscription(
            AcCommand, interfaces.TOPIC_COMMAND, self._on_command,
            interfaces.command_qos(cfg.timing, cfg.command_timeout_rt_s),
            event_callbacks=SubscriptionEventCallbacks(deadline=self._on_deadline,
                                                       incompatible_qos=lambda _e: self._event('incompatible_qos')),
            qos_overriding_options=interfaces.qos_overrides(deadline=rt))
        self.create_timer(self.dt, self._on_tick) if rt else self.create_timer(0.02, self._on_watchdog,
                                                                                 clock=self.steady)
        DiagnosticsTimer(self, self._health, cfg.diagnostics_period_s)
        self.get_logger().info(f'scenario {sc.name}: {self.n_steps} plant steps of {self.dt} s, '
                               f'Ts {cfg.control_period_s} s, timing {cfg.timing}')

    @property
    def n(self) -> int:
        """Current plant step index (measurements at t_n)."""
        return self.sp.n

    def _stamp(self, n: int):
        return conversions.stamp_from_s(n * self.dt) if self.config.timing == 'lockstep' else \
            self.get_clock().now().to_msg()

    def _publish_state(self) -> None:
        t, stamp = self.n * self.dt, self._stamp(self.n)
        if self.config.timing == 'lockstep':
            self.pub_clock.publish(ClockMsg(clock=stamp))
        self.pub_state.publish(conversions.state_msg(self.n, t, stamp, self.sp.meas, self.scenario.env_at(t),
                                                     self.sp.cmd, self.fallback.in_fallback))
        self.policy.published(stamp, t)

    def _plant_step(self, u: AcInput, fallback: bool) -> None:
        """One plant step n with u held (the simulator's core step), then comfort and power."""
        stamp = self._stamp(self.n)
        r = self.sp.step(u)
        self.e_comp_j += r.out.e_comp_j
        self.e_blower_j += r.out.e_blower_j
        c, meas = self.sp.comfort, r.meas
        valid = bool(iso7730_validity(c.air_temperature_c(meas['t_cab_c'], meas['t_vent_c']), meas['t_int_c'],
                                      c.air_speed_mps(u.mdot_bl_kgps), c.pa_pa if c.pa_pa is not None else 0.0,
                                      c.met, c.clo, r.pmv).all)
        self.pub_comfort.publish(conversions.comfort_msg(r.n, stamp, r.pmv, r.ppd, r.pmv_lb, r.pmv_ub, meas, u,
                                                         r.env.solar_wm2, c.met, c.clo, valid))
        self.pub_power.publish(conversions.power_msg(r.n, stamp, self.dt, u, r.out, self.e_comp_j,
                                                     self.e_blower_j, fallback))
        if self.n >= self.n_steps:
            self.finished = True
            self.get_logger().info(f'scenario complete: {self.n} plant steps, E_comp {self.e_comp_j:.0f} J, '
                                   f'E_blower {self.e_blower_j:.0f} J')
        else:
            self._publish_state()

    def _fallback_command(self, why: str) -> AcInput:
        line = self.fallback.command_missing(f'step {self.n} (t={self.n * self.dt:.1f} s)', why)
        if line:
            self.acc.reset()
            self.get_logger().warn(line)
        a = self.acc.step(self.sp.meas['t_cab_c'], self.config.control_period_s)
        return AcInput(mdot_bl_kgps=a.mdot_bl_kgps, t_evap_sp_c=a.t_evap_sp_c)

    def _ready(self) -> bool:
        cfg = self.config
        outs = (self.pub_comfort, self.pub_power, self.pub_clock)
        return (self.pub_state.get_subscription_count() >= cfg.min_state_subscribers
                and all(p.get_subscription_count() >= cfg.min_output_subscribers for p in outs)
                and self.count_subscribers(interfaces.TOPIC_COMMAND) >= cfg.min_command_subscribers
                and (self.sub_cmd.get_publisher_count() >= 1 or cfg.min_state_subscribers == 0))

    def _start(self) -> bool:
        if not self.started and not self._ready():
            return False
        if not self.started:
            self.started = True
            self.get_logger().info('subscribers matched: starting at step 0')
            self._publish_state()
            self.cmd_wd.kick(self.wall_s())
        return True

    # --------------------------------------------------------------- lockstep
    def _control_period(self, u: AcInput, fallback: bool) -> None:
        for _ in range(self.m):
            self._plant_step(u, fallback)
            if self.finished:
                return
        self.cmd_wd.kick(self.wall_s())

    def _on_watchdog(self) -> None:
        if self.finished or not self._start() or not self.cmd_wd.expired(self.wall_s()):
            return
        why = f'no command for control step {self.n // self.m} within {self.config.command_timeout_s} s (wall clock)'
        self._control_period(self._fallback_command(why), True)

    def _on_command(self, msg: AcCommand) -> None:
        if self.finished or not self.started:
            return
        if not self.policy.accept(msg, self.n // self.m, self.wall_s()):
            return
        u = conversions.command_input(msg)
        line = self.fallback.command_accepted(int(msg.step_index), msg.strategy)
        if line:
            self.get_logger().info(line)
        if self.config.timing == 'realtime':
            self._latest, self._deadline_missed = u, False
            self.cmd_wd.kick(self.clock_s())
        else:
            self._control_period(u, False)

    # --------------------------------------------------------------- realtime
    def _on_tick(self) -> None:
        if self.finished or not self._start():
            return
        fresh = self._latest is not None and not self.cmd_wd.expired(self.clock_s()) and not self._deadline_missed
        # a new command is taken at control steps; a stale one is dropped at once
        if self.n % self.m == 0 or (not fresh and not self.fallback.in_fallback):
            if fresh:
                self._u, self._u_fb = self._latest, False
            else:
                age = self.cmd_wd.age(self.clock_s())
                why = 'QoS deadline on hvac/command missed' if self._deadline_missed else \
                    f'no fresh command (latest {"none yet" if age == float("inf") else f"{age:.1f} s old"}, ' \
                    f'limit {self.config.command_timeout_rt_s:.1f} s)'
                self._u, self._u_fb = self._fallback_command(why), True
        self._plant_step(self._u, self._u_fb)

    # ------------------------------------------------------------------- glue
    def _on_deadline(self, _event) -> None:
        self._deadline_missed = True
        self._event('deadline_missed')

    def _event(self, name: str) -> None:
        self._events[name] += 1
        self.notice(name, f'QoS event on hvac/command: {name} (total {self._events[name]})')

    def _set_params(self, changes: dict) -> str | None:
        try:
            self.config = self.config.replaced(changes)
        except ValueError as err:
            return str(err)
        self.policy.cfg = self.config
        self.policy.rejections.throttle_s = self.notices.throttle_s = self.config.log_throttle_s
        if self.config.timing == 'lockstep':
            self.cmd_wd.timeout_s = self.config.command_timeout_s
        return None

    def _health(self):
        rej = self.policy.rejections
        new, self._reported = rej.total - self._reported, rej.total
        age = self.cmd_wd.age(self.wall_s() if self.config.timing == 'lockstep' else self.clock_s())
        return [('plant', plant_health(cfg=self.config, started=self.started, finished=self.finished, n=self.n,
                                       t_s=self.n * self.dt, supervisor=self.fallback, policy=self.policy,
                                       command_age_s=None if age == float('inf') else age,
                                       new_rejections=new, events=self._events))]


def main(args=None) -> int:
    """Entry point of the plant_node executable."""
    return run_node(PlantNode, args, 'plant_node')


if __name__ == '__main__':
    raise SystemExit(main())
