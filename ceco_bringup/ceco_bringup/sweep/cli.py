"""``ceco sweep GRID.yaml --out DIR``: run (or resume) a sweep, verify cells, the CLI."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

from ceco_bringup import cli_args

from . import backends
from . import cells as cells_mod
from .backends import append_row, read_done
from .cells import AIR_QUALITY_FLAG, METRIC_COLUMNS, TIMING_COLUMNS
from .grid import AXES, GROUP_AXES, GridError, expand_grid, load_grid
from .summary import _settings_of, _write_parquet, _write_table, point_name, summarize, summary_markdown, vehicle_rows

__all__ = ['run_sweep', 'verify_cells', 'build_parser', 'main']


def run_sweep(
    grid_path: str | os.PathLike,
    out_dir: str | os.PathLike,
    *,
    backend: str = 'local',
    workers: int | None = None,
    address: str | None = None,
    progress: bool = True,
    log=print,
) -> dict:
    """Run (or resume) the sweep of ``grid_path`` into ``out_dir``.

    Returns ``{'rows': [...], 'summary': [...], 'timing': {...}, 'paths': {...}}``, plus
    ``'failed'`` (the rows of the cells that failed in this run) and ``'vehicle'`` (the
    vehicle-level rows, empty when the grid has no ``vehicle`` entry).
    """
    if backend not in ('local', 'ray'):
        raise ValueError(f'backend: must be local or ray, got {backend!r}')
    ray_workers = workers
    workers = int(workers or os.cpu_count() or 1)
    if workers < 1:
        raise ValueError(f'workers: must be >= 1, got {workers}')
    grid = load_grid(grid_path)
    cells = expand_grid(grid)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / 'grid.json').write_text(
        json.dumps(
            {
                'grid': {k: v for k, v in grid.items() if k != '_base_dir'},
                'cells': [dataclasses.asdict(c) for c in cells],
            },
            indent=1,
            default=str,
        )
        + '\n',
        encoding='utf-8',
    )
    log_path = out / 'cells.jsonl'
    done = read_done(log_path)
    todo = [dataclasses.asdict(c) for c in cells if c.id not in done]
    runs_dir = str(out / 'runs') if grid.get('save_runs') else None
    log(
        f'ceco sweep: {len(cells)} cells, {len(cells) - len(todo)} already done, {len(todo)} to run '
        f'({backend}, {workers} worker(s))',
        file=sys.stderr,
    )
    bar = None
    if progress and todo:
        from tqdm import tqdm

        bar = tqdm(total=len(todo), desc='sweep', unit='cell', file=sys.stderr)
    new_rows: list = []

    def on_done(row):
        append_row(log_path, row)
        new_rows.append(row)
        if row['status'] != 'ok':
            log(
                f"ceco sweep: cell {row['cell_id']} {point_name(row['strategy'], _settings_of(row))} failed: "
                f"{row['error']}",
                file=sys.stderr,
            )
        if bar is not None:
            bar.update(1)
            bar.set_postfix_str(f"{row['strategy']}/{row['climate']}")

    t0 = time.perf_counter()
    try:
        if todo:
            n = min(workers, len(todo))
            if backend == 'local':
                backends.run_local(todo, n, on_done, cells_mod.run_cell, runs_dir)
            else:
                # on a cluster (address) without --workers: one worker per CPU of the cluster
                backends.run_ray(
                    todo, None if address and not ray_workers else n, address, on_done, cells_mod.run_cell, runs_dir
                )
    finally:
        if bar is not None:
            bar.close()
    wall_s = time.perf_counter() - t0
    done = read_done(log_path)
    rows = [done[c.id] for c in cells if c.id in done]
    failed = [r for r in new_rows if r['status'] != 'ok']
    columns = [
        'cell_id',
        *AXES,
        *METRIC_COLUMNS,
        AIR_QUALITY_FLAG,
        'scenario_name',
        'preview_quality',
        'code',
        'status',
        'error',
        'sim_time_s',
        'wall_time_s',
        'host',
        'pid',
    ]
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
    timing = {
        'cells': len(cells),
        'ran': len(new_rows),
        'skipped': len(cells) - len(todo),
        'failed': len(failed),
        'backend': backend,
        'workers': workers,
        'wall_s': wall_s,
        'cell_sum_s': cell_sum,
        'cell_mean_s': cell_sum / len(new_rows) if new_rows else float('nan'),
        'speedup': cell_sum / wall_s if new_rows and wall_s > 0 else float('nan'),
        'ok_total': len(rows),
        'ran_ok': len(ran_ok),
        'sim_mean_s': float(np.mean(sim_times)) if sim_times else float('nan'),
        'sim_median_s': float(np.median(sim_times)) if sim_times else float('nan'),
        'cells_per_hour': 3600.0 * len(new_rows) / wall_s if new_rows and wall_s > 0 else float('nan'),
    }
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
    with open(out / 'timing.jsonl', 'a', encoding='utf-8') as fh:  # every invocation, for the record
        fh.write(json.dumps(timing) + '\n')
    vrows: list = []
    if grid.get('vehicle'):
        vrows = vehicle_rows(rows, cells)
        v_cols: list = []
        for r in vrows:
            v_cols += [k for k in r if k not in v_cols]
        _write_table(out / 'vehicle.csv', vrows, v_cols)
    (out / 'summary.md').write_text(
        summary_markdown(summary, shown, str(grid.get('name', grid_path)), vrows), encoding='utf-8'
    )
    return {
        'rows': rows,
        'summary': summary,
        'timing': timing,
        'failed': failed,
        'vehicle': vrows,
        'paths': {
            'log': log_path,
            'csv': out / 'results.csv',
            'parquet': out / 'results.parquet' if parquet else None,
            'summary_md': out / 'summary.md',
            'summary_csv': out / 'summary.csv',
        },
    }


def verify_cells(out_dir: str | os.PathLike, n: int, grid_path: str | os.PathLike) -> list[dict]:
    """Rerun ``n`` finished cells of a sweep in this process and compare every metric with the table's value.

    The cells run one after another, no pool, and the comparison is for
    exact equality (wall-clock solve times, :data:`TIMING_COLUMNS`,
    excepted; metrics a log written by an older version lacks are skipped).
    The cells are the first ``n`` by id, so the choice is
    deterministic and spread over the grid. Returns one dict per cell:
    ``cell_id, axes, equal (bool), differences ({metric: (table, rerun)})``.
    """
    cells = {c.id: c for c in expand_grid(load_grid(grid_path))}
    done = read_done(Path(out_dir) / 'cells.jsonl')
    ids = sorted(i for i in done if i in cells)[: max(0, int(n))]
    out = []
    for i in ids:
        row = cells_mod.run_cell(dataclasses.asdict(cells[i]))
        diffs = {}
        for k in METRIC_COLUMNS:
            if k in TIMING_COLUMNS or k not in done[i]:  # not recorded (a log from an older sweep.py)
                continue
            a, b = done[i].get(k), row.get(k)
            same = (a == b) or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))
            if not same:
                diffs[k] = (a, b)
        if row['status'] != 'ok':
            diffs['status'] = (done[i]['status'], row['error'])
        out.append({'cell_id': i, 'axes': cells[i].axes, 'equal': not diffs, 'differences': diffs})
    return out


def build_parser() -> cli_args.Parser:
    """The parser of ``ceco sweep`` (``ceco sweep --help``)."""
    parser = cli_args.Parser(
        'ceco sweep',
        'Run a grid of closed-loop simulations (strategies x scenarios x drive '
        'cycles x climates x previews x occupants x seeds) in parallel; resumable.',
    )
    parser.add_argument('grid', help='grid YAML file (see ceco_bringup/config/sweep_example.yaml)')
    cli_args.add_out(parser, 'output directory (reuse it to resume)')
    cli_args.add_backend(parser)
    cli_args.add_workers(parser)
    cli_args.add_no_progress(parser)
    parser.add_argument(
        '--front-figure',
        default=None,
        metavar='PNG',
        help='afterwards, draw the energy-comfort plane of every group against its baseline '
        '(ΔE vs ΔI_PMV, whole run and comfort-zone phase) to this PNG',
    )
    parser.add_argument(
        '--verify',
        type=cli_args.nonnegative_int,
        default=0,
        metavar='N',
        help='afterwards, rerun N finished cells in this process and check the table equals them exactly',
    )
    return parser


def main(argv=None) -> int:
    """``ceco sweep GRID --out DIR``: run or resume a sweep, print its timing and paths, optionally verify it.

    Args:
        argv: the arguments after ``ceco sweep`` (default ``sys.argv[1:]``).

    Returns:
        The exit status: 0 when every cell succeeded (and ``--verify`` found the table equal to
        the reruns), 1 when a cell failed or a rerun differed, 2 for an invalid grid or options or
        when the sweep cannot run (a file or backend error),
        130 when interrupted (finished cells are kept).
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.address and args.backend != 'ray':
        parser.error('--address needs --backend ray')
    cli_args.check_out(parser, args.out)
    try:
        res = run_sweep(
            args.grid,
            args.out,
            backend=args.backend,
            workers=args.workers,
            address=args.address,
            progress=not args.no_progress,
        )
    except (GridError, ValueError, RuntimeError, OSError) as exc:
        print(f'ceco sweep: error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print('ceco sweep: interrupted; finished cells are kept, rerun the same command to resume', file=sys.stderr)
        return 130
    t = res['timing']
    print(
        f"ceco sweep: {t['ok_total']}/{t['cells']} cells done ({t['ran']} run now, {t['failed']} failed) in "
        f"{t['wall_s']:.1f} s; simulation {t['sim_mean_s']:.2f} s per cell (mean); worker time "
        f"{t['cell_sum_s']:.1f} s = {t['speedup']:.2f}x the wall time"
    )
    print(f"table: {res['paths']['csv']}" + (f" and {res['paths']['parquet']}" if res['paths']['parquet'] else ''))
    print(f"summary: {res['paths']['summary_md']}")
    broke = [r for r in res['summary'] if r['no_saving']]  # broke the limits, or its group's baseline did
    if broke:  # the rule of every verb (ceco_core.kpis.breaks_air_quality): said on the console too
        names = ', '.join(
            f"{'/'.join(str(r[a]) for a in GROUP_AXES)} {point_name(r['strategy'], r['settings'])}" for r in broke
        )
        why = 'it or its baseline broke the limits'
        print(f'air quality: no saving claimed for {len(broke)} point(s) ({why}): {names}')
    if args.front_figure:
        from ceco_bringup.figures import front_figure

        print(f"front figure: {front_figure(res['summary'], args.front_figure)}")
    bad = False
    if args.verify:
        for v in verify_cells(args.out, args.verify, args.grid):
            ax = '/'.join(str(v['axes'][a]) for a in AXES)
            print(
                f"verify {v['cell_id']} {ax}: "
                + ('table == direct run (all metrics identical)' if v['equal'] else f"DIFFERS {v['differences']}")
            )
            bad |= not v['equal']
    return 1 if res['failed'] or bad else 0


if __name__ == '__main__':
    sys.exit(main())
