"""`ceco benchmark` end to end on a short case: results.json, resume, report, validation, sensitivity."""

import json
import math

import pytest
import yaml

from ceco_bringup.benchmark import cli, runner
from ceco_bringup.benchmark import schema as bs
from ceco_bringup.benchmark.cases import CASE_SCHEMA

SETPOINTS = (25.0, 26.0, 27.0)


@pytest.fixture(scope='module')
def bench(tmp_path_factory):
    d = tmp_path_factory.mktemp('bench')
    case = d / 'short.yaml'
    case.write_text(yaml.safe_dump({'schema': CASE_SCHEMA, 'name': 'short', 'version': 1, 'scenario': 'sc03',
                                    'duration_s': 120, 'forecast_uncertainty': 'none', 'seeds': [0]}))
    sens = d / 'sens.yaml'
    sens.write_text(yaml.safe_dump({'schema': 'ceco-benchmark-sensitivity/1', 'case': 'short', 'parameters': [
        {'parameter': 'plant.c_int_jpk', 'target': 'plant', 'nominal': {'c_int_jpk': 90000.0},
         'low': {'c_int_jpk': 60000.0}, 'high': {'c_int_jpk': 120000.0}, 'source': 'test'}]}))
    kw = dict(workers=1, progress=False, log=lambda *a, **k: None, setpoints_c=SETPOINTS, sensitivity_path=sens)
    first = cli.run_benchmark([str(case)], d / 'out', **kw)
    second = cli.run_benchmark([str(case)], d / 'out', **kw)
    return d, first, second


def test_results_document(bench):
    d, doc, _ = bench
    assert bs.check_results(json.loads((d / 'out' / 'results.json').read_text())) == []
    (case,) = doc['cases']
    names = {r['controller'] for r in case['runs']}
    assert names == ({f'baseline@{s:.1f}' for s in SETPOINTS} | {f'baseline-allowance@{s:.1f}' for s in SETPOINTS}
                     | {'baseline-compensated', 'baseline-compensated-allowance', *runner.STRATEGY_NAMES})
    assert all(r['status'] == 'ok' and r['source'] == 'simulator' for r in case['runs'])
    assert {r['seed'] for r in case['runs'] if r['kind'] == 'strategy'} == {0}
    assert {r['seed'] for r in case['runs'] if r['kind'] != 'strategy'} == {None}
    assert sorted(p['controller'] for p in case['fronts']['plain']) == sorted(f'baseline@{s:.1f}' for s in SETPOINTS)
    assert set(case['matched']) == {'baseline-compensated', 'baseline-compensated-allowance', *runner.STRATEGY_NAMES}
    by = {r['controller']: r['kpis'] for r in case['runs']}
    # the allowance changes the baseline during the relaxed phase (the first 120 s are all relaxed)
    assert by['baseline-allowance@26.0']['energy_kwh'] < by['baseline@26.0']['energy_kwh']
    # a warmer set-point uses less energy
    assert by['baseline@27.0']['energy_kwh'] < by['baseline@26.0']['energy_kwh'] < by['baseline@25.0']['energy_kwh']
    # NMPC steps are timed, KPIs the comfort model does not provide yet are explained
    assert by['ceco']['time_ratio_mean'] > 0 and by['ceco']['fallback_steps'] == 0
    notes = next(r for r in case['runs'] if r['controller'] == 'ceco')['kpi_notes']
    assert all(by['ceco'][k] is None for k in notes)
    assert doc['settings']['setpoints_c'] == list(SETPOINTS) and not doc['quick']
    lines = (d / 'out' / 'kpis.csv').read_text().splitlines()
    assert len(lines) == 1 + len(case['runs'])


def test_resume_runs_nothing_and_gives_the_same_results(bench):
    _, first, second = bench
    assert first['timing']['ran_now'] == 36 and second['timing']['ran_now'] == 0      # 12 nominal + 2 x 12
    assert second['cases'][0]['matched'] == first['cases'][0]['matched']
    assert second['cases'][0]['sensitivity'] == first['cases'][0]['sensitivity']


def test_sensitivity_entries(bench):
    _, doc, _ = bench
    (s,) = doc['cases'][0]['sensitivity']
    assert s['parameter'] == 'plant.c_int_jpk' and (s['low'], s['nominal'], s['high']) == (60000.0, 90000.0, 120000.0)
    assert s['failed_low'] == s['failed_high'] == 0
    assert set(s['matched_low']) == set(doc['cases'][0]['matched'])
    assert s['matched_low'] != s['matched_high']                     # the interior's capacity matters


def test_report_files(bench):
    d, doc, _ = bench
    md = (d / 'out' / 'report.md').read_text()
    html = (d / 'out' / 'report.html').read_text()
    figs = sorted(p.name for p in (d / 'out' / 'figures').iterdir())
    assert figs == ['plane_short.png', 'tornado_short.png']
    assert html.count('data:image/png;base64,') == 2 and 'src="figures' not in html
    assert '## Savings at matched comfort' in md and '| short | ceco-c |' in md


def test_validate_command(bench, tmp_path, capsys):
    d, _, _ = bench
    assert cli.main(['--validate', str(d / 'out' / 'results.json')]) == 0
    doc = json.loads((d / 'out' / 'results.json').read_text())
    doc['cases'][0]['matched']['ceco']['energy_saving_pct'] = 99.0 if doc['cases'][0]['matched']['ceco'][
        'energy_saving_pct'] is None else -doc['cases'][0]['matched']['ceco']['energy_saving_pct'] - 1.0
    bad = tmp_path / 'bad.json'
    bad.write_text(json.dumps(doc))
    assert cli.main(['--validate', str(bad)]) == 1
    assert 'does not recompute' in capsys.readouterr().err


def test_baseline_constants_and_controllers():
    b = runner.load_baselines()
    assert b.tuned_on == 'sc03-paper' and b.allowance_k_per_pmv > 0 and len(b.sha) == 16
    specs = runner.controllers(b)
    assert [s.setpoint_c for s in specs if s.kind == 'baseline'] == [22.0 + 0.5 * i for i in range(15)]
    assert sum(s.seeded for s in specs) == 4 and len(specs) == 2 * 15 + 2 + 4
    allow = next(s for s in specs if s.name == 'baseline-allowance@26.0')
    assert dict(allow.overrides) == {'setpoint_c': 26.0, 'allowance_k_per_pmv': b.allowance_k_per_pmv}
    case_name, params = runner.load_sensitivity()
    assert case_name == 'sc03-paper' and all(p.low != p.high for p in params)
    assert not math.isnan(float(dict(next(s for s in specs if s.kind == 'compensated').overrides)['setpoint_c']))
