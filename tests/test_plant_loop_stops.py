"""A plant step the refrigerant model cannot simulate stops plant_node's loop for good, and only that error does."""

import pytest
from scenario_cases import BEYOND_THE_CYCLE

from ceco_core.contracts import AcInput
from ceco_core.supervision import ERROR
from ceco_plant_sim.plant_io import PLANT_PARAMETERS, PlantNodeConfig
from ceco_plant_sim.plant_loop import PLANT_STOPPED_EXIT, PlantLoop, simulation_stopped, stopped_line
from ceco_plant_sim.plant_ops import PlantStepError
from ceco_v2x_preview.scenario import scenario_from_dict

FULL = AcInput(mdot_bl_kgps=0.17, t_evap_sp_c=3.0)


def _started_loop() -> PlantLoop:
    cfg = PlantNodeConfig.from_params({s.name: s.default for s in PLANT_PARAMETERS})
    loop = PlantLoop(scenario_from_dict(BEYOND_THE_CYCLE), cfg)
    assert loop.may_start('', 0.0) and loop.running
    return loop


def test_a_step_beyond_the_cycle_stops_the_loop_for_good():
    """The PlantStepError is raised to the node and kept as the reason; no step follows; diagnostics say ERROR."""
    loop = _started_loop()
    with pytest.raises(PlantStepError) as err:
        for _ in range(loop.n_steps):
            loop.step(FULL)
    n = loop.n
    assert loop.stopped == str(err.value) and not loop.running and not loop.finished
    with pytest.raises(RuntimeError, match='^the plant cannot go on: refrigerant cycle did not converge'):
        loop.step(FULL)
    assert loop.n == n and loop.take_command(object(), 0.0, 0.0, lambda _m: FULL) is None
    assert loop.lockstep_overdue(1e9) is None  # no fallback period either
    h = loop.health('', 0.0, 0.0, {})
    assert h.level == ERROR and h.values['state'] == 'stopped' and stopped_line(loop.stopped) in h.reasons


def test_other_step_errors_do_not_stop_the_loop():
    """A command that is not an AcInput is the caller's error (ValueError): the loop is not stopped by it."""
    loop = _started_loop()
    with pytest.raises(ValueError, match='must be AcInput'):
        loop.step(object())  # type: ignore[arg-type]
    assert loop.stopped is None and loop.running
    loop.step(FULL)
    assert loop.n == 1


def test_the_error_line_reads_back_as_the_reason():
    """`ceco run` gets plant_node's reason back from its exit status and ERROR line, nothing else."""
    why = 'refrigerant cycle did not converge in 30 iterations (compiled plant, step 2, t = 2 s)'
    log = f'[INFO] [1.0] [plant_node]: started\n[ERROR] [2.0] [veh1.plant_node]: {stopped_line(why)}\n[INFO] stopped\n'
    assert simulation_stopped(PLANT_STOPPED_EXIT, log) == f'the simulation stopped: {why}'
    assert simulation_stopped(1, log) is None  # a crash is not a stopped simulation
    assert simulation_stopped(PLANT_STOPPED_EXIT, '[INFO] [plant_node]: the simulation stopped: x') is None
    assert stopped_line('two\nlines') == stopped_line('two lines')  # one line in the log
