"""Write rosbag2 bags the way Jazzy's rosbag2 does, with rosbags (no rclpy needed).

A bag is a rosbag2 directory: ``metadata.yaml`` (metadata version 9, the format
Jazzy's ``ros2 bag record`` writes and ``ros2 bag info`` reads, with ``ros_distro`` from
``ROS_DISTRO`` as rosbag2's SequentialWriter stores it) beside one storage file named as
rosbag2 names its first file (``<bag>/<bag>_0.mcap``, MCAP, Jazzy's default storage, or
``<bag>/<bag>_0.db3``, SQLite 3). Topic names are stored as given: the recorder passes the
fully qualified names (``/cabin/state``, ``/veh1/cabin/state``), as
``ros2 bag record`` does.

Crash tolerance: :meth:`BagWriter.flush` leaves a complete bag on disk that every
reader opens (rosbags, the ``mcap`` package, rosbag2): SQLite commits its
transaction; MCAP closes the open chunk and appends the summary section and
footer, which the next flush truncates and writes again. ``metadata.yaml`` is
rewritten atomically with the counts of what is on disk. A SIGKILL between two
flushes loses at most the messages since the last one.

Public API:
    STORAGES, TIMESTAMP_MODES, BAG_VERSION
    BagWriter(path, storage='mcap')
    SimTimeStamps()  -> bag timestamp [ns] of a serialized message in simulation time
"""

from __future__ import annotations

import os
import sqlite3
import struct
from io import BytesIO, StringIO
from pathlib import Path

from rosbags.interfaces import ConnectionExtRosbag2
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.metadata import dump_qos_v9
from rosbags.rosbag2.storage_mcap import Channel, McapWriter, write_channel, write_string
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer
from ruamel.yaml import YAML

from ceco_bringup.bagio import typestore

__all__ = [
    'STORAGES',
    'TIMESTAMP_MODES',
    'BAG_VERSION',
    'RMW_DURATION_INFINITE',
    'BagWriter',
    'SimTimeStamps',
    'cdr_leading_time_ns',
    'storage_file_name',
    'ros_distro',
]

STORAGES = ('mcap', 'sqlite3')
"""Storage plugins a bag can be written with (rosbag2's storage identifiers); the first is the default."""

TIMESTAMP_MODES = ('receive', 'sim')
"""Bag timestamps: ``receive`` = wall-clock receive time (rosbag2's default), ``sim`` =
simulation time (the message's header stamp; what rosbag2 records with ``--use-sim-time``)."""

BAG_VERSION = 9
"""rosbag2 metadata version written (Jazzy's rosbag2 writes 9)."""

RMW_DURATION_INFINITE = (9223372036, 854775807)
"""(sec, nsec) of an infinite QoS duration as Jazzy's rmw reports it and rosbag2 stores it."""

_PLUGINS = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}


def storage_file_name(bag_dir: str | os.PathLike, storage: str = STORAGES[0]) -> str:
    """The name of a bag's first storage file as rosbag2 writes it: ``<bag dir name>_0.<mcap|db3>``.

    rosbag2's ``SequentialWriter::format_storage_uri`` (Jazzy) appends ``_<file index>`` to the
    bag directory's name; the storage plugin adds its extension.
    """
    return f'{Path(bag_dir).name}_0.{"db3" if storage == "sqlite3" else "mcap"}'


def ros_distro() -> str:
    """The ``ros_distro`` rosbag2 stores in metadata.yaml: ``ROS_DISTRO`` of the environment.

    rosbag2's SequentialWriter reads the variable and stores '' when it is unset; a ceco bag
    is a Jazzy bag, so 'jazzy' then.
    """
    return os.environ.get('ROS_DISTRO') or 'jazzy'


class _KeepOpen:
    """A file proxy whose close() only flushes (so rosbags' close can write a summary mid-recording)."""

    def __init__(self, fh):
        self._fh = fh

    def __getattr__(self, name):
        return getattr(self._fh, name)

    def close(self) -> None:
        self._fh.flush()


class _FlushableMcapWriter(McapWriter):
    """rosbags' MCAP storage writer plus :meth:`flush`.

    After the first flush the file is always a complete MCAP (chunks, metadata
    record, summary with chunk indexes and statistics, footer), except while a chunk
    or that tail is being written: each chunk written (at a flush, or when it is full)
    replaces the tail, which is written again right after it.
    """

    def __init__(self, path: Path, compression) -> None:
        super().__init__(path, compression)
        # rosbags names the file <bag>.mcap; rosbag2 <bag>_0.mcap. The open handle survives the rename.
        renamed = path / storage_file_name(path, 'mcap')
        self.path.rename(renamed)
        self.path = renamed
        self._tail_at: int | None = None  # file offset of the summary tail on disk, if any
        self._meta: tuple[int, str] = (BAG_VERSION, '')

    def add_connection(self, connection, offered_qos_profiles: str) -> None:
        """Register a channel as rosbag2's MCAP plugin writes it.

        Its metadata holds ``offered_qos_profiles`` and ``topic_type_hash``
        (rosbags writes the first only).
        """
        metadata = BytesIO()
        for key, value in (('offered_qos_profiles', offered_qos_profiles), ('topic_type_hash', connection.digest)):
            write_string(metadata, key)
            write_string(metadata, value)
        self.channels.append(
            Channel(
                connection.id,
                connection.msgtype,
                connection.topic,
                connection.ext.serialization_format,
                metadata.getvalue(),
            )
        )
        self.channel_stats[connection.id] = 0
        write_channel(self.chunk.bio, self.channels[-1], self.schemas)

    def _drop_tail(self) -> None:
        if self._tail_at is not None:
            self.bio.seek(self._tail_at)
            self.bio.truncate()
            self._tail_at = None

    def _write_tail(self) -> None:
        tail_at = self.bio.tell()
        fh = self.bio
        self.bio = _KeepOpen(fh)
        try:
            McapWriter.close(self, *self._meta)  # the chunk is empty here: writes the tail only
        finally:
            self.bio = fh
        self._tail_at = tail_at

    def close_chunk(self) -> None:
        had_tail = self._tail_at is not None
        self._drop_tail()
        super().close_chunk()
        if had_tail:
            self._write_tail()

    def flush(self, version: int, metadata: str) -> None:
        """Write every message so far and a summary tail; the file stays open for more."""
        self._meta = (version, metadata)
        self._drop_tail()
        if self.chunk.bio.tell():
            McapWriter.close_chunk(self)
        self._write_tail()

    def close(self, version: int, metadata: str) -> None:
        self._drop_tail()
        super().close(version, metadata)


class _Writer(Writer):
    """rosbags' rosbag2 Writer with the flushable MCAP storage."""

    STORAGE_PLUGINS = {StoragePlugin.SQLITE3: Sqlite3Writer, StoragePlugin.MCAP: _FlushableMcapWriter}


class BagWriter:
    """A rosbag2 writer (metadata version 9, MCAP or SQLite 3) that stays readable if the process dies.

    :meth:`flush` puts a complete bag on disk, :meth:`close` finalises it. Messages
    are raw CDR bytes with a caller-chosen timestamp [ns].
    """

    def __init__(self, path: str | os.PathLike, storage: str = STORAGES[0]):
        if storage not in STORAGES:
            raise ValueError(f'storage: {storage!r} is not one of {STORAGES}')
        self.path = Path(path)
        self.storage = storage
        self._writer = _Writer(self.path, version=BAG_VERSION, storage_plugin=_PLUGINS[storage])
        self._writer.open()
        if storage == 'sqlite3':
            # rosbags opens sqlite bound to the creating thread; a recorder writes
            # from its executor thread and closes from the main thread (callers
            # serialise access), so reopen the (already initialised) database
            # without the same-thread check.
            # Renamed to rosbag2's <bag>_0.db3 while closed.
            st = self._writer.storage
            st.conn.commit()
            st.conn.close()
            renamed = self.path / storage_file_name(self.path, 'sqlite3')
            st.path.rename(renamed)
            st.path = renamed
            st.conn = sqlite3.connect(f'file:{st.path}', uri=True, check_same_thread=False)
            st.cursor = st.conn.cursor()
        self._connections: dict = {}
        self._store = typestore()
        self._closed = False

    def set_custom_data(self, key: str, value: str) -> None:
        """A ``custom_data`` entry of metadata.yaml (rosbag2 keeps string values only)."""
        self._writer.set_custom_data(str(key), str(value))

    def add_topic(self, topic: str, msgtype: str, qos=None) -> None:
        """Register a topic (idempotent).

        ``qos`` is the publisher's rclpy QoSProfile (stored as the offered QoS
        profile, as rosbag2 does) or None.
        """
        if topic in self._connections:
            return
        offered = [] if qos is None else [_qos_to_rosbags(qos)]
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, typestore=self._store, offered_qos_profiles=offered
        )

    def write(self, topic: str, t_ns: int, data: bytes) -> None:
        """Write one serialized message with bag timestamp ``t_ns`` [ns].

        Equal timestamps are allowed; readers return them in write order.
        """
        self._writer.write(self._connections[topic], int(t_ns), bytes(data))

    @property
    def counts(self) -> dict[str, int]:
        """Messages written per topic."""
        return {topic: self._writer.counts[c.id] for topic, c in self._connections.items()}

    def flush(self) -> None:
        """Put everything written so far on disk as a complete bag, metadata.yaml included."""
        if self._closed:
            return
        meta = _metadata(self._writer)
        if self.storage == 'sqlite3':
            self._writer.storage.conn.commit()
        else:
            self._writer.storage.flush(self._writer.version, _yaml_text(meta['rosbag2_bagfile_information']).strip())
        _write_atomically(self._writer.metapath, _yaml_text(meta))

    def close(self) -> None:
        """Finalise the bag as rosbags does (idempotent); metadata.yaml as :meth:`flush` writes it."""
        if self._closed:
            return
        self._closed = True
        meta = _metadata(self._writer)
        self._writer.close()
        _write_atomically(self._writer.metapath, _yaml_text(meta))


class SimTimeStamps:
    """Bag timestamps in simulation time, for a recorder in lockstep.

    A message that starts with a ``builtin_interfaces/Time`` (``std_msgs/Header
    header`` first, or ``rosgraph_msgs/Clock``) gets that time; any other message
    (``rcl_interfaces/Log`` on ``/rosout``, which rcl stamps on the wall clock) gets
    the latest simulation time seen so far (0 before any).
    """

    def __init__(self) -> None:
        self.latest_ns = 0
        """Latest simulation time seen [ns]."""
        self._leading_time: dict[str, bool] = {}

    def __call__(self, msgtype: str, data: bytes) -> int:
        """Bag timestamp [ns] of one serialized message of type ``msgtype``."""
        if self._starts_with_time(msgtype):
            self.latest_ns = max(self.latest_ns, cdr_leading_time_ns(data))
            return cdr_leading_time_ns(data)
        return self.latest_ns

    def _starts_with_time(self, msgtype: str) -> bool:
        if msgtype not in self._leading_time:
            store = typestore()
            fields = store.fielddefs[msgtype][1] if msgtype in store.fielddefs else []
            first = fields[0][1][1] if fields else None
            self._leading_time[msgtype] = msgtype != 'rcl_interfaces/msg/Log' and first in (
                'std_msgs/msg/Header',
                'builtin_interfaces/msg/Time',
            )
        return self._leading_time[msgtype]


def cdr_leading_time_ns(data: bytes) -> int:
    """The ``builtin_interfaces/Time`` at the start of a CDR-serialized message [ns].

    That is the header stamp: int32 sec and uint32 nanosec after the 4-byte
    encapsulation header, little- or big-endian as that header says.
    """
    if len(data) < 12:
        raise ValueError(f'{len(data)} bytes: too short for a CDR message starting with a time stamp')
    sec, nsec = struct.unpack_from('<iI' if data[1] & 1 else '>iI', data, 4)
    return sec * 1_000_000_000 + nsec


def _qos_to_rosbags(qos):
    """An rclpy QoSProfile as a rosbags Qos.

    Zero durations (rclpy's "default") are stored as the infinite duration the
    middleware then applies, as rosbag2 records them.
    """
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    def duration(d) -> QosTime:
        ns = int(d.nanoseconds)
        return QosTime(*RMW_DURATION_INFINITE) if ns == 0 else QosTime(sec=ns // 10**9, nsec=ns % 10**9)

    return Qos(
        history=QosHistory(int(qos.history)),
        depth=int(qos.depth),
        reliability=QosReliability(int(qos.reliability)),
        durability=QosDurability(int(qos.durability)),
        deadline=duration(qos.deadline),
        lifespan=duration(qos.lifespan),
        liveliness=QosLiveliness(int(qos.liveliness)),
        liveliness_lease_duration=duration(qos.liveliness_lease_duration),
        avoid_ros_namespace_conventions=bool(qos.avoid_ros_namespace_conventions),
    )


def _metadata(writer) -> dict:
    """The metadata.yaml content for what a rosbags Writer holds so far.

    The layout of rosbags' Writer.close, which follows rosbag2's YAML encoding of
    BagMetadata (rosbag2_storage/yaml.hpp, version 9).
    """
    count = sum(writer.counts.values())
    start = writer.min_timestamp if count else 0
    duration = max(0, writer.max_timestamp - writer.min_timestamp) if count else 0
    name = writer.storage.path.name
    return {
        'rosbag2_bagfile_information': {
            'version': writer.version,
            'storage_identifier': writer.storage_plugin.name.lower(),
            'relative_file_paths': [name],
            'duration': {'nanoseconds': duration},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': count,
            'topics_with_message_count': [
                {
                    'topic_metadata': {
                        'name': c.topic,
                        'type': c.msgtype,
                        'serialization_format': c.ext.serialization_format,
                        'offered_qos_profiles': dump_qos_v9(c.ext.offered_qos_profiles),
                        'type_description_hash': c.digest,
                    },
                    'message_count': writer.counts[c.id],
                }
                for c in writer.connections
                if isinstance(c.ext, ConnectionExtRosbag2)
            ],
            'compression_format': '',
            'compression_mode': '',
            'files': [
                {
                    'path': name,
                    'starting_time': {'nanoseconds_since_epoch': start},
                    'duration': {'nanoseconds': duration},
                    'message_count': count,
                }
            ],
            'custom_data': writer.custom_data or None,
            'ros_distro': ros_distro(),
        }
    }


def _yaml_text(data) -> str:
    yaml = YAML(typ='safe')
    yaml.default_flow_style = False
    yaml.width = 4096  # no folded lines (a type hash on one line, as rosbag2 writes it)
    text = StringIO()
    yaml.dump(data, text)
    return text.getvalue()


def _write_atomically(path: Path, text: str) -> None:
    tmp = path.with_suffix('.yaml.tmp')
    tmp.write_text(text, 'utf8')
    tmp.replace(path)
