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
  cell's plain description (a dict) and builds the scenario itself; its NMPC
  controllers it builds once and reuses, reset, for later cells (warm workers,
  :mod:`.backends`).
* ``--backend ray``: the same warm workers as Ray actors, on a local Ray
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
one row per cell, its axes and every metric, the air quality scored against the scenario's limits and the flag
``air_quality_broken`` of ``ceco_core.kpis.breaks_air_quality`` included; also ``results.parquet`` when
pyarrow or polars is installed), ``summary.md`` and ``summary.csv`` (per scenario,
climate, preview and occupant: each strategy's mean over seeds and its change
against the baseline; no change, i.e. no saving, where the point or its baseline broke the air-quality
limits), ``grid.json`` (the resolved cells), with
``save_runs: true`` in the grid one run directory per cell under ``DIR/runs/``,
and with ``vehicle: true`` ``vehicle.csv`` (FASTSim vehicle-level energy of
each group's strategies; the FASTSim extra).

Modules (none over ~500 lines): :mod:`.grid` (the grid file, its axes and their
expansion into cells), :mod:`.cells` (a cell's id, the code fingerprint, running
one cell), :mod:`.backends` (the resumable log, the local process pool and Ray:
any picklable cell function, also used by ``ceco benchmark``), :mod:`.summary`
(tables, summary, dominance, vehicle level), :mod:`.cli` (``run_sweep``,
``verify_cells``, ``main``); the front figure is
:func:`ceco_bringup.figures.front_figure`.
"""

from . import backends, cells, grid, summary
from .backends import WORKER_THREAD_ENV, append_row, read_done, run_local, run_ray
from .cells import METRIC_COLUMNS, TIMING_COLUMNS, Cell, cell_id, code_fingerprint, run_cell, runtime_overrides
from .cli import main, run_sweep, verify_cells
from .grid import (
    AXES,
    DEFAULT_SETTINGS,
    GROUP_AXES,
    GridError,
    expand_grid,
    load_grid,
    scenario_dict,
    strategy_setting_overrides,
)
from .summary import CHANGE_KEYS, SUMMARY_KEYS, dominance_rows, point_name, summarize, vehicle_rows

__all__ = [
    'GridError',
    'Cell',
    'load_grid',
    'expand_grid',
    'scenario_dict',
    'cell_id',
    'code_fingerprint',
    'run_cell',
    'read_done',
    'run_sweep',
    'summarize',
    'vehicle_rows',
    'verify_cells',
    'main',
    'AXES',
    'GROUP_AXES',
    'METRIC_COLUMNS',
    'TIMING_COLUMNS',
    'DEFAULT_SETTINGS',
    'strategy_setting_overrides',
    'runtime_overrides',
    'dominance_rows',
    'front_figure',
    'point_name',
    'run_local',
    'run_ray',
    'WORKER_THREAD_ENV',
    'SUMMARY_KEYS',
    'CHANGE_KEYS',
    'backends',
    'cells',
    'grid',
    'summary',
    'append_row',
]


def __getattr__(name: str):
    """``front_figure`` imported on first use: matplotlib costs a worker or the planning process ~1 s to import."""
    if name == 'front_figure':
        from ceco_bringup.figures import front_figure

        return front_figure
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
