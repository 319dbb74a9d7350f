"""preview_node: the V2X weather and traffic (speed) previews of a scenario as a node.

Previews over the control horizon, with the faults of
:class:`~ceco_v2x_preview.preview.PreviewQuality` (noise, delay, dropout); its status on
``/diagnostics``.

Timing (parameter ``timing``):
* ``lockstep`` (accelerated simulation): when the plant's state for a control step time
  t_k = k * Ts appears on ``cabin/state``, publish the previews on the grid t_k + i * Ts,
  i = 0..Np, stamped t_k and tagged with k; the controller waits for state k *and* previews k.
  Until the first previews go out, a step's previews wait until each preview publisher has
  matched ``lockstep.min_preview_subscribers`` data readers (the start of a run: a recorder or
  controller discovered late would miss step 0); every step's previews made meanwhile wait, in order,
  and go out together. After that they go out at once: a reader that
  leaves mid-run (a controller killed and restarted) holds back nobody else.
* ``realtime`` (vehicle): a timer on the node's clock every ``publish_period_s`` publishes the
  previews for the latest scenario time received on ``cabin/state``.

States are checked and ordered by the pure :class:`~ceco_v2x_preview.preview_io.PreviewInputs`
(a far-future or malformed state is rejected without moving anything, a restart is followed);
every number comes from ``make_previews``.
"""

from __future__ import annotations

from rclpy.node import Node

from ceco_core.control_grid import control_step_index, control_step_of
from ceco_core.sequencing import HeldSample
from ceco_msgs.msg import CabinState, TrafficPreview, WeatherPreview
from ceco_ros import conversions, interfaces
from ceco_ros.diagnostics import DiagnosticsTimer
from ceco_ros.node_base import NodeTools
from ceco_ros.node_main import run_node
from ceco_v2x_preview.preview import make_previews
from ceco_v2x_preview.preview_io import (
    PREVIEW_PARAMETERS,
    PreviewInputs,
    PreviewNodeConfig,
    held_previews,
    preview_health,
)
from ceco_v2x_preview.scenario import load_scenario_param


class PreviewNode(NodeTools, Node):
    """Publishes v2x/weather_preview and v2x/traffic_preview."""

    def __init__(self):
        super().__init__('preview_node')
        cfg = self.use_params(PREVIEW_PARAMETERS, PreviewNodeConfig.from_params)
        self.scenario = load_scenario_param(cfg.scenario)
        self.quality_text = cfg.quality.describe()
        self.inputs = PreviewInputs(cfg, self.log)
        self._last_k, self._published, self._failed, self._error, self._reported = None, 0, 0, '', 0
        # liveliness lease: a dead preview node is known to every reader that probes it
        qos = interfaces.preview_publisher_qos(cfg.timing, cfg.liveliness_lease_s)
        self._pub_w = self.create_publisher(WeatherPreview, interfaces.TOPIC_WEATHER, qos)
        self._pub_s = self.create_publisher(TrafficPreview, interfaces.TOPIC_TRAFFIC, qos)
        self.create_subscription(
            CabinState,
            interfaces.TOPIC_STATE,
            self._on_state,
            interfaces.state_qos(cfg.timing),
            qos_overriding_options=interfaces.qos_overrides(),
        )
        self._hold = HeldSample(keep=interfaces.LOCKSTEP_DEPTH)  # every step's previews reach the bag
        self._gate_open = False  # lockstep: the readers had matched once (the start gate is passed for good)
        if cfg.timing == 'realtime':
            self.create_timer(cfg.publish_period_s, self._on_timer)
        else:  # on the steady clock: sim time stands still while the plant waits for step 0
            self.create_timer(0.02, self._release_held, clock=self.steady)
        DiagnosticsTimer(self, self._health, cfg.diagnostics_period_s)
        self.get_logger().info(
            f'scenario {self.scenario.name}, timing {cfg.timing}, grid {cfg.horizon_steps + 1} x '
            f'{cfg.control_period_s} s, quality {self.quality_text}'
        )

    def _on_state(self, msg: CabinState) -> None:
        verdict = self.inputs.offer_state(msg, self.wall_s(), self.clock_s())
        if verdict is None:
            return
        if verdict.reset:
            self._last_k = None
        if self.config.timing != 'lockstep':
            return
        t_s = msg.scenario_time_s
        k = control_step_index(t_s, self.config.control_period_s)
        if k is not None and (self._last_k is None or k > self._last_k):
            self._publish(k, t_s, msg.header.stamp)  # t_s = n * dt, as the simulator's t

    def _on_timer(self) -> None:
        t_s = self.inputs.gate.last
        if t_s is not None:
            self._publish(control_step_of(t_s, self.config.control_period_s), t_s, self.get_clock().now().to_msg())

    def _publish(self, k: int, t0_s: float, stamp) -> None:
        try:
            p = make_previews(
                self.scenario, t0_s, self.config.control_period_s, self.config.horizon_steps + 1, self.config.quality
            )
            w, s = conversions.previews_to_msgs(p, k, stamp, self.quality_text)
        except (ValueError, OverflowError) as err:  # never crash on a time the scenario cannot serve
            self._failed += 1
            self._error = f't={t0_s!r} s: {err}'
            self.notice('publish-failed', f'no preview for step {k}: {self._error}', 'error')
            return
        lockstep = self.config.timing == 'lockstep'
        for pair in self._hold.offer((k, w, s), lockstep and self._short_of_readers(), self.wall_s()):
            self._send(*pair)

    def _send(self, k: int, w, s) -> None:
        self._pub_w.publish(w)
        self._pub_s.publish(s)
        self._last_k, self._published, self._error = k, self._published + 1, ''

    def _readers(self) -> dict[str, int]:
        pubs = ((interfaces.TOPIC_WEATHER, self._pub_w), (interfaces.TOPIC_TRAFFIC, self._pub_s))
        return {topic: self.data_readers(topic, pub) for topic, pub in pubs}

    def _short_of_readers(self) -> bool:
        """Before the first release: a preview publisher has fewer data readers than ``min_preview_subscribers``."""
        need = self.config.min_preview_subscribers
        if self._gate_open or need <= 0:
            return False
        self._gate_open = min(self._readers().values()) >= need
        return not self._gate_open

    def _held_text(self) -> str:
        """What the held previews wait for, once they waited ``hold_warning_s``; '' otherwise."""
        since = self._hold.since_s
        waited_s = 0.0 if since is None else self.wall_s() - since
        if self._hold.msg is None or waited_s < self.config.hold_warning_s:
            return ''
        first, last = self._hold.waiting[0][0], self._hold.waiting[-1][0]
        return held_previews(first, waited_s, self._readers(), self.config.min_preview_subscribers, last)

    def _release_held(self) -> None:
        """lockstep: send held previews once their readers matched (said once they waited long)."""
        if self._hold.msg is None:
            return
        for pair in self._hold.release(not self._short_of_readers()):
            self._send(*pair)
        text = self._held_text()
        if text:
            self.notice('previews-held', text)

    def config_changed(self) -> None:
        """Run-time parameter changes go to the input checks."""
        self.inputs.cfg = self.config
        self.inputs.rejections.throttle_s = self.config.log_throttle_s

    def _health(self):
        rej = self.inputs.rejections
        new, self._reported = rej.total - self._reported, rej.total
        return [
            (
                'previews',
                preview_health(
                    cfg=self.config,
                    inputs=self.inputs,
                    last_k=self._last_k,
                    n_published=self._published,
                    n_failed=self._failed,
                    last_error=self._error,
                    wall_s=self.wall_s(),
                    new_rejections=new,
                    held=self._held_text(),
                ),
            )
        ]


def main(args=None) -> int:
    """Entry point of the preview_node executable."""
    return run_node(PreviewNode, args, 'preview_node')


if __name__ == '__main__':
    raise SystemExit(main())
