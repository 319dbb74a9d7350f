"""plant_node: the cabin + A/C plant as a node.

Publishes ``cabin/state`` (one per plant step), ``cabin/comfort``, ``hvac/power``, ``/clock``
(lockstep) and ``/diagnostics``; takes ``hvac/command``. Per plant step it calls the
simulator's own core (``ScenarioPlant.step``), so a DDS run equals ``closed_loop.simulate``.

Timing: ``lockstep``: once its subscribers are matched it publishes the state at t_k and waits
for the command of step k, then advances Ts / dt plant steps; without a command within
``lockstep.command_timeout_s`` (wall clock) the production ACC law drives that period.
``realtime``: a timer every dt of the node clock applies the latest command; when it is older
than ``fallback.command_timeout_periods`` control periods, or the QoS deadline requested on
hvac/command is missed, the ACC law takes over until commands resume. Which command applies
and the health rules: the pure :mod:`ceco_plant_sim.plant_io`.
"""

from __future__ import annotations

from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg

import ceco_plant_sim.plant_io as pio
from ceco_core.contracts import AcInput
from ceco_core.supervision import Watchdog
from ceco_msgs.msg import AcCommand, AcPower, CabinState, Comfort
from ceco_plant_sim.plant_loop import PlantLoop
from ceco_ros import conversions, interfaces, params
from ceco_ros.diagnostics import DiagnosticsTimer
from ceco_ros.node_base import NodeTools
from ceco_ros.node_main import run_node
from ceco_v2x_preview.scenario import load_scenario_param


class PlantNode(NodeTools, Node):
    """Cabin + A/C plant simulation."""

    def __init__(self):
        super().__init__('plant_node')
        cfg = self.config = pio.PlantNodeConfig.from_params(params.declare_all(self, pio.PLANT_PARAMETERS))
        params.on_set(self, pio.PLANT_PARAMETERS, self._set_params)
        self.setup_tools(cfg.log_throttle_s)
        self.scenario = sc = load_scenario_param(cfg.scenario)
        self.loop, self.policy = PlantLoop(sc, cfg), pio.CommandPolicy(cfg, self.log)
        self.wait, self.started = Watchdog(cfg.command_timeout_s), False
        self._reported, self._events = 0, {'deadline_missed': 0, 'incompatible_qos': 0}
        rt, out_qos = cfg.timing == 'realtime', interfaces.state_qos(cfg.timing)
        self.pub_state = self.create_publisher(
            CabinState, interfaces.TOPIC_STATE, out_qos, qos_overriding_options=interfaces.qos_overrides()
        )
        self.pub_comfort = self.create_publisher(Comfort, interfaces.TOPIC_COMFORT, out_qos)
        self.pub_power = self.create_publisher(AcPower, interfaces.TOPIC_POWER, out_qos)
        self.pub_clock = self.create_publisher(ClockMsg, interfaces.TOPIC_CLOCK, interfaces.QOS_CLOCK)
        self.sub_cmd = self.create_subscription(
            AcCommand,
            interfaces.TOPIC_COMMAND,
            self._on_command,
            interfaces.command_qos(cfg.timing, cfg.command_timeout_rt_s),
            event_callbacks=SubscriptionEventCallbacks(
                deadline=lambda _e: self._event('deadline_missed'),
                incompatible_qos=lambda _e: self._event('incompatible_qos'),
            ),
            qos_overriding_options=interfaces.qos_overrides(deadline=rt),
        )
        if rt:
            self.create_timer(cfg.plant_dt_s, self._on_tick)
        else:
            self.create_timer(0.02, self._on_watchdog, clock=self.steady)
        DiagnosticsTimer(self, self._health, cfg.diagnostics_period_s)
        self.get_logger().info(
            f'scenario {sc.name}: {self.loop.n_steps} plant steps of {cfg.plant_dt_s} s, '
            f'Ts {cfg.control_period_s} s, timing {cfg.timing}; refrigerant tables: '
            f'{self.loop.sp.plant.tables_source}'
        )

    def _stamp(self):
        lockstep = self.config.timing == 'lockstep'
        return conversions.stamp_from_s(self.loop.t_s) if lockstep else self.get_clock().now().to_msg()

    def _publish_state(self) -> None:
        lp, stamp = self.loop, self._stamp()
        if self.config.timing == 'lockstep':
            self.pub_clock.publish(ClockMsg(clock=stamp))
        env = self.scenario.env_at(lp.t_s)
        self.pub_state.publish(
            conversions.state_msg(lp.n, lp.t_s, stamp, lp.sp.meas, env, lp.sp.cmd, lp.fallback.in_fallback)
        )
        self.policy.published(stamp, lp.t_s)

    def _plant_step(self, u: AcInput, fallback: bool) -> None:
        """One plant step n with u held (the simulator's core step), then comfort, power and the next state."""
        lp, stamp = self.loop, self._stamp()
        r, c = lp.step(u), lp.sp.comfort
        self.pub_comfort.publish(conversions.comfort_msg(r, stamp, c.met, c.clo))
        self.pub_power.publish(
            conversions.power_msg(r.n, stamp, lp.dt_s, u, r.out, lp.e_comp_j, lp.e_blower_j, fallback)
        )
        if lp.finished:
            self.get_logger().info(lp.summary())
        else:
            self._publish_state()

    def _fallback_command(self, why: str) -> AcInput:
        u, line = self.loop.fallback_command(why)
        if line:
            self.get_logger().warn(line)
        return u

    def _waiting_for(self) -> str:
        return pio.start_gate(
            self.config,
            self.pub_state.get_subscription_count(),
            tuple(p.get_subscription_count() for p in (self.pub_comfort, self.pub_power, self.pub_clock)),
            self.count_subscribers(interfaces.TOPIC_COMMAND),
            self.sub_cmd.get_publisher_count(),
        )

    def _start(self) -> bool:
        if not self.started and not self._waiting_for():
            self.started = True
            self.get_logger().info('subscribers matched: starting at step 0')
            self._publish_state()
            self.wait.kick(self.wall_s())
        return self.started and not self.loop.finished

    # -------------------------------------------------------------- lockstep
    def _control_period(self, u: AcInput, fallback: bool) -> None:
        for _ in range(self.loop.m):
            self._plant_step(u, fallback)
            if self.loop.finished:
                return
        self.wait.kick(self.wall_s())

    def _on_watchdog(self) -> None:
        if self._start() and self.wait.expired(self.wall_s()):
            why = f'no command for control step {self.loop.k} within {self.wait.timeout_s} s (wall clock)'
            self._control_period(self._fallback_command(why), True)

    def _on_command(self, msg: AcCommand) -> None:
        if not self.started or self.loop.finished or not self.policy.accept(msg, self.loop.k, self.wall_s()):
            return
        u, rt = conversions.command_input(msg), self.config.timing == 'realtime'
        line = self.loop.accept_command(u, int(msg.step_index), msg.strategy, self.clock_s() if rt else None)
        if line:
            self.get_logger().info(line)
        if not rt:
            self._control_period(u, False)

    # -------------------------------------------------------------- realtime
    def _on_tick(self) -> None:
        if self._start():
            u, fallback, line = self.loop.realtime_input(self.clock_s())
            if line:
                self.get_logger().warn(line)
            self._plant_step(u, fallback)

    # ------------------------------------------------------------------ glue
    def _event(self, name: str) -> None:
        self._events[name] += 1
        self.loop.rt.deadline_missed |= name == 'deadline_missed'
        self.notice(name, f'QoS event on hvac/command: {name} (total {self._events[name]})')

    def _set_params(self, changes: dict) -> str | None:
        try:
            self.config = self.config.replaced(changes)
        except ValueError as err:
            return str(err)
        self.policy.cfg, self.wait.timeout_s = self.config, self.config.command_timeout_s
        self.policy.rejections.throttle_s = self.notices.throttle_s = self.config.log_throttle_s
        return None

    def _health(self):
        rej, rt = self.policy.rejections, self.config.timing == 'realtime'
        new, self._reported = rej.total - self._reported, rej.total
        age = self.loop.rt.watchdog.age(self.clock_s()) if rt else self.wait.age(self.wall_s())
        lp = self.loop
        kw = dict(started=self.started, finished=lp.finished, n=lp.n, t_s=lp.t_s, events=self._events)
        kw.update(supervisor=lp.fallback, policy=self.policy, new_rejections=new)
        waiting = '' if self.started else self._waiting_for()
        age_s = None if age == float('inf') else age
        return [('plant', pio.plant_health(cfg=self.config, command_age_s=age_s, waiting_for=waiting, **kw))]


def main(args=None) -> int:
    """Entry point of the plant_node executable."""
    return run_node(PlantNode, args, 'plant_node')


if __name__ == '__main__':
    raise SystemExit(main())
