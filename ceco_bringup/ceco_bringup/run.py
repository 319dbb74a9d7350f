"""`ceco run`: the node stack over DDS, recorded into a rosbag2 bag.

    ceco run --scenario sc03 --strategy ceco-ioch --out DIR
    ceco run --scenario sc03 --strategy all --out DIR     # baseline + every CECO strategy
    ceco run --case hot-commute-4p --strategy baseline,ceco-pmv --out DIR   # a benchmark case's cell

Per strategy: starts preview_node, the controller (mpc_node or baseline_node)
and plant_node as separate OS processes on a private ROS_DOMAIN_ID (or the
user's: --domain-id, else ROS_DOMAIN_ID when set) with localhost-only
discovery, optionally all in one ROS namespace (--namespace veh1: nodes,
topics and the recorder under /veh1), records every topic (in-process recorder node,
rosbags, MCAP or `--storage sqlite3`, metadata version 9, fully qualified topic
names; bag timestamps: simulation time in lockstep, receive time in real time)
into DIR/bag, and when the scenario
is done writes DIR/metrics.json (compute_metrics on the recorded data),
DIR/timeseries.csv, DIR/diagnostics.csv and DIR/logs/<node>.log. Every run
directory also keeps its scenario file, command line and code fingerprint
(DIR/scenario.yaml, DIR/run.json: ``ceco_bringup.provenance``) and its
printed line (DIR/summary.txt). After the runs, the baseline family (the
production law at --baseline-setpoints-c, in-process) gives the saving at
matched comfort: the comparison table and the verdict are printed and kept in
DIR/comparison.txt, comparison.csv, verdict.json and summary.txt
(``ceco_bringup.outputs``).

`--case CASE`: the case's scenario with its overrides (DIR/case_scenario.yaml, the nodes' ``scenario``),
forecast uncertainty, seed (``--seed``, default its first), Ts, Np, and its baselines' door as a law file
(DIR/case_baseline_law.yaml, baseline_node's ``controller_config``), as ``ceco benchmark`` runs it.

Timing: `--timing lockstep` (default; accelerated, deterministic: the plant
advances a control period only when the command of that step has arrived)
or `--timing realtime` (wall-clock timers, as on a vehicle).

Ctrl-C (SIGINT) or SIGTERM at any moment: every child is stopped, the bag
is closed with its metadata, run.json says ``interrupted``, and `ceco run`
exits with status 130; the bag reads back completely up to the stop and
`ceco report DIR` reports it, marked partial.

A failed run (exit status 1; with several strategies the next one still runs, and the table
and the verdict compare the others): a node exits (plant_node with status 3 when a step leaves its
refrigerant model: ``the simulation stopped: <reason> (plant_node; ...)``, the words of ``ceco sim``),
the plant publishes nothing new for `--stall-timeout-s` of wall clock (stalled), the bag misses
a message the stack sent (the arrival check, metrics.json `recorded`), or the controller did not control the run (more
fallback steps than 5 % of its control steps and 2: metrics.json `status: failed`, no number
printed; ``ceco_core.run_status``). run.json then says ``failed`` and why.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import sys
import threading
import time
from pathlib import Path

import numpy as np

from ceco_bringup import arrival, cli_args, outputs, provenance, supervisor
from ceco_bringup.bag_writer import STORAGES
from ceco_bringup.verdict import FAMILY_SETPOINTS_C
from ceco_core.contracts import PLANT_STEP_S
from ceco_core.control_grid import TIMING_MODES
from ceco_core.run_status import STATUS_OK
from ceco_core.rundir import read_csv_columns


def build_parser() -> cli_args.Parser:
    """The ``ceco run`` argument parser (options as in the module docstring; ``ceco run --help``)."""
    p = cli_args.Parser('ceco run', __doc__.split('\n\n')[0])
    cli_args.add_scenario(p, default=None, help_extra=' (default: sc03; not with --case)')
    cli_args.add_case(p)
    cli_args.add_strategy(
        p, 'ceco-ioch', help_extra=' (several: one run directory per strategy, DIR/<strategy>/, then the verdict)'
    )
    cli_args.add_out(p, 'output run directory (must not hold a bag already)')
    cli_args.add_preview(p, default=None, help_extra=" (default: perfect; with --case the case's)")
    cli_args.add_control_period(p)
    cli_args.add_horizon(p)
    cli_args.add_duration(p)
    cli_args.add_seed(p)
    p.add_argument('--timing', default='lockstep', choices=TIMING_MODES, help='lockstep (accelerated) or realtime')
    p.add_argument(
        '--command-timeout-s',
        type=cli_args.positive_float,
        default=5.0,
        help='lockstep: wall-clock wait for a command before the plant applies its fallback law [s]',
    )
    p.add_argument(
        '--startup-timeout-s',
        type=cli_args.positive_float,
        default=120.0,
        help='wall-clock limit for the nodes to start and discover each other [s]',
    )
    p.add_argument(
        '--run-timeout-s', type=cli_args.positive_float, default=1800.0, help='wall-clock limit of one run [s]'
    )
    p.add_argument(
        '--stall-timeout-s',
        type=cli_args.positive_float,
        default=None,
        help='wall-clock time without a new plant step after which the run fails as stalled [s] '
        '(default: --command-timeout-s + 5 s; in lockstep it must exceed --command-timeout-s)',
    )
    cli_args.add_domain_id(
        p,
        'ROS_DOMAIN_ID of every run (default: the environment\'s ROS_DOMAIN_ID when set, '
        'else a private one per strategy)',
    )
    cli_args.add_namespace(
        p,
        'ROS namespace of the nodes, their topics and the recorder, e.g. veh1 '
        '(default: the root namespace); /clock and /rosout stay global',
        default='',
    )
    p.add_argument(
        '--storage',
        default=STORAGES[0],
        choices=STORAGES,
        help='rosbag2 storage of DIR/bag (mcap as ros2 bag record on Jazzy, or sqlite3)',
    )
    cli_args.add_baseline_setpoints(p, FAMILY_SETPOINTS_C)
    cli_args.add_no_progress(p)
    return p


def main(argv=None) -> int:
    """``ceco run``: run each requested strategy over DDS into its run directory, then the verdict.

    With several strategies they go into ``DIR/<strategy>/``; the comparison table and the verdict
    (saving at matched comfort against the baseline family, ``ceco_bringup.outputs``) follow.

    Args:
        argv: the arguments after ``ceco run`` (default ``sys.argv[1:]``).

    Returns:
        The exit status: 0 when every run finished, 2 for a user error (a bad option value, scenario,
        preview, namespace or domain id, an existing bag), 1 when a run failed, 130 when interrupted
        by SIGINT/SIGTERM.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    cli_args.check_out(parser, args.out)
    from ceco_bringup import supervisor
    from ceco_v2x_preview.preview import parse_quality
    from ceco_v2x_preview.scenario import load_scenario

    strategies = list(args.strategy)
    out = Path(args.out)
    run_dirs = {s: (out / s if len(strategies) > 1 else out) for s in strategies}
    case = None
    try:
        for d in run_dirs.values():
            if (d / 'bag').exists():
                raise ValueError(f'{d / "bag"} exists: choose a new --out directory')
        case = cli_args.apply_case(args, out)
        scenario = load_scenario(args.scenario)
        quality = parse_quality(args.preview)
        if args.seed is not None:
            quality = dataclasses.replace(quality, seed=int(args.seed))
        cli_args.check_duration(args.duration_s, scenario, args.control_period_s)
        cli_args.check_control_period(args, scenario)
        cli_args.warn_no_preview('ceco run', args, scenario, quality)
        args.namespace = supervisor.normalize_namespace(args.namespace)
        supervisor.resolve_domain_id(args.domain_id)  # an invalid user id fails here
        stall_timeout_s(args)
    except (ValueError, OSError) as err:
        parser.error(str(err))
    stop = supervisor.StopFlag()
    stop.install()
    metrics, columns, failed = {}, {}, {}
    try:
        for i, strategy in enumerate(strategies):
            run_dir = run_dirs[strategy]
            provenance.start_run(run_dir, 'run', argv, args.scenario, strategy)
            try:
                own = cli_args.case_overrides(case, strategy)  # (a baseline's door: its law file)
                law = write_baseline_law(own, out / CASE_BASELINE_LAW_FILE) if own else None
                m = run_one(args, scenario, quality, strategy, run_dir, stop, index=i, baseline_law=law)
            except supervisor.Interrupted:
                provenance.finish_run(run_dir, 'interrupted')
                print(
                    f'\nceco run: interrupted; the bag in {run_dir / "bag"} is closed and readable up to the stop '
                    f'(ceco report {run_dir} reports the partial run)',
                    file=sys.stderr,
                )
                return 130
            except RuntimeError as err:  # a node exited, a stall, lost messages: the other strategies still run
                provenance.finish_run(run_dir, 'failed', str(err))
                failed[strategy] = str(err)
                print(f'ceco run: {strategy}: FAILED: {err}', file=sys.stderr, flush=True)
                continue
            if m['status'] != STATUS_OK:  # the controller did not control: its numbers stay in run_dir, never shown
                provenance.finish_run(run_dir, 'failed', m['status_reason'])
                failed[strategy] = m['status_reason']
                line = outputs.failed_line(strategy, m['status_reason'], run_dir)
                (run_dir / 'summary.txt').write_text(line + '\n', encoding='utf-8')
                print(line, flush=True)
                continue
            provenance.finish_run(run_dir, 'complete')
            metrics[strategy] = m
            columns[strategy] = read_csv_columns(run_dir / 'timeseries.csv')
            line = outputs.run_line(m, run_dir)
            (run_dir / 'summary.txt').write_text(line + '\n', encoding='utf-8')
            print(line, flush=True)
    finally:
        stop.restore()
    if metrics:
        first = next(iter(metrics.values()))
        outputs.finish_job(
            out,
            scenario,
            metrics,
            columns,
            header=f'Scenario {scenario.name} over DDS ({args.timing}), Ts {first["control_period_s"]:g} s, '
            f'Np {first["horizon_steps"]}, preview {quality.describe()}, {out}:',
            family_setpoints_c=args.baseline_setpoints_c,
            family_overrides=cli_args.case_overrides(case, 'baseline'),
            case=args.case,
            duration_s=float(first['duration_s']),
            control_period_s=args.control_period_s,
            failed=failed,
            progress=not args.no_progress,
        )
    outputs.report_failed(out, failed, len(strategies))
    return 1 if failed else 0


def stall_timeout_s(args) -> float:
    """The stall limit of ``args`` [s]: ``--stall-timeout-s``, else ``--command-timeout-s`` + 5 s.

    Raises ValueError, in lockstep, for a limit not above the command timeout (the plant may
    legitimately wait that long for a command).
    """
    cmd = float(args.command_timeout_s)
    value = cmd + 5.0 if args.stall_timeout_s is None else float(args.stall_timeout_s)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f'--stall-timeout-s: must be finite and > 0, got {args.stall_timeout_s!r}')
    if args.timing == 'lockstep' and value <= cmd:
        raise ValueError(f'--stall-timeout-s {value:g} must exceed --command-timeout-s {cmd:g} in lockstep')
    return value


def _params(args, scenario, quality, strategy, duration_s):
    ts, np_ = scenario.control.timing(args.control_period_s, args.horizon_steps)
    common = {'scenario': args.scenario, 'timing': args.timing, 'control_period_s': ts}
    # Lockstep: the plant drives /clock; the other nodes follow it (their decisions
    # use the simulation-time stamps the messages carry, never a wall clock).
    sim_time = {'use_sim_time': True} if args.timing == 'lockstep' else {}
    spans = [x for span in quality.missing_spans_s for x in span] or [0.0]
    preview = dict(
        common,
        horizon_steps=np_,
        **sim_time,
        **{
            'faults.noise_std_t_amb_c': float(quality.noise_std_t_amb_c),
            'faults.noise_std_solar_wm2': float(quality.noise_std_solar_wm2),
            'faults.noise_std_speed_mps': float(quality.noise_std_speed_mps),
            'faults.noise_std_rh': float(quality.noise_std_rh),
            'faults.noise_ref_lead_s': float(quality.noise_ref_lead_s),
            'faults.delay_s': float(quality.delay_s),
            'faults.missing_spans_s': [float(x) for x in spans],
            'faults.missing_policy': quality.missing_policy,
            'faults.seed': -1 if quality.seed is None else int(quality.seed),
            'faults.uncertainty_level': quality.uncertainty,
            # lockstep: a step's previews wait until the controller and the recorder matched (an
            # external controller may not read them: ``run_one`` waits for the recorder alone there)
            'lockstep.min_preview_subscribers': 2,
        },
    )
    # lockstep: the first command waits until both the plant and the recorder are matched
    controller = dict(common, horizon_steps=np_, **sim_time, **{'lockstep.min_command_subscribers': 2})
    if strategy != 'baseline':
        controller['strategy'] = strategy
    plant = dict(
        common,
        duration_s=float(duration_s),
        **{
            'lockstep.command_timeout_s': float(args.command_timeout_s),
            'lockstep.min_state_subscribers': 3,
            'lockstep.min_output_subscribers': 1,
            'lockstep.min_command_subscribers': 2,
            # realtime too: step 0 waits for the recorder (and the controller's publisher), so the bag has it
            'realtime.start_gate': True,
        },
    )
    return ts, np_, preview, controller, plant


CASE_BASELINE_LAW_FILE = 'case_baseline_law.yaml'
"""Where ``--case`` writes its baselines' door fields as a law file (baseline_node's ``controller_config``)."""


def write_baseline_law(door: tuple, path: Path) -> str:
    """``door`` (``((RecircSettings field, value), ...)``) as a baseline law file (``acc_law:``); its path."""
    from ceco_controller.factory import write_acc_settings  # (here: the factory imports the NMPC and CasADi)

    return write_acc_settings(path, dict(door), "the baselines' door logic of the benchmark case (ceco run --case)")


def run_one(
    args,
    scenario,
    quality,
    strategy,
    run_dir: Path,
    stop: supervisor.StopFlag,
    index: int = 0,
    *,
    controller_cmd: list[str] | None = None,
    controller_env: dict | None = None,
    baseline_law: str | None = None,
) -> dict:
    """One strategy over DDS into run_dir; returns the metrics dict.

    ``baseline_law``: a baseline law file for baseline_node's ``controller_config`` (``--case`` with a
    baseline door: :func:`write_baseline_law`).

    ``controller_cmd``: a third-party controller's command line, started in place of
    mpc_node/baseline_node with the DDS environment plus ``controller_env`` (``ceco
    benchmark --controller-cmd``; the contract is in docs/benchmark.md).
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from ceco_bringup import bagio
    from ceco_bringup.recorder import Recorder

    dt_s = PLANT_STEP_S
    duration_s = min(args.duration_s or scenario.duration_s, scenario.duration_s)
    n_plant = int(math.floor(duration_s / dt_s + 1e-9))
    ts, np_, p_prev, p_ctrl, p_plant = _params(args, scenario, quality, strategy, duration_s)
    if baseline_law:
        p_ctrl['controller_config'] = str(baseline_law)
    if controller_cmd is not None:
        p_prev['lockstep.min_preview_subscribers'] = 1

    run_dir.mkdir(parents=True, exist_ok=True)
    bag_dir = run_dir / 'bag'
    if bag_dir.exists():
        raise RuntimeError(f'{bag_dir} exists: choose a new --out directory')
    log_dir = run_dir / 'logs'
    domain, _ = supervisor.resolve_domain_id(args.domain_id, index)
    env = supervisor.dds_env(domain)
    os.environ.update(
        {
            k: env[k]
            for k in (
                'ROS_DOMAIN_ID',
                'ROS_AUTOMATIC_DISCOVERY_RANGE',
                'FASTDDS_BUILTIN_TRANSPORTS',
                'FASTRTPS_DEFAULT_PROFILES_FILE',
            )
        }
    )
    os.environ.pop('ROS_LOCALHOST_ONLY', None)

    ctrl_exe = 'baseline_node' if strategy == 'baseline' else 'mpc_node'
    ns = args.namespace  # '' or '/veh1': nodes, relative topics and the recorder under it
    procs = {
        'preview_node': supervisor.stack_node('preview_node', env=env, log_dir=log_dir, namespace=ns, params=p_prev),
        'controller': supervisor.stack_node(ctrl_exe, env=env, log_dir=log_dir, namespace=ns, params=p_ctrl)
        if controller_cmd is None
        else supervisor.NodeProcess(
            'external_controller',
            None,
            None,
            env={**env, **(controller_env or {})},
            log_dir=log_dir,
            command=controller_cmd,
        ),
        'plant_node': supervisor.stack_node('plant_node', env=env, log_dir=log_dir, namespace=ns, params=p_plant),
    }
    custom = {
        'scenario': scenario.name,
        'strategy': strategy,
        'control_period_s': repr(float(ts)),
        'horizon_steps': str(np_),
        'preview_quality': quality.describe(),
        'timing': args.timing,
        'duration_s': repr(float(duration_s)),
        'ros_domain_id': str(domain),
        'ros_namespace': args.namespace,
    }

    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
    recorder = None
    executor = None
    spin_stop = threading.Event()
    thread = None
    lifecycle = None
    t_wall0 = time.monotonic()
    interrupted = False
    try:
        recorder = Recorder(
            bag_dir,
            custom_data=custom,
            context=context,
            storage=args.storage,
            timestamps='sim' if args.timing == 'lockstep' else 'receive',
            **({'namespace': ns} if ns else {}),
        )
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(recorder)

        def spin():
            while not spin_stop.is_set() and context.ok():
                executor.spin_once(timeout_sec=0.05)

        thread = threading.Thread(target=spin, name='recorder', daemon=True)
        thread.start()

        # All nodes start together (their imports overlap); the plant holds step 0
        # until every subscriber it needs is matched (preview node, controller and
        # recorder on cabin/state, the recorder on its other outputs, and the
        # recorder's subscription to hvac/command is in its graph).
        for name in ('preview_node', 'controller', 'plant_node'):
            procs[name].start()
        # The controller is a managed node: configure (build the controller, first solve),
        # then activate (start commanding); the plant's start gate waits for its command
        # publisher, created in configure.
        if controller_cmd is None:
            lifecycle = supervisor.configure_and_activate(
                context, executor, f'{ns}/{ctrl_exe}', args.startup_timeout_s, stop, procs
            )
        plant = procs['plant_node']
        stall_s = stall_timeout_s(args)
        start_watch = StartWatch(stall_s)

        def first_state() -> bool:
            if recorder.first_state_wall is not None:
                return True
            started = start_watch.started is not None or plant_started(plant.log_text())
            stalled, used = start_watch.check(time.monotonic(), started, plant.cpu_time_s())
            if stalled:
                raise RuntimeError(stalled_message(stall_s, 0, n_plant, procs, used))
            return False

        supervisor.wait_for(
            first_state, args.startup_timeout_s, stop, procs, 'the nodes to start and discover each other'
        )
        t_start = time.monotonic()

        bar = None
        if not args.no_progress:
            from tqdm import tqdm

            bar = tqdm(
                total=n_plant, desc=f'{strategy} over DDS', unit='s sim', file=sys.stderr, mininterval=0.5, leave=False
            )
        done = lambda: recorder.last_power_step >= n_plant - 1  # noqa: E731
        progress = (recorder.last_power_step, time.monotonic(), plant.cpu_time_s())
        try:
            while not done():
                if stop.event.wait(0.1):
                    raise supervisor.Interrupted()
                for name, proc in procs.items():
                    if not proc.running():
                        raise RuntimeError(supervisor.exited_message(name, proc))
                now = time.monotonic()
                if recorder.last_power_step != progress[0]:
                    progress = (recorder.last_power_step, now, plant.cpu_time_s())
                elif now - progress[1] > stall_s:
                    cpu = plant.cpu_time_s()
                    used = None if cpu is None or progress[2] is None else cpu - progress[2]
                    raise RuntimeError(stalled_message(stall_s, recorder.last_power_step + 1, n_plant, procs, used))
                if now - t_start > args.run_timeout_s:
                    raise RuntimeError(
                        f'run timeout ({args.run_timeout_s} s) at plant step {recorder.last_power_step + 1}/{n_plant}'
                    )
                if bar is not None:
                    bar.n = recorder.last_power_step + 1
                    bar.refresh()
        finally:
            if bar is not None:
                bar.close()
        t_run = recorder.last_power_wall - recorder.first_state_wall
        # the plant is done; a recorder that was starved or frozen may still be receiving the repairs
        # of what it missed (each writer at its own heartbeat): wait while that makes progress
        wait_for_backlog(recorder, arrival.expected_counts(n_plant, int(round(ts / dt_s)), args.timing), stall_s, stop)
        time.sleep(0.2)  # let the last diagnostics and log lines arrive
    except supervisor.Interrupted:
        interrupted = True
    finally:
        # every stop path: children first (plant first: it drives the loop), then the bag
        procs['plant_node'].stop()
        if lifecycle is not None and procs['controller'].running():  # a clean managed-node stop
            for transition in ('deactivate', 'shutdown'):
                lifecycle.change(transition, timeout_s=5.0)
        for name in ('controller', 'preview_node'):
            procs[name].stop()
        spin_stop.set()
        if thread is not None:
            thread.join(timeout=5.0)
        counts = recorder.close() if recorder is not None else {}
        if recorder is not None:  # publisher-side send times of states and commands (benchmark time ratio)
            (run_dir / 'send_times.json').write_text(json.dumps(recorder.source_ns) + '\n')
        if executor is not None:
            executor.shutdown()
        if recorder is not None:
            recorder.destroy_node()
        rclpy.try_shutdown(context=context)
    if interrupted:
        raise supervisor.Interrupted()

    wall = time.monotonic() - t_wall0
    m = int(round(ts / dt_s))  # plant steps per control period
    arrived = arrival.bag_arrival(bag_dir, n_plant, m, args.timing)
    if not all(a.complete for a in arrived):
        raise RuntimeError(f'the bag misses messages the stack sent: {arrival.summary(arrived)}')
    ts_data = bagio.load_run_timeseries(bag_dir)
    if ts_data['t_s'].size != n_plant:
        raise RuntimeError(f'bag holds {ts_data["t_s"].size} complete plant steps, expected {n_plant}')
    from ceco_core.metrics import run_metrics
    from ceco_core.run_status import check_control, fallback_control_steps

    metrics = run_metrics(ts_data, air_limits=scenario.air_quality.limits)
    metrics.update(
        {
            'scenario': scenario.name,
            'strategy': strategy,
            'control_period_s': float(ts),
            'horizon_steps': np_,
            'seed': int(scenario.seed if quality.seed is None else quality.seed),
            'preview_quality': quality.describe(),
            'source': 'dds',
            'timing': args.timing,
            'wall_time_s': wall,
            'loop_wall_time_s': t_run,
            'realtime_factor': duration_s / t_run,
            'ros_domain_id': domain,
            'ros_namespace': args.namespace,
            'bag_message_counts': counts,
            'fallback_steps': int(ts_data['fallback'].sum()),
        }
    )
    diag, cmds = bagio.load_diagnostics(bag_dir), bagio.load_commands(bag_dir)
    n_ctrl, n_fb = fallback_control_steps(ts_data['fallback'], m, cmds['k'][cmds['fallback']])
    metrics.update(check_control(n_ctrl, n_fb).as_metrics())
    metrics['recorded'] = {a.topic: [a.received, a.expected] for a in arrived}
    solve_ms = diag['solve_time_ms'][np.isfinite(diag['solve_time_ms'])]
    metrics.update(
        {
            'n_control_steps': n_ctrl,
            'n_fallback_shifted': int(np.sum(diag['fallback'] == 'shifted_plan')),
            'n_fallback_baseline': int(np.sum(diag['fallback'] == 'baseline')),
            'solve_time_median_ms': float(np.median(solve_ms)) if solve_ms.size else None,
            'solve_time_max_ms': float(np.max(solve_ms)) if solve_ms.size else None,
        }
    )
    bagio.write_timeseries_csv(run_dir / 'timeseries.csv', ts_data)
    bagio.write_diagnostics_csv(run_dir / 'diagnostics.csv', diag)
    clean = {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in metrics.items()}
    (run_dir / 'metrics.json').write_text(json.dumps(clean, indent=2, sort_keys=True) + '\n')
    return metrics


def wait_for_backlog(recorder, expected: dict[str, int], stall_s: float, stop: supervisor.StopFlag) -> None:
    """Wait until ``recorder`` holds ``expected`` messages per topic, as long as it makes progress.

    Returns at the first ``stall_s`` [s] without a new message on those topics (the arrival check then
    names what is missing); raises :class:`supervisor.Interrupted` on a stop signal.
    """
    last, t_last = -1, time.monotonic()
    while any(recorder.received.get(t, 0) < n for t, n in expected.items()):
        # progress on these topics only: a timer-driven publisher (the real-time preview node) never stops
        got = sum(recorder.received.get(t, 0) for t in expected)
        if got != last:
            last, t_last = got, time.monotonic()
        elif time.monotonic() - t_last > stall_s:
            return
        if stop.event.wait(0.05):
            raise supervisor.Interrupted()


def plant_started(log_text: str) -> bool:
    """Whether plant_node's log says its start gate opened (it published the state of step 0)."""
    from ceco_plant_sim.plant_io import STARTED  # (here, not at the top: the plant package imports CasADi)

    return STARTED in log_text


class StartWatch:
    """Start-up of a run: a plant that said it started step 0 while no state reached the recorder.

    Before the plant's start gate opens, waiting is right (imports, discovery, the controller's
    configure: ``--startup-timeout-s``). Once the plant says it started, a recorder still without a
    state after ``stall_s`` [s] of wall clock is a stalled run (the plant frozen or starved right
    after its start, or its states lost), said then rather than after the start-up timeout.
    """

    def __init__(self, stall_s: float):
        self.stall_s = stall_s
        self.started: tuple[float, float | None] | None = None
        """(wall clock [s], the plant's CPU time [s]) when the plant was first seen started."""

    def check(self, now_s: float, plant_started: bool, plant_cpu_s: float | None) -> tuple[bool, float | None]:
        """(stalled, the plant's CPU seconds since its start) with no state at the recorder at ``now_s`` [s]."""
        if self.started is None:
            if plant_started:
                self.started = (now_s, plant_cpu_s)
            return False, None
        t0, cpu0 = self.started
        used = None if plant_cpu_s is None or cpu0 is None else plant_cpu_s - cpu0
        return now_s - t0 > self.stall_s, used


def stalled_message(
    stall_s: float, n_recorded: int, n_plant: int, procs: dict, plant_cpu_s: float | None = None
) -> str:
    """The error of a stalled run.

    It says what the recorder has, whether the plant says it finished, and how much CPU the plant
    got meanwhile (``plant_cpu_s`` [s]: a stopped or starved plant gets next to none).
    """
    plant_log = procs['plant_node'].log_text()
    if 'scenario complete' in plant_log:
        why = 'the plant reports the scenario complete: its messages did not reach the recorder'
    elif n_recorded == 0 and plant_started(plant_log):
        why = 'the plant logged that it started step 0, and no state of it reached the recorder'
    else:
        why = 'the plant made no progress (all nodes are running)'
    if plant_cpu_s is not None:
        why += f'; plant_node used {plant_cpu_s:.2f} s of CPU in those {stall_s:g} s'
        if plant_cpu_s < 0.02 * stall_s:
            why += ' (stopped, or starved of CPU: on a machine that loaded raise --stall-timeout-s)'
    return (
        f'stalled: no new plant step for {stall_s:g} s of wall clock at plant step {n_recorded}/{n_plant}; {why}; '
        f'logs: {procs["plant_node"].log_path.parent}'
    )


if __name__ == '__main__':
    sys.exit(main())
