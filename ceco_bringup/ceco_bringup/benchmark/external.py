"""A third-party controller scored over ROS 2: ``ceco benchmark --controller-cmd "CMD"``.

Each (case, seed) of an external controller runs as ``ceco run`` does (preview_node,
plant_node and the in-process recorder as separate processes on a private DDS
domain, lockstep), with ``CMD`` started in place of mpc_node. The contract the
node must keep (topics, QoS, timing, what to publish and when) is in
docs/benchmark.md, "Your own controller over ROS 2". The run is scored from the
recorded bag with the simulator's KPI functions (``ceco_core.kpis.compute_kpis``),
``source: dds``; the time ratio uses the publisher-side send times: command k minus
the state at t_k, over Ts (like BOPTEST's, it includes the transport).

Needs the built workspace (rclpy, ceco_msgs, the node executables on
AMENT_PREFIX_PATH).
"""

from __future__ import annotations

import dataclasses
import os
import re
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import yaml

from ceco_bringup import provenance
from ceco_core.contracts import PLANT_STEP_S
from ceco_core.run_status import check_control, fallback_control_steps
from ceco_ros.topics import TOPIC_COMMAND, TOPIC_STATE

from .runner import mark_failed, new_row

__all__ = ['controller_env', 'step_times_from_bag', 'plant_rejections', 'one_line_error', 'run_external_cell']

_REJECTED = re.compile(r'\]: rejected hvac/command (.*?)(?: \(\d+ similar rejections since the last line\))?\s*$')
"""plant_node's log line of a rejected command (``ceco_plant_sim.plant_io.CommandPolicy.accept``)."""


def controller_env(spec: Mapping, scenario_path: Path, ts: float, n_p: int) -> dict:
    """Environment variables the external controller gets (besides the DDS ones)."""
    return {
        'CECO_SCENARIO': str(scenario_path),
        'CECO_CONTROL_PERIOD_S': repr(float(ts)),
        'CECO_HORIZON_STEPS': str(int(n_p)),
        'CECO_CASE': str(spec['case']),
        'CECO_SEED': '' if spec['seed'] is None else str(spec['seed']),
        'CECO_PREVIEW_QUALITY': str(spec['preview']),
    }


def step_times_from_bag(run_dir, control_period_s: float, plant_dt_s: float = 1.0) -> np.ndarray:
    """Per control step k: the controller's whole step over DDS [s].

    The publisher-side send time of ``hvac/command`` k minus that of the ``cabin/state``
    at t_k, DDS transport included: the rmw source timestamps the recorder kept with each
    message's step index (``send_times.json`` next to the bag). The first command of each
    step sent after its state counts: one sent before could not have used it (a controller that
    published ahead of the state made the time negative, -0.07 of the period on average); a step
    whose every command came before its state has no time.
    """
    import json

    sent = json.loads((Path(run_dir) / 'send_times.json').read_text(encoding='utf-8'))
    per = int(round(control_period_s / plant_dt_s))
    state, cmd = {}, {}
    for n, t_ns in sent[TOPIC_STATE]:
        if n % per == 0:
            state.setdefault(n // per, t_ns)
    for k, t_ns in sent[TOPIC_COMMAND]:
        if k in state and t_ns >= state[k]:
            cmd.setdefault(k, t_ns)
    ks = sorted(cmd)
    return np.array([(cmd[k] - state[k]) * 1e-9 for k in ks], dtype=float)


def plant_rejections(run_dir: Path, plant_fallback, n_commands: int, steps_per_control: int) -> str:
    """What the plant refused of an external controller, for a failed run's reason: ``''`` when nothing.

    The counts come from the bag: ``n_commands`` hvac/command messages recorded, of which the plant
    applied one per control step its law did not drive (``plant_fallback``: per plant step, True when
    the ACC law drove it; in lockstep an applied command drives its whole step). The reason exists
    only in plant_node's log (``DIR/logs/plant_node.log``): its first ``rejected hvac/command`` line,
    which is the first rejection (the plant logs the first of each kind, then throttles).

    Returns ``plant_node rejected R of N commands, first: step K: <reason> (log: PATH)``, or
    ``the controller sent no hvac/command (log: PATH)`` (its own log) when none was recorded.
    """
    run_dir = Path(run_dir)
    if n_commands == 0:
        return f'the controller sent no hvac/command (log: {run_dir / "logs" / "external_controller.log"})'
    n_ctrl, n_fallback = fallback_control_steps(plant_fallback, steps_per_control)
    rejected = n_commands - (n_ctrl - n_fallback)
    if rejected <= 0:
        return ''
    log = run_dir / 'logs' / 'plant_node.log'
    try:
        text = log.read_text(encoding='utf-8', errors='replace')
    except OSError:
        text = ''
    first = next((m_.group(1) for m_ in map(_REJECTED.search, text.splitlines()) if m_), '')
    return f'plant_node rejected {rejected} of {n_commands} commands{", first: " + first if first else ""} (log: {log})'


def one_line_error(text: str) -> str:
    """A run's error on one line: a child's exit with its log's tail keeps the tail's last line (the exception).

    ``controller exited with status 1; log: PATH`` and the log's tail on the next lines becomes
    ``controller exited with status 1: RuntimeError: boom; log: PATH``; the whole traceback stays in the log.
    """
    head, *tail = text.strip().splitlines() or ['']
    # the supervisor's own lines (``--- start 1: CMD``, ``--- stopped: ...``) are not the child's words
    last = next((line.strip() for line in reversed(tail) if line.strip() and not line.startswith('--- ')), '')
    if not last and not tail:
        return head
    last = last or 'it printed nothing'
    before, sep, path = head.partition('; log: ')
    return f'{before}: {last}{sep}{path}' if sep else f'{head}: {last}'


def run_external_cell(
    cell: Mapping,
    command: Sequence[str],
    run_dir: Path,
    *,
    command_timeout_s: float = 5.0,
    startup_timeout_s: float = 120.0,
    run_timeout_s: float = 1800.0,
) -> dict:
    """Run one external-controller cell over DDS into ``run_dir``; return its log row (never raises).

    ``run_dir`` is a run directory as ``ceco run`` leaves one, with its ``run.json``: ``failed`` and the row's
    error when the run is not ``ok`` (``ceco report`` names it, never shows its numbers).
    """
    from ceco_bringup.sweep import cells as sweep_cells

    t0 = time.perf_counter()
    row = new_row(cell, 'dds')
    try:
        import rclpy  # noqa: F401 (fail early and clearly without ROS)
    except ImportError as exc:
        row.update(status='error', error=f'--controller-cmd needs ROS 2 (rclpy): {exc}; source the workspace')
        row['wall_time_s'] = time.perf_counter() - t0
        return row
    try:
        from ceco_bringup import bagio, run, supervisor
        from ceco_core.kpis import compute_kpis
        from ceco_plant_sim.scenario_plant import steps_per_control
        from ceco_v2x_preview.preview import parse_quality
        from ceco_v2x_preview.scenario import load_scenario

        spec = cell['spec']
        row['code'] = sweep_cells.code_fingerprint()
        run_dir = Path(run_dir)
        if run_dir.exists():  # a previous, unfinished attempt: start afresh
            import shutil

            shutil.rmtree(run_dir)
        run_dir.mkdir(parents=True)
        scenario_path = run_dir / 'scenario.yaml'
        scenario_path.write_text(yaml.safe_dump(spec['scenario'], sort_keys=False), encoding='utf-8')
        scenario = load_scenario(str(scenario_path))
        provenance.start_run(run_dir, 'benchmark', list(command), str(scenario_path), 'external')  # (as run_one)
        quality = parse_quality(spec['preview'])
        if spec['seed'] is not None:
            quality = dataclasses.replace(quality, seed=int(spec['seed']))
        ts, n_p = scenario.control.timing(spec['control_period_s'], spec['horizon_steps'])
        # `ceco run`'s own defaults (bag storage, ...), then what this run sets: a private domain always (never the
        # user's ROS_DOMAIN_ID, which every worker would share), one no other ceco process holds
        args = run.build_parser().parse_args(['--out', str(run_dir), '--no-progress'])
        for key, value in dict(
            domain_id=supervisor.private_domain_id(),
            scenario=str(scenario_path),
            timing='lockstep',
            control_period_s=ts,
            horizon_steps=n_p,
            duration_s=spec['duration_s'],
            command_timeout_s=command_timeout_s,
            startup_timeout_s=startup_timeout_s,
            run_timeout_s=run_timeout_s,
        ).items():
            setattr(args, key, value)
        stop = supervisor.StopFlag()
        t_sim = time.perf_counter()
        metrics = run.run_one(
            args,
            scenario,
            quality,
            'external',
            run_dir,
            stop,
            controller_cmd=list(command),
            controller_env=controller_env(spec, scenario_path, ts, n_p),
        )
        row['sim_time_s'] = time.perf_counter() - t_sim
        ts_data = bagio.load_run_timeseries(run_dir / 'bag')
        row['dds_metrics'] = {k: metrics[k] for k in ('wall_time_s', 'loop_wall_time_s', 'realtime_factor')}
        # fallback steps as `ceco run` counts them: the plant's law, or a command marked fallback
        check = check_control(metrics['n_control_steps'], metrics['fallback_control_steps'])
        kpis, notes = compute_kpis(
            ts_data,
            step_time_s=step_times_from_bag(run_dir, ts),
            control_period_s=ts,
            fallback_steps=check.n_fallback_steps,
        )
        row['kpis'], row['kpi_notes'] = kpis, notes
        mark_failed(row, check)
        if row['status'] != 'ok':  # why: what the plant refused, and its first reason
            m = steps_per_control(ts, PLANT_STEP_S)
            n_cmd = int(bagio.load_commands(run_dir / 'bag')['k'].size)
            refused = plant_rejections(run_dir, ts_data['fallback'], n_cmd, m)
            row['error'] += f'; {refused}' if refused else ''
    except Exception as exc:  # a failed run is data
        row.update(status='error', error=one_line_error(f'{type(exc).__name__}: {exc}'))
    # (nothing happens without a run.json: a failure before the run began)
    provenance.finish_run(run_dir, 'complete' if row['status'] == 'ok' else 'failed', row['error'])
    row['wall_time_s'] = time.perf_counter() - t0
    row['pid'] = os.getpid()
    return row
