"""What a newcomer reads (issue 18, issue 17 items 7-8): the verdict with the saving at matched
comfort, one energy definition and one sign convention, console tables of at most 100 characters
with one unit per quantity, the same flags with their defaults in every verb, one-line user errors
with exit status 2, run directories that keep what made them, `ceco identify` never over a tracked
file. Pure and in-process (the simulator); the DDS side is in test_stack.py."""

import json
import subprocess
import sys

import numpy as np
import pytest
import yaml

from ceco_bringup import cli, cli_args, outputs, play, provenance, sim
from ceco_bringup import verdict as vd
from ceco_bringup.benchmark import front
from ceco_controller.closed_loop import SimSettings, simulate
from ceco_core.kpis import compute_kpis
from ceco_core.metrics import J_PER_KWH
from ceco_v2x_preview.scenario import load_scenario

SHORT_S = 60.0
SC03_LIMITS = load_scenario('sc03').air_quality.limits
"""The air-quality limits of SC03 (a family member is scored against its scenario's)."""


def _point(d, e, **kw):
    p = dict(energy_kwh=e, discomfort_pmvh=d, time_to_comfort_s=None, pmv_end=0.6, duration_s=600.0)
    p.update(kw)
    return p


FAMILY = {  # a convex front: 24 degC (cold, costly) .. 27 degC (warm, cheap)
    'baseline@24.0': _point(0.10, 0.44),
    'baseline@25.0': _point(0.11, 0.40),
    'baseline@26.0': _point(0.13, 0.37),
    'baseline@27.0': _point(0.17, 0.34),
}


# ---------------------------------------------------------------------------------------- formatting
FORMATTED = [  # (value, format, what every output prints): report_html.fmt_value, the one fixed-format formatter
    (0.36624, '.4f', '0.3662'),
    (12.46, '+.1f', '+12.5'),
    (np.float64(682.4), '.0f', '682'),
    (1500.0, 'g', '1500'),
    (None, '.1f', 'n/a'),  # not defined / not recorded
    (float('nan'), '.3f', 'n/a'),
    (float('inf'), '.0f', 'n/a'),
    (True, 's', 'yes'),
    (False, 's', 'no'),
    ('ceco-pmv', 's', 'ceco-pmv'),
]


@pytest.mark.parametrize('value, spec, text', FORMATTED)
def test_one_formatter_for_the_tables_and_the_verdict(value, spec, text):
    """The console and full tables (outputs) and the verdict's words format through report_html.fmt_value."""
    from ceco_bringup.report_html import fmt_value

    assert fmt_value(value, spec) == text
    row = {'strategy': 'x', 'otc_violation_pct': value}
    if not isinstance(value, (bool, str)):
        assert outputs.full_table([row]).splitlines()[2].split()[13] == fmt_value(value, '.1f')
        assert outputs.console_table([row]).splitlines()[2].split()[5] == fmt_value(value, '.1f')  # viol. [%]
        # the verdict's words: a run that broke the limits, with this value as its CO2 maximum
        words = vd._broke_words(_point(0.1, 0.3, co2_max_ppm=value), {'co2_limit_ppm': 450.0})
        assert words.startswith(f"BROKE the air-quality limits: CO2 max {fmt_value(value, '.0f')} ppm, above 450 ppm")


def test_the_broken_limits_words_say_n_a_for_what_was_not_recorded():
    """A run that broke the fog bound without a CO2 series: the verdict says n/a where there is no number."""
    p = _point(0.1, 0.3, co2_max_ppm=None, co2_above_limit_pct=None, fog_below_bound_s=12.0)
    words = vd._broke_words(p, {'co2_limit_ppm': 1500.0, 'fog_margin_bound_k': 3.0})
    assert words.startswith('BROKE the air-quality limits: CO2 max n/a ppm, above 1500 ppm n/a % of the time;')
    assert 'fog margin below 3 K 12 s: not matched, no saving' in words


# ---------------------------------------------------------------------------------------- verdict
def test_verdict_states_the_saving_at_matched_comfort_in_words():
    """The verdict reads each strategy against the family's front at its own discomfort: a point
    below the front saves (positive), one above it uses more (and is dominated), one more
    comfortable than every set-point gets no number but the reason; the baseline that never
    reached the band says so; a partial run is shown, never matched; the headline names the best."""
    points = {
        'baseline': _point(0.13, 0.37),  # on the front: the family's 26 degC member
        'ceco': _point(0.11, 0.38),  # front at D = 0.11: 0.40 -> saves 5.0 %
        'ceco-e': _point(0.12, 0.40),  # front at 0.12: 0.385 -> uses 3.9 % more, dominated
        # left of the front, in the band from 300 s on
        'ceco-c': _point(0.09, 0.45, time_to_comfort_s=300.0, pmv_end=0.1, pmv_out_after_comfort_s=0.0),
        'ceco-ioch': _point(0.12, 0.36),
    }
    v = vd.build_verdict('sc03', points, FAMILY, partial={'ceco-ioch': 'interrupted: 28 of 600 s'})
    assert v.matched['ceco']['energy_saving_pct'] == pytest.approx(5.0)
    assert v.matched['ceco-e']['energy_saving_pct'] == pytest.approx(100 * (0.385 - 0.40) / 0.385)
    assert v.matched['ceco-e']['dominated'] and not v.matched['ceco']['dominated']
    assert v.matched['ceco-c']['energy_saving_pct'] is None and 'ceco-ioch' not in v.matched
    assert v.changes['ceco']['energy_change_pct'] == pytest.approx(100 * (0.38 - 0.37) / 0.37)  # signed as measured
    lines = vd.verdict_lines(v)
    text = '\n'.join(lines)
    assert max(len(line) for line in lines) <= outputs.CONSOLE_WIDTH
    assert 'saves 5.0 % energy at matched comfort' in text
    assert 'uses 3.9 % more energy at matched comfort (dominated by a set-point)' in text
    assert 'more comfortable than every set-point: no matched value' in text
    # better on both axes than every set-point: said, not a bare 'no matched value' (the best outcome read as none)
    best = vd.build_verdict('sc03', {'ceco': _point(0.09, 0.30)}, FAMILY)
    said = ' '.join(' '.join(vd.verdict_lines(best)).split())
    assert 'more comfortable than every set-point and less energy than each: it dominates the family' in said
    assert 'never stayed in -0.5..+0.5 (PMV +0.60 over the last minute)' in text
    assert 'in -0.5..+0.5 from 300 s on' in text
    assert 'partial run (interrupted: 28 of 600 s): not compared' in text
    assert 'Headline: ceco saves the most energy at matched comfort, 5.0 %.' in text
    assert 'compressor + blower + condenser fan' in lines[0]
    assert 'a comparison at different comfort, not a saving' in text
    # without a family: a pointer to the command that computes it, never a number
    bare = '\n'.join(vd.verdict_lines(vd.build_verdict('sc03', points), pointer='run `ceco benchmark`'))
    assert 'Matched comfort: not computed for these runs; run `ceco benchmark`' in bare and 'saves' not in bare


def test_verdict_within_the_fronts_resolution_is_no_saving():
    """A point less than RESOLUTION_PCT below the front is 'the same energy', and the headline
    says no strategy saves 1 % or more (the 0.5-K front is linear between set-points)."""
    points = {'ceco': _point(0.11, 0.40 * (1 - 0.004))}
    text = '\n'.join(vd.verdict_lines(vd.build_verdict('sc03', points, FAMILY)))
    assert 'same energy as the set-point family at matched comfort (+0.4 %, under 1 %)' in text
    assert 'Headline: no strategy saves 1 % or more at matched comfort (best: ceco, +0.4 %).' in text


def test_less_energy_with_lost_comfort_is_not_called_a_saving():
    """A cloudy 35 degC scenario of one's own: ceco used 26.2 % less energy than the baseline run and
    lost comfort (+224 %); the table said `dE_tot_kWh % -26.2`, `dI_pmv % +224.1` and a reader saw a
    26 % saving. Now the change is signed as measured with its meaning, and the matched-comfort line
    says the point is less comfortable than every set-point (no saving is claimed)."""
    points = {'baseline': _point(0.05, 0.30), 'ceco': _point(0.05 * 3.24, 0.30 * (1 - 0.262))}
    fam = {
        'baseline@25.0': _point(0.04, 0.33),
        'baseline@26.0': _point(0.05, 0.30),
        'baseline@27.0': _point(0.08, 0.27),
    }
    v = vd.build_verdict('cloudy35', points, fam)
    text = '\n'.join(vd.verdict_lines(v))
    assert 'Against the baseline run alone the energy changes by -26.2 % and the discomfort' in text
    assert 'by +224.0 % (+ = more): a comparison at different comfort, not a saving.' in text
    assert 'less comfortable than every set-point: no matched value' in text
    assert 'Headline' not in text and 'saves' not in text


def test_verdict_json_round_trip(tmp_path):
    v = vd.build_verdict('sc03', {'ceco': _point(0.11, 0.38)}, FAMILY)
    data = vd.read_verdict(vd.write_verdict(tmp_path / 'verdict.json', v))
    assert data['matched']['ceco']['energy_saving_pct'] == pytest.approx(5.0)
    assert data['energy'] == 'compressor + blower + condenser fan' and data['family'] == FAMILY
    (tmp_path / 'other.json').write_text('{"schema": "x"}')
    with pytest.raises(ValueError, match='not a ceco-verdict/2 file'):
        vd.read_verdict(tmp_path / 'other.json')
    old = json.loads((tmp_path / 'verdict.json').read_text())
    (tmp_path / 'v1.json').write_text(json.dumps(dict(old, schema='ceco-verdict/1')))
    assert vd.read_verdict(tmp_path / 'v1.json')['family'] == FAMILY  # an older job's file still reads


def test_verdict_reads_each_run_against_the_stronger_law_and_names_the_production_number():
    """With the production and the tuned law in the family, a strategy is read against the law that
    spends least at its discomfort (the envelope), and the production law's number stands beside it:
    a saving against the sluggish production gains alone is not the headline."""
    tuned = {  # the tuned law: 4 % less energy than the production law at every set-point
        n.replace('baseline@', 'baseline-tuned@'): dict(p, energy_kwh=0.96 * p['energy_kwh']) for n, p in FAMILY.items()
    }
    points = {'baseline': _point(0.13, 0.37), 'ceco': _point(0.11, 0.38)}
    v = vd.build_verdict('sc03', points, {**FAMILY, **tuned})
    assert v.matched['ceco']['energy_saving_pct'] == pytest.approx(100 * (0.96 * 0.40 - 0.38) / (0.96 * 0.40))
    assert v.matched_by_law['baseline']['ceco']['energy_saving_pct'] == pytest.approx(5.0)
    assert v.matched_by_law['baseline-tuned']['ceco'] == v.matched['ceco']
    # the production law at 26 degC is above the tuned law's front: it is not "on the front"
    assert v.matched['baseline']['energy_saving_pct'] == pytest.approx(100 * (0.96 * 0.37 - 0.37) / (0.96 * 0.37))
    lines = vd.verdict_lines(v)
    text = ' '.join(line.strip() for line in lines)
    assert max(len(line) for line in lines) <= outputs.CONSOLE_WIDTH
    assert 'same energy as the set-point family at matched comfort (+1.0 %' not in text
    assert 'saves 1.0 % energy at matched comfort; +5.0 % against the production law alone' in text
    assert 'against the production law (gains 0.25 1/K, 120 s) and the tuned law (gains 0.5 1/K, 60 s)' in text
    assert 'at each discomfort the law that spends least' in text
    assert 'Headline: ceco saves the most energy at matched comfort, 1.0 %.' in text


def test_family_runs_the_tuned_law_with_its_frozen_gains():
    """run_family's tuned law is the production law with the benchmark's frozen gains: the same
    pull-down, then a different comfort-phase trajectory (300 s of SC03 at 25 degC)."""
    from ceco_bringup.benchmark import runner

    fam = vd.run_family('sc03', duration_s=300.0, setpoints_c=(25.0,), progress=False)
    assert sorted(fam) == ['baseline-tuned@25.0', 'baseline@25.0']
    gains = runner.load_baselines().families['tuned'][0]
    settings = SimSettings(
        duration_s=300.0, progress=False, strategy_overrides=tuple(sorted({**gains, 'setpoint_c': 25.0}.items()))
    )
    direct = vd.run_point(simulate('sc03', 'baseline', settings).timeseries, SC03_LIMITS)
    assert fam['baseline-tuned@25.0'] == direct
    e_prod, e_tuned = fam['baseline@25.0']['energy_kwh'], fam['baseline-tuned@25.0']['energy_kwh']
    assert abs(e_tuned - e_prod) > 1e-3 * e_prod


def test_a_strategy_that_moves_the_door_is_read_against_the_laws_with_that_door():
    """Same permissions: ``ceco-pmv-aq`` (it moves the recirculation door) is matched against the production and the
    tuned law with the CO2-holding door, ``ceco-pmv`` against the laws without it, whatever else the job ran; the
    words say so. Against the door-less laws ceco-pmv-aq's 20 % less energy would have read as a 20 % saving. A
    family kept without door laws gives it no matched value rather than that."""
    tuned = {
        n.replace('baseline@', 'baseline-tuned@'): dict(p, energy_kwh=0.96 * p['energy_kwh']) for n, p in FAMILY.items()
    }
    door = {  # the same laws with the door: 20 % less energy at every set-point
        n.replace('@', '-doorco2@'): dict(p, energy_kwh=0.8 * p['energy_kwh']) for n, p in {**FAMILY, **tuned}.items()
    }
    assert sorted({vd.family_law(n) for n in door}) == sorted(vd.DOOR_FAMILY_LAWS)
    assert vd.family_laws_for(['baseline', 'ceco-pmv']) == vd.FAMILY_LAWS
    assert vd.family_laws_for(['ceco-pmv', 'ceco-pmv-aq']) == vd.FAMILY_LAWS + vd.DOOR_FAMILY_LAWS
    assert [vd.moves_door(n) for n in ('baseline', 'ceco-pmv', 'ceco-pmv-aq', 'ceco-pmv-door')] == [0, 0, 1, 1]
    points = {'ceco-pmv': _point(0.11, 0.38), 'ceco-pmv-aq': _point(0.11, 0.304)}
    v = vd.build_verdict('sc03', points, {**FAMILY, **tuned, **door})
    plain_ref, door_ref = 0.96 * 0.40, 0.8 * 0.96 * 0.40
    assert v.matched['ceco-pmv']['energy_saving_pct'] == pytest.approx(100 * (plain_ref - 0.38) / plain_ref)
    assert v.matched['ceco-pmv-aq']['energy_saving_pct'] == pytest.approx(100 * (door_ref - 0.304) / door_ref)
    assert v.matched_by_law['baseline-doorco2']['ceco-pmv-aq']['energy_saving_pct'] == pytest.approx(5.0)
    assert 'ceco-pmv-aq' not in v.matched_by_law['baseline'] and 'ceco-pmv' not in v.matched_by_law['baseline-doorco2']
    text = ' '.join(line.strip() for line in vd.verdict_lines(v))
    assert 'saves 1.0 % energy at matched comfort; +5.0 % against the production law alone (the laws with the' in text
    assert 'A strategy that moves the recirculation door against the same laws with the CO2-holding door' in text
    assert '(28 runs' not in text and '(16 runs, in-process simulator)' in text
    old = vd.build_verdict('sc03', points, {**FAMILY, **tuned})  # a family kept from a job without door laws
    assert 'ceco-pmv-aq' not in old.matched and old.matched['ceco-pmv'] == v.matched['ceco-pmv']
    assert 'no matched value: the family has no law with the door it moves' in ' '.join(vd.verdict_lines(old))


def test_family_runs_the_door_laws_with_the_co2_holding_door():
    """run_family's door laws are the production and the tuned law with ``door_mode: co2_hold``: the same run as the
    baseline strategy with those overrides, and a door that moves (the door-less law leaves it at the plant's 0.8)
    for less energy (300 s of SC03 at 25 degC)."""
    from ceco_bringup.benchmark import runner

    fam = vd.run_family(
        'sc03', duration_s=300.0, setpoints_c=(25.0,), laws=vd.FAMILY_LAWS + vd.DOOR_FAMILY_LAWS, progress=False
    )
    assert sorted(fam) == [
        'baseline-doorco2@25.0',
        'baseline-tuned-doorco2@25.0',
        'baseline-tuned@25.0',
        'baseline@25.0',
    ]
    gains = runner.load_baselines().families['tuned'][0]
    over = {**gains, 'setpoint_c': 25.0, 'door_mode': 'co2_hold'}
    ts = simulate(
        'sc03',
        'baseline',
        SimSettings(duration_s=300.0, progress=False, strategy_overrides=tuple(sorted(over.items()))),
    ).timeseries
    assert fam['baseline-tuned-doorco2@25.0'] == vd.run_point(ts, SC03_LIMITS)
    assert np.any(ts['recirc_share_cmd'] != 0.8)
    for law in ('baseline', 'baseline-tuned'):
        assert fam[f'{law}-doorco2@25.0']['energy_kwh'] < fam[f'{law}@25.0']['energy_kwh']


# ---------------------------------------------------------------------------------------- energy and signs
@pytest.fixture(scope='module')
def short_runs():
    s = SimSettings(duration_s=SHORT_S, progress=False)
    return {name: simulate('sc03', name, s) for name in ('baseline', 'ceco-e')}


def test_one_energy_definition_in_metrics_and_kpis(short_runs):
    """E_tot of metrics.json (run, sim, report) is compressor + blower + condenser fan, the same number
    as the benchmark's energy_kwh; the parts are beside it."""
    for res in short_runs.values():
        ts, m = res.timeseries, res.metrics
        parts = [float(np.sum(ts[c])) for c in ('p_comp_w', 'p_blower_w', 'p_cond_fan_w')]  # dt = 1 s
        assert parts[2] > 0.0  # the fan runs while the compressor does
        assert m['E_tot_J'] == pytest.approx(sum(parts), rel=1e-12)
        assert (m['E_comp_J'], m['E_blower_J'], m['E_fan_J']) == pytest.approx(parts, rel=1e-12)
        kpis, _ = compute_kpis(ts)
        assert m['E_tot_J'] / J_PER_KWH == pytest.approx(kpis['energy_kwh'], rel=1e-12)


def test_console_table_width_units_signs_and_validity_labels(short_runs):
    """The console table: at most 100 characters, energy only in kWh, 'change' signed as measured
    (+ = more) and 'saving' positive for less energy, PMV beyond +3 shown as '>3' with the share
    outside ISO 7730 beside it; the full table explains the draught rating of the vent jets."""
    cols = {k: r.timeseries for k, r in short_runs.items()}
    metrics = {k: r.metrics for k, r in short_runs.items()}
    kpis = {k: compute_kpis(c)[0] for k, c in cols.items()}
    fam = {n: vd.run_point(cols['baseline']) for n in ('baseline@26.0',)}
    fam['baseline@27.0'] = dict(fam['baseline@26.0'], energy_kwh=0.5 * kpis['baseline']['energy_kwh'])
    fam['baseline@27.0']['discomfort_pmvh'] = 2.0 * fam['baseline@26.0']['discomfort_pmvh']
    # a more comfortable, costlier member: ceco-e (a little more comfortable than the baseline) inside the front
    fam['baseline@25.0'] = dict(fam['baseline@26.0'], energy_kwh=2.0 * kpis['baseline']['energy_kwh'])
    fam['baseline@25.0']['discomfort_pmvh'] = 0.5 * fam['baseline@26.0']['discomfort_pmvh']
    v = vd.build_verdict('sc03', {k: vd.run_point(c) for k, c in cols.items()}, fam)
    rows = outputs.table_rows(metrics, kpis, v)
    text = outputs.console_table(rows)
    lines = text.splitlines()
    assert max(len(line) for line in lines) <= outputs.CONSOLE_WIDTH
    assert lines[0].split('  ')[0].strip() == 'strategy' and 'E [kWh]' in lines[0]
    assert ' kJ' not in text and '[J]' not in text and 'E_tot_kWh %' not in text
    by = {r['strategy']: r for r in rows}
    e_base, e_ceco = kpis['baseline']['energy_kwh'], kpis['ceco-e']['energy_kwh']
    assert by['ceco-e']['energy_change_pct'] == pytest.approx(100 * (e_ceco - e_base) / e_base)
    cells = lines[3].split()
    assert cells[0] == 'ceco-e' and float(cells[2]) == pytest.approx(by['ceco-e']['energy_change_pct'], abs=0.05)
    # ceco-e uses less energy than the baseline at a little better comfort: 'change' negative, 'saving' positive and
    # larger (the front costs more at better comfort), printed with its sign
    saving = by['ceco-e']['energy_saving_matched_pct']
    assert saving > -by['ceco-e']['energy_change_pct'] > 0.0
    assert cells[2] == f"{by['ceco-e']['energy_change_pct']:+.1f}" and cells[4] == f'{saving:+.1f}'
    assert kpis['ceco-e']['discomfort_pmvh'] < fam['baseline@26.0']['discomfort_pmvh']
    assert metrics['ceco-e']['pmv_max'] > 3.0 and cells[7] == '>3'  # the hot pull-down, clipped where printed
    assert float(cells[8]) == pytest.approx(kpis['ceco-e']['iso7730_invalid_pct'], abs=0.05) and float(cells[8]) > 50
    assert 'ISO out: samples outside ISO 7730' in text and 'saving: energy' in text
    full = outputs.full_table(rows)
    assert 'DR>20% [%]' in full and 'a statement about the jet, not a vote' in full
    assert 'PMV max (raw)' in full


@pytest.mark.extra('fastsim')
def test_vehicle_rows_say_change_not_saving():
    """The vehicle-level columns are changes (negative = less energy), never a 'saving' with the
    opposite sign (report/vehicle.csv had saving_fit_pct = +4.38 for a strategy using more)."""
    from ceco_bringup import vehicle_energy as ve

    t, v = ve.drive_cycle_for_run('sc03', 120.0)
    rows = ve.vehicle_energy_table(
        {'baseline': 1000.0, 'ceco': 1500.0}, t, v, ve.VehicleEnergySettings(vehicles=(ve.ZOE,))
    )
    by = {r['strategy']: r for r in rows}
    assert not any('saving' in k for k in by['ceco'])
    assert by['ceco']['change_fit_pct'] > 0.0 and by['baseline']['change_fit_pct'] == 0.0


# ---------------------------------------------------------------------------------------- the sim verb
def test_sim_job_prints_the_verdict_and_keeps_what_made_it(tmp_path, capsys):
    """`ceco sim` (now in ceco_bringup) runs the strategies, then the baseline family, prints the
    table and the verdict (every line at most 100 characters) and keeps them; each run directory
    holds the scenario file, the command line and the code fingerprint."""
    out = tmp_path / 'job'
    argv = ['--strategy', 'baseline,ceco-e', '--duration-s', '60', '--baseline-setpoints-c', '25,26,27']
    argv += ['--out', str(out), '--no-progress']
    assert cli.main(['sim', *argv]) == 0
    text = capsys.readouterr().out
    flat = ' '.join(line.strip() for line in text.splitlines())  # the verdict's lines wrap at 100 characters
    assert 'Verdict on sc03 (60 s).' in text and 'Matched comfort: against the production law (gains' in flat
    assert 'and the tuned law (gains 0.5 1/K, 60 s) at 25-27 degC (6 runs' in flat
    table = text[text.index('strategy  ') : text.index('Verdict on')].splitlines()
    assert max(len(line) for line in table) <= outputs.CONSOLE_WIDTH
    v = json.loads((out / 'verdict.json').read_text())
    sps = ['@25.0', '@26.0', '@27.0']
    assert sorted(v['family']) == sorted([f'baseline{s}' for s in sps] + [f'baseline-tuned{s}' for s in sps])
    # the family member at 26 degC is the job's baseline run, in the same process: the same point
    assert v['family']['baseline@26.0']['energy_kwh'] == v['points']['baseline']['energy_kwh']
    # the matched saving is front.match against the kept family's envelope (one computation)
    laws = {
        law: front.build_front(
            {n: (p['discomfort_pmvh'], p['energy_kwh']) for n, p in v['family'].items() if n.startswith(law + '@')}
        )
        for law in ('baseline', 'baseline-tuned')
    }
    p = v['points']['ceco-e']
    env = front.Envelope.of(laws)
    assert v['matched']['ceco-e'] == front.match(env, p['discomfort_pmvh'], p['energy_kwh']).as_dict()
    f = laws['baseline']
    assert v['matched_by_law']['baseline']['ceco-e'] == front.match(f, p['discomfort_pmvh'], p['energy_kwh']).as_dict()
    csv_rows = (out / 'comparison.csv').read_text().splitlines()
    assert csv_rows[0].startswith('strategy,energy_kwh,') and len(csv_rows) == 3
    assert (out / 'summary.txt').read_text().count('Verdict on sc03') == 1
    assert 'DR>20%' in (out / 'comparison.txt').read_text()
    # the band applies from 300 s on SC03: a 60-s run has no band phase, so its seconds above +0.5 are empty
    assert csv_rows[0].split(',').index('pmv_above_band_s') > csv_rows[0].split(',').index('pmv_mean_band')
    assert all(r.split(',')[csv_rows[0].split(',').index('pmv_above_band_s')] == '' for r in csv_rows[1:])
    for s in ('baseline', 'ceco-e'):
        run = provenance.read_run(out / s)
        assert run['status'] == 'complete' and run['command'] == 'ceco sim ' + ' '.join(argv)
        assert len(run['code_fingerprint']) == 16 and run['scenario'] == 'sc03'
        bundled = provenance.resources.files('ceco_v2x_preview').joinpath('data', 'scenarios', 'sc03.yaml')
        assert (out / s / 'scenario.yaml').read_text() == bundled.read_text()  # the file, verbatim
        assert (out / s / 'summary.txt').read_text().startswith(f'{s:>10}: E ')


def _cli(*args):
    return subprocess.run(
        [sys.executable, '-m', 'ceco_bringup.cli', *args], capture_output=True, text=True, timeout=120
    )


def test_scenario_typo_is_one_line_in_every_verb(tmp_path):
    """A typo in a scenario file: `ceco sim` as `ceco run`, one line naming the field, exit status
    2, no traceback (sim gave a 20-line traceback)."""
    bad = tmp_path / 'mine.yaml'
    text = provenance.copy_scenario('sc03', tmp_path / 'copy').read_text()
    bad.write_text(text.replace('duration_s:', 'duraton_s:', 1))
    for verb in ('sim', 'run'):
        p = _cli(verb, '--scenario', str(bad), '--out', str(tmp_path / verb))
        assert p.returncode == 2, (verb, p.stderr)
        assert 'Traceback' not in p.stderr and len(p.stderr.strip().splitlines()) == 1, (verb, p.stderr)
        assert p.stderr.startswith(f'ceco {verb}: error: ') and 'duraton_s' in p.stderr, p.stderr


# ---------------------------------------------------------------------------------------- flags
BAD_NUMBERS = [
    ('run', '--control-period-s', '0'),
    ('run', '--horizon-steps', '0'),
    ('run', '--duration-s', 'nan'),
    ('run', '--duration-s', 'inf'),
    ('run', '--duration-s', '900'),  # beyond SC03's 600 s: refused, never clamped
    ('run', '--run-timeout-s', '-1'),
    ('run', '--command-timeout-s', '0'),
    ('run', '--startup-timeout-s', 'nan'),
    ('run', '--baseline-setpoints-c', '26'),
    ('sim', '--duration-s', 'nan'),
    ('sim', '--control-period-s', '-5'),
    ('sim', '--horizon', '0'),  # the old name is checked as the new one
    ('play', '--rate', '-1'),
    ('play', '--tol', 'nan'),
    ('play', '--step-timeout-s', '0'),
    ('report', '--rtol', 'inf'),
    ('benchmark', '--workers', '0'),
    ('sweep', '--workers', '-2'),
    ('sweep', '--verify', '-1'),
    ('oracle', '--duration-s', 'nan'),
    ('oracle', '--max-wall-time-s', '0'),
    ('oracle', '--levels', '0.1,nan'),
    ('identify', '--control-period-s', '0'),
    ('identify', '--horizon-steps', '-1'),
    ('identify', '--ts', 'nan'),  # the old name is checked as the new one
    ('bench', '--duration-s', 'nan'),
    ('bench', '--horizons', '6,0'),
    ('bench', '--cpu-slowdown', '0'),
    ('bench', '--slowdown-factors', '1,-10'),
    # the nodes' ranges, checked by every verb before anything runs (Ts 1e5 s hung `ceco sim` building its NLP,
    # Np 100 failed `ceco run` only once its nodes had started)
    ('sim', '--control-period-s', '100000'),
    ('run', '--horizon-steps', '100'),
    ('identify', '--horizon-steps', '61'),
    ('run', '--seed', '-1'),  # was run with seed -1 and exit 0
    ('play', '--domain-id', '999'),  # was a Fast DDS port error, exit 1
    ('sim', '--baseline-setpoints-c', '24,24'),  # one set-point twice is one set-point
]


@pytest.mark.parametrize('verb, flag, value', BAD_NUMBERS)
def test_bad_numbers_are_one_line_and_exit_2(verb, flag, value, tmp_path, capsys):
    """Issue 17 item 7: each bad number is one clear line naming the flag and what it accepts, exit
    status 2, before anything runs (--control-period-s 0 fell back to the scenario's, --duration-s
    nan was a traceback, inf and --run-timeout-s -1 were accepted)."""
    first = {
        'play': [str(tmp_path)],
        'report': [str(tmp_path)],
        'sweep': ['grid.yaml'],
        'oracle': ['sc03-paper'],
        'bench': ['nmpc'],
    }.get(verb, [])
    rest = [] if verb in ('play', 'report', 'bench') else ['--out', str(tmp_path / 'out')]
    with pytest.raises(SystemExit) as exc:
        cli.main([verb, *first, flag, value, *rest])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f'ceco {verb}: error: '), err
    assert flag in err[0] and ('must be' in err[0] or 'need' in err[0] or 'exceeds' in err[0]), err
    assert not (tmp_path / 'out').exists()


SHARED = {
    '--scenario': ('run', 'sim', 'play', 'report'),
    '--strategy': ('run', 'sim', 'play', 'report', 'bench'),
    '--out': ('run', 'sim', 'report', 'benchmark', 'sweep', 'oracle'),
    '--preview': ('run', 'sim'),
    '--control-period-s': ('run', 'sim', 'play', 'oracle', 'identify'),
    '--horizon-steps': ('run', 'sim', 'play', 'identify'),
    '--duration-s': ('run', 'sim', 'oracle', 'bench'),
    '--seed': ('run', 'sim'),
    '--workers': ('benchmark', 'sweep'),
    '--backend': ('benchmark', 'sweep'),
    '--namespace': ('run', 'play', 'report'),
    '--domain-id': ('run', 'play'),
    '--no-progress': ('run', 'sim', 'play', 'benchmark', 'sweep', 'oracle', 'bench'),
    '--baseline-setpoints-c': ('run', 'sim'),
}


def _parser(verb):
    from ceco_bringup import oracle_cli, report, run
    from ceco_bringup.benchmark import cli as bcli
    from ceco_bringup.sweep import cli as scli
    from ceco_controller import bench, identification

    builders = {
        'identify': identification,
        'bench': bench,
        'run': run,
        'sim': sim,
        'play': play,
        'report': report,
        'benchmark': bcli,
        'sweep': scli,
        'oracle': oracle_cli,
    }
    return builders[verb].build_parser()


def test_the_same_flag_names_in_every_verb():
    """The same setting has the same flag, type, default, choices and arity in every verb that has it (run and sim
    named them --preview/--horizon-steps/--control-period-s/--duration-s against --preview-quality/--horizon/
    --control-period/--duration). Defaults that differ by verb on purpose are listed with the reason."""
    actions = {}
    for flag, verbs in SHARED.items():
        for verb in verbs:
            parser = _parser(verb)
            opts = {o: a for a in parser._actions for o in a.option_strings}
            assert flag in opts, (verb, flag)
            actions.setdefault(flag, []).append((verb, opts[flag]))
    n_compared = 0
    for flag, acts in actions.items():
        if flag in ('--strategy', '--out', '--scenario'):  # defaults differ by verb, the name and meaning do not
            continue
        # --namespace: run's '' is "no namespace" (the stack it starts), play's and report's None is "the only one
        # in the bag" (the stack they read): the default differs, the type does not
        default = (lambda a: None) if flag == '--namespace' else (lambda a: repr(a.default))
        kinds = {(a.type, default(a), tuple(a.choices or ()), a.nargs, type(a)) for _, a in acts}
        assert len(kinds) == 1, (flag, kinds)
        n_compared += len(acts) > 1
    assert n_compared == len(SHARED) - 3


def test_old_flag_names_work_with_a_deprecation_line(tmp_path, capsys):
    """--horizon, --control-period, --duration, --preview-quality still parse for one release, into the
    new settings, each with one line saying which name to use."""
    old = sim.build_parser().parse_args(
        ['--out', 'x', '--horizon', '8', '--control-period', '4', '--duration', '30', '--preview-quality', 'noisy']
    )
    new = sim.build_parser().parse_args(
        ['--out', 'x', '--horizon-steps', '8', '--control-period-s', '4', '--duration-s', '30', '--preview', 'noisy']
    )
    assert vars(old) == vars(new)
    err = capsys.readouterr().err
    for o, n in cli_args.DEPRECATED_FLAGS.items():
        assert f'ceco sim: {o} is deprecated and goes in the next release: use {n}' in err


@pytest.mark.parametrize('verb', ['run', 'sim', 'play', 'report', 'benchmark', 'sweep'])
def test_help_shows_the_defaults(verb, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main([verb, '--help'])
    assert exc.value.code == 0
    text = ' '.join(capsys.readouterr().out.split())
    expected = {
        'run': ['(default: sc03; not with --case)', '(default: ceco-ioch)', '(default: 1800.0)', '(default: lockstep)'],
        'sim': [
            '(default: sc03; not with --case)',
            '(default: baseline,ceco,ceco-e,ceco-c,ceco-ioch,ceco-pmv)',
            "(default: perfect; with --case the case's)",
        ],
        'play': ['(default: 1.0)', '(default: 30.0)'],
        'report': ['(default: 1e-06)'],
        'benchmark': ['(default: local)'],
        'sweep': ['(default: local)'],
    }[verb]
    for e in expected:
        assert e in text, (verb, e)


def test_play_points_at_the_bag_of_a_run_directory(tmp_path, capsys):
    """`ceco play runs/sc03/ceco` (the run directory) says where its bag is, exit status 2."""
    (tmp_path / 'ceco' / 'bag').mkdir(parents=True)
    (tmp_path / 'ceco' / 'bag' / 'metadata.yaml').write_text('rosbag2_bagfile_information: {}\n')
    with pytest.raises(SystemExit) as exc:
        cli.main(['play', str(tmp_path / 'ceco')])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and f'its bag is {tmp_path / "ceco" / "bag"}' in err
    with pytest.raises(SystemExit):
        cli.main(['play', str(tmp_path)])
    assert f'give one bag, e.g. {tmp_path / "ceco" / "bag"}' in capsys.readouterr().err


def test_play_compares_the_door_as_well():
    """``ceco play --compare``'s door difference: both not commanded (NaN) agree, one commanded and one not differ
    beyond any tolerance, two shares by their distance."""
    nan = float('nan')
    assert play.door_difference(nan, nan) == 0.0
    assert play.door_difference(nan, 0.5) == play.door_difference(1.0, nan) == float('inf')
    assert play.door_difference(0.2, 0.5) == pytest.approx(0.3, abs=1e-15)


# ---------------------------------------------------------------------------------------- run directories
def test_scenario_copy_is_loadable_with_its_drive_cycle(tmp_path):
    """A user scenario naming its drive cycle by a relative CSV path: the copy in the run directory
    loads to the same scenario after the originals are gone."""
    from ceco_v2x_preview.scenario import load_scenario

    src = tmp_path / 'src'
    src.mkdir()
    data = yaml.safe_load(provenance.copy_scenario('sc03', tmp_path / 'a').read_text())
    cyc = load_scenario('sc03').drive_cycle
    (src / 'cyc.csv').write_text(
        'time_s,speed_mps\n' + ''.join(f'{t:g},{float(v)!r}\n' for t, v in zip(cyc.time_s, cyc.speed_mps))
    )
    data.update(name='mine', drive_cycle='cyc.csv')
    (src / 'mine.yaml').write_text(yaml.safe_dump(data))
    before = load_scenario(src / 'mine.yaml')
    copy = provenance.copy_scenario(src / 'mine.yaml', tmp_path / 'run')
    for f in src.iterdir():
        f.unlink()
    after = load_scenario(copy)
    assert after.name == 'mine' and after.duration_s == before.duration_s
    assert np.array_equal(after.drive_cycle.speed_mps, before.drive_cycle.speed_mps)


def test_scenario_hash_is_of_what_the_scenario_says_with_its_drive_cycle(tmp_path):
    """run.json's scenario_sha256 (``ceco report`` refuses runs of one name with different hashes): one CSV-cycle
    scenario started from two directories has one hash (the copies' headers name their sources, and the bytes'
    hash differed); a comment or a reordered key changes nothing; an edited CSV under the same YAML, or an edited
    YAML, is another scenario (the YAML's bytes alone missed the CSV)."""
    data = yaml.safe_load(provenance.copy_scenario('sc03', tmp_path / 'a').read_text())
    data.update(name='mine', drive_cycle='cyc.csv')
    sources = []
    for where in ('one', 'two'):
        src = tmp_path / where
        src.mkdir()
        (src / 'cyc.csv').write_text('time_s,speed_mps\n0,0\n30,10\n60,10\n')
        (src / 'mine.yaml').write_text(yaml.safe_dump(data, sort_keys=where == 'one'))
        sources.append(src / 'mine.yaml')
    (tmp_path / 'two' / 'mine.yaml').write_text('# my copy\n' + (tmp_path / 'two' / 'mine.yaml').read_text())
    start = lambda src, run: provenance.start_run(tmp_path / run, 'sim', [], str(src))['scenario_sha256']  # noqa: E731
    h1, h2 = start(sources[0], 'r1'), start(sources[1], 'r2')
    assert (tmp_path / 'r1' / 'scenario.yaml').read_bytes() != (tmp_path / 'r2' / 'scenario.yaml').read_bytes()
    assert h1 == h2 and len(h1) == 16
    (tmp_path / 'two' / 'cyc.csv').write_text('time_s,speed_mps\n0,0\n30,12\n60,10\n')
    assert start(sources[1], 'r3') != h1  # the CSV edited
    (tmp_path / 'one' / 'mine.yaml').write_text(yaml.safe_dump(dict(data, duration_s=50)))
    assert start(sources[0], 'r4') != h1  # the YAML edited
    assert start('sc03', 'r5') == provenance.scenario_sha256(tmp_path / 'a' / 'scenario.yaml')  # a bundled name


def test_identify_writes_a_new_run_directory_never_over_a_tracked_file(tmp_path, monkeypatch, capsys):
    """`ceco identify` writes into --out (default a new runs/identify-<time>), and refuses a directory
    that already holds its files (it wrote over the tracked config/model_params.yaml by default)."""
    from ceco_controller import identification as idn
    from ceco_controller import model as cm

    tracked = cm.DEFAULT_PARAMS_PATH.read_bytes()
    monkeypatch.chdir(tmp_path)
    data_dir, params = idn.output_paths(None)
    assert data_dir.resolve().parent == tmp_path / 'runs' and data_dir.name.startswith('identify-')
    assert params == data_dir / 'model_params.yaml' and params.resolve() != cm.DEFAULT_PARAMS_PATH.resolve()
    with pytest.raises(SystemExit) as exc:
        idn.main(['--out', str(cm.DEFAULT_PARAMS_PATH.parent)])  # the tracked file's directory
    assert exc.value.code == 2 and 'model_params.yaml exists: choose a new --out' in capsys.readouterr().err
    assert cm.DEFAULT_PARAMS_PATH.read_bytes() == tracked


def test_bench_and_identify_take_the_shared_flags_and_their_old_names_say_so(capsys):
    """`ceco bench nmpc` and `ceco identify` name their settings as every other verb does (--strategy, --duration-s,
    --no-progress; --control-period-s, --horizon-steps); their old names (--strategies, --duration, --progress; --ts,
    --horizon) still parse into the same settings, each with one line saying which name to use."""
    from ceco_controller import bench, identification
    from ceco_core.contracts import CECO_STRATEGIES

    old = bench.parse_args(['nmpc', '--strategies', 'ceco,ceco-pmv-aq', '--duration', '30', '--progress'])
    new = bench.parse_args(['nmpc', '--strategy', 'ceco,ceco-pmv-aq', '--duration-s', '30'])
    assert old[1:] == new[1:] == ([6, 12, 24, 60], ['ceco', 'ceco-pmv-aq'], 30.0)
    assert old[0].progress is new[0].progress is True  # progress bars by default, as in every verb
    err = capsys.readouterr().err
    assert 'ceco bench: --strategies is deprecated and goes in the next release: use --strategy' in err
    assert 'ceco bench: --duration is deprecated and goes in the next release: use --duration-s' in err
    assert 'ceco bench: --progress is deprecated' in err and '--no-progress hides them' in err
    quiet = bench.parse_args(['nmpc', '--strategy', 'all', '--quick', '--no-progress'])
    assert quiet[0].progress is False and quiet[1:] == ([6, 12], list(CECO_STRATEGIES), 200.0)  # all: the NMPC ones
    with pytest.raises(SystemExit) as exc:
        bench.parse_args(['nmpc', '--strategy', 'baseline,ceco'])  # named, the baseline is refused, not dropped
    assert exc.value.code == 2
    assert 'argument --strategy: baseline has no solver to time' in capsys.readouterr().err
    # --horizons: each in --horizon-steps' 1..60 (1000 ended in a traceback after the run began; 61 ran)
    assert bench.parse_args(['nmpc', '--horizons', '1,60'])[1] == [1, 60]
    for bad in ('61', '6,1000', '0'):
        with pytest.raises(SystemExit) as exc:
            bench.parse_args(['nmpc', '--horizons', bad])
        assert exc.value.code == 2
        assert 'argument --horizons: must be a whole number in 1..60, got' in capsys.readouterr().err

    ident = identification.build_parser()
    a = ident.parse_args(['--ts', '4', '--horizon', '8'])
    b = ident.parse_args(['--control-period-s', '4', '--horizon-steps', '8'])
    assert (a.control_period_s, a.horizon_steps) == (b.control_period_s, b.horizon_steps) == (4.0, 8)
    err = capsys.readouterr().err
    assert 'ceco identify: --ts is deprecated and goes in the next release: use --control-period-s' in err
    assert 'ceco identify: --horizon is deprecated and goes in the next release: use --horizon-steps' in err
    d = ident.parse_args([])
    assert (d.control_period_s, d.horizon_steps) == (None, None)  # resolved to the model's 5 s and 6 steps in main
    assert (identification.TS_DEFAULT_S, identification.NP_DEFAULT) == (5.0, 6)


def test_the_scenario_help_names_every_bundled_scenario():
    """`--scenario`'s help lists the scenarios that ship (it named 6 of 12)."""
    from ceco_core.cli_flags import BUNDLED_SCENARIOS
    from ceco_v2x_preview.scenario import list_scenarios

    assert sorted(BUNDLED_SCENARIOS) == sorted(list_scenarios())
    help_text = ' '.join(sim.build_parser().format_help().split())
    assert f"bundled scenario name ({', '.join(BUNDLED_SCENARIOS)}) or YAML path" in help_text


@pytest.mark.parametrize(
    'args, says',
    [
        (['--scenarios', 'nope'], "argument --scenarios: scenario: unknown scenario 'nope'"),
        (['--scenarios', ','], 'argument --scenarios: expected comma-separated scenario names'),
        (['--steps', '0'], '--steps and --repeat must be >= 1'),
        (['--seed', '-1'], "argument --seed: must be a whole number >= 0, got '-1'"),
    ],
)
def test_bench_plant_refuses_bad_input_in_one_line(args, says, capsys):
    """`ceco bench plant` with an unknown scenario was a traceback (exit 1); now one line, exit status 2."""
    with pytest.raises(SystemExit) as exc:
        cli.main(['bench', 'plant', *args])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('ceco bench plant: error: ') and says in err[0], err


@pytest.mark.parametrize(
    'verb, argv, says',
    [
        ('sim', ['--scenario', ''], "argument --scenario: must not be empty, got ''"),
        ('sim', ['--preview', ''], "argument --preview: must not be empty, got ''"),
        ('run', ['--out', ''], "argument --out: must not be empty, got ''"),
        ('sim', ['--duration-s', '1'], '--duration-s: 1 s is less than two plant steps: give at least 2'),
        ('sim', ['--duration-s', '4.9'], '--duration-s: 4.9 s is not a whole number of plant steps (1 s): give e.g. 4'),
        ('sim', ['--duration-s', '3'], '--duration-s: 3 s is shorter than one control period (5 s): give at least 5'),
        ('run', ['--duration-s', '1'], '--duration-s: 1 s is less than two plant steps'),  # was a traceback after start
        ('benchmark', ['--controller-cmd', ''], 'argument --controller-cmd: must not be empty'),
        # found only after every baseline run before; an unclosed quote did not name the flag
        ('benchmark', ['--controller-cmd', 'no_such_ctrl_xyz --x'], "'no_such_ctrl_xyz': not found (on PATH or"),
        ('benchmark', ['--controller-cmd', "python '/x.py"], 'argument --controller-cmd: No closing quotation in'),
        ('benchmark', ['--controller-name', 'mine'], 'argument --controller-name: needs --controller-cmd'),
    ],
)
def test_empty_values_short_runs_and_lone_controller_flags_are_one_line(verb, argv, says, tmp_path, capsys):
    """An empty --scenario, --preview or --out ran sc03, the perfect preview or wrote into the current directory; a
    --duration-s under two plant steps was a traceback once the run ended, a fraction was floored without a word;
    an empty --controller-cmd or a --controller-name without it started the whole benchmark of the bundled
    strategies. Each is one line now, exit status 2, and nothing is written."""
    rest = [] if '--out' in argv else ['--out', str(tmp_path / 'out')]
    with pytest.raises(SystemExit) as exc:
        cli.main([verb, *argv, *rest, '--no-progress'] if verb == 'benchmark' else [verb, *argv, *rest])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f'ceco {verb}: error: ') and says in err[0], err
    assert not (tmp_path / 'out').exists()


@pytest.mark.parametrize('verb', ['sim', 'run', 'oracle', 'benchmark', 'sweep', 'report'])
def test_an_out_that_is_a_file_or_cannot_be_made_is_one_line(verb, tmp_path, capsys):
    """`--out FILE` (or a path under a file) was a NotADirectoryError or FileExistsError traceback after the run had
    started; now one line naming the path, exit status 2, before anything runs, and no file is created."""
    afile = tmp_path / 'afile'
    afile.write_text('')
    first = {'oracle': ['sc03-paper'], 'sweep': ['grid.yaml'], 'report': [str(tmp_path)]}.get(verb, [])
    cases = ((afile, f'{afile} exists and is not a directory'), (afile / 'sub', f'{afile} is not a directory'))
    for out, says in cases:
        with pytest.raises(SystemExit) as exc:
            cli.main([verb, *first, '--out', str(out)])
        assert exc.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f'ceco {verb}: error: argument --out: ') and says in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ['afile']


@pytest.mark.parametrize(
    'argv, says',
    [
        (['--strategy', 'ceco-pmv', '--set', 'horizon_steps=3'], '--set horizon_steps: set by --horizon-steps'),
        (['--strategy', 'baseline', '--set', 'preview_shrink_c=2'], '--set: sets StrategySettings fields of the NMPC'),
        (['--strategy', 'baseline,ceco-ioch', '--set', 'foo=1'], '--set foo: not a StrategySettings field'),
        (['--strategy', 'ceco-ioch', '--model-params', 'CORRUPT'], 'not valid YAML at line 2, column 1'),
        (['--strategy', 'ceco-ioch', '--controller-config', 'TRUNC'], 'not valid YAML at line'),
        (['--strategy', 'baseline', '--controller-config', 'TRUNC'], 'not valid YAML at line'),
        (['--strategy', 'ceco-ioch', '--controller-config', 'BINARY'], 'not a UTF-8 text file'),
        (['--strategy', 'ceco-ioch', '--controller-config', 'NP9'], 'horizon_steps: 9 is not what this run uses (6)'),
        (['--strategy', 'ceco,ceco-pmv', '--controller-config', 'TYPO'], "unknown top-level key(s) 'strategy': a"),
        (['--strategy', 'ceco-pmv', '--controller-config', 'SCENARIO'], "unknown top-level key(s) 'name', "),
    ],
)
def test_bad_settings_and_config_files_are_one_line(argv, says, tmp_path, capsys):
    """`--set` of a field a flag sets, on the baseline alone, or of no StrategySettings field; a model or controller
    file that is not YAML or not text: each was a TypeError or a YAML parser traceback (or, for an unknown field,
    an error blamed on controller.yaml after the baseline had run). One line now, exit status 2."""
    from ceco_controller.model import package_config_path

    files = {'CORRUPT': tmp_path / 'corrupt.yaml', 'TRUNC': tmp_path / 'trunc.yaml', 'BINARY': tmp_path / 'bin.yaml'}
    files['CORRUPT'].write_text('[1,2')
    config = package_config_path('controller.yaml')
    text = config.read_text()
    files['TRUNC'].write_text(text[: text.index('codegen_flags: [') + 17])  # cut inside a flow list
    files['BINARY'].write_bytes(b'\xff\xfe')
    files['NP9'] = tmp_path / 'np9.yaml'  # (a horizon the run would not use: sc03's is 6)
    files['NP9'].write_text(text.replace('common:\n', 'common:\n  horizon_steps: 9\n', 1))
    files['TYPO'] = tmp_path / 'typo.yaml'  # `strategies:` misspelt: every strategy ran on its defaults
    files['TYPO'].write_text(text.replace('\nstrategies:\n', '\nstrategy:\n', 1))
    files['SCENARIO'] = provenance.copy_scenario('sc03', tmp_path / 'sc')  # a scenario file, not a controller file
    argv = [str(files.get(a, a)) for a in argv]
    rest = ['--duration-s', '30', '--baseline-setpoints-c', 'none', '--no-progress', '--out', str(tmp_path / 'out')]
    try:  # a flag's error exits through argparse; a file's is said when its strategy's run starts
        rc = sim.main([*argv, *rest])
    except SystemExit as exc:
        rc = exc.code
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('ceco sim: error: ') and says in err[0], err


@pytest.mark.parametrize(
    ('verb', 'argv', 'old', 'new'),
    [
        ('sim', ['--out', 'x'], ['--duration', '60'], ['--duration-s', '120']),
        ('sim', ['--out', 'x'], ['--horizon', '8'], ['--horizon-steps', '9']),
        ('sim', ['--out', 'x'], ['--control-period', '4'], ['--control-period-s', '5']),
        ('sim', ['--out', 'x'], ['--preview-quality', 'noisy'], ['--preview', 'perfect']),
        ('bench', ['nmpc'], ['--strategies', 'ceco'], ['--strategy', 'ceco-ioch']),
        ('identify', [], ['--ts', '4'], ['--control-period-s', '5']),
    ],
)
def test_an_old_and_a_new_name_of_one_flag_together_are_refused(verb, argv, old, new, capsys):
    """`--duration 60 --duration-s 120` kept whichever came last without a word: now exit status 2 naming both,
    in either order; the same name twice keeps argparse's rule (the last wins)."""
    from ceco_controller import bench, identification

    parse = {
        'sim': sim.build_parser().parse_args,
        'bench': bench.parse_args,
        'identify': identification.build_parser().parse_args,
    }[verb]
    for first, second in ((old, new), (new, old)):
        with pytest.raises(SystemExit) as exc:
            parse(argv + first + second)
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert f'argument {second[0]}: not allowed with argument {first[0]}' in err, err
    # the same name twice parses, and the last value wins
    last, want = {
        '--duration-s': ('30', 30.0),
        '--horizon-steps': ('7', 7),
        '--control-period-s': ('10', 10.0),
        '--preview': ('noisy', 'noisy'),
        '--strategy': ('ceco-pmv', ['ceco-pmv']),
    }[new[0]]
    ns = parse(argv + new + [new[0], last])
    ns = ns[0] if isinstance(ns, tuple) else ns  # bench.parse_args: (namespace, ...)
    assert getattr(ns, new[0].lstrip('-').replace('-', '_')) == want


def test_a_key_given_twice_is_refused_in_every_file_the_user_writes(tmp_path, capsys):
    """YAML keys are unique (YAML 1.2); PyYAML kept the second `duration_s:` of a scenario without a word. Now a
    scenario, a benchmark case, a sweep grid and a controller configuration with a key twice are each refused
    naming the key and both lines; a merge (`<<: *base`) overridden by one of its keys is still allowed."""
    from ceco_bringup.benchmark.cases import CaseError, load_case
    from ceco_bringup.sweep.grid import GridError, load_grid
    from ceco_controller.model import package_config_path
    from ceco_core import yamlio
    from ceco_v2x_preview.scenario import ScenarioError, load_scenario

    assert yamlio.safe_load('b: &b {x: 1, y: 2}\nd:\n  <<: *b\n  x: 5\n')['d'] == {'x': 5, 'y': 2}
    # a merged mapping that itself merges and overrides, anchored deeper than where it is merged (PyYAML flattens
    # it in place before building it: a check at construction saw 'k' twice)
    for text in (
        'items:\n  - &x\n    <<: {k: 1}\n    k: 2\ny:\n  <<: *x\n',
        'a:\n  b:\n    x: &x\n      <<: &base {k: 1}\n      k: 2\ny:\n  <<: *x\n',
        'b: &b {x: 1}\nc: &c {y: 2}\nd:\n  <<: [*b, *c]\n  y: 3\n',
    ):
        assert yamlio.safe_load(text) == yaml.safe_load(text), text
    with pytest.raises(yaml.YAMLError, match=r"found the key 'x' twice \(first at line 1\)"):
        yamlio.safe_load('b: &b {x: 1, x: 2}\nd:\n  <<: *b\n')  # a duplicate inside a merged mapping
    with pytest.raises(yaml.YAMLError, match=r"found the key 'k' twice \(first at line 3\)"):
        yamlio.safe_load('top:\n  inner:\n    k: 1\n    k: 2\n')

    def twice(text: str, key: str) -> str:
        """``text`` with the line of its first top-level ``key:`` written again at the end."""
        line = next(ln for ln in text.splitlines() if ln.startswith(f'{key}:'))
        assert text.count(f'\n{key}:') + text.startswith(f'{key}:') == 1
        return text.rstrip('\n') + '\n' + line + '\n'

    scenario = tmp_path / 'scenario.yaml'
    scenario.write_text(twice(provenance.copy_scenario('sc03', tmp_path / 'copy').read_text(), 'duration_s'))
    with pytest.raises(
        ScenarioError, match=r"not valid YAML at line \d+, column 1: found the key 'duration_s' twice"
    ) as e:
        load_scenario(scenario)
    assert '\n' not in str(e.value)  # one line (PyYAML's own text spans four)
    from ceco_bringup.benchmark.cases import _data_dir

    case = tmp_path / 'case.yaml'
    case.write_text(twice(_data_dir().joinpath('sc03-paper.yaml').read_text(), 'name'))
    with pytest.raises(CaseError, match=r"not valid YAML at line \d+, column 1: found the key 'name' twice") as e:
        load_case(case)
    assert '\n' not in str(e.value)
    grid = tmp_path / 'grid.yaml'
    grid.write_text('scenarios: [sc03]\nstrategies: [baseline]\nscenarios: [udds]\n')
    with pytest.raises(
        GridError, match=r"at line 3, column 1: found the key 'scenarios' twice \(first at line 1\)"
    ) as e:
        load_grid(grid)
    assert '\n' not in str(e.value)
    with pytest.raises(GridError, match=r': cannot read grid: a directory: give the grid YAML file$'):
        load_grid(tmp_path)  # (it was Python's '[Errno 21] Is a directory')
    config = tmp_path / 'controller.yaml'
    config.write_text(twice(package_config_path('controller.yaml').read_text(), 'common'))
    rest = ['--duration-s', '30', '--baseline-setpoints-c', 'none', '--no-progress', '--out', str(tmp_path / 'out')]
    assert sim.main(['--strategy', 'ceco-ioch', '--controller-config', str(config), *rest]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "found the key 'common' twice (first at line" in err[0], err


def test_all_beside_other_strategy_names_says_all_stands_alone(capsys):
    """`--strategy all,baseline` was "unknown strategy all: use all or ..."; now it says why: all stands alone."""
    from ceco_core.contracts import STRATEGIES

    for text in ('all,baseline', 'ceco, all'):
        with pytest.raises(SystemExit) as exc:
            sim.build_parser().parse_args(['--out', 'x', '--strategy', text])
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert f'argument --strategy: all stands alone (it names every strategy the verb runs), got {text!r}' in err
    assert sim.build_parser().parse_args(['--out', 'x', '--strategy', ' all ']).strategy == list(STRATEGIES)


def test_run_and_sim_warn_when_no_step_would_receive_a_preview(capsys):
    """`--preview delayed:40` at Np = 6 (a 30 s horizon): every forecast is older than its horizon, so the NMPC runs
    on the measured weather alone; ceco sim and ceco run say so in one warning line before running (the run is
    still made: a study of no preview is legitimate). Not for the baseline alone, not for delayed:30 or Np 8.
    Each command here stops at a later input error (an unknown --set field, a stall limit below the command
    timeout in lockstep), so nothing runs:
    the warning comes from the verbs' own input checks."""
    from ceco_bringup import run

    later_error = {'ceco sim': (sim.main, ['--set', 'foo=1']), 'ceco run': (run.main, ['--stall-timeout-s', '1'])}
    for prog, (main, stop_early) in later_error.items():
        for argv, preview, warns in (
            (['--strategy', 'ceco-ioch,baseline'], 'delayed:40', True),
            (['--strategy', 'baseline'], 'delayed:40', False),
            (['--strategy', 'ceco-ioch'], 'delayed:30', False),
            (['--strategy', 'ceco-ioch', '--horizon-steps', '8'], 'delayed:40', False),
            (['--strategy', 'ceco-pmv', '--duration-s', '100'], 'missing:0-100,policy=drop', True),
        ):
            with pytest.raises(SystemExit) as exc:
                main(['--out', 'never-made', '--preview', preview, *argv, *stop_early])
            assert exc.value.code == 2
            err = capsys.readouterr().err
            said = f'{prog}: warning: no control step of the run receives a usable preview with {preview}' in err
            assert said is warns, (prog, argv, preview, err)
            assert err.count('\n') == 1 + int(warns) and f'{prog}: error: ' in err


def test_the_verdict_matches_no_run_whose_discomfort_is_saturated():
    """ceco sim's verdict (verdict.matched) takes the benchmark's rule: a run with PMV at the +-3 clip for the
    whole run (discomfort at its ceiling, 60 s x 2.5 PMV / 3600) is not matched, and a family member at the
    ceiling anchors no match. The numbers are those of a controller that never cooled a 60-s SC03 run: it was
    credited +63.1 % against the member at the ceiling."""
    ceiling = 60.0 * 2.5 / 3600.0
    family = {
        'baseline@27.0': {
            'discomfort_pmvh': 0.04166508801149208,
            'energy_kwh': 0.06117656824567467,
            'duration_s': 60.0,
        },
        'baseline@29.0': {'discomfort_pmvh': ceiling, 'energy_kwh': 0.0537435302912003, 'duration_s': 60.0},
    }
    never_cooled = {'discomfort_pmvh': ceiling, 'energy_kwh': 0.019833987284092622, 'duration_s': 60.0}
    m = vd.matched(family, never_cooled)
    assert m['energy_saving_pct'] is None and m['discomfort_reduction_pct'] is None, m
    assert m['note'] == front.NOTE_SATURATED and m['dominated'] is False, m
    # just below the ceiling the run is read against the one member off it: more comfortable than it, no number
    below = vd.matched(family, dict(never_cooled, discomfort_pmvh=0.0416))
    assert below['energy_saving_pct'] is None and below['note'].startswith('more comfortable than every'), below


def test_matched_comfort_not_computed_names_the_flag_and_a_command_that_works(tmp_path, capsys, monkeypatch):
    """`ceco sim --scenario tropical.yaml ... --baseline-setpoints-c none` printed "run `ceco benchmark` or
    `ceco run --scenario tropical --strategy all` for it": `tropical` is the file's name, which --scenario does
    not take, and the cause (the flag) went unsaid. Now the verdict names the flag and gives the same command
    without it, whole on a line of its own; that command runs and computes the matched comfort. `ceco report`
    of the runs says the same (one hint for both)."""
    import shlex
    from pathlib import Path

    from ceco_bringup import report

    monkeypatch.chdir(tmp_path)
    data = yaml.safe_load(provenance.copy_scenario('sc03', tmp_path / 'orig').read_text())
    data['name'] = 'tropical'
    Path('tropical.yaml').write_text(yaml.safe_dump(data))
    argv = ['--scenario', 'tropical.yaml', '--strategy', 'baseline', '--duration-s', '20', '--no-progress']
    assert sim.main([*argv, '--baseline-setpoints-c', 'none', '--out', 'A']) == 0
    lines = capsys.readouterr().out.splitlines()
    i = next(i for i, line in enumerate(lines) if line.startswith('Matched comfort: not computed'))
    said = ' '.join(line.strip() for line in lines[i : i + 2])
    assert said == (
        'Matched comfort: not computed for these runs; `--baseline-setpoints-c none` skipped the baseline '
        'family; the same command without it computes it:'
    ), said
    command = lines[i + 2]
    assert command == '  ceco sim --scenario tropical.yaml --strategy baseline --duration-s 20 --no-progress --out A'
    assert '--scenario tropical ' not in '\n'.join(lines)
    words = shlex.split(command)
    assert words[:2] == ['ceco', 'sim'] and sim.main(words[2:]) == 0  # the command works: matched comfort now
    assert 'Matched comfort: against the production law' in capsys.readouterr().out
    assert sim.main([*argv, '--baseline-setpoints-c', 'none', '--out', 'B']) == 0
    capsys.readouterr()
    res = report.build_report([Path('B')], tmp_path / 'rep', log=lambda *a, **k: None)
    assert (
        '  ceco sim --scenario tropical.yaml --strategy baseline --duration-s 20 --no-progress --out B'
        in res['verdict']
    )
    md = res['markdown'].read_text()
    assert '`--baseline-setpoints-c none` skipped the baseline family' in md
    assert '`ceco sim --scenario tropical.yaml --strategy baseline --duration-s 20 --no-progress --out B`' in md


def test_matched_comfort_hint_without_the_jobs_command():
    """The hint written once (ceco sim, ceco run, ceco report): the flag in either spelling is the cause; without
    the job's arguments the scenario as given and the verb make the command; a case is named as a case."""
    flag = outputs.FAMILY_FLAG
    pointer, command = outputs.matched_comfort_hint('run', 'my dir/hot.yaml', argv=['--out', 'x', f'{flag}=none'])
    assert pointer.startswith(f'`{flag} none` skipped the baseline family') and command == 'ceco run --out x'
    assert outputs.matched_comfort_hint('sim', 's.yaml', argv=[flag, '25,26', '--out', 'x'])[1] == (
        "ceco sim --scenario s.yaml --strategy all --out DIR"
    )
    pointer, command = outputs.matched_comfort_hint('run', 'my dir/hot.yaml', skipped=True)
    assert (
        pointer.startswith(f'`{flag} none` skipped')
        and command == "ceco run --scenario 'my dir/hot.yaml' --strategy all --out DIR"
    )
    for verb in ('benchmark', 'oracle'):  # runs these verbs made: the command is `ceco run`'s, which takes --scenario
        assert outputs.matched_comfort_hint(verb, 's.yaml', argv=['x.yaml'])[1] == (
            'ceco run --scenario s.yaml --strategy all --out DIR'
        )
    pointer, command = outputs.matched_comfort_hint('sim', 'ignored', case='hotsoak-pulldown')
    assert (
        command == 'ceco sim --case hotsoak-pulldown --strategy all --out DIR'
        and 'ceco benchmark hotsoak-pulldown' in pointer
    )
    assert (
        outputs.family_skipped([flag, 'None'])
        and not outputs.family_skipped([flag, '24,25'])
        and not outputs.family_skipped(None)
    )
    # argparse's abbreviations of the flag (as typed, in run.json's argv) are the flag: the only flag of sim and run
    # that starts with --b, so argparse takes every prefix down to --b as it
    from ceco_bringup import run, sim

    for verb in (sim, run):
        options = verb.build_parser()._option_string_actions  # noqa: SLF001 (argparse has no public list)
        assert [o for o in options if o.startswith('--b')] == [flag]
        assert verb.build_parser().allow_abbrev  # (without it, a typed abbreviation is refused: no hint needed)
    for typed in (['--baseline-setpoints', 'none'], ['--baseline=none'], ['--b', 'NONE']):
        assert outputs.family_skipped(['--out', 'x', *typed]), typed
        assert outputs.matched_comfort_hint('run', 's.yaml', argv=['--out', 'x', *typed])[1] == 'ceco run --out x'
    assert not outputs.family_skipped(['--baselines', 'none']) and not outputs.family_skipped(['-b', 'none'])
