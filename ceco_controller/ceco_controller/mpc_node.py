"""mpc_node: a CECO NMPC strategy (ceco, ceco-e, ceco-c, ceco-ioch) as a managed node.

baseline_node is the same class with the production ACC law. Inputs ``cabin/state``,
``v2x/weather_preview``, ``v2x/traffic_preview``; outputs ``hvac/command`` (tagged with the
control step k), ``controller/diagnostics``, ``/diagnostics``. Lifecycle: configure loads the
scenario, builds the controller (NLP) and solves one throw-away step; activate starts
commanding; deactivate stops (the plant's fallback law takes over); cleanup/shutdown release
everything. Timing: ``lockstep`` computes step k once its state and both previews are here
(without previews after ``preview_timeout_s``); ``realtime`` every Ts of the node clock from
the latest inputs. Checks, ordering, bookkeeping and health rules: the pure
:mod:`ceco_controller.controller_io`; the controller's build, warm-up and step:
:class:`ceco_controller.step_adapter.NodeController` (the simulator's observation and core).
"""

from __future__ import annotations

import time
from functools import partial

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks

import ceco_controller.controller_io as cio
from ceco_controller.step_adapter import NodeController
from ceco_msgs.msg import AcCommand, CabinState, ControllerDiagnostics, TrafficPreview, WeatherPreview
from ceco_ros import conversions, interfaces, params
from ceco_ros.diagnostics import DiagnosticsTimer
from ceco_ros.node_base import FAILURE, ManagedNode
from ceco_ros.node_main import run_node


class ControllerNode(ManagedNode):
    """Supervisory A/C controller node (one strategy), managed."""

    def __init__(self, node_name: str = 'mpc_node', fixed_strategy: str | None = None):
        super().__init__(node_name)
        specs = cio.controller_parameters(fixed_strategy)
        self.config = cfg = cio.ControllerNodeConfig.from_params(params.declare_all(self, specs), fixed_strategy)
        params.on_set(self, specs, self._set_params)
        self.setup_tools(cfg.log_throttle_s)
        self.ctl, self._held, self.record = None, None, cio.ControllerRecord()
        self.inputs = cio.ControllerInputs(cfg, self.log, self._reset_core)
        DiagnosticsTimer(
            self,
            lambda: [
                (
                    'control',
                    self.record.health(
                        self.lifecycle, self.config, self.inputs, self.wall_s(), self.ctl and self.ctl.step_budget_s
                    ),
                )
            ],
            cfg.diagnostics_period_s,
        )
        self.start_managed(cfg.autostart)
        self.get_logger().info(f'{cfg.strategy}: unconfigured (autostart {cfg.autostart})')

    def on_configure(self, state):
        """Load the scenario, build the controller, solve once; create the entities."""
        cfg, t0 = self.config, time.perf_counter()
        try:
            self.ctl = NodeController(cfg)
        except (ValueError, RuntimeError, OSError) as err:
            self.get_logger().error(f'configure failed: {err}')
            return FAILURE
        rt, ovr = cfg.timing == 'realtime', interfaces.qos_overrides()
        events = {'incompatible_qos': lambda _e: self._event('incompatible_qos')}
        self._pubs = [
            self.create_lifecycle_publisher(
                AcCommand,
                interfaces.TOPIC_COMMAND,
                interfaces.command_qos(cfg.timing, cfg.command_deadline_periods * cfg.control_period_s),
                event_callbacks=PublisherEventCallbacks(deadline=lambda _e: self._event('deadline_missed'), **events),
                qos_overriding_options=interfaces.qos_overrides(deadline=rt),
            ),
            self.create_lifecycle_publisher(
                ControllerDiagnostics, interfaces.TOPIC_DIAGNOSTICS, interfaces.QOS_COMMAND
            ),
        ]
        self._subs = [
            self.create_subscription(
                CabinState,
                interfaces.TOPIC_STATE,
                self._on_state,
                interfaces.state_qos(cfg.timing),
                qos_overriding_options=ovr,
                event_callbacks=SubscriptionEventCallbacks(**events),
            ),
            *(
                self.create_subscription(
                    msg_type, topic, partial(self._on_preview, kind), interfaces.QOS_PREVIEW, qos_overriding_options=ovr
                )
                for msg_type, topic, kind in (
                    (WeatherPreview, interfaces.TOPIC_WEATHER, 'weather'),
                    (TrafficPreview, interfaces.TOPIC_TRAFFIC, 'traffic'),
                )
            ),
        ]
        self._timer = (
            self.create_timer(cfg.control_period_s, self._on_timer)
            if rt
            else self.create_timer(0.05, self._run_ready, clock=self.steady)
        )
        self.get_logger().info(
            f'configured in {time.perf_counter() - t0:.2f} s (controller built, first solve by '
            f'{self.ctl.warm_up}): {cfg.strategy}, Ts {cfg.control_period_s} s, Np {cfg.horizon_steps}, timing '
            f'{cfg.timing}, measurements {cfg.measurements}, scenario {self.ctl.scenario.name}'
        )
        return self.configured()

    def on_activate(self, state):
        """Start commanding (from a fresh controller state); a state that came while inactive is computed now."""
        self._reset_core()
        ret = super().on_activate(state)
        self.get_logger().info('active: commanding')
        if self.config.timing == 'lockstep':
            self._run_ready()
        return ret

    def on_deactivate(self, state):
        """Stop commanding."""
        self.get_logger().info("inactive: not commanding; the plant's fallback law takes over")
        return super().on_deactivate(state)

    def release(self) -> None:
        """Destroy what on_configure created."""
        self.destroy_timer(self._timer)
        for sub in self._subs:
            self.destroy_subscription(sub)
        for pub in self._pubs:
            self.destroy_lifecycle_publisher(pub)
        self.ctl = None
        self.inputs.clear()

    # ----------------------------------------------------------------- inputs
    def _on_state(self, msg: CabinState) -> None:
        if self.inputs.offer_state(msg, self.wall_s(), self.clock_s()):
            if self.config.timing == 'lockstep':
                self._run_ready()
            elif self.inputs.due():  # realtime: a tick came before this control step's first state
                self._on_timer()

    def _on_preview(self, kind: str, msg) -> None:
        if self.inputs.offer_preview(kind, msg, self.wall_s()) and self.config.timing == 'lockstep':
            self._run_ready()

    def _run_ready(self) -> None:
        """Lockstep: compute the waiting step when complete or overdue; inactive, inputs wait in the buffer.

        A command computed before ``lockstep.min_command_subscribers`` subscriptions matched the
        publisher (a plant or recorder that this node has not discovered yet: a volatile sample
        would never reach it) is held and sent once they have: lockstep sends each command once.
        """
        if self.lifecycle == 'active':
            if self._held is not None and not self._short_of_subscribers():
                self._pubs[0].publish(self._held)
                self._held = None
            self._run(self.inputs.ready() or self.inputs.overdue(self.wall_s()))

    def _on_timer(self) -> None:
        si, why = self.inputs.realtime_step(self.clock_s())
        if si is None and why and self.lifecycle == 'active':
            self.notice('no-state', f'not commanding: {why}')
        self._run(si)

    def _run(self, si: cio.StepInputs | None) -> None:
        if si is None or self.lifecycle != 'active':
            return
        t0, cfg, stamp = time.perf_counter(), self.config, si.state.header.stamp
        try:
            cmd, diag, note = self.ctl.step(si, cfg)
            if note:
                self.notice('no-previews', f'step {si.k}: {note}: solving without previews')
            fallback, ts = bool(diag.fallback), cfg.control_period_s
            msg = conversions.command_msg(cmd, si.k, stamp, ts, cfg.strategy, fallback)
            held = cfg.timing == 'lockstep' and self._short_of_subscribers()
            self._held = msg if held else None
            if not held:
                self._pubs[0].publish(msg)
            self._pubs[1].publish(conversions.diagnostics_msg(diag, stamp, cfg.strategy, ts))
            self.record.step(si.k, (time.perf_counter() - t0) * 1e3, diag, note)
            if fallback:
                self.notice('fallback', f'step {si.k}: fallback {diag.fallback}: {diag.message}')
        except Exception as err:  # one bad step must not take the node down
            self.record.error(si.k, err)
            self.get_logger().error(f'step {si.k} failed: {err!r}')

    # ------------------------------------------------------------------ glue
    def _reset_core(self) -> None:
        self._held = None
        if self.ctl is not None:
            self.ctl.reset()

    def _set_params(self, changes: dict) -> str | None:
        try:
            self.config = self.config.replaced(changes)
        except ValueError as err:
            return str(err)
        self.inputs.configure(self.config)
        self.notices.throttle_s = self.config.log_throttle_s
        self.get_logger().info(f'parameters set: {changes}')
        return None

    def _short_of_subscribers(self) -> bool:
        return self._pubs[0].get_subscription_count() < self.config.min_command_subscribers

    def _event(self, name: str) -> None:
        self.record.events[name] += 1
        self.notice(name, f'QoS event: {name} (total {self.record.events[name]})')


def main(args=None) -> int:
    """Entry point of the mpc_node executable."""
    return run_node(ControllerNode, args, 'mpc_node')


if __name__ == '__main__':
    raise SystemExit(main())
