"""The plant's start gate (``plant_io.start_gate``) by timing: lockstep waits for its peers; a
real-time plant stands for the vehicle and starts at once unless ``realtime.start_gate`` asks it to
wait as in lockstep (``ceco run``, ``record:=true``: so the recorder gets step 0). Pure, no DDS."""

from __future__ import annotations

import pytest

from ceco_plant_sim.plant_io import PLANT_PARAMETERS, PlantNodeConfig, start_gate

ALONE = dict(state_subs=0, output_subs=(0, 0), command_subs=1, command_pubs=0)
"""A plant with no peer: no state subscriber, no command publisher, its own command reader only."""


def _cfg(**values) -> PlantNodeConfig:
    params = {s.name: s.default for s in PLANT_PARAMETERS}
    params.update(values)
    return PlantNodeConfig.from_params(params)


def test_lockstep_plant_alone_waits_for_its_state_subscribers_and_a_command_publisher():
    assert start_gate(_cfg(timing='lockstep'), **ALONE) == 'cabin/state subscribers 0/2, a hvac/command publisher'


@pytest.mark.parametrize(
    'gate',
    [
        {},  # the defaults (2, 0, 1)
        {'lockstep.min_state_subscribers': 3, 'lockstep.min_output_subscribers': 1},  # ceco run's numbers
        {'lockstep.min_command_subscribers': 2},
    ],
)
def test_realtime_plant_alone_starts_at_once_whatever_the_lockstep_numbers(gate):
    """Before: 'cabin/state subscribers 0/2, a hvac/command publisher', and the plant never stepped."""
    cfg = _cfg(timing='realtime', **gate)
    assert cfg.realtime_start_gate is False  # the default
    assert start_gate(cfg, **ALONE) == ''


def test_realtime_start_gate_waits_as_lockstep_does():
    gate = {
        'lockstep.min_state_subscribers': 3,
        'lockstep.min_output_subscribers': 1,
        'lockstep.min_command_subscribers': 2,
        'realtime.start_gate': True,
    }
    rt, ls = _cfg(timing='realtime', **gate), _cfg(timing='lockstep', **gate)
    for counts in (ALONE, dict(state_subs=3, output_subs=(1, 1), command_subs=1, command_pubs=1)):
        assert start_gate(rt, **counts) == start_gate(ls, **counts) != ''
    assert start_gate(rt, state_subs=3, output_subs=(1, 1), command_subs=2, command_pubs=1) == ''


def test_realtime_start_gate_is_what_ceco_run_sets():
    from ceco_bringup import run
    from ceco_v2x_preview.preview import parse_quality
    from ceco_v2x_preview.scenario import load_scenario

    args = run.build_parser().parse_args(['--out', 'unused', '--scenario', 'sc03', '--timing', 'realtime'])
    sc = load_scenario('sc03')
    plant = run._params(args, sc, parse_quality('perfect'), 'baseline', sc.duration_s)[4]
    cfg = _cfg(**plant)
    assert cfg.timing == 'realtime' and cfg.realtime_start_gate is True
    assert start_gate(cfg, **ALONE) != ''  # the bag of a real-time ceco run still starts at step 0
