"""One cell of a sweep: its plain description, its id, the code fingerprint, running it.

A cell is plain data (picklable, JSON-able) so that a spawned pool worker or a Ray
task can build the scenario and the controller itself (CasADi objects are not
picklable). Its id is the SHA-256 of its canonical JSON description, which holds
the simulator's code fingerprint: a changed simulator reruns the cell.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import socket
import time
from collections.abc import Mapping
from pathlib import Path

from ceco_core.kpis import AIR_LIMIT_KEYS, AIR_QUALITY_KEYS, breaks_air_quality
from ceco_core.run_status import STATUS_FAILED

__all__ = [
    'METRIC_COLUMNS',
    'TIMING_COLUMNS',
    'AIR_QUALITY_FLAG',
    'Cell',
    'code_fingerprint',
    'cell_id',
    'runtime_overrides',
    'settings_from_spec',
    'run_cell',
]

METRIC_COLUMNS = (
    'E_tot_J',
    'E_tot_kWh',
    'E_comp_J',
    'E_blower_J',
    'P_mean_w',
    'I_pmv',
    'otc_violation_pct',
    'otc_violation_s',
    'otc_above_ub_s',
    'otc_below_lb_s',
    'time_to_comfort_s',
    'pmv_mean',
    'pmv_max',
    'pmv_min',
    'duration_s',
    'n_control_steps',
    'n_fallback_shifted',
    'n_fallback_baseline',
    'solve_time_median_ms',
    'solve_time_max_ms',
    'zone_start_s',
    'E_zone_J',
    'I_pmv_zone',
    'otc_violation_zone_pct',
    'pmv_mean_zone',
    *AIR_LIMIT_KEYS,
    *AIR_QUALITY_KEYS,
)
"""Metric columns of the results table (those the simulator returns; ``*_zone``:
the comfort-zone phase, where the upper PMV bound is at its tightest, from
``zone_start_s`` on; ``closed_loop.simulate``), then the air quality scored against the
cell's scenario's limits as every verb's ``metrics.json`` has it (``ceco_core.kpis.run_air_quality``:
the limits ``co2_limit_ppm`` [ppm], ``fog_margin_bound_k`` [K] and the KPIs ``co2_max_ppm`` ...
``air_quality_met``)."""

AIR_QUALITY_FLAG = 'air_quality_broken'
"""Column of a results row: True when the cell's run broke its scenario's air-quality limits
(``ceco_core.kpis.breaks_air_quality``, the rule of every verb): such a run claims no saving
(:func:`ceco_bringup.sweep.summary.summarize`)."""

TIMING_COLUMNS = ('solve_time_median_ms', 'solve_time_max_ms')
"""Metric columns that are wall-clock measurements (not reproducible)."""


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


_CODE_PACKAGES = ('ceco_core', 'ceco_v2x_preview', 'ceco_plant_sim', 'ceco_controller')
_CODE_SUFFIXES = ('.py', '.yaml', '.yml', '.csv', '.json')


def code_fingerprint() -> str:
    """SHA-256 (16 hex digits) of the simulator's code and configuration as importable here.

    It covers every ``.py/.yaml/.csv/.json`` file of the scenario,
    plant and controller packages, their ``config/`` directories and the
    identified model parameter file. Part of every cell's id, so a changed
    simulator reruns the cells instead of mixing results of two versions.
    """
    h = hashlib.sha256()
    files: list = []
    for name in _CODE_PACKAGES:
        mod = __import__(name)
        pkg = Path(mod.__file__).resolve().parent
        for root in (pkg, pkg.parent / 'config'):
            if root.is_dir():
                files += [
                    (f'{name}/{root.name}/{p.relative_to(root)}', p)
                    for p in root.rglob('*')
                    if p.suffix in _CODE_SUFFIXES and p.is_file() and '__pycache__' not in p.parts
                ]
    try:
        from ceco_controller.model import default_params_path

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


def runtime_overrides(plain: Mapping) -> dict:
    """Setting overrides as stored in a cell's spec (plain JSON data) -> keyword overrides of ``strategy_settings``.

    A ``solver`` mapping becomes a :class:`SolverSettings`, lists become tuples.
    """
    from ceco_controller.strategies import SolverSettings

    out = {}
    for key, value in plain.items():
        if key == 'solver':
            base = SolverSettings()
            value = dataclasses.replace(base, **{k: tuple(v) if isinstance(v, list) else v for k, v in value.items()})
        elif isinstance(value, list):
            value = tuple(value)
        out[key] = value
    return out


def settings_from_spec(spec: Mapping):
    """The :class:`~ceco_controller.closed_loop.SimSettings` of a cell's spec.

    Args:
        spec: the cell's spec (plain JSON data): ``preview`` (preview quality text),
            optional ``control_period_s`` [s], ``horizon_steps``, ``seed``, ``duration_s`` [s]
            (None: the scenario's), ``strategy_overrides`` (see :func:`runtime_overrides`) and,
            for the benchmark's sensitivity runs, ``plant_overrides`` / ``comfort_overrides``, and
            ``measurements`` ('full' when absent; 'vehicle' for the benchmark's comfort-feedback families),
            optional ``model_params_path`` (the controller's identified model file; absent: the package's,
            ``ceco_controller/config/model_params.yaml``; ``tools/variant_headroom.py --model-params``).

    Returns:
        The simulator settings, without a progress bar.
    """
    from ceco_controller.closed_loop import SimSettings
    from ceco_v2x_preview.preview import parse_quality

    hs = spec.get('horizon_steps')
    ovr = runtime_overrides(spec.get('strategy_overrides') or {})
    return SimSettings(
        control_period_s=spec.get('control_period_s'),
        horizon_steps=None if hs is None else int(hs),
        preview_quality=parse_quality(spec['preview']),
        seed=spec.get('seed'),
        duration_s=spec.get('duration_s'),
        progress=False,
        strategy_overrides=tuple(sorted(ovr.items())),
        plant_overrides=tuple(sorted((spec.get('plant_overrides') or {}).items())),
        comfort_overrides=tuple(sorted((spec.get('comfort_overrides') or {}).items())),
        measurements=spec.get('measurements', 'full'),
        model_params_path=spec.get('model_params_path'),
    )


def check_code(spec: Mapping, what: str) -> str:
    """This process's :func:`code_fingerprint`; RuntimeError if the driver's (``spec['code']``) differs.

    ``what`` names the driver ('sweep', 'benchmark') in the message.
    """
    code = code_fingerprint()
    if spec.get('code') and code != spec['code']:
        raise RuntimeError(
            f"the simulator's code here ({code}) differs from the {what}'s ({spec['code']}): code changed "
            f'during the {what}, or a Ray node runs another version; rerun the {what}'
        )
    return code


def run_cell(cell: Mapping, runs_dir: str | None = None, controller_cache=None) -> dict:
    """Run one cell in this process and return its results row; never raises for a failing run.

    ``controller_cache``: the worker's :class:`ceco_controller.factory.ControllerCache` (a warm
    worker reuses its controllers; the results are the same).

    The row holds the cell id, axes, every metric (:data:`METRIC_COLUMNS`, the air quality included),
    :data:`AIR_QUALITY_FLAG`, ``status`` ('ok', 'failed': the controller did not
    control the run, ``ceco_core.run_status``; or 'error'), ``error``,
    ``code`` (this process's :func:`code_fingerprint`; a cell whose
    fingerprint differs from the driver's is an error, not a result),
    ``sim_time_s`` (scenario build + simulation), ``wall_time_s`` (also the
    first imports in a fresh worker), ``host``, ``pid``. A failing run's
    error is in the row. ``cell`` is :class:`Cell` as a dict.
    """
    t0 = time.perf_counter()
    row = {'cell_id': cell['id'], **cell['axes'], 'status': 'ok', 'error': '', 'sim_time_s': float('nan')}
    try:
        from ceco_controller.closed_loop import simulate, write_run
        from ceco_v2x_preview.scenario import scenario_from_dict

        spec = cell['spec']
        row['code'] = check_code(spec, 'sweep')
        t_sim = time.perf_counter()
        scenario = scenario_from_dict(spec['scenario'])
        result = simulate(scenario, spec['strategy'], settings_from_spec(spec), controller_cache=controller_cache)
        row['sim_time_s'] = time.perf_counter() - t_sim
        for k in METRIC_COLUMNS:
            v = result.metrics.get(k)
            row[k] = float('nan') if v is None else float(v)
        row[AIR_QUALITY_FLAG] = breaks_air_quality(row)
        row['scenario_name'] = result.metrics.get('scenario', scenario.name)
        row['preview_quality'] = result.metrics.get('preview_quality', spec['preview'])
        if result.metrics.get('status') == STATUS_FAILED:  # its controller did not control it: no result
            row['status'], row['error'] = STATUS_FAILED, result.metrics['status_reason']
        if runs_dir:
            write_run(result, Path(runs_dir) / cell['id'])
    except Exception as exc:  # a failed cell is data, the sweep goes on
        row['status'] = 'error'
        row['error'] = f'{type(exc).__name__}: {exc}'
    row['wall_time_s'] = time.perf_counter() - t0
    row['host'] = socket.gethostname()
    row['pid'] = os.getpid()
    return row
