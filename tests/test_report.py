"""ceco report on run directories of the real closed-loop simulator (shortened
runs): metrics recomputed from a rosbag2 bag alone and from timeseries.csv
equal metrics.json, a tampered metrics.json is caught loudly, figures and the
self-contained HTML are written, solver statistics are right."""

import dataclasses
import json
import math
import re

import numpy as np
import pytest

from ceco_bringup import bagio, report
from ceco_controller.closed_loop import SimSettings, simulate, write_run

DURATION_S = 40.0
PNG_MAGIC = b'\x89PNG\r\n\x1a\n'


@pytest.fixture(scope='module')
def results():
    settings = SimSettings(duration_s=DURATION_S, progress=False)
    return {s: simulate('sc03', s, settings) for s in ('baseline', 'ceco-ioch')}


def _msg(store, typename, values, t_s):
    """A message of ``typename`` with the given field values; header stamped
    at ``t_s``; every other field zero/False."""
    cls = store.types[typename]
    header_cls = store.types['std_msgs/msg/Header']
    time_cls = store.types['builtin_interfaces/msg/Time']
    kw = {}
    for f in dataclasses.fields(cls):
        if f.name == 'header':
            sec = int(math.floor(t_s))
            kw['header'] = header_cls(stamp=time_cls(sec=sec, nanosec=int(round((t_s - sec) * 1e9))), frame_id='')
        elif f.name in values:
            kw[f.name] = values[f.name]
        else:
            kw[f.name] = False if f.type == 'bool' else (0 if f.type == 'int' else 0.0)
    return store.serialize_cdr(cls(**kw), typename)


def _write_bag(result, bag_dir):
    """Record a simulated run as the plant node does: state and comfort at
    t_n, power over [t_n, t_n + dt), one message each per plant step."""
    store = bagio.typestore()
    w = bagio.BagWriter(bag_dir)
    topics = {'cabin/state': 'ceco_msgs/msg/CabinState', 'cabin/comfort': 'ceco_msgs/msg/Comfort',
              'hvac/power': 'ceco_msgs/msg/AcPower'}
    for topic, typ in topics.items():
        w.add_topic(topic, typ)
    ts = result.timeseries
    for n in range(len(ts['t_s'])):
        t = float(ts['t_s'][n])
        row = {k: float(v[n]) for k, v in ts.items()}
        common = {'step_index': n, 'scenario_time_s': t}
        for topic, typ in topics.items():
            w.write(topic, int(t * 1e9) + 1, _msg(store, typ, {**row, **common}, t))
    w.close()


@pytest.fixture(scope='module')
def runs(tmp_path_factory, results):
    """A --strategy all parent: baseline with a bag, ceco-ioch with CSV only."""
    root = tmp_path_factory.mktemp('runs') / 'sc03_all'
    for s, r in results.items():
        write_run(r, root / s)
    _write_bag(results['baseline'], root / 'baseline' / 'bag')
    return root


def test_report_from_bag_and_csv(runs, results, tmp_path):
    out = tmp_path / 'rep'
    res = report.build_report([runs], out, log=lambda *a, **k: None)
    by = {r.strategy: r for r in res['runs']}
    assert set(by) == {'baseline', 'ceco-ioch'}
    assert by['baseline'].source == 'bag' and by['ceco-ioch'].source == 'timeseries.csv'
    assert not res['mismatch']
    # From the bag (float64 on the wire) the recomputation is exact.
    for key in ('E_tot_J', 'E_comp_J', 'E_blower_J', 'I_pmv', 'otc_violation_pct', 'pmv_max'):
        assert by['baseline'].recomputed[key] == results['baseline'].metrics[key], key
    assert by['baseline'].max_rel_diff == 0.0
    # From timeseries.csv: within the precision the file holds.
    digits = report.csv_precision_digits(runs / 'ceco-ioch' / 'timeseries.csv')
    assert by['ceco-ioch'].check_rtol == max(1e-6, 10.0 ** (1 - digits))
    assert by['ceco-ioch'].max_rel_diff <= by['ceco-ioch'].check_rtol
    assert len(by['ceco-ioch'].columns['t_s']) == int(DURATION_S)
    # Files: PNGs (PMV, temperatures, powers, inputs, bars, solver), HTML, Markdown, CSV.
    names = sorted(p.name for p in res['figures'])
    assert names == ['sc03_bars.png', 'sc03_inputs.png', 'sc03_pmv.png', 'sc03_powers.png', 'sc03_solver.png',
                     'sc03_temperatures.png']
    for p in res['figures']:
        data = p.read_bytes()
        assert data[:8] == PNG_MAGIC and len(data) > 20_000
    html = res['html'].read_text()
    assert html.count('src="data:image/png;base64,') == 6
    assert not re.search(r'(src|href)="(?!data:)', html)          # self-contained
    md = res['markdown'].read_text()
    assert '| baseline |' in md and '| ceco-ioch |' in md and 'figures/sc03_pmv.png' in md
    assert '-7.6 %' in md                                              # the paper's CECO-IOCH A/C saving
    lines = res['metrics_csv'].read_text().splitlines()
    assert len(lines) == 3


def test_tampered_metrics_are_reported_loudly(runs, tmp_path, capsys):
    bad = tmp_path / 'bad'
    import shutil
    shutil.copytree(runs / 'baseline', bad)
    m = json.loads((bad / 'metrics.json').read_text())
    m['E_tot_J'] *= 1.001
    (bad / 'metrics.json').write_text(json.dumps(m))
    rc = report.main([str(bad), '--out', str(tmp_path / 'rep')])
    assert rc == 1
    err = capsys.readouterr().err
    assert 'MISMATCH' in err and 'E_tot_J' in err
    assert 'WARNING: metrics of' in (tmp_path / 'rep' / 'report.html').read_text()


def test_discover_runs_rejects_a_non_run(tmp_path):
    with pytest.raises(ValueError, match='not a run directory'):
        report.discover_runs([tmp_path])
    assert report.main([str(tmp_path)]) == 2


def test_solver_stats_numbers():
    diag = {'k': np.arange(5.0), 'solve_time_ms': np.array([10.0, 20.0, np.nan, 30.0, 40.0]),
            'success': np.array([1.0, 1.0, np.nan, 0.0, 1.0]), 'iterations': np.array([5.0, 7.0, np.nan, 60.0, 9.0]),
            'fallback': np.array(['', 'shifted_plan', '', 'baseline', '']),
            'status': np.array(['Solve_Succeeded'] * 2 + ['baseline', 'Maximum_Iterations_Exceeded',
                                                          'Solve_Succeeded'])}
    s = report.solver_stats(diag)
    assert s['steps'] == 5 and s['solver_steps'] == 4
    assert s['solve_ms_median'] == 25.0 and s['solve_ms_max'] == 40.0
    assert s['success_pct'] == 75.0
    assert s['fallbacks'] == 2
    assert s['fallback_kinds'] == {'shifted_plan': 1, 'baseline': 1}
    assert report.fallback_mask(np.array([0.0, 1.0, np.nan])).tolist() == [False, True, False]
    assert s['iter_max'] == 60.0
    assert s['statuses'] == {'Solve_Succeeded': 3, 'baseline': 1, 'Maximum_Iterations_Exceeded': 1}
    assert math.isnan(report.solver_stats(None)['solve_ms_median'])


def test_csv_precision_digits(tmp_path):
    p = tmp_path / 'ts.csv'
    p.write_text('t_s,p_comp_w,p_blower_w,pmv\n0,1234.57,12.5,-0.0123457\n1,1e+03,0.5,1.5\n')
    assert report.csv_precision_digits(p) == 6
    p.write_text(f't_s,p_comp_w\n0,{2 / 3!r}\n')
    assert report.csv_precision_digits(p) == 16


@pytest.mark.extra('fastsim')
def test_report_vehicle_level(runs, tmp_path):
    from ceco_bringup import vehicle_energy as ve

    res = report.build_report([runs], tmp_path / 'rep', vehicle=True, log=lambda *a, **k: None,
                              vehicle_settings=ve.VehicleEnergySettings(fit_points=3))
    rows = res['vehicle_rows']['sc03']
    assert {(r['vehicle'], r['strategy']) for r in rows} == {
        (v, s) for v in (ve.PRIUS, ve.ZOE) for s in ('baseline', 'ceco-ioch')}
    by = {r['strategy']: r for r in rows if r['vehicle'] == ve.ZOE}
    m = {r.strategy: r.recomputed for r in res['runs']}
    # The A/C load is each run's mean A/C power, E_tot / T.
    assert by['ceco-ioch']['p_ac_mean_w'] == pytest.approx(m['ceco-ioch']['E_tot_J'] / DURATION_S, rel=1e-12)
    assert math.isfinite(by['ceco-ioch']['saving_fit_pct'])
    assert (tmp_path / 'rep' / 'figures' / 'sc03_vehicle.png').read_bytes()[:8] == PNG_MAGIC
    assert len((tmp_path / 'rep' / 'vehicle.csv').read_text().splitlines()) == 1 + 4
    assert 'Vehicle-level energy (FASTSim 3.1)' in res['markdown'].read_text()


def test_unreadable_bag_is_a_clear_error(runs, tmp_path, capsys):
    import shutil
    bad = tmp_path / 'run'
    shutil.copytree(runs / 'ceco-ioch', bad)
    (bad / 'bag').mkdir()
    (bad / 'bag' / 'metadata.yaml').write_text('not: a bag\n')
    assert report.main([str(bad), '--out', str(tmp_path / 'rep')]) == 2
    assert 'cannot read the bag' in capsys.readouterr().err
