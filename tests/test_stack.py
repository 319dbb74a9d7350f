"""Stack tests: the real node processes over real (headless, localhost-only)
DDS, each test on its own ROS_DOMAIN_ID, UDP-only transport (no shared-memory
segments left behind by killed processes).

Needs the built workspace (`bash tools/setup.sh; source tools/env.sh`, which
tools/test.sh does). No timed assertions: waits are bounded only so a broken
stack fails instead of hanging.
"""
from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

pytestmark = pytest.mark.stack

rclpy = pytest.importorskip('rclpy', reason='stack tests need the sourced ROS 2 workspace')

from ceco_bringup import bagio, supervisor  # noqa: E402
from ceco_ros import conversions, interfaces  # noqa: E402

_DOMAIN_COUNTER = [0]


def _domain() -> int:
    """A domain id per test (and per pytest process)."""
    _DOMAIN_COUNTER[0] += 1
    return 1 + (os.getpid() * 13 + _DOMAIN_COUNTER[0] * 17) % 100


def _wait_for(cond, timeout_s: float, what: str, procs=()):
    t0 = time.monotonic()
    while not cond():
        for p in procs:
            if p.proc is not None and not p.running():
                raise AssertionError(f'{p.name} exited ({p.returncode()}) while waiting for {what}:\n'
                                     + p.log_text()[-3000:])
        if time.monotonic() - t0 > timeout_s:
            raise AssertionError(f'gave up waiting ({timeout_s} s) for {what}')
        time.sleep(0.02)


class DdsPeer:
    """An in-process rclpy node on a given domain, spun in a thread."""

    def __init__(self, domain: int, name: str = 'stack_test'):
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
        env = supervisor.dds_env(domain)
        keys = ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'FASTDDS_BUILTIN_TRANSPORTS', 'FASTRTPS_DEFAULT_PROFILES_FILE')
        self._saved_env = {key: os.environ.get(key) for key in keys}
        for key in keys:   # read by the rmw when this process's participant is created
            os.environ[key] = env[key]
        self.env = env
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.received: dict[str, list] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self):
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=0.02)

    def collect(self, msg_type, topic, qos):
        box = self.received.setdefault(topic, [])
        self.node.create_subscription(msg_type, topic, box.append, qos)
        return box

    def close(self):
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        for key, value in self._saved_env.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def _recording_peer(tmp_path, **recorder_kw):
    """A test peer on a fresh domain with a rosbag2 Recorder spinning in it: (peer, recorder, log dir, bag)."""
    from ceco_bringup.recorder import Recorder
    tn = DdsPeer(_domain(), 'unused')
    bag = tmp_path / 'bag'
    rec = Recorder(bag, context=tn.context, **recorder_kw)
    tn.executor.add_node(rec)
    return tn, rec, tmp_path / 'logs', bag


def _proc(name, pkg, exe, env, log_dir, params):
    return supervisor.NodeProcess(name, pkg, exe, env=env, log_dir=log_dir, params=params,
                                  params_files=[supervisor.share_file(pkg, f'config/{exe}.yaml')])


def _cli(*args, **kw):
    return subprocess.Popen([sys.executable, '-m', 'ceco_bringup.cli', *args], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, **kw)


# ----------------------------------------------------------------------------
def test_short_closed_loop_over_dds_matches_simulator(tmp_path):
    """`ceco run` on 60 s of SC03 with ceco-ioch: the cabin cools, every command
    is inside the actuator bounds, one command per control step and one state
    per plant step in the bag, and the metrics equal the in-process simulator's."""
    out = tmp_path / 'run'
    p = _cli('run', '--scenario', 'sc03', '--strategy', 'ceco-ioch', '--duration-s', '60', '--out', str(out),
             '--no-progress', '--domain-id', str(_domain()))
    text, _ = p.communicate(timeout=300)
    assert p.returncode == 0, text
    bag = out / 'bag'
    ts = bagio.load_run_timeseries(bag)
    assert ts['t_s'].tolist() == [float(i) for i in range(60)]
    assert ts['t_cab_c'][-1] < ts['t_cab_c'][0] - 3.0          # cabin pulled down by > 3 K in a minute
    cmds = bagio.load_commands(bag)
    assert sorted(cmds['k'].tolist()) == list(range(12))       # exactly one command per control step
    assert np.all((cmds['mdot_bl_kgps'] >= 0.05) & (cmds['mdot_bl_kgps'] <= 0.17))
    assert np.all((cmds['t_evap_sp_c'] >= 3.0) & (cmds['t_evap_sp_c'] <= 10.0))
    assert set(cmds['strategy']) == {'ceco-ioch'}
    counts = bagio.topic_counts(bag)
    assert counts['/cabin/state'] == 60 and counts['/hvac/power'] == 60 and counts['/cabin/comfort'] == 60
    states = [m.step_index for _, _, m in bagio.read_messages(bag, ('cabin/state',))]
    assert sorted(states) == list(range(60))
    # the applied input of every plant step is the command of its control step
    by_k = dict(zip(cmds['k'].tolist(), cmds['mdot_bl_kgps'].tolist()))
    assert ts['mdot_bl_kgps'].tolist() == [by_k[i // 5] for i in range(60)]

    from ceco_controller.closed_loop import SimSettings, simulate
    sim_run = simulate('sc03', 'ceco-ioch', SimSettings(duration_s=60.0, progress=False))
    sim = sim_run.metrics
    # the comfort series published in cabin/comfort rebuild the simulator's columns (issue 9)
    for col in ('pa_pa', 't_dew_c', 'fog_margin_k', 'dr_pct', 'ta_occ_c', 'vel_occ_mps', 't_mr_c', 'w_rad_wm2',
                'iso7730_valid'):
        np.testing.assert_allclose(ts[col], sim_run.timeseries[col], rtol=1e-12, atol=1e-12, err_msg=col)
    metrics = json.loads((out / 'metrics.json').read_text())
    for key in ('E_tot_J', 'E_comp_J', 'E_blower_J', 'I_pmv', 'otc_violation_pct', 'pmv_mean'):
        assert metrics[key] == pytest.approx(sim[key], rel=1e-6, abs=1e-12), key
    assert metrics['strategy'] == 'ceco-ioch' and metrics['scenario'] == 'sc03'

    # the recorded drive fed to a fresh mpc_node (ceco play --compare) gives the same commands
    p = _cli('play', str(bag), '--compare', '--domain-id', str(_domain()))
    text, _ = p.communicate(timeout=300)
    assert p.returncode == 0, text
    assert '12/12 steps compared; max |d blower| 0.000e+00 kg/s, max |d set-point| 0.000e+00 K' in text
    _check_lockstep_bag(bag, n_steps=60)


def _check_lockstep_bag(bag, n_steps: int, dt_s: float = 1.0):
    """A lockstep bag of `ceco run`: MCAP, fully qualified names, bag timestamps = the
    simulation time (header stamps, /clock's clock; states at n * dt), the duration of
    the drive; the `mcap` package with mcap_ros2 decodes the same messages as rosbags."""
    import yaml
    from bag_helpers import assert_same_fields, check_jazzy_metadata, plain
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    info = check_jazzy_metadata(yaml.safe_load((bag / 'metadata.yaml').read_text()), bag)
    assert info['storage_identifier'] == 'mcap'
    assert {t['topic_metadata']['name'] for t in info['topics_with_message_count']} == {
        '/cabin/state', '/cabin/comfort', '/hvac/power', '/hvac/command', '/controller/diagnostics',
        '/v2x/weather_preview', '/v2x/traffic_preview', '/clock', '/rosout'}
    assert info['starting_time']['nanoseconds_since_epoch'] == 0
    assert info['duration']['nanoseconds'] == round((n_steps - 1) * dt_s * 1e9)
    ours = {}
    for topic, t_ns, msg in bagio.read_messages(bag):
        if topic == '/clock':
            assert t_ns == msg.clock.sec * 10**9 + msg.clock.nanosec
        elif topic != '/rosout':
            assert t_ns == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec, topic
        if topic == '/cabin/state':
            assert t_ns == round(msg.step_index * dt_s * 1e9)
        ours.setdefault(topic, []).append((t_ns, plain(msg)))
    (mcap_file,) = info['relative_file_paths']
    theirs = {}
    with open(bag / mcap_file, 'rb') as fh:
        for _, ch, m, d in make_reader(fh, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            theirs.setdefault(ch.topic, []).append((m.log_time, plain(d)))
    assert {t: len(v) for t, v in theirs.items()} == {t: len(v) for t, v in ours.items()}
    for topic in ours:   # (ties in time, several /rosout lines at one simulation time, in any order)
        for (t_a, a), (t_b, b) in zip(sorted(ours[topic], key=repr), sorted(theirs[topic], key=repr)):
            assert t_a == t_b
            assert_same_fields(a, b, topic)


# ----------------------------------------------------------------------------
def _state_msg(k_plant: int, t_s: float, **override):
    from ceco_msgs.msg import CabinState
    m = CabinState(step_index=k_plant, scenario_time_s=t_s, t_cab_c=45.0, t_int_c=50.0, t_shell_c=55.0,
                   t_glass_c=55.0, t_evap_c=45.0, t_vent_c=45.0, rh_cab=0.2, t_amb_c=35.0, solar_wm2=800.0,
                   rh=0.4, speed_mps=10.0, mdot_bl_kgps=0.17, t_evap_sp_c=3.0)
    m.header.stamp = conversions.stamp_from_s(t_s if math.isfinite(t_s) else 0.0)
    for key, value in override.items():
        setattr(m, key, value)
    return m


def test_recorder_records_a_namespaced_stack_fully_qualified(tmp_path):
    """A stack under /veh1 beside one in the root namespace, one domain: the Recorder
    for namespace /veh1 (SQLite 3, simulation-time stamps) records /veh1/cabin/state and
    the global /clock under their fully qualified names, nothing of the root stack, each
    state at its header stamp; bagio reads it back by the stack names."""
    from rosgraph_msgs.msg import Clock

    from ceco_msgs.msg import CabinState
    tn, rec, _, bag = _recording_peer(tmp_path, namespace='/veh1', storage='sqlite3', timestamps='sim')
    veh1 = rclpy.create_node('plant_node', namespace='/veh1', context=tn.context)
    root = rclpy.create_node('plant_node', context=tn.context)
    pub_veh1 = veh1.create_publisher(CabinState, interfaces.TOPIC_STATE, interfaces.QOS_STATE)
    pub_root = root.create_publisher(CabinState, interfaces.TOPIC_STATE, interfaces.QOS_STATE)
    pub_clock = root.create_publisher(Clock, interfaces.TOPIC_CLOCK, interfaces.QOS_CLOCK)
    try:
        assert rec.bag_topics[interfaces.TOPIC_STATE] == '/veh1/cabin/state'
        _wait_for(lambda: pub_veh1.get_subscription_count() >= 1 and pub_clock.get_subscription_count() >= 1,
                  30, 'the recorder to match /veh1/cabin/state and /clock')
        assert pub_root.get_subscription_count() == 0
        for n in range(10):
            pub_clock.publish(Clock(clock=conversions.stamp_from_s(0.5 * n)))
            pub_veh1.publish(_state_msg(n, 0.5 * n))
            pub_root.publish(_state_msg(n, 0.5 * n, t_cab_c=99.0))
        _wait_for(lambda: rec.n_messages >= 20, 30, 'the recorder to receive 10 states and 10 clocks')
        time.sleep(0.3)
    finally:
        counts = rec.close()
        veh1.destroy_node()
        root.destroy_node()
        tn.close()
    assert counts['/veh1/cabin/state'] == 10 and counts['/clock'] == 10 and '/cabin/state' not in counts
    got = [(t, m.step_index, m.t_cab_c) for _, t, m in bagio.read_messages(bag, ('cabin/state',))]
    assert got == [(n * 500_000_000, n, 45.0) for n in range(10)]
    assert (bag / 'bag.db3').is_file()


def _log_has(proc, text, timeout_s=20.0):
    _wait_for(lambda: text in proc.log_text(), timeout_s, f'{text!r} in {proc.name} log')


def test_bad_input_rejected_nodes_keep_commanding(tmp_path):
    """Malformed messages to each node (NaN, inf, wrong/empty arrays, stale or
    future steps, unknown strategy) are rejected with a clear log line; the
    nodes keep running and keep commanding within bounds; an unknown
    strategy parameter stops mpc_node at start with a clear message."""
    from ceco_msgs.msg import AcCommand, AcPower, CabinState, TrafficPreview, WeatherPreview
    log_dir = tmp_path / 'logs'
    # Domain A: preview_node + mpc_node, the test plays the plant.
    dom_a, dom_b = _domain(), _domain()
    ta = DdsPeer(dom_a, 'fake_plant')
    common = {'scenario': 'sc03', 'timing': 'lockstep', 'control_period_s': 5.0, 'horizon_steps': 6}
    preview = _proc('preview_node', 'ceco_v2x_preview', 'preview_node', ta.env, log_dir, common)
    mpc = _proc('mpc_node', 'ceco_controller', 'mpc_node', ta.env, log_dir,
                dict(common, strategy='ceco-ioch', preview_timeout_s=30.0))
    bad = _proc('mpc_bad', 'ceco_controller', 'mpc_node', ta.env, log_dir, dict(common, strategy='ceco-turbo'))
    # Domain B: plant_node alone, the test plays the controller.
    tb = DdsPeer(dom_b, 'fake_controller')
    plant = _proc('plant_node', 'ceco_plant_sim', 'plant_node', tb.env, log_dir, {
        'scenario': 'sc03', 'timing': 'lockstep', 'duration_s': 60.0, 'lockstep.command_timeout_s': 600.0,
        'lockstep.min_state_subscribers': 1, 'lockstep.min_command_subscribers': 1})
    procs = [preview, mpc, bad, plant]
    try:
        for p in procs:
            p.start()
        pub_state = ta.node.create_publisher(CabinState, interfaces.TOPIC_STATE, interfaces.QOS_STATE)
        pub_w = ta.node.create_publisher(WeatherPreview, interfaces.TOPIC_WEATHER, interfaces.QOS_PREVIEW)
        pub_s = ta.node.create_publisher(TrafficPreview, interfaces.TOPIC_TRAFFIC, interfaces.QOS_PREVIEW)
        cmds = ta.collect(AcCommand, interfaces.TOPIC_COMMAND, interfaces.QOS_COMMAND)
        states_b = tb.collect(CabinState, interfaces.TOPIC_STATE, interfaces.QOS_STATE)
        powers_b = tb.collect(AcPower, interfaces.TOPIC_POWER, interfaces.QOS_STATE)
        pub_cmd = tb.node.create_publisher(AcCommand, interfaces.TOPIC_COMMAND, interfaces.QOS_COMMAND)

        # unknown strategy name: refuses to start, says why
        _wait_for(lambda: not bad.running() and bad.returncode() is not None, 120, 'mpc_bad to exit')
        assert bad.returncode() == 2
        assert "invalid parameter strategy='ceco-turbo': unknown strategy" in bad.log_text()

        _wait_for(lambda: ta.node.count_publishers(interfaces.TOPIC_COMMAND) >= 1
                  and pub_state.get_subscription_count() >= 2, 120, 'mpc_node and preview_node up')
        # --- controller and preview node: bad states
        pub_state.publish(_state_msg(0, 0.0, t_cab_c=math.nan))
        _log_has(mpc, 'rejected cabin/state step 0: t_cab_c=nan is not finite')
        pub_state.publish(_state_msg(0, 0.0, t_vent_c=math.inf))
        _log_has(mpc, 'rejected cabin/state step 0: t_vent_c=inf is not finite')
        pub_state.publish(_state_msg(0, math.nan))
        _log_has(preview, 'rejected cabin/state: scenario_time_s=nan')
        # --- controller: bad previews (empty, wrong length, inf, NaN where valid)
        w = WeatherPreview(step_index=0, step_s=5.0)
        pub_w.publish(w)
        _log_has(mpc, 'rejected v2x/weather_preview step 0: arrays of lengths [0], expected 7')
        pub_w.publish(WeatherPreview(step_index=0, step_s=5.0, t_amb_c=[35.0] * 3, solar_wm2=[800.0] * 3,
                                     rh=[0.4] * 3, valid=[True] * 3))
        _log_has(mpc, 'rejected v2x/weather_preview step 0: arrays of lengths [3], expected 7')
        pub_s.publish(TrafficPreview(step_index=0, step_s=5.0, speed_mps=[math.inf] * 7, valid=[True] * 7))
        _log_has(mpc, 'rejected v2x/traffic_preview step 0: non-finite value where marked valid')
        pub_s.publish(TrafficPreview(step_index=0, step_s=5.0, speed_mps=[math.nan] * 7, valid=[True] * 7))
        _wait_for(lambda: mpc.log_text().count('rejected v2x/traffic_preview step 0') >= 2, 20, 'NaN rejected')
        assert not cmds  # nothing valid yet: no command
        # --- a valid state: the preview node issues previews 0, the controller commands step 0
        pub_state.publish(_state_msg(0, 0.0))
        _wait_for(lambda: any(c.step_index == 0 for c in cmds), 60, 'command 0')
        pub_state.publish(_state_msg(0, 0.0))
        _log_has(mpc, 'rejected cabin/state for step 0: stale')
        pub_state.publish(_state_msg(5, 5.0, t_cab_c=44.0))
        _wait_for(lambda: any(c.step_index == 1 for c in cmds), 60, 'command 1')
        assert [c.step_index for c in cmds] == [0, 1]
        for c in cmds:
            assert 0.05 <= c.blower_flow_kgps <= 0.17 and 3.0 <= c.evap_setpoint_c <= 10.0
            assert c.strategy == 'ceco-ioch'
        assert mpc.running() and preview.running()

        # --- plant: bad commands
        _wait_for(lambda: len(states_b) >= 1 and pub_cmd.get_subscription_count() >= 1, 120, 'plant up')
        bad_cmds = [
            (dict(blower_flow_kgps=math.nan), 'rejected hvac/command step 0: blower_flow_kgps=nan is not finite'),
            (dict(evap_setpoint_c=-math.inf), 'rejected hvac/command step 0: evap_setpoint_c=-inf is not finite'),
            (dict(blower_flow_kgps=0.5), 'rejected hvac/command step 0: mdot_bl_kgps: must be in [0.05, 0.17]'),
            (dict(strategy='turbo'), "rejected hvac/command step 0: unknown strategy 'turbo'"),
            (dict(step_index=7), 'rejected hvac/command step 7: future (waiting for step 0)'),
        ]
        for override, line in bad_cmds:
            m = AcCommand(step_index=0, control_period_s=5.0, blower_flow_kgps=0.1, evap_setpoint_c=5.0,
                          strategy='ceco')
            for key, value in override.items():
                setattr(m, key, value)
            pub_cmd.publish(m)
            _log_has(plant, line)
        assert len(states_b) == 1 and not powers_b          # the plant did not move
        pub_cmd.publish(AcCommand(step_index=0, control_period_s=5.0, blower_flow_kgps=0.1,
                                  evap_setpoint_c=5.0, strategy='ceco'))
        _wait_for(lambda: len(states_b) >= 6, 30, 'states 1..5')
        pub_cmd.publish(AcCommand(step_index=0, control_period_s=5.0, blower_flow_kgps=0.12,
                                  evap_setpoint_c=6.0, strategy='ceco'))
        _log_has(plant, 'rejected hvac/command step 0: stale (waiting for step 1)')
        pub_cmd.publish(AcCommand(step_index=1, control_period_s=5.0, blower_flow_kgps=0.12,
                                  evap_setpoint_c=6.0, strategy='ceco'))
        _wait_for(lambda: len(states_b) >= 11, 30, 'states 6..10')
        assert [s.step_index for s in states_b] == list(range(11))
        assert [(p.mdot_bl_kgps, p.t_evap_sp_c) for p in powers_b] == [(0.1, 5.0)] * 5 + [(0.12, 6.0)] * 5
        assert not any(p.fallback for p in powers_b)
        assert plant.running()
    finally:
        for p in procs:
            p.stop()
        ta.close()
        tb.close()


# ----------------------------------------------------------------------------
def test_kill_mpc_node_plant_falls_back_and_restart_takes_over(tmp_path):
    """SIGKILL the mpc_node mid-run: the plant notices the missing command
    (lockstep: a wall-clock timeout, within the next control step), logs it and
    applies the production ACC law; a restarted mpc_node takes over again.
    The bag holds every state exactly once, before and after the fault."""
    tn, rec, log_dir, bag = _recording_peer(tmp_path, timestamps='sim')
    n_steps = 600
    common = {'scenario': 'sc03', 'timing': 'lockstep', 'control_period_s': 5.0}
    preview = _proc('preview_node', 'ceco_v2x_preview', 'preview_node', tn.env, log_dir,
                    dict(common, horizon_steps=6))
    # The mpc_node answers within 0.5 s even when a step's previews are late (it then solves
    # without them), well inside the plant's 1.5 s command timeout: a late preview or a load
    # spike on the shared cores must not look like the fault this test injects (with 0.6 s
    # against the default 2 s preview wait, one full-suite run saw a fallback before the kill).
    mpc_params = dict(common, horizon_steps=6, strategy='ceco', preview_timeout_s=0.5)
    mpc = _proc('mpc_node', 'ceco_controller', 'mpc_node', tn.env, log_dir, mpc_params)
    plant = _proc('plant_node', 'ceco_plant_sim', 'plant_node', tn.env, log_dir, dict(
        common, duration_s=float(n_steps), **{'lockstep.command_timeout_s': 1.5,
                                              'lockstep.min_state_subscribers': 3,
                                              'lockstep.min_output_subscribers': 1,
                                              'lockstep.min_command_subscribers': 2}))
    procs = [preview, mpc, plant]
    try:
        for p in procs:
            p.start()
        _wait_for(lambda: rec.last_power_step >= 50, 180, 'plant step 50')
        mpc.kill()
        _log_has(plant, 'FALLBACK at step', 60)
        mpc.start()     # restart: same log file, second start
        _wait_for(lambda: rec.last_power_step >= n_steps - 1, 300, 'the end of the run')
        time.sleep(0.3)
    finally:
        for p in procs:
            p.stop()
        rec.close()
        tn.close()
    log = plant.log_text()
    assert 'no command for control step' in log and 'commands resumed at control step' in log
    ts = bagio.load_run_timeseries(bag)
    assert ts['step_index'].tolist() == list(range(n_steps))        # nothing lost, nothing doubled
    states = [m.step_index for _, _, m in bagio.read_messages(bag, ('cabin/state',))]
    assert sorted(states) == list(range(n_steps))
    fb = ts['fallback']
    # fallback only between kill and takeover
    assert fb.any() and not fb[:50].any() and not fb[-5:].any(), (
        f'fallback at plant steps {np.flatnonzero(fb).tolist()[:20]}; plant log tail:\n{log[-3000:]}')
    first_fb = int(np.flatnonzero(fb)[0])
    cmds = bagio.load_commands(bag)
    before = cmds['k'][cmds['k'] * 5 < first_fb]
    k_last = int(before.max())
    assert first_fb // 5 - k_last <= 2          # noticed within two control periods (here: the next step)
    after = cmds['k'][cmds['k'] * 5 > first_fb]
    assert after.size > 0 and set(cmds['strategy']) == {'ceco'}
    fb_steps = np.flatnonzero(fb)
    assert np.all(np.diff(fb_steps) == 1)       # one contiguous fallback span
    # during the fallback the ACC law drove the plant; its inputs are within bounds
    assert np.all((ts['mdot_bl_kgps'] >= 0.05) & (ts['mdot_bl_kgps'] <= 0.17))
    assert np.all((ts['t_evap_sp_c'] >= 3.0) & (ts['t_evap_sp_c'] <= 10.0))
    # every non-fallback plant step applied the command of its control step
    by_k = dict(zip(cmds['k'].tolist(), cmds['mdot_bl_kgps'].tolist()))
    for i in np.flatnonzero(~fb):
        assert ts['mdot_bl_kgps'][i] == by_k[int(i) // 5]


# ----------------------------------------------------------------------------
def test_sigint_to_ceco_run_leaves_complete_bag(tmp_path):
    """SIGINT to `ceco run` (real-time timing, so the stop lands mid-run): exit
    status 130, every child stopped, and the bag reads back completely: the
    metadata counts equal the stored messages and the states are contiguous
    from step 0 up to the stop."""
    out = tmp_path / 'run'
    p = _cli('run', '--scenario', 'sc03', '--strategy', 'baseline', '--timing', 'realtime', '--duration-s', '60',
             '--out', str(out), '--no-progress', '--domain-id', str(_domain()))
    meta = out / 'bag' / 'metadata.yaml'
    t_wall_start_ns = time.time_ns()

    def n_states():
        try:
            return bagio.topic_counts(out / 'bag').get('/cabin/state', 0)
        except Exception:
            return 0
    try:
        _wait_for(lambda: meta.exists() and n_states() >= 3, 180, 'a few real-time states in the bag')
        p.send_signal(signal.SIGINT)
        text, _ = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    t_wall_end_ns = time.time_ns()
    assert p.returncode == 130, text
    assert 'interrupted' in text
    counts = bagio.topic_counts(out / 'bag')
    read = {}
    for topic, _, _ in bagio.read_messages(out / 'bag'):
        read[topic] = read.get(topic, 0) + 1
    assert {t: c for t, c in counts.items() if c} == read
    states = [m.step_index for _, _, m in bagio.read_messages(out / 'bag', ('cabin/state',))]
    assert len(states) >= 3 and states == list(range(len(states)))
    # real time: bag timestamps are the wall-clock receive times (as rosbag2 records by default)
    stamps = [t for _, t, _ in bagio.read_messages(out / 'bag')]
    assert t_wall_start_ns < min(stamps) and max(stamps) < t_wall_end_ns
    for log in (out / 'logs').glob('*.log'):      # every child went through its shutdown path
        assert 'Traceback' not in log.read_text(), log


# ----------------------------------------------------------------------------
def test_preview_faults_over_dds_match_simulator(tmp_path):
    """Noise, delay and a dropout span set as preview_node parameters: the bag's
    previews carry them (invalid before the first delayed forecast, stale ages
    in the span) and the closed loop still equals the simulator's."""
    quality = 'noisy:solar=80,speed=2,seed=3+delayed:10+missing:20-40'
    out = tmp_path / 'run'
    p = _cli('run', '--scenario', 'sc03', '--strategy', 'ceco-ioch', '--duration-s', '60', '--preview', quality,
             '--out', str(out), '--no-progress', '--domain-id', str(_domain()))
    text, _ = p.communicate(timeout=300)
    assert p.returncode == 0, text
    prev = {m.step_index: m for _, _, m in bagio.read_messages(out / 'bag', ('v2x/weather_preview',))}
    assert sorted(prev) == list(range(12))
    assert not any(prev[0].valid) and not any(prev[1].valid)          # nothing issued before t = 10 s
    assert prev[2].age_s == 10.0 and list(prev[2].valid) == [True] * 5 + [False] * 2
    assert [prev[k].age_s for k in (4, 5, 6, 7)] == [10.0, 15.0, 20.0, 25.0]   # held during 20-40 s
    assert '+delayed:10+missing:20-40' in prev[3].quality

    from ceco_controller.closed_loop import SimSettings, simulate
    from ceco_v2x_preview.preview import parse_quality
    sim = simulate('sc03', 'ceco-ioch', SimSettings(duration_s=60.0, preview_quality=parse_quality(quality),
                                                     progress=False)).metrics
    metrics = json.loads((out / 'metrics.json').read_text())
    for key in ('E_tot_J', 'I_pmv', 'otc_violation_pct'):
        assert metrics[key] == pytest.approx(sim[key], rel=1e-6, abs=1e-12), key


# ----------------------------------------------------------------------------
def test_realtime_kill_controller_fallback_within_two_control_periods(tmp_path):
    """Real-time timing (wall-clock timers, as on a vehicle; Ts = 2 s, plant
    step 0.5 s): SIGKILL the controller; within two control periods of the
    plant's own clock the plant applies the ACC law, and a restarted controller
    takes over. Counted in plant steps, not asserted on elapsed time. The
    controller is baseline_node: the NMPC's model step (5 s) would make a
    real-time test last minutes; the plant-side logic under test is the same
    (the lockstep test above kills mpc_node)."""
    from ceco_msgs.msg import AcPower
    tn, rec, log_dir, bag = _recording_peer(tmp_path)
    powers = tn.collect(AcPower, interfaces.TOPIC_POWER, interfaces.QOS_STATE)
    common = {'scenario': 'sc03', 'timing': 'realtime', 'control_period_s': 2.0}
    preview = _proc('preview_node', 'ceco_v2x_preview', 'preview_node', tn.env, log_dir,
                    dict(common, horizon_steps=6, publish_period_s=2.0))
    mpc = _proc('baseline_node', 'ceco_controller', 'baseline_node', tn.env, log_dir,
                dict(common, horizon_steps=6))
    plant = _proc('plant_node', 'ceco_plant_sim', 'plant_node', tn.env, log_dir, dict(
        common, plant_dt_s=0.5, duration_s=600.0, **{'lockstep.min_state_subscribers': 3,
                                                     'lockstep.min_output_subscribers': 1,
                                                     'lockstep.min_command_subscribers': 2}))
    procs = [preview, mpc, plant]

    def n_normal():
        return sum(not p.fallback for p in powers)
    try:
        for p in procs:
            p.start()
        _wait_for(lambda: n_normal() >= 8, 180, 'two control periods under the controller', procs)
        mpc.kill()
        _wait_for(lambda: powers and powers[-1].fallback, 60, 'the plant to fall back', [preview, plant])
        mpc.start()
        n_fb_end = len(powers)
        _wait_for(lambda: len(powers) > n_fb_end and sum(not p.fallback for p in powers[n_fb_end:]) >= 8,
                  180, 'the restarted controller to take over', procs)
    finally:
        for p in procs:
            p.stop()
        rec.close()
        tn.close()
    m = 4                                                      # plant steps per control period
    fb = [p.fallback for p in sorted(powers, key=lambda p: p.step_index)]
    steps = sorted(p.step_index for p in powers)
    assert steps == list(range(len(steps)))                    # no step lost
    first_normal = fb.index(False)                             # key-on: ACC law until the first command
    spans = [i for i in range(first_normal, len(fb)) if fb[i] and not fb[i - 1]]
    assert len(spans) == 1                                     # one fallback span after the kill ...
    first_fb = spans[0]
    last_boundary = max(i for i in range(first_normal, first_fb) if i % m == 0)
    assert first_fb - last_boundary <= 2 * m + 1               # ... noticed within two control periods
    assert not any(fb[-8:])                                    # ... and the restarted node took over
    log = plant.log_text()
    assert 'no fresh command' in log and 'commands resumed' in log
    ts = bagio.load_run_timeseries(bag)
    assert np.all((ts['mdot_bl_kgps'] >= 0.05) & (ts['mdot_bl_kgps'] <= 0.17))
