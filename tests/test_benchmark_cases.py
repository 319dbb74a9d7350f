"""Benchmark test-case files (ceco_bringup.benchmark.cases)."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from ceco_bringup.benchmark import cases as bc
from ceco_bringup.benchmark.cases import load_case


def test_every_bundled_case_loads_and_the_lists_agree():
    names = bc.list_cases()
    assert sorted(bc.DEFAULT_CASES) == names
    assert set(bc.QUICK_CASES) <= set(names)
    for name in names:
        c = bc.load_case(name)
        assert c.name == name and c.version >= 1
        sc = c.load_scenario()
        if c.forecast_uncertainty == "none":
            assert c.seeds == (0,)
        else:
            assert len(c.seeds) >= bc.MIN_UNCERTAIN_SEEDS
        assert len(c.sha()) == 16
        assert sc.duration_s > 0


def test_overrides_and_sha():
    hot = bc.load_case("hotsoak-pulldown")
    assert hot.load_scenario().duration_s == 900.0
    # the band (upper bound 0.5) is reached inside the run
    lb, ub = hot.load_scenario().pmv_bounds(700.0)
    assert ub == pytest.approx(0.5)
    a, b = bc.load_case("sc03-low"), bc.load_case("sc03-medium")
    assert a.scenario_dict() == b.scenario_dict() and a.sha() != b.sha()
    assert bc.load_case("sc03-paper").sha() == bc.load_case("sc03-paper").sha()


def _write(tmp_path, **over):
    d = {
        "schema": bc.CASE_SCHEMA,
        "name": "my-case",
        "version": 1,
        "scenario": "sc03",
        "forecast_uncertainty": "low",
        "seeds": [0, 1, 2, 3, 4],
    }
    d.update(over)
    d = {k: v for k, v in d.items() if v is not ...}
    p = tmp_path / "my-case.yaml"
    p.write_text(yaml.safe_dump(d))
    return p


def test_a_user_case_file_with_a_relative_scenario(tmp_path):
    sc = tmp_path / "hot.yaml"
    sc.write_text(
        yaml.safe_dump(
            yaml.safe_load((bc.resources.files("ceco_v2x_preview") / "data" / "scenarios" / "sc03.yaml").read_text())
            | {"name": "hot"}
        )
    )
    c = bc.load_case(_write(tmp_path, scenario="hot.yaml", duration_s=120))
    assert c.load_scenario().name == "hot" and c.load_scenario().duration_s == 120.0


@pytest.mark.parametrize(
    "over, field",
    [
        ({"schema": "ceco-benchmark-case/2"}, "schema"),
        ({"name": "has space"}, "name"),
        ({"version": 0}, "version"),
        ({"version": 1.5}, "version"),
        ({"forecast_uncertainty": "extreme"}, "forecast_uncertainty"),
        ({"seeds": [0, 1]}, "seeds"),
        ({"seeds": [0, 0, 1, 2, 3]}, "seeds"),
        ({"forecast_uncertainty": "none", "seeds": [0, 1]}, "seeds"),
        ({"duration_s": -5}, "duration_s"),
        ({"scenario": "no_such_scenario"}, "scenario"),
        ({"colour": "red"}, "colour"),
        ({"seeds": ...}, "seeds"),
        ({"seeds": [0, 1, 2, 3, 2**31]}, r"seeds: must be a non-empty list of integers in 0\.\.2147483647"),
    ],
)
def test_bad_case_files_name_the_field(tmp_path, over, field):
    with pytest.raises(bc.CaseError, match=f"^{field}"):
        bc.load_case(_write(tmp_path, **over))
    with pytest.raises(bc.CaseError, match="unknown case"):
        bc.load_case("no-such-case")


@pytest.mark.parametrize("name", ["tunnel", "sun-shade", "idle-traffic", "highway-to-city", "known-stop"])
def test_previewable_disturbance_cases_run_and_show_their_disturbance(name):
    """Each new case loads and runs closed loop (the production law); its disturbance is in the record and moves
    the A/C: the cooling load (compressor power) is lower while the sun is gone or the car stands still."""
    from ceco_controller.closed_loop import SimSettings, simulate

    case = load_case(name)
    assert case.forecast_uncertainty == "medium" and len(case.seeds) == 5
    ts = simulate(case.load_scenario(), "baseline", SimSettings(progress=False)).timeseries
    t = ts["t_s"]
    assert t[-1] >= case.load_scenario().duration_s - 1.0 and np.all(np.isfinite(ts["pmv"]))

    def mean(col, a, b):
        return float(ts[col][(t >= a) & (t < b)].mean())

    if name == "tunnel":
        assert mean("solar_wm2", 490, 660) == 0.0 and mean("solar_wm2", 400, 480) > 700.0
        assert mean("p_comp_w", 560, 660) < 0.9 * mean("p_comp_w", 380, 480)
    elif name == "sun-shade":
        assert mean("solar_wm2", 430, 600) == 150.0 and mean("solar_wm2", 610, 780) > 600.0
        assert mean("w_rad_wm2", 430, 600) < 0.3 * mean("w_rad_wm2", 610, 780)  # the occupant's absorbed sun
        # against the same drive in full sun (udds): less compressor power once the shade has lasted a while
        sun = simulate(load_case("udds-hot").load_scenario(), "baseline", SimSettings(progress=False, duration_s=900))
        assert mean("p_comp_w", 520, 600) < float(sun.timeseries["p_comp_w"][(t >= 520) & (t < 600)].mean())
    elif name == "idle-traffic":
        assert mean("speed_mps", 351, 670) == 0.0 and mean("speed_mps", 700, 900) > 5.0
    elif name == "highway-to-city":
        assert mean("speed_mps", 100, 700) > 20.0 and mean("speed_mps", 766, 1270) < 12.0
    else:  # known-stop: parked, the occupant out (bound relaxed), back in the band at 840 s
        assert (
            mean("speed_mps", 601, 840) == 0.0 and mean("pmv_ub", 610, 830) == 3.0 and mean("pmv_ub", 850, 1080) == 0.5
        )


@pytest.mark.parametrize(
    'case_name, strategy, seed, duration_s',
    [
        ('hotsoak-pulldown', 'ceco-ioch', 2, None),  # 900 s: longer than its scenario file's 600 s; seeded previews
        ('hot-commute-4p', 'baseline', None, 240.0),  # four occupants; the baselines' production door logic
    ],
)
def test_ceco_sim_case_runs_the_benchmarks_cell(tmp_path, case_name, strategy, seed, duration_s):
    """`ceco sim --case NAME [--seed N]` runs what `ceco benchmark` runs for that case, controller and seed
    (the cell built by the benchmark's own runner, `case_cells` + `run_cell`): the same energy and
    discomfort to the bit, the same preview quality, and the case's resolved scenario kept in the run
    directory. (`--duration-s` shortens both alike; the cell is given the same length.)"""
    import json
    import subprocess
    import sys

    from ceco_bringup.benchmark import runner
    from ceco_bringup.sweep import scenario_dict
    from ceco_bringup.sweep.cells import code_fingerprint, run_cell
    from ceco_v2x_preview.scenario import load_scenario

    case = load_case(case_name)
    if duration_s is not None:
        case = bc.dataclasses.replace(case, duration_s=duration_s)
    kind = 'baseline' if strategy == 'baseline' else 'strategy'  # the production law at its file's set-point
    spec = runner.ControllerSpec(strategy, kind, strategy)
    cell = runner.case_cells(case, [spec], code_fingerprint(), seeds=None if seed is None else [seed])[0]
    row = run_cell(bc.dataclasses.asdict(cell))
    assert row['status'] == 'ok', row['error']
    out = tmp_path / 'sim'
    cmd = [sys.executable, '-m', 'ceco_bringup.cli', 'sim', '--case', case_name, '--strategy', strategy]
    cmd += ['--out', str(out), '--baseline-setpoints-c', 'none', '--no-progress']
    cmd += [] if seed is None else ['--seed', str(seed)]
    cmd += [] if duration_s is None else ['--duration-s', str(duration_s)]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stdout + p.stderr
    # the pointer names the flag that skipped the family and gives the same command, the case's, without it
    assert '`--baseline-setpoints-c none` skipped the baseline family' in ' '.join(p.stdout.split())
    again = f'  ceco sim --case {case_name} --strategy {strategy} --out {out} --no-progress'
    assert any(line.startswith(again) and '--baseline-setpoints' not in line for line in p.stdout.splitlines())
    m = json.loads((out / strategy / 'metrics.json').read_text())
    assert m['E_tot_J'] == row['E_tot_J'] and m['I_pmv'] == row['I_pmv'], (m['E_tot_J'], row['E_tot_J'])
    assert m['duration_s'] == (duration_s or 900.0)
    if strategy != 'baseline':  # (a baseline's cell is run once, with perfect previews: it reads none)
        assert m['preview_quality'] == row['preview_quality'] and 'medium' in m['preview_quality']
    kept = load_scenario(str(out / strategy / 'scenario.yaml'))  # the case's scenario, its overrides applied
    assert scenario_dict(kept) == load_case(case_name).scenario_dict()
    assert kept.occupants == (4 if case.occupants else 1)
    assert kept.duration_s == {'hotsoak-pulldown': 900.0, 'hot-commute-4p': 1369.0}[case_name]  # (the case's own)


def test_ceco_sim_case_and_scenario_are_one_or_the_other(tmp_path):
    import subprocess
    import sys

    cmd = [sys.executable, '-m', 'ceco_bringup.cli', 'sim', '--case', 'sc03-paper', '--scenario', 'sc03']
    p = subprocess.run(cmd + ['--out', str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and '--case and --scenario: give one' in p.stderr, p.stderr
    p = subprocess.run(
        [sys.executable, '-m', 'ceco_bringup.cli', 'sim', '--case', 'no-such-case', '--out', str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 2 and 'no-such-case' in p.stderr, p.stderr


def test_apply_case_fills_only_the_flags_not_given(tmp_path):
    """--case fills the scenario, preview, seed, Ts and Np the user did not give; a seed given by --seed or by
    a seed= in --preview stays; --scenario beside it is refused."""
    import argparse

    from ceco_bringup import cli_args
    from ceco_v2x_preview.scenario import load_scenario

    def args(**kw):
        base = dict(case='hotsoak-pulldown', scenario=None, preview=None, seed=None, control_period_s=None)
        return argparse.Namespace(**{**base, 'horizon_steps': None, **kw})

    a = args()
    case = cli_args.apply_case(a, tmp_path / 'a')
    assert case.name == 'hotsoak-pulldown' and cli_args.case_overrides(case, 'baseline') == ()  # no door
    assert (a.preview, a.seed, a.control_period_s, a.horizon_steps) == ('uncertain:medium', 0, None, None)
    assert load_scenario(a.scenario).duration_s == 900.0 and a.scenario.endswith('a/case_scenario.yaml')
    a = args(seed=3, preview='perfect', horizon_steps=8)
    cli_args.apply_case(a, tmp_path / 'b')
    assert (a.preview, a.seed, a.horizon_steps) == ('perfect', 3, 8)
    a = args(preview='uncertain:high+noisy:seed=7')
    cli_args.apply_case(a, tmp_path / 'c')
    assert a.seed is None and a.preview == 'uncertain:high+noisy:seed=7'  # the preview's own seed=7 decides
    case = cli_args.apply_case(args(case='hot-commute-4p'), tmp_path / 'd')
    assert cli_args.case_overrides(case, 'baseline') == (('door_mode', 'auto'),)  # the baselines' door only
    assert cli_args.case_overrides(case, 'ceco-pmv') == () and cli_args.case_overrides(None, 'baseline') == ()
    with pytest.raises(ValueError, match='--case and --scenario: give one'):
        cli_args.apply_case(args(scenario='sc03'), tmp_path / 'e')
    a = argparse.Namespace(case=None, scenario=None, preview=None, seed=None, control_period_s=None, horizon_steps=None)
    assert cli_args.apply_case(a, tmp_path / 'f') is None and (a.scenario, a.preview, a.seed) == (
        'sc03',
        'perfect',
        None,
    )
    assert not (tmp_path / 'f').exists()  # nothing written without --case


def test_family_overrides_reach_every_member():
    """The verdict's family with a case's baseline door (``ceco sim/run --case``): each member is the production law
    at its set-point with the door fields, equal to the simulator's run with them, and differs from the member
    without them on a four-occupant drive."""
    from ceco_bringup import verdict as vd
    from ceco_controller.closed_loop import SimSettings, simulate

    sc = load_case('hot-commute-4p').load_scenario()
    door = (('door_mode', 'auto'),)
    with_door = vd.run_family(
        sc, duration_s=240.0, setpoints_c=(25.0,), laws=('baseline',), progress=False, overrides=door
    )
    without = vd.run_family(sc, duration_s=240.0, setpoints_c=(25.0,), laws=('baseline',), progress=False)
    settings = SimSettings(
        duration_s=240.0, progress=False, strategy_overrides=(('door_mode', 'auto'), ('setpoint_c', 25.0))
    )
    direct = vd.run_point(simulate(sc, 'baseline', settings).timeseries, sc.air_quality.limits)
    assert list(with_door) == ['baseline@25.0'] and with_door['baseline@25.0'] == direct
    assert with_door['baseline@25.0'] != without['baseline@25.0']


STOPGO_YAML = """\
name: stopgo
drive_cycle: stopgo.csv
weather:
  time_s: [0, 100, 102, 200]
  t_amb_c: 36.0
  solar_wm2: [900, 900, 0, 0]
  rh: 0.35
occupant: {met: 1.2, clo: 0.5}
comfort_bounds: {time_s: [0], pmv_lb: -0.5, pmv_ub: 0.5}
initial: {t_cab_c: 42.0, t_int_c: 45.0, t_shell_c: 47.0}
"""
"""A scenario whose drive cycle is a CSV beside it, by a relative path (found by testing unseen scenarios)."""

STOPGO_CASE = """\
schema: ceco-benchmark-case/1
name: stopgo-case
version: 1
description: a relative CSV drive cycle
scenario: stopgo.yaml
duration_s: 20
forecast_uncertainty: none
seeds: [0]
"""


def test_sim_case_with_a_relative_csv_drive_cycle(tmp_path, monkeypatch, capsys):
    """``ceco sim --case`` (and ``ceco run --case``: the same ``apply_case``) on a case given by a relative path
    whose scenario names its CSV drive cycle relative to itself: OUT/case_scenario.yaml points at a copy of the CSV
    beside it (provenance.copy_drive_cycle), the cycle is the CSV's, and the run completes. Before, the relative
    path was written as it was and resolved against OUT: 'unknown drive cycle' and exit 2."""
    import argparse

    from ceco_bringup import cli_args, sim
    from ceco_v2x_preview.scenario import load_scenario

    src = tmp_path / 'cases'
    src.mkdir()
    csv = 'time_s,speed_mps\n' + ''.join(f'{t},{(t % 20) * 0.5:.1f}\n' for t in range(0, 201))
    (src / 'stopgo.csv').write_text(csv, encoding='utf-8')
    (src / 'stopgo.yaml').write_text(STOPGO_YAML, encoding='utf-8')
    (src / 'case_stopgo.yaml').write_text(STOPGO_CASE, encoding='utf-8')
    monkeypatch.chdir(src)
    a = argparse.Namespace(
        case='case_stopgo.yaml', scenario=None, preview=None, seed=None, control_period_s=None, horizon_steps=None
    )
    cli_args.apply_case(a, tmp_path / 'out')
    sc = load_scenario(a.scenario)
    assert (tmp_path / 'out' / 'drive_cycle_stopgo.csv').read_text(encoding='utf-8') == csv
    assert sc.drive_cycle.speed_mps[:3].tolist() == [0.0, 0.5, 1.0] and sc.duration_s == 20.0
    assert 'drive_cycle stopgo.csv copied to drive_cycle_stopgo.csv' in Path(a.scenario).read_text(encoding='utf-8')
    out = tmp_path / 'sim'
    rc = sim.main(['--case', 'case_stopgo.yaml', '--strategy', 'baseline', '--no-progress', '--out', str(out)])
    assert rc == 0, capsys.readouterr().err
    assert (out / 'drive_cycle_stopgo.csv').is_file() and (out / 'baseline' / 'run.json').is_file()


def test_a_case_number_yaml_reads_as_text_says_how_to_write_it():
    """A case's ``duration_s: 6e1`` is text to PyYAML (YAML 1.1): refused with the form it reads as a number."""
    text = STOPGO_CASE.replace('duration_s: 20', 'duration_s: 6e1')
    why = r"^duration_s: must be a number, got '6e1' \(YAML reads 6e1 as text: write 6.0e\+1\)$"
    with pytest.raises(bc.CaseError, match=why):
        bc.case_from_dict(yaml.safe_load(text), base_dir='.')
