"""Read the stack's rosbag2 bags with rosbags (no rclpy needed).

Bags are rosbag2 directories (metadata version 9, MCAP or SQLite 3 storage:
the formats Jazzy's rosbag2 writes; writing is ``ceco_bringup.bag_writer``).
The ceco_msgs types are registered in a rosbags typestore from the ``.msg``
text (installed share directory of ceco_msgs, or the source tree).

Topic names: the readers take the stack's names (``cabin/state``, relative, as
in ``ceco_ros.interfaces``; ``/clock`` absolute) and find them in a bag under
any naming: relative (ceco bags before fully qualified names), fully
qualified (``/cabin/state``, what ``ros2 bag record`` and the recorder write)
or namespaced (``/veh1/cabin/state``). A bag holding the stack under several
namespaces needs ``namespace=`` to say which one; a ``namespace`` the bag does
not hold the stack under is refused (:class:`NamespaceError`, a ValueError).

Public API:
    typestore() -> rosbags Typestore with ROS 2 Jazzy + ceco_msgs types
    topic_namespace(bag_topic, name) -> namespace under which bag_topic carries name, or None
    topic_namespaces(bag_topics, names) -> sorted namespaces under which the bag holds any of the relative names
    namespace_not_held(namespace, names, held) -> the one-line refusal of a namespace the bag does not hold
    bag_topic_map(bag_topics, names, namespace=None) -> {bag topic: requested name}; NamespaceError
    topic_types(bag_dir, topics=None, namespace=None) -> {name: message type}
    read_raw(bag_dir, topics=None, namespace=None) -> iterator of (name, t_ns, raw CDR bytes)
    read_messages(bag_dir, topics=None, namespace=None) -> iterator of (name, t_ns, msg)
    topic_counts(bag_dir) -> {bag topic: message count}
    load_run_timeseries(bag_dir) -> dict of numpy arrays (timeseries.csv columns)
    load_commands(bag_dir) -> dict of numpy arrays (one entry per command message)
    load_diagnostics(bag_dir) -> dict of numpy arrays (diagnostics.csv columns)
    write_timeseries_csv / write_diagnostics_csv
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

from ceco_core import rundir
from ceco_core.cli_flags import normalize_namespace
from ceco_core.contracts import DIAGNOSTICS_CONTRACT_COLUMNS as DIAGNOSTICS_COLUMNS
from ceco_core.contracts import RECIRC_NOT_COMMANDED_WIRE
from ceco_core.units import s_from_stamp
from ceco_ros.topics import TOPIC_COMFORT, TOPIC_COMMAND, TOPIC_DIAGNOSTICS, TOPIC_POWER, TOPIC_STATE

TIMESERIES_COLUMNS = rundir.TIMESERIES_COLUMNS
"""Columns of timeseries.csv (docs/architecture.md); extra columns follow."""

TIMESERIES_EXTRA = rundir.TIMESERIES_EXTRA + ('step_index', 'fallback')
"""The extras of a stack run: the simulator's, then the plant step index and the fallback flag."""


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


LEGACY_ACCOMMAND = 'ceco_msgs_legacy/msg/AcCommand'
"""The AcCommand of bags recorded before ``epoch`` / ``sequence`` were added (issue 17)."""

_OLDER_FORMATS: dict[str, tuple[tuple[str, str], ...]] = {
    'ceco_msgs/msg/AcCommand': (
        ('ceco_msgs_legacy/msg/AcCommandNoDoor', 'recirc_share'),
        (LEGACY_ACCOMMAND, 'epoch'),
    ),
    'ceco_msgs/msg/CabinState': (('ceco_msgs_legacy/msg/CabinStateNoAir', 'co2_cab_ppm'),),
}
"""The older formats of a message, newest first: (legacy type name, the first field it lacks). Fields are only
ever appended, so an older message is the current one cut before that field."""

OLDER_FORMAT_FILL: dict[str, dict[str, float | int]] = {
    'ceco_msgs/msg/AcCommand': {'epoch': 0, 'sequence': 0, 'recirc_share': RECIRC_NOT_COMMANDED_WIRE},
    'ceco_msgs/msg/CabinState': {
        'co2_cab_ppm': math.nan,
        'co2_sensor_ppm': math.nan,
        'recirc_share': math.nan,
        'recirc_share_cmd': math.nan,
    },
}
"""What a message of an older format gets for the fields it lacks: an AcCommand no epoch / sequence (0, not set)
and a door left alone (-1, the plant's default share); a CabinState of before issue 21 NaN for its cabin CO2, the
CO2 sensor and the door (not recorded: the plant of then held the door at ``PlantParams.recirc_fraction``)."""


def _prefix_msg(text: str, first_missing: str) -> str:
    """The .msg ``text`` cut before the line that defines the field ``first_missing``."""
    out = []
    for line in text.splitlines():
        words = line.split('#', 1)[0].split()
        if len(words) >= 2 and words[1] == first_missing:
            return '\n'.join(out) + '\n'
        out.append(line)
    raise ValueError(f'field {first_missing!r} not found in the message definition')


@functools.lru_cache(maxsize=1)
def typestore():
    """A rosbags typestore with the ROS 2 Jazzy types, every ceco_msgs type and their older formats."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for path in sorted(_msg_dir().glob('*.msg')):
        msgtype = f'ceco_msgs/msg/{path.stem}'
        text = path.read_text()
        types.update(get_types_from_msg(text, msgtype))
        for legacy, first_missing in _OLDER_FORMATS.get(msgtype, ()):
            types.update(get_types_from_msg(_prefix_msg(text, first_missing), legacy))
    store.register(types)
    return store


def deserialize(raw: bytes, msgtype: str):
    """A CDR message of ``msgtype``; a message of an older format gets :data:`OLDER_FORMAT_FILL` for what it lacks.

    An older format is told by its length: it ends where the current one carries the appended fields.
    """
    store = typestore()
    older = _OLDER_FORMATS.get(msgtype, ())
    if not older:
        return store.deserialize_cdr(raw, msgtype)
    try:
        return store.deserialize_cdr(raw, msgtype)
    except Exception:  # rosbags reads past the end of an older message
        pass
    for legacy, _ in older:
        try:
            old = store.deserialize_cdr(raw, legacy)
        except Exception:
            continue
        fields = {name: getattr(old, name) for name in old.__dataclass_fields__ if name != '__msgtype__'}
        fill = {k: v for k, v in OLDER_FORMAT_FILL[msgtype].items() if k not in fields}
        return store.types[msgtype](**fields, **fill)
    raise ValueError(f'{msgtype}: the message matches neither the current definition nor an older one')


# --- Names ---------------------------------------------------------------------
def topic_namespace(bag_topic: str, name: str) -> str | None:
    """The namespace under which bag topic ``bag_topic`` carries stack topic ``name``.

    '' is the root namespace; None means it does not carry it. An absolute ``name``
    (``/clock``) matches only itself; a relative one (``cabin/state``) matches
    ``cabin/state`` and ``/cabin/state`` ('') and ``/ns/cabin/state`` ('/ns').
    """
    if name.startswith('/'):
        return '' if bag_topic == name else None
    if bag_topic == name:
        return ''
    if bag_topic.startswith('/') and bag_topic.endswith('/' + name):
        return bag_topic[: -len(name) - 1]
    return None


class NamespaceError(ValueError):
    """A namespace that does not pick the stack in the bag: a wrong ``--namespace``, not a damaged bag.

    Not held there, invalid, or none given where the bag holds several.
    """


def _grouped(bag_topics: Iterable[str], names: Iterable[str]) -> tuple[dict[str, str], dict[str, dict[str, str]]]:
    """({bag topic: absolute name}, {namespace: {bag topic: relative name}}) of the stack ``names`` in the bag."""
    names = list(names)
    absolute: dict[str, str] = {}
    by_ns: dict[str, dict[str, str]] = {}
    for topic in bag_topics:
        for name in names:
            ns = topic_namespace(topic, name)
            if ns is None:
                continue
            if name.startswith('/'):
                absolute[topic] = name
            else:
                by_ns.setdefault(ns, {})[topic] = name
    return absolute, by_ns


def topic_namespaces(bag_topics: Iterable[str], names: Iterable[str]) -> list[str]:
    """The namespaces ('' the root) under which ``bag_topics`` carry any of the relative stack ``names``, sorted."""
    return sorted(_grouped(bag_topics, names)[1])


def namespace_not_held(namespace: str, names: Iterable[str], held: Iterable[str]) -> str:
    """The refusal of a valid ``namespace`` under which the bag holds none of ``names``; ``held``: where it does.

    ``--namespace veh3: not in the bag (no cabin/state under /veh3): give one of its namespaces, /, /veh2``.
    """
    listed = [n for n in names if not n.startswith('/')]
    what = listed[0] if len(listed) == 1 else f'{", ".join(listed[:-1])} or {listed[-1]}'
    return (
        f'--namespace {namespace}: not in the bag (no {what} under {normalize_namespace(namespace) or "/"}): give '
        f'one of its namespaces, {", ".join(n or "/" for n in held)}'
    )


def bag_topic_map(bag_topics: Iterable[str], names: Iterable[str], namespace: str | None = None) -> dict[str, str]:
    """{bag topic: stack name} for the stack ``names`` found among ``bag_topics``.

    Relative names are taken from one namespace: ``namespace`` when given, else the
    only one the bag holds them under. Raises :class:`NamespaceError` when the bag holds them
    under several namespaces and ``namespace`` is None, for an invalid ``namespace``, and for a
    ``namespace`` the bag holds none of them under while it holds them under others (a bag
    without any of them gives the absolute names only: the caller says what is missing).
    """
    names = list(names)
    absolute, by_ns = _grouped(bag_topics, names)
    if namespace is not None:
        try:
            ns = normalize_namespace(namespace)
        except ValueError as exc:
            raise NamespaceError(f'--namespace: {exc}') from None
        if by_ns and ns not in by_ns:
            raise NamespaceError(namespace_not_held(namespace, names, sorted(by_ns)))
        chosen = by_ns.get(ns, {})
    elif len(by_ns) > 1:
        raise NamespaceError(
            f'the bag holds {sorted(set(by_ns[next(iter(by_ns))].values()))} under several '
            f'namespaces ({", ".join(repr(ns or "/") for ns in sorted(by_ns))}): say which one with --namespace'
        )
    else:
        chosen = next(iter(by_ns.values()), {})
    return {**absolute, **chosen}


# --- Reading ---------------------------------------------------------------------
def _open(bag_dir):
    from rosbags.rosbag2 import Reader

    return Reader(Path(bag_dir))


def _selected(reader, topics, namespace) -> dict[str, str]:
    bag_topics = {c.topic for c in reader.connections}
    if topics is None:
        return {t: t for t in bag_topics}
    return bag_topic_map(bag_topics, topics, namespace)


def topic_types(bag_dir, topics: Iterable[str] | None = None, namespace: str | None = None) -> dict[str, str]:
    """{name: message type} of the requested stack topics found in the bag.

    All its topics under their bag names when ``topics`` is None.
    """
    with _open(bag_dir) as reader:
        names = _selected(reader, topics, namespace)
        return {names[c.topic]: c.msgtype for c in reader.connections if c.topic in names}


def _records(bag_dir, topics, namespace) -> Iterator[tuple[str, int, bytes, str]]:
    """(stack name, bag timestamp [ns], CDR bytes, message type) of the selected topics, in bag order."""
    with _open(bag_dir) as reader:
        names = _selected(reader, topics, namespace)
        conns = [c for c in reader.connections if c.topic in names]
        if not conns:
            return
        for conn, t_ns, raw in reader.messages(connections=conns):
            yield names[conn.topic], t_ns, raw, conn.msgtype


def read_raw(
    bag_dir, topics: Iterable[str] | None = None, namespace: str | None = None
) -> Iterator[tuple[str, int, bytes]]:
    """Yield (name, bag timestamp [ns], serialized CDR bytes) in bag (timestamp) order.

    ``name`` is the requested stack name (the bag name when ``topics`` is None).
    """
    for name, t_ns, raw, _ in _records(bag_dir, topics, namespace):
        yield name, t_ns, bytes(raw)


def read_messages(
    bag_dir, topics: Iterable[str] | None = None, namespace: str | None = None
) -> Iterator[tuple[str, int, object]]:
    """Yield (name, bag timestamp [ns], deserialized message) in bag (timestamp) order.

    ``name`` as in :func:`read_raw`.
    """
    for name, t_ns, raw, msgtype in _records(bag_dir, topics, namespace):
        yield name, t_ns, deserialize(raw, msgtype)


def topic_counts(bag_dir) -> dict[str, int]:
    """Message count per topic under its name in the bag, as read from the bag's metadata."""
    with _open(bag_dir) as reader:
        out: dict[str, int] = {}
        for c in reader.connections:
            out[c.topic] = out.get(c.topic, 0) + c.msgcount
        return out


def load_run_timeseries(bag_dir, namespace: str | None = None) -> dict[str, np.ndarray]:
    """The run's time series: one row per complete plant step.

    A row for plant step n needs the state at t_n, the comfort at t_n and the power
    (and applied command) over [t_n, t_n + dt). Columns: TIMESERIES_COLUMNS plus
    `step_index` and `fallback`; the door command applied over the step (`recirc_share_cmd`) is read from the
    state of step n + 1 (NaN for the last step when the bag ends there, and in bags of before issue 21);
    `fallback` is the power's (``AcPower.fallback`` of step n: the plant's law drove [t_n, t_n + dt)); the state's
    flag describes no step (it stays set until the next command is accepted, after the state of the step that
    command drives was sent); rows sorted by step index; a step index seen
    twice keeps its first message in bag order.
    """
    state, comfort, power = {}, {}, {}
    tables = {TOPIC_STATE: state, TOPIC_COMFORT: comfort, TOPIC_POWER: power}
    for topic, _, msg in read_messages(bag_dir, tuple(tables), namespace):
        table = tables[topic]
        table.setdefault(int(msg.step_index), msg)
    steps = sorted(set(state) & set(comfort) & set(power))
    rows = {c: [] for c in TIMESERIES_COLUMNS + TIMESERIES_EXTRA}
    for n in steps:
        s, c, p = state[n], comfort[n], power[n]
        rows['t_s'].append(s.scenario_time_s)
        for col in (
            't_cab_c',
            't_int_c',
            't_shell_c',
            't_evap_c',
            't_vent_c',
            't_amb_c',
            'solar_wm2',
            'speed_mps',
            'rh',
            't_glass_c',
            'rh_cab',
            'co2_cab_ppm',
            'co2_sensor_ppm',
            'recirc_share',
        ):
            rows[col].append(getattr(s, col))
        # the door command applied over [t_n, t_n+1) is the one the state of step n + 1 reports as applied
        nxt = state.get(n + 1)
        rows['recirc_share_cmd'].append(math.nan if nxt is None else nxt.recirc_share_cmd)
        for col in (
            'mdot_bl_kgps',
            't_evap_sp_c',
            'p_comp_w',
            'p_blower_w',
            'q_evap_w',
            'cop',
            'p_cond_fan_w',
            'q_latent_w',
            'comp_speed_rpm',
        ):
            rows[col].append(getattr(p, col))
        rows['capacity_limited'].append(float(p.capacity_limited))
        for col in ('pmv', 'ppd', 'pmv_lb', 'pmv_ub'):
            rows[col].append(getattr(c, col))
        for col in rundir.COMFORT_COLUMNS:
            rows[col].append(float(c.iso_valid) if col == 'iso7730_valid' else getattr(c, col, math.nan))
        rows['step_index'].append(n)
        rows['fallback'].append(bool(p.fallback))
    out = {k: np.asarray(v, dtype=float) for k, v in rows.items()}
    out['step_index'] = np.asarray(rows['step_index'], dtype=np.int64)
    out['fallback'] = np.asarray(rows['fallback'], dtype=bool)
    return out


def load_commands(bag_dir, topic: str = TOPIC_COMMAND, namespace: str | None = None) -> dict[str, np.ndarray]:
    """Every AcCommand in the bag, in bag order.

    Columns `k`, `t_s` (header stamp), `mdot_bl_kgps`, `t_evap_sp_c`, `strategy`
    (str array), `fallback`, `t_recv_ns` (bag timestamp), `epoch`, `sequence` (the sending
    controller's activation and the command's number; 0 in bags of before they existed), ``recirc_share`` (the door's
    command [0..1]; NaN: not commanded, also in bags of before the door existed).
    """
    cols = {
        c: []
        for c in (
            'k',
            't_s',
            'mdot_bl_kgps',
            't_evap_sp_c',
            'strategy',
            'fallback',
            't_recv_ns',
            'epoch',
            'sequence',
            'recirc_share',
        )
    }
    for _, t_ns, m in read_messages(bag_dir, (topic,), namespace):
        cols['k'].append(m.step_index)
        cols['t_s'].append(s_from_stamp(m.header.stamp))
        cols['mdot_bl_kgps'].append(m.blower_flow_kgps)
        cols['t_evap_sp_c'].append(m.evap_setpoint_c)
        cols['strategy'].append(m.strategy)
        cols['fallback'].append(m.fallback)
        cols['t_recv_ns'].append(t_ns)
        cols['epoch'].append(m.epoch)
        cols['sequence'].append(m.sequence)
        cols['recirc_share'].append(math.nan if m.recirc_share == RECIRC_NOT_COMMANDED_WIRE else m.recirc_share)
    return {
        'k': np.asarray(cols['k'], dtype=np.int64),
        't_s': np.asarray(cols['t_s'], dtype=float),
        'mdot_bl_kgps': np.asarray(cols['mdot_bl_kgps'], dtype=float),
        't_evap_sp_c': np.asarray(cols['t_evap_sp_c'], dtype=float),
        'strategy': np.asarray(cols['strategy'], dtype=str),
        'fallback': np.asarray(cols['fallback'], dtype=bool),
        't_recv_ns': np.asarray(cols['t_recv_ns'], dtype=np.int64),
        'epoch': np.asarray(cols['epoch'], dtype=np.uint64),
        'sequence': np.asarray(cols['sequence'], dtype=np.int64),
        'recirc_share': np.asarray(cols['recirc_share'], dtype=float),
    }


def load_diagnostics(bag_dir, namespace: str | None = None) -> dict[str, np.ndarray]:
    """Every ControllerDiagnostics in bag order, as the diagnostics.csv columns.

    Columns `k, t_s, status, success, iterations, solve_time_ms, cost_energy,
    cost_comfort, cost_ioch, eps_mean, fallback` (iterations -1 and NaN costs
    where not applicable; ``fallback`` the kind: '', 'shifted_plan', 'baseline', as the
    simulator writes it) plus `strategy` and `fallback_reason`.
    """
    cols = {c: [] for c in DIAGNOSTICS_COLUMNS + ('strategy', 'fallback_reason')}
    for _, _, m in read_messages(bag_dir, (TOPIC_DIAGNOSTICS,), namespace):
        cols['k'].append(m.step_index)
        cols['t_s'].append(s_from_stamp(m.header.stamp))
        cols['status'].append(m.status)
        cols['success'].append(m.success)
        cols['iterations'].append(m.iterations)
        cols['solve_time_ms'].append(m.solve_time_s * 1e3)
        cols['cost_energy'].append(m.cost_energy)
        cols['cost_comfort'].append(m.cost_comfort)
        cols['cost_ioch'].append(m.cost_ioch)
        cols['eps_mean'].append(m.eps_mean)
        # the contract's fallback kind ('', 'shifted_plan', 'baseline'), as diagnostics.csv of a simulated run
        cols['fallback'].append(m.fallback_reason.partition(':')[0] if m.fallback else '')
        cols['strategy'].append(m.strategy)
        cols['fallback_reason'].append(m.fallback_reason)
    out = {}
    for c, v in cols.items():
        if c in ('status', 'strategy', 'fallback', 'fallback_reason'):
            out[c] = np.asarray(v, dtype=str)
        elif c == 'success':
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
