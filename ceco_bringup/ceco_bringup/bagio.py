"""Read and write the stack's rosbag2 bags with rosbags (no rclpy needed).

Bags are rosbag2 directories (sqlite3 storage, metadata version 9, the
format Jazzy's rosbag2 writes). The ceco_msgs types are registered in a
rosbags typestore from the ``.msg`` text (installed share directory of
ceco_msgs, or the source tree).

Public API:
    typestore() -> rosbags Typestore with ROS 2 Jazzy + ceco_msgs types
    BagWriter(path)               crash-tolerant writer (periodic flush)
    read_messages(bag_dir, topics=None) -> iterator of (topic, t_ns, msg)
    topic_counts(bag_dir) -> {topic: message count}
    load_run_timeseries(bag_dir) -> dict of numpy arrays (timeseries.csv columns)
    load_commands(bag_dir) -> dict of numpy arrays (one entry per command message)
    load_diagnostics(bag_dir) -> dict of numpy arrays (diagnostics.csv columns)
    write_timeseries_csv / write_diagnostics_csv
"""
from __future__ import annotations

import functools
import math
import os
from io import StringIO
from pathlib import Path
from typing import Iterable, Iterator

import numpy as np

from ceco_core import rundir
from ceco_core.units import s_from_sec_nanosec
from ceco_core.contracts import DIAGNOSTICS_CONTRACT_COLUMNS as DIAGNOSTICS_COLUMNS

TIMESERIES_COLUMNS = rundir.TIMESERIES_COLUMNS
"""Columns of timeseries.csv (docs/architecture.md); extra columns follow."""

TIMESERIES_EXTRA = rundir.TIMESERIES_EXTRA + ('step_index', 'fallback')
"""The extras of a stack run: the simulator's, then the plant step index and the fallback flag."""

BAG_VERSION = 9
"""rosbag2 metadata version written (Jazzy's rosbag2 writes 9)."""


def _msg_dir() -> Path:
    """Directory of the ceco_msgs .msg files: installed share, else source tree."""
    try:
        from ament_index_python.packages import get_package_share_directory
        share = Path(get_package_share_directory('ceco_msgs')) / 'msg'
        if any(share.glob('*.msg')):
            return share
    except Exception:  # not sourced / not installed: fall back to the source tree
        pass
    src = Path(__file__).resolve().parents[2] / 'ceco_msgs' / 'msg'
    if not src.is_dir():
        raise FileNotFoundError('ceco_msgs .msg files not found (neither installed nor in the source tree)')
    return src


@functools.lru_cache(maxsize=1)
def typestore():
    """A rosbags typestore with the ROS 2 Jazzy types plus every ceco_msgs type."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for path in sorted(_msg_dir().glob('*.msg')):
        types.update(get_types_from_msg(path.read_text(), f'ceco_msgs/msg/{path.stem}'))
    store.register(types)
    return store


class BagWriter:
    """rosbag2 writer (rosbags, sqlite3, version 9) that stays readable if the
    process dies: `flush()` commits the database and rewrites metadata.yaml
    atomically with the counts committed so far. `close()` finalises as
    rosbags does. Messages are raw CDR bytes.
    """

    def __init__(self, path: str | os.PathLike):
        from rosbags.rosbag2 import Writer
        self.path = Path(path)
        self._writer = Writer(self.path, version=BAG_VERSION)
        self._writer.open()
        # rosbags opens sqlite bound to the creating thread; a recorder writes
        # from its executor thread and closes from the main thread (callers
        # serialise access), so reopen the (already initialised) database
        # without the same-thread check.
        import sqlite3
        st = self._writer.storage
        st.conn.commit()
        st.conn.close()
        st.conn = sqlite3.connect(f'file:{st.path}', uri=True, check_same_thread=False)
        st.cursor = st.conn.cursor()
        self._connections = {}
        self._store = typestore()
        self._closed = False
        self.last_t_ns = 0

    def add_topic(self, topic: str, msgtype: str, qos=None) -> None:
        """Register a topic (idempotent). `qos` is an rclpy QoSProfile or None."""
        if topic in self._connections:
            return
        offered = [] if qos is None else [_qos_to_rosbags(qos)]
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, typestore=self._store, offered_qos_profiles=offered)

    def write(self, topic: str, t_ns: int, data: bytes) -> int:
        """Write one serialized message; timestamps are made strictly increasing
        (ties of the receive clock get +1 ns) so the bag order is the arrival
        order. Returns the timestamp used."""
        t_ns = max(int(t_ns), self.last_t_ns + 1)
        self._writer.write(self._connections[topic], t_ns, bytes(data))
        self.last_t_ns = t_ns
        return t_ns

    @property
    def counts(self) -> dict[str, int]:
        return {topic: self._writer.counts[c.id] for topic, c in self._connections.items()}

    def flush(self) -> None:
        """Commit everything written so far and write a metadata.yaml that
        describes exactly that (so a reader sees a complete bag up to here)."""
        if self._closed:
            return
        self._writer.storage.conn.commit()
        _write_metadata_yaml(self._writer)

    def close(self) -> None:
        """Commit, write the final metadata (idempotent)."""
        if self._closed:
            return
        self._closed = True
        self._writer.close()


def _qos_to_rosbags(qos):
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
    never = QosTime(sec=0x7FFFFFFF, nsec=0xFFFFFFFF)
    return Qos(
        history=QosHistory(int(qos.history)),
        depth=int(qos.depth),
        reliability=QosReliability(int(qos.reliability)),
        durability=QosDurability(int(qos.durability)),
        deadline=never, lifespan=never,
        liveliness=QosLiveliness(int(qos.liveliness)),
        liveliness_lease_duration=never,
        avoid_ros_namespace_conventions=False,
    )


def _write_metadata_yaml(writer) -> None:
    """metadata.yaml for what a rosbags Writer holds so far (same layout as
    rosbags' Writer.close), written atomically."""
    from rosbags.interfaces import ConnectionExtRosbag2
    from rosbags.rosbag2.metadata import dump_qos_v9
    from ruamel.yaml import YAML
    count = sum(writer.counts.values())
    start = writer.min_timestamp if count else 0
    duration = max(0, writer.max_timestamp - writer.min_timestamp) if count else 0
    name = writer.storage.path.name
    meta = {'rosbag2_bagfile_information': {
        'version': writer.version,
        'storage_identifier': 'sqlite3',
        'relative_file_paths': [name],
        'duration': {'nanoseconds': duration},
        'starting_time': {'nanoseconds_since_epoch': start},
        'message_count': count,
        'topics_with_message_count': [
            {'topic_metadata': {
                'name': c.topic, 'type': c.msgtype,
                'serialization_format': c.ext.serialization_format,
                'offered_qos_profiles': dump_qos_v9(c.ext.offered_qos_profiles),
                'type_description_hash': c.digest},
             'message_count': writer.counts[c.id]}
            for c in writer.connections if isinstance(c.ext, ConnectionExtRosbag2)],
        'compression_format': '',
        'compression_mode': '',
        'files': [{'path': name, 'starting_time': {'nanoseconds_since_epoch': start},
                   'duration': {'nanoseconds': duration}, 'message_count': count}],
        'custom_data': writer.custom_data or None,
        'ros_distro': 'rosbags',
    }}
    yaml = YAML(typ='safe')
    yaml.default_flow_style = False
    text = StringIO()
    yaml.dump(meta, text)
    tmp = writer.metapath.with_suffix('.yaml.tmp')
    tmp.write_text(text.getvalue(), 'utf8')
    tmp.replace(writer.metapath)


# --- Reading ---------------------------------------------------------------------
def read_messages(bag_dir, topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, object]]:
    """Yield (topic, bag timestamp [ns], deserialized message) in bag order."""
    from rosbags.rosbag2 import Reader
    store = typestore()
    with Reader(Path(bag_dir)) as reader:
        wanted = None if topics is None else set(topics)
        conns = [c for c in reader.connections if wanted is None or c.topic in wanted]
        if not conns:
            return
        for conn, t_ns, raw in reader.messages(connections=conns):
            yield conn.topic, t_ns, store.deserialize_cdr(raw, conn.msgtype)


def topic_counts(bag_dir) -> dict[str, int]:
    """Message count per topic, as read from the bag's metadata."""
    from rosbags.rosbag2 import Reader
    with Reader(Path(bag_dir)) as reader:
        out: dict[str, int] = {}
        for c in reader.connections:
            out[c.topic] = out.get(c.topic, 0) + c.msgcount
        return out


def load_run_timeseries(bag_dir) -> dict[str, np.ndarray]:
    """One row per plant step n for which the bag holds the state at t_n, the
    comfort at t_n and the power (and applied command) over [t_n, t_n + dt). Columns: TIMESERIES_COLUMNS plus
    `step_index` and `fallback`; rows sorted by step index; a step index seen
    twice keeps its first message."""
    state, comfort, power = {}, {}, {}
    for topic, _, msg in read_messages(bag_dir, ('cabin/state', 'cabin/comfort', 'hvac/power')):
        table = {'cabin/state': state, 'cabin/comfort': comfort, 'hvac/power': power}[topic]
        table.setdefault(int(msg.step_index), msg)
    steps = sorted(set(state) & set(comfort) & set(power))
    rows = {c: [] for c in TIMESERIES_COLUMNS + TIMESERIES_EXTRA}
    for n in steps:
        s, c, p = state[n], comfort[n], power[n]
        rows['t_s'].append(s.scenario_time_s)
        for col in ('t_cab_c', 't_int_c', 't_shell_c', 't_evap_c', 't_vent_c', 't_amb_c',
                    'solar_wm2', 'speed_mps', 'rh', 't_glass_c', 'rh_cab'):
            rows[col].append(getattr(s, col))
        for col in ('mdot_bl_kgps', 't_evap_sp_c', 'p_comp_w', 'p_blower_w', 'q_evap_w', 'cop',
                    'p_cond_fan_w', 'q_latent_w', 'comp_speed_rpm'):
            rows[col].append(getattr(p, col))
        rows['capacity_limited'].append(float(p.capacity_limited))
        for col in ('pmv', 'ppd', 'pmv_lb', 'pmv_ub'):
            rows[col].append(getattr(c, col))
        for col in rundir.COMFORT_COLUMNS:
            rows[col].append(float(c.iso_valid) if col == 'iso7730_valid' else getattr(c, col, math.nan))
        rows['step_index'].append(n)
        rows['fallback'].append(bool(s.fallback or p.fallback))
    out = {k: np.asarray(v, dtype=float) for k, v in rows.items()}
    out['step_index'] = np.asarray(rows['step_index'], dtype=np.int64)
    out['fallback'] = np.asarray(rows['fallback'], dtype=bool)
    return out


def load_commands(bag_dir, topic: str = 'hvac/command') -> dict[str, np.ndarray]:
    """Every AcCommand in the bag, in bag order: `k`, `t_s` (header stamp),
    `mdot_bl_kgps`, `t_evap_sp_c`, `strategy` (str array), `fallback`,
    `t_recv_ns` (bag timestamp)."""
    cols = {c: [] for c in ('k', 't_s', 'mdot_bl_kgps', 't_evap_sp_c', 'strategy', 'fallback', 't_recv_ns')}
    for _, t_ns, m in read_messages(bag_dir, (topic,)):
        cols['k'].append(m.step_index)
        cols['t_s'].append(s_from_sec_nanosec(m.header.stamp.sec, m.header.stamp.nanosec))
        cols['mdot_bl_kgps'].append(m.blower_flow_kgps)
        cols['t_evap_sp_c'].append(m.evap_setpoint_c)
        cols['strategy'].append(m.strategy)
        cols['fallback'].append(m.fallback)
        cols['t_recv_ns'].append(t_ns)
    return {
        'k': np.asarray(cols['k'], dtype=np.int64),
        't_s': np.asarray(cols['t_s'], dtype=float),
        'mdot_bl_kgps': np.asarray(cols['mdot_bl_kgps'], dtype=float),
        't_evap_sp_c': np.asarray(cols['t_evap_sp_c'], dtype=float),
        'strategy': np.asarray(cols['strategy'], dtype=str),
        'fallback': np.asarray(cols['fallback'], dtype=bool),
        't_recv_ns': np.asarray(cols['t_recv_ns'], dtype=np.int64),
    }


def load_diagnostics(bag_dir) -> dict[str, np.ndarray]:
    """Every ControllerDiagnostics in bag order, as the diagnostics.csv columns
    (`k, t_s, status, success, iterations, solve_time_ms, cost_energy,
    cost_comfort, cost_ioch, eps_mean, fallback`; iterations -1 and NaN costs
    where not applicable) plus `strategy` and `fallback_reason`."""
    cols = {c: [] for c in DIAGNOSTICS_COLUMNS + ('strategy', 'fallback_reason')}
    for _, _, m in read_messages(bag_dir, ('controller/diagnostics',)):
        cols['k'].append(m.step_index)
        cols['t_s'].append(s_from_sec_nanosec(m.header.stamp.sec, m.header.stamp.nanosec))
        cols['status'].append(m.status)
        cols['success'].append(m.success)
        cols['iterations'].append(m.iterations)
        cols['solve_time_ms'].append(m.solve_time_s * 1e3)
        cols['cost_energy'].append(m.cost_energy)
        cols['cost_comfort'].append(m.cost_comfort)
        cols['cost_ioch'].append(m.cost_ioch)
        cols['eps_mean'].append(m.eps_mean)
        cols['fallback'].append(m.fallback)
        cols['strategy'].append(m.strategy)
        cols['fallback_reason'].append(m.fallback_reason)
    out = {}
    for c, v in cols.items():
        if c in ('status', 'strategy', 'fallback_reason'):
            out[c] = np.asarray(v, dtype=str)
        elif c in ('success', 'fallback'):
            out[c] = np.asarray(v, dtype=bool)
        elif c in ('k', 'iterations'):
            out[c] = np.asarray(v, dtype=np.int64)
        else:
            out[c] = np.asarray(v, dtype=float)
    return out


def write_timeseries_csv(path, ts: dict[str, np.ndarray]) -> None:
    """timeseries.csv from load_run_timeseries' dict (columns in contract order)."""
    cols = list(TIMESERIES_COLUMNS) + [c for c in ts if c not in TIMESERIES_COLUMNS]
    rundir.write_csv(path, cols, ts)


def write_diagnostics_csv(path, diag: dict[str, np.ndarray]) -> None:
    """diagnostics.csv from load_diagnostics' dict (baseline: empty solver cells)."""
    diag = dict(diag)
    it = diag['iterations']
    diag['iterations'] = np.asarray([('' if i < 0 else int(i)) for i in it], dtype=object)
    cols = list(DIAGNOSTICS_COLUMNS) + ['strategy', 'fallback_reason']
    rundir.write_csv(path, cols, diag)
