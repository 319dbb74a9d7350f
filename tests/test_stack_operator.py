"""Stack tests of what an operator sees (issue 17): stopping, start-up messages, parameters as
typed on a command line, a dead controller or preview source, commands from a foreign
participant, reconfiguring a managed node.

Real node processes over real DDS, each test on its own ROS_DOMAIN_ID (helpers of
tests/test_stack.py). No timed assertions: waits are bounded so a broken stack fails instead of
hanging; latencies are counted in plant steps or printed.
"""

from __future__ import annotations

import os
import signal
import time

import pytest

pytestmark = pytest.mark.stack

rclpy = pytest.importorskip('rclpy', reason='stack tests need the sourced ROS 2 workspace')
if not hasattr(pytest.importorskip('ceco_msgs.msg', reason='stack tests need the built ceco_msgs'), 'AcCommand'):
    pytest.skip('stack tests need the sourced ROS 2 workspace (ceco_msgs is not built here)', allow_module_level=True)

from test_stack import DdsPeer, _domain, _log_has, _proc  # noqa: E402

from ceco_bringup import supervisor  # noqa: E402


def _group_sigints(proc, n: int, gap_s: float) -> None:
    """``n`` SIGINTs to the process, ``gap_s`` apart (a terminal's Ctrl-C plus launch's own, and more)."""
    for _ in range(n):
        if not proc.running():
            return
        try:
            os.kill(proc.pid, signal.SIGINT)
        except ProcessLookupError:
            return
        time.sleep(gap_s)


@pytest.mark.parametrize('node', ['preview_node', 'plant_node', 'mpc_node'])
def test_repeated_sigint_during_cleanup_exits_0_and_says_so(tmp_path, node):
    """Ctrl-C under `ros2 launch` reaches a node twice (terminal and launch): a burst of SIGINTs, so
    that some land while the node is being destroyed, ends every node with status 0, a line
    saying it stopped, and no traceback (before: KeyboardInterrupt inside destroy_node, exit -2)."""
    env = supervisor.dds_env(_domain())
    params = {'scenario': 'sc03', 'timing': 'lockstep'}
    if node == 'mpc_node':
        params.update(strategy='ceco', autostart=True)
    proc = _proc(node, node, env, tmp_path / 'logs', params)
    ready = {'mpc_node': 'active: commanding', 'plant_node': 'scenario sc03', 'preview_node': 'scenario sc03'}[node]
    try:
        proc.start()
        _log_has(proc, ready, 120)
        _group_sigints(proc, 40, 0.002)
        rc = proc.proc.wait(timeout=30)
    finally:
        proc.stop()
    log = proc.log_text()
    assert rc == 0, log[-3000:]
    assert 'Traceback' not in log and 'KeyboardInterrupt' not in log, log[-3000:]
    assert f'[{node}]: stopped (SIGINT): exit 0' in log, log[-2000:]


def test_fatal_line_names_the_renamed_node_and_integers_are_taken_for_doubles(tmp_path):
    """`-p control_period_s:=5` (an integer for a double) is accepted (before: refused at start);
    an invalid value stops the node with one FATAL line naming the node as remapped
    (`__node:=ctl_a`, under `/veh1`), not the executable's default name, and status 2."""
    env = supervisor.dds_env(_domain())
    log_dir = tmp_path / 'logs'
    ok = supervisor.NodeProcess(
        'preview_int',
        'ceco_v2x_preview',
        'preview_node',
        env=env,
        log_dir=log_dir,
        params={'control_period_s': 5, 'publish_period_s': 5, 'timing': 'realtime'},
    )
    bad = supervisor.NodeProcess(
        'ctl_bad',
        'ceco_controller',
        'mpc_node',
        env=env,
        log_dir=log_dir,
        node_name='ctl_a',
        namespace='veh1',
        params={'strategy': 'ceco-turbo'},
    )
    try:
        ok.start()
        bad.start()
        assert bad.proc.wait(timeout=60) == 2
        _log_has(ok, 'grid 7 x 5.0 s', 60)
        assert ok.running()
    finally:
        ok.stop()
        bad.stop()
    fatal = [line for line in bad.log_text().splitlines() if '[FATAL]' in line]
    assert len(fatal) == 1 and '[veh1.ctl_a]' in fatal[0] and "strategy='ceco-turbo'" in fatal[0], fatal
    assert 'Traceback' not in bad.log_text() and 'Traceback' not in ok.log_text()


def test_unconfigured_controller_and_lone_plant_say_what_they_wait_for(tmp_path):
    """An mpc_node without autostart says how to start it (`ros2 lifecycle set ... configure`); a
    lockstep plant without peers says in its log (not only on /diagnostics) what step 0 waits for."""
    tn = DdsPeer(_domain(), 'operator')
    log_dir = tmp_path / 'logs'
    mpc = _proc('mpc_node', 'mpc_node', tn.env, log_dir, {'strategy': 'ceco'})
    plant = _proc('plant_node', 'plant_node', tn.env, log_dir, {'timing': 'lockstep'})
    try:
        mpc.start()
        plant.start()
        _log_has(mpc, 'ros2 lifecycle set /mpc_node configure', 60)
        _log_has(plant, 'waiting for subscribers before step 0', 60)
    finally:
        mpc.stop()
        plant.stop()
        tn.close()
    assert 'cabin/state subscribers' in plant.log_text()
