"""preview_node: publishes the V2X weather and traffic (speed) previews of a
scenario over the control horizon, with the faults of the core's
:class:`~ceco_v2x_preview.preview.PreviewQuality` (noise, delay, dropout).

Timing modes (parameter ``timing``):
* ``lockstep`` (accelerated simulation): when the plant's state for a control
  step time t_k = k * Ts appears on ``cabin/state``, publish the previews on
  the grid t_k + i * Ts, i = 0..Np, stamped t_k and tagged with k. The
  controller waits for state k *and* previews k, so it always solves with
  the previews of its own step.
* ``realtime`` (vehicle): a timer on the node's clock every
  ``publish_period_s`` publishes the previews for the latest scenario time
  received on ``cabin/state``.

Glue only: every number comes from ``make_previews``.
"""
from __future__ import annotations

import dataclasses
import math

from rclpy.node import Node

from ceco_core.control_grid import control_step_index
from ceco_msgs.msg import CabinState, TrafficPreview, WeatherPreview
from ceco_ros import conversions, interfaces, params
from ceco_ros.node_main import run_node
from ceco_v2x_preview import forecast_error
from ceco_v2x_preview.preview import PreviewQuality, make_previews
from ceco_v2x_preview.scenario import load_scenario_param

TIMING_MODES = interfaces.TIMING_MODES


@dataclasses.dataclass(frozen=True)
class PreviewNodeConfig:
    """Validated parameters of preview_node."""

    scenario: str
    """Scenario name or YAML path."""
    timing: str
    """'lockstep' or 'realtime'."""
    control_period_s: float
    """Preview grid step = control period Ts [s]."""
    horizon_steps: int
    """Prediction horizon Np; the grid has Np + 1 points [-]."""
    publish_period_s: float
    """Publication period in realtime mode [s]."""
    quality: PreviewQuality
    """Preview faults."""

    def validate(self) -> None:
        if self.timing not in TIMING_MODES:
            raise ValueError(f'invalid parameter timing={self.timing!r}: must be one of {TIMING_MODES}')
        self.quality.validate()


class PreviewNode(Node):
    """Publishes v2x/weather_preview and v2x/traffic_preview."""

    def __init__(self):
        super().__init__('preview_node')
        self.config = self._read_config()
        self.scenario = load_scenario_param(self.config.scenario)
        self.quality_text = self.config.quality.describe()
        self._pub_w = self.create_publisher(WeatherPreview, interfaces.TOPIC_WEATHER, interfaces.QOS_PREVIEW)
        self._pub_s = self.create_publisher(TrafficPreview, interfaces.TOPIC_TRAFFIC, interfaces.QOS_PREVIEW)
        self.create_subscription(CabinState, interfaces.TOPIC_STATE, self._on_state, interfaces.QOS_STATE)
        self._last_k = -1
        self._latest_t_s = None
        if self.config.timing == 'realtime':
            self.create_timer(self.config.publish_period_s, self._on_timer)
        self.get_logger().info(
            f'scenario {self.scenario.name}, timing {self.config.timing}, grid '
            f'{self.config.horizon_steps + 1} x {self.config.control_period_s} s, quality {self.quality_text}')

    def _read_config(self) -> PreviewNodeConfig:
        d = params.declare
        scenario = d(self, 'scenario', 'sc03', 'scenario name (bundled) or path of a scenario YAML file')
        timing = d(self, 'timing', 'lockstep', 'lockstep (accelerated simulation, driven by cabin/state) '
                   'or realtime (timer on the node clock)', choices=TIMING_MODES)
        ts = d(self, 'control_period_s', 5.0, 'preview grid step = controller period Ts [s]',
               float_range=(0.1, 3600.0))
        np_ = d(self, 'horizon_steps', 6, 'prediction horizon Np [steps]; the grid has Np + 1 points',
                int_range=(1, 1000))
        pub = d(self, 'publish_period_s', 5.0, 'publication period in realtime mode [s]',
                float_range=(0.01, 3600.0))
        spans = d(self, 'faults.missing_spans_s', [0.0],
                  'spans of issue time without a new forecast, flattened [start, end, start, end, ...] '
                  '[s]; [0.0] = none')
        if len(spans) == 1 and spans[0] == 0.0:
            spans = []
        if len(spans) % 2:
            raise ValueError(f'invalid parameter faults.missing_spans_s={list(spans)!r}: '
                             'needs an even number of values (start, end pairs)')
        seed = d(self, 'faults.seed', -1, 'preview noise seed; -1 uses the scenario seed [-]',
                 int_range=(-1, 2**31 - 1))
        quality = PreviewQuality(
            noise_std_t_amb_c=d(self, 'faults.noise_std_t_amb_c', 0.0,
                                'std of the ambient-temperature forecast error at the reference lead [K]',
                                float_range=(0.0, 20.0)),
            noise_std_solar_wm2=d(self, 'faults.noise_std_solar_wm2', 0.0,
                                  'std of the solar forecast error at the reference lead [W/m^2]',
                                  float_range=(0.0, 1000.0)),
            noise_std_speed_mps=d(self, 'faults.noise_std_speed_mps', 0.0,
                                  'std of the speed forecast error at the reference lead [m/s]',
                                  float_range=(0.0, 30.0)),
            noise_std_rh=d(self, 'faults.noise_std_rh', 0.0,
                           'std of the relative-humidity forecast error at the reference lead [-]',
                           float_range=(0.0, 1.0)),
            noise_ref_lead_s=d(self, 'faults.noise_ref_lead_s', 30.0,
                               'lead time at which the error std equals noise_std_* [s]',
                               float_range=(0.1, 86400.0)),
            delay_s=d(self, 'faults.delay_s', 0.0, 'age of the forecast when received [s]',
                      float_range=(0.0, 86400.0)),
            missing_spans_s=tuple(zip(spans[0::2], spans[1::2])),
            missing_policy=d(self, 'faults.missing_policy', 'hold_last',
                             'while missing: hold_last (keep the last forecast) or drop',
                             choices=('hold_last', 'drop')),
            seed=None if seed < 0 else int(seed),
            uncertainty=d(self, 'faults.uncertainty_level', 'none',
                          'benchmark forecast-uncertainty level (AR(1) errors, ceco_v2x_preview.forecast_error)',
                          choices=forecast_error.LEVELS),
        )
        cfg = PreviewNodeConfig(scenario=scenario, timing=timing, control_period_s=ts,
                                horizon_steps=np_, publish_period_s=pub, quality=quality)
        cfg.validate()
        return cfg

    # ------------------------------------------------------------- callbacks
    def _on_state(self, msg: CabinState) -> None:
        t_s = msg.scenario_time_s
        if not math.isfinite(t_s) or t_s < 0.0:
            self.get_logger().error(f'rejected cabin/state: scenario_time_s={t_s!r} is not a finite '
                                    'time >= 0')
            return
        if self._latest_t_s is not None and t_s < self._latest_t_s and self.config.timing == 'realtime':
            self.get_logger().warn(f'rejected cabin/state: stale scenario_time_s={t_s} < {self._latest_t_s}')
            return
        self._latest_t_s = t_s
        if self.config.timing != 'lockstep':
            return
        k = control_step_index(t_s, self.config.control_period_s)
        if k is None:
            return  # not a control step time
        if k <= self._last_k:
            if k < self._last_k:
                self.get_logger().warn(f'rejected cabin/state: stale step k={k} (already published {self._last_k})')
            return
        self._publish(k, t_s, msg.header.stamp)  # t_s = n * dt, as the simulator's t

    def _on_timer(self) -> None:
        if self._latest_t_s is None:
            return
        ts = self.config.control_period_s
        self._publish(int(self._latest_t_s // ts), self._latest_t_s, self.get_clock().now().to_msg())

    def _publish(self, k: int, t0_s: float, stamp) -> None:
        try:
            p = make_previews(self.scenario, t0_s, self.config.control_period_s,
                              self.config.horizon_steps + 1, self.config.quality)
        except ValueError as err:
            self.get_logger().error(f'no preview for t={t0_s} s: {err}')
            return
        w, s = conversions.previews_to_msgs(p, k, stamp, self.quality_text)
        self._pub_w.publish(w)
        self._pub_s.publish(s)
        self._last_k = max(self._last_k, k)


def main(args=None) -> int:
    return run_node(PreviewNode, args, 'preview_node')


if __name__ == '__main__':
    raise SystemExit(main())
