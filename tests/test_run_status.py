"""A run whose controller did not control it is a failed run (issue 17 item 1), and a run's bag is
checked against what the stack sent (item 2): the pure rules, the simulator, `ceco sim` and the
benchmark's simulator path. The DDS paths are in tests/test_benchmark_external.py and
tests/test_stack_stall.py."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from ceco_bringup import arrival
from ceco_bringup.benchmark import cli, runner
from ceco_bringup.benchmark.cases import case_from_dict
from ceco_bringup.sweep.cells import code_fingerprint
from ceco_core.run_status import KEY_ON_FALLBACK_STEPS, MAX_FALLBACK_SHARE, check_control, fallback_control_steps

# an NMPC whose step deadline (5 us after the step starts: budget 10 us, reserve 5 us) has passed before its solver
# can start, on any machine: it falls back to the production law on every step. (A 2 ms budget, used until 4 Dec
# 2026, let 4 of 12 steps through on a machine whose solve takes 0.34 ms: a timing assumption, not a rule.)
STARVED_SOLVER = {'step_budget_s': 0.00001, 'step_reserve_s': 0.000005}


# ------------------------------------------------------------------ the rule
@pytest.mark.parametrize(
    'n, f, ok',
    [
        (120, 0, True),
        (120, 6, True),  # 5 %
        (120, 7, False),
        (120, 120, False),
        (6, 2, True),  # a 30-s real-time run: its key-on
        (20, 3, False),
        (4, 4, False),  # a 20-s run that never controlled
        (1, 1, False),  # a 5-s run whose one step was the fallback's: within the key-on allowance, never its own
        (2, 2, False),
        (2, 1, True),
        (1, 0, True),
        (0, 0, False),
    ],
)
def test_failed_above_the_documented_share(n, f, ok):
    c = check_control(n, f)
    assert MAX_FALLBACK_SHARE == 0.05 and KEY_ON_FALLBACK_STEPS == 2
    assert c.ok is ok and c.status == ('ok' if ok else 'failed')
    assert (c.reason == '') is ok
    if n and not ok:
        assert f'{f} of {n} control steps in fallback' in c.reason
        assert ('none was its own' in c.reason) is (f == n)  # a run that never controlled says so, not a share
    m = c.as_metrics()
    assert m['status'] == c.status and m['fallback_control_steps'] == f
    assert m['fallback_share'] == pytest.approx(f / n if n else 1.0)


@pytest.mark.parametrize(
    'n, f, share', [(-1, 0, 0.05), (10, 11, 0.05), (10, -1, 0.05), (10, 1, 1.5), (10, 1, float('nan'))]
)
def test_bad_counts_are_refused(n, f, share):
    with pytest.raises(ValueError):
        check_control(n, f, share)


def test_fallback_steps_count_control_steps_of_either_side():
    # 23 plant steps, 5 per control step -> 5 control steps (the last one short)
    plant = [False] * 23
    plant[6] = plant[7] = True  # the plant's law drove two plant steps of control step 1
    plant[22] = True  # ... and the last plant step (control step 4)
    assert fallback_control_steps(plant, 5) == (5, 2)
    # the controller's own fallback on steps 1 (already counted), 3, and a step beyond the run (ignored)
    assert fallback_control_steps(plant, 5, [1, 3, 9]) == (5, 3)
    assert fallback_control_steps([], 5) == (0, 0)
    with pytest.raises(ValueError):
        fallback_control_steps(plant, 0)


# ------------------------------------------------------------------ the arrival check
def test_arrival_names_every_missing_message():
    n, m = 20, 5
    full = {t: range(n) for t in arrival.PLANT_TOPICS} | {t: range(4) for t in arrival.PREVIEW_TOPICS}
    full['hvac/command'] = [0, 1, 2, 3, 2]  # a rejected duplicate of step 2 is harmless
    out = arrival.check_arrival(full, n, m, 'lockstep', [False] * n, clock_count=n)
    assert all(a.complete for a in out) and {a.topic for a in out} >= {'/clock', 'hvac/command'}
    lost = dict(full, **{'cabin/state': [i for i in range(n) if i not in (3, 4, 17)], 'v2x/weather_preview': [0, 1]})
    out = {a.topic: a for a in arrival.check_arrival(lost, n, m, 'lockstep', [False] * n, clock_count=12)}
    assert (out['cabin/state'].received, out['cabin/state'].expected, out['cabin/state'].missing) == (
        17,
        20,
        (3, 4, 17),
    )
    assert out['v2x/weather_preview'].missing == (2, 3) and out['/clock'].received == 12
    assert 'cabin/state 17/20 (missing steps 3, 4, 17)' in arrival.summary(list(out.values()))
    # control steps the plant's law drove need no command; the others do
    fb = [True] * 10 + [False] * 10
    out = {a.topic: a for a in arrival.check_arrival(dict(full, **{'hvac/command': [2]}), n, m, 'lockstep', fb)}
    assert (out['hvac/command'].expected, out['hvac/command'].missing) == (2, (3,))
    # real time: previews and commands follow timers; only the plant's outputs are counted
    rt = arrival.check_arrival({t: range(n) for t in arrival.PLANT_TOPICS}, n, m, 'realtime')
    assert {a.topic for a in rt} == set(arrival.PLANT_TOPICS) and all(a.complete for a in rt)


# ------------------------------------------------------------------ a run that stops at its start
def test_start_watch_says_stalled_once_the_plant_started_and_no_state_came():
    """Before the plant's start gate opens, waiting is right however long (the start-up timeout
    decides); from the plant's "starting at step 0", stall_s without a state is a stalled run."""
    from ceco_bringup.run import StartWatch

    w = StartWatch(stall_s=10.0)
    assert w.check(0.0, False, 1.0) == (False, None) and w.check(500.0, False, 3.0) == (False, None)
    assert w.started is None  # not started: no clock runs
    assert w.check(600.0, True, 4.0) == (False, None) and w.started == (600.0, 4.0)
    assert w.check(609.9, True, 4.5) == (False, 0.5)
    stalled, used = w.check(610.5, True, 4.01)
    assert stalled and used == pytest.approx(0.01)
    assert StartWatch(5.0).check(1.0, True, None) == (False, None)
    w = StartWatch(5.0)
    w.check(1.0, True, None)
    assert w.check(7.0, True, 2.0) == (True, None)  # no CPU reading at the start: none since


def test_stalled_message_at_the_start_names_the_plants_start_and_its_cpu(tmp_path):
    from ceco_bringup import supervisor
    from ceco_bringup.run import stalled_message
    from ceco_plant_sim.plant_io import STARTED

    plant = supervisor.NodeProcess('plant_node', 'ceco_plant_sim', 'plant_node', env={}, log_dir=tmp_path)
    plant.log_path.write_text(
        f'[INFO] [1.0] [plant_node]: waiting for subscribers\n[INFO] [2.0] [plant_node]: {STARTED}\n'
    )
    text = stalled_message(10.0, 0, 60, {'plant_node': plant}, 0.0)
    assert text.startswith('stalled: no new plant step for 10 s of wall clock at plant step 0/60; ')
    assert 'the plant logged that it started step 0, and no state of it reached the recorder' in text
    assert 'plant_node used 0.00 s of CPU in those 10 s (stopped, or starved of CPU' in text
    plant.log_path.write_text('[INFO] [1.0] [plant_node]: waiting for subscribers\n')  # mid-run wording otherwise
    assert 'the plant made no progress' in stalled_message(10.0, 0, 60, {'plant_node': plant}, 3.0)


# ------------------------------------------------------------------ the simulator and `ceco sim`
def test_ceco_sim_fails_a_strategy_that_never_controls(tmp_path):
    cfg = tmp_path / 'starved.yaml'
    # the baseline keeps its law (acc_law: defaults), the NMPC gets the starved solver
    # fixed-point numbers: YAML 1.1 reads '1e-05' as text
    cfg.write_text(
        'acc_law: {}\ncommon:\n  solver:\n' + ''.join(f'    {k}: {v:.6f}\n' for k, v in STARVED_SOLVER.items())
    )
    out = tmp_path / 'sim'
    p = subprocess.run(
        [sys.executable, '-m', 'ceco_bringup.cli', 'sim', '--scenario', 'sc03', '--strategy', 'baseline,ceco-ioch']
        + ['--duration-s', '60', '--controller-config', str(cfg), '--baseline-setpoints-c', '25,26,27']
        + ['--out', str(out), '--no-progress'],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert p.returncode == 1, p.stdout + p.stderr
    failed = json.loads((out / 'ceco-ioch' / 'metrics.json').read_text())
    assert failed['status'] == 'failed' and failed['fallback_control_steps'] == 12 == failed['n_control_steps']
    assert failed['n_fallback_baseline'] == 12  # every step was the production law
    run = json.loads((out / 'ceco-ioch' / 'run.json').read_text())
    assert run['status'] == 'failed' and 'did not control the run: 12 of 12' in run['error']
    assert run['strategy'] == 'ceco-ioch'  # (a run that failed before any data is named by it: ceco report)
    ok = json.loads((out / 'baseline' / 'metrics.json').read_text())
    assert ok['status'] == 'ok' and ok['fallback_control_steps'] == 0
    # the failed run shows no number: its line says FAILED, it is in no table and not in the verdict
    line = next(x for x in p.stdout.splitlines() if x.strip().startswith('ceco-ioch:'))
    assert 'FAILED: the controller did not control the run: 12 of 12' in line and 'kWh' not in line
    assert '1 of 2 runs failed (not compared):' in p.stdout
    csv_rows = (out / 'comparison.csv').read_text().splitlines()
    assert [r.split(',')[0] for r in csv_rows[1:]] == ['baseline']
    verdict = json.loads((out / 'verdict.json').read_text())
    assert set(verdict['points']) == {'baseline'} and 'ceco-ioch' not in verdict['matched']
    # ... but it is named there, with why (no number)
    assert (
        list(verdict['failed']) == ['ceco-ioch']
        and 'did not control the run: 12 of 12' in verdict['failed']['ceco-ioch']
    )
    assert '1 of 2 runs failed' in (out / 'summary.txt').read_text()


# ------------------------------------------------------------------ the benchmark (simulator path)
def test_benchmark_keeps_a_failed_strategy_out_of_the_matched_results(tmp_path):
    case = case_from_dict(
        {
            'schema': 'ceco-benchmark-case/1',
            'name': 'mild-60s',
            'version': 1,
            'scenario': 'sc03_mild',
            'duration_s': 60,
            'forecast_uncertainty': 'none',
            'seeds': [0],
        }
    )
    baselines = runner.load_baselines()
    specs = [s for s in runner.controllers(baselines, (25.0, 27.0, 29.0), ('ceco',)) if s.kind != 'compensated']
    specs.append(runner.ControllerSpec('ceco-starved', 'strategy', 'ceco', (('solver', STARVED_SOLVER),)))
    cells = runner.case_cells(case, specs, code_fingerprint())
    rows = [runner.run_benchmark_cell({'id': c.id, 'axes': c.axes, 'spec': c.spec}) for c in cells]
    by = {r['controller']: r for r in rows}
    starved, good = by['ceco-starved'], by['ceco']
    assert good['status'] == 'ok' and good['kpis']['fallback_steps'] == 0.0
    assert starved['status'] == 'failed' and 'did not control the run: 12 of 12' in starved['error']
    assert starved['kpis']['fallback_steps'] == 12.0 and starved['kpis']['energy_kwh'] > 0.0  # KPIs kept
    doc_case = runner.assemble_case(case, rows)
    run = next(r for r in doc_case['runs'] if r['controller'] == 'ceco-starved')
    assert run['status'] == 'failed' and run['kpis']['energy_kwh'] == starved['kpis']['energy_kwh']
    assert 'ceco' in doc_case['matched'] and 'ceco-starved' not in doc_case['matched']
    # (a whole results document with a failed run validates: tests/test_benchmark_schema.py)
    assert all(p['controller'] != 'ceco-starved' for fam in doc_case['fronts'].values() for p in fam)
    doc = {'cases': [doc_case]}
    lines = cli.summary_lines(doc)
    assert not any('ceco-starved' in line and 'energy saved' in line for line in lines)
    assert any('ceco-starved' in line and 'seed 0: FAILED: the controller did not control' in line for line in lines)
