"""The grid file of ``ceco sweep`` and its expansion into cells.

A grid (YAML; ``ceco_bringup/config/sweep_example.yaml``, docs/analysis.md) names the
axes strategies x scenarios x drive_cycles x climates x previews x occupants x seeds
(x settings); every combination is a :class:`~ceco_bringup.sweep.cells.Cell`. Every
cell's scenario is validated while expanding, so a bad grid fails before any run
with a :class:`GridError` naming the key.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import yaml

from ceco_core import yamlio
from ceco_core.cli_flags import check_duration
from ceco_core.scenario_types import yaml_number_hint

from . import cells as cells_mod
from .cells import Cell, cell_id, runtime_overrides

__all__ = [
    'GridError',
    'AXES',
    'GROUP_AXES',
    'DEFAULT_SETTINGS',
    'load_grid',
    'scenario_dict',
    'strategy_setting_overrides',
    'expand_grid',
]


class GridError(ValueError):
    """An invalid grid file; the message names the key."""


AXES = ('scenario', 'drive_cycle', 'climate', 'preview', 'occupant', 'seed', 'strategy', 'settings')
"""Axis columns of the results table, in order (``settings``: the label of the
strategy's setting overrides, :data:`DEFAULT_SETTINGS` for none)."""

DEFAULT_SETTINGS = 'default'
"""Settings label of a cell run with its strategy's default settings
(every baseline cell, and strategies no ``settings`` label names)."""

_FIXED_SETTING_FIELDS = {'name': 'strategies', 'horizon_steps': 'horizon_steps', 'control_period_s': 'control_period_s'}
"""StrategySettings fields the settings axis may not set (the grid key that sets them)."""

GROUP_AXES = ('scenario', 'drive_cycle', 'climate', 'preview', 'occupant')
"""The axes that make a group: every (strategy, settings) of a group is compared with its one baseline."""

_GRID_KEYS = {
    'name',
    'description',
    'strategies',
    'scenarios',
    'drive_cycles',
    'climates',
    'previews',
    'occupants',
    'seeds',
    'duration_s',
    'save_runs',
    'control_period_s',
    'horizon_steps',
    'vehicle',
    'settings',
}
_CLIMATE_KEYS = {'t_amb_c', 'solar_wm2', 'rh', 'initial', 'comfort_bounds'}


def load_grid(path: str | os.PathLike) -> dict:
    """Read and check a grid YAML file.

    Unknown keys and wrong types raise GridError naming the key.
    """
    path = Path(path)
    try:
        data = yamlio.safe_load(path.read_text(encoding='utf-8'))
    except OSError as exc:
        raise GridError(f'{path}: cannot read grid: {yamlio.os_error_words(exc, "the grid YAML file")}') from None
    except yaml.YAMLError as exc:
        raise GridError(f'{path}: cannot read grid: not valid YAML{yamlio.error_text(exc)}') from None
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
        _no_repeats(key, [str(v) for v in value])
        return {str(v): v for v in value}
    raise GridError(f'{key}: must be a list or a mapping, got {type(value).__name__}')


def _no_repeats(key: str, items: Sequence) -> None:
    """GridError naming the first item of an axis list given twice (a list axis would drop it, or run it twice)."""
    seen: set = set()
    for item in items:
        if item in seen:
            raise GridError(f'{key}: {item!r} is listed twice')
        seen.add(item)


def scenario_dict(scenario) -> dict:
    """A :class:`Scenario` as the mapping ``scenario_from_dict`` accepts.

    The sun, the occupants, the air quality and the initial cabin CO2 appear only where they differ from the
    loader's defaults, so the mapping (and a benchmark case's sha) of a scenario that does not use them is the
    same as before they existed.
    """
    from ceco_core.scenario_types import AirQuality, SunGeometry

    sc = scenario
    ini = {k: float(sc.initial[k]) for k in sc.initial}
    if ini.get('co2_cab_ppm') == float(sc.air_quality.co2_amb_ppm):
        del ini['co2_cab_ppm']  # the loader's default: the ambient CO2
    optional: dict = {}
    if sc.sun != SunGeometry():
        optional['sun'] = {k: float(v) for k, v in dataclasses.asdict(sc.sun).items()}
    if int(sc.occupants) != 1:
        optional['occupants'] = int(sc.occupants)
    if sc.air_quality != AirQuality():
        optional['air_quality'] = {k: v for k, v in dataclasses.asdict(sc.air_quality).items() if v is not None}
    return {
        'name': sc.name,
        'description': sc.description,
        'drive_cycle': sc.drive_cycle.name,
        'duration_s': float(sc.duration_s),
        'weather': {
            'time_s': [float(x) for x in sc.weather_time_s],
            't_amb_c': [float(x) for x in sc.weather_t_amb_c],
            'solar_wm2': [float(x) for x in sc.weather_solar_wm2],
            'rh': [float(x) for x in sc.weather_rh],
        },
        'occupant': {'met': float(sc.occupant.met), 'clo': float(sc.occupant.clo)},
        'comfort_bounds': {
            'time_s': [float(x) for x in sc.bounds_time_s],
            'pmv_lb': [float(x) for x in sc.bounds_pmv_lb],
            'pmv_ub': [float(x) for x in sc.bounds_pmv_ub],
        },
        'initial': ini,
        'control': {
            'control_period_s': float(sc.control.control_period_s),
            'horizon_steps': int(sc.control.horizon_steps),
        },
        **optional,
        'seed': int(sc.seed),
    }


def _two_knots(key: str, value) -> list:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return [float(value), float(value)]
    if (
        isinstance(value, (list, tuple))
        and len(value) == 2
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
    ):
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
    """A setting value from the grid as plain JSON data of the default's type.

    An int for a float field becomes a float, so ``2000`` and ``2000.0``
    give the same cell id. Wrong types raise GridError naming ``where``.
    """
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
    else:  # str, or str | None
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


def strategy_setting_overrides(grid: Mapping, strategies: Sequence[str]) -> dict:
    """The ``settings`` axis of a grid, checked: ``{strategy: {label: overrides}}``.

    The keys are the strategies some label names, ``overrides`` being
    ``{StrategySettings field: plain value}``. Every override set is
    validated now (``strategy_settings(name, **overrides).validate()``, with
    the grid's Ts and Np if it sets them), so a bad field or value fails
    before any run with a GridError (a ValueError) naming
    ``settings.<label>.<strategy>.<field>``. A label naming a strategy not in
    ``strategies``, the baseline (it has no StrategySettings), the reserved
    label ``default``, or one of the fields the grid sets elsewhere (name,
    horizon_steps, control_period_s) is an error.
    """
    raw = grid.get('settings')
    if raw is None:
        return {}
    if not isinstance(raw, Mapping) or not raw:
        raise GridError('settings: must be a non-empty mapping {label: {strategy: {field: value}}}')
    from ceco_controller.strategies import NODE_STRATEGIES, StrategySettings, strategy_settings

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
            if strategy not in NODE_STRATEGIES:
                raise GridError(f'{where}: {strategy} has no StrategySettings (use one of {list(NODE_STRATEGIES)})')
            if fields is None:
                fields = {}
            if not isinstance(fields, Mapping):
                raise GridError(f'{where}: must be a mapping {{StrategySettings field: value}}, got {fields!r}')
            for key in fields:
                if key in _FIXED_SETTING_FIELDS:
                    raise GridError(
                        f'{where}.{key}: set by the grid key {_FIXED_SETTING_FIELDS[key]!r}, not by the settings axis'
                    )
            plain = _plain_fields(where, StrategySettings(), fields)
            try:
                strategy_settings(strategy, **fixed, **runtime_overrides(plain))
            except (ValueError, TypeError) as exc:
                raise GridError(f'{where}: {exc}') from None
            out.setdefault(strategy, {})[label] = plain
    return out


def expand_grid(grid: Mapping) -> list[Cell]:
    """Every cell of a grid (axes in the order of :data:`AXES`, strategy fastest).

    Each cell's scenario is validated here (``scenario_from_dict``),
    so a bad grid fails before any run.
    """
    from ceco_v2x_preview.preview import parse_quality
    from ceco_v2x_preview.scenario import load_drive_cycle, load_scenario, scenario_from_dict

    base_dir = grid.get('_base_dir')
    strategies = grid.get('strategies')
    if not isinstance(strategies, (list, tuple)) or not strategies or not all(isinstance(s, str) for s in strategies):
        raise GridError('strategies: must be a non-empty list of strategy names')
    from ceco_core.contracts import NAMED_STRATEGIES

    bad = [s for s in strategies if s not in NAMED_STRATEGIES]
    if bad:
        raise GridError(f'strategies: unknown strategy {bad[0]!r} (use {list(NAMED_STRATEGIES)})')
    _no_repeats('strategies', strategies)
    scenarios = _named('scenarios', grid.get('scenarios'), {'sc03': 'sc03'})
    cycles = _named('drive_cycles', grid.get('drive_cycles'), {'scenario': None})
    climates = _named('climates', grid.get('climates'), {'scenario': None})
    previews = _named('previews', grid.get('previews'), {'perfect': 'perfect'})
    occupants = _named('occupants', grid.get('occupants'), {'scenario': None})
    seeds = grid.get('seeds', [None])
    if (
        not isinstance(seeds, (list, tuple))
        or not seeds
        or not all(s is None or (isinstance(s, int) and not isinstance(s, bool) and s >= 0) for s in seeds)
    ):
        raise GridError('seeds: must be a non-empty list of non-negative integers')
    _no_repeats('seeds', seeds)
    duration = grid.get('duration_s')
    if duration is not None and not (
        isinstance(duration, (int, float))
        and not isinstance(duration, bool)
        and math.isfinite(duration)
        and duration > 0
    ):
        raise GridError(f'duration_s: must be a positive number, got {duration!r}{yaml_number_hint(duration)}')
    from ceco_core.contracts import CONTROL_PERIOD_RANGE_S, HORIZON_RANGE

    for key, (lo, hi) in (('control_period_s', CONTROL_PERIOD_RANGE_S), ('horizon_steps', HORIZON_RANGE)):
        v = grid.get(key)  # the nodes' ranges, as every verb's flags
        kinds = int if key == 'horizon_steps' else (int, float)
        if v is not None and not (isinstance(v, kinds) and not isinstance(v, bool) and lo <= v <= hi):
            what = 'an integer' if key == 'horizon_steps' else 'a number'
            raise GridError(f'{key}: must be {what} in {lo:g}..{hi:g}, got {v!r}{yaml_number_hint(v)}')
    for label, q in previews.items():
        if not isinstance(q, str):
            raise GridError(f'previews.{label}: must be a preview-quality string (e.g. "noisy:solar=50")')
        try:
            parse_quality(q)
        except ValueError as exc:
            raise GridError(f'previews.{label}: {exc}') from None
    overrides = strategy_setting_overrides(grid, strategies)
    code = cells_mod.code_fingerprint()
    cells = []
    for (sl, sv), (cl, cv), (kl, kv), (pl, pv), (ol, ov), seed in itertools.product(
        scenarios.items(), cycles.items(), climates.items(), previews.items(), occupants.items(), seeds
    ):
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
            d['duration_s'] = cyc.run_duration_s  # whole plant steps, as the scenario loader takes a cycle's length
        _apply_climate(d, kl, kv)
        if ov is not None:
            if not isinstance(ov, Mapping) or set(ov) - {'met', 'clo'}:
                raise GridError(f'occupants.{ol}: must be a mapping with met and/or clo')
            d['occupant'] = {**d['occupant'], **{k: float(v) for k, v in ov.items()}}
        d['name'] = d['name'] if cv is None and kv is None else f"{d['name']}[{cl},{kl}]"
        try:
            cell_scenario = scenario_from_dict(d)
            # duration_s shortens every run: within each cell's scenario, whole plant steps (never lengthened,
            # never rounded), at least one control period
            check_duration(duration, cell_scenario, grid.get('control_period_s'), name='duration_s')
        except ValueError as exc:
            raise GridError(f'cell {sl}/{cl}/{kl}/{ol}: {exc}') from None
        for strategy in strategies:
            for label, ovr in overrides.get(strategy, {DEFAULT_SETTINGS: None}).items():
                spec = {
                    'code': code,
                    'scenario': d,
                    'strategy': strategy,
                    'preview': pv,
                    'seed': seed,
                    'duration_s': None if duration is None else float(duration),
                    'control_period_s': grid.get('control_period_s'),
                    'horizon_steps': grid.get('horizon_steps'),
                }
                if ovr is not None:
                    spec['strategy_overrides'] = ovr
                axes = {
                    'scenario': sl,
                    'drive_cycle': cl,
                    'climate': kl,
                    'preview': pl,
                    'occupant': ol,
                    'seed': '' if seed is None else seed,
                    'strategy': strategy,
                    'settings': label,
                }
                cells.append(Cell(id=cell_id(spec), axes=axes, spec=spec))
    seen: dict = {}
    for c in cells:
        if c.id in seen:
            a, b = seen[c.id].axes, c.axes
            diff = [f'{k} {a[k]!r} / {b[k]!r}' for k in AXES if a[k] != b[k]]
            raise GridError(
                f'the grid holds the same cell twice (two axis labels with the same definition: {", ".join(diff)})'
            )
        seen[c.id] = c
    return cells
