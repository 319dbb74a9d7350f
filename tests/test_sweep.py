"""ceco sweep: grid expansion, deterministic cell ids, resume, and cells equal
to direct closed-loop runs, on the local process pool and on a local Ray
instance. Runs are shortened (duration_s) to keep the suite fast."""

import csv
import dataclasses
import importlib.util
import json
import math
import os

import pytest
from sweep_helpers import sweep_row

from ceco_bringup import sweep
from ceco_controller.closed_loop import SimSettings, simulate
from ceco_v2x_preview.preview import parse_quality
from ceco_v2x_preview.scenario import scenario_from_dict

GRID = """
name: test grid
strategies: [baseline, ceco]
scenarios: [sc03]
climates:
  hot: null
  mild: {t_amb_c: 28.0, solar_wm2: [400, 300], rh: 0.5, initial: {t_cab_c: 40.0}}
duration_s: {duration}
"""


def _grid(tmp_path, text=GRID, duration=20, name='grid.yaml'):
    p = tmp_path / name
    p.write_text(text.replace('{duration}', str(duration)), encoding='utf-8')
    return p


def _direct(cell):
    """The same run as the cell, by a direct simulate() call in this process."""
    spec = cell.spec
    settings = SimSettings(
        preview_quality=parse_quality(spec['preview']), seed=spec['seed'], duration_s=spec['duration_s'], progress=False
    )
    return simulate(scenario_from_dict(spec['scenario']), spec['strategy'], settings).metrics


def test_expand_grid_counts_ids_and_overrides(tmp_path):
    text = (
        GRID + 'previews: {perfect: perfect, noisy: "noisy:solar=50"}\nseeds: [0, 1]\n'
        'occupants: {light: {met: 1.1}, heavy: {met: 1.6, clo: 0.7}}\n'
    )
    cells = sweep.expand_grid(sweep.load_grid(_grid(tmp_path, text)))
    assert len(cells) == 2 * 2 * 2 * 2 * 2  # strategies x climates x previews x seeds x occupants
    assert len({c.id for c in cells}) == len(cells)
    again = sweep.expand_grid(sweep.load_grid(_grid(tmp_path, text)))
    assert [c.id for c in again] == [c.id for c in cells]  # deterministic
    mild = next(c for c in cells if c.axes['climate'] == 'mild' and c.axes['occupant'] == 'heavy')
    sc = mild.spec['scenario']
    assert sc['weather']['t_amb_c'] == [28.0, 28.0]
    assert sc['weather']['solar_wm2'] == [400.0, 300.0]
    assert sc['weather']['time_s'] == [0.0, 600.0]  # spans the run
    assert sc['initial'] == {'t_cab_c': 40.0}
    assert sc['occupant'] == {'met': 1.6, 'clo': 0.7}
    hot = next(c for c in cells if c.axes['climate'] == 'hot')
    assert hot.spec['scenario']['weather']['t_amb_c'] == [35.0, 35.0]  # the scenario's own
    assert hot.spec['duration_s'] == 20.0
    # Editing one climate changes the ids of its cells only.
    edited = sweep.expand_grid(
        sweep.load_grid(_grid(tmp_path, text.replace('t_amb_c: 28.0', 't_amb_c: 29.0'), name='g2.yaml'))
    )
    changed = {c.id for c in edited} ^ {c.id for c in cells}
    assert len(changed) == 2 * 16
    assert all(c.axes['climate'] == 'mild' for c in edited if c.id in changed)


@pytest.mark.parametrize(
    'text, key',
    [
        ('strategies: [baseline]\nbogus: 1\n', 'bogus'),
        ('strategies: [warp-drive]\n', 'strategies'),
        ('strategies: [baseline]\nclimates: {x: {t_amb_c: "hot"}}\n', 'climates.x.t_amb_c'),
        ('strategies: [baseline]\nclimates: {x: {wind: 3}}\n', 'climates.x.wind'),
        ('strategies: [baseline]\npreviews: {p: "foggy"}\n', 'previews.p'),
        ('strategies: [baseline]\nseeds: [-1]\n', 'seeds'),
        ('strategies: [baseline]\nduration_s: .nan\n', 'duration_s'),
        ('strategies: [baseline]\nclimates: {x: {t_amb_c: 95.0}}\n', 'weather.t_amb_c'),
        # duration_s shortens the runs: one longer than the scenario ran 100000 s, a fraction was floored
        ('strategies: [baseline]\nduration_s: 100000.0\n', 'duration_s: 100000 s exceeds the length of scenario'),
        ('strategies: [baseline]\nduration_s: 30.5\n', 'duration_s: 30.5 s is not a whole number of plant steps'),
        ('strategies: [baseline]\ncontrol_period_s: 100000.0\n', 'control_period_s: must be a number in 0.1..300'),
        ('strategies: [baseline]\nhorizon_steps: 100\n', 'horizon_steps: must be an integer in 1..60'),
        ('strategies: [baseline]\nhorizon_steps: 6.5\n', 'horizon_steps: must be an integer in 1..60, got 6.5'),
        # a list axis naming a value twice: the scenarios' was dropped without a word, the strategies' said
        # "the same cell twice" with an empty reason
        ('strategies: [ceco-ioch, ceco-ioch]\n', "strategies: 'ceco-ioch' is listed twice"),
        ('strategies: [baseline]\nscenarios: [sc03, udds, sc03]\n', "scenarios: 'sc03' is listed twice"),
        ('strategies: [baseline]\nseeds: [1, 2, 1]\n', 'seeds: 1 is listed twice'),
        ('strategies: [baseline]\nscenarios: [sc03]\nscenarios: [udds]\n', "found the key 'scenarios' twice"),
    ],
)
def test_bad_grid_names_the_key(tmp_path, text, key):
    with pytest.raises(sweep.GridError, match=key.replace('.', r'\.')):
        sweep.expand_grid(sweep.load_grid(_grid(tmp_path, text)))


def test_local_sweep_equals_direct_runs_and_resumes(tmp_path):
    grid = _grid(tmp_path)
    out = tmp_path / 'out'
    res = sweep.run_sweep(grid, out, workers=2, progress=False, log=lambda *a, **k: None)
    assert res['timing']['ran'] == 4 and res['timing']['failed'] == 0
    with open(out / 'results.csv', newline='') as fh:
        table = list(csv.DictReader(fh))
    assert len(table) == 4
    assert {(r['strategy'], r['climate']) for r in table} == {
        ('baseline', 'hot'),
        ('ceco', 'hot'),
        ('baseline', 'mild'),
        ('ceco', 'mild'),
    }
    if importlib.util.find_spec('polars') is not None:  # the analysis extra (fastsim pulls it): Parquet too
        import polars as pl

        pq = pl.read_parquet(out / 'results.parquet')
        assert pq.height == 4 and pq['E_tot_J'].to_list() == [float(r['E_tot_J']) for r in table]
    elif importlib.util.find_spec('pyarrow') is None:
        assert not (out / 'results.parquet').exists()
    # Two cells against direct simulate() calls in this process: equal exactly.
    cells = {c.id: c for c in sweep.expand_grid(sweep.load_grid(grid))}
    for row in table[:2]:
        direct = _direct(cells[row['cell_id']])
        for key in ('E_tot_J', 'E_comp_J', 'E_blower_J', 'I_pmv', 'otc_violation_pct', 'pmv_max'):
            assert float(row[key]) == direct[key], key
    # The mild climate is mild: less A/C energy than the hot one for the baseline.
    e = {(r['strategy'], r['climate']): float(r['E_tot_J']) for r in table}
    assert e[('baseline', 'mild')] < e[('baseline', 'hot')]
    summary = (out / 'summary.md').read_text()
    assert '| sc03 | scenario | mild | perfect | scenario | ceco |' in summary
    # Resume: nothing is rerun; a torn last line (crash mid-write) is ignored.
    with open(out / 'cells.jsonl', 'a') as fh:
        fh.write('{"cell_id": "deadbeef", "status": "ok", "E_tot')
    again = sweep.run_sweep(grid, out, workers=2, progress=False, log=lambda *a, **k: None)
    assert again['timing']['ran'] == 0 and again['timing']['skipped'] == 4
    assert len(again['rows']) == 4
    assert sweep.main([str(grid), '--out', str(out), '--no-progress']) == 0  # the CLI resumes too
    # A new cell in the grid runs alone; the log keeps every line parseable.
    grid3 = _grid(tmp_path, GRID.replace('[baseline, ceco]', '[baseline, ceco, ceco-e]'), name='g3.yaml')
    third = sweep.run_sweep(grid3, out, workers=1, progress=False, log=lambda *a, **k: None)
    assert third['timing']['ran'] == 2 and len(third['rows']) == 6
    lines = (out / 'cells.jsonl').read_text().splitlines()
    parsed = [json.loads(ln) for ln in lines if not ln.startswith('{"cell_id": "deadbeef"')]
    assert len(parsed) == 6


def _fresh_process_row(cell):
    """The cell run in a process of its own (spawned for it, nothing built before)."""
    import concurrent.futures as cf
    import multiprocessing

    ctx = multiprocessing.get_context('spawn')
    with cf.ProcessPoolExecutor(max_workers=1, mp_context=ctx, max_tasks_per_child=1) as pool:
        return pool.submit(sweep.run_cell, dataclasses.asdict(cell)).result()


_RESULT_KEYS = [k for k in sweep.METRIC_COLUMNS if k not in sweep.TIMING_COLUMNS]


def test_warm_workers_reuse_controllers_and_equal_fresh_processes(tmp_path):
    """A warm worker builds each controller once and reuses it, reset, for its later cells; every
    cell's results equal those of the same cell run in a fresh process, bit for bit, whether the
    warm worker is this process or a pool process, and whatever ran on it before."""
    grid = _grid(tmp_path, GRID.replace('[baseline, ceco]', '[baseline, ceco, ceco-ioch]'), duration=40)
    cells = sweep.expand_grid(sweep.load_grid(grid))
    assert len(cells) == 6
    fresh = {c.id: _fresh_process_row(c) for c in cells if c.axes['strategy'] != 'baseline'}
    fresh.update({c.id: sweep.run_cell(dataclasses.asdict(c)) for c in cells if c.axes['strategy'] == 'baseline'})
    # one warm worker in this process, the cells in grid order and then again in reverse
    worker = sweep.backends.WarmWorker()
    warm = [worker.run(sweep.run_cell, dataclasses.asdict(c)) for c in cells + cells[::-1]]
    assert worker.cache.builds == 2 and worker.cache.hits == 6  # ceco and ceco-ioch built once each
    # the local pool: two warm processes, spawned when the pool is made (before any cell is known), then
    # two runs of the cells on the same processes
    items = [dataclasses.asdict(c) for c in cells]
    with sweep.backends.LocalPool(2) as pool:
        started = pool.worker_pids()
        pooled: list = []
        pool.run(items, pooled.append, sweep.run_cell)
        pool.run(items[::-1], pooled.append, sweep.run_cell)
    assert len(started) == 2 and os.getpid() not in started
    assert len(pooled) == 12 and {r['pid'] for r in pooled} <= started
    for row in warm + pooled:
        ref = fresh[row['cell_id']]
        assert row['status'] == ref['status'] == 'ok'
        assert [repr(row[k]) for k in _RESULT_KEYS] == [repr(ref[k]) for k in _RESULT_KEYS], row['strategy']  # NaN too
    # the NMPC cells did control (no number from a failed run)
    assert all(fresh[c.id]['n_control_steps'] == 8 for c in cells)
    assert all(fresh[c.id]['n_fallback_baseline'] == 0 for c in cells if c.axes['strategy'] != 'baseline')


def test_cells_start_longest_first():
    """The pool starts NMPC and long cells first (only the order changes, never a result)."""
    items = [
        {'spec': {'strategy': 'baseline', 'duration_s': 600.0}},
        {'spec': {'strategy': 'ceco', 'duration_s': 300.0}},
        {'spec': {'strategy': 'baseline', 'duration_s': 1369.0}},
        {'spec': {'strategy': 'ceco-c', 'duration_s': 600.0, 'horizon_steps': 24}},
        {'spec': {'strategy': 'ceco', 'duration_s': None, 'scenario': {'duration_s': 765.0}}},
    ]
    costs = [sweep.backends.estimated_cost(i) for i in items]
    assert costs == [600.0, 900.0, 1369.0, 7200.0, 2295.0]
    assert sweep.backends._longest_first(items) == [items[3], items[4], items[2], items[1], items[0]]


def test_failed_cell_is_recorded_and_retried(tmp_path, monkeypatch):
    cell = sweep.expand_grid(sweep.load_grid(_grid(tmp_path)))[0]
    bad = {'id': cell.id, 'axes': cell.axes, 'spec': {**cell.spec, 'preview': 'foggy'}}
    row = sweep.run_cell(bad)
    assert row['status'] == 'error' and 'preview quality' in row['error']
    assert math.isnan(row['sim_time_s'])
    log = tmp_path / 'cells.jsonl'
    sweep.append_row(log, row)
    assert sweep.read_done(log) == {}  # errors are retried


@pytest.mark.extra('ray')
def test_ray_backend_matches_local(tmp_path):
    grid = _grid(
        tmp_path,
        GRID.replace('  mild: {t_amb_c: 28.0, solar_wm2: [400, 300], rh: 0.5, initial: {t_cab_c: 40.0}}\n', ''),
        duration=15,
    )
    ray_res = sweep.run_sweep(
        grid, tmp_path / 'ray', backend='ray', workers=2, progress=False, log=lambda *a, **k: None
    )
    assert ray_res['timing']['ran'] == 2 and ray_res['timing']['failed'] == 0
    local = sweep.run_sweep(grid, tmp_path / 'local', workers=1, progress=False, log=lambda *a, **k: None)
    by_axes = {r['strategy']: r for r in local['rows']}
    assert len(by_axes) == 2
    for r in ray_res['rows']:
        for key in ('E_tot_J', 'I_pmv', 'otc_violation_pct'):
            assert r[key] == by_axes[r['strategy']][key]


def _free_port():
    import socket

    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


@pytest.mark.extra('ray')
def test_ray_cluster_of_two_nodes_joined_by_address(tmp_path):
    """docs/analysis.md's multi-node recipe on this machine: a head started with ``ray start --head``,
    a second node (its own raylet) joined by ``ray start --address``, token authentication, then
    ``ceco sweep --backend ray --address``: every cell runs, on both nodes, with the results of the
    local in-process run."""
    import os
    import secrets
    import shutil
    import signal
    import subprocess
    import sys
    import tempfile
    import time

    ray_cli = shutil.which('ray')
    assert ray_cli, 'the ray command of the Ray extra'
    env = {
        **os.environ,
        'RAY_USAGE_STATS_ENABLED': '0',
        'RAY_AUTH_MODE': 'token',
        'RAY_AUTH_TOKEN': secrets.token_hex(32),
    }
    port = _free_port()
    ray_tmp = tempfile.mkdtemp(prefix='ceco_ray_', dir='/tmp')  # short: Ray's AF_UNIX socket paths (<= 107 bytes)
    common = ['--block', '--num-cpus', '1', '--temp-dir', ray_tmp, '--node-ip-address', '127.0.0.1']
    common += ['--disable-usage-stats']
    head_cmd = [ray_cli, 'start', '--head', '--port', str(port), '--include-dashboard', 'false']
    head_cmd += ['--dashboard-agent-listen-port', str(_free_port())]
    node_cmd = [ray_cli, 'start', '--address', f'127.0.0.1:{port}']
    node_cmd += ['--dashboard-agent-listen-port', str(_free_port())]
    procs = []
    try:
        for cmd in (head_cmd + common, node_cmd + common):
            log = open(tmp_path / f'ray_{len(procs)}.log', 'w')
            procs.append(subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True))
            deadline = time.monotonic() + 120
            while 'will now block forever' not in (tmp_path / f'ray_{len(procs) - 1}.log').read_text():
                assert procs[-1].poll() is None, (tmp_path / f'ray_{len(procs) - 1}.log').read_text()[-2000:]
                assert time.monotonic() < deadline, 'ray start did not come up in 120 s'
                time.sleep(0.5)
        grid = _grid(tmp_path, GRID.replace('[baseline, ceco]', '[baseline, ceco, ceco-ioch]'), duration=20)
        # the driver as a user runs it: `ceco sweep` in a shell that has the cluster's token
        cmd = [sys.executable, '-m', 'ceco_bringup.cli', 'sweep', str(grid), '--out', str(tmp_path / 'cluster')]
        cmd += ['--backend', 'ray', '--address', f'127.0.0.1:{port}', '--no-progress']
        run = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
        assert run.returncode == 0, run.stderr[-3000:]
        assert '6/6 cells done (6 run now, 0 failed)' in run.stdout + run.stderr
        rows = [json.loads(ln) for ln in (tmp_path / 'cluster' / 'cells.jsonl').read_text().splitlines()]
        assert len(rows) == 6 and all(r['status'] == 'ok' for r in rows)
        assert len({r['ray_node'] for r in rows}) == 2  # both nodes ran cells
        local = sweep.run_sweep(grid, tmp_path / 'local', workers=1, progress=False, log=lambda *a, **k: None)
        ref = {r['cell_id']: r for r in local['rows']}
        for r in rows:
            assert [repr(r[k]) for k in _RESULT_KEYS] == [repr(ref[r['cell_id']][k]) for k in _RESULT_KEYS]
    finally:
        for p in reversed(procs):  # the processes this test started (their own sessions), by id
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGTERM)
        for p in reversed(procs):
            try:
                p.wait(timeout=60)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait(timeout=10)
        shutil.rmtree(ray_tmp, ignore_errors=True)


@pytest.mark.extra('fastsim')
def test_verify_reruns_cells_exactly_and_vehicle_level(tmp_path):
    grid = _grid(tmp_path, GRID.replace('[baseline, ceco]', '[ceco-ioch]') + 'vehicle: true\n', duration=40)
    res = sweep.run_sweep(grid, tmp_path / 'out', workers=1, progress=False, log=lambda *a, **k: None)
    # Vehicle level per group: each strategy's mean A/C power over the group's cycle.
    assert len(res['vehicle']) == 2 * 2  # climates x vehicles
    p = {r['climate']: r['P_mean_w'] for r in res['rows']}
    assert all(v['p_ac_mean_w'] == p[v['climate']] for v in res['vehicle'])
    assert all(0.02 < v['distance_km'] < 0.1 for v in res['vehicle'])  # SC03 creeps from 19 s on
    assert len((tmp_path / 'out' / 'vehicle.csv').read_text().splitlines()) == 5
    checks = sweep.verify_cells(tmp_path / 'out', 5, grid)
    assert len(checks) == 2 and all(c['equal'] for c in checks), checks
    # A table value that differs from the rerun is reported.
    log = tmp_path / 'out' / 'cells.jsonl'
    rows = [json.loads(x) for x in log.read_text().splitlines()]
    rows[0]['E_tot_J'] *= 1.0 + 1e-12
    log.write_text(''.join(json.dumps(r) + '\n' for r in rows))
    checks = sweep.verify_cells(tmp_path / 'out', 5, grid)
    assert sorted(c['equal'] for c in checks) == [False, True]
    assert list(next(c for c in checks if not c['equal'])['differences']) == ['E_tot_J']


def test_code_fingerprint_is_part_of_the_id(tmp_path, monkeypatch):
    grid = sweep.load_grid(_grid(tmp_path))
    cells = sweep.expand_grid(grid)
    assert all(c.spec['code'] == sweep.code_fingerprint() for c in cells)
    monkeypatch.setattr(sweep.cells, 'code_fingerprint', lambda: '0' * 16)
    other = sweep.expand_grid(grid)
    assert not {c.id for c in other} & {c.id for c in cells}  # changed simulator: every cell reruns
    monkeypatch.undo()
    # A worker whose code differs from the driver's refuses to produce a result.
    row = sweep.run_cell({'id': other[0].id, 'axes': other[0].axes, 'spec': other[0].spec})
    assert row['status'] == 'error' and 'differs from the sweep' in row['error']


# ------------------------------------------------------------ settings axis
SETTINGS_GRID = """
name: gamma test grid
strategies: [baseline, ceco-c]
scenarios: [sc03_mild]
duration_s: 240
settings:
  g1k:  {ceco-c: {gamma_w: 1000}}
  g50k: {ceco-c: {gamma_w: 50000.0}}
"""


def test_settings_axis_expands_per_strategy_and_keeps_other_ids(tmp_path):
    cells = sweep.expand_grid(sweep.load_grid(_grid(tmp_path, SETTINGS_GRID)))
    # The baseline runs once (label "default"), ceco-c once per label naming it.
    assert [(c.axes['strategy'], c.axes['settings']) for c in cells] == [
        ('baseline', 'default'),
        ('ceco-c', 'g1k'),
        ('ceco-c', 'g50k'),
    ]
    assert cells[1].spec['strategy_overrides'] == {'gamma_w': 1000.0}  # int in YAML -> float field
    assert isinstance(cells[1].spec['strategy_overrides']['gamma_w'], float)
    assert 'strategy_overrides' not in cells[0].spec
    # The same grid without the axis gives the baseline the same id (old sweeps resume).
    plain = sweep.expand_grid(sweep.load_grid(_grid(tmp_path, SETTINGS_GRID.split('settings:')[0], name='p.yaml')))
    assert plain[0].id == cells[0].id and plain[1].axes['settings'] == 'default'
    assert plain[1].id not in {c.id for c in cells}
    # 1000 and 1000.0 are one cell; two labels with the same overrides are an error naming both.
    dup = SETTINGS_GRID + '  again: {ceco-c: {gamma_w: 1000.0}}\n'
    with pytest.raises(sweep.GridError, match=r"settings 'g1k' / 'again'"):
        sweep.expand_grid(sweep.load_grid(_grid(tmp_path, dup, name='d.yaml')))


@pytest.mark.parametrize(
    'entry, match',
    [
        ('g: {ceco-c: {gama_w: 1000.0}}', r'settings\.g\.ceco-c\.gama_w: unknown StrategySettings field'),
        ('g: {ceco-c: {gamma_w: -5.0}}', r'settings\.g\.ceco-c: StrategySettings\.gamma_w must be finite and >= 0'),
        ('g: {ceco-c: {gamma_w: "high"}}', r'settings\.g\.ceco-c\.gamma_w: must be of the type'),
        ('g: {ceco-c: {solver: {max_itr: 5}}}', r'settings\.g\.ceco-c\.solver\.max_itr: unknown SolverSettings field'),
        ('g: {ceco-c: {solver: {max_cpu_time_s: 9.0}}}', r'settings\.g\.ceco-c: .*max_cpu_time_s must be below'),
        (
            'g: {ceco-c: {horizon_steps: 12}}',
            r"settings\.g\.ceco-c\.horizon_steps: set by the grid key 'horizon_steps'",
        ),
        ('g: {ceco-ioch: {beta_w: 10.0}}', r"settings\.g\.ceco-ioch: strategy 'ceco-ioch' is not in the grid"),
        ('g: {baseline: {gamma_w: 1.0}}', r'settings\.g\.baseline: baseline has no StrategySettings'),
        ('default: {ceco-c: {gamma_w: 1.0}}', r"settings\.default: the label 'default' is reserved"),
    ],
)
def test_bad_settings_fail_before_any_run_naming_the_field(tmp_path, monkeypatch, entry, match):
    monkeypatch.setattr(sweep.cells, 'run_cell', lambda *a, **k: pytest.fail('a cell ran'))
    text = SETTINGS_GRID.split('settings:')[0] + 'settings:\n  ' + entry + '\n'
    with pytest.raises(ValueError, match=match):
        sweep.run_sweep(_grid(tmp_path, text), tmp_path / 'out', workers=1, progress=False, log=lambda *a, **k: None)
    assert not (tmp_path / 'out' / 'cells.jsonl').exists()


def test_settings_override_changes_ceco_c_and_equals_direct_run(tmp_path):
    res = sweep.run_sweep(
        _grid(tmp_path, SETTINGS_GRID), tmp_path / 'out', workers=1, progress=False, log=lambda *a, **k: None
    )
    assert res['timing']['ran'] == 3 and res['timing']['failed'] == 0
    by = {(r['strategy'], r['settings']): r for r in res['rows']}
    e1, e50 = by[('ceco-c', 'g1k')]['E_tot_J'], by[('ceco-c', 'g50k')]['E_tot_J']
    # A 50x comfort weight cools harder: > 5 % more energy in 240 s (measured +10.4 %; over the first 120 s
    # both weights run the pull-down at full cooling under the occupant-environment PMV), lower I_PMV.
    assert e50 > 1.05 * e1
    assert by[('ceco-c', 'g50k')]['I_pmv'] < by[('ceco-c', 'g1k')]['I_pmv']
    # The cell equals a direct simulate() with the same override, exactly.
    direct = simulate(
        'sc03_mild', 'ceco-c', SimSettings(duration_s=240.0, progress=False, strategy_overrides=(('gamma_w', 1000.0),))
    ).metrics
    for key in ('E_tot_J', 'I_pmv', 'otc_violation_pct', 'E_zone_J', 'I_pmv_zone'):
        assert by[('ceco-c', 'g1k')][key] == direct[key], key
    # Both labels are compared with the one baseline cell of the group.
    summ = {(r['strategy'], r['settings']): r for r in res['summary']}
    base = by[('baseline', 'default')]['E_tot_J']
    assert summ[('ceco-c', 'g50k')]['E_tot_kWh_change_pct'] == pytest.approx(100.0 * (e50 - base) / base, rel=1e-12)
    dom = {d['settings']: d for d in sweep.dominance_rows(res['summary'])}
    assert set(dom) == {'g1k', 'g50k'}
    for d in dom.values():
        assert d['dominates'] == (d['E_tot_kWh_change_pct'] < 0 and d['I_pmv_change_pct'] <= 0)
    text = (tmp_path / 'out' / 'summary.md').read_text()
    assert '| sc03_mild | scenario | scenario | perfect | scenario | ceco-c | g50k | 1 |' in text
    assert 'Pareto-dominating points' in text
    # Resume: nothing reruns.
    again = sweep.run_sweep(
        _grid(tmp_path, SETTINGS_GRID), tmp_path / 'out', workers=1, progress=False, log=lambda *a, **k: None
    )
    assert again['timing']['ran'] == 0 and len(again['rows']) == 3


def test_dominance_pairs_every_point_with_its_groups_one_baseline(tmp_path):
    def row(scenario, strategy, settings, e, i, ez, iz):
        return sweep_row(
            scenario,
            strategy,
            settings=settings,
            E_tot_kWh=e,
            I_pmv=i,
            E_zone_J=ez,
            I_pmv_zone=iz,
            otc_violation_pct=1.0,
            otc_violation_zone_pct=0.0,
        )

    rows = [
        row('a', 'baseline', 'default', 1.0, 100.0, 10.0, 10.0),
        row('a', 'ceco-c', 'lo', 0.9, 99.0, 11.0, 9.0),  # dominates over the run, not in the zone
        row('a', 'ceco-c', 'eq', 0.99, 100.0, 9.0, 10.0),  # equal I_PMV counts; zone too
        row('a', 'ceco-c', 'hi', 1.1, 90.0, 9.0, 11.0),  # costs energy
        row('b', 'baseline', 'default', 2.0, 50.0, 20.0, 5.0),
        row('b', 'ceco-c', 'lo', 1.9, 55.0, 19.0, 4.0),
    ]  # same label, other group: its own baseline
    summary = sweep.summarize(rows)
    dom = {(d['scenario'], d['settings']): d for d in sweep.dominance_rows(summary)}
    assert len(dom) == 4
    assert dom[('a', 'lo')]['E_tot_kWh_change_pct'] == pytest.approx(-10.0)
    assert dom[('a', 'lo')]['I_pmv_change_pct'] == pytest.approx(-1.0)
    assert [
        (dom[k]['dominates'], dom[k]['dominates_zone']) for k in [('a', 'lo'), ('a', 'eq'), ('a', 'hi'), ('b', 'lo')]
    ] == [(True, False), (True, True), (False, False), (False, True)]
    assert dom[('b', 'lo')]['I_pmv_zone_change_pct'] == pytest.approx(-20.0)
    import matplotlib.image as mpimg

    png = sweep.front_figure(summary, tmp_path / 'front.png')
    h, w = mpimg.imread(png).shape[:2]
    assert w > 1000 and h > 1000  # two groups x two phases at 200 dpi


def test_a_cell_with_its_own_model_file_equals_a_direct_run_with_it(tmp_path):
    """A cell's ``model_params_path`` (``tools/variant_headroom.py --model-params``) reaches the controller: the
    cell equals ``simulate`` with the same file, and a model whose COP falls 1.5 times faster with the lift (the
    COP at 30 K unchanged) moves the commands, where the package's file gives the default run."""
    import yaml

    from ceco_bringup.benchmark.cases import load_case
    from ceco_bringup.sweep import cells
    from ceco_controller.model import default_params_path

    doc = yaml.safe_load(default_params_path().read_text(encoding='utf-8'))
    c0, c1 = doc['params']['comp_c0'], doc['params']['comp_c1_per_k']
    doc['params']['comp_c1_per_k'] = 1.5 * c1
    doc['params']['comp_c0'] = c0 - 0.5 * c1 * 30.0
    path = tmp_path / 'steeper.yaml'
    path.write_text(yaml.safe_dump(doc), encoding='utf-8')
    scenario = load_case('mild-day').scenario_dict()  # sc03_mild
    spec = {'scenario': scenario, 'strategy': 'ceco-pmv', 'preview': 'perfect', 'duration_s': 120.0}
    assert cells.settings_from_spec(spec).model_params_path is None
    assert cells.settings_from_spec({**spec, 'model_params_path': str(path)}).model_params_path == str(path)
    settings = SimSettings(duration_s=120.0, progress=False)
    sc = scenario_from_dict(scenario)
    default = simulate(sc, 'ceco-pmv', settings).metrics
    steeper = simulate(sc, 'ceco-pmv', dataclasses.replace(settings, model_params_path=str(path))).metrics
    assert steeper['E_tot_J'] != default['E_tot_J']
    row = sweep.run_cell({'id': 'x', 'axes': {}, 'spec': {**spec, 'model_params_path': str(path)}})
    assert row['status'] == 'ok', row
    assert row['E_tot_J'] == steeper['E_tot_J']
    assert sweep.run_cell({'id': 'y', 'axes': {}, 'spec': spec})['E_tot_J'] == default['E_tot_J']


def test_the_study_tools_say_when_results_are_of_other_code(tmp_path, capsys):
    """``tools/variant_headroom.py`` and ``tools/edge_headroom.py`` score a rerun strategy against RESULTS' families
    and oracle: RESULTS written by this code reads without a note, by other code with one naming both fingerprints."""
    import pathlib
    import sys

    from ceco_bringup.sweep.cells import code_fingerprint

    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / 'tools'))
    import edge_headroom
    import variant_headroom

    assert edge_headroom.load_results is variant_headroom.load_results  # one reader for both tools
    here = code_fingerprint()
    same, other = tmp_path / 'same.json', tmp_path / 'other.json'
    same.write_text(json.dumps({'code_fingerprint': here, 'cases': []}), encoding='utf-8')
    other.write_text(json.dumps({'code_fingerprint': '0123456789abcdef', 'cases': [1]}), encoding='utf-8')
    assert variant_headroom.load_results(str(same)) == {'code_fingerprint': here, 'cases': []}
    assert capsys.readouterr().err == ''
    assert variant_headroom.load_results(str(other))['cases'] == [1]
    err = capsys.readouterr().err
    assert '0123456789abcdef' in err and here in err


def test_variant_headroom_routes_the_horizon_to_the_run_and_the_rest_to_the_settings():
    """``tools/variant_headroom.py --set``: ``horizon_steps`` and ``control_period_s`` become the cell's own (as a
    case's scenario sets them; as settings they clashed with the run's and raised a TypeError), every other name a
    StrategySettings override; the cell's spec is copied, not changed; a 10-s run of that cell succeeds, and an
    invalid value of each is refused by the run's own check (SimSettings) or the strategy's (StrategySettings)."""
    import pathlib
    import sys

    from ceco_bringup.benchmark import runner
    from ceco_bringup.benchmark.cases import load_case

    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / 'tools'))
    import variant_headroom

    cell = variant_headroom.strategy_cells(load_case('sc03-paper'), 'ceco-pmv')[0]
    before = json.dumps(cell.spec, sort_keys=True)
    spec = variant_headroom.variant_spec(cell.spec, {'horizon_steps': 12, 'backoff_init_pmv': 0.05}, '/m.yaml')
    assert json.dumps(cell.spec, sort_keys=True) == before
    assert (spec['horizon_steps'], spec['control_period_s'], spec['model_params_path']) == (12, None, '/m.yaml')
    assert dict(spec['strategy_overrides']) == {**dict(cell.spec['strategy_overrides']), 'backoff_init_pmv': 0.05}

    def run(overrides):
        spec = dict(variant_headroom.variant_spec(cell.spec, overrides), duration_s=10.0)
        return runner.run_benchmark_cell({'id': cell.id, 'axes': cell.axes, 'spec': spec})

    row = run({'horizon_steps': 12})
    assert row['status'] == 'ok', row.get('error')
    assert 'SimSettings.horizon_steps must be an int >= 1' in run({'horizon_steps': 0})['error']
    assert 'StrategySettings.backoff_init_pmv must be finite and >= 0' in run({'backoff_init_pmv': -1.0})['error']


def test_edge_headroom_co2_margin_reaches_the_bounds_and_is_checked(capsys):
    """``tools/edge_headroom.py --co2-margin-ppm``: the bounds' settings carry the margin (150 ppm, the CO2-holding
    door's) with the case's door logic and control period, the oracle's 10 ppm without it; a negative or non-finite
    margin is refused by the oracle's own check, by name, before any results file is read."""
    import pathlib
    import sys

    from ceco_bringup.benchmark.cases import load_case
    from ceco_controller.oracle import OracleSettings
    from ceco_core.co2_door import Co2DoorSettings

    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / 'tools'))
    import edge_headroom

    case = load_case('hot-commute-4p')
    door = Co2DoorSettings().margin_ppm
    st = edge_headroom.oracle_settings(case, door)
    assert st.co2_margin_ppm == door == 150.0
    assert st.door_logic == tuple(case.baseline_door) and st.door_logic and st.control_period_s == case.control_period_s
    assert edge_headroom.oracle_settings(case).co2_margin_ppm == OracleSettings().co2_margin_ppm == 10.0

    for bad in ('-5', 'nan', 'inf'):
        with pytest.raises(SystemExit) as e:
            edge_headroom.main(['no-such-results.json', 'hot-commute-4p', '--co2-margin-ppm', bad])
        assert e.value.code == 2
        err = capsys.readouterr().err
        assert '--co2-margin-ppm: OracleSettings.co2_margin_ppm: must be finite and >= 0' in err, err


def test_a_drive_cycle_axis_takes_a_cycle_of_a_fractional_length_as_the_loader_does(tmp_path):
    """A user cycle ending at 60.5 s: a scenario that names it runs 60 s (whole plant steps), and so does the grid's
    drive_cycles axis (it wrote the cycle's raw 60.5 s into the cell's scenario, which the loader then refused)."""
    (tmp_path / 'odd.csv').write_text('time_s,speed_mps\n0,0\n30,10\n60.5,10\n')
    text = 'strategies: [baseline]\nscenarios: [sc03]\ndrive_cycles: {odd: odd.csv}\n'
    (cell,) = sweep.expand_grid(sweep.load_grid(_grid(tmp_path, text)))
    assert cell.axes['drive_cycle'] == 'odd' and cell.spec['scenario']['duration_s'] == 60.0
    assert scenario_from_dict(cell.spec['scenario']).duration_s == 60.0
