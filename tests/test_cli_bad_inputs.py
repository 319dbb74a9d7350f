"""Bad input to `ceco report`, `ceco benchmark --validate` and `ceco play`: one line on stderr naming what is
wrong (and the fix), exit status 2, no traceback, and nothing started (play refuses before any node)."""

import pytest
from bag_helpers import sample
from cli_helpers import one_error_line
from scenario_cases import BEYOND_THE_CYCLE

from ceco_bringup import bag_writer, bagio, play, report
from ceco_bringup.benchmark import cli as bench_cli

STATE = 'ceco_msgs/msg/CabinState'
CMD = 'ceco_msgs/msg/AcCommand'
FLAGS = ('--scenario', 'sc03', '--strategy', 'baseline', '--control-period-s', '5', '--horizon-steps', '6')
"""What a bag without ceco metadata does not say, so that --compare gets as far as the namespace."""


# --------------------------------------------------------------------------- ceco report
@pytest.mark.parametrize(
    'text', ['[1, 2]', '"just a string"', '', '{"strategy": '], ids=['list', 'str', 'empty', 'cut']
)
def test_report_names_a_metrics_json_that_is_not_a_json_object(tmp_path, capsys, text):
    run = tmp_path / 'run'
    run.mkdir()
    (run / 'metrics.json').write_text(text)
    (run / 'timeseries.csv').write_text('t_s\n0\n5\n')
    assert report.main([str(run), '--out', str(tmp_path / 'rep')]) == 2
    err = one_error_line(capsys.readouterr().err)
    assert f'{run / "metrics.json"}:' in err


def test_report_names_a_corrupt_run_json(tmp_path, capsys):
    run = tmp_path / 'run'
    run.mkdir()
    (run / 'metrics.json').write_text('{}')
    (run / 'timeseries.csv').write_text('t_s\n0\n5\n')
    (run / 'run.json').write_bytes(b'')
    assert report.main([str(run), '--out', str(tmp_path / 'rep')]) == 2
    err = one_error_line(capsys.readouterr().err)
    assert f'{run / "run.json"}: not a JSON file' in err and 'remove it' in err


# --------------------------------------------------------------------------- ceco benchmark --validate
def test_validate_refuses_a_binary_file_and_an_empty_path(tmp_path, capsys):
    binary = tmp_path / 'results.json'
    binary.write_bytes(b'\xff\xfe')
    assert bench_cli.main(['--validate', str(binary)]) == 2
    assert f'{binary}: not a UTF-8 text file' in one_error_line(capsys.readouterr().err)
    assert bench_cli.main(['--validate', '']) == 2
    err = one_error_line(capsys.readouterr().err)
    assert '--validate: the path is empty' in err and '--out' not in err
    # a CSV, a directory, no file: named in words, not Python's ('Expecting value: line 1 column 1', '[Errno 21]')
    csv = tmp_path / 'kpis.csv'
    csv.write_text('controller,energy_kwh\nceco,0.3\n')
    for path, said in (
        (csv, f'{csv}: not a JSON file (Expecting value at line 1, column 1): give a results.json ceco benchmark'),
        (tmp_path, f'{tmp_path}: a directory: give the results.json in it'),
        (tmp_path / 'none.json', f"{tmp_path / 'none.json'}: not found"),
    ):
        assert bench_cli.main(['--validate', str(path)]) == 2
        assert one_error_line(capsys.readouterr().err).startswith(f'ceco benchmark: {said}')


# --------------------------------------------------------------------------- ceco play
def _bag(path, n=5, topic='/cabin/state'):
    store = bagio.typestore()
    w = bag_writer.BagWriter(path)
    w.add_topic(topic, STATE)
    for k in range(n):
        w.write(topic, k * 10**9, store.serialize_cdr(sample(store, STATE, k, stamp_ns=k * 10**9), STATE))
    w.close()
    return path


def _cut_short(bag):
    mcap = next(bag.glob('*.mcap'))
    mcap.write_bytes(mcap.read_bytes()[:-200])


def _emptied(bag):
    next(bag.glob('*.mcap')).write_bytes(b'')


def _corrupt_metadata(bag):
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: [unclosed\n')


@pytest.mark.parametrize('damage', [_cut_short, _emptied, _corrupt_metadata], ids=['cut', 'empty', 'metadata'])
@pytest.mark.parametrize('compare', [False, True], ids=['play', 'compare'])
def test_play_refuses_a_damaged_bag_as_report_does(tmp_path, capsys, damage, compare):
    bag = _bag(tmp_path / 'bag')
    damage(bag)
    assert play.main([str(bag), '--no-progress', *(['--compare'] if compare else [])]) == 2
    err = one_error_line(capsys.readouterr().err)
    assert f'ceco play: error: {bag}: cannot read the bag: ReaderError' in err


def test_play_refuses_a_topic_the_bag_does_not_hold(tmp_path, capsys):
    bag = _bag(tmp_path / 'bag')
    with pytest.raises(SystemExit) as exc:
        play.main([str(bag), '--no-progress', '--topics', '/nonexistent', '/cabin/state'])
    assert exc.value.code == 2
    err = one_error_line(capsys.readouterr().err)
    assert '--topics: /nonexistent not in the bag' in err and err.rstrip().endswith(
        '/cabin/state (ceco play --help lists the options)'
    )


def test_play_compare_refuses_a_namespace_the_bag_does_not_hold(tmp_path, capsys):
    bag = _bag(tmp_path / 'bag', topic='/veh1/cabin/state')
    with pytest.raises(SystemExit) as exc:
        play.main([str(bag), '--no-progress', '--compare', '--namespace', 'bogus', *FLAGS])
    assert exc.value.code == 2
    err = one_error_line(capsys.readouterr().err)
    assert '--namespace bogus: not in the bag' in err and 'namespaces, /veh1' in err


def test_play_compare_asks_which_namespace_of_a_two_vehicle_bag(tmp_path, capsys):
    """Without --namespace on a bag of two stacks: refused before any node starts, naming the flag (not a damaged
    bag)."""
    store = bagio.typestore()
    bag = tmp_path / 'bag'
    topics = {
        f'/{ns}/{t}': typ for ns in ('veh1', 'veh2') for t, typ in (('cabin/state', STATE), ('hvac/command', CMD))
    }
    w = bag_writer.BagWriter(bag)
    for topic, typ in topics.items():
        w.add_topic(topic, typ)
    for k in range(3):
        for topic, typ in topics.items():
            w.write(topic, k * 10**9, store.serialize_cdr(sample(store, typ, k, stamp_ns=k * 10**9), typ))
    w.close()
    assert play.main([str(bag), '--no-progress', '--compare', *FLAGS]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if not line.startswith('ceco play --compare: ')]
    assert err == [
        "ceco play: error: the bag holds ['hvac/command'] under several namespaces ('/veh1', '/veh2'): say which one "
        'with --namespace'
    ]


def test_missing_topics_and_namespace_messages():
    assert play.missing_topics_message(['/a'], {'/a': 1, '/b': 2}) is None
    assert play.missing_topics_message(['/c', '/a'], {'/b': 2, '/a': 1}).startswith('--topics: /c not in the bag')
    held = {'/cabin/state': 3, '/veh2/cabin/state': 3, '/clock': 3}
    assert play.namespace_message(None, held) is None and play.namespace_message('/veh2/', held) is None
    assert play.namespace_message('', held) is None  # the root namespace
    assert play.namespace_message('veh3', held).endswith('namespaces, /, /veh2')
    assert 'no cabin/state under any namespace' in play.namespace_message(None, {'/clock': 1})


@pytest.mark.parametrize('verb', ['report', 'play', 'run'])
def test_an_invalid_namespace_is_refused_when_the_command_line_is_read(tmp_path, capsys, verb):
    """`--namespace 1veh` (not a ROS name) is refused by the parser, in every verb that takes it, before any file
    is read or node started (report and play checked it only once a bag was read: ceco report said so after
    loading the runs, and on a run without a bag not at all)."""
    from ceco_bringup import run

    main = {'report': report.main, 'play': play.main, 'run': run.main}[verb]
    args = {'report': [str(tmp_path)], 'play': [str(tmp_path)], 'run': ['--scenario', 'sc03']}[verb]
    with pytest.raises(SystemExit) as exc:
        main(
            [*args, '--namespace', '1veh', '--out', str(tmp_path / 'o')]
            if verb != 'play'
            else [*args, '--namespace', '1veh']
        )
    assert exc.value.code == 2
    assert one_error_line(capsys.readouterr().err) == (
        f"ceco {verb}: error: argument --namespace: invalid namespace '1veh': tokens of letters, digits and "
        f'underscores, not starting with a digit, separated by / (ceco {verb} --help lists the options)'
    )
    assert list(tmp_path.iterdir()) == []  # nothing written (no --out for report and run, nothing by play)


# --------------------------------------------------------------------------- ceco sim / ceco run
@pytest.mark.parametrize('verb', ['sim', 'run'])
def test_a_control_period_a_strategy_cannot_run_is_refused_before_any_run(tmp_path, capsys, verb):
    """--control-period-s 7 with an NMPC strategy (its model steps 5 s): refused when the command line is checked,
    naming the strategies (ceco sim ran the baseline first, then stopped at ceco with exit status 2)."""
    from ceco_bringup import run, sim

    main = {'sim': sim.main, 'run': run.main}[verb]
    with pytest.raises(SystemExit) as exc:
        main(
            [
                '--scenario',
                'sc03',
                '--strategy',
                'baseline,ceco',
                '--control-period-s',
                '7',
                '--out',
                str(tmp_path / 'o'),
            ]
        )
    assert exc.value.code == 2
    assert one_error_line(capsys.readouterr().err) == (
        f'ceco {verb}: error: --control-period-s: control period 7.0 s must be a whole multiple of the model step '
        f'5.0 s (the NMPC strategies: ceco) (ceco {verb} --help lists the options)'
    )
    assert not (tmp_path / 'o').exists()


@pytest.mark.parametrize('evaluation', ['compiled', 'python'])
def test_both_plant_evaluations_raise_the_plant_step_error(evaluation):
    """The compiled step (on its flag) and the Python step (the cycle solve's own check) raise PlantStepError, the
    one error `ceco sim` turns into a failed run."""
    from ceco_controller.closed_loop import SimSettings, simulate
    from ceco_plant_sim.plant_ops import PlantStepError
    from ceco_v2x_preview.scenario import scenario_from_dict

    with pytest.raises(PlantStepError, match=r'^refrigerant cycle did not converge in 30 iterations \('):
        simulate(
            scenario_from_dict(BEYOND_THE_CYCLE), 'baseline', SimSettings(progress=False, plant_evaluation=evaluation)
        )


def test_a_run_the_plant_cannot_simulate_is_a_failed_run_not_a_traceback(tmp_path, capsys):
    """Beyond the refrigerant model (60 degC air, 1400 W/m2, the cabin soaked at 70 degC) each run is a failed run
    with the reason, and the job goes on to the next strategy (it was a traceback that lost the other strategies);
    exit status 1."""
    import json

    import yaml

    from ceco_bringup import sim

    path = tmp_path / 'hot.yaml'
    path.write_text(yaml.safe_dump(BEYOND_THE_CYCLE))
    out = tmp_path / 'o'
    argv = ['--scenario', str(path), '--strategy', 'baseline,ceco', '--no-progress', '--out', str(out)]
    assert sim.main(argv) == 1
    text = capsys.readouterr()
    assert 'Traceback' not in text.err + text.out
    why = 'the simulation stopped: refrigerant cycle did not converge in 30 iterations ('  # compiled or Python plant
    for strategy in ('baseline', 'ceco'):
        assert f'{strategy:>10}: FAILED: {why}' in text.out, text.out
        run = json.loads((out / strategy / 'run.json').read_text())
        assert run['status'] == 'failed' and run['error'].startswith(why), run
        assert not (out / strategy / 'metrics.json').exists()
    assert '2 of 2 runs failed (not compared):' in text.out


def test_a_bad_model_file_is_named_as_such_not_as_a_control_period_error(tmp_path, capsys):
    """The up-front Ts check reads the NMPC's model file: a file that is not one says so by itself (the check
    prefixed it with "scenario sc03: control.control_period_s")."""
    from ceco_bringup import sim

    bad = tmp_path / 'bad.yaml'
    bad.write_text('foo: 1\n')
    with pytest.raises(SystemExit) as exc:
        sim.main(
            [
                '--scenario',
                'sc03',
                '--strategy',
                'baseline,ceco',
                '--model-params',
                str(bad),
                '--out',
                str(tmp_path / 'o'),
            ]
        )
    assert exc.value.code == 2
    err = one_error_line(capsys.readouterr().err)
    assert err.startswith(f'ceco sim: error: {bad}: ') and 'control_period_s' not in err, err


BEYOND_THE_PREVIEW_NODE = {  # a flag value the parser took and preview_node then refused (a failed run, exit 1)
    'delay': (
        ['--preview', 'delayed:1e12'],
        "preview quality: delayed: 1e+12 s is outside 0..86400 s, the range of preview_node's faults.delay_s",
    ),
    'seed': (['--seed', '3000000000'], "argument --seed: must be a whole number in 0..2147483647, got '3000000000'"),
}


@pytest.mark.parametrize('verb', ['sim', 'run'])
@pytest.mark.parametrize('what', sorted(BEYOND_THE_PREVIEW_NODE))
def test_a_value_beyond_the_preview_nodes_range_is_refused_before_any_run(tmp_path, capsys, verb, what):
    """--preview delayed:1e12 and --seed 3000000000: refused when the command line is checked, naming preview_node's
    range (ceco run started the stack, preview_node exited on faults.delay_s or faults.seed out of range, and the
    run was reported FAILED, exit status 1, in several lines)."""
    from ceco_bringup import run, sim

    flags, says = BEYOND_THE_PREVIEW_NODE[what]
    main = {'sim': sim.main, 'run': run.main}[verb]
    with pytest.raises(SystemExit) as exc:
        main(['--scenario', 'sc03', '--strategy', 'baseline', *flags, '--out', str(tmp_path / 'o')])
    assert exc.value.code == 2
    assert (
        one_error_line(capsys.readouterr().err) == f'ceco {verb}: error: {says} (ceco {verb} --help lists the options)'
    )
    assert not (tmp_path / 'o').exists()


# --------------------------------------------------------------------------- a reader that leaves early
@pytest.mark.parametrize('verb', ['help', 'sim'])
def test_a_reader_that_closes_the_pipe_stops_the_printing_not_the_job(tmp_path, verb):
    """`ceco sim ... | head -1`: the first table line after head left raised BrokenPipeError, a traceback and exit
    status 1, and the job's files (written after the table) were never written. Now the rest of the output goes
    to /dev/null: no traceback, the verb's own exit status, every file written."""
    import os
    import subprocess
    import sys

    out = tmp_path / 'job'
    args = (
        ['--help']
        if verb == 'help'
        else ['sim', '--strategy', 'baseline', '--duration-s', '20', '--no-progress', '--baseline-setpoints-c', 'none']
        + ['--out', str(out)]
    )
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before the first line
    try:
        p = subprocess.run(
            [sys.executable, '-m', 'ceco_bringup.cli', *args], stdout=write_end, stderr=subprocess.PIPE, text=True
        )
    finally:
        os.close(write_end)
    assert p.returncode == 0 and 'Traceback' not in p.stderr and 'BrokenPipe' not in p.stderr, p.stderr
    if verb == 'sim':
        files = {'comparison.csv', 'comparison.txt', 'summary.txt', 'verdict.json'}
        assert files <= {f.name for f in out.iterdir()} and (out / 'baseline' / 'metrics.json').is_file()
