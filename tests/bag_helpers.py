"""Test helpers for rosbag2 bags: sample messages, a field-by-field comparison, the
metadata rules of Jazzy's rosbag2, and a bag written the way `ros2 bag record` writes
one, by code independent of rosbags (the `mcap` and `mcap_ros2` packages).

Where the format rules come from (read, not copied; nothing here is fetched at test
time): rosbag2 on its `jazzy` branch, `rosbag2_storage/include/rosbag2_storage/yaml.hpp`
(`convert<BagMetadata>::decode` and `convert<TopicMetadata>::decode` for version 9:
every key below is read with `as<...>()`, so a missing key or a wrong type makes
`ros2 bag info` fail), `rosbag2_storage/src/rosbag2_storage/qos.cpp` (version 9 QoS:
a YAML sequence of maps, policies as rmw strings, durations {sec, nsec}), and
`rosbag2_storage_mcap/src/mcap_storage.cpp` (channel metadata `offered_qos_profiles`
and `topic_type_hash`, metadata record `rosbag2` / `serialized_metadata`).
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import yaml

QOS_POLICIES = {
    'history': {'system_default', 'keep_last', 'keep_all', 'unknown'},
    'reliability': {'system_default', 'reliable', 'best_effort', 'best_available', 'unknown'},
    'durability': {'system_default', 'transient_local', 'volatile', 'best_available', 'unknown'},
    'liveliness': {'system_default', 'automatic', 'manual_by_topic', 'best_available', 'unknown'},
}
"""rmw's policy strings (rmw/qos_string_conversions.h, Jazzy) that rosbag2 writes and reads for version 9."""

INFINITE = {'sec': 9223372036, 'nsec': 854775807}
"""RMW_DURATION_INFINITE as Jazzy's rosbag2 stores it."""


# --- sample messages ------------------------------------------------------------------
def _value(store, node, seed: float, name: str):
    from rosbags.typesys.store import Nodetype

    kind, info = node
    if kind == Nodetype.BASE:
        typ = info[0]
        if typ == 'string':
            return f'{name}-{seed:g}'
        if typ == 'bool':
            return int(seed) % 2 == 1
        if typ.startswith(('int', 'uint')):
            return (int(seed) * 7 + len(name)) % 200 + (0 if typ.startswith('u') else -50)
        return seed * 1.25 + len(name) * 0.001
    if kind == Nodetype.NAME:
        return sample(store, info, seed)
    if kind == Nodetype.SEQUENCE:
        (sub_kind, sub_info), _ = info
        values = [_value(store, (sub_kind, sub_info), seed + i, name) for i in range(3)]
        if sub_kind == Nodetype.BASE and sub_info[0] == 'float64':
            values[1] = math.nan
            return np.array(values, dtype=np.float64)
        if sub_kind == Nodetype.BASE and sub_info[0] == 'bool':
            return np.array(values, dtype=bool)
        return values
    raise NotImplementedError(f'{name}: node kind {kind}')


def sample(store, msgtype: str, seed: float, stamp_ns: int | None = None):
    """A message of ``msgtype`` (rosbags class) with every field set from ``seed``;
    a leading time stamp (header or Clock) set to ``stamp_ns`` when given."""
    cls = store.types[msgtype]
    fields = store.fielddefs[msgtype][1]
    kw = {name: _value(store, node, seed, name) for name, node in fields}
    if stamp_ns is not None and fields:
        first = fields[0][0]
        time_cls = store.types['builtin_interfaces/msg/Time']
        stamp = time_cls(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
        if msgtype == 'rosgraph_msgs/msg/Clock':
            kw[first] = stamp
        elif first == 'header':
            kw[first] = store.types['std_msgs/msg/Header'](stamp=stamp, frame_id='')
    if msgtype == 'builtin_interfaces/msg/Time':
        kw = {'sec': int(seed) % 1000, 'nanosec': (int(seed) * 1000003) % 10**9}
    return cls(**kw)


def plain(obj):
    """A message (rosbags dataclass or mcap_ros2 decoded object) as nested dicts and lists."""
    if dataclasses.is_dataclass(obj):
        return {
            f.name: plain(getattr(obj, f.name))
            for f in dataclasses.fields(obj)
            if not f.name.startswith('__') and not f.name.isupper()
        }  # ROS constants are upper case
    if hasattr(obj, '__slots__') and not isinstance(obj, (str, bytes)):
        return {k: plain(getattr(obj, k)) for k in obj.__slots__ if not k.startswith('_')}
    if isinstance(obj, np.ndarray):
        return [plain(x) for x in obj.tolist()]
    if isinstance(obj, (list, tuple)):
        return [plain(x) for x in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def assert_same_fields(a, b, path='msg') -> None:
    """Equal field by field (NaN equals NaN; bools and numbers compared by value)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), f'{path}: fields {sorted(a)} vs {sorted(b)}'
        for k in a:
            assert_same_fields(a[k], b[k], f'{path}.{k}')
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), f'{path}: {a!r} vs {b!r}'
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same_fields(x, y, f'{path}[{i}]')
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), f'{path}: NaN vs {b!r}'
    else:
        assert a == b and type(a) is type(b) or (isinstance(a, (int, float)) and not isinstance(a, bool) and a == b), (
            f'{path}: {a!r} vs {b!r}'
        )


# --- Jazzy's metadata rules ------------------------------------------------------------
def _uint64(x, what):
    assert isinstance(x, int) and not isinstance(x, bool) and 0 <= x < 2**64, f'{what}: {x!r} is not a uint64'


def _duration(d, what):
    assert isinstance(d, dict) and set(d) == {'sec', 'nsec'}, f'{what}: {d!r}'
    _uint64(d['sec'], f'{what}.sec')
    _uint64(d['nsec'], f'{what}.nsec')


def check_qos_v9(profiles, what='offered_qos_profiles') -> None:
    """A version 9 offered_qos_profiles value: a sequence of maps with rmw strings."""
    assert isinstance(profiles, list), f'{what}: version 9 stores a YAML sequence, got {type(profiles).__name__}'
    keys = {
        'history',
        'depth',
        'reliability',
        'durability',
        'deadline',
        'lifespan',
        'liveliness',
        'liveliness_lease_duration',
        'avoid_ros_namespace_conventions',
    }
    for i, q in enumerate(profiles):
        assert isinstance(q, dict) and set(q) == keys, f'{what}[{i}]: keys {sorted(q)}'
        for policy, allowed in QOS_POLICIES.items():
            assert q[policy] in allowed, f'{what}[{i}].{policy}: {q[policy]!r} not in {sorted(allowed)}'
        assert isinstance(q['depth'], int) and q['depth'] >= 0
        for d in ('deadline', 'lifespan', 'liveliness_lease_duration'):
            _duration(q[d], f'{what}[{i}].{d}')
        assert isinstance(q['avoid_ros_namespace_conventions'], bool)


def check_jazzy_metadata(meta: dict, bag_dir: Path) -> dict:
    """Assert that ``meta`` (a loaded metadata.yaml) decodes under rosbag2 Jazzy's
    version 9 rules and describes the files in ``bag_dir``; returns the inner dict."""
    assert set(meta) == {'rosbag2_bagfile_information'}
    info = meta['rosbag2_bagfile_information']
    assert info['version'] == 9
    assert info['storage_identifier'] in ('mcap', 'sqlite3')
    _uint64(info['duration']['nanoseconds'], 'duration')
    _uint64(info['starting_time']['nanoseconds_since_epoch'], 'starting_time')
    _uint64(info['message_count'], 'message_count')
    assert isinstance(info['topics_with_message_count'], list)
    total = 0
    for t in info['topics_with_message_count']:
        tm = t['topic_metadata']
        assert isinstance(tm['name'], str) and tm['name']
        assert re.fullmatch(r'[A-Za-z0-9_]+/(msg|srv|action)/[A-Za-z0-9_]+', tm['type']), tm['type']
        assert tm['serialization_format'] == 'cdr'
        check_qos_v9(tm['offered_qos_profiles'], f'{tm["name"]}.offered_qos_profiles')
        assert re.fullmatch(r'RIHS01_[0-9a-f]{64}', tm['type_description_hash']), tm['type_description_hash']
        _uint64(t['message_count'], f'{tm["name"]}.message_count')
        total += t['message_count']
    assert total == info['message_count']
    assert isinstance(info['compression_format'], str) and isinstance(info['compression_mode'], str)
    assert isinstance(info['relative_file_paths'], list) and info['relative_file_paths']
    for rel in info['relative_file_paths']:
        assert (Path(bag_dir) / rel).is_file(), rel
    assert [f['path'] for f in info['files']] == info['relative_file_paths']
    for f in info['files']:
        _uint64(f['starting_time']['nanoseconds_since_epoch'], 'files.starting_time')
        _uint64(f['duration']['nanoseconds'], 'files.duration')
        _uint64(f['message_count'], 'files.message_count')
    assert sum(f['message_count'] for f in info['files']) == info['message_count']
    assert 'custom_data' in info and (
        info['custom_data'] is None
        or all(isinstance(k, str) and isinstance(v, str) for k, v in info['custom_data'].items())
    )
    assert isinstance(info['ros_distro'], str)
    return info


def check_rosbag2_record_layout(meta: dict, bag_dir: Path) -> None:
    """What `ros2 bag record` (Jazzy) writes beyond the decoder's rules: one storage file named
    ``<bag dir>_0.<ext>`` (SequentialWriter::format_storage_uri) and ``ros_distro: jazzy``
    (SequentialWriter::open reads ROS_DISTRO)."""
    info = meta['rosbag2_bagfile_information']
    ext = {'mcap': 'mcap', 'sqlite3': 'db3'}[info['storage_identifier']]
    assert info['relative_file_paths'] == [f'{Path(bag_dir).name}_0.{ext}']
    assert info['ros_distro'] == 'jazzy'


# --- a bag as `ros2 bag record` (Jazzy, default mcap storage) writes it -------------------
_HEADER_MSG = 'builtin_interfaces/Time stamp\nstring frame_id\n'
_TIME_MSG = 'int32 sec\nuint32 nanosec\n'
_SEP = '=' * 80 + '\n'


def ros2msg_schema(msgtype: str, msg_dir: Path) -> str:
    """The concatenated .msg text rosbag2 stores as an MCAP schema (message, then its dependencies)."""
    name = msgtype.split('/')[-1]
    text = (Path(msg_dir) / f'{name}.msg').read_text()
    deps = [('std_msgs/msg/Header', _HEADER_MSG)] if 'std_msgs/Header' in text else []
    deps.append(('builtin_interfaces/msg/Time', _TIME_MSG))
    return text + ''.join(f'{_SEP}MSG: {dep}\n{body}' for dep, body in deps)


def write_ros2_bag_record_style(bag_dir: Path, topics: dict, messages, msg_dir: Path, type_hashes: dict) -> None:
    """Write a bag the way Jazzy's `ros2 bag record` does, without rosbags.

    ``topics``: {fully qualified name: message type}; ``messages``: iterable of
    (name, receive time [ns], message as nested dicts). Storage file
    ``<bag>_0.mcap`` (mcap package writer, zstd chunks), channel metadata
    ``offered_qos_profiles`` (version 9 YAML string) and ``topic_type_hash``, a
    ``rosbag2`` metadata record, and metadata.yaml with rosbag2's key order,
    ``ros_distro: jazzy`` and ``custom_data: ~``.
    """
    from mcap.writer import CompressionType, Writer
    from mcap_ros2._dynamic import serialize_dynamic

    bag_dir = Path(bag_dir)
    bag_dir.mkdir(parents=True)
    fname = f'{bag_dir.name}_0.mcap'
    qos = [
        {
            'history': 'keep_last',
            'depth': 1000,
            'reliability': 'reliable',
            'durability': 'volatile',
            'deadline': INFINITE,
            'lifespan': INFINITE,
            'liveliness': 'automatic',
            'liveliness_lease_duration': INFINITE,
            'avoid_ros_namespace_conventions': False,
        }
    ]
    counts = dict.fromkeys(topics, 0)
    t_min, t_max = None, None
    with open(bag_dir / fname, 'wb') as fh:
        w = Writer(fh, compression=CompressionType.ZSTD)
        w.start(profile='ros2', library='rosbag2.mcap.jazzy (test emulation)')
        channels, encoders = {}, {}
        for topic, msgtype in topics.items():
            text = ros2msg_schema(msgtype, msg_dir) if msgtype.startswith('ceco_msgs/') else None
            if text is None:
                raise ValueError(f'{msgtype}: only ceco_msgs types in this emulation')
            sid = w.register_schema(msgtype, 'ros2msg', text.encode())
            channels[topic] = w.register_channel(
                topic,
                'cdr',
                sid,
                metadata={
                    'offered_qos_profiles': yaml.safe_dump(qos, sort_keys=False),
                    'topic_type_hash': type_hashes.get(msgtype, ''),
                },
            )
            encoders[topic] = serialize_dynamic(msgtype, text)[msgtype]
        for topic, t_ns, msg in messages:
            w.add_message(channels[topic], log_time=t_ns, publish_time=t_ns, data=encoders[topic](msg))
            counts[topic] += 1
            t_min = t_ns if t_min is None else min(t_min, t_ns)
            t_max = t_ns if t_max is None else max(t_max, t_ns)
        n = sum(counts.values())
        info = {
            'version': 9,
            'storage_identifier': 'mcap',
            'duration': {'nanoseconds': (t_max - t_min) if n else 0},
            'starting_time': {'nanoseconds_since_epoch': t_min if n else 0},
            'message_count': n,
            'topics_with_message_count': [
                {
                    'topic_metadata': {
                        'name': t,
                        'type': m,
                        'serialization_format': 'cdr',
                        'offered_qos_profiles': qos,
                        'type_description_hash': type_hashes.get(m, ''),
                    },
                    'message_count': counts[t],
                }
                for t, m in topics.items()
            ],
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [fname],
            'files': [
                {
                    'path': fname,
                    'starting_time': {'nanoseconds_since_epoch': t_min if n else 0},
                    'duration': {'nanoseconds': (t_max - t_min) if n else 0},
                    'message_count': n,
                }
            ],
            'custom_data': None,
            'ros_distro': 'jazzy',
        }
        w.add_metadata('rosbag2', {'serialized_metadata': yaml.safe_dump(info, sort_keys=False)})
        w.finish()
    (bag_dir / 'metadata.yaml').write_text(
        yaml.safe_dump({'rosbag2_bagfile_information': info}, sort_keys=False).replace(
            'custom_data: null', 'custom_data: ~'
        )
    )
