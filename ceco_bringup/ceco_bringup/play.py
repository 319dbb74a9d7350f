"""`ceco play`: republish a recorded bag on DDS (rosbag2 playback without rosbag2).

    ceco play DIR/bag [--rate R]               # original timing (R = 1) or R times faster
    ceco play DIR/bag --compare                # feed a fresh mpc_node, compare its commands

Plain playback publishes every recorded topic (except /rosout and
/parameter_events) under its recorded name with the stack's QoS profile,
spacing the messages as their bag timestamps are spaced (simulation time for a
lockstep run, so a 600 s drive plays in 600 s; receive time otherwise), divided
by --rate (--rate 0: as fast as possible). Other nodes on the same ROS_DOMAIN_ID (default: the environment's)
receive the drive as it happened: `ros2 run ceco_controller mpc_node` (or
this machine's install/lib equivalent) started with the run's parameters
then computes new commands from the recorded states and previews.

--compare does exactly that in one command: it starts the controller of the
recorded strategy (bag metadata: scenario, strategy, Ts, Np) in lockstep
timing on a private domain (in its root namespace), republishes the recorded states, previews and
/clock (not the recorded commands), paced by the new controller's answers
(step k+1 is sent once command k came back), and compares the new commands
with the recorded ones step by step. Exit status 0 when every step's command
matches within --tol.

Bags with either naming are read: relative names (older ceco bags), fully
qualified (`/cabin/state`, ceco's recorder and `ros2 bag record`) and
namespaced (`/veh1/cabin/state`; --namespace picks one vehicle of a bag that
holds several).
"""

from __future__ import annotations

import math
import sys
import threading
import time
from pathlib import Path

from ceco_bringup import cli_args
from ceco_core.control_grid import control_step_index


def build_parser() -> cli_args.Parser:
    """The argument parser of `ceco play`."""
    p = cli_args.Parser('ceco play', __doc__.split('\n\n')[0])
    p.add_argument('bag', type=Path, help='rosbag2 directory (DIR/bag of a ceco run, or any ros2 bag record bag)')
    p.add_argument(
        '--rate',
        type=cli_args.nonnegative_float,
        default=1.0,
        help='playback rate: 1 = recorded timing, R = R times faster, 0 = as fast as possible',
    )
    p.add_argument('--topics', nargs='*', default=None, help='topics to publish (default: all but /rosout)')
    p.add_argument(
        '--compare',
        action='store_true',
        help='start the recorded strategy\'s controller, feed it the recorded drive, compare commands',
    )
    cli_args.add_strategy(p, None, help_extra=' (--compare: one; default: the recorded one)')
    cli_args.add_scenario(
        p, default=None, help_extra=' (--compare; default: the run\'s scenario.yaml, the bag\'s metadata or parameters)'
    )
    cli_args.add_control_period(p)
    cli_args.add_horizon(p)
    p.add_argument(
        '--tol', type=cli_args.nonnegative_float, default=1e-9, help='--compare: tolerance on |command difference|'
    )
    cli_args.add_namespace(p, '--compare: namespace of the recorded stack (default: the only one in the bag)')
    cli_args.add_domain_id(p, 'ROS_DOMAIN_ID (default: the environment\'s; --compare: a private one)')
    p.add_argument(
        '--step-timeout-s',
        type=cli_args.positive_float,
        default=30.0,
        help='--compare: wall-clock wait for each new command [s]',
    )
    cli_args.add_no_progress(p)
    return p


def not_a_bag_message(path: Path) -> str:
    """Why ``path`` is not a rosbag2 directory, with the fix (the bag of a run directory)."""
    from ceco_bringup.bagrun import is_bag

    if is_bag(path / 'bag'):
        return f'{path} is a run directory, not a rosbag2 directory: its bag is {path / "bag"}'
    if path.is_dir():
        inner = sorted(d for d in path.iterdir() if d.is_dir() and is_bag(d / 'bag'))
        if inner:
            listed = ', '.join(str(d / 'bag') for d in inner[:3]) + (', ...' if len(inner) > 3 else '')
            return f'{path} holds run directories, not a rosbag2 directory: give one bag, e.g. {listed}'
    return f'{path} is not a rosbag2 directory (no metadata.yaml): give DIR/bag of a ceco run or a ros2 bag'


def missing_topics_message(requested, bag_topics) -> str | None:
    """Why ``--topics requested`` cannot be played from a bag holding ``bag_topics`` (None: all are in it)."""
    missing = [t for t in requested if t not in bag_topics]
    if not missing:
        return None
    return (
        f'--topics: {", ".join(missing)} not in the bag: give its topics by their bag names, '
        f'{", ".join(sorted(bag_topics))}'
    )


def namespace_message(namespace: str | None, bag_topics) -> str | None:
    """Why --compare cannot take the recorded stack under ``namespace`` from a bag holding ``bag_topics``.

    None when the bag holds the cabin state there (``namespace`` None: under any namespace; several are
    for ``ceco_bringup.bagrun`` to refuse).
    """
    from ceco_bringup.bagio import namespace_not_held, topic_namespaces
    from ceco_core.cli_flags import normalize_namespace
    from ceco_ros.topics import TOPIC_STATE

    held = topic_namespaces(bag_topics, (TOPIC_STATE,))
    if not held:
        return f'--compare: the bag holds no {TOPIC_STATE} under any namespace: no recorded stack to feed a controller'
    if namespace is None:
        return None
    try:
        ns = normalize_namespace(namespace)
    except ValueError as exc:
        return f'--namespace: {exc}'
    return None if ns in held else namespace_not_held(namespace, (TOPIC_STATE,), held)


def main(argv=None) -> int:
    """`ceco play`: plain playback, or --compare."""
    parser = build_parser()
    args = parser.parse_args(argv)
    from ceco_bringup import bagio
    from ceco_bringup.bagrun import is_bag
    from ceco_bringup.rundata import read_bag

    if not is_bag(args.bag):
        parser.error(not_a_bag_message(args.bag))
    if args.strategy is not None and len(args.strategy) != 1:
        parser.error(f'--strategy: --compare runs one controller, got {",".join(args.strategy)}')
    try:  # opening the bag reads its metadata and index: a damaged bag stops here, before any node starts
        bag_topics = read_bag(args.bag, bagio.topic_counts)
    except ValueError as err:
        print(f'ceco play: error: {err}', file=sys.stderr)
        return 2
    if args.compare:
        problem = namespace_message(args.namespace, bag_topics)
    else:
        problem = missing_topics_message(args.topics or (), bag_topics)
    if problem:
        parser.error(problem)
    return compare(args) if args.compare else play(args)


def _make_node(name, domain_id):
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    context = rclpy.Context()
    kw = {} if domain_id is None else {'domain_id': domain_id}
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO, **kw)
    node = rclpy.create_node(name, context=context)
    return context, node


def _publishers(node, types):
    """A publisher per topic of ``types`` ({name: message type}).

    The stack's QoS where the name is a stack topic under any namespace, else
    reliable depth 100.
    """
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from ceco_bringup import bagio
    from ceco_bringup.recorder import message_class
    from ceco_ros import interfaces

    pubs = {}
    for topic, type_name in types.items():
        stack = [n for n in interfaces.STACK_TOPICS if bagio.topic_namespace(topic, n) is not None]
        qos = (
            interfaces.STACK_TOPICS[stack[0]][1]
            if stack
            else QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        )
        pubs[topic] = node.create_publisher(message_class(type_name), topic, qos)
    return pubs


_NOT_REPLAYED = ('/rosout', '/parameter_events')
"""Infrastructure topics a bag may hold that plain playback does not republish."""


def play(args) -> int:
    """Republish the bag with its recorded spacing divided by --rate."""
    import rclpy

    from ceco_bringup import bagio

    types = bagio.topic_types(args.bag)
    if args.topics:
        types = {t: types[t] for t in args.topics}  # each in the bag (main)
    else:
        types = {t: m for t, m in types.items() if t not in _NOT_REPLAYED}
    context, node = _make_node('ceco_play', args.domain_id)
    n = 0
    bar = None
    if not args.no_progress:
        from tqdm import tqdm

        counts = bagio.topic_counts(args.bag)
        bar = tqdm(
            total=sum(counts.get(t, 0) for t in types),
            desc=f'ceco play x{args.rate:g}' if args.rate else 'ceco play (as fast as possible)',
            unit='msg',
            file=sys.stderr,
            mininterval=0.5,
        )
    try:
        pubs = _publishers(node, types)
        time.sleep(1.0)  # let subscribers discover the publishers
        t_wall0 = time.monotonic()
        t_bag0 = None
        for topic, t_ns, raw in bagio.read_raw(args.bag, list(types)):
            if t_bag0 is None:
                t_bag0 = t_ns
            if args.rate > 0:
                delay = t_wall0 + (t_ns - t_bag0) * 1e-9 / args.rate - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            pubs[topic].publish(raw)
            n += 1
            if bar is not None:
                bar.update(1)
        time.sleep(0.5)
        print(f'ceco play: published {n} messages from {args.bag} in {time.monotonic() - t_wall0:.1f} s')
    except KeyboardInterrupt:
        print(f'ceco play: interrupted after {n} messages', file=sys.stderr)
        return 130
    finally:
        if bar is not None:
            bar.close()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return 0


def compare(args) -> int:
    """Feed the recorded drive to a fresh controller and compare its commands with the recorded ones."""
    import numpy as np
    import rclpy

    from ceco_bringup import bagio, supervisor
    from ceco_bringup.bagrun import bag_run_info
    from ceco_msgs.msg import AcCommand
    from ceco_ros import conversions, interfaces

    scenario = args.scenario
    if scenario is None and (args.bag.parent / 'scenario.yaml').is_file():  # the run directory's copy
        scenario = str(args.bag.parent / 'scenario.yaml')
    try:
        info = bag_run_info(
            args.bag,
            args.namespace,
            scenario=scenario,
            strategy=args.strategy[0] if args.strategy else None,
            control_period_s=args.control_period_s,
            horizon_steps=args.horizon_steps,
        )
    except ValueError as err:
        print(f'ceco play: error: {err} (--namespace)', file=sys.stderr)
        return 2
    flags = {'scenario': '--scenario', 'strategy': '--strategy', 'control_period_s': '--control-period-s'}
    flags['horizon_steps'] = '--horizon-steps'
    missing = [key for key in flags if getattr(info, key) is None]
    if missing:
        print(
            f'ceco play: error: {args.bag} does not say its {", ".join(missing)} (no ceco metadata, recorded '
            f'parameters or controller messages): pass {" ".join(flags[k] + " ..." for k in missing)}',
            file=sys.stderr,
        )
        return 2
    strategy = str(info.strategy)
    print(
        'ceco play --compare: '
        + ', '.join(f'{k} {getattr(info, k)} ({info.sources[k]})' for k in flags if k in info.sources),
        file=sys.stderr,
    )
    try:
        recorded = bagio.load_commands(args.bag, namespace=args.namespace)
        types = bagio.topic_types(
            args.bag, (interfaces.TOPIC_STATE, interfaces.TOPIC_WEATHER, interfaces.TOPIC_TRAFFIC), args.namespace
        )
    except ValueError as err:  # a NamespaceError names --namespace itself
        print(f'ceco play: error: {err}', file=sys.stderr)
        return 2
    rec_by_k = {
        int(k): (m, s, r)
        for k, m, s, r in zip(
            recorded['k'], recorded['mdot_bl_kgps'], recorded['t_evap_sp_c'], recorded['recirc_share']
        )
    }
    domain = args.domain_id if args.domain_id is not None else supervisor.private_domain_id()
    env = supervisor.dds_env(domain)
    import os

    for key in ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'FASTDDS_BUILTIN_TRANSPORTS', 'FASTRTPS_DEFAULT_PROFILES_FILE'):
        os.environ[key] = env[key]
    exe = 'baseline_node' if strategy == 'baseline' else 'mpc_node'
    params = {
        'scenario': str(info.scenario),
        'timing': 'lockstep',
        'control_period_s': float(info.control_period_s or 0.0),
        'horizon_steps': int(info.horizon_steps or 0),
        'autostart': True,
    }  # managed node: self-activate
    if exe == 'mpc_node':
        params['strategy'] = strategy
    log_dir = args.bag.parent / 'play_logs'
    proc = supervisor.stack_node(exe, env=env, log_dir=log_dir, params=params)
    context, node = _make_node('ceco_play', domain)
    new = {}
    got = threading.Condition()

    def on_cmd(msg):
        with got:
            try:  # the door's -1 (not commanded) as NaN, as the recording's
                u = conversions.command_input(msg)
                new[int(msg.step_index)] = (u.mdot_bl_kgps, u.t_evap_sp_c, u.recirc_share)
            except ValueError:  # outside the actuator bounds: compared as sent (it differs)
                new[int(msg.step_index)] = (msg.blower_flow_kgps, msg.evap_setpoint_c, math.inf)
            got.notify_all()

    node.create_subscription(AcCommand, interfaces.TOPIC_COMMAND, on_cmd, interfaces.QOS_COMMAND)
    from rclpy.executors import SingleThreadedExecutor

    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    stop = threading.Event()

    def spin_loop():
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.05)

    spin = threading.Thread(target=spin_loop, daemon=True)
    spin.start()
    proc.start()
    ts = float(params['control_period_s'])
    try:
        pubs = _publishers(node, types)  # the stack names, in this node's (root) namespace
        t0 = time.monotonic()
        while (
            pubs[interfaces.TOPIC_STATE].get_subscription_count() < 1
            or node.count_publishers(interfaces.TOPIC_COMMAND) < 1
        ):
            if not proc.running():
                print(f'ceco play: {exe} exited:\n{proc.log_text()[-2000:]}', file=sys.stderr)
                return 1
            if time.monotonic() - t0 > 120:
                print('ceco play: the controller did not come up within 120 s', file=sys.stderr)
                return 1
            time.sleep(0.05)
        # Causal order per control step k (the bag's receive order across topics
        # is not causal): every state of the period, then previews k, then wait
        # for the new command k.
        from rclpy.serialization import deserialize_message

        from ceco_msgs.msg import CabinState

        steps: dict[int, dict] = {}
        for topic, _, raw in bagio.read_raw(args.bag, list(types), args.namespace):
            if topic == interfaces.TOPIC_STATE:
                msg = deserialize_message(raw, CabinState)
                k = int(msg.scenario_time_s // ts + 1e-9)
                on_grid = control_step_index(msg.scenario_time_s, ts) is not None
                steps.setdefault(k, {}).setdefault('states', []).append((not on_grid, msg.step_index, raw))
            elif topic in (interfaces.TOPIC_WEATHER, interfaces.TOPIC_TRAFFIC):
                k = int(deserialize_message(raw, _cls(topic)).step_index)
                steps.setdefault(k, {})[topic] = raw
        order = sorted(steps)
        if not args.no_progress:
            from tqdm import tqdm

            order = tqdm(order, desc=f'ceco play --compare {strategy}', unit='step', file=sys.stderr, leave=False)
        for k in order:
            step = steps[k]
            for _, _, raw in sorted(step.get('states', []), key=lambda x: (x[0], x[1])):
                pubs[interfaces.TOPIC_STATE].publish(raw)
            for topic in (interfaces.TOPIC_WEATHER, interfaces.TOPIC_TRAFFIC):
                if topic in step:
                    pubs[topic].publish(step[topic])
            if k in rec_by_k:
                with got:
                    if not got.wait_for(lambda k=k: k in new, timeout=args.step_timeout_s):
                        print(f'ceco play: no new command for step {k} within {args.step_timeout_s} s', file=sys.stderr)
                        break
    except KeyboardInterrupt:
        print('ceco play: interrupted', file=sys.stderr)
        return 130
    finally:
        proc.stop()
        stop.set()
        spin.join(timeout=2.0)
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    ks = sorted(k for k in rec_by_k if k in new)
    if not ks:
        print('ceco play: no command to compare', file=sys.stderr)
        return 1
    d_m = np.array([abs(new[k][0] - rec_by_k[k][0]) for k in ks])
    d_s = np.array([abs(new[k][1] - rec_by_k[k][1]) for k in ks])
    d_r = np.array([door_difference(new[k][2], rec_by_k[k][2]) for k in ks])
    worst = int(ks[int(np.argmax(np.maximum(np.maximum(d_m / 0.12, d_s / 7.0), d_r)))])
    print(
        f'ceco play --compare: {strategy} re-run on the recorded drive of {args.bag}: '
        f'{len(ks)}/{len(rec_by_k)} steps compared; max |d blower| {d_m.max():.3e} kg/s, '
        f'max |d set-point| {d_s.max():.3e} K, max |d door| {d_r.max():.3e} (worst step {worst})'
    )
    ok = len(ks) == len(rec_by_k) and max(d_m.max(), d_s.max(), d_r.max()) <= args.tol
    print('commands identical to the recording' if ok else 'commands differ from the recording')
    return 0 if ok else 1


def door_difference(a: float, b: float) -> float:
    """|a - b| of two door commands [0..1]; both not commanded (NaN) is 0, one of them not commanded is inf."""
    if math.isnan(a) or math.isnan(b):
        return 0.0 if math.isnan(a) and math.isnan(b) else math.inf
    return abs(a - b)


def _cls(topic):
    from ceco_msgs.msg import TrafficPreview, WeatherPreview
    from ceco_ros import interfaces

    return WeatherPreview if topic == interfaces.TOPIC_WEATHER else TrafficPreview


if __name__ == '__main__':
    sys.exit(main())
