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
    # the burst may land while the node is still being constructed (its first log line comes from there)
    said = (f'[{node}]: stopped (SIGINT): exit 0', f'[{node}]: stopped (SIGINT) while starting: exit 0')
    assert any(line in log for line in said), log[-2000:]


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


@pytest.mark.parametrize('enclave_dir', [False, True], ids=['no-keystore', 'enclave-without-keys'])
def test_a_node_rcl_cannot_create_says_so_in_one_error_line_and_exits_1(tmp_path, enclave_dir):
    """ROS security on (Enforce) where the node cannot get its security: a keystore that does not exist (rcl's init
    fails) or an enclave directory without keys (node creation fails: this Fast DDS has no security libraries, or
    the keys are missing). plant_node from the built workspace says `could not start: ...` once as an ERROR with the
    keystore hint, no traceback, no `stopped ... exit 0` line, and exits 1 (before: `stopped (shutdown) while
    starting: exit 0`, then a traceback)."""
    import subprocess

    keystore = tmp_path / 'keystore'
    if enclave_dir:
        (keystore / 'enclaves' / 'ceco' / 'plant_node').mkdir(parents=True)
    env = dict(
        supervisor.dds_env(_domain()),
        ROS_SECURITY_ENABLE='true',
        ROS_SECURITY_STRATEGY='Enforce',
        ROS_SECURITY_KEYSTORE=str(keystore),
    )
    cmd = [supervisor.find_executable('ceco_plant_sim', 'plant_node'), '--ros-args', '--enclave', '/ceco/plant_node']
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=120)
    out = done.stdout + done.stderr
    print(out)
    assert done.returncode == 1, out
    errors = [line for line in out.splitlines() if line.startswith('[ERROR]')]
    assert len(errors) == 1 and '[plant_node]: could not start: ' in errors[0], out
    assert 'security' in errors[0].lower() and 'ROS_SECURITY_KEYSTORE' in errors[0], errors
    assert ('error creating node' if enclave_dir else 'failed to initialize rcl') in errors[0], errors
    assert 'Traceback' not in out and 'exit 0' not in out, out


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


def test_lone_realtime_plant_drives_on_its_acc_law_until_a_controller_commands(tmp_path):
    """A real-time plant_node with no controller (and the lockstep gate's defaults, 2 state
    subscribers and a command publisher, unmet): it stands for the vehicle, so it steps on its own
    clock from step 0 and its ACC law drives (AcPower.fallback). Before: it logged 'waiting for
    subscribers before step 0' and published nothing until a controller existed."""
    from test_stack import _wait_for

    from ceco_msgs.msg import AcPower, CabinState
    from ceco_ros import interfaces

    tn = DdsPeer(_domain(), 'vehicle_watch')
    states = tn.collect(CabinState, interfaces.TOPIC_STATE, interfaces.state_qos('realtime'))
    powers = tn.collect(AcPower, interfaces.TOPIC_POWER, interfaces.state_qos('realtime'))
    params = {'scenario': 'sc03', 'timing': 'realtime', 'control_period_s': 2.0, 'plant_dt_s': 0.5}
    plant = _proc('plant_node', 'plant_node', tn.env, tmp_path / 'logs', params)
    try:
        plant.start()
        _wait_for(lambda: len(powers) >= 6 and len(states) >= 6, 120, 'six plant steps without a controller', [plant])
    finally:
        plant.stop()
        tn.close()
    assert all(p.fallback for p in powers) and all(s.fallback for s in states[1:])  # the ACC law drove
    log = plant.log_text()
    assert 'waiting for subscribers' not in log and 'subscribers matched: starting at step 0' in log


def _realtime_stack(tn, log_dir, ts=2.0, dt=0.5, controller='baseline_node', **plant_extra):
    common = {'scenario': 'sc03', 'timing': 'realtime', 'control_period_s': ts}
    preview = _proc('preview_node', 'preview_node', tn.env, log_dir, dict(common, horizon_steps=6, publish_period_s=ts))
    ctrl = _proc(controller, controller, tn.env, log_dir, dict(common, horizon_steps=6, autostart=True))
    plant = _proc(
        'plant_node',
        'plant_node',
        tn.env,
        log_dir,
        dict(
            common,
            plant_dt_s=dt,
            duration_s=600.0,
            **{'lockstep.min_state_subscribers': 2, 'realtime.start_gate': True},
            **plant_extra,
        ),
    )
    return preview, ctrl, plant


def test_dead_preview_source_is_reported_from_the_first_missed_update(tmp_path):
    """SIGKILL of preview_node (real time, Ts 2 s): the controller's /diagnostics says the preview
    publishers lost their liveliness (lease 1 s) and then that the previews missed their update,
    with their age (before: OK for 33 s while the age grew)."""
    from diagnostic_msgs.msg import DiagnosticArray
    from test_stack import _diag_statuses, _values, _wait_for

    tn = DdsPeer(_domain(), 'preview_watch')
    diags = []
    tn.node.create_subscription(
        DiagnosticArray,
        '/diagnostics',
        lambda m: diags.append((time.monotonic(), m)),
        __import__('ceco_ros.interfaces', fromlist=['x']).QOS_DIAGNOSTICS,
    )
    procs = _realtime_stack(tn, tmp_path / 'logs')
    preview, ctrl, plant = procs

    def statuses(after=0.0):
        return [(t, st) for t, a in list(diags) if t > after for st in _diag_statuses([a], 'baseline_node')]

    try:
        for p in procs:
            p.start()
        _wait_for(
            lambda: any(st.level == b'\x00' for _, st in statuses()), 120, 'baseline_node OK (previews flowing)', procs
        )
        t_kill = time.monotonic()
        preview.kill()
        _wait_for(
            lambda: any('no live publisher' in st.message for _, st in statuses(t_kill)),
            30,
            'the lost preview publisher on /diagnostics',
            [ctrl, plant],
        )
        t_live = next(t for t, st in statuses(t_kill) if 'no live publisher' in st.message)
        _wait_for(
            lambda: any('no update for' in st.message for _, st in statuses(t_kill)), 30, 'the missed update', [ctrl]
        )
        t_age, late = next((t, st) for t, st in statuses(t_kill) if 'no update for' in st.message)
    finally:
        for p in reversed(procs):
            p.stop()
        tn.close()
    assert late.level == b'\x01' and 'v2x/weather_preview' in late.message
    assert float(_values(late)['weather_age_s']) > 2.0 + 2.0  # Ts + preview_timeout_s
    # from the first missed update on: every report whose weather is older than Ts + preview_timeout_s says so
    aged = [st for _, st in statuses(t_kill) if float(_values(st).get('weather_age_s', 'nan')) > 2.0 + 2.0]
    assert aged and all('no update for' in st.message for st in aged), [st.message for st in aged]
    assert 'the publisher lost its liveliness' in ctrl.log_text()
    # liveliness within its lease plus a report period; the age after Ts + preview_timeout_s (4 s)
    assert t_live - t_kill < t_age - t_kill
    print(
        f'\npreview_node killed: liveliness lost on /diagnostics after {t_live - t_kill:.1f} s, missed update after '
        f'{t_age - t_kill:.1f} s: "{late.message}"'
    )


def test_valid_commands_of_a_foreign_participant_are_not_applied(tmp_path):
    """A participant on the domain that reads cabin/state and sends, for every control step, a
    command valid in every field (the state's stamp and step, in-range inputs, a known strategy)
    without the bound controller's epoch, and a replay of the controller's own last command: the
    plant applies none of them (before: applied for 15 / 5 / 5 plant steps), counts them as
    foreign / duplicate on /diagnostics, and stays with its controller."""
    from diagnostic_msgs.msg import DiagnosticArray
    from test_stack import _diag_statuses, _values, _wait_for

    from ceco_msgs.msg import AcCommand, AcPower, CabinState
    from ceco_ros import interfaces

    ts = 2.0
    tn = DdsPeer(_domain(), 'intruder')
    powers, cmds, diags, injected = [], [], [], {'foreign': 0, 'replay': 0}
    tn.node.create_subscription(AcPower, interfaces.TOPIC_POWER, powers.append, interfaces.state_qos('realtime'))
    tn.node.create_subscription(AcCommand, interfaces.TOPIC_COMMAND, cmds.append, interfaces.QOS_COMMAND)
    tn.node.create_subscription(DiagnosticArray, '/diagnostics', diags.append, interfaces.QOS_DIAGNOSTICS)
    pub = tn.node.create_publisher(AcCommand, interfaces.TOPIC_COMMAND, interfaces.command_qos('realtime'))
    attack = {'on': False}
    rng = __import__('random').Random(20261202)

    def on_state(m):
        k = round(m.scenario_time_s / ts)
        if not attack['on'] or abs(m.scenario_time_s - k * ts) > 1e-9:
            return
        c = AcCommand(step_index=k, control_period_s=ts, blower_flow_kgps=0.1, evap_setpoint_c=5.0, strategy='baseline')
        c.header.stamp = m.header.stamp
        c.epoch, c.sequence = rng.choice((0, rng.getrandbits(64))), k + 1
        pub.publish(c)
        injected['foreign'] += 1
        own = [x for x in cmds if x.strategy == 'baseline' and x.epoch != c.epoch]
        if own:  # a replay of the controller's own last command
            pub.publish(own[-1])
            injected['replay'] += 1

    tn.node.create_subscription(CabinState, interfaces.TOPIC_STATE, on_state, interfaces.state_qos('realtime'))
    procs = _realtime_stack(tn, tmp_path / 'logs', ts=ts)
    try:
        for p in procs:
            p.start()
        _wait_for(lambda: sum(not p.fallback for p in powers) >= 8, 120, 'the plant under its controller', procs)
        attack['on'] = True
        n0 = len(powers)
        _wait_for(lambda: injected['foreign'] >= 10, 120, 'ten control steps of injected commands', procs)
        attack['on'] = False
        time.sleep(3.0)  # a last /diagnostics report
    finally:
        for p in reversed(procs):
            p.stop()
        tn.close()
    during = powers[n0:]
    applied = [(p.mdot_bl_kgps, p.t_evap_sp_c) for p in during]
    assert during and (0.1, 5.0) not in applied  # no injected command drove a plant step
    assert not any(p.fallback for p in during[2:])  # the controller kept the plant
    v = _values(_diag_statuses(diags, 'plant_node')[-1])
    assert int(v['rejected_foreign']) >= injected['foreign'] - 1, (v, injected)  # one may race the first binding
    assert int(v['command_sources_bound']) == 1
    plant_log = procs[2].log_text()
    assert 'rejected hvac/command' in plant_log and 'foreign: epoch' in plant_log
    assert injected['replay'] >= 1 and 'duplicate: sequence' in plant_log
    # each injected command is one rejection (a foreign one may race the first binding)
    assert int(v['rejected_total']) >= injected['foreign'] + injected['replay'] - 1, (v, injected)
    print(f'\nforeign participant: injected {injected}; plant applied none of {len(during)} steps; {v}')


_SIM_TIME_IN_REALTIME = (
    'use_sim_time is true but timing is realtime: nothing publishes /clock in real time; '
    'use timing lockstep or use_sim_time false'
)
_NOT_A_MODEL_STEP = 'control period 7.5 s must be a whole multiple of the model step 5.0 s'


def _set_param(tn, node: str, name: str, value):
    """``ros2 param set /<node> <name> <value>`` (bool, float or str): the node's SetParametersResult."""
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters

    kind, field = {
        bool: (ParameterType.PARAMETER_BOOL, 'bool_value'),
        float: (ParameterType.PARAMETER_DOUBLE, 'double_value'),
        str: (ParameterType.PARAMETER_STRING, 'string_value'),
    }[type(value)]
    client = tn.node.create_client(SetParameters, f'/{node}/set_parameters')
    req = SetParameters.Request(parameters=[Parameter(name=name, value=ParameterValue(type=kind, **{field: value}))])
    res = supervisor.call_service(client, req, 30.0, attempt_s=5.0)
    tn.node.destroy_client(client)
    assert res is not None, f'no answer from /{node}/set_parameters in 30 s'
    return res.results[0]


@pytest.mark.parametrize(
    ('node', 'params', 'line'),
    [
        ('plant_node', {'timing': 'realtime', 'lockstep.min_state_subscribers': 0, 'use_sim_time': True}, 'sim'),
        ('preview_node', {'timing': 'realtime', 'use_sim_time': True}, 'sim'),
        ('mpc_node', {'timing': 'realtime', 'use_sim_time': True, 'autostart': True}, 'sim'),
        ('mpc_node', {'timing': 'realtime', 'control_period_s': 7.5, 'autostart': True}, 'step'),
        ('baseline_node', {'control_period_s': 7.5, 'measurements': 'vehicle'}, 'step'),
    ],
    ids=['plant-sim-time', 'preview-sim-time', 'mpc-sim-time', 'mpc-ts-7.5', 'baseline-vehicle-ts-7.5'],
)
def test_a_start_that_cannot_work_is_one_fatal_line_and_exit_2(tmp_path, node, params, line):
    """use_sim_time true in real time (nothing publishes /clock: the plant published nothing, the controller
    refused every state as ahead of its clock) and a Ts the control model cannot step (mpc_node: configure failed
    after a clean start; baseline_node with the estimator of measurements vehicle the same) stop the node at start
    with one FATAL line and status 2, as any bad parameter."""
    env = supervisor.dds_env(_domain())
    proc = _proc(node, node, env, tmp_path / 'logs', params)
    try:
        proc.start()
        rc = proc.proc.wait(timeout=120)
    finally:
        proc.stop()
    log = proc.log_text()
    fatal = [x for x in log.splitlines() if '[FATAL]' in x]
    want = _SIM_TIME_IN_REALTIME if line == 'sim' else f'invalid parameter control_period_s=7.5: {_NOT_A_MODEL_STEP}'
    assert rc == 2, log[-3000:]
    assert len(fatal) == 1 and fatal[0].endswith(f'[{node}]: {want}'), log[-3000:]
    assert 'Traceback' not in log


def test_use_sim_time_and_the_model_step_are_refused_at_run_time_with_the_reason(tmp_path):
    """`ros2 param set` of use_sim_time true on a real-time node (controller, preview node, plant), of a real-time
    timing on an unconfigured use_sim_time controller, and of a Ts the model cannot step on an unconfigured
    mpc_node: each refused with the reason, the value kept; lockstep with use_sim_time true still starts and a
    whole multiple of the model step is taken."""
    tn = DdsPeer(_domain(), 'operator')
    log_dir = tmp_path / 'logs'
    mpc = _proc('mpc_node', 'mpc_node', tn.env, log_dir, {'strategy': 'ceco', 'use_sim_time': True})
    preview = _proc('preview_node', 'preview_node', tn.env, log_dir, {'timing': 'realtime'})
    plant = _proc(
        'plant_node', 'plant_node', tn.env, log_dir, {'timing': 'realtime', 'lockstep.min_state_subscribers': 0}
    )
    procs = (mpc, preview, plant)
    try:
        for p in procs:
            p.start()
        _log_has(mpc, 'ros2 lifecycle set /mpc_node configure', 120)
        r = _set_param(tn, 'mpc_node', 'timing', 'realtime')  # lockstep + use_sim_time true: started, unconfigured
        assert not r.successful and r.reason == _SIM_TIME_IN_REALTIME, r
        r = _set_param(tn, 'mpc_node', 'control_period_s', 7.5)
        assert not r.successful and r.reason == f'invalid parameter control_period_s=7.5: {_NOT_A_MODEL_STEP}', r
        assert _set_param(tn, 'mpc_node', 'control_period_s', 10.0).successful
        assert _set_param(tn, 'mpc_node', 'use_sim_time', False).successful
        assert _set_param(tn, 'mpc_node', 'timing', 'realtime').successful
        r = _set_param(tn, 'mpc_node', 'use_sim_time', True)
        assert not r.successful and r.reason == _SIM_TIME_IN_REALTIME, r
        for node in ('preview_node', 'plant_node'):
            r = _set_param(tn, node, 'use_sim_time', True)
            assert not r.successful and r.reason == _SIM_TIME_IN_REALTIME, (node, r)
            assert _set_param(tn, node, 'use_sim_time', False).successful
        assert all(p.running() for p in procs)
    finally:
        for p in procs:
            p.stop()
        tn.close()
    for p in procs:
        assert 'Traceback' not in p.log_text(), p.log_text()[-3000:]
