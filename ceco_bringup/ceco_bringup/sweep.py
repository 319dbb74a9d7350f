"""``ceco sweep GRID.yaml --out DIR``: scenario grids with the in-process simulator.

A grid file (YAML; example and every key: ``ceco_bringup/config/sweep_example.yaml``,
docs/analysis.md) names the axes

    strategies x scenarios x drive_cycles x climates x previews x occupants x seeds
    (x settings: per-strategy controller-setting overrides, e.g. ceco-c's gamma_w)

and every combination (a *cell*) is one closed-loop run
(``ceco_controller.closed_loop.simulate``), no ROS. The ``settings`` axis
applies per strategy: a strategy named under a settings label runs once per
label naming it, with those :class:`StrategySettings` fields overridden; a
strategy no label names (always ``baseline``) runs once per group with its
defaults, label ``default``, and every other cell of the group is compared
with that one baseline cell. Cells run in parallel:

* ``--backend local`` (default): ``concurrent.futures.ProcessPoolExecutor``
  with the ``spawn`` start method on ``--workers`` processes (default: all
  cores). CasADi objects are not picklable, so a worker receives only the
  cell's plain description (a dict) and builds the scenario and the
  controller itself.
* ``--backend ray``: the same cell function as a Ray task, on a local Ray
  instance (``ray.init(num_cpus=workers, include_dashboard=False)``) or on an
  existing cluster with ``--address`` (whose nodes must have ceco and its
  dependencies installed). Ray is an optional extra (requirements/analysis.txt).

Resumable: every cell has a deterministic id, the SHA-256 of its full
description (the scenario after the overrides, the strategy and its setting
overrides, the preview quality, the seed, the run length, and a fingerprint of the simulator's code
and configuration), so a cell whose definition and code did not change
keeps its id, and a changed simulator reruns it. Each finished cell is appended to ``DIR/cells.jsonl``
as one line written with a single ``write`` on an ``O_APPEND`` descriptor and
``fsync``-ed; on start, cells already in it with status ``ok`` are not run
again (failed cells are retried; a torn last line from a crash is ignored).

Outputs in ``DIR``: ``cells.jsonl`` (the log), ``results.csv`` (the tidy table:
one row per cell, its axes and every metric; also ``results.parquet`` when
pyarrow or polars is installed), ``summary.md`` and ``summary.csv`` (per scenario,
climate, preview and occupant: each strategy's mean over seeds and its change
against the baseline), ``grid.json`` (the resolved cells), with
``save_runs: true`` in the grid one run directory per cell under ``DIR/runs/``,
and with ``vehicle: true`` ``vehicle.csv`` (FASTSim vehicle-level energy of
each group's strategies; the FASTSim extra).
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import contextlib
import csv
import dataclasses
import hashlib
import itertools
import json
import math
import multiprocessing
import os
import socket
import sys
import time
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
import yaml

from ceco_core.metrics import relative_change_pct

__all__ = ['GridError', 'Cell', 'load_grid', 'expand_grid', 'scenario_dict', 'cell_id', 'code_fingerprint', 'run_cell',
           'read_done', 'run_sweep', 'summarize', 'vehicle_rows', 'verify_cells', 'main', 'AXES',
           'METRIC_COLUMNS', 'DEFAULT_SETTINGS', 'strategy_setting_overrides', 'runtime_overrides',
           'dominance_rows', 'front_figure']


class GridError(ValueError):
    """An invalid grid file; the message names the key."""


AXES = ('scenario', 'drive_cycle', 'climate', 'preview', 'occupant', 'seed', 'strategy', 'settings')
"""Axis columns of the results table, in order (``settings``: the label of the
strategy's setting overrides, :data:`DEFAULT_SETTINGS` for none)."""

DEFAULT_SETTINGS = 'default'
"""Settings label of a cell run with its strategy's default settings
(every baseline cell, and strategies no ``settings`` label names)."""

_FIXED_SETTING_FIELDS = {'name': 'strategies', 'horizon_steps': 'horizon_steps',
                         'control_period_s': 'control_period_s'}
"""StrategySettings fields the settings axis may not set (the grid key that sets them)."""

METRIC_COLUMNS = ('E_tot_J', 'E_tot_kWh', 'E_comp_J', 'E_blower_J', 'P_mean_w', 'I_pmv', 'otc_violation_pct',
                  'otc_violation_s', 'otc_above_ub_s', 'otc_below_lb_s', 'time_to_comfort_s', 'pmv_mean',
                  'pmv_max', 'pmv_min', 'duration_s', 'n_control_steps', 'n_fallback_shifted',
                  'n_fallback_baseline', 'solve_time_median_ms', 'solve_time_max_ms',
                  'zone_start_s', 'E_zone_J', 'I_pmv_zone', 'otc_violation_zone_pct', 'pmv_mean_zone')
"""Metric columns of the results table (those the simulator returns; ``*_zone``:
the comfort-zone phase, where the upper PMV bound is at its tightest, from
``zone_start_s`` on; ``closed_loop.simulate``)."""

TIMING_COLUMNS = ('solve_time_median_ms', 'solve_time_max_ms')
"""Metric columns that are wall-clock measurements (not reproducible)."""

_GRID_KEYS = {'name', 'description', 'strategies', 'scenarios', 'drive_cycles', 'climates', 'previews',
              'occupants', 'seeds', 'duration_s', 'save_runs', 'control_period_s', 'horizon_steps', 'vehicle',
              'settings'}
_CLIMATE_KEYS = {'t_amb_c', 'solar_wm2', 'rh', 'initial', 'comfort_bounds'}


@dataclasses.dataclass(frozen=True)
class Cell:
    """One closed-loop run of a sweep (plain data: picklable, JSON-able)."""

    id: str
    """Deterministic id: first 16 hex digits of SHA-256 of ``spec``."""
    axes: dict
    """Axis labels: scenario, drive_cycle, climate, preview, occupant, seed, strategy."""
    spec: dict
    """What the worker needs: ``code`` (:func:`code_fingerprint` of the
    driver), ``scenario`` (a scenario mapping for
    ``scenario_from_dict``), ``strategy``, ``preview`` (quality string),
    ``seed``, ``duration_s`` (None: the scenario's), ``control_period_s``,
    ``horizon_steps`` (None: the scenario's), and only for a cell with
    setting overrides ``strategy_overrides`` ({StrategySettings field:
    plain value}; absent for default settings, so grids without the
    settings axis keep their ids)."""


# ------------------------------------------------------------------ grid file
def load_grid(path: str | os.PathLike) -> dict:
    """Read and check a grid YAML file (unknown keys and wrong types raise
    GridError naming the key)."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text(encoding='utf-8'))
    except (OSError, yaml.YAMLError) as exc:
        raise GridError(f'{path}: cannot read grid: {exc}') from None
    if not isinstance(data, Mapping):
        raise GridError(f'{path}: top level must be a mapping')
    unknown = sorted(set(data) - _GRID_KEYS)
    if unknown:
        raise GridError(f'{unknown[0]}: unknown grid key (allowed: {sorted(_GRID_KEYS)})')
    data = dict(data)
    data['_base_dir'] = str(path.parent.resolve())
    return data


def _named(key: str, value, default: Mapping) -> dict:
    """An axis given as a list (labels = str(item)) or a mapping label -> value."""
    if value is None:
        return dict(default)
    if isinstance(value, Mapping):
        if not value:
            raise GridError(f'{key}: must not be empty')
        return {str(k): v for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        if not value:
            raise GridError(f'{key}: must not be empty')
        return {str(v): v for v in value}
    raise GridError(f'{key}: must be a list or a mapping, got {type(value).__name__}')


def scenario_dict(scenario) -> dict:
    """A :class:`Scenario` as the mapping ``scenario_from_dict`` accepts."""
    sc = scenario
    ini = {k: float(sc.initial[k]) for k in sc.initial}
    return {
        'name': sc.name, 'description': sc.description, 'drive_cycle': sc.drive_cycle.name,
        'duration_s': float(sc.duration_s),
        'weather': {'time_s': [float(x) for x in sc.weather_time_s], 't_amb_c': [float(x) for x in sc.weather_t_amb_c],
                    'solar_wm2': [float(x) for x in sc.weather_solar_wm2], 'rh': [float(x) for x in sc.weather_rh]},
        'occupant': {'met': float(sc.occupant.met), 'clo': float(sc.occupant.clo)},
        'comfort_bounds': {'time_s': [float(x) for x in sc.bounds_time_s],
                           'pmv_lb': [float(x) for x in sc.bounds_pmv_lb],
                           'pmv_ub': [float(x) for x in sc.bounds_pmv_ub]},
        'initial': ini,
        'control': {'control_period_s': float(sc.control.control_period_s),
                    'horizon_steps': int(sc.control.horizon_steps)},
        'seed': int(sc.seed),
    }


def _two_knots(key: str, value) -> list:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return [float(value), float(value)]
    if isinstance(value, (list, tuple)) and len(value) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        return [float(v) for v in value]
    raise GridError(f'{key}: must be a number or [start, end], got {value!r}')


def _apply_climate(d: dict, label: str, climate) -> None:
    if climate is None:
        return
    if not isinstance(climate, Mapping):
        raise GridError(f'climates.{label}: must be a mapping of {sorted(_CLIMATE_KEYS)} or null')
    unknown = sorted(set(climate) - _CLIMATE_KEYS)
    if unknown:
        raise GridError(f'climates.{label}.{unknown[0]}: unknown key (allowed: {sorted(_CLIMATE_KEYS)})')
    weather = dict(d['weather'])
    if any(k in climate for k in ('t_amb_c', 'solar_wm2', 'rh')):
        # The climate's values span the run: knots at 0 and at the run length.
        weather = {'time_s': [0.0, float(d['duration_s'])]}
        for k in ('t_amb_c', 'solar_wm2', 'rh'):
            if k in climate:
                weather[k] = _two_knots(f'climates.{label}.{k}', climate[k])
            else:  # keep the base scenario's start and end values
                base = d['weather'][k]
                weather[k] = [float(base[0]), float(base[-1])]
    d['weather'] = weather
    if 'initial' in climate:
        if not isinstance(climate['initial'], Mapping):
            raise GridError(f'climates.{label}.initial: must be a mapping')
        # The soak state is the climate's: fields it does not give default
        # as in a scenario file (to t_cab_c, rh_cab from the ambient).
        d['initial'] = dict(climate['initial'])
    if 'comfort_bounds' in climate:
        d['comfort_bounds'] = dict(climate['comfort_bounds'])


def _plain_setting(where: str, default, value):
    """A setting value from the grid as plain JSON data of the default's type
    (an int for a float field becomes a float, so ``2000`` and ``2000.0``
    give the same cell id). Wrong types raise GridError naming ``where``."""
    if dataclasses.is_dataclass(default):
        if not isinstance(value, Mapping):
            raise GridError(f'{where}: must be a mapping of {type(default).__name__} fields, got {value!r}')
        return _plain_fields(where, default, value)
    if isinstance(default, bool):
        ok = isinstance(value, bool)
    elif isinstance(default, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif isinstance(default, float):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        value = float(value) if ok else value
    elif isinstance(default, tuple):
        ok = isinstance(value, (list, tuple))
        value = list(value) if ok else value
    else:   # str, or str | None
        ok = isinstance(value, str) or (default is None and value is None)
    if not ok:
        raise GridError(f'{where}: must be of the type of its default {default!r}, got {value!r}')
    return value


def _plain_fields(where: str, default, mapping: Mapping) -> dict:
    names = [f.name for f in dataclasses.fields(default)]
    out = {}
    for key, value in mapping.items():
        if key not in names:
            raise GridError(f'{where}.{key}: unknown {type(default).__name__} field (allowed: {names})')
        out[str(key)] = _plain_setting(f'{where}.{key}', getattr(default, key), value)
    return out


def runtime_overrides(plain: Mapping) -> dict:
    """Setting overrides as stored in a cell's spec (plain JSON data) ->
    keyword overrides of ``strategy_settings`` (a ``solver`` mapping becomes
    a :class:`SolverSettings`, lists become tuples)."""
    from ceco_controller.strategies import SolverSettings  # noqa: PLC0415

    out = {}
    for key, value in plain.items():
        if key == 'solver':
            base = SolverSettings()
            value = dataclasses.replace(base, **{k: tuple(v) if isinstance(v, list) else v
                                                 for k, v in value.items()})
        elif isinstance(value, list):
            value = tuple(value)
        out[key] = value
    return out


def strategy_setting_overrides(grid: Mapping, strategies: Sequence[str]) -> dict:
    """The ``settings`` axis of a grid, checked: ``{strategy: {label:
    overrides}}`` for the strategies some label names, ``overrides`` being
    ``{StrategySettings field: plain value}``. Every override set is
    validated now (``strategy_settings(name, **overrides).validate()``, with
    the grid's Ts and Np if it sets them), so a bad field or value fails
    before any run with a GridError (a ValueError) naming
    ``settings.<label>.<strategy>.<field>``. A label naming a strategy not in
    ``strategies``, the baseline (it has no StrategySettings), the reserved
    label ``default``, or one of the fields the grid sets elsewhere (name,
    horizon_steps, control_period_s) is an error."""
    raw = grid.get('settings')
    if raw is None:
        return {}
    if not isinstance(raw, Mapping) or not raw:
        raise GridError('settings: must be a non-empty mapping {label: {strategy: {field: value}}}')
    from ceco_controller.strategies import CECO_STRATEGIES, StrategySettings, strategy_settings  # noqa: PLC0415

    fixed = {k: grid[k] for k in ('control_period_s', 'horizon_steps') if grid.get(k) is not None}
    if 'horizon_steps' in fixed:
        fixed['horizon_steps'] = int(fixed['horizon_steps'])
    if 'control_period_s' in fixed:
        fixed['control_period_s'] = float(fixed['control_period_s'])
    out: dict = {}
    for label, per_strategy in raw.items():
        label = str(label)
        if label == DEFAULT_SETTINGS:
            raise GridError(f'settings.{label}: the label {DEFAULT_SETTINGS!r} is reserved for default settings')
        if not isinstance(per_strategy, Mapping) or not per_strategy:
            raise GridError(f'settings.{label}: must be a non-empty mapping {{strategy: {{field: value}}}}')
        for strategy, fields in per_strategy.items():
            where = f'settings.{label}.{strategy}'
            if strategy not in strategies:
                raise GridError(f'{where}: strategy {strategy!r} is not in the grid\'s strategies {list(strategies)}')
            if strategy not in CECO_STRATEGIES:
                raise GridError(f'{where}: {strategy} has no StrategySettings (use one of {list(CECO_STRATEGIES)})')
            if fields is None:
                fields = {}
            if not isinstance(fields, Mapping):
                raise GridError(f'{where}: must be a mapping {{StrategySettings field: value}}, got {fields!r}')
            for key in fields:
                if key in _FIXED_SETTING_FIELDS:
                    raise GridError(f'{where}.{key}: set by the grid key {_FIXED_SETTING_FIELDS[key]!r}, '
                                    'not by the settings axis')
            plain = _plain_fields(where, StrategySettings(), fields)
            try:
                strategy_settings(strategy, **fixed, **runtime_overrides(plain))
            except (ValueError, TypeError) as exc:
                raise GridError(f'{where}: {exc}') from None
            out.setdefault(strategy, {})[label] = plain
    return out


_CODE_PACKAGES = ('ceco_v2x_preview', 'ceco_plant_sim', 'ceco_controller')
_CODE_SUFFIXES = ('.py', '.yaml', '.yml', '.csv', '.json')


def code_fingerprint() -> str:
    """SHA-256 (16 hex digits) of the simulator's code and configuration as
    importable here: every ``.py/.yaml/.csv/.json`` file of the scenario,
    plant and controller packages, their ``config/`` directories and the
    identified model parameter file. Part of every cell's id, so a changed
    simulator reruns the cells instead of mixing results of two versions."""
    h = hashlib.sha256()
    files: list = []
    for name in _CODE_PACKAGES:
        mod = __import__(name)
        pkg = Path(mod.__file__).resolve().parent
        for root in (pkg, pkg.parent / 'config'):
            if root.is_dir():
                files += [(f'{name}/{root.name}/{p.relative_to(root)}', p) for p in root.rglob('*')
                          if p.suffix in _CODE_SUFFIXES and p.is_file() and '__pycache__' not in p.parts]
    try:
        from ceco_controller.model import default_params_path  # noqa: PLC0415

        files.append(('model_params', default_params_path()))
    except (ImportError, FileNotFoundError):
        pass
    for rel, path in sorted(files, key=lambda x: x[0]):
        h.update(rel.encode('utf-8') + b'\0' + Path(path).read_bytes() + b'\0')
    return h.hexdigest()[:16]


def _canonical(obj) -> str:
    return json.dumps(obj, sort_keys=True, separators=(',', ':'), allow_nan=True)


def cell_id(spec: Mapping) -> str:
    """Deterministic id of a cell: SHA-256 of its canonical JSON, 16 hex digits."""
    return hashlib.sha256(_canonical(spec).encode('utf-8')).hexdigest()[:16]


def expand_grid(grid: Mapping) -> list[Cell]:
    """Every cell of a grid (axes in the order of :data:`AXES`, strategy
    fastest). Each cell's scenario is validated here (``scenario_from_dict``),
    so a bad grid fails before any run."""
    from ceco_v2x_preview.preview import parse_quality  # noqa: PLC0415
    from ceco_v2x_preview.scenario import load_drive_cycle, load_scenario, scenario_from_dict  # noqa: PLC0415

    base_dir = grid.get('_base_dir')
    strategies = grid.get('strategies')
    if not isinstance(strategies, (list, tuple)) or not strategies or not all(isinstance(s, str) for s in strategies):
        raise GridError('strategies: must be a non-empty list of strategy names')
    try:
        from ceco_controller.strategies import STRATEGIES  # noqa: PLC0415
    except ImportError:
        STRATEGIES = None
    if STRATEGIES is not None:
        bad = [s for s in strategies if s not in STRATEGIES]
        if bad:
            raise GridError(f'strategies: unknown strategy {bad[0]!r} (use {list(STRATEGIES)})')
    scenarios = _named('scenarios', grid.get('scenarios'), {'sc03': 'sc03'})
    cycles = _named('drive_cycles', grid.get('drive_cycles'), {'scenario': None})
    climates = _named('climates', grid.get('climates'), {'scenario': None})
    previews = _named('previews', grid.get('previews'), {'perfect': 'perfect'})
    occupants = _named('occupants', grid.get('occupants'), {'scenario': None})
    seeds = grid.get('seeds', [None])
    if not isinstance(seeds, (list, tuple)) or not seeds or not all(
            s is None or (isinstance(s, int) and not isinstance(s, bool) and s >= 0) for s in seeds):
        raise GridError('seeds: must be a non-empty list of non-negative integers')
    duration = grid.get('duration_s')
    if duration is not None and not (isinstance(duration, (int, float)) and not isinstance(duration, bool)
                                     and math.isfinite(duration) and duration > 0):
        raise GridError(f'duration_s: must be a positive number, got {duration!r}')
    for key in ('control_period_s', 'horizon_steps'):
        v = grid.get(key)
        if v is not None and not (isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0):
            raise GridError(f'{key}: must be a positive number, got {v!r}')
    for label, q in previews.items():
        if not isinstance(q, str):
            raise GridError(f'previews.{label}: must be a preview-quality string (e.g. "noisy:solar=50")')
        try:
            parse_quality(q)
        except ValueError as exc:
            raise GridError(f'previews.{label}: {exc}') from None
    overrides = strategy_setting_overrides(grid, strategies)
    code = code_fingerprint()
    cells = []
    for (sl, sv), (cl, cv), (kl, kv), (pl, pv), (ol, ov), seed in itertools.product(
            scenarios.items(), cycles.items(), climates.items(), previews.items(), occupants.items(), seeds):
        try:
            src = str(sv)
            if base_dir and src.endswith(('.yaml', '.yml')) and not Path(src).is_absolute():
                src = str(Path(base_dir) / src)
            d = scenario_dict(load_scenario(src))
        except (ValueError, OSError) as exc:
            raise GridError(f'scenarios.{sl}: {exc}') from None
        if cv is not None:
            try:
                cyc_src = str(cv)
                if base_dir and cyc_src.endswith('.csv') and not Path(cyc_src).is_absolute():
                    cyc_src = str(Path(base_dir) / cyc_src)
                cyc = load_drive_cycle(cyc_src)
            except (ValueError, OSError) as exc:
                raise GridError(f'drive_cycles.{cl}: {exc}') from None
            d['drive_cycle'] = cyc.name
            d['duration_s'] = float(cyc.duration_s)
        _apply_climate(d, kl, kv)
        if ov is not None:
            if not isinstance(ov, Mapping) or set(ov) - {'met', 'clo'}:
                raise GridError(f'occupants.{ol}: must be a mapping with met and/or clo')
            d['occupant'] = {**d['occupant'], **{k: float(v) for k, v in ov.items()}}
        d['name'] = d['name'] if cv is None and kv is None else f"{d['name']}[{cl},{kl}]"
        try:
            scenario_from_dict(d)
        except ValueError as exc:
            raise GridError(f'cell {sl}/{cl}/{kl}/{ol}: {exc}') from None
        for strategy in strategies:
            for label, ovr in overrides.get(strategy, {DEFAULT_SETTINGS: None}).items():
                spec = {'code': code, 'scenario': d, 'strategy': strategy, 'preview': pv, 'seed': seed,
                        'duration_s': None if duration is None else float(duration),
                        'control_period_s': grid.get('control_period_s'),
                        'horizon_steps': grid.get('horizon_steps')}
                if ovr is not None:
                    spec['strategy_overrides'] = ovr
                axes = {'scenario': sl, 'drive_cycle': cl, 'climate': kl, 'preview': pl, 'occupant': ol,
                        'seed': '' if seed is None else seed, 'strategy': strategy, 'settings': label}
                cells.append(Cell(id=cell_id(spec), axes=axes, spec=spec))
    seen: dict = {}
    for c in cells:
        if c.id in seen:
            a, b = seen[c.id].axes, c.axes
            diff = [f'{k} {a[k]!r} / {b[k]!r}' for k in AXES if a[k] != b[k]]
            raise GridError('the grid holds the same cell twice (two axis labels with the same definition: '
                            f"{', '.join(diff)})")
        seen[c.id] = c
    return cells


# ------------------------------------------------------------------ one cell
def _settings_from_spec(spec: Mapping):
    from ceco_controller.closed_loop import SimSettings  # noqa: PLC0415
    from ceco_v2x_preview.preview import parse_quality  # noqa: PLC0415

    hs = spec.get('horizon_steps')
    ovr = runtime_overrides(spec.get('strategy_overrides') or {})
    return SimSettings(control_period_s=spec.get('control_period_s'),
                       horizon_steps=None if hs is None else int(hs),
                       preview_quality=parse_quality(spec['preview']), seed=spec.get('seed'),
                       duration_s=spec.get('duration_s'), progress=False,
                       strategy_overrides=tuple(sorted(ovr.items())))


def run_cell(cell: Mapping, runs_dir: str | None = None) -> dict:
    """Run one cell in this process and return its results row: the cell id,
    axes, every metric, ``status`` ('ok' or 'error'), ``error``,
    ``code`` (this process's :func:`code_fingerprint`; a cell whose
    fingerprint differs from the driver's is an error, not a result),
    ``sim_time_s`` (scenario build + simulation), ``wall_time_s`` (also the
    first imports in a fresh worker), ``host``, ``pid``. Never raises for a failing run (the
    error is in the row). ``cell`` is :class:`Cell` as a dict."""
    t0 = time.perf_counter()
    row = {'cell_id': cell['id'], **cell['axes'], 'status': 'ok', 'error': '', 'sim_time_s': float('nan')}
    try:
        from ceco_controller.closed_loop import simulate, write_run  # noqa: PLC0415
        from ceco_v2x_preview.scenario import scenario_from_dict  # noqa: PLC0415

        spec = cell['spec']
        row['code'] = code_fingerprint()
        if spec.get('code') and row['code'] != spec['code']:
            raise RuntimeError(f"the simulator's code here ({row['code']}) differs from the sweep's "
                               f"({spec['code']}): code changed during the sweep, or a Ray node runs another "
                               'version; rerun the sweep')
        t_sim = time.perf_counter()
        scenario = scenario_from_dict(spec['scenario'])
        result = simulate(scenario, spec['strategy'], _settings_from_spec(spec))
        row['sim_time_s'] = time.perf_counter() - t_sim
        for k in METRIC_COLUMNS:
            v = result.metrics.get(k)
            row[k] = float('nan') if v is None else float(v)
        row['scenario_name'] = result.metrics.get('scenario', scenario.name)
        row['preview_quality'] = result.metrics.get('preview_quality', spec['preview'])
        if runs_dir:
            write_run(result, Path(runs_dir) / cell['id'])
    except Exception as exc:  # noqa: BLE001 (a failed cell is data, the sweep goes on)
        row['status'] = 'error'
        row['error'] = f'{type(exc).__name__}: {exc}'
    row['wall_time_s'] = time.perf_counter() - t0
    row['host'] = socket.gethostname()
    row['pid'] = os.getpid()
    return row


# ------------------------------------------------------------------ the log
def read_done(log_path: str | os.PathLike) -> dict:
    """``{cell_id: row}`` of the cells with status 'ok' in a ``cells.jsonl``
    (later lines win; an unreadable line, e.g. torn by a crash, is skipped)."""
    done: dict = {}
    p = Path(log_path)
    if not p.is_file():
        return done
    for line in p.read_text(encoding='utf-8').splitlines():
        try:
            row = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(row, dict) and row.get('status') == 'ok' and 'cell_id' in row:
            done[row['cell_id']] = row
    return done


def _append_row(log_path: Path, row: Mapping) -> None:
    """Append one JSON line atomically: one write() on an O_APPEND fd, fsync."""
    data = (json.dumps(row, allow_nan=True, separators=(',', ':')) + '\n').encode('utf-8')
    fd = os.open(log_path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        # A torn last line (crash mid-write) is skipped by read_done; start on a new line.
        if os.fstat(fd).st_size:
            with open(log_path, 'rb') as fh:
                fh.seek(-1, os.SEEK_END)
                if fh.read(1) != b'\n':
                    data = b'\n' + data
        written = os.write(fd, data)
        if written != len(data):
            raise OSError(f'{log_path}: short write ({written} of {len(data)} bytes)')
        os.fsync(fd)
    finally:
        os.close(fd)


# ------------------------------------------------------------------ backends
def _pythonpath() -> str:
    """Source dirs of the ceco packages as imported here (so spawned or Ray
    workers import the same code)."""
    dirs = []
    for mod in ('ceco_bringup', 'ceco_controller', 'ceco_plant_sim', 'ceco_v2x_preview'):
        try:
            m = __import__(mod)
        except ImportError:
            continue
        dirs.append(str(Path(m.__file__).resolve().parent.parent))
    extra = os.environ.get('PYTHONPATH', '')
    return os.pathsep.join(dict.fromkeys(dirs + ([extra] if extra else [])))


WORKER_THREAD_ENV = {'OMP_NUM_THREADS': '1', 'OPENBLAS_NUM_THREADS': '1', 'MKL_NUM_THREADS': '1'}
"""Environment of parallel workers: one BLAS/OpenMP thread each. The solver
(IPOPT/MUMPS) and numpy otherwise start a thread per core in every worker;
two workers on two cores then ran a cell 2-3x slower than one worker alone
(measured: docs/analysis.md). A value the user set is kept."""


@contextlib.contextmanager
def _worker_env():
    """Set :data:`WORKER_THREAD_ENV` (where unset) while workers start:
    spawned processes copy the environment at start."""
    added = {k: v for k, v in WORKER_THREAD_ENV.items() if k not in os.environ}
    os.environ.update(added)
    try:
        yield {k: os.environ[k] for k in WORKER_THREAD_ENV}
    finally:
        for k in added:
            os.environ.pop(k, None)


def _run_local(cells: Sequence[dict], workers: int, runs_dir, on_done: Callable) -> None:
    if workers == 1:
        for c in cells:
            on_done(run_cell(c, runs_dir))
        return
    ctx = multiprocessing.get_context('spawn')
    with _worker_env(), cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
        futures = [pool.submit(run_cell, c, runs_dir) for c in cells]
        try:
            for fut in cf.as_completed(futures):
                on_done(fut.result())
        except KeyboardInterrupt:
            for f in futures:
                f.cancel()
            raise


def _run_ray(cells: Sequence[dict], workers: int, address: str | None, runs_dir, on_done: Callable) -> None:
    try:
        import ray  # noqa: PLC0415 (optional extra)
    except ImportError as exc:
        raise RuntimeError('--backend ray needs the optional Ray extra: '
                           'pip install -r requirements/analysis.txt (ray==2.60.0)') from exc
    with _worker_env() as thread_env:
        runtime_env = {'env_vars': {'PYTHONPATH': _pythonpath(), **thread_env}}
    started = False
    if not ray.is_initialized():
        if address:
            ray.init(address=address, runtime_env=runtime_env, include_dashboard=False,
                     log_to_driver=False)
        else:
            ray.init(num_cpus=workers, runtime_env=runtime_env, include_dashboard=False, log_to_driver=False)
        started = True
    try:
        remote = ray.remote(num_cpus=1, max_retries=0)(run_cell)
        pending = [remote.remote(c, runs_dir) for c in cells]
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            for ref in ready:
                on_done(ray.get(ref))
    finally:
        if started:
            ray.shutdown()


# ------------------------------------------------------------------ outputs
def _write_table(path: Path, rows: Sequence[Mapping], columns: Sequence[str]) -> None:
    tmp = path.with_suffix(path.suffix + '.tmp')
    with open(tmp, 'w', newline='', encoding='utf-8') as fh:
        w = csv.DictWriter(fh, fieldnames=list(columns), extrasaction='ignore')
        w.writeheader()
        for r in rows:
            w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in r.items()})
    os.replace(tmp, path)


def _typed(values: Sequence) -> list:
    """One column with one type: int, float or str (None stays missing)."""
    kinds = {type(v) for v in values if v is not None}
    if kinds and kinds <= {int}:
        return list(values)
    if kinds and kinds <= {int, float}:
        return [None if v is None else float(v) for v in values]
    return [None if v is None else str(v) for v in values]


def _write_parquet(path: Path, rows: Sequence[Mapping], columns: Sequence[str]) -> str | None:
    """The table as Parquet with pyarrow, else polars (a FASTSim dependency);
    returns the engine used, None if neither is installed."""
    data = {c: _typed([r.get(c) for r in rows]) for c in columns}
    tmp = path.with_suffix('.parquet.tmp')
    try:
        import pyarrow as pa  # noqa: PLC0415
        import pyarrow.parquet as pq  # noqa: PLC0415

        pq.write_table(pa.table(data), tmp)
        engine = 'pyarrow'
    except ImportError:
        try:
            import polars as pl  # noqa: PLC0415
        except ImportError:
            return None
        pl.DataFrame(data).write_parquet(tmp)
        engine = 'polars'
    os.replace(tmp, path)
    return engine


SUMMARY_KEYS = ('E_tot_kWh', 'I_pmv', 'otc_violation_pct', 'time_to_comfort_s', 'pmv_max', 'sim_time_s',
                'E_zone_J', 'I_pmv_zone', 'otc_violation_zone_pct', 'pmv_mean_zone')
"""Metrics averaged over seeds in the summary."""

CHANGE_KEYS = ('E_tot_kWh', 'I_pmv', 'E_zone_J', 'I_pmv_zone')
"""Metrics whose change against the baseline [%] the summary gives (``d<key>_pct``)."""


def _settings_of(row: Mapping) -> str:
    return str(row.get('settings') or DEFAULT_SETTINGS)   # rows logged before the settings axis: defaults


def summarize(rows: Sequence[Mapping], baseline: str = 'baseline') -> list[dict]:
    """Per (scenario, drive_cycle, climate, preview, occupant, strategy,
    settings): the mean over seeds of the main metrics (:data:`SUMMARY_KEYS`),
    the number of seeds, and the change against the baseline of the same
    group (scenario, drive_cycle, climate, preview, occupant; means compared,
    :data:`CHANGE_KEYS`). The baseline runs once per group with its default
    settings; every (strategy, settings) of the group is compared with that
    one baseline. Rows keep the order of first appearance."""
    group_axes = [a for a in AXES if a not in ('seed', 'strategy', 'settings')]
    groups: dict = {}
    for r in rows:
        if r.get('status') != 'ok':
            continue
        g = tuple(r[a] for a in group_axes)
        groups.setdefault(g, {}).setdefault((r['strategy'], _settings_of(r)), []).append(r)

    def mean(rs, k):
        vals = [float(x.get(k, float('nan'))) for x in rs]
        return float(np.nanmean(vals)) if any(math.isfinite(v) for v in vals) else float('nan')

    out = []
    for g, by_key in groups.items():
        means = {key: {k: mean(rs, k) for k in SUMMARY_KEYS} for key, rs in by_key.items()}
        base = means.get((baseline, DEFAULT_SETTINGS))
        for (s, label), m in means.items():
            row = dict(zip(group_axes, g))
            row['strategy'] = s
            row['settings'] = label
            row['n_seeds'] = len(by_key[(s, label)])
            row.update({f'{k}_mean': v for k, v in m.items()})
            for k in CHANGE_KEYS:
                row[f'd{k}_pct'] = relative_change_pct(m[k], base[k]) if base else float('nan')
            out.append(row)
    return out


def dominance_rows(summary: Sequence[Mapping], baseline: str = 'baseline') -> list[dict]:
    """Against the baseline of its group, for every other (strategy,
    settings) of a summary: does it use less energy AND have a lower or equal
    I_PMV (a Pareto-dominating point; ``dominates``), over the whole run and
    in the comfort-zone phase (``dominates_zone``)? The changes are the
    summary's ``dE_tot_kWh_pct, dI_pmv_pct, dE_zone_J_pct, dI_pmv_zone_pct``
    (NaN where the group has no baseline: ``dominates`` is then False)."""
    out = []
    for r in summary:
        if r['strategy'] == baseline and r.get('settings', DEFAULT_SETTINGS) == DEFAULT_SETTINGS:
            continue
        de, di = float(r['dE_tot_kWh_pct']), float(r['dI_pmv_pct'])
        dez, diz = float(r.get('dE_zone_J_pct', float('nan'))), float(r.get('dI_pmv_zone_pct', float('nan')))
        out.append({**{a: r[a] for a in _GROUP_AXES}, 'strategy': r['strategy'],
                    'settings': r.get('settings', DEFAULT_SETTINGS),
                    'dE_tot_kWh_pct': de, 'dI_pmv_pct': di, 'otc_violation_pct': r['otc_violation_pct_mean'],
                    'dE_zone_J_pct': dez, 'dI_pmv_zone_pct': diz,
                    'otc_violation_zone_pct': r.get('otc_violation_zone_pct_mean', float('nan')),
                    'dominates': bool(de < 0.0 and di <= 0.0),
                    'dominates_zone': bool(dez < 0.0 and diz <= 0.0)})
    return out


_GROUP_AXES = ('scenario', 'drive_cycle', 'climate', 'preview', 'occupant')


def point_name(strategy: str, settings: str = DEFAULT_SETTINGS) -> str:
    """``strategy`` for default settings, else ``strategy[label]``."""
    return strategy if settings == DEFAULT_SETTINGS else f'{strategy}[{settings}]'


def _ordered_points(keys) -> list:
    """(strategy, settings) keys: strategies in figures.ordered order, labels in first-appearance order."""
    from ceco_bringup.figures import ordered  # noqa: PLC0415

    keys = list(keys)
    return [k for s in ordered(list(dict.fromkeys(k[0] for k in keys))) for k in keys if k[0] == s]


def vehicle_rows(rows: Sequence[Mapping], cells: Sequence[Cell], settings=None) -> list[dict]:
    """Vehicle-level energy (FASTSim, :mod:`ceco_bringup.vehicle_energy`) of
    every group (scenario, cycle, climate, preview, occupant) whose cells
    are done: each strategy's A/C load is its mean ``P_mean_w`` over seeds,
    over the group's drive cycle and run length. One row per group, vehicle
    and strategy, with the group's axes (``strategy``: :func:`point_name`,
    e.g. ``ceco-c[g2k]`` for a settings label)."""
    from ceco_bringup import vehicle_energy as ve  # noqa: PLC0415
    from ceco_v2x_preview.scenario import scenario_from_dict  # noqa: PLC0415

    settings = settings or ve.VehicleEnergySettings()
    spec_of = {c.id: c.spec for c in cells}
    groups: dict = {}
    for r in rows:
        if r.get('status') == 'ok' and r['cell_id'] in spec_of:
            groups.setdefault(tuple(r[a] for a in _GROUP_AXES), []).append(r)
    out = []
    for g, rs in groups.items():
        p_mean: dict = {}
        for r in rs:
            p_mean.setdefault(point_name(r['strategy'], _settings_of(r)), []).append(float(r['P_mean_w']))
        spec = spec_of[rs[0]['cell_id']]
        sc = scenario_from_dict(spec['scenario'])
        duration_s = float(rs[0]['duration_s'])
        t = np.arange(0.0, math.floor(duration_s) + 1.0)
        v = np.asarray(sc.speed_mps(t), dtype=float)
        from ceco_bringup.figures import ordered  # noqa: PLC0415

        loads = {s: float(np.mean(p_mean[s])) for s in ordered(list(p_mean))}
        for vr in ve.vehicle_energy_table(loads, t, v, settings):
            out.append({**dict(zip(_GROUP_AXES, g)), **vr})
    return out


def front_figure(summary: Sequence[Mapping], path: str | os.PathLike, baseline: str = 'baseline',
                 zoom_pct: tuple | None = (4.0, 8.0)) -> Path:
    """The energy-comfort plane of every group of a summary, against its
    baseline: top row the whole run (ΔE_tot vs ΔI_PMV [%]), middle row the
    same near the baseline (half-widths ``zoom_pct`` = (energy, I_PMV) [%];
    None: no such row), bottom row the comfort-zone phase (ΔE_zone vs
    ΔI_PMV,zone [%]); one column per group.
    The baseline is the origin (black cross); the shaded lower-left quadrant
    is where a point dominates it (less energy, lower or equal I_PMV). The
    points of a strategy with settings labels are joined in label order (the
    grid's order) and annotated with the label; strategies with default
    settings are single markers. Writes a PNG (200 dpi) and returns its path."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt  # noqa: PLC0415

    from ceco_bringup.figures import strategy_style  # noqa: PLC0415

    groups: dict = {}
    for r in summary:
        groups.setdefault(tuple(r[a] for a in _GROUP_AXES), []).append(r)
    if not groups:
        raise ValueError('front_figure: the summary has no rows')
    n = len(groups)
    panels = [('dE_tot_kWh_pct', 'dI_pmv_pct', 'whole run', 'ΔE_tot [%]', 'ΔI_PMV [%]', None),
              ('dE_zone_J_pct', 'dI_pmv_zone_pct', 'comfort-zone phase', 'ΔE_zone [%]', 'ΔI_PMV,zone [%]', None)]
    if zoom_pct is not None:
        panels.insert(1, ('dE_tot_kWh_pct', 'dI_pmv_pct', 'whole run, near the baseline', 'ΔE_tot [%]',
                          'ΔI_PMV [%]', (float(zoom_pct[0]), float(zoom_pct[1]))))
    with plt.rc_context({'font.size': 8, 'axes.grid': True, 'grid.alpha': 0.3, 'savefig.bbox': 'tight'}):
        fig, axes = plt.subplots(len(panels), n, figsize=(3.6 * n, 3.2 * len(panels)), squeeze=False)
        for j, (g, rs) in enumerate(groups.items()):
            name = ' / '.join(str(x) for x, a in zip(g, _GROUP_AXES) if x not in ('scenario', 'perfect') or a == 'scenario')
            for i, (kx, ky, phase, xl, yl, zoom) in enumerate(panels):
                ax = axes[i][j]
                pts = [r for r in rs if not (r['strategy'] == baseline and r.get('settings') == DEFAULT_SETTINGS)]
                xs = [float(r.get(kx, float('nan'))) for r in pts] + [0.0]
                ys = [float(r.get(ky, float('nan'))) for r in pts] + [0.0]
                fin = [(x, y) for x, y in zip(xs, ys) if math.isfinite(x) and math.isfinite(y)]
                if zoom:
                    fin = [(-zoom[0], -zoom[1]), (zoom[0], zoom[1])]
                x0 = min(x for x, _ in fin)
                y0 = min(y for _, y in fin)
                pad_x = 0.08 * (max(x for x, _ in fin) - x0 or 1.0)
                pad_y = 0.08 * (max(y for _, y in fin) - y0 or 1.0)
                ax.fill_between([min(x0, 0.0) - 2 * pad_x, 0.0], min(y0, 0.0) - 2 * pad_y, 0.0, color='#009E73',
                                alpha=0.12, lw=0, label='dominates the baseline')
                ax.axhline(0.0, color='k', lw=0.6)
                ax.axvline(0.0, color='k', lw=0.6)
                ax.plot([0.0], [0.0], 'kx', ms=8, mew=2, label=strategy_style(baseline)['label'])
                by_strategy: dict = {}
                for r in pts:
                    by_strategy.setdefault(r['strategy'], []).append(r)
                for k, (st, srs) in enumerate(by_strategy.items()):
                    style = strategy_style(st, k)
                    x = [float(r.get(kx, float('nan'))) for r in srs]
                    y = [float(r.get(ky, float('nan'))) for r in srs]
                    labelled = len(srs) > 1 or srs[0].get('settings') != DEFAULT_SETTINGS
                    ax.plot(x, y, marker='o', ms=4, color=style['color'], lw=1.0 if labelled else 0,
                            label=style['label'] + (' (settings labels)' if labelled else ''))
                    if labelled:   # labels of points closer than 4 % of the axes to the last labelled one are left out
                        span_x = (max(x for x, _ in fin) - min(x0, 0.0)) or 1.0
                        span_y = (max(y for _, y in fin) - min(y0, 0.0)) or 1.0
                        last = None
                        for r, xv, yv in zip(srs, x, y):
                            if not (math.isfinite(xv) and math.isfinite(yv)):
                                continue
                            if last and math.hypot((xv - last[0]) / span_x, (yv - last[1]) / span_y) < 0.04:
                                continue
                            last = (xv, yv)
                            ax.annotate(str(r.get('settings')), (xv, yv), textcoords='offset points',
                                        xytext=(3, 3), fontsize=6.5, color=style['color'])
                ax.set_xlim(min(x0, 0.0) - pad_x, max(x for x, _ in fin) + pad_x)
                ax.set_ylim(min(y0, 0.0) - pad_y, max(y for _, y in fin) + pad_y)
                ax.set_xlabel(xl + ' vs baseline')
                ax.set_ylabel(yl + ' vs baseline')
                ax.set_title(f'{name}: {phase}')
        handles, labels = axes[0][0].get_legend_handles_labels()
        fig.legend(handles, labels, loc='lower center', ncol=len(labels), frameon=False,
                   bbox_to_anchor=(0.5, -0.04))
        fig.tight_layout()
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=200)
        plt.close(fig)
    return path


def _summary_markdown(summary: Sequence[Mapping], timing: Mapping, grid_name: str,
                      vehicle: Sequence[Mapping] = ()) -> str:
    lines = [f'# Sweep summary: {grid_name}', '',
             f"{timing['cells']} cells ({timing['ran']} run now, {timing['skipped']} already done, "
             f"{timing['failed']} failed) with backend `{timing['backend']}` on {timing['workers']} worker(s). "
             f"Wall time of this invocation {timing['wall_s']:.1f} s ({timing['cells_per_hour']:.0f} cells/h). "
             f"Simulation time per cell (scenario build + closed loop, cells run now): mean "
             f"{timing['sim_mean_s']:.2f} s, median {timing['sim_median_s']:.2f} s; worker time per cell incl. "
             f"imports in a fresh worker {timing['cell_mean_s']:.2f} s (sum {timing['cell_sum_s']:.1f} s, "
             f"{timing['speedup']:.2f}x the wall time).", '',
             '| scenario | cycle | climate | preview | occupant | strategy | settings | seeds | E_tot [kWh] | '
             'ΔE [%] | I_PMV [s] | ΔI_PMV [%] | OTC viol. [%] | t_comfort [s] | ΔE zone [%] | ΔI_PMV zone [%] | '
             'OTC viol. zone [%] |',
             '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']

    def f(x, fmt):
        return 'n/a' if x is None or not math.isfinite(float(x)) else format(float(x), fmt)

    rows = sorted(summary, key=lambda r: (r['scenario'], r['drive_cycle'], r['climate'], r['preview'],
                                          r['occupant']))
    groups: dict = {}
    for r in rows:
        groups.setdefault(tuple(r[a] for a in _GROUP_AXES), {})[(r['strategy'], r.get('settings', DEFAULT_SETTINGS))] = r
    for g, by in groups.items():
        for key in _ordered_points(by):
            r = by[key]
            lines.append(f"| {' | '.join(map(str, g))} | {key[0]} | {key[1]} | {r['n_seeds']} | "
                         f"{f(r['E_tot_kWh_mean'], '.4f')} | "
                         f"{f(r['dE_tot_kWh_pct'], '+.1f')} | {f(r['I_pmv_mean'], '.1f')} | "
                         f"{f(r['dI_pmv_pct'], '+.1f')} | {f(r['otc_violation_pct_mean'], '.2f')} | "
                         f"{f(r['time_to_comfort_s_mean'], '.0f')} | {f(r.get('dE_zone_J_pct'), '+.1f')} | "
                         f"{f(r.get('dI_pmv_zone_pct'), '+.1f')} | {f(r.get('otc_violation_zone_pct_mean'), '.2f')} |")
    dom = dominance_rows(summary)
    if dom:
        lines += ['', '## Against the baseline: Pareto-dominating points', '',
                  'A point dominates the baseline of its group when it uses less energy and has a lower or '
                  'equal I_PMV (ΔE < 0 and ΔI_PMV <= 0), over the whole run or in the comfort-zone phase.', '']
        for g in groups:
            here = [d for d in dom if tuple(d[a] for a in _GROUP_AXES) == g]
            if not here:
                continue
            tot = [point_name(d['strategy'], d['settings']) for d in here if d['dominates']]
            zone = [point_name(d['strategy'], d['settings']) for d in here if d['dominates_zone']]
            lines.append(f"- {'/'.join(map(str, g))}: whole run: {', '.join(tot) or 'none'}; "
                         f"zone phase: {', '.join(zone) or 'none'}")
    if vehicle:
        lines += ['', '## Vehicle level (FASTSim 3.1, load-averaged line; see docs/analysis.md)', '',
                  '| scenario | cycle | climate | preview | occupant | vehicle | strategy | P_A/C [W] | '
                  'Δ vehicle energy [%] | noise 1σ [%] | paper, SC03 [%] | range lost [km] |',
                  '|---|---|---|---|---|---|---|---|---|---|---|---|']
        for r in vehicle:
            lines.append(f"| {' | '.join(str(r[a]) for a in _GROUP_AXES)} | {r['vehicle']} | {r['strategy']} | "
                         f"{f(r['p_ac_mean_w'], '.0f')} | {f(r['saving_fit_pct'], '+.2f')} | "
                         f"{f(r['noise_pct'], '.2f')} | {f(r['paper_saving_pct'], '+.1f')} | "
                         f"{f(r['range_lost_km'], '.1f')} |")
    return '\n'.join(lines) + '\n'


def run_sweep(grid_path: str | os.PathLike, out_dir: str | os.PathLike, *, backend: str = 'local',
              workers: int | None = None, address: str | None = None, progress: bool = True,
              log=print) -> dict:
    """Run (or resume) the sweep of ``grid_path`` into ``out_dir``. Returns
    ``{'rows': [...], 'summary': [...], 'timing': {...}, 'paths': {...}}``."""
    if backend not in ('local', 'ray'):
        raise ValueError(f'backend: must be local or ray, got {backend!r}')
    workers = int(workers or os.cpu_count() or 1)
    if workers < 1:
        raise ValueError(f'workers: must be >= 1, got {workers}')
    grid = load_grid(grid_path)
    cells = expand_grid(grid)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / 'grid.json').write_text(json.dumps({'grid': {k: v for k, v in grid.items() if k != '_base_dir'},
                                               'cells': [dataclasses.asdict(c) for c in cells]},
                                              indent=1, default=str) + '\n', encoding='utf-8')
    log_path = out / 'cells.jsonl'
    done = read_done(log_path)
    todo = [dataclasses.asdict(c) for c in cells if c.id not in done]
    runs_dir = str(out / 'runs') if grid.get('save_runs') else None
    log(f'ceco sweep: {len(cells)} cells, {len(cells) - len(todo)} already done, {len(todo)} to run '
        f'({backend}, {workers} worker(s))', file=sys.stderr)
    bar = None
    if progress and todo:
        from tqdm import tqdm  # noqa: PLC0415

        bar = tqdm(total=len(todo), desc='sweep', unit='cell', file=sys.stderr)
    new_rows: list = []

    def on_done(row):
        _append_row(log_path, row)
        new_rows.append(row)
        if row['status'] != 'ok':
            log(f"ceco sweep: cell {row['cell_id']} {point_name(row['strategy'], _settings_of(row))} failed: "
                f"{row['error']}", file=sys.stderr)
        if bar is not None:
            bar.update(1)
            bar.set_postfix_str(f"{row['strategy']}/{row['climate']}")

    t0 = time.perf_counter()
    try:
        if todo:
            n = min(workers, len(todo))
            if backend == 'local':
                _run_local(todo, n, runs_dir, on_done)
            else:
                _run_ray(todo, n, address, runs_dir, on_done)
    finally:
        if bar is not None:
            bar.close()
    wall_s = time.perf_counter() - t0
    done = read_done(log_path)
    rows = [done[c.id] for c in cells if c.id in done]
    failed = [r for r in new_rows if r['status'] != 'ok']
    columns = ['cell_id', *AXES, *METRIC_COLUMNS, 'scenario_name', 'preview_quality', 'code', 'status', 'error',
               'sim_time_s', 'wall_time_s', 'host', 'pid']
    _write_table(out / 'results.csv', rows, columns)
    parquet = _write_parquet(out / 'results.parquet', rows, columns)
    summary = summarize(rows)
    s_cols: list = []
    for r in summary:
        s_cols += [k for k in r if k not in s_cols]
    _write_table(out / 'summary.csv', summary, s_cols)
    ran_ok = [r for r in new_rows if r['status'] == 'ok']
    cell_sum = float(sum(r['wall_time_s'] for r in new_rows))
    sim_times = [r['sim_time_s'] for r in ran_ok]
    timing = {'cells': len(cells), 'ran': len(new_rows), 'skipped': len(cells) - len(todo),
              'failed': len(failed), 'backend': backend, 'workers': workers, 'wall_s': wall_s,
              'cell_sum_s': cell_sum, 'cell_mean_s': cell_sum / len(new_rows) if new_rows else float('nan'),
              'speedup': cell_sum / wall_s if new_rows and wall_s > 0 else float('nan'),
              'ok_total': len(rows), 'ran_ok': len(ran_ok),
              'sim_mean_s': float(np.mean(sim_times)) if sim_times else float('nan'),
              'sim_median_s': float(np.median(sim_times)) if sim_times else float('nan'),
              'cells_per_hour': 3600.0 * len(new_rows) / wall_s if new_rows and wall_s > 0 else float('nan')}
    timing_path = out / 'timing.json'
    shown = timing
    if not new_rows and timing_path.is_file():
        # Nothing ran now (a finished sweep rerun): the summary keeps the
        # timing of the invocation that ran the cells.
        try:
            shown = {**json.loads(timing_path.read_text(encoding='utf-8')), 'ok_total': len(rows)}
        except (OSError, json.JSONDecodeError):
            shown = timing
    else:
        timing_path.write_text(json.dumps(timing, indent=1) + '\n', encoding='utf-8')
    with open(out / 'timing.jsonl', 'a', encoding='utf-8') as fh:   # every invocation, for the record
        fh.write(json.dumps(timing) + '\n')
    vrows: list = []
    if grid.get('vehicle'):
        vrows = vehicle_rows(rows, cells)
        v_cols: list = []
        for r in vrows:
            v_cols += [k for k in r if k not in v_cols]
        _write_table(out / 'vehicle.csv', vrows, v_cols)
    (out / 'summary.md').write_text(_summary_markdown(summary, shown, str(grid.get('name', grid_path)), vrows),
                                    encoding='utf-8')
    return {'rows': rows, 'summary': summary, 'timing': timing, 'failed': failed, 'vehicle': vrows,
            'paths': {'log': log_path, 'csv': out / 'results.csv',
                      'parquet': out / 'results.parquet' if parquet else None,
                      'summary_md': out / 'summary.md', 'summary_csv': out / 'summary.csv'}}


def verify_cells(out_dir: str | os.PathLike, n: int, grid_path: str | os.PathLike) -> list[dict]:
    """Rerun ``n`` finished cells of a sweep in this process (one after
    another, no pool) and compare every metric with the table's value for
    exact equality (wall-clock solve times, :data:`TIMING_COLUMNS`,
    excepted; metrics a log written by an older version lacks are skipped). The cells are the first ``n`` by id, so the choice is
    deterministic and spread over the grid. Returns one dict per cell:
    ``cell_id, axes, equal (bool), differences ({metric: (table, rerun)})``."""
    cells = {c.id: c for c in expand_grid(load_grid(grid_path))}
    done = read_done(Path(out_dir) / 'cells.jsonl')
    ids = sorted(i for i in done if i in cells)[:max(0, int(n))]
    out = []
    for i in ids:
        row = run_cell(dataclasses.asdict(cells[i]))
        diffs = {}
        for k in METRIC_COLUMNS:
            if k in TIMING_COLUMNS or k not in done[i]:   # not recorded (a log from an older sweep.py)
                continue
            a, b = done[i].get(k), row.get(k)
            same = (a == b) or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))
            if not same:
                diffs[k] = (a, b)
        if row['status'] != 'ok':
            diffs['status'] = (done[i]['status'], row['error'])
        out.append({'cell_id': i, 'axes': cells[i].axes, 'equal': not diffs, 'differences': diffs})
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog='ceco sweep', description='Run a grid of closed-loop simulations (strategies x scenarios x drive '
        'cycles x climates x previews x occupants x seeds) in parallel; resumable.')
    parser.add_argument('grid', help='grid YAML file (see ceco_bringup/config/sweep_example.yaml)')
    parser.add_argument('--out', required=True, help='output directory (reuse it to resume)')
    parser.add_argument('--backend', choices=('local', 'ray'), default='local',
                        help='local process pool (default) or Ray')
    parser.add_argument('--address', default=None,
                        help='Ray cluster address (e.g. auto or ray://host:10001); default: a local Ray instance')
    parser.add_argument('--workers', type=int, default=None,
                        help=f'parallel workers (default: all cores, {os.cpu_count()} here)')
    parser.add_argument('--no-progress', action='store_true', help='no progress bar')
    parser.add_argument('--front-figure', default=None, metavar='PNG',
                        help='afterwards, draw the energy-comfort plane of every group against its baseline '
                             '(ΔE vs ΔI_PMV, whole run and comfort-zone phase) to this PNG')
    parser.add_argument('--verify', type=int, default=0, metavar='N',
                        help='afterwards, rerun N finished cells in this process and check the table equals '
                             'them exactly')
    args = parser.parse_args(argv)
    if args.workers is not None and args.workers < 1:
        parser.error(f'--workers: must be >= 1, got {args.workers}')
    if args.address and args.backend != 'ray':
        parser.error('--address needs --backend ray')
    try:
        res = run_sweep(args.grid, args.out, backend=args.backend, workers=args.workers, address=args.address,
                        progress=not args.no_progress)
    except (GridError, ValueError, RuntimeError, OSError) as exc:
        print(f'ceco sweep: error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print('ceco sweep: interrupted; finished cells are kept, rerun the same command to resume',
              file=sys.stderr)
        return 130
    t = res['timing']
    print(f"ceco sweep: {t['ok_total']}/{t['cells']} cells done ({t['ran']} run now, {t['failed']} failed) in "
          f"{t['wall_s']:.1f} s; simulation {t['sim_mean_s']:.2f} s per cell (mean); worker time "
          f"{t['cell_sum_s']:.1f} s = {t['speedup']:.2f}x the wall time")
    print(f"table: {res['paths']['csv']}" + (f" and {res['paths']['parquet']}" if res['paths']['parquet'] else ''))
    print(f"summary: {res['paths']['summary_md']}")
    if args.front_figure:
        print(f"front figure: {front_figure(res['summary'], args.front_figure)}")
    bad = False
    if args.verify:
        for v in verify_cells(args.out, args.verify, args.grid):
            ax = '/'.join(str(v['axes'][a]) for a in AXES)
            print(f"verify {v['cell_id']} {ax}: " + ('table == direct run (all metrics identical)' if v['equal']
                                                      else f"DIFFERS {v['differences']}"))
            bad |= not v['equal']
    return 1 if res['failed'] or bad else 0


if __name__ == '__main__':
    sys.exit(main())
