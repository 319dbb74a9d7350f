"""Bags without ROS: rosbags-serialized ceco messages written by bag_writer.BagWriter
(MCAP and SQLite 3, metadata version 9), read back by bagio under every topic naming,
read by an independent reader (the `mcap` package with mcap_ros2), and a bag written
the way `ros2 bag record` writes one read by bagio."""

import csv
import json
import math
import shutil
import struct
from pathlib import Path

import numpy as np
import pytest
import yaml
from bag_helpers import (
    assert_same_fields,
    check_jazzy_metadata,
    check_qos_v9,
    check_rosbag2_record_layout,
    plain,
    sample,
    write_ros2_bag_record_style,
)

from ceco_bringup import bag_writer, bagio

TYPES = {
    'cabin/state': 'ceco_msgs/msg/CabinState',
    'cabin/comfort': 'ceco_msgs/msg/Comfort',
    'hvac/power': 'ceco_msgs/msg/AcPower',
    'hvac/command': 'ceco_msgs/msg/AcCommand',
    'controller/diagnostics': 'ceco_msgs/msg/ControllerDiagnostics',
    'v2x/weather_preview': 'ceco_msgs/msg/WeatherPreview',
    'v2x/traffic_preview': 'ceco_msgs/msg/TrafficPreview',
}
SEC = 1_000_000_000


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
            values[name] = (
                {'str': '', 'bool': False, 'int': 0, 'float': 0.0}.get(anno)
                if anno in ('str', 'bool', 'int', 'float')
                else np.zeros(0)
            )
    return cls(**values)


def _ser(msg):
    return bagio.typestore().serialize_cdr(msg, msg.__msgtype__)


def _writer(path, storage='mcap', ns='/'):
    w = bag_writer.BagWriter(path, storage=storage)
    for topic, type_name in TYPES.items():
        w.add_topic(ns + topic if ns is not None else topic, type_name)
    return w


def _write_steps(w, steps, *, ns='/', skip_power=(), scale=1.0):
    pre = ns if ns is not None else ''
    for n in steps:
        t_ns = n * SEC
        w.write(
            pre + 'cabin/state',
            t_ns,
            _ser(
                _msg(
                    'ceco_msgs/msg/CabinState',
                    t=float(n),
                    step_index=n,
                    scenario_time_s=float(n),
                    t_cab_c=scale * (40.0 - n),
                    t_vent_c=10.0 + n,
                )
            ),
        )
        w.write(
            pre + 'cabin/comfort',
            t_ns,
            _ser(_msg('ceco_msgs/msg/Comfort', t=float(n), step_index=n, pmv=1.0 - 0.1 * n, pmv_lb=-0.5, pmv_ub=0.5)),
        )
        if n not in skip_power:
            w.write(
                pre + 'hvac/power',
                t_ns,
                _ser(
                    _msg(
                        'ceco_msgs/msg/AcPower',
                        t=float(n),
                        step_index=n,
                        p_comp_w=scale * (1000.0 + n),
                        p_blower_w=50.0,
                        mdot_bl_kgps=0.1,
                        t_evap_sp_c=5.0,
                    )
                ),
            )


@pytest.mark.parametrize('storage', bag_writer.STORAGES)
def test_round_trip_rows_are_the_complete_plant_steps(tmp_path, storage):
    w = _writer(tmp_path / 'bag', storage)
    _write_steps(w, [2, 0, 1, 3], skip_power={3})
    w.write('/cabin/state', 5 * SEC, _ser(_msg('ceco_msgs/msg/CabinState', step_index=1, t_cab_c=99.0)))  # duplicate
    w.close()
    # rosbag2's name of the first storage file: <bag>_0.<ext> (SequentialWriter::format_storage_uri)
    assert sorted(p.name for p in (tmp_path / 'bag').iterdir()) == [
        f'bag_0.{"mcap" if storage == "mcap" else "db3"}',
        'metadata.yaml',
    ]
    ts = bagio.load_run_timeseries(tmp_path / 'bag')
    assert list(ts)[: len(bagio.TIMESERIES_COLUMNS)] == list(bagio.TIMESERIES_COLUMNS)
    assert ts['step_index'].tolist() == [0, 1, 2]  # sorted; step 3 has no power: no row
    assert ts['t_cab_c'].tolist() == [40.0, 39.0, 38.0]  # first message (bag order) of a duplicated step
    assert ts['p_comp_w'].tolist() == [1000.0, 1001.0, 1002.0]
    assert ts['pmv'].tolist() == pytest.approx([1.0, 0.9, 0.8])
    assert ts['mdot_bl_kgps'].tolist() == [0.1] * 3
    counts = bagio.topic_counts(tmp_path / 'bag')
    assert counts['/cabin/state'] == 5 and counts['/hvac/power'] == 3


@pytest.mark.parametrize('storage', bag_writer.STORAGES)
def test_metadata_decodes_under_jazzy_rosbag2_rules(tmp_path, storage):
    """metadata.yaml as `ros2 bag info` (Jazzy, version 9) reads it: every key it decodes,
    with its type; QoS as a sequence of rmw policy strings; infinite durations as rmw's."""
    interfaces = pytest.importorskip('ceco_ros.interfaces', reason='needs rclpy (its QoS profiles)')

    w = bag_writer.BagWriter(tmp_path / 'bag', storage=storage)
    w.set_custom_data('strategy', 'ceco-ioch')
    for topic, (type_name, offered, _) in interfaces.STACK_TOPICS.items():
        w.add_topic(topic if topic.startswith('/') else '/' + topic, type_name, offered)
    _write_steps(w, [0, 1])
    w.close()
    meta = yaml.safe_load((tmp_path / 'bag' / 'metadata.yaml').read_text())
    info = check_jazzy_metadata(meta, tmp_path / 'bag')
    check_rosbag2_record_layout(meta, tmp_path / 'bag')  # the file name and ros_distro of ros2 bag record
    assert info['storage_identifier'] == storage and info['message_count'] == 6
    assert info['starting_time']['nanoseconds_since_epoch'] == 0 and info['duration']['nanoseconds'] == SEC
    assert info['custom_data'] == {'strategy': 'ceco-ioch'}
    topics = {t['topic_metadata']['name']: t for t in info['topics_with_message_count']}
    assert set(topics) == {
        '/cabin/state',
        '/cabin/comfort',
        '/hvac/power',
        '/hvac/command',
        '/controller/diagnostics',
        '/v2x/weather_preview',
        '/v2x/traffic_preview',
        '/clock',
        '/rosout',
    }
    assert topics['/cabin/state']['message_count'] == 2 and topics['/hvac/command']['message_count'] == 0
    (state_qos,) = topics['/cabin/state']['topic_metadata']['offered_qos_profiles']
    assert (state_qos['history'], state_qos['depth'], state_qos['reliability'], state_qos['durability']) == (
        'keep_last',
        interfaces.LOCKSTEP_DEPTH,
        'reliable',
        'volatile',
    )
    assert state_qos['deadline'] == {'sec': 9223372036, 'nsec': 854775807}
    (preview_qos,) = topics['/v2x/weather_preview']['topic_metadata']['offered_qos_profiles']
    assert (preview_qos['depth'], preview_qos['durability']) == (1, 'transient_local')


def test_type_hashes_equal_rosidl_generated_ones(tmp_path):
    """The type_description_hash of every ceco_msgs topic equals the RIHS01 hash rosidl
    generated at build time (share/ceco_msgs/msg/<Type>.json), which Jazzy compares."""
    ament = pytest.importorskip('ament_index_python.packages', reason='needs the sourced workspace')
    try:
        share = ament.get_package_share_directory('ceco_msgs')
    except Exception:  # PackageNotFoundError and friends
        pytest.skip('ceco_msgs is not installed: build the workspace (colcon build)')
    w = _writer(tmp_path / 'bag')
    w.close()
    meta = yaml.safe_load((tmp_path / 'bag' / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert len(meta['topics_with_message_count']) == len(TYPES)  # every topic, also without messages
    for t in meta['topics_with_message_count']:
        tm = t['topic_metadata']
        rosidl = json.loads(open(f"{share}/msg/{tm['type'].split('/')[-1]}.json").read())['type_hashes'][0]
        assert rosidl['type_name'] == tm['type'] and rosidl['hash_string'] == tm['type_description_hash']


def test_equal_timestamps_are_kept_and_read_in_write_order(tmp_path):
    """Lockstep bags stamp a state, its comfort and its power with the same simulation time."""
    w = _writer(tmp_path / 'bag')
    for k, t in enumerate([5, 5, 0, 10, 5]):
        w.write('/hvac/command', t * SEC, _ser(_msg('ceco_msgs/msg/AcCommand', step_index=k)))
    w.close()
    c = bagio.load_commands(tmp_path / 'bag')
    assert c['t_recv_ns'].tolist() == [0, 5 * SEC, 5 * SEC, 5 * SEC, 10 * SEC]
    assert c['k'].tolist() == [2, 0, 1, 4, 3]


@pytest.mark.parametrize('storage', bag_writer.STORAGES)
def test_flushed_bag_is_complete_on_disk_without_close(tmp_path, storage):
    """What a SIGKILLed recorder leaves: a copy of the files taken after a flush and
    more (unflushed) writes reads back exactly what was flushed."""
    w = _writer(tmp_path / 'bag', storage)
    _write_steps(w, range(4))
    w.flush()
    assert bagio.load_run_timeseries(tmp_path / 'bag')['step_index'].tolist() == [0, 1, 2, 3]
    _write_steps(w, range(4, 6))
    w.flush()
    _write_steps(w, range(6, 9))  # not flushed: lost by a SIGKILL now
    shutil.copytree(tmp_path / 'bag', tmp_path / 'killed')
    assert bagio.load_run_timeseries(tmp_path / 'killed')['step_index'].tolist() == list(range(6))
    assert bagio.topic_counts(tmp_path / 'killed')['/cabin/state'] == 6
    w.close()
    assert bagio.load_run_timeseries(tmp_path / 'bag')['step_index'].tolist() == list(range(9))
    assert bagio.topic_counts(tmp_path / 'bag')['/cabin/state'] == 9
    if storage == 'mcap':  # and a reader that is not rosbags agrees
        from mcap.reader import make_reader

        with open(tmp_path / 'killed' / 'bag_0.mcap', 'rb') as fh:
            r = make_reader(fh)
            assert r.get_summary().statistics.message_count == 18
            assert sum(1 for _ in r.iter_messages()) == 18


def test_full_mcap_chunk_between_flushes_leaves_a_complete_file(tmp_path):
    """rosbags closes an MCAP chunk at 1 MiB; between two flushes the file then still ends
    with a valid summary and footer, holding every message of the closed chunks."""
    w = _writer(tmp_path / 'bag')
    w.flush()
    big = sample(bagio.typestore(), 'ceco_msgs/msg/WeatherPreview', 0)
    big.t_amb_c = np.arange(4000.0)
    for k in range(40):  # 40 x 32 kB: one chunk closes past 1 MiB
        big.step_index = k
        w.write('/v2x/weather_preview', k * SEC, _ser(big))
    shutil.copytree(tmp_path / 'bag', tmp_path / 'killed')
    from mcap.reader import make_reader

    with open(tmp_path / 'killed' / 'bag_0.mcap', 'rb') as fh:
        n_on_disk = sum(1 for _ in make_reader(fh).iter_messages())
    assert 30 <= n_on_disk < 40  # the closed chunk, not the open one
    got = [m.step_index for _, _, m in bagio.read_messages(tmp_path / 'killed', ['v2x/weather_preview'])]
    assert got == list(range(n_on_disk))
    w.close()


def test_commands_and_diagnostics_loaders(tmp_path):
    w = _writer(tmp_path / 'bag')
    w.write(
        '/hvac/command',
        1,
        _ser(
            _msg(
                'ceco_msgs/msg/AcCommand',
                t=5.0,
                step_index=1,
                blower_flow_kgps=0.12,
                evap_setpoint_c=4.5,
                strategy='ceco-ioch',
                fallback=True,
            )
        ),
    )
    w.write(
        '/controller/diagnostics',
        2,
        _ser(
            _msg(
                'ceco_msgs/msg/ControllerDiagnostics',
                t=5.0,
                step_index=1,
                strategy='baseline',
                status='pi',
                iterations=-1,
                solve_time_s=0.0015,
                cost_energy=math.nan,
                cost_comfort=math.nan,
                cost_ioch=math.nan,
                eps_mean=math.nan,
                cost_total=math.nan,
            )
        ),
    )
    w.write(
        '/controller/diagnostics',
        3,
        _ser(
            _msg(
                'ceco_msgs/msg/ControllerDiagnostics',
                t=10.0,
                step_index=2,
                strategy='ceco-ioch',
                status='Solve_Succeeded',
                iterations=2,
                solve_time_s=0.002,
                fallback=True,
                fallback_reason='shifted_plan: no usable solution',
            )
        ),
    )
    w.close()
    c = bagio.load_commands(tmp_path / 'bag')
    assert c['k'].tolist() == [1] and c['t_s'].tolist() == [5.0]
    assert c['mdot_bl_kgps'].tolist() == [0.12] and c['t_evap_sp_c'].tolist() == [4.5]
    assert c['strategy'].tolist() == ['ceco-ioch'] and c['fallback'].tolist() == [True]
    d = bagio.load_diagnostics(tmp_path / 'bag')
    assert d['solve_time_ms'].tolist() == pytest.approx([1.5, 2.0])
    assert d['fallback'].tolist() == ['', 'shifted_plan']  # the kind, as the simulator's diagnostics.csv
    bagio.write_diagnostics_csv(tmp_path / 'diagnostics.csv', d)
    rows = list(csv.DictReader(open(tmp_path / 'diagnostics.csv')))
    assert list(rows[0])[: len(bagio.DIAGNOSTICS_COLUMNS)] == list(bagio.DIAGNOSTICS_COLUMNS)
    assert rows[0]['iterations'] == '' and rows[0]['cost_energy'] == '' and rows[0]['status'] == 'pi'
    assert [r['fallback'] for r in rows] == ['', 'shifted_plan'] and rows[1]['iterations'] == '2'


# --- names ---------------------------------------------------------------------------
def test_topic_namespace_of_each_naming():
    assert bagio.topic_namespace('cabin/state', 'cabin/state') == ''  # relative (older ceco bags)
    assert bagio.topic_namespace('/cabin/state', 'cabin/state') == ''  # fully qualified
    assert bagio.topic_namespace('/veh1/cabin/state', 'cabin/state') == '/veh1'
    assert bagio.topic_namespace('/fleet/veh1/cabin/state', 'cabin/state') == '/fleet/veh1'
    assert bagio.topic_namespace('/veh1/cabin/state_raw', 'cabin/state') is None
    assert bagio.topic_namespace('/veh1/xcabin/state', 'cabin/state') is None
    assert bagio.topic_namespace('veh1/cabin/state', 'cabin/state') is None  # relative names carry no namespace
    assert bagio.topic_namespace('/clock', '/clock') == ''
    assert bagio.topic_namespace('/veh1/clock', '/clock') is None


def test_bag_topic_map_picks_one_namespace():
    bag = ['/veh1/cabin/state', '/veh1/hvac/power', '/veh2/cabin/state', '/clock', '/rosout']
    names = ['cabin/state', 'hvac/power', '/clock']
    with pytest.raises(ValueError, match="several namespaces .*'/veh1', '/veh2'"):
        bagio.bag_topic_map(bag, names)
    assert bagio.bag_topic_map(bag, names, 'veh1') == {
        '/veh1/cabin/state': 'cabin/state',
        '/veh1/hvac/power': 'hvac/power',
        '/clock': '/clock',
    }
    assert bagio.bag_topic_map(bag, names, '/veh2/') == {'/veh2/cabin/state': 'cabin/state', '/clock': '/clock'}
    assert bagio.bag_topic_map(['/cabin/state', '/clock'], names) == {'/cabin/state': 'cabin/state', '/clock': '/clock'}
    assert bagio.bag_topic_map(['/cabin/state', '/clock'], names, '/') == {
        '/cabin/state': 'cabin/state',
        '/clock': '/clock',
    }


def test_bag_topic_map_refuses_a_namespace_the_bag_does_not_hold():
    """Not the reader's empty result (which a caller would report as missing data): the namespace asked for and the
    ones the bag holds; a ValueError, so that callers catching that still do."""
    bag = ['/veh1/cabin/state', '/veh1/hvac/power', '/veh2/cabin/state', '/clock', '/rosout']
    names = ['cabin/state', 'hvac/power', '/clock']
    assert bagio.topic_namespaces(bag, names) == ['/veh1', '/veh2']
    assert bagio.topic_namespaces(bag + ['/cabin/state'], ['cabin/state']) == ['', '/veh1', '/veh2']
    assert bagio.topic_namespaces(bag, ['/clock']) == []  # absolute names carry no namespace
    with pytest.raises(bagio.NamespaceError) as exc:
        bagio.bag_topic_map(bag, names, 'veh3')
    assert str(exc.value) == (
        '--namespace veh3: not in the bag (no cabin/state or hvac/power under /veh3): give one of its namespaces, '
        '/veh1, /veh2'
    )
    with pytest.raises(bagio.NamespaceError) as exc:
        bagio.bag_topic_map(bag, names, '/')  # the root namespace, where this bag holds nothing
    assert str(exc.value) == (
        '--namespace /: not in the bag (no cabin/state or hvac/power under /): give one of its namespaces, /veh1, /veh2'
    )
    with pytest.raises(bagio.NamespaceError) as exc:
        bagio.bag_topic_map(['/cabin/state'], ['cabin/state'], 'bogus')
    assert (
        str(exc.value)
        == '--namespace bogus: not in the bag (no cabin/state under /bogus): give one of its namespaces, /'
    )
    with pytest.raises(bagio.NamespaceError, match=r"^--namespace: invalid namespace '1veh'"):
        bagio.bag_topic_map(bag, names, '1veh')
    with pytest.raises(
        bagio.NamespaceError, match=r"several namespaces \('/veh1', '/veh2'\): say which one with --namespace$"
    ):
        bagio.bag_topic_map(bag, names)
    assert issubclass(bagio.NamespaceError, ValueError)
    # A bag holding none of the relative names under any namespace: nothing to choose among, so no refusal (the
    # caller says what is missing); the absolute names still map.
    assert bagio.bag_topic_map(['/clock', '/rosout'], names, 'bogus') == {'/clock': '/clock'}


@pytest.mark.parametrize('ns', [None, '/', '/veh1/'], ids=['relative', 'fully-qualified', 'namespaced'])
def test_loaders_read_every_naming(tmp_path, ns):
    w = _writer(tmp_path / 'bag', 'sqlite3', ns)
    _write_steps(w, range(3), ns=ns)
    w.write((ns or '') + 'hvac/command', 0, _ser(_msg('ceco_msgs/msg/AcCommand', step_index=0, blower_flow_kgps=0.1)))
    w.close()
    ts = bagio.load_run_timeseries(tmp_path / 'bag')
    assert ts['step_index'].tolist() == [0, 1, 2] and ts['t_cab_c'].tolist() == [40.0, 39.0, 38.0]
    assert bagio.load_commands(tmp_path / 'bag')['mdot_bl_kgps'].tolist() == [0.1]
    assert set(bagio.topic_types(tmp_path / 'bag', ['cabin/state', 'hvac/power'])) == {'cabin/state', 'hvac/power'}


def test_two_vehicle_bag_needs_a_namespace(tmp_path):
    w = bag_writer.BagWriter(tmp_path / 'bag')
    for ns in ('/veh1/', '/veh2/'):
        for topic in ('cabin/state', 'cabin/comfort', 'hvac/power'):
            w.add_topic(ns + topic, TYPES[topic])
    _write_steps(w, range(3), ns='/veh1/')
    _write_steps(w, range(2), ns='/veh2/', scale=2.0)
    w.close()
    with pytest.raises(ValueError, match='several namespaces'):
        bagio.load_run_timeseries(tmp_path / 'bag')
    v1 = bagio.load_run_timeseries(tmp_path / 'bag', namespace='veh1')
    v2 = bagio.load_run_timeseries(tmp_path / 'bag', namespace='/veh2')
    assert v1['t_cab_c'].tolist() == [40.0, 39.0, 38.0]
    assert v2['t_cab_c'].tolist() == [80.0, 78.0] and v2['p_comp_w'].tolist() == [2000.0, 2002.0]


# --- bag timestamps ------------------------------------------------------------------------
def test_sim_time_stamps_are_the_header_stamps():
    store = bagio.typestore()
    stamps = bag_writer.SimTimeStamps()
    log = store.serialize_cdr(
        sample(store, 'rcl_interfaces/msg/Log', 1, stamp_ns=1_700_000_000 * SEC), 'rcl_interfaces/msg/Log'
    )
    assert stamps('rcl_interfaces/msg/Log', log) == 0  # before any simulation time
    for n, typ in enumerate(
        [
            'ceco_msgs/msg/CabinState',
            'ceco_msgs/msg/WeatherPreview',
            'rosgraph_msgs/msg/Clock',
            'ceco_msgs/msg/ControllerDiagnostics',
        ]
    ):
        t_ns = 5 * n * SEC + 250_000_000
        assert stamps(typ, store.serialize_cdr(sample(store, typ, n, stamp_ns=t_ns), typ)) == t_ns
    assert stamps('rcl_interfaces/msg/Log', log) == 15 * SEC + 250_000_000  # wall-clock stamp ignored
    # an older state after a newer one keeps its own stamp; the latest time does not go back
    state = 'ceco_msgs/msg/CabinState'
    old = store.serialize_cdr(sample(store, state, 0, stamp_ns=3 * SEC), state)
    assert stamps('ceco_msgs/msg/CabinState', old) == 3 * SEC and stamps.latest_ns == 15 * SEC + 250_000_000


def test_cdr_leading_time_little_and_big_endian():
    assert bag_writer.cdr_leading_time_ns(b'\x00\x01\x00\x00' + struct.pack('<iI', 7, 5)) == 7 * SEC + 5
    assert bag_writer.cdr_leading_time_ns(b'\x00\x00\x00\x00' + struct.pack('>iI', 7, 5)) == 7 * SEC + 5
    with pytest.raises(ValueError, match='too short'):
        bag_writer.cdr_leading_time_ns(b'\x00\x01\x00\x00')


def test_lockstep_stamps_pace_the_bag_at_the_drive(tmp_path):
    """Bag timestamps from SimTimeStamps: every stamped message at its header stamp
    n * dt, so the bag lasts the drive (N - 1) * dt and `ros2 bag play` replays it at
    its pace; /rosout at the simulation time it arrived in."""
    store = bagio.typestore()
    stamps = bag_writer.SimTimeStamps()
    w = bag_writer.BagWriter(tmp_path / 'bag')
    w.add_topic('/cabin/state', TYPES['cabin/state'])
    w.add_topic('/clock', 'rosgraph_msgs/msg/Clock')
    w.add_topic('/rosout', 'rcl_interfaces/msg/Log')
    dt_ns, n_steps = SEC, 30
    for n in range(n_steps):
        for topic, typ in (('/clock', 'rosgraph_msgs/msg/Clock'), ('/cabin/state', TYPES['cabin/state'])):
            data = store.serialize_cdr(sample(store, typ, n, stamp_ns=n * dt_ns), typ)
            w.write(topic, stamps(typ, data), data)
        if n % 10 == 5:
            data = store.serialize_cdr(
                sample(store, 'rcl_interfaces/msg/Log', n, stamp_ns=1_700_000_000 * SEC), 'rcl_interfaces/msg/Log'
            )
            w.write('/rosout', stamps('rcl_interfaces/msg/Log', data), data)
    w.close()
    got = {}
    for topic, t_ns, msg in bagio.read_messages(tmp_path / 'bag'):
        got.setdefault(topic, []).append(t_ns)
        if topic == '/cabin/state':
            assert t_ns == msg.header.stamp.sec * SEC + msg.header.stamp.nanosec
    assert got['/cabin/state'] == [n * dt_ns for n in range(n_steps)]
    assert got['/clock'] == got['/cabin/state']
    assert got['/rosout'] == [5 * SEC, 15 * SEC, 25 * SEC]
    info = yaml.safe_load((tmp_path / 'bag' / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['duration']['nanoseconds'] == (n_steps - 1) * dt_ns
    assert info['starting_time']['nanoseconds_since_epoch'] == 0


# --- independent reader and writer -----------------------------------------------------------
def test_independent_mcap_reader_gets_the_same_messages(tmp_path):
    """Every ceco_msgs type (plus Clock and Log) written by BagWriter is decoded by the
    `mcap` package with mcap_ros2 (its own CDR decoder, from the schema in the file) to
    the same field values; log times are the bag timestamps; the channel metadata and
    the embedded rosbag2 metadata are Jazzy's version 9."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    store = bagio.typestore()
    types = {'/' + t: m for t, m in TYPES.items()} | {
        '/clock': 'rosgraph_msgs/msg/Clock',
        '/rosout': 'rcl_interfaces/msg/Log',
    }
    interfaces = pytest.importorskip('ceco_ros.interfaces', reason='needs rclpy (its QoS profiles)')

    w = bag_writer.BagWriter(tmp_path / 'bag')
    for topic, typ in types.items():
        w.add_topic(topic, typ, interfaces.QOS_STATE)
    written = []
    for n in range(3):
        for topic, typ in types.items():
            msg = sample(store, typ, 10 * n + len(topic), stamp_ns=n * SEC)
            w.write(topic, n * SEC + len(topic), store.serialize_cdr(msg, typ))
            written.append((topic, n * SEC + len(topic), plain(msg)))
    w.close()
    with open(tmp_path / 'bag' / 'bag_0.mcap', 'rb') as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        decoded = [
            (ch.topic, m.log_time, plain(d)) for _, ch, m, d in reader.iter_decoded_messages(log_time_order=False)
        ]
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert summary.statistics.message_count == len(written) == 27
    assert {ch.topic: sch.name for ch in summary.channels.values() for sch in [summary.schemas[ch.schema_id]]} == types
    for ch in summary.channels.values():
        assert ch.message_encoding == 'cdr' and summary.schemas[ch.schema_id].encoding == 'ros2msg'
        check_qos_v9(yaml.safe_load(ch.metadata['offered_qos_profiles']), ch.topic)
        assert ch.metadata['topic_type_hash'] == store.hash_rihs01(types[ch.topic])
    by_key = {(t, ts): v for t, ts, v in decoded}
    assert len(by_key) == len(written)
    for topic, t_ns, values in written:
        assert_same_fields(values, by_key[(topic, t_ns)], f'{topic}@{t_ns}')
    check_jazzy_metadata(
        {'rosbag2_bagfile_information': yaml.safe_load(meta['rosbag2']['serialized_metadata'])}, tmp_path / 'bag'
    )
    # and rosbags reads the same values back
    back = [(t, ts, plain(m)) for t, ts, m in bagio.read_messages(tmp_path / 'bag')]
    assert sorted((t, ts) for t, ts, _ in back) == sorted((t, ts) for t, ts, _ in written)  # every message, once
    for topic, t_ns, values in back:
        assert_same_fields(values, by_key[(topic, t_ns)], f'rosbags {topic}@{t_ns}')


def _ros2_bag_record_bag(bag_dir, steps, ns=''):
    """A `ros2 bag record`-style bag (independent writer) of plant steps 0..steps-1."""
    store = bagio.typestore()
    topics = {
        f'{ns}/cabin/state': TYPES['cabin/state'],
        f'{ns}/cabin/comfort': TYPES['cabin/comfort'],
        f'{ns}/hvac/power': TYPES['hvac/power'],
        f'{ns}/hvac/command': TYPES['hvac/command'],
    }
    msgs = []
    for n in range(steps):
        t_wall = 1_764_000_000 * SEC + n * 20_000_000  # receive times of an accelerated loop
        for topic, typ in topics.items():
            if typ == TYPES['hvac/command'] and n % 5:
                continue
            m = plain(sample(store, typ, n, stamp_ns=n * SEC))
            m['step_index'] = n // 5 if typ == TYPES['hvac/command'] else n
            if typ == TYPES['cabin/state']:
                m['scenario_time_s'], m['t_cab_c'] = float(n), 45.0 - 0.5 * n
            if typ == TYPES['hvac/power']:
                m['p_comp_w'], m['p_blower_w'] = 1500.0 - n, 60.0
            msgs.append((topic, t_wall, m))
    hashes = {t: store.hash_rihs01(t) for t in topics.values()}
    from ceco_bringup.bagio import _msg_dir

    write_ros2_bag_record_style(bag_dir, topics, msgs, _msg_dir(), hashes)


@pytest.mark.parametrize('ns', ['', '/veh1'], ids=['root', 'namespaced'])
def test_reads_a_bag_as_ros2_bag_record_writes_it(tmp_path, ns):
    _ros2_bag_record_bag(tmp_path / 'rec', 10, ns)
    meta = yaml.safe_load((tmp_path / 'rec' / 'metadata.yaml').read_text())
    check_jazzy_metadata(meta, tmp_path / 'rec')  # the emulation follows the same rules
    check_rosbag2_record_layout(meta, tmp_path / 'rec')
    ts = bagio.load_run_timeseries(tmp_path / 'rec')
    assert ts['step_index'].tolist() == list(range(10))
    assert ts['t_cab_c'].tolist() == [45.0 - 0.5 * n for n in range(10)]
    assert ts['p_comp_w'].tolist() == [1500.0 - n for n in range(10)]
    cmds = bagio.load_commands(tmp_path / 'rec')
    assert cmds['k'].tolist() == [0, 1] and cmds['t_s'].tolist() == [0.0, 5.0]
    assert bagio.topic_counts(tmp_path / 'rec')[f'{ns}/cabin/state'] == 10


def test_commands_of_bags_before_epoch_and_sequence_read_with_both_zero(tmp_path):
    """AcCommand gained `epoch` and `sequence` (issue 17); a bag recorded before holds the older
    (shorter) CDR under the same type name: it reads with both 0, the other fields intact, beside
    commands of the current format."""
    store = bagio.typestore()
    w = bag_writer.BagWriter(tmp_path / 'bag')
    w.add_topic('/hvac/command', 'ceco_msgs/msg/AcCommand')
    old = sample(store, bagio.LEGACY_ACCOMMAND, 3, stamp_ns=5 * SEC)
    new = sample(store, 'ceco_msgs/msg/AcCommand', 4, stamp_ns=10 * SEC)
    w.write('/hvac/command', 5 * SEC, store.serialize_cdr(old, bagio.LEGACY_ACCOMMAND))
    w.write('/hvac/command', 10 * SEC, store.serialize_cdr(new, 'ceco_msgs/msg/AcCommand'))
    w.close()
    cmds = bagio.load_commands(tmp_path / 'bag')
    assert cmds['epoch'].tolist() == [0, new.epoch] and cmds['sequence'].tolist() == [0, new.sequence]
    assert new.epoch != 0 and new.sequence != 0  # the sample sets every field
    assert cmds['k'].tolist() == [old.step_index, new.step_index]
    assert cmds['mdot_bl_kgps'].tolist() == [old.blower_flow_kgps, new.blower_flow_kgps]
    assert cmds['strategy'].tolist() == [old.strategy, new.strategy]


PRE_ISSUE21_MSGS = Path(__file__).parent / 'data' / 'ceco_msgs_before_issue21'
"""CabinState.msg and AcCommand.msg as main defined them before the door and cabin CO2 (issue 21)."""


def _pre_issue21_store():
    """A typestore holding the pre-issue-21 CabinState and AcCommand under their own names."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    for name in ('CabinState', 'AcCommand'):
        text = (PRE_ISSUE21_MSGS / f'{name}.msg').read_text()
        store.register(get_types_from_msg(text, f'ceco_msgs_pre21/msg/{name}'))
    return store


def test_bags_recorded_before_the_door_and_co2_read_with_them_unknown(tmp_path):
    """A bag of CabinState / AcCommand serialized with main's definitions of before issue 21 (no cabin CO2, no
    door) reads under the current types: every old field intact, the cabin CO2, the sensor and the door NaN
    (not recorded) and the door command NaN (not commanded), beside messages of the current format."""
    old_store = _pre_issue21_store()
    store = bagio.typestore()
    w = bag_writer.BagWriter(tmp_path / 'bag')
    w.add_topic('/cabin/state', 'ceco_msgs/msg/CabinState')
    w.add_topic('/hvac/command', 'ceco_msgs/msg/AcCommand')
    old_state = sample(old_store, 'ceco_msgs_pre21/msg/CabinState', 1, stamp_ns=0)
    old_cmd = sample(old_store, 'ceco_msgs_pre21/msg/AcCommand', 2, stamp_ns=0)
    new_state = sample(store, 'ceco_msgs/msg/CabinState', 3, stamp_ns=SEC)
    new_cmd = sample(store, 'ceco_msgs/msg/AcCommand', 4, stamp_ns=SEC)
    w.write('/cabin/state', 0, old_store.serialize_cdr(old_state, 'ceco_msgs_pre21/msg/CabinState'))
    w.write('/hvac/command', 0, old_store.serialize_cdr(old_cmd, 'ceco_msgs_pre21/msg/AcCommand'))
    w.write('/cabin/state', SEC, store.serialize_cdr(new_state, 'ceco_msgs/msg/CabinState'))
    w.write('/hvac/command', SEC, store.serialize_cdr(new_cmd, 'ceco_msgs/msg/AcCommand'))
    w.close()
    states = [m for _, _, m in bagio.read_messages(tmp_path / 'bag', ('cabin/state',))]
    assert len(states) == 2
    for name in ('t_cab_c', 'rh_cab', 't_amb_c', 'mdot_bl_kgps', 't_evap_sp_c', 'step_index', 'fallback'):
        assert getattr(states[0], name) == getattr(old_state, name), name
        assert getattr(states[1], name) == getattr(new_state, name), name
    for name in ('co2_cab_ppm', 'co2_sensor_ppm', 'recirc_share', 'recirc_share_cmd'):
        assert math.isnan(getattr(states[0], name)), name
        assert getattr(states[1], name) == getattr(new_state, name) and math.isfinite(getattr(new_state, name))
    cmds = bagio.load_commands(tmp_path / 'bag')
    assert cmds['k'].tolist() == [old_cmd.step_index, new_cmd.step_index]
    assert cmds['epoch'].tolist() == [old_cmd.epoch, new_cmd.epoch] and old_cmd.epoch != 0
    assert cmds['mdot_bl_kgps'].tolist() == [old_cmd.blower_flow_kgps, new_cmd.blower_flow_kgps]
    assert math.isnan(cmds['recirc_share'][0]) and cmds['recirc_share'][1] == new_cmd.recirc_share


def test_door_and_co2_round_trip_through_a_bag(tmp_path):
    """The plant's CabinState and a controller's AcCommand with the door and cabin CO2 set (conversions) come back
    from a bag with the same numbers; a command that leaves the door alone reads as NaN."""
    from ceco_core.contracts import MEASUREMENTS, AcInput
    from ceco_ros import conversions
    from ceco_v2x_preview.scenario import Environment

    meas = {k: 20.0 + i for i, k in enumerate(MEASUREMENTS)}
    meas.update(rh_cab=0.5, co2_cab_ppm=1734.5, co2_sensor_ppm=1701.0, recirc_share=0.37)
    env = Environment(t_amb_c=35.0, solar_wm2=800.0, rh=0.4, speed_mps=13.0)
    u = AcInput(0.08, 5.0, recirc_share=0.25)
    st = conversions.state_msg(7, 3.5, conversions.stamp_from_s(3.5), meas, env, u, False, recirc_share_cmd=0.25)
    c1 = conversions.command_msg(u, 3, conversions.stamp_from_s(3.0), 1.0, 'baseline', False)
    c2 = conversions.command_msg(AcInput(0.08, 5.0), 4, conversions.stamp_from_s(4.0), 1.0, 'baseline', False)
    assert c2.recirc_share == -1.0  # the wire's "not commanded"
    assert conversions.command_input(c2).door_commanded is False
    assert conversions.command_input(c1).recirc_share == 0.25
    from rclpy.serialization import serialize_message

    w = bag_writer.BagWriter(tmp_path / 'bag')
    w.add_topic('/cabin/state', 'ceco_msgs/msg/CabinState')
    w.add_topic('/hvac/command', 'ceco_msgs/msg/AcCommand')
    w.write('/cabin/state', 3 * SEC, serialize_message(st))
    w.write('/hvac/command', 3 * SEC, serialize_message(c1))
    w.write('/hvac/command', 4 * SEC, serialize_message(c2))
    w.close()
    (back,) = [m for _, _, m in bagio.read_messages(tmp_path / 'bag', ('cabin/state',))]
    assert (back.co2_cab_ppm, back.co2_sensor_ppm, back.recirc_share, back.recirc_share_cmd) == (
        1734.5,
        1701.0,
        0.37,
        0.25,
    )
    cmds = bagio.load_commands(tmp_path / 'bag')
    assert cmds['recirc_share'][0] == 0.25 and math.isnan(cmds['recirc_share'][1])
