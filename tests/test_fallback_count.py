"""One rejected command is one fallback control step: the plant steps its law drove, and no more.

The plant flags each plant step n its ACC law drove in ``AcPower.fallback`` (step n, [t_n, t_n+1));
``CabinState.fallback`` at t_n is its supervisor's mode when that state goes out, which is still
``true`` at the end of a fallback period (the next command is awaited after it). The time series of
a stack run (``bagio.load_run_timeseries``) flags plant step n by the former alone, and
``ceco_core.run_status.fallback_control_steps`` counts the control steps holding one: a NaN command
at control step 3 of a lockstep run with Ts 5 s and 1-s plant steps is plant steps 15..19 and one
fallback control step (before: the state at t = 20 flagged step 20 as well, and 2 were counted).
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from ceco_bringup import bag_writer, bagio
from ceco_core.run_status import check_control, fallback_control_steps

M, N_CTRL = 5, 12  # plant steps per control period, control steps: 60 s, Ts 5 s, dt 1 s
TYPES = {
    'cabin/state': 'ceco_msgs/msg/CabinState',
    'cabin/comfort': 'ceco_msgs/msg/Comfort',
    'hvac/power': 'ceco_msgs/msg/AcPower',
}


def _ser(type_name: str, **fields) -> bytes:
    """A CDR message of ``type_name`` with ``fields`` set, every other field left at its zero."""
    store = bagio.typestore()
    cls = store.types[type_name]
    zero = {'str': '', 'bool': False, 'int': 0, 'float': 0.0}
    values = {}
    for name, field in cls.__dataclass_fields__.items():
        if name.startswith('__'):
            continue
        if name == 'header':
            values[name] = store.types['std_msgs/msg/Header'](
                stamp=store.types['builtin_interfaces/msg/Time'](sec=0, nanosec=0), frame_id=''
            )
        else:
            values[name] = fields.get(name, zero.get(field.type, np.zeros(0)))
    return store.serialize_cdr(cls(**values), type_name)


def _plant_bag(path: Path, rejected: tuple[int, ...]) -> None:
    """The plant's outputs of a lockstep run whose commands of control steps ``rejected`` were refused.

    As plant_node publishes them (measured: tester's nan3 bag): the power of every plant step of a
    rejected control step says fallback; the state at t_n says it from the first step of the period
    on to the state at its end (t = 20 for step 3), until the next command is accepted.
    """
    drove = {n for k in rejected for n in range(k * M, (k + 1) * M)}
    w = bag_writer.BagWriter(path)
    for topic, type_name in TYPES.items():
        w.add_topic('/' + topic, type_name)
    for n in range(N_CTRL * M):
        t_ns = n * 1_000_000_000
        w.write(
            '/cabin/state',
            t_ns,
            _ser(TYPES['cabin/state'], step_index=n, scenario_time_s=float(n), fallback=n - 1 in drove),
        )
        w.write('/cabin/comfort', t_ns, _ser(TYPES['cabin/comfort'], step_index=n))
        w.write('/hvac/power', t_ns, _ser(TYPES['hvac/power'], step_index=n, fallback=n in drove))
    w.close()


@pytest.mark.parametrize(
    'rejected, plant_steps, control_steps',
    [
        ((3,), list(range(15, 20)), 1),
        ((3, 4), list(range(15, 25)), 2),
        ((0, 11), [0, 1, 2, 3, 4, 55, 56, 57, 58, 59], 2),
    ],
)
def test_a_rejected_control_step_is_its_own_plant_steps(tmp_path, rejected, plant_steps, control_steps):
    _plant_bag(tmp_path / 'bag', rejected)
    ts = bagio.load_run_timeseries(tmp_path / 'bag')
    assert ts['step_index'].tolist() == list(range(N_CTRL * M))
    assert np.flatnonzero(ts['fallback']).tolist() == plant_steps  # the step after the span is the controller's
    assert fallback_control_steps(ts['fallback'], M) == (N_CTRL, control_steps)
    assert check_control(N_CTRL, control_steps).ok  # 2 of 12 are within the allowance


def test_the_count_is_per_plant_step():
    """A control step counts when one of its own plant steps was on the law: the boundaries decide."""
    span = lambda a, b: [a <= n < b for n in range(N_CTRL * M)]  # noqa: E731
    assert fallback_control_steps(span(15, 20), M) == (12, 1)
    assert fallback_control_steps(span(15, 21), M) == (12, 2)  # one plant step more: step 4 too
    assert fallback_control_steps(span(14, 20), M) == (12, 2)  # one before: step 2 too
    assert fallback_control_steps(span(15, 20), M, [3]) == (12, 1)  # the controller's mark on the same step


# ------------------------------------------------------------------ over DDS
NODE = Path(__file__).with_name('ext_controller_baseline.py')


@pytest.mark.stack
@pytest.mark.parametrize('nan_steps, plant_steps', [((3,), list(range(15, 20))), ((3, 4), list(range(15, 25)))])
def test_one_nan_command_is_one_fallback_control_step_over_dds(tmp_path, nan_steps, plant_steps):
    """tests/ext_controller_baseline.py sending NaN at control steps ``nan_steps`` of a 60-s SC03 run."""
    pytest.importorskip('rclpy', reason='stack tests need the sourced ROS 2 workspace')
    from ceco_bringup.benchmark import external, runner
    from ceco_bringup.benchmark.cases import case_from_dict
    from ceco_bringup.sweep.cells import code_fingerprint

    publish = '        self.pub.publish(cmd)\n'
    nan = f'        if k in {nan_steps!r}:\n            cmd.blower_flow_kgps = float("nan")\n'
    node = tmp_path / 'nan.py'
    node.write_text(NODE.read_text().replace(publish, nan + publish))
    case = case_from_dict(
        {
            'schema': 'ceco-benchmark-case/1',
            'name': 'sc03-60s',
            'version': 1,
            'scenario': 'sc03',
            'duration_s': 60,
            'forecast_uncertainty': 'none',
            'seeds': [0],
        }
    )
    (cell,) = runner.case_cells(
        case, [runner.ControllerSpec('external:nan', 'external', 'external')], code_fingerprint()
    )
    run_dir = tmp_path / 'ext'
    row = external.run_external_cell(
        {'id': cell.id, 'axes': cell.axes, 'spec': cell.spec},
        [sys.executable, str(node)],
        run_dir,
        command_timeout_s=0.5,
    )
    log = (run_dir / 'logs' / 'plant_node.log').read_text()
    assert f'rejected hvac/command step {nan_steps[0]}' in log, log[-3000:]  # (the next ones: log throttled)
    assert f'commands resumed at control step {nan_steps[-1] + 1}' in log, log[-3000:]
    metrics = json.loads((run_dir / 'metrics.json').read_text())
    assert (metrics['fallback_steps'], metrics['fallback_control_steps']) == (len(plant_steps), len(nan_steps))
    assert metrics['n_control_steps'] == N_CTRL and metrics['status'] == 'ok'
    with (run_dir / 'timeseries.csv').open() as f:
        flagged = [round(float(r['t_s'])) for r in csv.DictReader(f) if r['fallback'] in ('1', 'True')]
    assert flagged == plant_steps
    assert row['status'] == 'ok' and row['kpis']['fallback_steps'] == float(len(nan_steps)), row['error']
