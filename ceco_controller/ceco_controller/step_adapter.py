"""mpc_node's message adapter: the checked inputs of one control step -> the Observation.

The inputs are a CabinState and the two previews; the core's
:class:`~ceco_core.contracts.Observation` is built by the simulator's own
:func:`ceco_controller.observation.observation` so a DDS run equals the simulator bit for bit.
"""

from __future__ import annotations

import ceco_ros.conversions as conversions
from ceco_core.contracts import AcInput, Observation

from .controller_io import ControllerNodeConfig, StepInputs
from .observation import observation

__all__ = ['step_observation']


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
