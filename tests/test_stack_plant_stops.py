"""`ceco run` of a scenario the plant cannot simulate, over real DDS between real processes.

Beyond the refrigerant model (60 degC air, 1400 W/m2, the cabin soaked at 70 degC) plant_node's step
raises PlantStepError: the node says why in one ERROR line and on /diagnostics, publishes no further
state and exits with status 3; `ceco run` fails that run with the plant's reason, in the words of
`ceco sim` (``the simulation stopped: ``), and goes on with the next strategy.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
import yaml

pytestmark = pytest.mark.stack

rclpy = pytest.importorskip('rclpy', reason='stack tests need the sourced ROS 2 workspace')
if not hasattr(pytest.importorskip('ceco_msgs.msg', reason='stack tests need the built ceco_msgs'), 'AcCommand'):
    pytest.skip('stack tests need the sourced ROS 2 workspace (ceco_msgs is not built here)', allow_module_level=True)

from scenario_cases import BEYOND_THE_CYCLE  # noqa: E402
from test_stack import DdsPeer  # noqa: E402

from ceco_bringup import bagio  # noqa: E402
from ceco_ros import interfaces  # noqa: E402


def test_a_run_the_plant_cannot_simulate_fails_with_the_plants_reason(tmp_path):
    """Each run is FAILED with `the simulation stopped: <reason> (plant_node; ...)` on the console, in run.json and
    in the job's summary, no traceback anywhere; the plant's last state is the step it could not simulate, and its
    /diagnostics said ERROR with the reason (before: `plant_node exited with status 1` and its traceback)."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

    scenario, out = tmp_path / 'hot.yaml', tmp_path / 'o'
    scenario.write_text(yaml.safe_dump(BEYOND_THE_CYCLE))
    domain = 1 + (os.getpid() * 13 + 5) % 100
    peer = DdsPeer(domain, 'diagnostics_watch')
    diags = peer.collect(DiagnosticArray, interfaces.TOPIC_ROS_DIAGNOSTICS, interfaces.QOS_DIAGNOSTICS)
    try:
        p = subprocess.run(
            [sys.executable, '-m', 'ceco_bringup.cli', 'run', '--scenario', str(scenario), '--out', str(out)]
            + ['--strategy', 'baseline,ceco', '--no-progress', '--domain-id', str(domain)],
            capture_output=True,
            text=True,
            timeout=600,
        )
    finally:
        peer.close()
    text = p.stdout + p.stderr
    assert p.returncode == 1, text
    assert 'Traceback' not in text, text
    why = 'the simulation stopped: refrigerant cycle did not converge in 30 iterations (compiled plant, step '
    for strategy in ('baseline', 'ceco'):
        assert f'ceco run: {strategy}: FAILED: {why}' in p.stderr, text
        assert f'  {strategy}: {why}' in p.stdout, text  # the job's summary
        run = json.loads((out / strategy / 'run.json').read_text())
        assert run['status'] == 'failed' and run['error'].startswith(why), run
        assert run['error'].endswith(f'(plant_node; log: {out / strategy / "logs" / "plant_node.log"})'), run
        log = (out / strategy / 'logs' / 'plant_node.log').read_text()
        assert log.count('[ERROR]') == 1 and 'Traceback' not in log, log
        assert f'{why}' in log and '; the plant cannot go on: exit 3' in log, log
        assert log.rstrip().endswith('[plant_node]: stopped (the plant cannot go on): exit 3'), log[-300:]
        counts = bagio.topic_counts(out / strategy / 'bag')  # states of steps 0..n, outputs of steps 0..n-1
        assert counts['/cabin/state'] == counts['/hvac/power'] + 1 == counts['/cabin/comfort'] + 1 > 1, counts
    assert '2 of 2 runs failed (not compared):' in p.stdout, text
    errors = [
        s
        for a in diags
        for s in a.status
        if s.name == 'plant_node: plant' and s.level == DiagnosticStatus.ERROR and s.message.startswith(why)
    ]
    assert len(errors) == 2, [(s.name, s.level, s.message) for a in diags for s in a.status]  # one per run
