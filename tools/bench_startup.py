"""Key-on benchmark: each node's time from process start to its first log line and to its first
valid output, with its peers already up (issue 12, item 5).

    source ros_ws/install/setup.bash
    python tools/bench_startup.py [--repeat 3] [--nodes mpc_node baseline_node plant_node preview_node]

For every node the benchmark process is the node's peers: an rclpy node on a private
ROS_DOMAIN_ID that is up before the node's process starts, that feeds it valid inputs
(cabin/state and both previews for the controllers, a command publisher for the plant,
cabin/state for the preview node) and receives its output (hvac/command, cabin/state,
v2x/weather_preview). A managed node (lifecycle services in the graph) is driven through
configure and activate by the peer as soon as its services appear, as ``ceco run`` does.

Reference measured in the same run: a minimal rclpy talker started the same way
(interpreter, rclpy, one publisher), from process start to its first message here; every
time is also printed as a ratio to it; so is each process's peak resident memory (VmHWM of
/proc/PID/status, read at its first output, before it is stopped). Nothing is asserted: numbers only.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

REFERENCE = r"""
import rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node('bench_reference')
pub = node.create_publisher(String, 'bench_reference', 10)
print('reference up', flush=True)
timer = node.create_timer(0.01, lambda: pub.publish(String(data='x')))
rclpy.spin(node)
"""


def _reader(stream, lines: list) -> None:
    for raw in iter(stream.readline, b''):
        lines.append((time.monotonic(), raw.decode(errors='replace').rstrip()))


class Peer:
    """The node's peers, in this process, on their own domain."""

    def __init__(self, domain: int):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        from ceco_bringup import supervisor

        self.env = supervisor.dds_env(domain)
        for key in ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'FASTDDS_BUILTIN_TRANSPORTS', 'FASTRTPS_DEFAULT_PROFILES_FILE'):
            os.environ[key] = self.env[key]
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node('bench_peer', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.first_output: float | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self):
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=0.005)

    def on_output(self, _msg) -> None:
        if self.first_output is None:
            self.first_output = time.monotonic()

    def close(self):
        import rclpy

        self._stop.set()
        self._thread.join(timeout=2.0)
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def _drive_lifecycle(peer: Peer, name: str, stop: threading.Event) -> None:
    """configure + activate ``name`` once its change_state service is up (no-op for a plain node)."""
    from lifecycle_msgs.msg import Transition
    from lifecycle_msgs.srv import ChangeState

    client = peer.node.create_client(ChangeState, f'/{name}/change_state')
    while not stop.is_set() and not client.wait_for_service(timeout_sec=0.01):
        pass
    for tid in (Transition.TRANSITION_CONFIGURE, Transition.TRANSITION_ACTIVATE):
        if stop.is_set():
            return
        fut = client.call_async(ChangeState.Request(transition=Transition(id=tid)))
        while not fut.done() and not stop.is_set():
            time.sleep(0.002)


def _state0():
    from ceco_msgs.msg import CabinState
    from ceco_ros import conversions

    msg = CabinState(
        step_index=0,
        scenario_time_s=0.0,
        t_cab_c=45.0,
        t_int_c=50.0,
        t_shell_c=55.0,
        t_glass_c=55.0,
        t_evap_c=45.0,
        t_vent_c=45.0,
        rh_cab=0.2,
        t_amb_c=35.0,
        solar_wm2=800.0,
        rh=0.4,
        speed_mps=10.0,
        mdot_bl_kgps=0.17,
        t_evap_sp_c=3.0,
    )
    msg.header.stamp = conversions.stamp_from_s(0.0)
    return msg


def _controller_inputs(peer: Peer):
    """Publishers and messages: a valid state 0 and previews 0 (sc03)."""
    from ceco_msgs.msg import CabinState, TrafficPreview, WeatherPreview
    from ceco_ros import conversions, interfaces
    from ceco_v2x_preview.preview import PreviewQuality, make_previews
    from ceco_v2x_preview.scenario import load_scenario

    stamp = conversions.stamp_from_s(0.0)
    w, s = conversions.previews_to_msgs(
        make_previews(load_scenario('sc03'), 0.0, 5.0, 7, PreviewQuality()), 0, stamp, 'perfect'
    )
    return [
        (peer.node.create_publisher(CabinState, interfaces.TOPIC_STATE, interfaces.QOS_STATE), _state0()),
        # the preview node's QoS (a liveliness lease): mpc_node's liveliness probes match it
        (
            peer.node.create_publisher(
                WeatherPreview, interfaces.TOPIC_WEATHER, interfaces.preview_publisher_qos('realtime')
            ),
            w,
        ),
        (
            peer.node.create_publisher(
                TrafficPreview, interfaces.TOPIC_TRAFFIC, interfaces.preview_publisher_qos('realtime')
            ),
            s,
        ),
    ]


def _preview_inputs(peer: Peer):
    from ceco_msgs.msg import CabinState
    from ceco_ros import interfaces

    return [(peer.node.create_publisher(CabinState, interfaces.TOPIC_STATE, interfaces.QOS_STATE), _state0())]


def _feed(peer: Peer, pubs, stop: threading.Event) -> None:
    """Re-send the inputs every 50 ms, once matched, until the output came."""
    while not stop.is_set() and peer.first_output is None:
        if pubs[0][0].get_subscription_count() > 0:
            for pub, msg in pubs:
                pub.publish(msg)
        time.sleep(0.05)


NODES = {
    # executable (ceco_bringup.supervisor.STACK_NODES): (output topic key, parameters, feeder)
    'mpc_node': ('command', {'strategy': 'ceco-ioch'}, _controller_inputs),
    'baseline_node': ('command', {}, _controller_inputs),
    'plant_node': ('state', {'lockstep.min_state_subscribers': 1, 'lockstep.min_command_subscribers': 1}, None),
    'preview_node': ('weather', {}, _preview_inputs),
}


def _peak_rss_mib(pid: int) -> float | None:
    """A live process's peak resident set size so far (VmHWM) [MiB]; None where /proc has none."""
    try:
        for line in Path(f'/proc/{pid}/status').read_text().splitlines():
            if line.startswith('VmHWM:'):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return None


def run_node(name: str, domain: int, timeout_s: float, extra: dict | None = None) -> dict:
    from ceco_bringup import supervisor
    from ceco_msgs.msg import AcCommand, CabinState, WeatherPreview
    from ceco_ros import interfaces

    out, params, feeder = NODES[name]
    peer = Peer(domain)
    stop = threading.Event()
    topics = {
        'command': (AcCommand, interfaces.TOPIC_COMMAND, interfaces.QOS_COMMAND),
        'state': (CabinState, interfaces.TOPIC_STATE, interfaces.QOS_STATE),
        'weather': (WeatherPreview, interfaces.TOPIC_WEATHER, interfaces.QOS_PREVIEW),
    }
    cls, topic, qos = topics[out]
    peer.node.create_subscription(cls, topic, peer.on_output, qos)
    if name == 'plant_node':  # the plant starts once a command publisher is matched
        # mpc_node's QoS (a liveliness lease): the plant's liveliness probe matches it
        peer.node.create_publisher(AcCommand, interfaces.TOPIC_COMMAND, interfaces.command_publisher_qos('lockstep'))
    threads = [threading.Thread(target=_drive_lifecycle, args=(peer, name, stop), daemon=True)]
    if feeder is not None:
        threads.append(threading.Thread(target=_feed, args=(peer, feeder(peer), stop), daemon=True))
    # the command line ceco run starts the node with (installed parameter file, then -p overrides)
    cmd = supervisor.stack_node(name, env=peer.env, log_dir=Path('.'), params=dict(params, **(extra or {}))).cmd
    lines: list = []
    time.sleep(0.3)  # peers up and announced before the node starts
    t0 = time.monotonic()
    proc = subprocess.Popen(
        cmd, env=peer.env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL
    )
    reader = threading.Thread(target=_reader, args=(proc.stdout, lines), daemon=True)
    reader.start()
    for t in threads:
        t.start()
    try:
        while peer.first_output is None and time.monotonic() - t0 < timeout_s and proc.poll() is None:
            time.sleep(0.005)
    finally:
        stop.set()
        rss = _peak_rss_mib(proc.pid)
        proc.send_signal(2)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        for t in threads:
            t.join(timeout=2)
        peer.close()

    def first(*needles):
        t = next((t for t, text in lines if any(n in text for n in needles)), None)
        return None if t is None else t - t0

    return {
        'first_log_s': first('[INFO]', '[WARN]'),
        'configured_s': first('configured in'),
        'active_s': first('active: commanding'),
        'first_output_s': None if peer.first_output is None else peer.first_output - t0,
        'peak_rss_mib': rss,
        'log_head': [text for _, text in lines[:3]],
        'log': [text for _, text in lines],
    }


def run_reference(domain: int, timeout_s: float) -> tuple[float | None, float | None]:
    """The minimal talker's time to its first message here [s] and its peak RSS then [MiB]."""
    from std_msgs.msg import String

    peer = Peer(domain)
    peer.node.create_subscription(String, 'bench_reference', peer.on_output, 10)
    time.sleep(0.3)
    t0 = time.monotonic()
    proc = subprocess.Popen(
        [sys.executable, '-c', REFERENCE],
        env=peer.env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        stdin=subprocess.DEVNULL,
    )
    try:
        while peer.first_output is None and time.monotonic() - t0 < timeout_s:
            time.sleep(0.005)
    finally:
        rss = _peak_rss_mib(proc.pid)
        proc.send_signal(2)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
        peer.close()
    return (None if peer.first_output is None else peer.first_output - t0), rss


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--repeat', type=int, default=3)
    p.add_argument('--nodes', nargs='*', default=list(NODES), choices=list(NODES))
    p.add_argument('--timeout-s', type=float, default=60.0)
    p.add_argument('--domain-id', type=int, default=None)
    p.add_argument('--json', default=None, help='write the numbers to this file')
    p.add_argument(
        '--autostart',
        action='store_true',
        help='managed nodes configure and activate themselves (parameter autostart:=true)',
    )
    args = p.parse_args(argv)
    from ceco_bringup import supervisor

    domain = args.domain_id if args.domain_id is not None else supervisor.private_domain_id()
    refs = [run_reference(domain, args.timeout_s) for _ in range(args.repeat)]
    ref = [t for t, _ in refs if t is not None]
    ref_med = statistics.median(ref) if ref else float('nan')
    ref_rss = [m for _, m in refs if m is not None]
    ref_rss_med = statistics.median(ref_rss) if ref_rss else float('nan')
    result = {'reference_first_message_s': ref_med, 'reference_peak_rss_mib': ref_rss_med, 'nodes': {}}
    print(
        f'reference (minimal rclpy talker, first message): median {ref_med:.3f} s, peak RSS {ref_rss_med:.0f} MiB '
        f'over {len(ref)} runs'
    )
    print(
        f'{"node":<14} {"first log [s]":>14} {"configured [s]":>15} {"active [s]":>10} {"first output [s]":>17} '
        f'{"output / ref":>13} {"peak RSS [MiB]":>15} {"RSS / ref":>10}'
    )
    for name in args.nodes:
        extra = {'autostart': 'true'} if args.autostart and name in ('mpc_node', 'baseline_node') else None
        runs = [run_node(name, domain, args.timeout_s, extra) for _ in range(args.repeat)]
        logs = [r['first_log_s'] for r in runs if r['first_log_s'] is not None]
        outs = [r['first_output_s'] for r in runs if r['first_output_s'] is not None]
        med_log = statistics.median(logs) if logs else float('nan')
        med_out = statistics.median(outs) if outs else float('nan')
        cfg = [r['configured_s'] for r in runs if r['configured_s'] is not None]
        act = [r['active_s'] for r in runs if r['active_s'] is not None]
        med_cfg = statistics.median(cfg) if cfg else float('nan')
        med_act = statistics.median(act) if act else float('nan')
        rss = [r['peak_rss_mib'] for r in runs if r['peak_rss_mib'] is not None]
        med_rss = statistics.median(rss) if rss else float('nan')
        result['nodes'][name] = {
            'first_log_s': logs,
            'first_output_s': outs,
            'configured_s': cfg,
            'active_s': act,
            'median_first_log_s': med_log,
            'median_first_output_s': med_out,
            'missing_outputs': len(runs) - len(outs),
            'peak_rss_mib': rss,
            'median_peak_rss_mib': med_rss,
        }
        print(
            f'{name:<14} {med_log:>14.3f} {med_cfg:>15.3f} {med_act:>10.3f} {med_out:>17.3f} '
            f'{med_out / ref_med:>13.1f} {med_rss:>15.0f} {med_rss / ref_rss_med:>10.2f}'
            + (
                ''
                if len(outs) == len(runs)
                else f'  ({len(runs) - len(outs)} runs without output: {runs[0]["log_head"]})'
            ),
            flush=True,
        )
    if args.json:
        with open(args.json, 'w') as f:
            json.dump(result, f, indent=2)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
