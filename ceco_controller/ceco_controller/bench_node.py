"""The whole control step inside ``mpc_node``, message in to command out (``ceco bench nmpc --node``).

The real :class:`ceco_controller.mpc_node.ControllerNode` runs in this process on a private
ROS_DOMAIN_ID with its default lockstep timing; a feeder node plays the plant and preview nodes.
What it sends is a closed-loop run of the in-process simulator with the same controller settings
(``closed_loop.simulate``), replayed: at every control step the previews and the cabin state at t_k
(messages made by the same ``ceco_ros.conversions`` functions the plant and preview nodes use), then
it waits for the command. The node computes the simulator's commands (the stack equals the
simulator bit for bit; the largest difference is returned), so the replay is the closed loop, and
between steps this process does nothing else (the plant runs in its own process in a stack).

Measured per control step, inside the node: from the entry of the subscription callback in which
the step runs (the message in, after rclpy took it off the wire) to the return of the command's
``publish`` (the command out, handed to DDS): wall time and the thread's CPU time; and the
solver's own wall time (the node's ``controller/diagnostics``) and CPU time (read from the node's
controller). The node file is not touched: its ``create_subscription`` and
``create_lifecycle_publisher`` are wrapped on the instance before it configures itself.

A benchmark, not a test; needs the built workspace (rclpy, ceco_msgs). No rclpy import at module
import: :func:`node_step_times` imports it.
"""

from __future__ import annotations

import importlib
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ceco_core import yamlio

__all__ = ["node_step_times"]


def _controller_config(codegen: bool) -> str:
    """A copy of the package's controller file with ``solver.codegen`` set; its path."""
    from .model import package_config_path

    doc: Any = yamlio.load_file(package_config_path("controller.yaml"))  # (the package's own file)
    doc.setdefault("common", {}).setdefault("solver", {})["codegen"] = bool(codegen)
    fd, path = tempfile.mkstemp(prefix="ceco_bench_node_", suffix=".yaml")
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        yaml.safe_dump(doc, fh)
    return path


def node_step_times(
    strategy: str,
    scenario: str = "sc03",
    horizon_steps: int = 6,
    duration_s: float | None = None,
    codegen: bool = True,
    domain_id: int | None = None,
    timeout_s: float = 30.0,
) -> dict:
    """Run ``mpc_node`` (``strategy``) over ``scenario`` in lockstep; time every control step inside it.

    Returns arrays per control step (``k`` 0..): ``node_ms`` (wall, message in to command out),
    ``node_cpu_ms`` (the thread's CPU time over the same span), ``solve_ms`` (the solver's own
    wall time, from the node's diagnostics), ``solve_cpu_ms`` (its CPU time, read from the node's
    controller), the commands (``mdot_bl_kgps``, ``t_evap_sp_c``), ``fallback`` (steps not under
    NMPC control) and the scalar ``max_command_diff_to_simulator`` [kg/s or degC].
    """
    os.environ["ROS_DOMAIN_ID"] = str(150 + os.getpid() % 60 if domain_id is None else domain_id)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    from ceco_core.contracts import MEASUREMENTS, AcInput
    from ceco_plant_sim.scenario_plant import KEY_ON_COMMAND, steps_per_control
    from ceco_v2x_preview.preview import PERFECT, make_previews
    from ceco_v2x_preview.scenario import load_scenario

    from .closed_loop import SimSettings, simulate

    # the ROS side, imported here at run time (it needs the built workspace; mypy checks the pure packages)
    rclpy = importlib.import_module("rclpy")
    SingleThreadedExecutor = importlib.import_module("rclpy.executors").SingleThreadedExecutor
    msgs = importlib.import_module("ceco_msgs.msg")
    conversions = importlib.import_module("ceco_ros.conversions")
    interfaces = importlib.import_module("ceco_ros.interfaces")
    ControllerNode = importlib.import_module("ceco_controller.mpc_node").ControllerNode
    AcCommand, CabinState, ControllerDiagnostics = msgs.AcCommand, msgs.CabinState, msgs.ControllerDiagnostics
    TrafficPreview, WeatherPreview = msgs.TrafficPreview, msgs.WeatherPreview

    sc = load_scenario(scenario)
    ts = sc.control.control_period_s
    config = _controller_config(codegen)
    # the closed loop the node will run, from the simulator: per step t_k, the measurements, u(k-1)
    sim = simulate(
        sc,
        strategy,
        SimSettings(horizon_steps=horizon_steps, duration_s=duration_s, progress=False, controller_config_path=config),
    )
    m = steps_per_control(ts, 1.0)
    cols, diags = sim.timeseries, sim.diag_objects
    replay = [
        (
            float(cols["t_s"][k * m]),
            {f: float(cols[f][k * m]) for f in MEASUREMENTS},
            KEY_ON_COMMAND if k == 0 else AcInput(diags[k - 1].mdot_bl_kgps, diags[k - 1].t_evap_sp_c),
        )
        for k in range(len(diags))
    ]
    args = ["--ros-args", "--log-level", "warn"]
    for name, value in (
        ("strategy", strategy),
        ("scenario", scenario),
        ("horizon_steps", horizon_steps),
        ("control_period_s", ts),
        ("controller_config", config),
        ("autostart", True),
    ):
        args += ["-p", f"{name}:={'true' if value is True else value}"]
    rclpy.init(args=args)
    mark = {"t0": 0.0, "c0": 0.0}
    pubs: dict = {}
    node_ms: dict[int, float] = {}
    node_cpu_ms: dict[int, float] = {}
    solve_cpu_ms: dict[int, float] = {}
    try:
        node = ControllerNode("mpc_node")
        # instrument the instance (its on_configure creates the entities when the executor first spins)
        create_sub, create_pub = node.create_subscription, node.create_lifecycle_publisher

        def timed_subscription(msg_type, topic, callback, *a, **kw):
            def cb(msg):
                mark["t0"], mark["c0"] = time.perf_counter(), time.thread_time()
                return callback(msg)

            return create_sub(msg_type, topic, cb, *a, **kw)

        def timed_publisher(msg_type, topic, *a, **kw):
            pub = create_pub(msg_type, topic, *a, **kw)
            if topic == interfaces.TOPIC_COMMAND:
                pubs["command"] = pub
                publish = pub.publish

                def timed_publish(msg):
                    publish(msg)
                    k = int(msg.step_index)
                    node_ms[k] = 1e3 * (time.perf_counter() - mark["t0"])
                    node_cpu_ms[k] = 1e3 * (time.thread_time() - mark["c0"])
                    last_chain = getattr(node.session.ctl.core, "last_chain", None)  # (read only: the NmpcController)
                    chain = last_chain() if last_chain is not None else None
                    solve_cpu_ms[k] = (chain.cpu_ms or 0.0) if chain is not None else float("nan")

                pub.publish = timed_publish
            return pub

        node.create_subscription = timed_subscription
        node.create_lifecycle_publisher = timed_publisher

        feeder = rclpy.create_node("bench_feeder")
        pub_state = feeder.create_publisher(CabinState, interfaces.TOPIC_STATE, interfaces.state_qos("lockstep"))
        # the preview node's QoS (a liveliness lease: the node's liveliness probes match it)
        pub_w = feeder.create_publisher(
            WeatherPreview, interfaces.TOPIC_WEATHER, interfaces.preview_publisher_qos("realtime")
        )
        pub_s = feeder.create_publisher(
            TrafficPreview, interfaces.TOPIC_TRAFFIC, interfaces.preview_publisher_qos("realtime")
        )
        commands: dict[int, Any] = {}  # (AcCommand messages)
        solve_ms: dict[int, float] = {}
        fallback: dict[int, bool] = {}
        feeder.create_subscription(
            AcCommand,
            interfaces.TOPIC_COMMAND,
            lambda m: commands.__setitem__(int(m.step_index), m),
            interfaces.command_qos("lockstep"),
        )

        def on_diag(m):
            solve_ms[int(m.step_index)] = 1e3 * m.solve_time_s
            fallback[int(m.step_index)] = bool(m.fallback)

        feeder.create_subscription(ControllerDiagnostics, interfaces.TOPIC_DIAGNOSTICS, on_diag, interfaces.QOS_COMMAND)
        ex = SingleThreadedExecutor()
        ex.add_node(node)
        ex.add_node(feeder)

        def spin_until(cond, what):
            deadline = time.monotonic() + timeout_s
            while not cond():
                if time.monotonic() > deadline:
                    raise TimeoutError(f"bench node: no {what} within {timeout_s} s")
                ex.spin_once(timeout_sec=0.01)

        spin_until(lambda: node.lifecycle == "active" and pub_state.get_subscription_count() > 0, "active mpc_node")
        spin_until(lambda: pubs["command"].get_subscription_count() > 0, "the command subscription matched")
        for k, (t_s, meas, u_prev) in enumerate(replay):
            stamp = conversions.stamp_from_s(t_s)
            p = make_previews(sc, t_s, ts, horizon_steps + 1, PERFECT)
            w, s = conversions.previews_to_msgs(p, k, stamp, "perfect")
            pub_w.publish(w)
            pub_s.publish(s)
            door = float(cols["recirc_share_cmd"][max(k * m - 1, 0)])  # the share applied over the last period
            pub_state.publish(conversions.state_msg(k * m, t_s, stamp, meas, sc.env_at(t_s), u_prev, False, door))
            spin_until(lambda k=k: k in commands and k in solve_ms, f"command for step {k}")
        ks = sorted(commands)
        return {
            "k": np.array(ks),
            "node_ms": np.array([node_ms[k] for k in ks]),
            "node_cpu_ms": np.array([node_cpu_ms[k] for k in ks]),
            "solve_ms": np.array([solve_ms[k] for k in ks]),
            "solve_cpu_ms": np.array([solve_cpu_ms[k] for k in ks]),
            "mdot_bl_kgps": np.array([commands[k].blower_flow_kgps for k in ks]),
            "t_evap_sp_c": np.array([commands[k].evap_setpoint_c for k in ks]),
            "fallback": np.array([fallback[k] for k in ks]),
            "max_command_diff_to_simulator": float(
                max(
                    max(abs(commands[k].blower_flow_kgps - diags[k].mdot_bl_kgps) for k in ks),
                    max(abs(commands[k].evap_setpoint_c - diags[k].t_evap_sp_c) for k in ks),
                )
            ),
        }
    finally:
        rclpy.try_shutdown()
        Path(config).unlink(missing_ok=True)
