"""Bag writing/reading without ROS: rosbags-serialized ceco messages through
BagWriter (sqlite3, metadata version 9) and back through bagio's loaders."""
import csv
import math

import numpy as np
import pytest
import yaml

from ceco_bringup import bagio

TOPICS = {'cabin/state': 'ceco_msgs/msg/CabinState', 'cabin/comfort': 'ceco_msgs/msg/Comfort',
          'hvac/power': 'ceco_msgs/msg/AcPower', 'hvac/command': 'ceco_msgs/msg/AcCommand',
          'controller/diagnostics': 'ceco_msgs/msg/ControllerDiagnostics'}


def _msg(type_name, **fields):
    store = bagio.typestore()
    cls = store.types[type_name]
    Header = store.types['std_msgs/msg/Header']
    Time = store.types['builtin_interfaces/msg/Time']
    values = {}
    for name in cls.__dataclass_fields__:
        if name.startswith('__'):
            continue
        if name == 'header':
            t = fields.pop('t', 0.0)
            values[name] = Header(stamp=Time(sec=int(t), nanosec=int(round((t % 1) * 1e9))), frame_id='')
        elif name in fields:
            values[name] = fields[name]
        else:
            anno = cls.__dataclass_fields__[name].type
            values[name] = {'str': '', 'bool': False, 'int': 0, 'float': 0.0}.get(anno) if anno in (
                'str', 'bool', 'int', 'float') else np.zeros(0)
    return cls(**values)


def _ser(msg):
    return bagio.typestore().serialize_cdr(msg, msg.__msgtype__)


def _writer(path):
    w = bagio.BagWriter(path)
    for topic, type_name in TOPICS.items():
        w.add_topic(topic, type_name)
    return w


def _write_steps(w, steps, *, skip_power=()):
    for n in steps:
        w.write('cabin/state', 1_000, _ser(_msg('ceco_msgs/msg/CabinState', t=float(n), step_index=n,
                                                 scenario_time_s=float(n), t_cab_c=40.0 - n, t_vent_c=10.0 + n)))
        w.write('cabin/comfort', 1_000, _ser(_msg('ceco_msgs/msg/Comfort', t=float(n), step_index=n,
                                                   pmv=1.0 - 0.1 * n, pmv_lb=-0.5, pmv_ub=0.5)))
        if n not in skip_power:
            w.write('hvac/power', 1_000, _ser(_msg('ceco_msgs/msg/AcPower', t=float(n), step_index=n,
                                                    p_comp_w=1000.0 + n, p_blower_w=50.0, mdot_bl_kgps=0.1,
                                                    t_evap_sp_c=5.0)))


def test_round_trip_rows_are_the_complete_plant_steps(tmp_path):
    w = _writer(tmp_path / 'bag')
    _write_steps(w, [2, 0, 1, 3], skip_power={3})
    w.write('cabin/state', 1_000, _ser(_msg('ceco_msgs/msg/CabinState', step_index=1, t_cab_c=99.0)))  # duplicate
    w.close()
    ts = bagio.load_run_timeseries(tmp_path / 'bag')
    assert list(ts)[:len(bagio.TIMESERIES_COLUMNS)] == list(bagio.TIMESERIES_COLUMNS)
    assert ts['step_index'].tolist() == [0, 1, 2]               # sorted; step 3 has no power: no row
    assert ts['t_cab_c'].tolist() == [40.0, 39.0, 38.0]         # first message of a duplicated step kept
    assert ts['p_comp_w'].tolist() == [1000.0, 1001.0, 1002.0]
    assert ts['pmv'].tolist() == pytest.approx([1.0, 0.9, 0.8])
    assert ts['mdot_bl_kgps'].tolist() == [0.1] * 3
    counts = bagio.topic_counts(tmp_path / 'bag')
    assert counts['cabin/state'] == 5 and counts['hvac/power'] == 3


def test_metadata_is_rosbag2_version_9_sqlite3(tmp_path):
    w = _writer(tmp_path / 'bag')
    _write_steps(w, [0])
    w.close()
    meta = yaml.safe_load((tmp_path / 'bag' / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['version'] == 9 and meta['storage_identifier'] == 'sqlite3'
    assert meta['message_count'] == 3
    names = {t['topic_metadata']['name']: t['message_count'] for t in meta['topics_with_message_count']}
    assert names['cabin/state'] == 1 and names['hvac/command'] == 0


def test_timestamps_strictly_increase_in_arrival_order(tmp_path):
    w = _writer(tmp_path / 'bag')
    used = [w.write('hvac/command', t, _ser(_msg('ceco_msgs/msg/AcCommand', step_index=k)))
            for k, t in enumerate([500, 500, 100, 800])]
    w.close()
    assert used == [500, 501, 502, 800]
    assert bagio.load_commands(tmp_path / 'bag')['k'].tolist() == [0, 1, 2, 3]


def test_flushed_bag_reads_back_without_close(tmp_path):
    """What a SIGKILLed recorder leaves: everything up to the last flush."""
    w = _writer(tmp_path / 'bag')
    _write_steps(w, range(4))
    w.flush()
    ts = bagio.load_run_timeseries(tmp_path / 'bag')
    assert ts['step_index'].tolist() == [0, 1, 2, 3]
    _write_steps(w, range(4, 6))
    w.flush()
    assert bagio.load_run_timeseries(tmp_path / 'bag')['step_index'].tolist() == list(range(6))
    assert bagio.topic_counts(tmp_path / 'bag')['cabin/state'] == 6
    w.close()
    assert bagio.topic_counts(tmp_path / 'bag')['cabin/state'] == 6


def test_commands_and_diagnostics_loaders(tmp_path):
    w = _writer(tmp_path / 'bag')
    w.write('hvac/command', 1, _ser(_msg('ceco_msgs/msg/AcCommand', t=5.0, step_index=1, blower_flow_kgps=0.12,
                                          evap_setpoint_c=4.5, strategy='ceco-ioch', fallback=True)))
    w.write('controller/diagnostics', 2, _ser(_msg(
        'ceco_msgs/msg/ControllerDiagnostics', t=5.0, step_index=1, strategy='baseline', status='pi',
        iterations=-1, solve_time_s=0.0015, cost_energy=math.nan, cost_comfort=math.nan, cost_ioch=math.nan,
        eps_mean=math.nan, cost_total=math.nan)))
    w.close()
    c = bagio.load_commands(tmp_path / 'bag')
    assert c['k'].tolist() == [1] and c['t_s'].tolist() == [5.0]
    assert c['mdot_bl_kgps'].tolist() == [0.12] and c['t_evap_sp_c'].tolist() == [4.5]
    assert c['strategy'].tolist() == ['ceco-ioch'] and c['fallback'].tolist() == [True]
    d = bagio.load_diagnostics(tmp_path / 'bag')
    assert d['solve_time_ms'].tolist() == pytest.approx([1.5])
    bagio.write_diagnostics_csv(tmp_path / 'diagnostics.csv', d)
    rows = list(csv.DictReader(open(tmp_path / 'diagnostics.csv')))
    assert list(rows[0])[:len(bagio.DIAGNOSTICS_COLUMNS)] == list(bagio.DIAGNOSTICS_COLUMNS)
    assert rows[0]['iterations'] == '' and rows[0]['cost_energy'] == '' and rows[0]['status'] == 'pi'
