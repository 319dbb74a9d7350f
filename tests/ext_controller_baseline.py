"""A third-party controller for `ceco benchmark --controller-cmd`, written against the topics only.

It re-implements the production PI law of docs/controller.md section 3 (set-point
26 degC, K_p = 0.25 /K, T_i = 120 s, back-calculation T_t = 60 s, pull-down above
4 K until below 2 K, economy-first map) in a few lines, without importing anything
from ceco: only rclpy and the ceco_msgs message types. The benchmark must score it
exactly as the built-in `baseline@26.0` (tests/test_benchmark_external.py).

Contract used (docs/benchmark.md, "Your own controller over ROS 2"): subscribe
`cabin/state` (reliable, keep-last, volatile); for each state at a control step
t_k = k * Ts publish one `hvac/command` with step_index k; Ts from the environment
variable CECO_CONTROL_PERIOD_S; AcCommand.strategy = "external"; AcCommand.epoch random and
non-zero, drawn at start, and AcCommand.sequence = 1, 2, ... (the plant refuses epoch 0). The command
publisher offers automatic liveliness with a 1-s lease, so the plant's liveliness probe matches it (and tells
a dead controller at once; without a lease rmw logs an "incompatible QoS ... LIVELINESS" warning).
"""

import os
import secrets
import sys

import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy

from ceco_msgs.msg import AcCommand, CabinState

SP, KP, TI, TT = 26.0, 0.25, 120.0, 60.0


class ExternalBaseline(Node):
    def __init__(self):
        super().__init__('external_controller')
        self.ts = float(os.environ['CECO_CONTROL_PERIOD_S'])
        self.integral, self.pulldown = 0.0, False
        self.epoch, self.sequence = secrets.randbits(64) or 1, 0
        self.pub = self.create_publisher(
            AcCommand,
            'hvac/command',
            QoSProfile(
                history=HistoryPolicy.KEEP_LAST,
                depth=100,
                reliability=ReliabilityPolicy.RELIABLE,
                durability=DurabilityPolicy.VOLATILE,
                liveliness=LivelinessPolicy.AUTOMATIC,
                liveliness_lease_duration=Duration(seconds=1),
            ),
        )
        self.create_subscription(
            CabinState,
            'cabin/state',
            self.on_state,
            QoSProfile(
                history=HistoryPolicy.KEEP_LAST,
                depth=1000,
                reliability=ReliabilityPolicy.RELIABLE,
                durability=DurabilityPolicy.VOLATILE,
            ),
        )

    def demand(self, t_cab_c):
        err = t_cab_c - SP
        if self.pulldown and err < 2.0:
            self.pulldown, self.integral = False, 1.0 - KP * err
        elif not self.pulldown and err > 4.0:
            self.pulldown = True
        if self.pulldown:
            return 1.0
        v = KP * err + self.integral
        d = min(max(v, 0.0), 1.0)
        self.integral += self.ts * (KP / TI * err + (d - v) / TT)
        return d

    def on_state(self, msg):
        k = round(msg.scenario_time_s / self.ts)
        if abs(msg.scenario_time_s - k * self.ts) > 1e-6:
            return  # not a control step
        d = self.demand(msg.t_cab_c)
        self.sequence += 1
        cmd = AcCommand(step_index=k, control_period_s=self.ts, strategy='external', fallback=False)
        cmd.epoch, cmd.sequence = self.epoch, self.sequence
        cmd.header.stamp = msg.header.stamp
        cmd.evap_setpoint_c = 10.0 - min(d / 0.5, 1.0) * (10.0 - 3.0)
        cmd.blower_flow_kgps = 0.05 + max(d - 0.3, 0.0) / (1.0 - 0.3) * (0.17 - 0.05)
        self.pub.publish(cmd)


def main():
    rclpy.init()
    node = ExternalBaseline()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
