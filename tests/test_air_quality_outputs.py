"""Every verb's outputs tell the truth about air quality with the benchmark's rule (docs/metrics.md, "Air quality").

A run of ``ceco sim`` keeps in its metrics.json the air-quality KPIs (``ceco_core.kpis.air_quality_kpis``) scored
against its scenario's limits; the job's tables and verdict show them, and a run that broke a limit is said to have
broken it and claims no saving (``ceco_core.kpis.breaks_air_quality``, the benchmark's rule); ``ceco report``
recomputes and checks them, and reads a run from before they were recorded without calling it a mismatch.
In-process, 90 s of SC03 with a CO2 limit the cabin starts above."""

import json

import pytest
from scenario_cases import write_stale_sc03

from ceco_bringup import outputs, report, rundata, sim
from ceco_bringup import verdict as vd
from ceco_core.air_quality import AirQualityLimits
from ceco_core.kpis import AIR_QUALITY_KEYS, air_quality_kpis
from ceco_core.rundir import read_csv_columns

DURATION_S = 90.0
LIMITS = AirQualityLimits(co2_limit_ppm=450.0, fog_margin_min_k=3.0)
"""The test scenario's limits: SC03's ambient CO2 (425 ppm) is below the limit, the cabin starts at 900 ppm."""


@pytest.fixture(scope='module')
def job(tmp_path_factory):
    """``ceco sim`` of baseline and ceco on SC03 with a 450-ppm CO2 limit, and a two-member family."""
    tmp = tmp_path_factory.mktemp('aq')
    path = write_stale_sc03(tmp, LIMITS.co2_limit_ppm)
    out = tmp / 'job'
    argv = ['--scenario', str(path), '--strategy', 'baseline,ceco', '--duration-s', str(DURATION_S)]
    assert sim.main([*argv, '--out', str(out), '--no-progress', '--baseline-setpoints-c', '25,26']) == 0
    return out


def test_metrics_json_holds_the_kpis_of_the_time_series(job):
    """Each run's metrics.json: the limits it was scored against and air_quality_kpis of its own time series."""
    for name in ('baseline', 'ceco'):
        m = json.loads((job / name / 'metrics.json').read_text())
        ts = read_csv_columns(job / name / 'timeseries.csv')
        want, _ = air_quality_kpis(ts['co2_cab_ppm'], ts['fog_margin_k'], 1.0, LIMITS)
        assert (m['co2_limit_ppm'], m['fog_margin_bound_k']) == (450.0, 3.0)
        assert {k: m[k] for k in AIR_QUALITY_KEYS} == pytest.approx(want, rel=1e-12)
        assert m['air_quality_met'] == 0.0 and m['co2_max_ppm'] > 450.0 and m['co2_above_limit_pct'] > 0.0


def test_tables_and_verdict_say_the_limit_was_broken_and_claim_no_saving(job):
    """summary.txt names each run that broke the limit and says it claims no saving; verdict.json records the
    limits, the numbers and the broken runs, and matches none of them; comparison.txt has the columns."""
    summary = (job / 'summary.txt').read_text()
    assert summary.count('BROKE the air-quality limits: CO2 max') == 2
    assert 'broken by baseline, ceco (not matched, no saving)' in summary
    assert 'saves' not in summary and 'Headline' not in summary
    v = json.loads((job / 'verdict.json').read_text())
    assert v['air_limits'] == {'co2_limit_ppm': 450.0, 'fog_margin_bound_k': 3.0}
    assert v['air_quality_broken'] == ['baseline', 'ceco'] and not v['matched']
    assert v['points']['ceco']['air_quality_met'] == 0.0 and v['points']['ceco']['co2_max_ppm'] > 450.0
    full = (job / 'comparison.txt').read_text()
    assert 'CO2 max [ppm]' in full and 'fog<bound [s]' in full and 'air quality met' in full


def test_a_broken_run_below_the_front_gets_no_saving_and_a_broken_member_makes_no_front():
    """The verdict's rule on points: a run that broke a limit saves nothing even below the front (it said "saves"),
    and a family member that broke one is on no front (the benchmark's ``fronts_of``)."""

    def point(d, e, met=1.0):
        p = dict(energy_kwh=e, discomfort_pmvh=d, time_to_comfort_s=None, pmv_end=0.6, duration_s=600.0)
        p.update(air_quality_met=met, co2_max_ppm=1600.0 if met == 0.0 else 800.0, co2_above_limit_pct=5.0)
        return dict(p, fog_below_bound_s=0.0, fog_margin_min_k=6.0)

    family = {f'baseline@{sp:.1f}': point(d, e) for sp, d, e in ((24, 0.10, 0.44), (26, 0.13, 0.37), (27, 0.17, 0.34))}
    limits = AirQualityLimits(1500.0, 3.0)
    points = {'ceco': point(0.11, 0.30, met=0.0), 'ceco-e': point(0.11, 0.38)}
    v = vd.build_verdict('sc03', points, family, air_limits=limits)
    assert 'ceco' not in v.matched and v.air_quality_broken == ['ceco']
    assert v.matched['ceco-e']['energy_saving_pct'] > 0.0
    text = '\n'.join(vd.verdict_lines(v))
    assert 'BROKE the air-quality limits: CO2 max 1600 ppm, above 1500 ppm 5.0 % of the time' in text
    assert 'Headline: ceco-e saves the most' in text
    # ceco-pmv lies between the 26 and 27 degC members; once the 27-degC member broke a limit it is left of no front
    warm = {'ceco-pmv': point(0.15, 0.36)}
    assert vd.build_verdict('sc03', warm, family).matched['ceco-pmv']['energy_saving_pct'] is not None
    family['baseline@27.0']['air_quality_met'] = 0.0
    v = vd.build_verdict('sc03', warm, family, air_limits=limits)
    assert v.matched['ceco-pmv']['energy_saving_pct'] is None
    assert '1 of the 3 runs broke the air-quality limits: on no front.' in '\n'.join(vd.verdict_lines(v))


def test_the_air_quality_line_does_not_say_co2_held_for_a_run_without_co2():
    """A run without a CO2 series (a bag from before it was recorded) is judged on its fog margin alone: the verdict's
    line says no CO2 was recorded for it (it said "every run held CO2 <= 1500 ppm (max n/a ppm)")."""
    base = dict(energy_kwh=0.4, discomfort_pmvh=0.1, time_to_comfort_s=None, pmv_end=0.6, duration_s=600.0)
    aq = dict(air_quality_met=1.0, co2_above_limit_pct=0.0, fog_below_bound_s=0.0, fog_margin_min_k=6.0)
    points = {'baseline': dict(base, **aq, co2_max_ppm=None), 'ceco': dict(base, **aq, co2_max_ppm=700.0)}

    def text() -> str:  # the verdict's lines, unwrapped (they are wrapped at 100 characters)
        lines = vd.verdict_lines(vd.build_verdict('sc03', points, {}, air_limits=AirQualityLimits(1500.0, 3.0)))
        return ' '.join(' '.join(lines).split())

    head = 'Air quality (CO2 <= 1500 ppm, fog margin >= 3 K): the runs held them'
    assert 'every run held' not in text()
    assert (
        f'{head} (CO2 max 700 ppm, fog margin min 6.0 K); no CO2 recorded for baseline (judged on the fog margin '
        'alone).'
    ) in text()
    points['ceco']['co2_max_ppm'] = None
    assert f'{head} (fog margin min 6.0 K); no CO2 recorded for baseline, ceco (judged on the fog margin alone).' in (
        text()
    )


def test_report_recomputes_and_checks_the_air_quality(job, tmp_path):
    """ceco report on the job: the recomputed air quality equals metrics.json (checked), and the report shows it;
    a changed co2_max_ppm is a mismatch; a metrics.json without the keys (an older run) loads with a note."""
    res = report.build_report([job], tmp_path / 'rep', log=lambda *a, **k: None)
    assert not res['mismatch']
    for r in res['runs']:
        for key in ('co2_limit_ppm', 'fog_margin_bound_k', *AIR_QUALITY_KEYS):
            assert r.recomputed[key] == pytest.approx(r.stored[key], rel=1e-12)
    md = res['markdown'].read_text()
    assert '| CO2 max [ppm] | CO2>limit [%] | fog<bound [s] | air quality met |' in md
    assert md.count('no: BROKE a limit') == 2 and 'broken by baseline, ceco (not matched, no saving)' in md
    run = job / 'ceco'
    stored = json.loads((run / 'metrics.json').read_text())
    tampered = tmp_path / 'tampered'
    (tampered).mkdir()
    (tampered / 'timeseries.csv').write_text((run / 'timeseries.csv').read_text())
    (tampered / 'metrics.json').write_text(json.dumps({**stored, 'co2_max_ppm': stored['co2_max_ppm'] - 100.0}))
    assert [k for k, _, _ in rundata.load_run(tampered).mismatches] == ['co2_max_ppm']
    old = {k: v for k, v in stored.items() if k not in ('co2_limit_ppm', 'fog_margin_bound_k', *AIR_QUALITY_KEYS)}
    (tampered / 'metrics.json').write_text(json.dumps(old))
    (tampered / 'scenario.yaml').write_text((run / 'scenario.yaml').read_text())
    loaded = rundata.load_run(tampered)
    assert not loaded.mismatches and loaded.recomputed['air_quality_met'] == 0.0
    assert any('metrics.json records no air quality' in n and 'not checked' in n for n in loaded.notes)


def test_the_run_line_says_a_run_broke_the_air_quality_limits(job):
    """Each run of the job broke the 450-ppm CO2 limit (its fog margin held): its line, printed and in its
    summary.txt, says so with its CO2 max and the limit, and names no fog margin (it said nothing)."""
    for name in ('baseline', 'ceco'):
        m = json.loads((job / name / 'metrics.json').read_text())
        line = (job / name / 'summary.txt').read_text().strip()
        assert m['fog_below_bound_s'] == 0.0 and m['co2_above_limit_pct'] > 0.0
        assert line.endswith(f"; BROKE air quality: CO2 max {m['co2_max_ppm']:.0f} ppm > 450 ppm -> {job / name}")


def test_the_run_line_names_the_limit_broken_and_is_unchanged_within_them():
    """A run within its limits, or whose air quality was not recorded, gets the line it always had (README's
    quoted lines); one that broke the fog bound, or both limits, names each with the run's number and the limit."""
    m = dict(strategy='ceco', E_comp_J=1.1e6, E_blower_J=1.3e5, E_fan_J=9.0e4, E_tot_J=1.32e6, otc_violation_pct=19.8)
    m['wall_time_s'] = 3.2
    plain = '      ceco: E 0.3667 kWh (comp 0.3056, blower 0.0361, fan 0.0250), viol. 19.8 %, wall 3.2 s -> runs/ceco'
    assert outputs.run_line(m, 'runs/ceco') == plain
    aq = dict(co2_limit_ppm=1500.0, fog_margin_bound_k=3.0, co2_max_ppm=1400.4, fog_margin_min_k=6.2)
    held = dict(m, **aq, co2_above_limit_pct=0.0, fog_below_bound_s=0.0, air_quality_met=1.0)
    assert outputs.run_line(held, 'runs/ceco') == plain
    unknown = dict(m, **aq, co2_above_limit_pct=None, fog_below_bound_s=None, air_quality_met=None)
    assert outputs.run_line(unknown, 'runs/ceco') == plain
    fog = dict(held, fog_margin_min_k=1.24, fog_below_bound_s=12.0, air_quality_met=0.0)
    assert outputs.run_line(fog, 'runs/ceco') == plain.replace(
        ' -> ', '; BROKE air quality: fog margin min 1.2 K < 3 K -> '
    )
    both = dict(fog, co2_max_ppm=1650.4, co2_above_limit_pct=4.0)
    assert outputs.run_line(both, 'runs/ceco') == plain.replace(
        ' -> ', '; BROKE air quality: CO2 max 1650 ppm > 1500 ppm, fog margin min 1.2 K < 3 K -> '
    )
