"""ceco sweep scores air quality with every verb's rule (docs/metrics.md, "Air quality"; docs/analysis.md).

Each cell's row holds the air quality its run was scored against its scenario's limits
(``ceco_core.kpis.run_air_quality``, as ``closed_loop.simulate`` writes it) and the flag
``ceco_core.kpis.breaks_air_quality``; the summary claims no saving for a point that broke the limits, nor
against a baseline that broke them. In-process (one worker), 20 s of SC03 twice: as it is (CO2 limit
1500 ppm) and with a 450-ppm limit the cabin starts above (900 ppm), as tests/test_air_quality_outputs.py."""

import csv
import json
import math

import pytest
from scenario_cases import write_stale_sc03
from sweep_helpers import sweep_row

from ceco_bringup import sweep
from ceco_controller.closed_loop import SimSettings, simulate
from ceco_core.kpis import AIR_LIMIT_KEYS, AIR_QUALITY_KEYS
from ceco_core.metrics import relative_change_pct
from ceco_v2x_preview.preview import parse_quality
from ceco_v2x_preview.scenario import scenario_from_dict

STALE = 'stale'
PLAIN = 'plain'


@pytest.fixture(scope='module')
def swept(tmp_path_factory):
    """``run_sweep`` of baseline and ceco on SC03 and on SC03 with a 450-ppm CO2 limit, 20 s, one worker."""
    tmp = tmp_path_factory.mktemp('sweep_aq')
    write_stale_sc03(tmp, 450.0)
    grid = tmp / 'grid.yaml'
    grid.write_text(
        f'name: aq\nstrategies: [baseline, ceco]\nscenarios: {{{STALE}: sc03_stale.yaml, {PLAIN}: sc03}}\n'
        'duration_s: 20\n'
    )
    out = tmp / 'out'
    res = sweep.run_sweep(grid, out, workers=1, progress=False, log=lambda *a, **k: None)
    assert res['timing']['ran'] == 4 and res['timing']['failed'] == 0
    return grid, out, res


def _by_point(rows):
    return {(r['scenario'], r['strategy']): r for r in rows}


def test_each_cell_records_its_air_quality_and_the_flag(swept):
    """results.csv and cells.jsonl: the limits, the KPIs of the cell's own run, and ``air_quality_broken`` True
    exactly for the cells of the 450-ppm scenario (both start at 900 ppm)."""
    grid, out, _ = swept
    with open(out / 'results.csv', newline='') as fh:
        table = _by_point(csv.DictReader(fh))
    assert set(table) == {(s, k) for s in (STALE, PLAIN) for k in ('baseline', 'ceco')}
    for (scenario, _), r in table.items():
        stale = scenario == STALE
        assert r['air_quality_broken'] == str(stale)
        assert float(r['air_quality_met']) == (0.0 if stale else 1.0)
        assert float(r['co2_limit_ppm']) == (450.0 if stale else 1500.0)
        assert float(r['fog_margin_bound_k']) == 3.0
        assert (float(r['co2_max_ppm']) >= 900.0) == stale and float(r['co2_above_limit_pct']) == (
            100.0 if stale else 0.0
        )
    # the row's air quality is the one its run computed (simulate's metrics), not a copy of the rule
    cells = {c.id: c for c in sweep.expand_grid(sweep.load_grid(grid))}
    cell = cells[table[(STALE, 'ceco')]['cell_id']]
    spec = cell.spec
    settings = SimSettings(
        preview_quality=parse_quality(spec['preview']), duration_s=spec['duration_s'], progress=False
    )
    direct = simulate(scenario_from_dict(spec['scenario']), 'ceco', settings).metrics
    for key in (*AIR_LIMIT_KEYS, *AIR_QUALITY_KEYS):
        assert float(table[(STALE, 'ceco')][key]) == direct[key], key
    logged = [json.loads(line) for line in (out / 'cells.jsonl').read_text().splitlines()]
    assert sorted((r['scenario'], r['air_quality_broken']) for r in logged) == [
        (PLAIN, False),
        (PLAIN, False),
        (STALE, True),
        (STALE, True),
    ]


def test_a_point_that_broke_the_limits_claims_no_saving(swept):
    """ceco's thermal result is the same on both scenarios (CO2 does not steer anything in 20 s); on SC03 it saves
    and dominates the baseline, on the 450-ppm copy it broke the limit: no change, no domination, said why, in
    summary.csv, the summary's rows, summary.md and the console."""
    grid, out, res = swept
    summ = _by_point(res['summary'])
    plain, stale = summ[(PLAIN, 'ceco')], summ[(STALE, 'ceco')]
    assert stale['E_tot_kWh_mean'] == pytest.approx(plain['E_tot_kWh_mean'], rel=1e-3)
    assert plain['E_tot_kWh_change_pct'] == pytest.approx(
        relative_change_pct(plain['E_tot_kWh_mean'], summ[(PLAIN, 'baseline')]['E_tot_kWh_mean'])
    )
    assert plain['E_tot_kWh_change_pct'] < -1.0 and plain['no_saving'] == '' and not plain['air_quality_broken']
    assert stale['air_quality_broken'] and stale['n_air_quality_broken'] == 1
    assert stale['no_saving'] == 'broke the air-quality limits (1 of 1 seeds)'
    assert stale['co2_limit_ppm_mean'] == 450.0 and stale['co2_max_ppm_mean'] > 900.0
    for key in sweep.CHANGE_KEYS:
        assert math.isnan(stale[f'{key}_change_pct']) and math.isfinite(plain[f'{key}_change_pct']), key
    dom = {d['scenario']: d for d in sweep.dominance_rows(res['summary'])}
    assert (dom[PLAIN]['dominates'], dom[PLAIN]['air_quality_broken']) == (True, False)
    assert (dom[STALE]['dominates'], dom[STALE]['dominates_zone'], dom[STALE]['air_quality_broken']) == (
        False,
        False,
        True,
    )
    with open(out / 'summary.csv', newline='') as fh:
        csv_rows = _by_point(csv.DictReader(fh))
    assert csv_rows[(STALE, 'ceco')]['E_tot_kWh_change_pct'] == 'nan'
    assert csv_rows[(STALE, 'ceco')]['air_quality_broken'] == 'True'
    assert csv_rows[(PLAIN, 'ceco')]['no_saving'] == '' and float(csv_rows[(PLAIN, 'ceco')]['E_tot_kWh_change_pct'])
    md = (out / 'summary.md').read_text()
    assert md.count('| BROKE 1/1 |') == 2 and md.count('| met |') == 2
    assert '| stale | scenario | scenario | perfect | scenario | ceco | default | 1 | 0.0216 | n/a |' in md
    assert '## Air quality: no saving claimed' in md
    assert (
        '- stale/scenario/scenario/perfect/scenario ceco: broke the air-quality limits (1 of 1 seeds); CO2 max 902 ppm '
        '(limit 450 ppm)'
    ) in md
    assert '- stale/scenario/scenario/perfect/scenario: whole run: none; zone phase: none' in md
    assert '- plain/scenario/scenario/perfect/scenario: whole run: ceco; zone phase: ceco' in md


def test_the_console_names_the_points_that_broke_the_limits(swept, capsys):
    """``ceco sweep`` (resuming the finished sweep: nothing runs) says which points broke the limits."""
    grid, out, _ = swept
    assert sweep.main([str(grid), '--out', str(out), '--no-progress']) == 0
    text = capsys.readouterr().out
    assert (
        'air quality: no saving claimed for 2 point(s) (it or its baseline broke the limits): '
        'stale/scenario/scenario/perfect/scenario '
        'baseline, stale/scenario/scenario/perfect/scenario ceco'
    ) in text


def _row(scenario, strategy, seed, e, i, met):
    r = sweep_row(
        scenario, strategy, seed=seed, E_tot_kWh=e, I_pmv=i, E_zone_J=1000.0 * e, I_pmv_zone=i, otc_violation_pct=0.0
    )
    if met is not None:  # None: a row of a log written before the sweep recorded air quality
        r.update(co2_limit_ppm=1500.0, fog_margin_bound_k=3.0, co2_max_ppm=1600.0 - 800.0 * met, air_quality_met=met)
    return r


def test_one_broken_seed_or_a_broken_baseline_claims_no_saving():
    """The rule on hand-made rows: one seed of two that broke is enough; a baseline that broke leaves the points
    of its group without a saving; rows without air quality (an older log) are not breaks."""
    rows = [
        _row('a', 'baseline', 0, 1.0, 100.0, 1.0),
        _row('a', 'baseline', 1, 1.0, 100.0, 1.0),
        _row('a', 'ceco', 0, 0.8, 90.0, 1.0),
        _row('a', 'ceco', 1, 0.8, 90.0, 0.0),
        _row('a', 'ceco-e', 0, 0.9, 95.0, 1.0),
        _row('a', 'ceco-e', 1, 0.9, 95.0, 1.0),
        _row('b', 'baseline', 0, 1.0, 100.0, 0.0),
        _row('b', 'ceco', 0, 0.8, 90.0, 1.0),
        _row('c', 'baseline', 0, 1.0, 100.0, None),
        _row('c', 'ceco', 0, 0.8, 90.0, None),
    ]
    s = _by_point(sweep.summarize(rows))
    assert (s[('a', 'ceco')]['n_air_quality_broken'], s[('a', 'ceco')]['air_quality_met_mean']) == (1, 0.5)
    assert s[('a', 'ceco')]['no_saving'] == 'broke the air-quality limits (1 of 2 seeds)'
    assert math.isnan(s[('a', 'ceco')]['E_tot_kWh_change_pct'])
    assert s[('a', 'ceco-e')]['E_tot_kWh_change_pct'] == pytest.approx(-10.0) and s[('a', 'ceco-e')]['no_saving'] == ''
    assert s[('b', 'ceco')]['no_saving'] == 'its baseline broke the air-quality limits'
    assert not s[('b', 'ceco')]['air_quality_broken'] and math.isnan(s[('b', 'ceco')]['I_pmv_change_pct'])
    assert s[('c', 'ceco')]['E_tot_kWh_change_pct'] == pytest.approx(-20.0) and not s[('c', 'ceco')]['no_saving']
    dom = {(d['scenario'], d['strategy']): d['dominates'] for d in sweep.dominance_rows(list(s.values()))}
    assert dom == {('a', 'ceco'): False, ('a', 'ceco-e'): True, ('b', 'ceco'): False, ('c', 'ceco'): True}
    timing = dict.fromkeys(('cells', 'ran', 'skipped', 'failed', 'workers'), 0)
    timing.update(backend='local', wall_s=1.0, cells_per_hour=0.0, sim_mean_s=0.0, sim_median_s=0.0)
    timing.update(cell_mean_s=0.0, cell_sum_s=0.0, speedup=0.0)
    md = sweep.summary.summary_markdown(list(s.values()), timing, 'hand-made')
    last = [line.rsplit('|', 2)[1].strip() for line in md.splitlines() if line.startswith('| ') and '---' not in line]
    assert last[1:] == ['met', 'BROKE 1/2', 'met', 'BROKE 1/1', 'met', 'n/a', 'n/a']  # [0]: the header
    assert '- b/scenario/scenario/perfect/scenario ceco: its baseline broke the air-quality limits;' in md
