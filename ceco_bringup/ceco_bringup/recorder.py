"""Recorder node: `ros2 bag record` of the stack's topics for a machine without rosbag2.

Subscribes to every topic of the stack as serialized (raw CDR) messages and
writes them with rosbags into a rosbag2 bag (``ceco_bringup.bag_writer``: MCAP
by default, SQLite 3 as an option; metadata version 9, Jazzy's format).

Topic names in the bag are the fully qualified names the subscriptions resolve
to, as `ros2 bag record` writes them: ``/cabin/state`` in the root namespace,
``/veh1/cabin/state`` for a stack under ``/veh1`` (``namespace='/veh1'`` or
``--ros-args -r __ns:=/veh1``); ``/clock`` and ``/rosout`` stay global.

Bag timestamps: ``timestamps='receive'`` (real time; rosbag2's default) records
the wall-clock receive time; ``timestamps='sim'`` (lockstep) records the
simulation time, the header stamp of each message (``bag_writer.SimTimeStamps``),
so `ros2 bag play` replays the drive at its own pace.

The bag is put on disk complete every `flush_period_s`, so even a SIGKILL
leaves a readable bag up to the last flush; `close()` (every normal or Ctrl-C
stop path) writes the rest.

Every `drain_period_s` a timer also takes whatever waits in each subscription's DDS
reader, until it is empty: the recorder does not depend on the executor's wait set
reporting a subscription ready. Under CPU starvation (issue 17) that report was lost:
the plant's 300 samples per topic had all reached the recorder's readers (every
HEARTBEAT acknowledged on the wire) and 129 of them still sat there, never handed to
the callback, 70 s after the plant had finished (docs/ros.md, "Starvation and stalls").

Run standalone: `python -m ceco_bringup.recorder OUT_BAG_DIR [--storage sqlite3]
[--timestamps sim] [--namespace /veh1]` (Ctrl-C stops).
"""

from __future__ import annotations

import sys
import threading
import time

from rclpy.node import Node
from rclpy.serialization import deserialize_message

from ceco_bringup.bag_writer import STORAGES, TIMESTAMP_MODES, BagWriter, SimTimeStamps
from ceco_msgs.msg import AcCommand, AcPower, CabinState
from ceco_ros import interfaces


def message_class(type_name: str):
    """The generated Python class of a 'pkg/msg/Name' type."""
    import importlib

    pkg, _, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.msg'), name)


class Recorder(Node):
    """Records STACK_TOPICS (or ``topics``) into ``bag_dir``."""

    def __init__(
        self,
        bag_dir,
        *,
        topics=None,
        storage: str = STORAGES[0],
        timestamps: str = 'receive',
        namespace: str = '',
        flush_period_s: float = 0.5,
        drain_period_s: float = 0.1,
        custom_data: dict | None = None,
        node_name: str = 'ceco_recorder',
        **node_kwargs,
    ):
        if timestamps not in TIMESTAMP_MODES:
            raise ValueError(f'timestamps: {timestamps!r} is not one of {TIMESTAMP_MODES}')
        super().__init__(node_name, namespace=namespace, **node_kwargs)
        self.writer = BagWriter(bag_dir, storage=storage)
        for key, value in (custom_data or {}).items():
            self.writer.set_custom_data(key, value)
        self._sim_stamps = SimTimeStamps() if timestamps == 'sim' else None
        self._lock = threading.Lock()
        self.topics = dict(interfaces.STACK_TOPICS if topics is None else topics)
        self.subs = {}
        self.bag_topics: dict[str, str] = {}
        """Stack topic name -> fully qualified name in the bag."""
        for topic, (type_name, offered, qos) in self.topics.items():
            sub = self.create_subscription(
                message_class(type_name), topic, self._make_cb(topic, type_name), qos, raw=True
            )
            self.subs[topic] = sub
            self.bag_topics[topic] = sub.topic_name
            self.writer.add_topic(sub.topic_name, type_name, offered)
        self.last_power_step = -1
        self.first_state_wall = None  # monotonic time of the first cabin/state [s]
        self.last_power_wall = None  # monotonic time of the latest hvac/power [s]
        self.n_messages = 0
        self.n_drained = 0  # messages the drain timer took (not handed out by the wait set first)
        self.received = dict.fromkeys(self.topics, 0)
        """Messages recorded per stack topic [-]."""
        # (step_index, publisher-side wall-clock stamp = rmw source_timestamp [ns]) of every state and
        # command, in arrival order: the benchmark's computational time ratio (command k sent - state t_k sent)
        self.source_ns = {interfaces.TOPIC_STATE: [], interfaces.TOPIC_COMMAND: []}
        self._step_type = {interfaces.TOPIC_STATE: CabinState, interfaces.TOPIC_COMMAND: AcCommand}
        self.create_timer(flush_period_s, self.flush)
        self.create_timer(drain_period_s, self.drain)

    def _make_cb(self, topic, type_name):
        def cb(data: bytes, info) -> None:  # two arguments: rclpy passes the message info
            self._record(topic, type_name, data, info)

        return cb

    def _record(self, topic: str, type_name: str, data: bytes, info) -> None:
        t_recv_ns = time.time_ns()
        with self._lock:
            if self.writer is None:
                return
            t_ns = t_recv_ns if self._sim_stamps is None else self._sim_stamps(type_name, data)
            self.writer.write(self.bag_topics[topic], t_ns, data)
            self.n_messages += 1
            self.received[topic] += 1
            if topic in self.source_ns:
                n = int(deserialize_message(data, self._step_type[topic]).step_index)
                self.source_ns[topic].append((n, int(info['source_timestamp'])))
            if topic == interfaces.TOPIC_POWER:
                self.last_power_step = int(deserialize_message(data, AcPower).step_index)
                self.last_power_wall = time.monotonic()
            elif topic == interfaces.TOPIC_STATE and self.first_state_wall is None:
                self.first_state_wall = time.monotonic()

    def drain(self) -> int:
        """Take and record everything waiting in the subscriptions' readers; the number taken.

        Runs on the executor's thread (a timer), so it never races the subscription callbacks.
        """
        taken = 0
        for topic, sub in self.subs.items():
            type_name = self.topics[topic][0]
            while self.writer is not None:
                with sub.handle:
                    got = sub.handle.take_message(sub.msg_type, True)
                if got is None:
                    break
                self._record(topic, type_name, got[0], got[1])
                taken += 1
        self.n_drained += taken
        return taken

    def publisher_counts(self) -> dict[str, int]:
        """Publishers this node's graph sees per recorded (stack) topic."""
        return {t: self.count_publishers(t) for t in self.topics}

    def flush(self) -> None:
        """Put everything received so far on disk as a complete bag."""
        with self._lock:
            if self.writer is not None:
                try:
                    self.writer.flush()
                except Exception as err:  # never let a flush error stop the recording
                    self.get_logger().error(f'bag flush failed: {err}')

    def close(self) -> dict[str, int]:
        """Finalise the bag (idempotent); the message count per bag topic."""
        with self._lock:
            if self.writer is None:
                return {}
            counts = self.writer.counts
            self.writer.close()
            self.writer = None
            return counts


def main(argv=None) -> int:
    """`python -m ceco_bringup.recorder BAG_DIR`: record until Ctrl-C."""
    import argparse

    import rclpy
    from rclpy.executors import ExternalShutdownException

    parser = argparse.ArgumentParser(
        prog='python -m ceco_bringup.recorder', description='record every ceco topic into a rosbag2 bag'
    )
    parser.add_argument('bag_dir')
    parser.add_argument('--storage', choices=STORAGES, default=STORAGES[0], help='storage plugin (default mcap)')
    parser.add_argument(
        '--timestamps',
        choices=TIMESTAMP_MODES,
        default='receive',
        help='bag timestamps: wall-clock receive time, or the simulation time (lockstep)',
    )
    parser.add_argument('--namespace', default='', help='namespace of the stack to record (default: root)')
    args, ros_args = parser.parse_known_args(sys.argv[1:] if argv is None else argv)
    rclpy.init(args=['recorder'] + ros_args)
    node = None
    try:
        node = Recorder(args.bag_dir, storage=args.storage, timestamps=args.timestamps, namespace=args.namespace)
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
