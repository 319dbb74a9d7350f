"""mpc_node's controller side: the checked inputs of one control step -> the Observation -> the command.

The inputs are a CabinState and the two previews; the core's
:class:`~ceco_core.contracts.Observation` is built by the simulator's own
:func:`ceco_controller.observation.observation` so a DDS run equals the simulator bit for bit
(:func:`step_observation`). :class:`NodeController` is the controller a node drives: built
and warmed up from the node's configuration in the lifecycle configure transition, then one
control step per call. No rclpy here; messages are read by attribute.
"""

from __future__ import annotations

import ceco_ros.conversions as conversions
from ceco_core.contracts import AcInput, Diagnostics, Observation
from ceco_v2x_preview.scenario import load_scenario_param

from .controller_io import ControllerNodeConfig, StepInputs, warm_up
from .observation import observation

__all__ = ['step_observation', 'NodeController']


def step_observation(
    si: StepInputs, cfg: ControllerNodeConfig, scenario, prev_cmd: AcInput | None
) -> tuple[Observation, str]:
    """``(observation, note)``; ``note`` says why the step is solved without previews ('' if with).

    Real time: the previews are re-gridded to the state's time (``conversions.align_previews``).
    The previous command is this node's last one, or at the first step the plant's (key-on).
    """
    ts = cfg.control_period_s
    st, w, s, note = si.state, si.weather, si.traffic, si.note
    t_s = st.scenario_time_s  # n * dt, exactly the simulator's t
    if w is not None and s is not None and cfg.timing == 'realtime':
        aligned = conversions.align_previews(w, s, t_s, ts)
        if aligned is None:
            note = f'previews starting at {conversions.s_from_stamp(w.start):.1f} s do not cover t = {t_s:.1f} s'
        w, s = aligned if aligned is not None else (None, None)
    if w is None or s is None:
        w, s = conversions.empty_previews(cfg.horizon_steps + 1, ts)
        note = note or 'no previews'
    prev = prev_cmd or AcInput(mdot_bl_kgps=st.mdot_bl_kgps, t_evap_sp_c=st.t_evap_sp_c)
    obs = observation(
        si.k, t_s, conversions.state_measurements(st), st, prev, conversions.previews(w, s, t_s, ts), scenario
    )
    return obs, note


class NodeController:
    """The controller core of mpc_node / baseline_node, built and warmed up from the node's configuration.

    Raises ValueError, RuntimeError or OSError (a bad scenario, controller file or solver) at
    construction; the node then fails its configure transition.
    """

    def __init__(self, cfg: ControllerNodeConfig):
        """Load the scenario, build the strategy's controller and pay its first solve (:func:`warm_up`)."""
        from . import factory  # here: baseline_node never imports the NMPC modules

        self.scenario = load_scenario_param(cfg.scenario)
        self.core = factory.make_controller(
            cfg.strategy,
            self.scenario,
            control_period_s=cfg.control_period_s,
            horizon_steps=cfg.horizon_steps,
            config_path=cfg.controller_config or None,
            measurements=cfg.measurements,
        )
        self.warm_up = warm_up(self.core, self.scenario, cfg.control_period_s, cfg.horizon_steps)
        """How the first solve was done (for the log)."""
        self.prev_cmd: AcInput | None = None
        """The last command this controller computed (the next step's previous command)."""

    def reset(self) -> None:
        """A fresh controller state (activation, a backward time jump)."""
        self.prev_cmd = None
        self.core.reset()

    @property
    def step_budget_s(self) -> float | None:
        """The core's own deadline of a whole step [s] (the NMPC's step budget), None without one."""
        solver = getattr(getattr(self.core, 'settings', None), 'solver', None)
        return getattr(solver, 'step_budget_s', None)

    def settle(self) -> None:
        """The core's work for its next step that its command did not need (``NmpcController.settle``).

        A core without such work (the ACC law) has nothing to do.
        """
        settle = getattr(self.core, 'settle', None)
        if callable(settle):
            settle()

    def step(self, si: StepInputs, cfg: ControllerNodeConfig) -> tuple[AcInput, Diagnostics, str]:
        """``(command, diagnostics, note)`` of control step ``si.k``; the NMPC's deadline counts from this call.

        ``note`` says why the step was solved without previews ('' if with).
        """
        t_start = self.core.clock() if callable(getattr(self.core, 'clock', None)) else None
        obs, note = step_observation(si, cfg, self.scenario, self.prev_cmd)
        cmd, diag = self.core.compute(obs, t_start=t_start)
        self.prev_cmd = cmd
        return cmd, diag, note
