"""Stack tests for namespaces and several vehicles: real node processes over
real DDS (headless, localhost-only, each test its own ROS_DOMAIN_ID), as in
tests/test_stack.py, whose helpers they use."""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.stack

rclpy = pytest.importorskip('rclpy', reason='stack tests need the sourced ROS 2 workspace')

from test_stack import DdsPeer, _cli, _domain, _wait_for  # noqa: E402

from ceco_bringup import bagio, supervisor  # noqa: E402


def _get_parameter(peer: DdsPeer, node: str, name: str, timeout_s: float = 60.0):
    """`ros2 param get NODE NAME` over DDS: the node's get_parameters service.

    A request without an answer after 5 s is sent again: Fast DDS can drop the response
    when the node has not yet matched this client's reader (CI, 5 Dec 2026: three nodes
    starting at once on 2 cores, /veh1 never answered the one request in 60 s)."""
    from rcl_interfaces.srv import GetParameters
    from rclpy.parameter import parameter_value_to_python

    client = peer.node.create_client(GetParameters, f'{node}/get_parameters')
    try:
        assert client.wait_for_service(timeout_sec=timeout_s), f'{node}/get_parameters not found'
        res = supervisor.call_service(client, GetParameters.Request(names=[name]), timeout_s, attempt_s=5.0)
        assert res is not None, f'no answer from {node}/get_parameters in {timeout_s} s'
        return parameter_value_to_python(res.values[0])
    finally:
        peer.node.destroy_client(client)


def test_namespaced_node_reads_its_parameter_file(tmp_path):
    """preview_node with horizon_steps: 9 in a copy of its installed parameter
    file (key /**/preview_node) reports 9 via its parameter service under /veh1
    and in the root namespace; the same file keyed by the bare node name is
    ignored under /veh2, which falls back to the declared default 6."""
    installed = Path(supervisor.share_file('ceco_v2x_preview', 'config/preview_node.yaml'))
    text = installed.read_text()
    assert text.count('    horizon_steps: 6 ') == 1 and '\n/**/preview_node:' in text
    wildcard = tmp_path / 'preview_wildcard.yaml'
    wildcard.write_text(text.replace('    horizon_steps: 6 ', '    horizon_steps: 9 '))
    bare = tmp_path / 'preview_bare.yaml'
    bare.write_text(wildcard.read_text().replace('\n/**/preview_node:', '\npreview_node:'))
    peer = DdsPeer(_domain(), 'param_probe')
    procs = [
        supervisor.NodeProcess(
            name,
            'ceco_v2x_preview',
            'preview_node',
            params_files=[f],
            env=peer.env,
            log_dir=tmp_path / 'logs',
            namespace=ns,
        )
        for name, f, ns in (('veh1', wildcard, 'veh1'), ('root', wildcard, ''), ('veh2', bare, 'veh2'))
    ]
    try:
        for p in procs:
            p.start()
        values = {
            node: _get_parameter(peer, node, 'horizon_steps')
            for node in ('/veh1/preview_node', '/preview_node', '/veh2/preview_node')
        }
        assert values == {'/veh1/preview_node': 9, '/preview_node': 9, '/veh2/preview_node': 6}
        want = {('preview_node', '/veh1'), ('preview_node', '/'), ('preview_node', '/veh2')}
        # the node list reaches the peer's graph apart from the services answered above: a single read raced it
        # (CI, 4 Dec 2026: '/' not yet listed); waited for, a node outside its namespace still fails here
        _wait_for(lambda: want <= set(peer.node.get_node_names_and_namespaces()), 30.0, f'{sorted(want)} in the graph')
    finally:
        for p in procs:
            p.stop()
        peer.close()
    assert 'grid 10 x 5.0 s' in procs[0].log_text() and 'grid 7 x 5.0 s' in procs[2].log_text()


def test_two_namespaced_vehicles_in_one_domain_no_cross_talk(tmp_path):
    """Two `ceco run --namespace` stacks at once in ONE domain, taken from the
    user's ROS_DOMAIN_ID, real-time timing (lockstep needs a domain per stack:
    /clock is global): /veh1 runs the baseline on sc03 (35 degC), /veh2 ceco-ioch
    on sc03_mild (28 degC). Each bag holds its own vehicle's 30 states exactly
    once and only its own controller's commands; the graph shows both stacks."""
    domain = _domain()
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
    runs = {'veh1': ('baseline', 'sc03', 35.0), 'veh2': ('ceco-ioch', 'sc03_mild', 28.0)}
    n_steps = 30
    peer = DdsPeer(domain, 'fleet_probe')
    procs = {}
    try:
        for ns, (strategy, scenario, _) in runs.items():
            procs[ns] = _cli(
                'run',
                '--scenario',
                scenario,
                '--strategy',
                strategy,
                '--timing',
                'realtime',
                '--duration-s',
                str(n_steps),
                '--namespace',
                ns,
                '--out',
                str(tmp_path / ns),
                '--no-progress',
                env=env,
            )

        def graph():
            return set(peer.node.get_node_names_and_namespaces())

        expected = {
            ('plant_node', '/veh1'),
            ('preview_node', '/veh1'),
            ('baseline_node', '/veh1'),
            ('ceco_recorder', '/veh1'),
            ('plant_node', '/veh2'),
            ('preview_node', '/veh2'),
            ('mpc_node', '/veh2'),
            ('ceco_recorder', '/veh2'),
        }
        _wait_for(
            lambda: expected <= graph() or any(p.poll() is not None for p in procs.values()),
            180,
            'both stacks in the graph',
        )
        assert expected <= graph(), graph()
        texts = {ns: p.communicate(timeout=300)[0] for ns, p in procs.items()}
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.kill()
        peer.close()
    for ns, (strategy, scenario, t_amb_c) in runs.items():
        assert procs[ns].returncode == 0, texts[ns]
        out = tmp_path / ns
        metrics = json.loads((out / 'metrics.json').read_text())
        assert (metrics['ros_domain_id'], metrics['ros_namespace']) == (domain, f'/{ns}')
        assert (metrics['strategy'], metrics['scenario']) == (strategy, scenario)
        states = [m for _, _, m in bagio.read_messages(out / 'bag', ('cabin/state',))]
        assert [m.step_index for m in states] == list(range(n_steps))  # own states, each once
        assert {m.t_amb_c for m in states} == {t_amb_c}  # own scenario's weather
        cmds = bagio.load_commands(out / 'bag')
        assert set(cmds['strategy']) == {strategy}  # own controller only
        assert 4 <= cmds['k'].size <= 7 and len(set(cmds['k'].tolist())) == cmds['k'].size
        powers = [m for _, _, m in bagio.read_messages(out / 'bag', ('hvac/power',))]
        assert [m.step_index for m in powers] == list(range(n_steps))


def _node_pids_in_namespace(ns: str) -> list[int]:
    pids = []
    for proc in Path('/proc').iterdir():
        if proc.name.isdigit():
            try:
                cmd = (proc / 'cmdline').read_bytes().split(b'\0')
            except OSError:
                continue
            if f'__ns:={ns}'.encode() in cmd:
                pids.append(int(proc.name))
    return pids


def test_sigkill_to_ceco_run_stops_its_nodes(tmp_path):
    """SIGKILL to `ceco run` (no chance to clean up): its three node processes
    get the parent-death signal (setpriv --pdeathsig SIGINT) and exit."""
    ns = f'/kill{os.getpid()}'
    p = _cli(
        'run',
        '--scenario',
        'sc03',
        '--strategy',
        'baseline',
        '--timing',
        'realtime',
        '--duration-s',
        '60',
        '--namespace',
        ns,
        '--out',
        str(tmp_path / 'run'),
        '--no-progress',
        '--domain-id',
        str(_domain()),
    )
    try:
        _wait_for(lambda: len(_node_pids_in_namespace(ns)) == 3 or p.poll() is not None, 120, 'three nodes')
        pids = _node_pids_in_namespace(ns)
        assert len(pids) == 3, p.communicate()[0] if p.poll() is not None else pids
        time.sleep(2.0)  # nodes up and spinning
        p.send_signal(signal.SIGKILL)
        p.wait(timeout=10)
        _wait_for(lambda: not _node_pids_in_namespace(ns), 30, 'the nodes to exit')
    finally:
        if p.poll() is None:
            p.kill()
        for pid in _node_pids_in_namespace(ns):
            os.kill(pid, signal.SIGKILL)
