"""What a rosbag2 bag says about the run it recorded: scenario, strategy, Ts, Np, length.

``ceco report`` and ``ceco play --compare`` work on any rosbag2 bag that holds the ceco topics,
not only on a ``ceco run`` directory: a bag of ``ros2 bag record`` (or the launch file's
``record:=true``) has no ceco metadata. Each field comes from the first source that has it:

1. the user's flag (``--scenario``, ``--strategy``, ``--control-period-s``, ``--horizon-steps``; ``ceco report``
   refuses a ``--scenario``/``--strategy`` that contradicts what the run records, so there it names only what
   the bag does not say);
2. the bag's ``metadata.yaml`` ``custom_data`` (ceco's recorder writes scenario, strategy,
   control_period_s, horizon_steps, duration_s);
3. the nodes' parameters in ``/parameter_events`` when the recording holds them (``scenario``,
   ``strategy``, ``control_period_s``, ``horizon_steps``, ``duration_s`` of the stack's nodes);
4. the messages: the strategy every command and diagnostics message carries, Ts the
   diagnostics' ``prediction_step_s``, Np one less than the length of their predicted PMV.

:func:`bag_run_info` returns the values and where each came from; a field no source has is None
(the caller says which flag gives it). Reads with rosbags (``ceco_bringup.bagio``); no ROS needed.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import yaml

__all__ = ['BagRunInfo', 'bag_run_info', 'custom_data', 'is_bag', 'bag_dir_of', 'headless_bag_of']

_FIELDS = ('scenario', 'strategy', 'control_period_s', 'horizon_steps', 'duration_s')


@dataclasses.dataclass(frozen=True)
class BagRunInfo:
    """The run a bag recorded, as far as the bag (and the flags) tell."""

    scenario: str | None = None
    """Scenario name or YAML path."""
    strategy: str | None = None
    """Controller strategy."""
    control_period_s: float | None = None
    """Ts [s]."""
    horizon_steps: int | None = None
    """Np [steps]."""
    duration_s: float | None = None
    """The run's intended length [s] (what a complete run holds)."""
    sources: dict = dataclasses.field(default_factory=dict)
    """{field: 'flag' | 'bag metadata' | 'parameter events' | 'messages'} for every field found."""


def is_bag(path: str | Path) -> bool:
    """True when ``path`` is a rosbag2 directory (it holds ``metadata.yaml``)."""
    return (Path(path) / 'metadata.yaml').is_file()


def bag_dir_of(run_dir: str | Path) -> Path | None:
    """The bag of a run directory (``DIR/bag``), ``DIR`` itself when it is a bag, else None."""
    p = Path(run_dir)
    if is_bag(p):
        return p
    if is_bag(p / 'bag'):
        return p / 'bag'
    return None


STORAGE_SUFFIXES = ('.mcap', '.db3')
"""File endings of a rosbag2 bag's storage files (MCAP, SQLite 3)."""


def headless_bag_of(run_dir: str | Path) -> tuple[Path, list[str]] | None:
    """A bag that lost its ``metadata.yaml``: (its directory, its storage files), else None.

    ``DIR/bag``, else ``DIR``, holding storage files (``.mcap``, ``.db3``) but no ``metadata.yaml``: rosbag2 opens
    a bag by its metadata, so it cannot be read. None for a whole bag (:func:`bag_dir_of`) and a directory without
    storage files.
    """
    p = Path(run_dir)
    for d in (p / 'bag', p):
        if d.is_dir() and not is_bag(d):
            files = sorted(f.name for f in d.iterdir() if f.is_file() and f.suffix in STORAGE_SUFFIXES)
            if files:
                return d, files
    return None


def custom_data(bag: str | Path) -> dict:
    """The ``custom_data`` of a bag's ``metadata.yaml`` ({} when there is none)."""
    meta = yaml.safe_load((Path(bag) / 'metadata.yaml').read_text(encoding='utf-8'))
    info = (meta or {}).get('rosbag2_bagfile_information') or {}
    return dict(info.get('custom_data') or {})


def _convert(name: str, value):
    if value is None or value == '':
        return None
    if name == 'horizon_steps':
        return int(float(value))
    if name in ('control_period_s', 'duration_s'):
        return float(value)
    return str(value)


def _parameter_events(bag: Path, namespace: str | None) -> dict:
    """{parameter: value} the stack's nodes announced on /parameter_events (declared or changed)."""
    from ceco_bringup import bagio

    if '/parameter_events' not in bagio.topic_types(bag):
        return {}
    prefix = '' if not namespace else '/' + namespace.strip('/')
    out: dict = {}
    for _, _, ev in bagio.read_messages(bag, ('/parameter_events',)):
        node = str(ev.node)
        if prefix and not node.startswith(prefix + '/'):
            continue
        for p in list(ev.new_parameters) + list(ev.changed_parameters):
            if p.name not in _FIELDS:
                continue
            v = p.value
            value = {1: v.bool_value, 2: v.integer_value, 3: v.double_value, 4: v.string_value}.get(int(v.type))
            if value is not None and value != '':
                out[p.name] = value
    return out


def _from_messages(bag: Path, namespace: str | None) -> dict:
    """strategy, Ts and Np from the controller's messages."""
    from ceco_bringup import bagio
    from ceco_ros.topics import TOPIC_COMMAND, TOPIC_DIAGNOSTICS

    out: dict = {}
    try:
        for _, _, m in bagio.read_messages(bag, (TOPIC_DIAGNOSTICS,), namespace):
            if m.strategy:
                out.setdefault('strategy', str(m.strategy))
            if m.prediction_step_s > 0:
                out.setdefault('control_period_s', float(m.prediction_step_s))
            if len(m.predicted_pmv) >= 2:
                out.setdefault('horizon_steps', len(m.predicted_pmv) - 1)
            if len(out) == 3:
                break
        if 'strategy' not in out:
            for _, _, m in bagio.read_messages(bag, (TOPIC_COMMAND,), namespace):
                if m.strategy:
                    out['strategy'] = str(m.strategy)
                    break
    except ValueError:  # the bag has not got the topic (or it is ambiguous): nothing from it
        pass
    return out


def bag_run_info(bag: str | Path, namespace: str | None = None, **flags) -> BagRunInfo:
    """The run of ``bag`` (module docstring): ``flags`` are the user's values (None: not given)."""
    bag = Path(bag)
    found: dict = {}
    sources: dict = {}

    def take(values: dict, source: str):
        for k in _FIELDS:
            v = _convert(k, values.get(k))
            if v is not None and k not in found:
                found[k], sources[k] = v, source

    take({k: v for k, v in flags.items() if k in _FIELDS}, 'flag')
    take(custom_data(bag), 'bag metadata')
    if any(k not in found for k in _FIELDS):
        take(_parameter_events(bag, namespace), 'parameter events')
    if any(k not in found for k in ('strategy', 'control_period_s', 'horizon_steps')):
        take(_from_messages(bag, namespace), 'messages')
    return BagRunInfo(**found, sources=sources)
