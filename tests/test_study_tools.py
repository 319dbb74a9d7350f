"""The study tools that read a run window by window (``tools/phase_energy.py``) and from a run's state
(``tools/split_study.py --case``): what they compute is what the runs hold."""

import csv
import pathlib
import sys

import numpy as np
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / 'tools'))

import phase_energy  # noqa: E402  (tools/)
import split_study  # noqa: E402  (tools/)

COLUMNS = (
    't_s',
    'p_comp_w',
    'p_blower_w',
    'p_cond_fan_w',
    't_evap_sp_c',
    'mdot_bl_kgps',
    'pmv',
    'pmv_lb',
    'pmv_ub',
    *phase_energy.END_STATES,
)


def _run_dir(path: pathlib.Path, p_comp_w, n: int = 10) -> pathlib.Path:
    """A run directory whose timeseries has ``n`` 1-s steps, the compressor at ``p_comp_w(t)``."""
    path.mkdir()
    with (path / 'timeseries.csv').open('w', newline='', encoding='utf-8') as fh:
        w = csv.writer(fh)
        w.writerow(COLUMNS + ('strategy',))
        for k in range(n):
            ends = [25.0 + k, 40.0, 41.0, 36.0, 3.0 + k]
            w.writerow([k, p_comp_w(k), 100.0, 50.0, 3.0 + (k >= 5), 0.15, 0.4, -0.5, 0.5, *ends, 'x'])
    return path


def test_phase_energy_integrates_each_window_and_prints_the_difference(tmp_path, capsys):
    a = _run_dir(tmp_path / 'a', lambda k: 1000.0 if k < 5 else 2000.0)
    b = _run_dir(tmp_path / 'b', lambda k: 900.0 if k < 5 else 2000.0)
    ts = phase_energy.read_timeseries(str(a))
    wins = phase_energy.windows_of('0,5,END', 10.0)
    assert wins == [(0.0, 5.0), (5.0, 10.0)]
    rows = phase_energy.window_table(ts, wins)
    assert rows[0]['energy_kwh'] == pytest.approx(1150.0 * 5 / 3.6e6, rel=1e-12)
    assert rows[1]['energy_kwh'] == pytest.approx(2150.0 * 5 / 3.6e6, rel=1e-12)
    assert (rows[0]['t_evap_sp_c'], rows[1]['t_evap_sp_c']) == (3.0, 4.0)
    assert phase_energy.main([str(a), str(b), '--windows', '0,5,END', '--names', 'A,B']) == 0
    out = capsys.readouterr().out
    assert f'| 0-5 | {1150 * 5 / 3.6e6:.4f} | {1050 * 5 / 3.6e6:.4f} | {-100 * 5 / 3.6e6:+.4f} |' in out
    assert '| 5-10 | ' in out and '+0.0000 |' in out
    assert '| A | 34.00 | 40.00 | 41.00 | 36.00 | 12.00 |' in out  # the last row's states
    with pytest.raises(SystemExit, match='increasing'):
        phase_energy.windows_of('0,5,5', 10.0)
    with pytest.raises(SystemExit, match='fewer than two plant steps'):
        phase_energy.window_table(ts, [(0.0, 1.0)])
    with pytest.raises(SystemExit, match='same time grid'):
        phase_energy.main([str(a), str(_run_dir(tmp_path / 'c', lambda k: 0.0, n=8))])


def test_split_study_starts_from_the_runs_state_and_reads_the_model_at_the_plants_pmv():
    """``--case``: the commands of the benchmark's run replayed on the case's plant reach the run's own state at
    T, bit for bit; at the run's set-point the control model, read against its offset, needs the plant's flow."""
    res = split_study.run_study('hotsoak-pulldown', 'ceco-pmv', 0, 700.0, 120.0, 0.49)
    for k in ('t_cab_c', 't_int_c', 't_shell_c', 't_evap_c', 'rh_cab'):
        assert res['start'][k] == res['run_state'][k], k
    plant, model = res['rows'][3.0]  # the run's set-point there: the coil's 3 degC floor
    assert plant is not None and model is not None
    assert abs(plant[0] - model[0]) < 0.001  # [kg/s]: the grid's interpolation only
    assert 0.3 < res['offset'] < 0.6  # the model's open-loop PMV sits above the plant's there (docs/results.md)
    powers = {sp: r[0][1] for sp, r in res['rows'].items() if r[0] is not None}
    assert min(powers, key=powers.get) == 3.0 and len(powers) >= 4
    assert np.all(np.diff([res['rows'][sp][0][0] for sp in sorted(powers)]) > 0)  # a warmer coil needs more air
