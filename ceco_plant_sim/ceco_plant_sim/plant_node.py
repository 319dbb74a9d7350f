"""plant_node: the cabin + A/C plant as a node (the simulator's own core per plant step).

Out: ``cabin/state``, ``cabin/comfort``, ``hvac/power``, ``/clock`` (lockstep), ``/diagnostics``.
In: ``hvac/command`` and its publishers' liveliness. lockstep: the state at t_k, then the command
of step k (or, after ``lockstep.command_timeout_s`` or a lost controller, the ACC law) for Ts/dt
plant steps; realtime: a timer every dt applies the latest fresh command, else the ACC law.
A step the plant cannot simulate (PlantStepError: the refrigerant cycle left its model) ends the node:
one ERROR line, an ERROR status on /diagnostics, no further step, exit status 3 (``PLANT_STOPPED_EXIT``).
The logic: :class:`ceco_plant_sim.plant_loop.PlantLoop`; docs/ros.md.
"""

from __future__ import annotations

import time

from rclpy.duration import Duration
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg

import ceco_plant_sim.plant_io as pio
from ceco_core.contracts import AcInput
from ceco_msgs.msg import AcCommand, AcPower, CabinState, Comfort
from ceco_plant_sim.plant_loop import PLANT_STOPPED_EXIT, PlantLoop, stopped_line
from ceco_plant_sim.plant_ops import PlantStepError
from ceco_ros import conversions, interfaces
from ceco_ros.diagnostics import DiagnosticsTimer
from ceco_ros.node_base import NodeTools
from ceco_ros.node_main import run_node
from ceco_v2x_preview.scenario import load_scenario_param

STOP_FLUSH_S = 1.0
"""Wall-clock bound of the wait for the readers' acknowledgements when the plant cannot go on [s]."""


class PlantNode(NodeTools, Node):
    """Cabin + A/C plant simulation."""

    def __init__(self):
        super().__init__('plant_node')
        cfg = self.use_params(pio.PLANT_PARAMETERS, pio.PlantNodeConfig.from_params)
        self.scenario = sc = load_scenario_param(cfg.scenario)
        self.loop, self.lockstep = PlantLoop(sc, cfg, self.log), cfg.timing == 'lockstep'
        self.exit_status: int | None = None
        """Set (with ``exit_reason``) when the node ends itself: what :func:`run_node` returns and logs."""
        self.exit_reason = ''
        out_qos = interfaces.state_qos(cfg.timing)
        self.pub_state = self.create_publisher(
            CabinState, interfaces.TOPIC_STATE, out_qos, qos_overriding_options=interfaces.qos_overrides()
        )
        self.pub_comfort = self.create_publisher(Comfort, interfaces.TOPIC_COMFORT, out_qos)
        self.pub_power = self.create_publisher(AcPower, interfaces.TOPIC_POWER, out_qos)
        # /clock only in lockstep: a real-time plant follows the wall clock and publishes no idle /clock
        self.pub_clock = (
            self.create_publisher(ClockMsg, interfaces.TOPIC_CLOCK, interfaces.QOS_CLOCK) if self.lockstep else None
        )
        self.sub_cmd = self.checked_subscription(
            AcCommand, interfaces.TOPIC_COMMAND, self._on_command, interfaces.command_qos(cfg.timing)
        )
        live = lambda alive, lost: self.loop.liveliness_changed(alive, lost, self.wall_s())  # noqa: E731
        self.liveliness_probe(AcCommand, interfaces.TOPIC_COMMAND, cfg.liveliness_lease_s, live)
        if self.lockstep:
            self.create_timer(0.02, self._on_watchdog, clock=self.steady)
        else:
            self.create_timer(cfg.plant_dt_s, self._on_tick)
        self.diagnostics = DiagnosticsTimer(self, self._health, cfg.diagnostics_period_s)
        self.get_logger().info(
            f'scenario {sc.name}: {self.loop.n_steps} plant steps of {cfg.plant_dt_s} s, '
            f'Ts {cfg.control_period_s} s, timing {cfg.timing}; refrigerant tables: '
            f'{self.loop.sp.plant.tables_source}'
        )

    def _stamp(self):
        return conversions.stamp_from_s(self.loop.t_s) if self.lockstep else self.get_clock().now().to_msg()

    def _publish_state(self) -> None:
        lp, stamp = self.loop, self._stamp()
        if self.pub_clock is not None:
            self.pub_clock.publish(ClockMsg(clock=stamp))
        env = self.scenario.env_at(lp.t_s)
        self.pub_state.publish(
            conversions.state_msg(
                lp.n,
                lp.t_s,
                stamp,
                lp.sp.meas,
                env,
                lp.sp.cmd,
                lp.fallback.in_fallback,
                recirc_share_cmd=lp.sp.plant.equation_input(lp.sp.cmd).recirc_share,
            )
        )
        lp.policy.published(stamp, lp.t_s)

    def _plant_step(self, u: AcInput, fallback: bool) -> None:
        """One plant step n with u held (the simulator's core step), then comfort, power and the next state."""
        lp, stamp = self.loop, self._stamp()
        try:
            r, c = lp.step(u), lp.sp.comfort
        except PlantStepError:  # the refrigerant cycle left its model: the run cannot go on
            self._stop()
            return
        self.pub_comfort.publish(conversions.comfort_msg(r, stamp, c.met, c.clo))
        self.pub_power.publish(
            conversions.power_msg(r.n, stamp, lp.dt_s, u, r.out, lp.e_comp_j, lp.e_blower_j, fallback)
        )
        if lp.finished:
            self.get_logger().info(lp.summary())
        else:
            self._publish_state()

    def _waiting_for(self) -> str:
        outputs = [self.pub_comfort, self.pub_power] + ([self.pub_clock] if self.pub_clock else [])
        return pio.start_gate(
            self.config,
            self.pub_state.get_subscription_count(),
            tuple(p.get_subscription_count() for p in outputs),
            self.data_readers(interfaces.TOPIC_COMMAND),  # its own probe not counted
            self.sub_cmd.get_publisher_count(),
        )

    def _running(self) -> bool:
        if not self.loop.started and self.loop.may_start(self._waiting_for(), self.wall_s()):
            self._publish_state()
        return self.loop.running

    # -------------------------------------------------------------- lockstep
    def _control_period(self, u: AcInput, fallback: bool) -> None:
        for _ in range(self.loop.m):
            self._plant_step(u, fallback)
            if not self.loop.running:  # finished, or stopped
                return
        self.loop.wait.kick(self.wall_s())

    def _on_watchdog(self) -> None:
        why = self._running() and self.loop.lockstep_overdue(self.wall_s())
        if why:
            self.loop.controller_lost = False  # said once: the next periods wait for a command again
            self._control_period(self._fallback_command(why), True)

    def _on_command(self, msg: AcCommand) -> None:
        u = self.loop.take_command(msg, self.wall_s(), self.clock_s(), conversions.command_input)
        if u is not None and self.lockstep:
            self._control_period(u, False)

    def _fallback_command(self, why: str) -> AcInput:
        u, line = self.loop.fallback_command(why)
        if line:
            self.get_logger().warn(line)
        return u

    # -------------------------------------------------------------- realtime
    def _on_tick(self) -> None:
        if self._running():
            u, fallback, line = self.loop.realtime_input(self.clock_s())
            if line:
                self.get_logger().warn(line)
            self._plant_step(u, fallback)

    def _stop(self) -> None:
        """The plant cannot go on: say why (log, /diagnostics), then end spinning (``main`` exits with status 3).

        Every matched reader first acknowledges what the plant published, the last states and the ERROR status
        (a wait of at most :data:`STOP_FLUSH_S` in all): a process that exits drops the reliable samples not yet
        delivered, and a CI run's bag once held 1 cabin/state of the 3 steps (3 /clock) the plant had published
        before it stopped.
        """
        self.get_logger().error(stopped_line(self.loop.stopped or ''))
        self.exit_status, self.exit_reason = PLANT_STOPPED_EXIT, 'the plant cannot go on'  # run_node's
        self.diagnostics.publish()
        deadline = time.monotonic() + STOP_FLUSH_S
        for pub in self.publishers:
            left_s = deadline - time.monotonic()
            if left_s <= 0.0:
                break
            pub.wait_for_all_acked(Duration(nanoseconds=int(left_s * 1e9)))
        self.context.try_shutdown()

    # ------------------------------------------------------------------ glue
    def config_changed(self) -> None:
        """Run-time parameter changes go to the loop."""
        self.loop.set_config(self.config)

    def _health(self):
        waiting = '' if self.loop.started else self._waiting_for()
        clocks = self.count_publishers(interfaces.TOPIC_CLOCK) if self.lockstep else 0
        if clocks > 1:
            self.notice('clock', pio.clock_conflict(clocks), 'error')
        return [('plant', self.loop.health(waiting, self.wall_s(), self.clock_s(), self.qos_events, clocks))]


def main(args=None) -> int:
    """Entry point of the plant_node executable: :func:`run_node`'s status (3 when the plant could not go on)."""
    return run_node(PlantNode, args, 'plant_node')


if __name__ == '__main__':
    raise SystemExit(main())
