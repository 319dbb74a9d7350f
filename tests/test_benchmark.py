"""`ceco benchmark` end to end on a short case: results.json, resume, report, validation, sensitivity."""

import json
import math
from html.parser import HTMLParser

import pytest
import yaml

from ceco_bringup.benchmark import cli, runner
from ceco_bringup.benchmark import schema as bs
from ceco_bringup.benchmark.cases import CASE_SCHEMA

SETPOINTS = (25.0, 27.0, 29.0)
SETPOINTS_PMV = (0.0, 0.5)
FAMILY_RUNS = 4 * len(SETPOINTS) + 2 * len(SETPOINTS_PMV)  # temperature families: plain, allowance, tuned x 2
ORACLE = 'oracle_standin:solve_front'  # tests/oracle_standin.py: real scored runs, not an optimum
LEVELS_N = [0] * 4  # runner.oracle_levels asks for 4 levels


def _write_short_case(path, duration_s: float, uncertainty: str, seeds: list[int]) -> None:
    """A case 'short' on the mild day's first ``duration_s`` seconds."""
    doc = {'schema': CASE_SCHEMA, 'name': 'short', 'version': 1, 'scenario': 'sc03_mild', 'duration_s': duration_s}
    path.write_text(yaml.safe_dump({**doc, 'forecast_uncertainty': uncertainty, 'seeds': seeds}))


@pytest.fixture(scope='module')
def bench(tmp_path_factory):
    d = tmp_path_factory.mktemp('bench')
    case = d / 'short.yaml'
    # the mild day (28 degC, 400 W/m2, cabin 39 degC at key-on): in its first 120 s the PI law at 25/27/29 degC
    # already regulates (on SC03's hot soak every set-point is still at full cooling then, issue 9's slower
    # pull-down), and the bound is relaxed all the time (3.0 until 60 s, 0.5 at 240 s)
    _write_short_case(case, duration_s=120, uncertainty='none', seeds=[0])
    sens = d / 'sens.yaml'
    sens.write_text(
        yaml.safe_dump(
            {
                'schema': 'ceco-benchmark-sensitivity/1',
                'case': 'short',
                'parameters': [
                    {
                        'parameter': 'plant.c_int_jpk',
                        'target': 'plant',
                        'nominal': {'c_int_jpk': 90000.0},
                        'low': {'c_int_jpk': 60000.0},
                        'high': {'c_int_jpk': 120000.0},
                        'source': 'test',
                    }
                ],
            }
        )
    )
    import oracle_standin

    kw = dict(
        workers=1,
        progress=False,
        log=lambda *a, **k: None,
        setpoints_c=SETPOINTS,
        setpoints_pmv=SETPOINTS_PMV,
        sensitivity_path=sens,
        oracle=True,
        oracle_entry=ORACLE,
    )
    oracle_standin.CALLS.clear()
    first = cli.run_benchmark([str(case)], d / 'out', **kw)
    calls = list(oracle_standin.CALLS)
    second = cli.run_benchmark([str(case)], d / 'out', **kw)
    assert oracle_standin.CALLS == calls  # the oracle's cell is cached like the runs
    return d, first, second


TWINS = tuple(s + runner.PERSISTENCE_SUFFIX for s in runner.PERSISTENCE_TWINS)
"""The strategies' persistence twins (``ceco-pmv-persistence``)."""


def test_results_document(bench):
    d, doc, _ = bench
    assert bs.check_results(json.loads((d / 'out' / 'results.json').read_text())) == []
    (case,) = doc['cases']
    names = {r['controller'] for r in case['runs']}
    assert names == (
        {f'{k}@{s:.1f}' for s in SETPOINTS for k in ('baseline', 'baseline-allowance', 'baseline-tuned')}
        | {f'baseline-tuned-allowance@{s:.1f}' for s in SETPOINTS}
        | {f'{k}@{s:+.2f}' for s in SETPOINTS_PMV for k in ('baseline-pmv', 'baseline-pmv-allowance')}
        | {'baseline-compensated', 'baseline-compensated-allowance', *runner.STRATEGY_NAMES, *TWINS}
    )
    assert {r['setpoint_pmv'] for r in case['runs'] if r['kind'] == 'baseline-pmv'} == set(SETPOINTS_PMV)
    assert all(r['status'] == 'ok' and r['source'] == 'simulator' for r in case['runs'])
    assert {r['seed'] for r in case['runs'] if r['kind'] == 'strategy'} == {0}
    assert {r['seed'] for r in case['runs'] if r['kind'] != 'strategy'} == {None}
    assert sorted(p['controller'] for p in case['fronts']['plain']) == sorted(f'baseline@{s:.1f}' for s in SETPOINTS)
    assert set(case['matched']) == {
        'baseline-compensated',
        'baseline-compensated-allowance',
        *runner.STRATEGY_NAMES,
        *TWINS,
    }
    by = {r['controller']: r['kpis'] for r in case['runs']}
    # the allowance changes the baseline during the relaxed phase (the first 120 s are all relaxed)
    assert by['baseline-allowance@27.0']['energy_kwh'] < by['baseline@27.0']['energy_kwh']
    # a warmer set-point uses less energy and is less comfortable (the law regulates within 120 s on the mild day)
    assert by['baseline@29.0']['energy_kwh'] < by['baseline@27.0']['energy_kwh'] < by['baseline@25.0']['energy_kwh']
    assert (
        by['baseline@29.0']['discomfort_pmvh']
        > by['baseline@27.0']['discomfort_pmvh']
        > by['baseline@25.0']['discomfort_pmvh']
    )
    # the strategies that follow the relaxed bound are compared with the allowance front (inside its range)
    for name in ('ceco', 'ceco-ioch'):
        m = case['matched'][name]
        assert m['energy_saving_pct'] is None and 'less comfortable than every efficient baseline' in m['note']
        assert m['allowance']['energy_saving_pct'] is not None
    # the strongest family: the least energy of every family at a discomfort; each level names one
    st = case['strongest']
    assert set(st['families']) <= set(bs.FAMILIES) and st['family'] in st['families']
    assert len(st['levels']) == len(case['oracle']['levels']) >= 4
    # the strongest family is never weaker than a family in it: the saving against it is at most the saving against
    # the production PI's front and against the allowance front, wherever both are numbers (some are, counted)
    n_compared = 0
    for m in case['matched'].values():
        strongest = m['strongest']['energy_saving_pct']
        for saving in (m['energy_saving_pct'], m['allowance']['energy_saving_pct']):
            if strongest is not None and saving is not None:
                assert strongest <= saving + 1e-9
                n_compared += 1
    assert n_compared >= 3
    # the oracle's cell ran (the stand-in: first level unsolved) and headroom_captured was computed from it
    orc = case['oracle']
    assert orc['status'] == 'ok' and orc['entry_point'] == runner.ORACLE_ENTRY
    (f,) = orc['fronts']
    assert f['seed'] == 0 and f['points'][0]['kpis'] is None and f['points'][0]['error'] == 'not solved'
    assert all(p['kpis']['energy_kwh'] > 0 for p in f['points'][1:]) and len(f['front']) == len(LEVELS_N) - 1
    assert all(m['headroom'] is not None and m['headroom']['n_seeds'] == 1 for m in case['matched'].values())
    # by_phase reads the fronts where headroom does: the bound's saving from its energies is headroom's
    read = 0
    for name, m in case['matched'].items():
        p, h = m['by_phase'], m['headroom']
        assert p['n_seeds'] == 1 and p['controller']['energy_kwh'] == by[name]['energy_kwh']
        if h['bound_saving_pct'] is not None:
            e_env, e_b = p['strongest']['energy_kwh'], p['bound']['energy_kwh']
            assert 100.0 * (e_env - e_b) / e_env == pytest.approx(h['bound_saving_pct'], rel=1e-9, abs=1e-9)
            read += 1
    assert read >= 1
    # NMPC steps are timed; the comfort series of issue 9 are scored; what a 120-s run cannot have is explained
    assert by['ceco']['time_ratio_mean'] > 0 and by['ceco']['fallback_steps'] == 0
    for name in ('baseline@27.0', 'ceco'):
        k = by[name]
        assert 0.0 <= k['draught_pct'] <= 100.0 and k['draught_max_pct'] == pytest.approx(100.0, abs=1.0)  # face jet
        assert k['fog_margin_min_k'] > 5.0 and k['fog_risk_pct'] == 0.0  # a sunny day's warm glass
        assert 0.0 < k['iso7730_invalid_pct'] <= 100.0  # the pull-down is outside ISO 7730
        assert k['i_pmv_clipped'] < k['i_pmv']  # PMV above 3 at key-on
    notes = next(r for r in case['runs'] if r['controller'] == 'ceco')['kpi_notes']
    assert all(by['ceco'][k] is None for k in notes)
    assert set(notes) >= {'discomfort_band_pmvh', 'pmv_mean_band'}  # the band applies from 240 s
    assert not set(notes) & {'draught_pct', 'fog_margin_min_k', 'iso7730_invalid_pct'}
    assert doc['settings']['setpoints_c'] == list(SETPOINTS) and not doc['quick']
    lines = (d / 'out' / 'kpis.csv').read_text().splitlines()
    assert len(lines) == 1 + len(case['runs'])


def test_resume_runs_nothing_and_gives_the_same_results(bench):
    _, first, second = bench
    n_strat = len(runner.STRATEGY_NAMES) + len(TWINS)  # the strategies and the persistence twins
    n = FAMILY_RUNS + 2 + n_strat  # the families, the compensated laws, the strategies
    n_sens = 2 * len(SETPOINTS) + 2 + n_strat  # the tornado reruns the production families and the scored ones
    # the nominal runs and the sensitivity's two ends, plus the oracle's one cell
    assert first['timing']['ran_now'] == n + 2 * n_sens + 1 and second['timing']['ran_now'] == 0
    assert first['timing']['oracle_cells_now'] == 1 and second['timing']['oracle_cells_now'] == 0
    for t in (first['timing'], second['timing']):  # the two phases' wall times lie within the whole
        assert 0 < t['runs_phase_s'] and 0 <= t['oracle_phase_s']
        assert t['runs_phase_s'] + t['oracle_phase_s'] <= t['wall_s']
    assert second['cases'][0]['matched'] == first['cases'][0]['matched']
    assert second['cases'][0]['sensitivity'] == first['cases'][0]['sensitivity']


def test_sensitivity_entries(bench):
    _, doc, _ = bench
    (s,) = doc['cases'][0]['sensitivity']
    assert s['parameter'] == 'plant.c_int_jpk' and (s['low'], s['nominal'], s['high']) == (60000.0, 90000.0, 120000.0)
    assert s['failed_low'] == s['failed_high'] == 0
    assert set(s['matched_low']) == set(doc['cases'][0]['matched'])
    # the interior's capacity matters: both ends' overrides were applied (each end's saving differs from the nominal)
    name = 'baseline-compensated-allowance'
    nominal = doc['cases'][0]['matched'][name]['energy_saving_pct']
    low, high = (s[f'matched_{end}'][name]['energy_saving_pct'] for end in ('low', 'high'))
    assert None not in (nominal, low, high) and low != nominal and high != nominal and low != high


def test_report_files(bench):
    d, doc, _ = bench
    md = (d / 'out' / 'report.md').read_text()
    html = (d / 'out' / 'report.html').read_text()
    figs = sorted(p.name for p in (d / 'out' / 'figures').iterdir())
    assert figs == ['plane_short.png', 'tornado_short.png']
    assert html.count('data:image/png;base64,') == 2 and 'src="figures' not in html
    assert '## Savings at matched comfort' in md and '| short | ceco-c |' in md
    assert '## The strongest family' in md and 'headroom_captured' in md
    assert 'Where the savings sit' in md and "oracle's saving vs strongest [kWh]: whole run / band phase" in md


def test_validate_command(bench, tmp_path, capsys):
    d, _, _ = bench
    assert cli.main(['--validate', str(d / 'out' / 'results.json')]) == 0
    doc = json.loads((d / 'out' / 'results.json').read_text())
    doc['cases'][0]['matched']['ceco']['energy_saving_pct'] = (
        99.0
        if doc['cases'][0]['matched']['ceco']['energy_saving_pct'] is None
        else -doc['cases'][0]['matched']['ceco']['energy_saving_pct'] - 1.0
    )
    bad = tmp_path / 'bad.json'
    bad.write_text(json.dumps(doc))
    assert cli.main(['--validate', str(bad)]) == 1
    assert 'does not recompute' in capsys.readouterr().err


def test_summary_lines_carry_the_signed_matched_values(bench):
    _, doc, _ = bench
    lines = cli.summary_lines(doc)
    (case,) = doc['cases']
    assert len(lines) == len(case['matched'])
    for line, (name, m) in zip(lines, case['matched'].items(), strict=True):
        line, _, why = line.partition('; n/a: ')  # a saving that is n/a says why, at the end
        assert why == ('' if m['energy_saving_pct'] is not None else m['note'])
        assert line.split()[:2] == ['short', name]
        saved = line.split('energy saved at matched comfort')[1].split('(allowance')[0].strip()
        cut = line.split('discomfort cut at matched energy')[1].split(',')[0].strip()
        want = 'n/a' if m['energy_saving_pct'] is None else f"{m['energy_saving_pct']:+.1f} %"
        assert saved == want
        want = 'n/a' if m['discomfort_reduction_pct'] is None else f"{m['discomfort_reduction_pct']:+.1f} %"
        assert cut == want
        assert line.endswith(', dominated') == m['dominated']
    # the sign convention of results.json: a strategy that needs more energy than the front shows a negative saving
    doc2 = json.loads(json.dumps(doc))
    doc2['cases'][0]['matched']['ceco'].update(energy_saving_pct=-3.04, dominated=True)
    (line,) = [x for x in cli.summary_lines(doc2) if x.split()[1] == 'ceco']
    assert 'energy saved at matched comfort   -3.0 % (' in line and line.endswith(', dominated')
    # ... and an n/a saving says why (it said only "n/a")
    why = 'more comfortable than every efficient baseline (no extrapolation)'
    doc2['cases'][0]['matched']['ceco'].update(energy_saving_pct=None, note=why)
    (line,) = [x for x in cli.summary_lines(doc2) if x.split()[1] == 'ceco']
    assert 'energy saved at matched comfort      n/a (' in line and line.endswith(f', dominated; n/a: {why}')
    # a case whose every family member is at the discomfort ceiling has no front: each scored controller is
    # named with why (it vanished from the summary without a word)
    doc3 = json.loads(json.dumps(doc))
    doc3['cases'][0]['matched'] = {}
    for pts in doc3['cases'][0]['fronts'].values():
        for pt in pts:
            pt['efficient'] = False
    lines = cli.summary_lines(doc3)
    for name in case['matched']:
        why = "not matched: every baseline's discomfort is saturated (no family front has a vertex)"
        assert f'{name:<32} {why}' in '\n'.join(lines), lines


def test_baseline_constants_and_controllers():
    from importlib import resources

    from ceco_bringup.benchmark.cases import load_case

    b = runner.load_baselines()
    assert b.tuned_on == 'sc03-paper' and b.allowance_k_per_pmv > 0 and len(b.sha) == 16
    frozen = yaml.safe_load(
        resources.files('ceco_bringup').joinpath('data', 'benchmark', 'baselines.yaml').read_text('utf-8')
    )
    assert frozen['tuned_on_sha'] == load_case('sc03-paper').sha()  # tuned on the case as it is now
    # the comfort-neutral set-point of the rule lies inside the family, the compensated law's too
    assert runner.SETPOINTS_C[0] <= frozen['neutral_setpoint_c'] <= runner.SETPOINTS_C[-1]
    assert runner.SETPOINTS_C[0] <= frozen['compensation']['setpoint_c'] <= runner.SETPOINTS_C[-1]
    assert all(r['pmv_band'] == pytest.approx(0.0, abs=0.01) for r in frozen['runs'] if r['run'].endswith('neutral'))
    specs = runner.controllers(b)
    assert [s.setpoint_c for s in specs if s.kind == 'baseline'] == [22.0 + 0.5 * i for i in range(15)]
    assert [s.setpoint_pmv for s in specs if s.kind == 'baseline-pmv'] == pytest.approx(runner.SETPOINTS_PMV)
    assert sum(s.seeded for s in specs) == 6 and len(specs) == 4 * 15 + 2 * 9 + 2 + 5 + 1  # 5 strategies, 1 twin
    # the tuned families: gains from the file, the comfort-feedback ones on the PMV through the estimator
    fams = {f.family: f for f in b.family_specs()}
    assert list(fams) + [f.family for f in b.door_family_specs()] == list(bs.FAMILIES)
    assert fams['tuned'].feedback == 'cabin_temperature' and fams['tuned'].measurements == 'full'
    assert fams['pmv'].feedback == 'pmv' and fams['pmv'].measurements == 'vehicle'
    assert fams['tuned-allowance'].overrides['allowance_k_per_pmv'] == b.allowance_k_per_pmv
    assert fams['pmv-allowance'].overrides['allowance_pmv_per_pmv'] > 0
    for name in runner.TUNED_FAMILIES:
        f = frozen['families'][name]
        kp = 'kp_per_pmv' if name.startswith('pmv') else 'kp_per_k'
        # the chosen gains are the grid point of least objective, and the file says so
        best = min((g for g in f['grid'] if g['objective_kwh'] is not None), key=lambda g: g['objective_kwh'])
        assert (f['settings'][kp], f['settings']['ti_s']) == (best['kp'], best['ti_s'])
        assert f['objective_kwh'] == best['objective_kwh'] and len(f['levels_pmvh']) == 11
        assert f['held_out']['case'] != frozen['tuned_on']
    assert frozen['tuning_cost']['runs_step6'] > 0 and frozen['tuning_cost']['wall_s'] > 0
    allow = next(s for s in specs if s.name == 'baseline-allowance@26.0')
    assert dict(allow.overrides) == {'setpoint_c': 26.0, 'allowance_k_per_pmv': b.allowance_k_per_pmv}
    case_name, params = runner.load_sensitivity()
    assert case_name == 'sc03-paper' and all(p.low != p.high for p in params)
    assert not math.isnan(float(dict(next(s for s in specs if s.kind == 'compensated').overrides)['setpoint_c']))


def _write_sens(path, params):
    path.write_text(
        yaml.safe_dump({'schema': 'ceco-benchmark-sensitivity/1', 'case': 'sc03-paper', 'parameters': params})
    )
    return path


def test_sensitivity_table_names_the_new_comfort_model(tmp_path):
    from ceco_core.cabin_comfort import ComfortParams
    from ceco_plant_sim.plant_params import PlantParams

    _, params = runner.load_sensitivity()
    names = {p.parameter for p in params}
    # issue 10's list on the physics of issue 9: jet exposure and mixing, air-speed map, sun, radiant weights,
    # the humidity source; the plant's least certain parameters incl. the new duct mass
    assert names >= {
        'comfort.air.jet_body_fraction',
        'comfort.air.r_jet_temperature',
        'comfort.air.k_jet',
        'comfort.air.c_room',
        'comfort.solar.f_bes',
        'comfort.radiant.f_interior',
        'comfort.pa_pa',
        'plant.c_int_jpk',
        'plant.u_shell_in_wm2k',
        'plant.ua_duct_wpk',
        'plant.c_duct_jpk',
    }
    cp, pp = ComfortParams(), PlantParams()
    for p in params:
        assert p.parameter == f'{p.target}.{next(iter(p.nominal))}'
        for field, value in p.nominal.items():
            obj = cp if p.target == 'comfort' else pp
            if field == 'pa_pa':
                assert value is None  # nominal: the plant's moisture balance
                continue
            for part in field.split('.'):
                obj = getattr(obj, part)
            assert obj == value
        assert p.low != p.nominal != p.high
    radiant = next(p for p in params if p.parameter == 'comfort.radiant.f_interior')
    for end in (radiant.low, radiant.high):  # the angle factors still sum to 1
        assert end['radiant.f_interior'] + end['radiant.f_shell'] + cp.radiant.f_glass == pytest.approx(1.0)


@pytest.mark.parametrize(
    'entry, message',
    [
        ({'nominal': {'a2': 0.25}, 'low': {'a2': 0.1}, 'high': {'a2': 0.4}}, 'ComfortParams.a2: no such field'),
        (
            {
                'nominal': {'air.jet_bodyfraction': 0.1},
                'low': {'air.jet_bodyfraction': 0.05},
                'high': {'air.jet_bodyfraction': 0.2},
            },
            'ComfortParams.air.jet_bodyfraction: no such field',
        ),
        (
            {
                'nominal': {'air.jet_body_fraction': 0.15},
                'low': {'air.jet_body_fraction': 0.05},
                'high': {'air.jet_body_fraction': 0.2},
            },
            "differs from the code's default 0.1",
        ),
        (
            {'nominal': {'radiant.f_glass': 0.22}, 'low': {'radiant.f_glass': 0.14}, 'high': {'radiant.f_glass': 0.3}},
            'RadiantParams.f_interior: the angle factors must sum to 1',
        ),
        ({'nominal': {'air': 1.0}, 'low': {'air': 0.5}, 'high': {'air': 2.0}}, 'override its fields by dotted name'),
        (
            {'nominal': {'pa_pa': 1700.0}, 'low': {'pa_pa': 860.0}, 'high': {'pa_pa': 1800.0}},
            "differs from the code's default None",
        ),
        ({'nominal': {'pa_pa': None}, 'low': {'pa_pa': -5.0}, 'high': {'pa_pa': 1700.0}}, 'pa_pa (scored cabin vapour'),
        (
            {'nominal': {'solar.f_bes': 0.5}, 'low': {'solar.asw': 0.57}, 'high': {'solar.f_bes': 0.75}},
            'must set the same fields',
        ),
    ],
)
def test_sensitivity_table_errors_name_the_field(tmp_path, entry, message):
    path = _write_sens(tmp_path / 's.yaml', [{'parameter': 'comfort.x', 'target': 'comfort', **entry}])
    with pytest.raises(ValueError, match=message.replace('(', r'\(').replace('.', r'\.')):
        runner.load_sensitivity(path)


def test_plant_sensitivity_field_is_checked(tmp_path):
    path = _write_sens(
        tmp_path / 's.yaml',
        [
            {
                'parameter': 'plant.c_int',
                'target': 'plant',
                'nominal': {'c_int': 1.0},
                'low': {'c_int': 0.5},
                'high': {'c_int': 2.0},
            }
        ],
    )
    with pytest.raises(ValueError, match=r'PlantParams\.c_int: no such field'):
        runner.load_sensitivity(path)


def test_comfort_overrides_reach_the_scored_pmv_only():
    """Nested comfort overrides and a fixed scored p_a change the score, not the plant (and are validated)."""
    from ceco_controller.closed_loop import SimSettings
    from ceco_core.contracts import AcInput
    from ceco_plant_sim.scenario_plant import ScenarioPlant
    from ceco_v2x_preview.scenario import load_scenario

    sc = load_scenario('sc03')
    u = AcInput(mdot_bl_kgps=0.12, t_evap_sp_c=4.0)

    def last(**kw):
        sp = ScenarioPlant(sc, 1.0, **kw)
        for _ in range(400):
            rec = sp.step(u)
        return rec

    nominal = last()
    jet = last(comfort_overrides={'air.jet_body_fraction': 0.2})
    pa = last(comfort_overrides={'pa_pa': 1700.0})
    assert jet.meas == nominal.meas and pa.meas == nominal.meas  # the plant is untouched
    assert jet.comfort.ta_occ_c < nominal.comfort.ta_occ_c - 0.5  # more of the body in the cold jet
    assert jet.pmv < nominal.pmv - 0.3
    assert nominal.comfort.pa_pa < 1200.0 and pa.comfort.pa_pa == 1700.0  # the moisture balance: ~860 Pa
    assert pa.pmv > nominal.pmv + 0.05  # the paper's humid cabin is warmer
    assert pa.comfort.t_dew_c == nominal.comfort.t_dew_c  # dew point: the plant's humidity
    assert ScenarioPlant(sc, 1.0, comfort_overrides={'solar.f_bes': 0.25}).comfort.solar.f_bes == 0.25
    for bad, msg in (
        ((('air.jet_bodyfraction', 0.2),), r'ComfortParams\.air\.jet_bodyfraction: no such field'),
        ((('solar.f_bes', 1.5),), r'SolarParams\.f_bes must be a finite number in \[0\.0, 1\.0\]'),
    ):
        with pytest.raises(ValueError, match=msg):
            SimSettings(comfort_overrides=bad).validate()
    with pytest.raises(ValueError, match=r'PlantParams\.c_intjpk: no such field'):
        SimSettings(plant_overrides=(('c_intjpk', 1.0),)).validate()


def test_plane_figure_with_equal_seeds(tmp_path):
    """Seeds with the same point: the mean can exceed their max by an ulp (0.1 * 3 / 3); no negative whisker."""
    from ceco_bringup.benchmark.figures import fig_plane

    run = {
        'controller': 'ceco',
        'kind': 'strategy',
        'status': 'ok',
        'kpis': {'discomfort_pmvh': 0.1, 'energy_kwh': 0.1},
    }
    case = {
        'case': 'c',
        'fronts': {
            'plain': [{'controller': 'baseline@25.0', 'discomfort': 0.05, 'energy': 0.2, 'efficient': True}],
            'allowance': [],
        },
        'runs': [dict(run, seed=s) for s in range(3)],
    }
    out = fig_plane(case, tmp_path / 'p.png', {'front_axis': 'discomfort_pmvh', 'energy_axis': 'energy_kwh'})
    assert out.stat().st_size > 1000


def test_a_missing_oracle_module_is_skipped_with_one_line(tmp_path):
    """No oracle module: every case says 'unavailable' with the reason, one log line, and the run goes on."""
    from ceco_bringup.benchmark.cases import load_case

    assert runner.oracle_unavailable('ceco_no_such_package.oracle:solve_front') == (
        'ceco_no_such_package.oracle is not installed'
    )
    assert 'has no function' in runner.oracle_unavailable('ceco_core.acc_law:no_such_function')
    assert runner.oracle_unavailable('oracle_standin:solve_front') is None
    lines = []
    case = load_case('sc03-paper')
    runs = [
        {
            'controller': f'baseline@{s}',
            'kind': 'baseline',
            'seed': None,
            'status': 'ok',
            'kpis': {'discomfort_pmvh': d, 'energy_kwh': e},
        }
        for s, d, e in ((24.0, 0.1024, 0.425), (25.0, 0.1051, 0.397), (26.0, 0.1242, 0.366))
    ]

    def oracles(requested, entry):
        def dispatch(*a):
            pytest.fail('nothing may be dispatched')

        return cli._run_oracles(
            [case], {case.name: []}, lambda cs: [], {case.name: [0]}, 'abcdef0123456789', tmp_path / 'cells.jsonl',
            dispatch, lambda *a, **k: lines.append(a[0]), requested, entry, None,
        )  # fmt: skip

    out = oracles(True, 'ceco_no_such_package.oracle:solve_front')
    assert out[case.name]['status'] == 'unavailable' and 'not installed' in out[case.name]['note']
    assert len(lines) == 1 and 'oracle skipped' in lines[0] and 'without --oracle it is not asked' in lines[0]
    # not requested (the default; --no-oracle): skipped, no line
    lines.clear()
    out = oracles(False, runner.ORACLE_ENTRY)
    assert out[case.name]['status'] == 'skipped' and out[case.name]['fronts'] == [] and not lines
    assert out[case.name]['note'].startswith('not requested (ceco benchmark --oracle')
    # the command line: off by default, --oracle asks it
    assert not cli.build_parser().parse_args(['--out', 'x']).oracle
    assert cli.build_parser().parse_args(['--out', 'x', '--oracle']).oracle
    # --oracle-cases: a subset of the selected cases, with --oracle only; a stray name is one clear error
    a = cli.build_parser().parse_args(['--out', 'x', '--oracle', '--oracle-cases', 'sc03-paper, udds-hot'])
    assert a.oracle_cases == ['sc03-paper', 'udds-hot']
    with pytest.raises(SystemExit):
        cli.main(['sc03-paper', '--out', 'x', '--oracle-cases', 'sc03-paper'])
    with pytest.raises(ValueError, match='--oracle-cases: udds-hot not among the selected cases'):
        cli.run_benchmark(['sc03-paper'], 'x', oracle=True, oracle_cases=['udds-hot'])
    # the levels: >= 4, from the least discomfort of the families to 1.5 times it
    levels = runner.oracle_levels([{**r, 'kpis': dict(r['kpis'])} for r in runs])
    assert len(levels) == 4 and levels[0] == pytest.approx(0.1024) and levels[-1] == pytest.approx(1.5 * 0.1024)
    # spaced quadratically: dense at the comfortable end, where the fronts are steepest
    frac = [(x - levels[0]) / (levels[-1] - levels[0]) for x in levels]
    assert frac == pytest.approx([0.0, 1.0 / 9.0, 4.0 / 9.0, 1.0])


class _Text(HTMLParser):
    """The text a browser shows (no style or script)."""

    def __init__(self):
        super().__init__()
        self.parts, self._skip = [], 0

    def handle_starttag(self, tag, attrs):
        self._skip += tag in ('style', 'script')

    def handle_endtag(self, tag):
        self._skip -= tag in ('style', 'script')

    def handle_data(self, data):
        if not self._skip:
            self.parts.append(data)


def _shown_text(html: str) -> str:
    p = _Text()
    p.feed(html)
    return '\n'.join(p.parts)


def _markdown_markers(text: str) -> list[str]:
    import re

    found = [m for m in ('**', '`', '|---', '](') if m in text]
    found += [line for line in text.splitlines() if re.match(r'\s*#{1,6} ', line)]
    return found


def test_benchmark_html_shows_no_markdown_markers(bench, tmp_path):
    """The benchmark's report.html, parsed as a browser shows it, holds no literal Markdown marker
    (`**yes**` showed in 20 table cells of a full benchmark: cells were escaped without the inline
    formatter); what the Markdown makes bold is bold in the HTML. The short case's results, with one
    controller marked dominated as the full benchmark's are, give the "**yes**" cells."""
    import copy

    from ceco_bringup.benchmark.report import write_report

    d, doc, _ = bench
    for out, document in ((d / 'out', None), (tmp_path, copy.deepcopy(doc))):
        if document is not None:
            for m in document['cases'][0]['matched'].values():
                m['dominated'] = True
                m['allowance']['dominated'] = True
            write_report(document, out)
        html = (out / 'report.html').read_text()
        md = (out / 'report.md').read_text()
        assert _markdown_markers(_shown_text(html)) == []
        assert md.count('**') // 2 == html.count('<b>') > 0
    assert '**yes**' in md and '<td><b>yes</b></td>' in html


def test_table_cells_render_inline_markdown():
    from ceco_bringup.report_html import Heading, Table, render_html

    html = render_html([Heading(2, 'Case `sc03`'), Table(('a', '**b**'), [('**yes**', '`x`')])])
    assert '<td><b>yes</b></td><td><code>x</code></td>' in html and '<th><b>b</b></th>' in html
    assert _markdown_markers(_shown_text(html)) == []


def _kpis_but_wall_clock(row):
    return {k: v for k, v in row['kpis'].items() if not k.startswith('time_ratio')}


def test_persistence_twin_runs_once_for_every_seed(tmp_path):
    """The persistence twin's run does not depend on the seed (the seed draws the preview errors only, and
    persistence has none): the benchmark runs it once per case and reuses the row for every seed; the scored
    strategy with uncertain previews still runs per seed and differs between seeds."""
    case = tmp_path / 'uncertain.yaml'
    case.write_text(
        yaml.safe_dump(
            {
                'schema': CASE_SCHEMA,
                'name': 'uncertain',
                'version': 1,
                'scenario': 'sc03_mild',
                'duration_s': 300,  # past the pull-down (full cooling whatever the preview) into regulation
                'forecast_uncertainty': 'high',
                'seeds': [0, 1, 2, 3, 4],
            }
        )
    )
    twin = 'ceco-pmv' + runner.PERSISTENCE_SUFFIX
    # the claim itself: the twin at two seeds, each run on its own, gives the same KPIs (the wall-clock ones aside)
    specs = runner.controllers(runner.load_baselines(), (26.0,), ('ceco-pmv',), (0.0,))
    cells = runner.case_cells(cli.load_case(str(case)), specs, cli.code_fingerprint(), seeds=[0, 1])
    by = {(c.axes['controller'], c.axes['seed']): dict(id=c.id, axes=c.axes, spec=c.spec) for c in cells}
    rows = {k: runner.run_benchmark_cell(by[k]) for k in [(twin, 0), (twin, 1), ('ceco-pmv', 0), ('ceco-pmv', 1)]}
    assert [r['status'] for r in rows.values()] == ['ok'] * 4, [r['error'] for r in rows.values()]
    assert _kpis_but_wall_clock(rows[(twin, 0)]) == _kpis_but_wall_clock(rows[(twin, 1)])
    assert _kpis_but_wall_clock(rows[('ceco-pmv', 0)]) != _kpis_but_wall_clock(rows[('ceco-pmv', 1)])
    assert not runner.seed_matters(by[(twin, 1)]['spec']) and runner.seed_matters(by[('ceco-pmv', 1)]['spec'])
    # the benchmark: one run of the twin, its row reused for the other four seeds
    out = tmp_path / 'out'
    doc = cli.run_benchmark(
        [str(case)],
        out,
        workers=1,
        progress=False,
        log=lambda *a, **k: None,
        setpoints_c=(26.0,),
        setpoints_pmv=(0.0,),
        sensitivity=False,
        strategies=('ceco-pmv',),
    )
    logged = [json.loads(line) for line in (out / 'cells.jsonl').read_text().splitlines()]
    twins = [r for r in logged if r['controller'] == twin]
    assert sorted(r['seed'] for r in twins) == [0, 1, 2, 3, 4] and len({r['cell_id'] for r in twins}) == 5
    ran = [r for r in twins if 'reused_from' not in r]
    assert len(ran) == 1 and all(r['reused_from'] == ran[0]['cell_id'] for r in twins if r is not ran[0])
    assert len([r for r in logged if r['controller'] == 'ceco-pmv' and 'reused_from' not in r]) == 5
    assert doc['timing']['ran_now'] == len(logged) and doc['timing']['runs'] == len(logged)
    runs = [r for r in doc['cases'][0]['runs'] if r['controller'] == twin]
    assert len(runs) == 5 and all(r['kpis'] == runs[0]['kpis'] for r in runs)
    # the reused twin rows equal the twin run at seed 1 on its own
    seed1 = next(r for r in twins if r['seed'] == 1)
    assert _kpis_but_wall_clock(seed1) == _kpis_but_wall_clock(rows[(twin, 1)])


def test_oracle_levels_that_break_air_quality_are_no_bound():
    """An oracle level whose replay broke the CO2 limit stays in ``points`` (with why) but not on the front."""
    ok = {'discomfort_pmvh': 0.10, 'energy_kwh': 0.40, 'air_quality_met': 1.0}
    stale = {'discomfort_pmvh': 0.12, 'energy_kwh': 0.30, 'air_quality_met': 0.0}
    unknown = {'discomfort_pmvh': 0.15, 'energy_kwh': 0.28, 'air_quality_met': None}
    row = {
        'seed': 0,
        'status': 'ok',
        'error': '',
        'points': [
            {'level': 0.10, 'kpis': ok, 'error': ''},
            {'level': 0.12, 'kpis': stale, 'error': ''},
            {'level': 0.15, 'kpis': unknown, 'error': ''},
        ],
    }
    doc = runner.oracle_entry('ok', '', [0.10, 0.12, 0.15], [row])
    (f,) = doc['fronts']
    assert [p['discomfort'] for p in f['front']] == [0.10, 0.15]
    assert f['points'][1]['error'].startswith('breaks the air-quality limits')
    assert f['points'][0]['error'] == '' and f['points'][2]['error'] == ''
    bounds = runner.oracle_bounds(doc)
    assert bounds[0].energy_at(0.12) == pytest.approx(0.40 + (0.28 - 0.40) * (0.02 / 0.05))


def test_oracle_cell_keeps_the_solvers_account():
    """An oracle level says why it was not solved (IPOPT's status, iterations, wall time), and the account
    reaches results.json; a malformed account fails the cell with the field named."""
    from ceco_bringup.benchmark.cases import load_case

    case = load_case('sc03-paper')
    levels = [0.10, 0.11, 0.12, 0.13]
    (cell,) = runner.oracle_cells(case, [0], levels, cli.code_fingerprint(), 'oracle_standin:solve_front_accounted')
    row = runner.run_oracle_cell({'id': cell.id, 'axes': cell.axes, 'spec': cell.spec})
    assert row['status'] == 'ok', row['error']
    first, *rest = row['points']
    assert first['kpis'] is None and first['error'] == 'not solved (Maximum_WallTime_Exceeded, 57 iterations, 900 s)'
    assert first['solver'] == {'status': 'Maximum_WallTime_Exceeded', 'iterations': 57, 'wall_time_s': 900.4}
    assert [p['solver']['iterations'] for p in rest] == [10, 11, 12] and all(p['kpis']['energy_kwh'] > 0 for p in rest)
    assert all(p['solver']['evaluation'] == 'compiled' for p in rest) and 'evaluation' not in first['solver']
    doc = runner.oracle_entry('ok', '', levels, [row])
    (f,) = doc['fronts']
    assert f['points'][0]['solver']['status'] == 'Maximum_WallTime_Exceeded' and len(f['front']) == 3
    (bad,) = runner.oracle_cells(case, [0], levels, cli.code_fingerprint(), 'oracle_standin:solve_front_bad_account')
    row = runner.run_oracle_cell({'id': bad.id, 'axes': bad.axes, 'spec': bad.spec})
    assert row['status'] == 'error' and 'iterations must be an int >= 0, got -1' in row['error']


def test_the_strategy_flag_chooses_what_is_scored(tmp_path, capsys):
    """``ceco benchmark --strategy``: all (the default set), none (the families only), a comma-separated list of
    strategies and variants (duplicates dropped); an unknown name is one clear error (exit 2). A real --quick run
    with ``--strategy ceco-e`` scores ceco-e and the compensated laws, no other strategy, and records the flag."""
    parse = cli.build_parser().parse_args
    assert parse(['--out', 'x']).strategy is None and parse(['--out', 'x', '--strategy', 'all']).strategy is None
    assert parse(['--out', 'x', '--strategy', 'none']).strategy == ()
    assert parse(['--out', 'x', '--strategy', 'ceco-pmv-door, ceco,ceco']).strategy == ('ceco-pmv-door', 'ceco')
    with pytest.raises(SystemExit) as exc:
        cli.main(['sc03-paper', '--out', str(tmp_path / 'bad'), '--strategy', 'ceco,nope'])
    assert exc.value.code == 2 and 'nope: not a strategy' in capsys.readouterr().err
    out = tmp_path / 'q'
    assert cli.main(['--quick', '--strategy', 'ceco-e', '--no-progress', '--workers', '2', '--out', str(out)]) == 0
    doc = json.loads((out / 'results.json').read_text())
    scored = {r['controller'] for c in doc['cases'] for r in c['runs'] if r['kind'] == 'strategy'}
    assert scored == {'ceco-e'}
    for c in doc['cases']:  # every case scores ceco-e and the two compensated laws, nothing else
        assert set(c['matched']) == {'ceco-e', 'baseline-compensated', 'baseline-compensated-allowance'}, c['case']
    assert '--strategy ceco-e' in doc['command'] and bs.check_results(doc) == []


def test_cases_with_the_same_oracle_problem_solve_it_once():
    """sc03-paper and sc03-high differ only in what the oracle does not see (forecast uncertainty, seeds): with
    the same levels their oracle cells are one solve, the other cell reuses its row under its own id and axes;
    another drive, other levels or an entry point of the user's (which may read any field) solve apart."""
    from ceco_bringup.benchmark.cases import load_case

    paper, high, udds = load_case('sc03-paper'), load_case('sc03-high'), load_case('udds-hot')
    assert runner.oracle_problem(paper) == runner.oracle_problem(high) != runner.oracle_problem(udds)
    levels = [0.1024, 0.108, 0.125, 0.1535]

    def items(*cells):
        return [dict(id=c.id, axes=c.axes, spec=c.spec) for cs in cells for c in cs]

    a = runner.oracle_cells(paper, [0], levels, 'code')
    b = runner.oracle_cells(high, [0], levels, 'code')
    assert a[0].id != b[0].id
    run, reuse = runner.share_seed_invariant(items(a, b))
    assert [x['id'] for x in run] == [a[0].id] and [x['id'] for x in reuse[a[0].id]] == [b[0].id]
    row = {'cell_id': a[0].id, **a[0].axes, 'status': 'ok', 'error': '', 'points': [{'level': 0.1}]}
    row['wall_time_s'] = 80.0
    got = runner.reused_row(row, reuse[a[0].id][0])
    assert got['cell_id'] == b[0].id and got['case'] == 'sc03-high' and got['reused_from'] == a[0].id
    assert got['wall_time_s'] == 0.0 and 'sim_time_s' not in got and got['points'] == row['points']
    for other in (
        runner.oracle_cells(udds, [0], levels, 'code'),
        runner.oracle_cells(high, [0], levels[:3] + [0.16], 'code'),
        runner.oracle_cells(high, [0], levels, 'other code'),
    ):
        run, reuse = runner.share_seed_invariant(items(a, other))
        assert len(run) == 2 and not reuse
    mine = 'tests.oracle_standin:solve_front'
    c, d = runner.oracle_cells(paper, [0], levels, 'code', mine), runner.oracle_cells(high, [0], levels, 'code', mine)
    assert 'problem' not in c[0].spec
    run, reuse = runner.share_seed_invariant(items(c, d))
    assert len(run) == 2 and not reuse


def test_oracle_cells_run_longest_expected_first_and_the_shared_solve_stays_first():
    """The oracle's cells go to the pool longest expected solve first (the drive's duration, doubled with the
    door as a decision): a 1369-s door case, then the 1369-s udds-hot, then the 600-s SC03 cases in their given
    order, so that sc03-paper (listed first) stays the one solve the other SC03 cells reuse."""
    from ceco_bringup.benchmark.cases import load_case

    names = ['sc03-paper', 'udds-hot', 'sc03-high', 'hot-commute-4p', 'mild-day']
    cases = {n: load_case(n) for n in names}
    levels = [0.1024, 0.108, 0.125, 0.1535]
    cells = [c for n in names for c in runner.oracle_cells(cases[n], [0], levels, 'code')]
    order = runner.oracle_cost_order(cells, cases)
    assert [c.axes['case'] for c in order] == ['hot-commute-4p', 'udds-hot', 'sc03-paper', 'sc03-high', 'mild-day']
    assert sorted(c.id for c in order) == sorted(c.id for c in cells)
    run, reuse = runner.share_seed_invariant([dict(id=c.id, axes=c.axes, spec=c.spec) for c in order])
    shared = {c.axes['case']: c.id for c in order}
    assert [x['id'] for x in reuse[shared['sc03-paper']]] == [shared['sc03-high']]


def test_a_quick_document_lists_the_seeds_it_ran(tmp_path):
    """--quick runs a case's first seed only; its document lists that seed, not the case file's five (the validator
    holds every seed-dependent controller to a run per listed seed). The families alone: seconds."""
    case = tmp_path / 'short.yaml'
    _write_short_case(case, duration_s=20, uncertainty='medium', seeds=[0, 1, 2, 3, 4])
    kw = dict(workers=1, progress=False, log=lambda *a, **k: None, setpoints_c=[25.0], setpoints_pmv=[0.0])
    doc = cli.run_benchmark([str(case)], tmp_path / 'out', quick=True, strategies=(), **kw)
    assert doc['cases'][0]['seeds'] == [0]
    assert json.loads((tmp_path / 'out' / 'results.json').read_text())['cases'][0]['seeds'] == [0]
    assert bs.check_results(doc) == []
