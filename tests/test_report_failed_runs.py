"""A failed run is never a number and never silently dropped (``ceco report``, the verdict, the baseline family).

A run whose controller did not control it, or that stopped (the plant left its refrigerant model, a node exited, a
stall), is *failed*: ``run.json`` says ``failed`` with the reason in ``error`` (``ceco sim``, ``ceco run``), or
``metrics.json`` has ``status: failed`` (``ceco_core.run_status``; a run directory ``ceco benchmark --save-runs``
kept). ``ceco report`` names every failed run it finds with its reason in the words of ``ceco sim``'s final block
(``N of M runs failed (not compared):``), on the console, in summary.md and report.html and in its scenario's
verdict, shows none of its numbers and exits 1; a directory of failed runs only is reported as such (it said
"not a run directory" and dropped them beside good runs). A baseline-family member whose plant leaves its model is
a failed member named in the verdict (it was a traceback).

The failures are real: a scenario beyond the refrigerant model (60 degC ambient, a 70 degC cabin: the cycle does not
converge at the second plant step), run by ``ceco sim`` in-process; the "did not control" run is the record
``ceco sim`` writes for one (its metrics.json with ``status: failed``, run.json ``failed``) over a real 40-s run.
"""

import dataclasses
import json
import re
import shutil

import pytest
import yaml
from scenario_cases import BEYOND_THE_CYCLE as HOT  # the plant leaves its refrigerant model at once
from test_report import _msg, _plant_bag_writer

from ceco_bringup import provenance, report, rundata, sim
from ceco_bringup import verdict as vd
from ceco_controller.closed_loop import SimSettings, simulate, write_run

DURATION_S = 40.0


STOPPED = 'the simulation stopped: refrigerant cycle did not converge in 30 iterations (compiled plant, step 2'
"""How ``ceco sim`` words a run of :data:`HOT` (its run.json's ``error``)."""

NOT_CONTROLLED = 'the controller did not control the run: 8 of 8 control steps were fallback steps'
"""The reason of the run whose controller did not control it."""


@pytest.fixture(scope='module')
def hot(tmp_path_factory):
    path = tmp_path_factory.mktemp('hot') / 'hot.yaml'
    path.write_text(yaml.safe_dump(HOT))
    return path


@pytest.fixture(scope='module')
def failed_job(tmp_path_factory, hot):
    """``ceco sim`` of baseline and ceco on :data:`HOT`: both fail (exit 1), run.json ``failed``, no data."""
    out = tmp_path_factory.mktemp('fail') / 'job'
    assert sim.main(['--scenario', str(hot), '--strategy', 'baseline,ceco', '--out', str(out), '--no-progress']) == 1
    return out


@pytest.fixture(scope='module')
def results():
    settings = SimSettings(duration_s=DURATION_S, progress=False)
    return {s: simulate('sc03', s, settings) for s in ('baseline', 'ceco-ioch')}


def _write_bag(result, bag_dir, custom):
    """A bag of ``result`` as ceco's recorder writes it (``custom``: its custom_data), plant topics only."""
    store, w, topics = _plant_bag_writer(bag_dir, custom)
    ts = result.timeseries
    for n in range(len(ts['t_s'])):
        t = float(ts['t_s'][n])
        row = {k: float(v[n]) for k, v in ts.items()}
        for topic, typ in topics.items():
            w.write(topic, int(round(t * 1e9)), _msg(store, typ, {**row, 'step_index': n, 'scenario_time_s': t}, t))
    w.close()


def _not_controlled(result, run_dir):
    """The run directory ``ceco sim`` leaves for a run whose controller did not control it (sim.py's order)."""
    provenance.start_run(run_dir, 'sim', ['--scenario', 'sc03'], 'sc03')
    metrics = {**result.metrics, 'status': 'failed', 'status_reason': NOT_CONTROLLED}
    result = dataclasses.replace(result, metrics=metrics)
    write_run(result, run_dir)
    provenance.finish_run(run_dir, 'failed', NOT_CONTROLLED)
    return run_dir


def test_ceco_sim_leaves_failed_runs_without_data(failed_job):
    """The premise: both runs of the hot job failed, run.json says why, and there is no number to load."""
    for name in ('baseline', 'ceco'):
        info = json.loads((failed_job / name / 'run.json').read_text())
        assert info['status'] == 'failed' and info['error'].startswith(STOPPED)
        assert not (failed_job / name / 'metrics.json').exists() and not (failed_job / name / 'timeseries.csv').exists()


def test_a_directory_of_failed_runs_is_reported_as_such(failed_job, tmp_path, capsys):
    """Every run failed: exit 1, the runs named with their reasons as ``ceco sim`` names them (it said "not a run
    directory", exit 2), and summary.md / report.html say it too, with no table."""
    code = report.main([str(failed_job), '--out', str(tmp_path / 'rep')])
    out, err = capsys.readouterr()
    assert code == 1, out + err
    assert 'not a run directory' not in err
    assert 'ceco report: every run failed: nothing to compare' in err
    block = out[out.index('2 of 2 runs failed (not compared):') :].splitlines()
    assert block[1].startswith(f'  baseline: {STOPPED}') and block[2].startswith(f'  ceco: {STOPPED}')
    assert f'{failed_job / "ceco"}: ceco on beyond_the_cycle: FAILED, not compared' in out
    # the words of ceco sim's own block, line for line
    assert block[:3] == (failed_job / 'summary.txt').read_text().splitlines()[-3:]
    md = (tmp_path / 'rep' / 'summary.md').read_text()
    assert 'No run to report: every run found failed' in md
    assert f'> **WARNING:** 2 of 2 runs failed (not compared): baseline (`{failed_job / "baseline"}`): {STOPPED}' in md
    assert f'; ceco (`{failed_job / "ceco"}`): {STOPPED}' in md and 'kWh' not in md.split('WARNING')[1]
    html = (tmp_path / 'rep' / 'report.html').read_text()
    assert 'class="warn">WARNING: 2 of 2 runs failed (not compared): baseline (<code>' in html


def test_failed_runs_beside_good_ones_are_named_and_show_no_number(failed_job, results, tmp_path, capsys):
    """A parent holding a good baseline, a run whose controller did not control it (same scenario, its numbers
    recorded) and a run that stopped (another scenario): the report compares the baseline alone and names both
    failed runs with their reasons on the console, in summary.md, report.html and the sc03 verdict; exit 1."""
    root = tmp_path / 'job'
    write_run(results['baseline'], root / 'baseline')
    _not_controlled(results['ceco-ioch'], root / 'ceco-ioch')
    shutil.copytree(failed_job / 'ceco', root / 'ceco')
    code = report.main([str(root), '--out', str(tmp_path / 'rep')])
    out, err = capsys.readouterr()
    assert code == 1, out + err
    assert 'ceco report: failed runs are not compared' in err
    block = out[out.index('2 of 3 runs failed (not compared):') :].splitlines()
    assert block[1] == f'  ceco: {json.loads((root / "ceco" / "run.json").read_text())["error"]}'
    assert block[2] == f'  ceco-ioch: {NOT_CONTROLLED}'
    # in the verdict: named, never a number (its energy is in its metrics.json, not here)
    assert f'ceco-ioch FAILED ({NOT_CONTROLLED}), not compared' in ' '.join(out.split())
    assert not re.search(r'ceco-ioch\s+[0-9]', out) and re.search(r'baseline\s+[0-9.]+ kWh', out)
    md = (tmp_path / 'rep' / 'summary.md').read_text()
    assert f'ceco-ioch FAILED ({NOT_CONTROLLED}), not compared' in md  # the sc03 verdict
    assert f'2 of 3 runs failed (not compared): ceco (`{root / "ceco"}`): {STOPPED}' in md
    assert f'ceco-ioch (`{root / "ceco-ioch"}`): {NOT_CONTROLLED}' in md
    assert not re.search(r'(\| |  )ceco-ioch\s+(\| )?[0-9]', md) and '| baseline | ' in md  # no row, no number
    assert f'ceco-ioch FAILED ({NOT_CONTROLLED}), not compared' in (tmp_path / 'rep' / 'report.html').read_text()
    rows = (tmp_path / 'rep' / 'metrics.csv').read_text().splitlines()
    assert [r.split(',')[1] for r in rows[1:]] == ['baseline']


def test_a_failed_ceco_run_with_a_bag_is_failed_not_partial(results, tmp_path):
    """``ceco run`` that failed mid-run (a node exited, a stall: run.json ``failed``) leaves a bag of what it
    recorded; it was shown as a partial run with its numbers, now it is a failed run with its reason."""
    run = tmp_path / 'run'
    provenance.start_run(run, 'run', ['--scenario', 'sc03', '--strategy', 'ceco-ioch'], 'sc03', 'ceco-ioch')
    _write_bag(results['ceco-ioch'], run / 'bag', custom={'strategy': 'ceco-ioch', 'scenario': 'sc03'})
    provenance.finish_run(run, 'failed', 'stalled: no new plant step for 20 s of wall clock at plant step 28/40')
    loaded, failed = rundata.load_runs([run])
    assert loaded == [] and [(f.strategy, f.scenario) for f in failed] == [('ceco-ioch', 'sc03')]
    assert failed[0].reason == 'stalled: no new plant step for 20 s of wall clock at plant step 28/40'
    with pytest.raises(ValueError, match=r'a failed run \(stalled: no new plant step .*\): no number to report'):
        rundata.load_run(run)
    # a bag the failed run left damaged (the process killed while writing) names nothing; run.json names the run
    mcap = next((run / 'bag').rglob('*.mcap'))
    mcap.write_bytes(mcap.read_bytes()[:200])
    loaded, failed = rundata.load_runs([run])
    assert loaded == [] and [(f.strategy, f.scenario) for f in failed] == [('ceco-ioch', 'sc03')]
    assert failed[0].reason.startswith('stalled: no new plant step')
    # ... and without a strategy in run.json (older run directories), the directory's name stands for it
    info = json.loads((run / 'run.json').read_text())
    del info['strategy']
    (run / 'run.json').write_text(json.dumps(info))
    assert [(f.strategy, f.scenario) for f in rundata.load_runs([run])[1]] == [('run', 'sc03')]


def test_a_saved_run_whose_controller_did_not_control_it_is_failed(results, tmp_path):
    """A run directory with metrics.json ``status: failed`` and no run.json (``ceco benchmark --save-runs``) is
    failed with metrics.json's reason; one with ``status: ok`` loads."""
    saved = tmp_path / 'saved'
    _not_controlled(results['ceco-ioch'], saved)
    (saved / 'run.json').unlink()
    assert rundata.failed_reason(saved) == NOT_CONTROLLED
    assert rundata.failed_reason(tmp_path) is None  # nothing recorded: not failed
    good = write_run(results['baseline'], tmp_path / 'good')
    assert rundata.failed_reason(good) is None
    loaded, failed = rundata.load_runs([tmp_path])
    assert [r.strategy for r in loaded] == ['baseline'] and [f.path for f in failed] == [saved]


def test_a_family_member_beyond_the_plant_model_is_a_failed_member(hot):
    """run_family on the hot scenario: the plant leaves its model (PlantStepError; a traceback before), each member
    is failed with the reason and no number, and the verdict says the matched comfort was not computed and why."""
    fam = vd.run_family(str(hot), setpoints_c=(25.0,), laws=('baseline',), progress=False)
    assert list(fam) == ['baseline@25.0'] and set(fam['baseline@25.0']) == {vd.FAILED_KEY}
    assert fam['baseline@25.0'][vd.FAILED_KEY].startswith(STOPPED)
    v = vd.build_verdict('beyond_the_cycle', {}, fam)
    assert v.family == {} and list(v.family_failed) == ['baseline@25.0']
    text = ' '.join(' '.join(vd.verdict_lines(v)).split())
    assert f'Matched comfort: not computed: 1 of the 1 family runs failed (baseline@25.0: {STOPPED}' in text


def test_a_failed_member_is_on_no_front_and_named(hot, tmp_path):
    """A family of two good members and one failed: a run is matched against the good ones only (the same saving as
    without the failed one), the failed one is named in the lines and kept in verdict.json."""

    def point(d, e):
        return dict(energy_kwh=e, discomfort_pmvh=d, time_to_comfort_s=100.0, pmv_end=0.2, duration_s=600.0)

    good = {'baseline@25.0': point(0.10, 0.44), 'baseline@27.0': point(0.20, 0.34)}
    family = {**good, 'baseline@26.0': {vd.FAILED_KEY: f'{STOPPED}, t = 2 s)'}}
    points = {'ceco': point(0.15, 0.35)}
    v = vd.build_verdict('sc03', points, family)
    assert v.matched['ceco'] == vd.build_verdict('sc03', points, good).matched['ceco']
    assert v.matched['ceco']['energy_saving_pct'] == pytest.approx(100 * (0.39 - 0.35) / 0.39)
    text = ' '.join(' '.join(vd.verdict_lines(v)).split())
    assert 'at 25-27 degC (2 runs, in-' in text  # the failed member counts in no front
    assert f'1 of the 3 family runs failed (baseline@26.0: {STOPPED}, t = 2 s)): on no front.' in text
    data = vd.read_verdict(vd.write_verdict(tmp_path / 'verdict.json', v))
    assert data['family_failed'] == {'baseline@26.0': f'{STOPPED}, t = 2 s)'} and set(data['family']) == set(good)


def test_ceco_report_names_the_failed_family_members_its_job_kept(results, tmp_path, capsys):
    """A job's verdict.json keeps its failed family members (``family_failed``); ceco report reads the family
    from it and names them as the job's verdict did (they were dropped: the report's verdict said nothing)."""
    job = tmp_path / 'job'
    assert (
        sim.main(
            [
                '--scenario',
                'sc03',
                '--strategy',
                'baseline',
                '--duration-s',
                f'{DURATION_S:g}',
                '--baseline-setpoints-c',
                '25,26',
                '--out',
                str(job),
                '--no-progress',
            ]
        )
        == 0
    )
    kept = json.loads((job / 'verdict.json').read_text())
    kept['family_failed'] = {'baseline@27.0': 'the simulation stopped: refrigerant cycle did not converge (test)'}
    (job / 'verdict.json').write_text(json.dumps(kept))
    capsys.readouterr()
    assert report.main([str(job), '--out', str(tmp_path / 'r')]) == 0
    out = capsys.readouterr().out
    assert '1 of the 5 family runs failed (baseline@27.0: the simulation stopped: refrigerant cycle' in out, out
