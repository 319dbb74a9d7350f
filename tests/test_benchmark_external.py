"""`ceco benchmark --controller-cmd`: a third-party controller over real DDS, scored like the built-ins.

The controller (tests/ext_controller_baseline.py) is the production PI re-implemented
against the topics only (rclpy + ceco_msgs, nothing from ceco). Over the lockstep DDS
contract it must score exactly as the in-process `baseline@26.0`: every KPI but the
wall-clock time ratios equal (the DDS path reproduces the simulator bit for bit).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.stack

rclpy = pytest.importorskip('rclpy', reason='stack tests need the sourced ROS 2 workspace')

from ceco_bringup.benchmark import external, runner  # noqa: E402
from ceco_bringup.benchmark.cases import case_from_dict  # noqa: E402
from ceco_bringup.sweep.cells import code_fingerprint  # noqa: E402

NODE = Path(__file__).with_name('ext_controller_baseline.py')


def test_external_controller_over_dds_scores_as_the_builtin_baseline(tmp_path):
    case = case_from_dict(
        {
            'schema': 'ceco-benchmark-case/1',
            'name': 'sc03-90s',
            'version': 1,
            'scenario': 'sc03',
            'duration_s': 90,
            'forecast_uncertainty': 'none',
            'seeds': [0],
        }
    )
    code = code_fingerprint()
    builtin = runner.ControllerSpec('baseline@26.0', 'baseline', 'baseline', (('setpoint_c', 26.0),), 26.0)
    ext = runner.ControllerSpec('external:pi', 'external', 'external')
    (cell_b,), (cell_e,) = runner.case_cells(case, [builtin], code), runner.case_cells(case, [ext], code)
    as_dict = lambda c: {'id': c.id, 'axes': c.axes, 'spec': c.spec}  # noqa: E731
    ref = runner.run_benchmark_cell(as_dict(cell_b))
    row = external.run_external_cell(
        as_dict(cell_e), [sys.executable, str(NODE)], tmp_path / 'ext', command_timeout_s=10.0
    )
    assert ref['status'] == 'ok' and row['status'] == 'ok', row['error']
    assert row['source'] == 'dds' and row['kind'] == 'external'
    for key, value in ref['kpis'].items():
        if key.startswith('time_ratio'):
            continue
        assert row['kpis'][key] == value, key  # bit-identical over DDS
    assert row['kpi_notes'].keys() - {'time_ratio_mean', 'time_ratio_max'} == ref['kpi_notes'].keys() - {
        'time_ratio_mean',
        'time_ratio_max',
    }
    # the time ratio is measured over DDS: 18 control steps, each one finite and positive
    steps = external.step_times_from_bag(tmp_path / 'ext', 5.0)
    assert steps.shape == (18,) and bool(np.all(np.isfinite(steps) & (steps > 0.0)))
    assert row['kpis']['time_ratio_mean'] == pytest.approx(float(np.mean(steps)) / 5.0, rel=1e-9)
    assert row['kpis']['time_ratio_max'] == pytest.approx(float(np.max(steps)) / 5.0, rel=1e-9)
    assert row['kpis']['fallback_steps'] == 0.0 and ref['kpis']['energy_kwh'] > 0.0
    run_json = json.loads((tmp_path / 'ext' / 'run.json').read_text())
    assert (run_json['status'], run_json['error'], run_json['strategy']) == ('complete', '', 'external')
    # the documented QoS matches every reader of hvac/command: rmw warns of no incompatible one
    log = (tmp_path / 'ext' / 'logs' / 'external_controller.log').read_text()
    assert 'incompatible QoS' not in log, log[-2000:]


def test_a_command_sent_before_its_state_does_not_time_the_step(tmp_path):
    """The step time is the first command of step k sent after state k (rmw send times): a controller that published
    commands ahead of the states got a negative time ratio (-0.068, tester's) that --validate accepted. Step 0: an
    early command, then one 40 ms after the state; step 1: only early ones (no time); step 2: 10 ms after."""
    s = 1_000_000_000
    sent = {
        'cabin/state': [[0, 10 * s], [1, 11 * s], [5, 15 * s], [10, 20 * s]],  # plant steps; Ts 5 s of 1-s steps
        'hvac/command': [[0, 9 * s], [0, 10 * s + 40_000_000], [1, 14 * s], [2, 20 * s + 10_000_000]],
    }
    (tmp_path / 'send_times.json').write_text(json.dumps(sent))
    steps = external.step_times_from_bag(tmp_path, 5.0)
    assert steps.tolist() == pytest.approx([0.04, 0.01])


def test_a_child_that_printed_nothing_is_said_so_not_quoted_with_the_supervisors_header():
    """A controller that exits 0 at once: its reason quoted ceco's own log header (`--- start 1: python x.py`) as
    if it were the controller's last words. A traceback's last line is still what is quoted."""
    head = 'controller exited with status 0 while waiting for the nodes; log: /o/logs/external_controller.log'
    said = external.one_line_error(f'{head}\n--- start 1: python /x/bad.py exit0')
    assert said == (
        'controller exited with status 0 while waiting for the nodes: it printed nothing; '
        'log: /o/logs/external_controller.log'
    )
    boom = external.one_line_error(f'{head}\n--- start 1: python x.py\nTraceback ...\nRuntimeError: boom\n')
    assert boom.startswith('controller exited with status 0 while waiting for the nodes: RuntimeError: boom; log: ')
    assert external.one_line_error('no log here') == 'no log here'


# What the node publishes instead of a command: nothing, NaN, a blower flow above its range.
NOT_CONTROLLING = {
    'silent': '        pass\n',
    'nan': '        cmd.blower_flow_kgps = float("nan")\n        self.pub.publish(cmd)\n',
    'out-of-range': '        cmd.blower_flow_kgps = 0.5\n        self.pub.publish(cmd)\n',
}


# ... and what its failed run's reason ends with (the plant's first rejection comes from its log).
WHY = {
    'silent': '; the controller sent no hvac/command (log: {ext}/logs/external_controller.log)',
    'nan': '; plant_node rejected 4 of 4 commands, first: step 0: blower_flow_kgps=nan is not finite '
    '(log: {ext}/logs/plant_node.log)',
    'out-of-range': '; plant_node rejected 4 of 4 commands, first: step 0: blower_flow_kgps=0.5 is outside the '
    'plausible range [0.05, 0.17] (log: {ext}/logs/plant_node.log)',
}


def _case(name: str, duration_s: float):
    return case_from_dict(
        {
            'schema': 'ceco-benchmark-case/1',
            'name': name,
            'version': 1,
            'scenario': 'sc03',
            'duration_s': duration_s,
            'forecast_uncertainty': 'none',
            'seeds': [0],
        }
    )


@pytest.mark.parametrize('what', sorted(NOT_CONTROLLING))
def test_a_controller_that_never_commands_is_a_failed_run(tmp_path, what):
    """A node that never sends an acceptable command (issue 17 item 1): the plant rejects NaN and
    out-of-range commands (never clamps them), its watchdog applies the ACC law every control period,
    and the run, whose KPIs are then the fallback law's, is failed: KPIs kept, never matched."""
    case = case_from_dict(
        {
            'schema': 'ceco-benchmark-case/1',
            'name': 'sc03-20s',
            'version': 1,
            'scenario': 'sc03',
            'duration_s': 20,
            'forecast_uncertainty': 'none',
            'seeds': [0],
        }
    )
    node = tmp_path / f'{what}.py'
    node.write_text(NODE.read_text().replace('        self.pub.publish(cmd)\n', NOT_CONTROLLING[what]))
    spec = runner.ControllerSpec(f'external:{what}', 'external', 'external')
    (cell,) = runner.case_cells(case, [spec], code_fingerprint())
    row = external.run_external_cell(
        {'id': cell.id, 'axes': cell.axes, 'spec': cell.spec},
        [sys.executable, str(node)],
        tmp_path / 'ext',
        command_timeout_s=0.5,
    )
    assert row['status'] == 'failed', (row['status'], row['error'])
    assert 'did not control the run: 4 of 4 control steps in fallback' in row['error']
    # the reason says why: what the plant refused (counted from the bag) and its first reason, with the log
    assert row['error'].endswith(WHY[what].format(ext=tmp_path / 'ext')), row['error']
    assert row['kpis']['fallback_steps'] == 4.0  # 20 s / Ts 5 s, all from the plant's law
    assert row['kpis']['energy_kwh'] > 0.0  # kept
    log = (tmp_path / 'ext' / 'logs' / 'plant_node.log').read_text()
    assert ('rejected hvac/command' in log) is (what != 'silent')
    # its run directory says failed, with the same reason: ceco report names it and shows no number
    from ceco_bringup import rundata

    assert rundata.failed_reason(tmp_path / 'ext') == row['error']
    loaded, failed = rundata.load_runs([tmp_path / 'ext'])
    assert loaded == [] and [(f.strategy, f.scenario) for f in failed] == [('external', 'sc03')]
    # the same runs as the plant's law at 26 degC: matched, that would have read "+0.0 % saved"
    base = runner.ControllerSpec('baseline@26.0', 'baseline', 'baseline', (('setpoint_c', 26.0),), 26.0)
    (ref_cell,) = runner.case_cells(case, [base], code_fingerprint())
    ref = runner.run_benchmark_cell({'id': ref_cell.id, 'axes': ref_cell.axes, 'spec': ref_cell.spec})
    assert row['kpis']['energy_kwh'] == ref['kpis']['energy_kwh']
    entry = runner.assemble_case(case, [row, ref])
    assert entry['matched'] == {} and [r['status'] for r in entry['runs']] == ['ok', 'failed']


def test_a_controller_that_raises_is_one_error_line(tmp_path):
    """A node whose callback raises at step 1 exits: the run's error is one line, the exception and the
    log's path (the console and the report print it as is); the traceback is in the controller's log."""
    node = tmp_path / 'raises.py'
    node.write_text(
        NODE.read_text().replace(
            '        self.pub.publish(cmd)\n',
            '        if k == 1:\n            raise RuntimeError(f"boom at step {k}")\n        self.pub.publish(cmd)\n',
        )
    )
    spec = runner.ControllerSpec('external:raises', 'external', 'external')
    (cell,) = runner.case_cells(_case('sc03-20s', 20), [spec], code_fingerprint())
    row = external.run_external_cell(
        {'id': cell.id, 'axes': cell.axes, 'spec': cell.spec}, [sys.executable, str(node)], tmp_path / 'ext'
    )
    log = tmp_path / 'ext' / 'logs' / 'external_controller.log'
    assert row['status'] == 'error'
    assert row['error'] == f'RuntimeError: controller exited with status 1: RuntimeError: boom at step 1; log: {log}'
    assert 'Traceback (most recent call last)' in log.read_text()


def test_plant_rejections_counts_from_the_bag_and_quotes_the_first_logged_reason(tmp_path):
    """The count is the commands recorded minus the control steps they drove (the plant's law drove the
    others); the reason the first rejection line of plant_node's log, whatever the throttle left out."""
    logs = tmp_path / 'logs'
    logs.mkdir()
    (logs / 'plant_node.log').write_text(
        '[INFO] [1.0] [plant_node]: started step 0\n'
        '[WARN] [2.0] [plant_node]: rejected hvac/command step 1: future: waiting for step 0\n'
        '[WARN] [3.0] [plant_node]: rejected hvac/command step 1: blower_flow_kgps=5.0 is outside the plausible '
        'range [0.05, 0.17] (3 similar rejections since the last line)\n'
    )
    fallback = [False] * 20
    fallback[5:15] = [True] * 10  # 4 control steps of 5 plant steps, the 2nd and 3rd on the plant's law
    why = external.plant_rejections(tmp_path, fallback, 7, 5)
    assert why == (
        f'plant_node rejected 5 of 7 commands, first: step 1: future: waiting for step 0 (log: {logs}/plant_node.log)'
    )
    assert external.plant_rejections(tmp_path, fallback, 2, 5) == ''  # every command drove its step
    assert external.plant_rejections(tmp_path, fallback, 0, 5) == (
        f'the controller sent no hvac/command (log: {logs}/external_controller.log)'
    )


def test_external_cell_id_is_the_controller_name_command_and_directory():
    """Each of the name, the command and the directory makes another cell; the same three, the same cell."""
    case, code = _case('sc03-20s', 20), code_fingerprint()

    def cell_id(name='external:pi', command=('python', 'pi.py'), cwd='/w'):
        spec = runner.ControllerSpec(name, 'external', 'external', command=command, cwd=cwd)
        (cell,) = runner.case_cells(case, [spec], code)
        return cell.id

    ref = cell_id()
    assert cell_id() == ref
    others = [
        cell_id(name='external:pi2'),
        cell_id(command=('python', 'nan.py')),
        cell_id(command=('python', 'pi.py', 'x')),
        cell_id(cwd='/v'),
    ]
    assert len({ref, *others}) == 5


def test_another_controller_in_the_same_out_runs_its_own_cells(tmp_path):
    """Issue: every external controller had one cell id, so a second controller in the same --out was
    "already done" with the first one's score. Now another command or name runs; the same command resumes."""
    import json

    from ceco_bringup.benchmark import cli

    case = tmp_path / 'c20.yaml'
    case.write_text(
        'schema: ceco-benchmark-case/1\nname: c20\nversion: 1\nscenario: sc03\nduration_s: 20\n'
        'forecast_uncertainty: none\nseeds: [0]\n'
    )
    lazy = tmp_path / 'lazy.py'  # the PI with the evaporator held at 10 degC: another controller, other KPIs
    text = NODE.read_text()
    assert '        cmd.evap_setpoint_c = 10.0 - ' in text
    lazy.write_text(
        text.replace('        cmd.evap_setpoint_c = 10.0 - ', '        cmd.evap_setpoint_c = 10.0 + 0.0 * ')
    )
    out = tmp_path / 'out'

    def bench(path, name):
        said = []
        doc = cli.run_benchmark(
            [str(case)],
            out,
            workers=2,
            progress=False,
            log=lambda *a, **k: said.append(' '.join(map(str, a))),
            setpoints_c=(26.0,),
            setpoints_pmv=(0.0,),
            sensitivity=False,
            strategies=(),
            controller_cmd=f'{sys.executable} {path}',
            controller_name=name,
        )
        (run,) = [r for r in doc['cases'][0]['runs'] if r['kind'] == 'external']
        n = len(doc['cases'][0]['runs'])
        return run, said[0], n

    first, said, n = bench(NODE, 'pi')
    assert f'{n} runs, 0 already done, {n} to run' in said
    assert first['status'] == 'ok', first['error']
    second, said, _ = bench(lazy, 'pi')  # another command, the same name
    assert f'{n} runs, {n - 1} already done, 1 to run' in said
    assert second['status'] == 'ok', second['error']
    assert second['kpis']['energy_kwh'] < 0.9 * first['kpis']['energy_kwh']  # its own run: less cooling
    again, said, _ = bench(NODE, 'pi')  # the first one again: resumed, its own score
    assert f'{n} runs, {n} already done, 0 to run' in said
    assert again['kpis'] == first['kpis']
    renamed, said, _ = bench(NODE, 'pi-b')  # the same command under another name: another controller
    assert f'{n} runs, {n - 1} already done, 1 to run' in said
    assert renamed['controller'] == 'external:pi-b'
    logged = [json.loads(line) for line in (out / 'cells.jsonl').read_text().splitlines()]
    ext = [(r['controller'], r['kpis']['energy_kwh']) for r in logged if r['kind'] == 'external']
    assert len({r['cell_id'] for r in logged if r['kind'] == 'external'}) == 3  # three controllers, each run once
    assert ext == [
        ('external:pi', first['kpis']['energy_kwh']),
        ('external:pi', second['kpis']['energy_kwh']),
        ('external:pi-b', renamed['kpis']['energy_kwh']),
    ]


def test_uncertainty_level_over_dds_equals_the_simulator(tmp_path):
    """The benchmark's forecast-uncertainty level set as a preview_node parameter: the DDS
    previews equal make_previews' and the ceco-ioch closed loop equals the simulator's."""
    import json
    import subprocess

    import numpy as np

    from ceco_bringup import bagio
    from ceco_controller.closed_loop import SimSettings, simulate
    from ceco_v2x_preview.preview import make_previews, parse_quality
    from ceco_v2x_preview.scenario import load_scenario

    quality = 'uncertain:high,seed=4'
    out = tmp_path / 'run'
    p = subprocess.run(
        [
            sys.executable,
            '-m',
            'ceco_bringup.cli',
            'run',
            '--scenario',
            'sc03',
            '--strategy',
            'ceco-ioch',
            '--duration-s',
            '40',
            '--preview',
            quality,
            '--out',
            str(out),
            '--no-progress',
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert p.returncode == 0, p.stdout + p.stderr
    sc, q = load_scenario('sc03'), parse_quality(quality)
    previews = list(bagio.read_messages(out / 'bag', ('v2x/weather_preview', 'v2x/traffic_preview')))
    kinds = [name for name, _, _ in previews]
    assert kinds.count('v2x/weather_preview') == kinds.count('v2x/traffic_preview') == 8  # 40 s / 5 s
    for _, _, m in previews:
        ref = make_previews(sc, 5.0 * m.step_index, 5.0, 7, q)
        if hasattr(m, 't_amb_c'):
            np.testing.assert_array_equal(np.asarray(m.t_amb_c), ref.t_amb_c)
            np.testing.assert_array_equal(np.asarray(m.solar_wm2), ref.solar_wm2)
        else:
            np.testing.assert_array_equal(np.asarray(m.speed_mps), ref.speed_mps)
    sim = simulate('sc03', 'ceco-ioch', SimSettings(duration_s=40.0, preview_quality=q, progress=False)).metrics
    metrics = json.loads((out / 'metrics.json').read_text())
    assert any(
        make_previews(sc, 5.0, 5.0, 7, q).t_amb_c != make_previews(sc, 5.0, 5.0, 7, parse_quality('perfect')).t_amb_c
    )  # the level does change the previews
    for key in ('E_tot_J', 'I_pmv', 'otc_violation_pct'):
        assert metrics[key] == sim[key], key


def test_two_workers_run_their_external_cells_on_two_private_domains_whatever_the_users_domain(tmp_path, monkeypatch):
    """The docs promise each external cell a private ROS_DOMAIN_ID: with the user's ROS_DOMAIN_ID set, every worker
    used it, so two cells run at once shared one domain. Now each takes a private id no other ceco process holds."""
    import json

    from ceco_bringup.benchmark import cli

    case = tmp_path / 'c20.yaml'
    case.write_text(
        'schema: ceco-benchmark-case/1\nname: c20\nversion: 1\nscenario: sc03\nduration_s: 20\n'
        'forecast_uncertainty: low\nseeds: [0, 1, 2, 3, 4]\n'
    )
    monkeypatch.setenv('ROS_DOMAIN_ID', '0')
    doc = cli.run_benchmark(
        [str(case)],
        tmp_path / 'out',
        workers=2,
        progress=False,
        log=lambda *a, **k: None,
        setpoints_c=(26.0,),
        setpoints_pmv=(0.0,),
        sensitivity=False,
        strategies=(),
        controller_cmd=f'{sys.executable} {NODE}',
        controller_name='pi',
    )
    runs = [r for r in doc['cases'][0]['runs'] if r['kind'] == 'external']
    assert sorted(r['seed'] for r in runs) == [0, 1, 2, 3, 4] and all(r['status'] == 'ok' for r in runs), runs
    domains = [json.loads(m.read_text())['ros_domain_id'] for m in (tmp_path / 'out').rglob('metrics.json')]
    assert len(domains) == 5 and 0 not in domains and len(set(domains)) >= 2, domains  # (the two workers' own)
