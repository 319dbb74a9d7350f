"""What made a run: the scenario file, the command line, the code fingerprint, the printed tables.

Every directory ``ceco run`` and ``ceco sim`` write (docs/architecture.md, "Run directory
format") holds, next to the data:

* ``scenario.yaml``: a copy of the scenario file the run used (the bundled file for a bundled
  name); a drive-cycle CSV the scenario names by path is copied beside it and the copy points
  at it, so ``load_scenario(DIR/scenario.yaml)`` gives the run's scenario anywhere;
* ``run.json``: ``{schema, verb, command, argv, cwd, created_utc, ceco_version,
  code_fingerprint, scenario, scenario_source, scenario_sha256, status, error}``, where
  ``status`` is ``started`` while the run goes on, then ``complete``, ``interrupted`` or
  ``failed`` (a stopped run keeps what it recorded: ``ceco report`` marks it partial);
* the tables printed on the console (``summary.txt`` per run; ``comparison.txt``,
  ``comparison.csv`` and ``verdict.json`` of a job, ``ceco_bringup.outputs``).

``ceco report`` reads the scenario from the copy (:func:`scenario_path`), never from the
bundled scenarios when the copy is there. Pure Python; no ROS import.
"""

from __future__ import annotations

import datetime
import hashlib
import json
import os
import shlex
import shutil
from collections.abc import Mapping, Sequence
from importlib import resources
from pathlib import Path

import yaml

from ceco_core import yamlio

__all__ = [
    'RUN_SCHEMA',
    'RUN_STATUSES',
    'copy_drive_cycle',
    'copy_scenario',
    'scenario_path',
    'start_run',
    'finish_run',
    'read_run',
    'command_line',
]

RUN_SCHEMA = 'ceco-run/1'
"""The ``schema`` of ``run.json``."""

RUN_STATUSES = ('started', 'complete', 'interrupted', 'failed')
"""Values of ``run.json``'s ``status``."""

SCENARIO_FILE = 'scenario.yaml'
RUN_FILE = 'run.json'


def command_line(verb: str, argv: Sequence[str]) -> str:
    """The command as typed: ``ceco VERB ARG...`` with shell quoting."""
    return ' '.join(['ceco', verb, *(shlex.quote(str(a)) for a in argv)])


def copy_scenario(name_or_path: str | os.PathLike, dest_dir: str | os.PathLike) -> Path:
    """Copy the scenario file (bundled name or YAML path) to ``dest_dir/scenario.yaml``; return that path.

    A bundled scenario's file is copied as it is. A user file is copied as it is when its drive
    cycle is a bundled name; when it names a CSV by path, the CSV is copied beside the copy and
    the copy's ``drive_cycle`` points at it (the file is then rewritten by the YAML dumper, with a
    header saying so).
    """
    from ceco_v2x_preview.scenario import list_scenarios

    dest = Path(dest_dir)
    dest.mkdir(parents=True, exist_ok=True)
    out = dest / SCENARIO_FILE
    name = str(name_or_path)
    if name in list_scenarios():
        text = resources.files('ceco_v2x_preview').joinpath('data', 'scenarios', name + '.yaml').read_text('utf-8')
        out.write_text(text, encoding='utf-8')
        return out
    src = Path(name).expanduser()
    text = src.read_text(encoding='utf-8')
    data = yamlio.safe_load(text)
    copied, note = copy_drive_cycle(data, src.parent, dest)
    if not note:
        out.write_text(text, encoding='utf-8')
        return out
    out.write_text(f'# copy of {src} ({note})\n' + yaml.safe_dump(copied, sort_keys=False), encoding='utf-8')
    return out


def csv_drive_cycle(data) -> str | None:
    """The drive cycle of the scenario mapping ``data`` when it is a CSV path (not a bundled name), else None."""
    from ceco_v2x_preview.scenario import list_drive_cycles

    cycle = data.get('drive_cycle') if isinstance(data, Mapping) else None
    return cycle if isinstance(cycle, str) and cycle not in list_drive_cycles() else None


def copy_drive_cycle(data, src_dir: str | os.PathLike, dest_dir: str | os.PathLike) -> tuple:
    """A scenario mapping that can be written to ``dest_dir``: ``(data, note)``.

    Its drive cycle a bundled name (or no mapping): ``(data, '')`` unchanged. A CSV path (a relative one
    resolved against ``src_dir``, the directory the scenario was read from): the CSV copied to
    ``dest_dir/drive_cycle_<file name>``, a copy of ``data`` pointing at it, and the note ``drive_cycle X copied
    to Y beside it`` for the written file's header.
    """
    cycle = csv_drive_cycle(data)
    if cycle is None:
        return data, ''
    csv = Path(cycle).expanduser()
    if not csv.is_absolute():
        csv = Path(src_dir) / csv
    copied = Path(dest_dir) / f'drive_cycle_{csv.name}'
    if csv.resolve() != copied.resolve():
        shutil.copyfile(csv, copied)
    return dict(data, drive_cycle=copied.name), f'drive_cycle {cycle} copied to {copied.name} beside it'


def scenario_sha256(copy: str | os.PathLike) -> str:
    """The content hash of a run's scenario copy (``run.json``'s ``scenario_sha256``, 16 hex digits).

    Over what the scenario says, not the file's bytes: its YAML data (comments, key order and layout do not
    count) and, for a drive cycle named by path, the bytes of the CSV copied beside it in place of that
    path. The same CSV-cycle scenario run from two directories has one hash (its copy's header names the
    source and differed); an edited CSV under the same YAML has another (the YAML's bytes alone missed it).
    """
    copy = Path(copy)
    data = yamlio.load_file(copy)
    cycle = csv_drive_cycle(data)
    if cycle is not None:
        csv = Path(cycle) if Path(cycle).is_absolute() else copy.parent / cycle
        data = dict(data, drive_cycle={'csv_sha256': hashlib.sha256(csv.read_bytes()).hexdigest()})
    text = json.dumps(data, sort_keys=True, separators=(',', ':'), default=str)
    return hashlib.sha256(text.encode('utf-8')).hexdigest()[:16]


def scenario_path(run_dir: str | os.PathLike) -> Path | None:
    """The run's copy of its scenario file, or None for a run directory written before it was kept."""
    p = Path(run_dir) / SCENARIO_FILE
    return p if p.is_file() else None


def _version_and_code() -> tuple[str, str]:
    from ceco_bringup.benchmark.cli import ceco_version
    from ceco_bringup.sweep.cells import code_fingerprint

    return ceco_version(), code_fingerprint()


def start_run(
    run_dir: str | os.PathLike, verb: str, argv: Sequence[str], scenario_source: str, strategy: str | None = None
) -> dict:
    """Write ``scenario.yaml`` and ``run.json`` (status ``started``) into ``run_dir``; return the record.

    ``strategy``: the one strategy the run directory is of (``ceco sim``, ``ceco run``), recorded so that a run
    that failed before any data names it (``ceco report``); None: not one strategy's run.
    """
    d = Path(run_dir)
    d.mkdir(parents=True, exist_ok=True)
    copy = copy_scenario(scenario_source, d)
    version, code = _version_and_code()
    from ceco_v2x_preview.scenario import load_scenario

    record = {
        'schema': RUN_SCHEMA,
        'verb': verb,
        'command': command_line(verb, argv),
        'argv': [str(a) for a in argv],
        'cwd': os.getcwd(),
        'created_utc': datetime.datetime.now(datetime.UTC).strftime('%Y-%m-%dT%H:%M:%SZ'),
        'ceco_version': version,
        'code_fingerprint': code,
        'scenario': load_scenario(copy).name,
        'scenario_source': str(scenario_source),
        'scenario_sha256': scenario_sha256(copy),
        **({'strategy': strategy} if strategy else {}),
        'status': 'started',
        'error': '',
    }
    _write(d, record)
    return record


def finish_run(run_dir: str | os.PathLike, status: str, error: str = '') -> None:
    """Set ``run.json``'s ``status`` (and ``error``); nothing happens without a ``run.json``."""
    if status not in RUN_STATUSES:
        raise ValueError(f'status: must be one of {RUN_STATUSES}, got {status!r}')
    record = read_run(run_dir)
    if record is None:
        return
    record.update(status=status, error=str(error))
    _write(Path(run_dir), record)


def read_run(run_dir: str | os.PathLike) -> dict | None:
    """``run.json`` as a dict, or None when the directory has none (older run directories)."""
    p = Path(run_dir) / RUN_FILE
    if not p.is_file():
        return None
    data = json.loads(p.read_text(encoding='utf-8'))
    if not isinstance(data, dict):
        raise ValueError(f'{p}: expected a JSON object')
    return data


def _write(d: Path, record: Mapping) -> None:
    tmp = d / (RUN_FILE + '.tmp')
    tmp.write_text(json.dumps(record, indent=1) + '\n', encoding='utf-8')
    tmp.replace(d / RUN_FILE)
