"""Building a strategy's controller core: the one constructor the simulator and the nodes call.

Imports no plant code (no CoolProp): ``mpc_node`` and ``baseline_node`` start
from here.
"""

from __future__ import annotations

from ceco_core.acc_law import AccSettings
from ceco_core.cabin_comfort import comfort_params_for
from ceco_core.scenario_types import Scenario

from . import model as cm
from .baseline import BaselineController
from .estimating_controller import with_measurements
from .nmpc import NmpcController
from .strategies import load_strategy_settings

__all__ = ["make_controller"]


def make_controller(
    strategy: str,
    scenario: Scenario,
    control_period_s: float,
    horizon_steps: int,
    model_params: cm.ControlModelParams | None = None,
    overrides: dict | None = None,
    config_path: str | None = None,
    measurements: str = "full",
    estimator_settings=None,
    estimator_params=None,
):
    """Build the controller of a strategy for a scenario.

    NMPC settings: the controller file (``config_path``, default the package's
    ``config/controller.yaml``), then ``horizon_steps``/``control_period_s``, then ``overrides``.
    Baseline: ``overrides`` are :class:`~ceco_core.acc_law.AccSettings` fields.
    ``measurements``: 'full' (every modelled state read from the observation) or 'vehicle' (only the
    production sensors; the controller behind ``estimating_controller.EstimatingController``, with
    ``estimator_settings``/``estimator_params``, default the package's identified file).
    """
    ctrl: BaselineController | NmpcController
    if strategy == "baseline":
        # overrides: AccSettings fields (set-point, allowance, sun/ambient compensation)
        ctrl = BaselineController(AccSettings(**(overrides or {})), control_period_s=control_period_s)
    else:
        settings = load_strategy_settings(
            strategy, config_path, horizon_steps=horizon_steps, control_period_s=control_period_s, **(overrides or {})
        )
        ctrl = NmpcController(settings, model_params=model_params, comfort_params=comfort_params_for(scenario))
    return with_measurements(
        ctrl,
        measurements,
        control_period_s,
        model_params=model_params,
        params=estimator_params,
        settings=estimator_settings,
    )
