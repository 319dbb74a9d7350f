"""Run directories loaded and checked: the data behind ``ceco report`` (no figures, no rendering).

A run directory (docs/architecture.md, "Run directory format") holds
``metrics.json`` and the time series, as a rosbag2 bag (``DIR/bag``, read with
``ceco_bringup.bagio``; any topic naming) or as ``DIR/timeseries.csv``;
optionally ``diagnostics.csv``, ``run.json`` and the scenario's copy
(``ceco_bringup.provenance``). A run is also any rosbag2 bag with the ceco topics
(``ros2 bag record``, the launch file's ``record:=true``) and a run directory a
stopped ``ceco run`` left without ``metrics.json``: their metrics come from the bag
alone, with scenario and strategy from ``ceco_bringup.bagrun``; a run that holds
fewer plant steps than its length is marked partial. :func:`load_run` reads one,
recomputes its metrics with ``ceco_core.metrics.run_metrics`` and compares them
with ``metrics.json`` when there is one; :func:`solver_stats` summarises its
solver diagnostics.

A run whose bag cannot be read (a damaged storage file, a corrupt ``metadata.yaml``, or a ``bag/`` holding an
.mcap without ``metadata.yaml``) is reported from its ``timeseries.csv`` (and checked against its
``metrics.json``) when it has one, with a note saying the bag could not be read and why
(:attr:`RunData.bag_unread`); without a ``timeseries.csv`` nothing else holds its data: a ValueError naming the
bag (:class:`DamagedBagError`).

A failed run (its ``run.json`` says ``failed``, or its ``metrics.json`` has ``status: failed``: the controller
did not control it, ``ceco_core.run_status``, or the run stopped: the plant left its model, a node exited, a
stall) is a run too, with no number: :func:`load_runs` gives it as a :class:`FailedRun` (its reason, never its
data), which the report names, and :func:`load_run` refuses it.

Air quality is scored against the limits ``metrics.json`` records (``co2_limit_ppm``, ``fog_margin_bound_k``),
else those of the run's scenario (its copy, or the bundled one by name); a ``metrics.json`` without the
air-quality numbers (an older run) has them computed from the time series and noted as not recorded, not as a
mismatch.

Public API:
    RunData                        one loaded, checked run
    FailedRun                      one failed run: where, which, why (no number)
    discover_runs(paths)           run directories among paths (or one level below), failed ones too
    failed_reason(run_dir)         why a run failed, None when it did not
    load_runs(paths, ...)          (loaded runs, failed runs) among paths
    load_run(run_dir, rtol, namespace, scenario=None, strategy=None) -> RunData
    read_bag(bag_dir, read, *args) a bagio reader's result; a damaged bag as one DamagedBagError, a wrong namespace
                                   apart
    DamagedBagError                a bag that cannot be read (a ValueError): which bag, why
    recompute_metrics(columns, air_limits) / compare_metrics(stored, recomputed, rtol, atol)
    csv_precision_digits(path)     significant digits a CSV's writer used
    fallback_mask(column)          which control steps fell back
    solver_stats(diagnostics)      summary statistics of the solver diagnostics
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ceco_bringup.verdict import reason_line
from ceco_core.air_quality import AirQualityLimits
from ceco_core.rundir import read_csv_columns, read_metrics_json

__all__ = [
    'RunData',
    'FailedRun',
    'discover_runs',
    'failed_reason',
    'load_runs',
    'csv_precision_digits',
    'recompute_metrics',
    'compare_metrics',
    'load_run',
    'read_bag',
    'DamagedBagError',
    'fallback_mask',
    'solver_stats',
]

METRIC_INPUTS = ('t_s', 'p_comp_w', 'p_blower_w', 'p_cond_fan_w', 'pmv', 'pmv_lb', 'pmv_ub')
"""Time-series columns the metrics need (``ceco_core.metrics.RUN_METRIC_COLUMNS``)."""


@dataclasses.dataclass
class RunData:
    """One run directory, loaded and checked."""

    path: Path
    """The run directory."""
    strategy: str
    """From metrics.json (else the directory name)."""
    scenario: str
    """From metrics.json (else 'unknown')."""
    stored: dict
    """metrics.json as read."""
    columns: dict
    """Time series: name -> 1-D array (``timeseries.csv`` names)."""
    source: str
    """'bag' or 'timeseries.csv': where ``columns`` came from."""
    recomputed: dict
    """compute_metrics over ``columns``."""
    mismatches: list
    """(key, stored, recomputed) for every metric that differs."""
    max_rel_diff: float
    """Largest relative difference over the compared metrics."""
    diagnostics: dict | None
    """diagnostics.csv columns (or the bag's diagnostics), or None when absent."""
    check_rtol: float = 0.0
    """Relative tolerance the check used (looser than asked when timeseries.csv was
    written with fewer significant digits)."""
    partial: str = ''
    """Why the run is incomplete ('' for a complete run), e.g. 'interrupted: 28 of 600 s'."""
    notes: list = dataclasses.field(default_factory=list)
    """What the reader must know about this run's data (older format, no metrics.json, ...)."""
    scenario_path: Path | None = None
    """The run's copy of its scenario file (``DIR/scenario.yaml``), None for older runs and bags."""
    info: dict = dataclasses.field(default_factory=dict)
    """``run.json`` (``ceco_bringup.provenance``); ``recorded``: {'scenario'|'strategy': (value, where)} as the run
    records them, flags aside ((None, '') where it does not); for a bag, ``identified_from``: where each came from."""
    air_limits: AirQualityLimits | None = None
    """The limits the run's air quality is scored against (metrics.json's, else its scenario's); None: unknown."""
    bag_unread: str = ''
    """Why the run's bag could not be read, its time series then from timeseries.csv, as one line ('' when the bag
    was read or the run has none), e.g. 'bag/ could not be read (ReaderError: File end magic is invalid.): metrics
    from timeseries.csv'; also among :attr:`notes`."""


@dataclasses.dataclass(frozen=True)
class FailedRun:
    """A run that failed: no number is shown, its reason is (docs/analysis.md, "Failed runs")."""

    path: Path
    """The run directory."""
    strategy: str
    """From metrics.json, else run.json, else its bag, else the directory name."""
    scenario: str
    """From metrics.json, else run.json, else its bag, else 'unknown'."""
    reason: str
    """Why it failed: run.json's ``error`` (else metrics.json's ``status_reason``)."""


def failed_reason(run_dir: str | Path) -> str | None:
    """Why the run in ``run_dir`` failed; None when it did not (or records nothing about it).

    Failed: ``run.json``'s ``status`` is ``failed`` (``ceco run``, ``ceco sim``; its ``error`` says why) or
    ``metrics.json``'s ``status`` is ``failed`` (a run whose controller did not control it,
    ``ceco_core.run_status``; ``status_reason``), e.g. a run directory ``ceco benchmark --save-runs`` kept.
    """
    from ceco_bringup import provenance
    from ceco_core.run_status import STATUS_FAILED

    d = Path(run_dir)
    info = _read_json(d / provenance.RUN_FILE, lambda: provenance.read_run(d), _RUN_JSON_FIX) or {}
    stored = _stored(d) if (d / 'metrics.json').is_file() else {}
    if info.get('status') != STATUS_FAILED and stored.get('status') != STATUS_FAILED:
        return None
    why = str(info.get('error') or '') if info.get('status') == STATUS_FAILED else ''
    return why or str(stored.get('status_reason') or '') or 'no reason recorded'


def _failed_run(run_dir: Path, reason: str, namespace: str | None = None) -> FailedRun:
    """The failed run in ``run_dir``, named as :func:`load_run` names a run (:func:`_identity`).

    From metrics.json, run.json, its bag, else its directory; a bag a failed run left may be damaged: then it is
    named without its bag.
    """
    stored = _stored(run_dir) if (run_dir / 'metrics.json').is_file() else {}
    try:
        scenario, strategy, _, _ = _identity(run_dir, stored, namespace, None, None)
    except Exception:  # rosbags raises its own types for a damaged bag; the run is named without it
        scenario, strategy, _, _ = _identity(run_dir, stored, namespace, None, None, use_bag=False)
    return FailedRun(path=run_dir, strategy=strategy, scenario=scenario, reason=reason)


def is_run(path: str | Path) -> bool:
    """True when ``path`` is a run: ``metrics.json``, a bag in ``bag/``, itself a rosbag2 bag, or a failed run.

    A bag that lost its metadata.yaml (``ceco_bringup.bagrun.headless_bag_of``) counts: :func:`load_run` reports
    the run from its timeseries.csv or says the bag cannot be read.
    """
    from ceco_bringup import provenance
    from ceco_bringup.bagrun import bag_dir_of, headless_bag_of

    p = Path(path)
    if (p / 'metrics.json').is_file() or bag_dir_of(p) is not None or headless_bag_of(p) is not None:
        return True
    return (p / provenance.RUN_FILE).is_file() and failed_reason(p) is not None


def discover_runs(paths: Sequence[str | Path]) -> list[Path]:
    """Run directories among ``paths``.

    A directory that :func:`is_run` is a run; otherwise its immediate subdirectories that are
    runs are (a parent of several strategies). Raises ValueError for a path that is neither, and for a
    parent with a subdirectory that holds a ``run.json`` but is no run (no metrics.json, no bag, not failed:
    its data went missing; it was left out without a word). Failed runs are among them (:func:`load_runs`
    tells them apart).
    """
    from ceco_bringup import provenance

    runs: list[Path] = []
    for p in map(Path, paths):
        if not p.is_dir():
            raise ValueError(f'{p}: not a directory')
        if is_run(p):
            runs.append(p)
            continue
        for d in sorted(d for d in p.iterdir() if d.is_dir() and (d / provenance.RUN_FILE).is_file()):
            if not is_run(d):
                status = (provenance.read_run(d) or {}).get('status')
                raise ValueError(
                    f'{d}: a run directory (run.json, status {status!r}) with no metrics.json, bag/ or rosbag2 '
                    'metadata.yaml: its data is missing; name the other run directories to report them'
                )
        subs = sorted(d for d in p.iterdir() if d.is_dir() and is_run(d))
        if not subs:
            raise ValueError(
                f'{p}: not a run directory: no metrics.json, bag/, rosbag2 metadata.yaml or run.json of a failed '
                'run in it nor in its subdirectories'
            )
        runs.extend(subs)
    return runs


def load_runs(
    paths: Sequence[str | Path],
    rtol: float = 1e-6,
    namespace: str | None = None,
    *,
    scenario: str | None = None,
    strategy: str | None = None,
) -> tuple[list[RunData], list[FailedRun]]:
    """The runs among ``paths`` (:func:`discover_runs`): ``(loaded, failed)``, each in the order found.

    A failed run (:func:`failed_reason`) is never loaded: its numbers are no result. The others are loaded
    with :func:`load_run` (its arguments).
    """
    loaded, failed = [], []
    for d in discover_runs(paths):
        why = failed_reason(d)
        if why is not None:
            failed.append(_failed_run(d, why, namespace))
        else:
            loaded.append(load_run(d, rtol=rtol, namespace=namespace, scenario=scenario, strategy=strategy))
    return loaded, failed


def csv_precision_digits(path: str | Path, columns: Sequence[str] = METRIC_INPUTS[1:]) -> int:
    """Significant digits the writer of a CSV file used for ``columns``.

    The largest count found in any cell: ``%g`` drops trailing zeros, so the maximum
    is the format's precision (17 for Python's ``repr``).
    """
    best = 0
    with open(path, newline='', encoding='utf-8') as fh:
        reader = csv.reader(fh)
        header = [h.strip() for h in next(reader)]
        idx = [header.index(c) for c in columns if c in header]
        for row in reader:
            for i in idx:
                mant = row[i].strip().lstrip('+-').lower().split('e')[0].replace('.', '').lstrip('0')
                best = max(best, len(mant))
    return best


def recompute_metrics(columns: Mapping, air_limits: AirQualityLimits | None = None) -> dict:
    """The metrics over a run's time series columns (``ceco_core.metrics.run_metrics``).

    With ``air_limits`` also the air quality scored against them, as ``ceco sim`` and ``ceco run`` write it.

    A time series without the condenser fan column (a run directory from before it was recorded)
    gets the fan as 0 W; the caller says so (:func:`load_run` adds a note).
    """
    from ceco_core.metrics import run_metrics

    missing = [c for c in METRIC_INPUTS if c not in columns and c != 'p_cond_fan_w']
    if missing:
        raise ValueError(f'time series: missing columns {missing}')
    if 'p_cond_fan_w' not in columns:
        columns = dict(columns, p_cond_fan_w=np.zeros(len(columns['t_s'])))
    return run_metrics(columns, air_limits)


CHECKED_KEYS = ('E_comp_J', 'E_blower_J', 'E_tot_J', 'duration_s')
"""Metrics every metrics.json holds: one without them (or with another type) is a mismatch, not a skipped check."""


def compare_metrics(stored: Mapping, recomputed: Mapping, rtol: float = 1e-9, atol: float = 1e-9):
    """Compare every metric recomputed with the stored one; ``(mismatches, max_rel_diff)``.

    NaN equals NaN, and a stored null is NaN (JSON has no NaN); ``|a - b| <= atol + rtol |b|`` passes. A stored
    value that is not a number (text, true/false) is a mismatch, and so is a missing one of :data:`CHECKED_KEYS`
    (a metrics.json that leaves out its energy would otherwise pass); other missing keys are skipped (older run
    directories lack some).
    """
    mism, worst = [], 0.0
    for key, new in recomputed.items():
        if key not in stored:
            if key in CHECKED_KEYS:
                mism.append((key, 'missing', float(new)))
                worst = math.inf
            continue
        value = stored[key]
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))):
            mism.append((key, value, float(new)))
            worst = math.inf
            continue
        old, new = (math.nan if value is None else float(value)), float(new)
        if math.isnan(old) and math.isnan(new):
            continue
        if math.isnan(old) != math.isnan(new):
            mism.append((key, old, new))
            worst = math.inf
            continue
        diff = abs(old - new)
        worst = max(worst, diff / abs(new) if new != 0 else (0.0 if diff == 0 else math.inf))
        if diff > atol + rtol * abs(new):
            mism.append((key, old, new))
    return mism, worst


class DamagedBagError(ValueError):
    """A bag that cannot be read: ``<bag>: cannot read the bag: <why>`` (one line)."""

    def __init__(self, bag_dir: str | Path, why: str):
        super().__init__(f'{bag_dir}: cannot read the bag: {why}')
        self.bag_dir = Path(bag_dir)
        """The bag's directory."""
        self.why = why
        """Why, one line: rosbags' error type and message (``ReaderError: File end magic is invalid.``)."""


def read_bag(bag_dir: str | Path, read, *args):
    """``read(bag_dir, *args)`` (a ``ceco_bringup.bagio`` reader); any error as a ValueError naming the bag.

    rosbags raises its own types for a damaged bag (an .mcap cut short or empty, a corrupt
    metadata.yaml): a :class:`DamagedBagError`, ``<bag>: cannot read the bag: ReaderError: ...``
    (``ceco report``, ``ceco play``). A namespace that does not pick the stack in the bag is no damage:
    ``<bag>: --namespace ...``, still a :class:`ceco_bringup.bagio.NamespaceError`.
    """
    from ceco_bringup.bagio import NamespaceError

    try:
        return read(bag_dir, *args)
    except NamespaceError as exc:  # a wrong --namespace: its own message, with the bag
        raise NamespaceError(f'{bag_dir}: {exc}') from exc
    except Exception as exc:  # rosbags raises its own types; say which bag
        why = ' '.join(str(exc).split())  # one line (a YAML error spans several)
        raise DamagedBagError(bag_dir, f'{type(exc).__name__}: {why}') from exc


def _load_bag(bag_dir: Path, namespace: str | None) -> dict:
    from ceco_bringup import bagio  # needs rosbags only; imported when a bag exists

    cols = {k: np.asarray(v) for k, v in read_bag(bag_dir, bagio.load_run_timeseries, namespace).items()}
    if not len(cols.get('t_s', ())) >= 2:
        why = _step_topics(bag_dir, namespace)
        raise ValueError(f'{bag_dir}: the bag holds fewer than 2 complete plant steps ({why})')
    return cols


def _step_topics(bag_dir: Path, namespace: str | None) -> str:
    """What a plant step needs from the bag and how many messages of each it holds: why it has no 2 whole steps."""
    from ceco_bringup import bagio
    from ceco_ros.topics import TOPIC_COMFORT, TOPIC_POWER, TOPIC_STATE

    needed = (TOPIC_STATE, TOPIC_COMFORT, TOPIC_POWER)
    counts = read_bag(bag_dir, bagio.topic_counts)
    held = {name: counts[topic] for topic, name in bagio.bag_topic_map(counts, needed, namespace).items()}
    return 'a step needs one message of each of ' + ', '.join(f'{n} (the bag: {held.get(n, 0)})' for n in needed)


def _time_series(run_dir: Path, namespace: str | None) -> tuple[dict, str, str]:
    """(columns, source, bag_unread): the bag alone when the run has a readable one, else timeseries.csv.

    ``bag_unread`` (:attr:`RunData.bag_unread`) says why a bag the run has could not be read: a damaged one
    (:class:`DamagedBagError`) or one without metadata.yaml. Without a timeseries.csv that is the error.
    """
    from ceco_bringup.bagrun import bag_dir_of, headless_bag_of

    csv_path = run_dir / 'timeseries.csv'
    bag = bag_dir_of(run_dir)
    headless = headless_bag_of(run_dir) if bag is None else None
    if bag is not None:
        try:
            return _load_bag(bag, namespace), 'bag', ''
        except DamagedBagError as exc:
            damage = exc
    elif headless is not None:
        where, files = headless
        damage = DamagedBagError(where, f'no metadata.yaml beside {", ".join(files)}')
    elif csv_path.is_file():
        return read_csv_columns(csv_path), 'timeseries.csv', ''
    else:
        raise ValueError(f'{run_dir}: neither bag/ nor timeseries.csv')
    if not csv_path.is_file():  # nothing else holds the run's data
        if damage.bag_dir == run_dir:  # a bag given as such: no run directory around it
            raise damage
        raise ValueError(
            f'{damage.bag_dir}: cannot read the bag ({damage.why}) and the run has no timeseries.csv to report it from'
        )
    name = f'{damage.bag_dir.name}/' if damage.bag_dir != run_dir else 'the bag'
    return (
        read_csv_columns(csv_path),
        'timeseries.csv',
        f'{name} could not be read ({damage.why}): metrics from {csv_path.name}',
    )


def _diagnostics(run_dir: Path, source: str, namespace: str | None) -> dict | None:
    if (run_dir / 'diagnostics.csv').is_file():
        return read_csv_columns(run_dir / 'diagnostics.csv')
    if source == 'bag':
        from ceco_bringup import bagio
        from ceco_bringup.bagrun import bag_dir_of

        try:
            diag = bagio.load_diagnostics(bag_dir_of(run_dir), namespace)
        except ValueError:  # no diagnostics topic in this bag
            return None
        return {k: np.asarray(v) for k, v in diag.items()} if len(diag['k']) else None
    return None


UNKNOWN_SCENARIO = 'unknown'
"""The scenario of a run that records none and gets no ``--scenario``."""


LEGACY_ENERGY_KEYS = ('E_tot_J', 'E_tot_kWh', 'P_mean_w')
"""Metrics a run directory from before ``E_fan_J`` counted as compressor + blower (checked as such)."""


def _legacy_view(recomputed: Mapping) -> dict:
    """The recomputed metrics as an older metrics.json defined them: E_tot = compressor + blower."""
    from ceco_core.metrics import J_PER_KWH

    e = recomputed['E_comp_J'] + recomputed['E_blower_J']
    return dict(recomputed, E_tot_J=e, E_tot_kWh=e / J_PER_KWH, P_mean_w=e / recomputed['duration_s'])


_RUN_JSON_FIX = 'remove it (run.json only records how the run was made; older run directories have none)'
"""What to do about a run.json that is not JSON."""

_METRICS_JSON_FIX = 'rerun the run, or remove the file to report a run with a bag from its bag alone'
"""What to do about a metrics.json that is not JSON."""


def _stored(run_dir: Path) -> dict:
    """``run_dir/metrics.json`` as read; a file that is not JSON is a ValueError naming it."""
    return _read_json(run_dir / 'metrics.json', lambda: read_metrics_json(run_dir / 'metrics.json'), _METRICS_JSON_FIX)


def _read_json(path: Path, read, fix: str):
    """``read()`` of the JSON file ``path``; a file that is not JSON text is a ValueError naming it, with ``fix``."""
    try:
        return read()
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f'{path}: not a JSON file ({exc}): {fix}') from None


def _identity(
    run_dir: Path, stored: Mapping, namespace, scenario, strategy, use_bag: bool = True
) -> tuple[str, str, dict, float | None]:
    """(scenario, strategy, info, intended length [s]) from the flags, metrics.json, run.json, the bag (``use_bag``)."""
    from ceco_bringup import provenance
    from ceco_bringup.bagrun import bag_dir_of, bag_run_info

    info = dict(_read_json(run_dir / provenance.RUN_FILE, lambda: provenance.read_run(run_dir), _RUN_JSON_FIX) or {})
    # what the run itself records, flags aside: metrics.json (and run.json for the scenario), else its bag
    places = {
        'scenario': (('metrics.json', stored), ('run.json', info)),
        'strategy': (('metrics.json', stored), ('run.json', info)),
    }
    rec = {k: next(((str(d[k]), where) for where, d in ps if d.get(k)), (None, '')) for k, ps in places.items()}
    length = None
    bag = bag_dir_of(run_dir) if use_bag else None
    if bag is not None:
        b = bag_run_info(bag, namespace)
        rec = {k: (v, where) if v is not None else (getattr(b, k), 'its bag') for k, (v, where) in rec.items()}
        length = b.duration_s or None  # a plant parameter of 0 means the scenario's length
        found = dict(b.sources)  # where the bag gave it; a flag, or metrics.json / run.json, come first
        for (k, (value, where)), flag in zip(rec.items(), (scenario, strategy)):
            if flag or (value is not None and where != 'its bag'):
                found[k] = 'flag' if flag else where
        info['identified_from'] = found
    info['recorded'] = rec  # {'scenario'|'strategy': (value, where)}, flags aside; (None, '') where none
    sc, st = scenario or rec['scenario'][0], strategy or rec['strategy'][0]
    if length is None and sc:
        try:
            from ceco_v2x_preview.scenario import load_scenario

            length = float(load_scenario(provenance.scenario_path(run_dir) or sc).duration_s)
        except (ValueError, OSError):
            pass
    return str(sc or UNKNOWN_SCENARIO), str(st or run_dir.name), info, length


def _air_limits(run_dir: Path, stored: Mapping, scenario: str) -> tuple[AirQualityLimits | None, str]:
    """(limits, where from): those metrics.json records, else those of the run's scenario; (None, why) if neither."""
    from ceco_bringup import provenance
    from ceco_core.kpis import air_limits_of

    try:
        recorded = air_limits_of(stored)
    except ValueError as exc:
        raise ValueError(f'{run_dir / "metrics.json"}: {exc}') from None
    if recorded is not None:
        return recorded, 'metrics.json'
    try:
        from ceco_v2x_preview.scenario import load_scenario

        path = provenance.scenario_path(run_dir)
        return load_scenario(path or scenario).air_quality.limits, f'its scenario {scenario}'
    except (ImportError, ValueError, OSError):
        return None, f'metrics.json records no limits and the scenario {scenario!r} cannot be read'


def load_run(
    run_dir: str | Path,
    rtol: float = 1e-6,
    namespace: str | None = None,
    *,
    scenario: str | None = None,
    strategy: str | None = None,
) -> RunData:
    """Load one run, recompute its metrics and check them against metrics.json when there is one.

    ``namespace`` picks the stack of a bag that holds several (default: the only one);
    ``scenario`` and ``strategy`` name the run of a bag that does not say (``ceco_bringup.bagrun``).
    A run without ``metrics.json`` is reported from its bag alone (noted); one that holds fewer
    plant steps than its length, or whose ``run.json`` says it was stopped, is partial. A failed run
    (:func:`failed_reason`) is a ValueError: it has no number (:func:`load_runs` names it instead).
    """
    from ceco_bringup import provenance

    run_dir = Path(run_dir)
    notes: list[str] = []
    has_json = (run_dir / 'metrics.json').is_file()
    why = failed_reason(run_dir)
    if why is not None:
        raise ValueError(f'{run_dir}: a failed run ({reason_line(why)}): no number to report')
    stored = _stored(run_dir) if has_json else {}
    columns, source, bag_unread = _time_series(run_dir, namespace)
    if bag_unread:
        notes.append(bag_unread)
    # an unreadable bag names nothing: the run is named without it
    sc, st, info, length = _identity(run_dir, stored, namespace, scenario, strategy, use_bag=source == 'bag')
    if 'p_cond_fan_w' not in columns:
        notes.append('no condenser fan column (older run directory): E_tot counts compressor + blower only')
    air_limits, limits_from = _air_limits(run_dir, stored, sc)
    if air_limits is None:
        notes.append(f'air quality not scored: {limits_from}')
    elif has_json and 'air_quality_met' not in stored:
        notes.append(
            'metrics.json records no air quality (an older run): not recorded, so not checked; shown as computed '
            f'from the time series against the limits of {limits_from}'
        )
    recomputed = recompute_metrics(columns, air_limits)
    check_rtol = rtol
    if source == 'timeseries.csv':
        # A value written with d significant digits is off by up to
        # 0.5e(1-d) relative; the sums and extrema of the metrics inherit
        # that bound, so the check cannot be tighter than the file.
        digits = csv_precision_digits(run_dir / 'timeseries.csv')
        if digits:
            check_rtol = max(rtol, 10.0 ** (1 - digits))
    mism: list = []
    worst = 0.0
    if has_json:
        legacy = 'E_fan_J' not in stored and not float(stored.get('E_aux_J') or 0.0)
        against = _legacy_view(recomputed) if legacy else recomputed
        if legacy:
            notes.append(
                'older run directory: its metrics.json counts E_tot as compressor + blower; shown here as '
                'compressor + blower + condenser fan'
            )
        mism, worst = compare_metrics(stored, against, rtol=check_rtol)
    else:
        notes.append(f'no metrics.json: metrics computed from the {source} alone (nothing to check them against)')
    # metrics.json is written when a run is complete; without it the bag is what a stopped run left
    partial = ''
    status = info.get('status')
    n = len(columns['t_s'])
    dt = float(columns['t_s'][1] - columns['t_s'][0])
    if not has_json and length is not None and n * dt < length - 0.5 * dt:
        partial = f'{status or "stopped"}: {n * dt:.0f} of {length:.0f} s recorded'
    elif status == 'interrupted':
        partial = f'{status}: {n * dt:.0f} s recorded'
    return RunData(
        path=run_dir,
        strategy=st,
        scenario=sc,
        stored=stored,
        columns=columns,
        source=source,
        recomputed=recomputed,
        mismatches=mism,
        max_rel_diff=worst,
        diagnostics=_diagnostics(run_dir, source, namespace),
        check_rtol=check_rtol,
        partial=partial,
        notes=notes,
        scenario_path=provenance.scenario_path(run_dir),
        info=info,
        air_limits=air_limits,
        bag_unread=bag_unread,
    )


def fallback_mask(column) -> np.ndarray:
    """Which control steps fell back.

    The ``fallback`` column is the fallback kind ('' = none, 'shifted_plan',
    'baseline', ...) or a 0/1 flag.
    """
    col = np.asarray(column)
    if col.dtype.kind in 'fiub':
        f = col.astype(float)
        return np.isfinite(f) & (f != 0.0)
    text = np.char.lower(np.char.strip(col.astype(str)))
    return ~np.isin(text, ('', '0', '0.0', 'false', 'none', 'no', 'nan'))


def _fallback_stats(column) -> dict:
    mask = fallback_mask(column)
    col = np.asarray(column)
    kinds = col.astype(str)[mask] if col.dtype.kind in 'US' else np.array([])
    vals, counts = np.unique(kinds, return_counts=True)
    return {'fallbacks': int(mask.sum()), 'fallback_kinds': {str(v): int(c) for v, c in zip(vals, counts)}}


def _success_flags(column) -> np.ndarray:
    col = np.asarray(column)
    if col.dtype.kind == 'f':
        return col.astype(float)
    return np.array([str(x).strip().lower() in ('1', 'true', 'yes') for x in col], dtype=float)


def _solve_stats(diag: Mapping, n: int) -> dict:
    """Solve-time, success and iteration statistics over the rows with a solve time."""
    nan = float('nan')
    st = np.asarray(diag.get('solve_time_ms', np.full(n, nan)), dtype=float)
    ok = np.isfinite(st)
    out: dict = {'solver_steps': int(ok.sum())}
    if not ok.any():
        return out
    out.update(
        solve_ms_median=float(np.median(st[ok])),
        solve_ms_p95=float(np.percentile(st[ok], 95)),
        solve_ms_max=float(np.max(st[ok])),
        solve_ms_mean=float(np.mean(st[ok])),
    )
    if 'success' in diag:
        out['success_pct'] = 100.0 * float(np.nansum(_success_flags(diag['success'])[ok])) / int(ok.sum())
    it = np.asarray(diag.get('iterations', np.full(n, nan)), dtype=float)[ok]
    if np.any(np.isfinite(it)):
        out['iter_median'] = float(np.nanmedian(it))
        out['iter_max'] = float(np.nanmax(it))
    return out


def solver_stats(diag: Mapping | None) -> dict:
    """Summary of one run's ``diagnostics.csv``.

    Keys: ``steps``, ``solver_steps`` (rows with a solve time), ``success_pct``,
    ``fallbacks`` (count), ``fallback_kinds`` ({kind: count}),
    ``solve_ms_median/p95/max/mean``, ``iter_median/max``, ``statuses``
    ({status: count}). Empty solver columns (baseline) give NaN.
    """
    nan = float('nan')
    out = {
        'steps': 0,
        'solver_steps': 0,
        'success_pct': nan,
        'fallbacks': 0,
        'solve_ms_median': nan,
        'solve_ms_p95': nan,
        'solve_ms_max': nan,
        'solve_ms_mean': nan,
        'iter_median': nan,
        'iter_max': nan,
        'statuses': {},
        'fallback_kinds': {},
    }
    if not diag:
        return out
    n = len(next(iter(diag.values())))
    out['steps'] = n
    if 'fallback' in diag:
        out.update(_fallback_stats(diag['fallback']))
    out.update(_solve_stats(diag, n))
    if 'status' in diag:
        vals, counts = np.unique(np.asarray(diag['status']).astype(str), return_counts=True)
        out['statuses'] = {str(v): int(c) for v, c in zip(vals, counts) if v and v != 'nan'}
    return out
