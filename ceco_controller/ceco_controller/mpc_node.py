"""mpc_node: a CECO NMPC strategy (ceco, ceco-e, ceco-c, ceco-ioch) as a managed node.

baseline_node is the same class with the production ACC law. Inputs ``cabin/state``,
``v2x/weather_preview``, ``v2x/traffic_preview`` (and the liveliness of the preview publishers);
outputs ``hvac/command`` (control step k, the activation's epoch and a sequence number, an
automatic liveliness lease), ``controller/diagnostics``, ``/diagnostics``. Lifecycle: configure
builds the controller from the configuration parameters (settable while unconfigured) and solves
one throw-away step; activate starts commanding under a new epoch; deactivate stops (the plant's
fallback law takes over); cleanup/shutdown release everything. Timing: ``lockstep`` computes
step k once its state and both previews are here; ``realtime`` every Ts of the node clock. The
logic: :class:`ceco_controller.controller_session.ControllerSession`.
"""

from __future__ import annotations

import time
from functools import partial

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks

import ceco_controller.controller_io as cio
from ceco_controller.controller_session import ControllerSession, StepResult
from ceco_msgs.msg import AcCommand, CabinState, ControllerDiagnostics, TrafficPreview, WeatherPreview
from ceco_ros import conversions, interfaces
from ceco_ros.diagnostics import DiagnosticsTimer
from ceco_ros.node_base import FAILURE, ManagedNode
from ceco_ros.node_main import run_node

PREVIEWS = (
    (WeatherPreview, interfaces.TOPIC_WEATHER, 'weather'),
    (TrafficPreview, interfaces.TOPIC_TRAFFIC, 'traffic'),
)


class ControllerNode(ManagedNode):
    """Supervisory A/C controller node (one strategy), managed."""

    def __init__(self, node_name: str = 'mpc_node', fixed_strategy: str | None = None):
        super().__init__(node_name)
        specs = cio.controller_parameters(fixed_strategy)
        cfg = self.use_params(specs, lambda v: cio.ControllerNodeConfig.from_params(v, fixed_strategy))
        self.session, self._held = ControllerSession(cfg, self.log, self.notice), None
        name = self.get_fully_qualified_name()
        health = partial(self.session.health, node_name=name)
        DiagnosticsTimer(self, lambda: [('control', self._health(health))], cfg.diagnostics_period_s)
        self.start_managed(cfg.autostart, cfg.strategy)

    def on_configure(self, state):
        """Build the controller from the configuration, solve once; create the entities."""
        cfg, t0 = self.config, time.perf_counter()
        try:
            warm = self.session.configure(cfg)
        except (ValueError, RuntimeError, OSError) as err:
            self.get_logger().error(f'configure failed: {err}')
            return FAILURE
        qos_bad = {'incompatible_qos': lambda _e: self.qos_event('incompatible_qos', interfaces.TOPIC_COMMAND)}
        cmd_qos = interfaces.with_liveliness(interfaces.command_qos(cfg.timing), cfg.liveliness_lease_s)
        self._pubs = [
            self.create_lifecycle_publisher(
                AcCommand,
                interfaces.TOPIC_COMMAND,
                cmd_qos,
                event_callbacks=PublisherEventCallbacks(**qos_bad),
                qos_overriding_options=interfaces.qos_overrides(),
            ),
            self.create_lifecycle_publisher(
                ControllerDiagnostics, interfaces.TOPIC_DIAGNOSTICS, interfaces.QOS_COMMAND
            ),
        ]
        ovr, lease = interfaces.qos_overrides(), cfg.liveliness_lease_s
        self._subs = [
            self.create_subscription(
                CabinState,
                interfaces.TOPIC_STATE,
                self._on_state,
                interfaces.state_qos(cfg.timing),
                qos_overriding_options=ovr,
                event_callbacks=SubscriptionEventCallbacks(**qos_bad),
            ),
            *(
                self.create_subscription(
                    t, topic, partial(self._on_preview, k), interfaces.QOS_PREVIEW, qos_overriding_options=ovr
                )
                for t, topic, k in PREVIEWS
            ),
            *(self.liveliness_probe(t, topic, lease, partial(self._preview_liveliness, k)) for t, topic, k in PREVIEWS),
        ]
        rt = cfg.timing == 'realtime'
        self._timer = self.create_timer(
            cfg.control_period_s if rt else 0.05,
            self._on_timer if rt else self._poll,
            clock=None if rt else self.steady,
        )
        self.get_logger().info(
            f'configured in {time.perf_counter() - t0:.2f} s (controller built, first solve by {warm}): '
            f'{cfg.strategy}, Ts {cfg.control_period_s} s, Np {cfg.horizon_steps}, timing {cfg.timing}, '
            f'measurements {cfg.measurements}, scenario {self.session.ctl.scenario.name}'
        )
        return self.configured()

    def on_activate(self, state):
        """Start commanding under a new epoch; a lockstep state that came while inactive is computed now."""
        self.session.activate()
        self._held = None
        ret = super().on_activate(state)
        self.get_logger().info(f'active: commanding (epoch {self.session.epoch:#018x})')
        if self.config.timing == 'lockstep':
            self._poll()
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
        self.session.release()

    # ------------------------------------------------------------ callbacks
    def _active(self) -> bool:
        return self.lifecycle == 'active'

    def _on_state(self, msg: CabinState) -> None:
        self._publish(self.session.on_state(msg, self.wall_s(), self.clock_s(), self._active()))

    def _on_preview(self, kind: str, msg) -> None:
        self._publish(self.session.on_preview(kind, msg, self.wall_s(), self._active()))

    def _preview_liveliness(self, kind: str, alive: int, lost: int) -> None:
        self.session.preview_liveliness(kind, alive, lost, self.wall_s())

    def _on_timer(self) -> None:
        self._publish(self.session.on_timer(self.clock_s(), self._active()))

    def _poll(self) -> None:
        """lockstep: send a held command once its subscribers matched; compute a waiting, overdue step."""
        if self._held is not None and self._active() and not self._short_of_subscribers():
            self._pubs[0].publish(self._held)
            self._held = None
        self._publish(self.session.poll(self.wall_s(), self._active()))

    def _publish(self, results: list[StepResult]) -> None:
        """Each step's command and diagnostics; in lockstep a command is held until its subscribers matched.

        A command computed before ``lockstep.min_command_subscribers`` subscriptions matched the
        publisher (a volatile sample would never reach a reader not matched yet) is sent once they
        have: lockstep sends each command once.
        """
        cfg = self.config
        for r in results:
            try:
                msg = conversions.command_msg(
                    r.command, r.k, r.stamp, cfg.control_period_s, cfg.strategy, r.fallback, r.epoch, r.sequence
                )
                held = cfg.timing == 'lockstep' and self._short_of_subscribers()
                self._held = msg if held else None
                if not held:
                    self._pubs[0].publish(msg)
                diag = conversions.diagnostics_msg(r.diagnostics, r.stamp, cfg.strategy, cfg.control_period_s)
                self._pubs[1].publish(diag)
            except Exception as err:  # one bad step must not take the node down
                self.session.record.error(r.k, err)
                self.get_logger().error(f'step {r.k}: publishing failed: {err!r}')

    # ------------------------------------------------------------------ glue
    def config_changed(self) -> None:
        """Parameter changes go to the session (configuration ones take effect on configure)."""
        self.session.set_config(self.config)

    def _short_of_subscribers(self) -> bool:
        return self._pubs[0].get_subscription_count() < self.config.min_command_subscribers

    def _health(self, health):
        self.session.record.events.update(self.qos_events)
        return health(self.lifecycle, self.wall_s())


def main(args=None) -> int:
    """Entry point of the mpc_node executable."""
    return run_node(ControllerNode, args, 'mpc_node')


if __name__ == '__main__':
    raise SystemExit(main())
