"""mpc_node: a CECO NMPC strategy as a managed node (baseline_node: the same class, the ACC law).

In: ``cabin/state``, the two previews (and their publishers' liveliness). Out: ``hvac/command``
(step k, epoch, sequence; a liveliness lease), ``controller/diagnostics``, ``/diagnostics``.
The logic: :class:`ceco_controller.controller_session.ControllerSession`; docs/ros.md.
"""

from __future__ import annotations

import time
from functools import partial

import ceco_controller.controller_io as cio
from ceco_controller.controller_session import ControllerSession, StepResult
from ceco_core.sequencing import HeldSample
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
        self.session, self._hold = ControllerSession(cfg, self.log, self.notice), HeldSample()
        self._enough_at: int | None = None  # the matched hvac/command count last found sufficient
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
        cmd_qos = interfaces.command_publisher_qos(cfg.timing, cfg.liveliness_lease_s)
        self._enough_at = None
        self._pubs = [
            self.checked_lifecycle_publisher(AcCommand, interfaces.TOPIC_COMMAND, cmd_qos),
            self.create_lifecycle_publisher(
                ControllerDiagnostics, interfaces.TOPIC_DIAGNOSTICS, interfaces.QOS_COMMAND
            ),
        ]
        lease = cfg.liveliness_lease_s
        self._subs = [
            self.checked_subscription(
                CabinState, interfaces.TOPIC_STATE, self._on_state, interfaces.state_qos(cfg.timing)
            ),
            *(
                self.checked_subscription(t, topic, partial(self._on_preview, k), interfaces.QOS_PREVIEW)
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
        self.get_logger().info(self.session.configured_line(warm, time.perf_counter() - t0))
        return self.configured()

    def on_activate(self, state):
        """Start commanding under a new epoch; a lockstep state that came while inactive is computed now."""
        self.session.activate()
        self._hold.clear()
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
    def _on_state(self, msg: CabinState) -> None:
        self._publish(self.session.on_state(msg, self.wall_s(), self.clock_s(), self.active))

    def _on_preview(self, kind: str, msg) -> None:
        self._publish(self.session.on_preview(kind, msg, self.wall_s(), self.active))

    def _preview_liveliness(self, kind: str, alive: int, lost: int) -> None:
        self.session.preview_liveliness(kind, alive, lost, self.wall_s())

    def _on_timer(self) -> None:
        self._publish(self.session.on_timer(self.clock_s(), self.active))

    def _poll(self) -> None:
        """lockstep: send a held command once its subscribers matched; compute a waiting, overdue step."""
        for msg in self._hold.release(self.active and not self._short_of_subscribers()):
            self._pubs[0].publish(msg)
        self._publish(self.session.poll(self.wall_s(), self.active))

    def _publish(self, results: list[StepResult]) -> None:
        """Each step's command (lockstep: held until its subscribers matched, ``HeldSample``), diagnostics."""
        cfg = self.config
        for r in results:
            try:
                msg = conversions.command_msg(
                    r.command, r.k, r.stamp, cfg.control_period_s, cfg.strategy, r.fallback, r.epoch, r.sequence
                )
                for out in self._hold.offer(msg, cfg.timing == 'lockstep' and self._short_of_subscribers()):
                    self._pubs[0].publish(out)
                if self._pubs[1].get_subscription_count():  # (volatile: no reader, nobody would get it)
                    diag = conversions.diagnostics_msg(r.diagnostics, r.stamp, cfg.strategy, cfg.control_period_s)
                    self._pubs[1].publish(diag)
            except Exception as err:  # one bad step must not take the node down
                self.session.record.error(r.k, err)
                self.get_logger().error(f'step {r.k}: publishing failed: {err!r}')
            self.session.settle(r.k)  # the command is out: what only the next step needs

    # ------------------------------------------------------------------ glue
    def config_changed(self) -> None:
        """Parameter changes go to the session (configuration ones take effect on configure)."""
        self.session.set_config(self.config)

    def _short_of_subscribers(self) -> bool:
        """lockstep: fewer hvac/command data readers matched than ``min_command_subscribers``.

        The graph (``data_readers``: 0.1-0.2 ms, a third of the step's Python around the solver) is asked
        only while the matched count differs from the last one found sufficient; on a running stack the
        check is one read of the matched count per step.
        """
        matched = self._pubs[0].get_subscription_count()
        if matched == self._enough_at:
            return False
        short = self.data_readers(interfaces.TOPIC_COMMAND, self._pubs[0]) < self.config.min_command_subscribers
        self._enough_at = None if short else matched
        return short

    def _health(self, health):
        self.session.record.events.update(self.qos_events)
        return health(self.lifecycle, self.wall_s())


def main(args=None) -> int:
    """Entry point of the mpc_node executable."""
    return run_node(ControllerNode, args, 'mpc_node')


if __name__ == '__main__':
    raise SystemExit(main())
