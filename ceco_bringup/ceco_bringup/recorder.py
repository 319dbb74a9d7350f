"""Recorder node: subscribes to every topic of the stack as serialized
(raw CDR) messages and writes them into a rosbag2 bag with rosbags
(sqlite3, metadata version 9) -- `ros2 bag record` for a machine without
rosbag2.

Bag timestamps are the receive time on the wall clock (as rosbag2 records
by default), made strictly increasing so the bag order is the arrival
order. The bag is committed and its metadata.yaml rewritten every
`flush_period_s`, so even a SIGKILL leaves a readable bag up to the last
flush; `close()` (every normal or Ctrl-C stop path) writes the rest.

Run standalone: `python -m ceco_bringup.recorder OUT_BAG_DIR` (Ctrl-C stops).
"""
from __future__ import annotations

import sys
import threading
import time

from rclpy.node import Node
from rclpy.serialization import deserialize_message

from ceco_bringup.bagio import BagWriter
from ceco_msgs.msg import AcPower
from ceco_ros import interfaces


def message_class(type_name: str):
    """'pkg/msg/Name' -> the generated Python class."""
    import importlib
    pkg, _, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.msg'), name)


class Recorder(Node):
    """Records STACK_TOPICS into `bag_dir`."""

    def __init__(self, bag_dir, *, topics=None, flush_period_s: float = 0.5,
                 custom_data: dict | None = None, node_name: str = 'ceco_recorder', **node_kwargs):
        super().__init__(node_name, **node_kwargs)
        self.writer = BagWriter(bag_dir)
        for key, value in (custom_data or {}).items():
            self.writer._writer.set_custom_data(str(key), str(value))
        self._lock = threading.Lock()
        self.topics = dict(interfaces.STACK_TOPICS if topics is None else topics)
        self.subs = {}
        for topic, (type_name, offered, qos) in self.topics.items():
            self.writer.add_topic(topic, type_name, offered)
            self.subs[topic] = self.create_subscription(
                message_class(type_name), topic, self._make_cb(topic), qos, raw=True)
        self.last_power_step = -1
        self.first_state_wall = None   # monotonic time of the first cabin/state [s]
        self.last_power_wall = None    # monotonic time of the latest hvac/power [s]
        self.n_messages = 0
        self.create_timer(flush_period_s, self.flush)

    def _make_cb(self, topic):
        def cb(data: bytes) -> None:
            with self._lock:
                if self.writer is None:
                    return
                self.writer.write(topic, time.time_ns(), data)
                self.n_messages += 1
                if topic == interfaces.TOPIC_POWER:
                    self.last_power_step = int(deserialize_message(data, AcPower).step_index)
                    self.last_power_wall = time.monotonic()
                elif topic == interfaces.TOPIC_STATE and self.first_state_wall is None:
                    self.first_state_wall = time.monotonic()
        return cb

    def publisher_counts(self) -> dict[str, int]:
        """Publishers this node's graph sees per recorded topic."""
        return {t: self.count_publishers(t) for t in self.topics}

    def flush(self) -> None:
        with self._lock:
            if self.writer is not None:
                try:
                    self.writer.flush()
                except Exception as err:  # never let a flush error stop the recording
                    self.get_logger().error(f'bag flush failed: {err}')

    def close(self) -> dict[str, int]:
        """Finalise the bag (idempotent). Returns the message count per topic."""
        with self._lock:
            if self.writer is None:
                return {}
            counts = self.writer.counts
            self.writer.close()
            self.writer = None
            return counts


def main(argv=None) -> int:
    import argparse

    import rclpy
    from rclpy.executors import ExternalShutdownException
    parser = argparse.ArgumentParser(prog='python -m ceco_bringup.recorder',
                                     description='record every ceco topic into a rosbag2 bag')
    parser.add_argument('bag_dir')
    args, ros_args = parser.parse_known_args(sys.argv[1:] if argv is None else argv)
    rclpy.init(args=['recorder'] + ros_args)
    node = None
    try:
        node = Recorder(args.bag_dir)
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            print(f'recorder: {node.close()}', file=sys.stderr)
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
