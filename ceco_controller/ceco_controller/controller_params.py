"""The parameters of mpc_node and baseline_node: their table and the validated configuration.

:func:`controller_parameters` is the one table (type, default, description with unit, range) that
the node declares, validates and documents (docs/ros.md's tables come from it);
:class:`ControllerNodeConfig` is the validated configuration built from the declared values.
Pure: no rclpy.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from ceco_core.contracts import CECO_STRATEGIES, MEASUREMENT_MODES
from ceco_core.control_grid import TIMING_MODES
from ceco_ros.params import (
    CLOCK_AHEAD_PARAMETER,
    DIAGNOSTICS_PERIOD_PARAMETER,
    INPUT_WINDOW_PARAMETERS,
    SHARED_FIELDS,
    NodeConfig,
    ParamSpec,
    log_throttle_parameter,
)

__all__ = ['controller_parameters', 'ControllerNodeConfig', 'DYNAMIC']


def controller_parameters(fixed_strategy: str | None = None) -> tuple[ParamSpec, ...]:
    """The parameter table of mpc_node (``fixed_strategy`` None) or baseline_node ('baseline')."""
    strategy = (
        ()
        if fixed_strategy
        else (
            ParamSpec(
                'strategy',
                'ceco-ioch',
                'CECO strategy: ceco (general), ceco-e (energy), ceco-c (comfort), ceco-ioch (speed-aware slack)',
            ),
        )
    )
    return strategy + (
        ParamSpec('scenario', 'sc03', 'scenario name or YAML path: occupant (met, clo) and PMV comfort bounds'),
        ParamSpec(
            'timing',
            'lockstep',
            'lockstep (event driven, deterministic) or realtime (timer every Ts on the node clock)',
            choices=TIMING_MODES,
        ),
        ParamSpec('control_period_s', 5.0, 'control period Ts [s]', float_range=(0.1, 3600.0)),
        ParamSpec('horizon_steps', 6, 'prediction horizon Np [steps]', int_range=(1, 200)),
        ParamSpec(
            'controller_config',
            '',
            "baseline law file (acc_law: AccSettings fields, e.g. the package's config/baseline_pmv.yaml for the "
            "comfort-feedback PI; empty: the production law)"
            if fixed_strategy == 'baseline'
            else "NMPC settings file (solver, weights, bounds; empty: the package's config/controller.yaml)",
        ),
        ParamSpec(
            'measurements',
            'full',
            'full (every modelled state from cabin/state) or vehicle (only the '
            'production sensors; an EKF estimates the rest, ceco_controller.estimator)',
            choices=MEASUREMENT_MODES,
        ),
        ParamSpec(
            'autostart',
            False,
            'configure and activate by itself after start (true), or wait for a '
            'lifecycle manager (false: ceco run, the launch file)',
        ),
        ParamSpec(
            'preview_timeout_s',
            2.0,
            'lockstep: wall-clock wait for the previews of a step before solving without them [s]',
            float_range=(0.01, 600.0),
            read_only=False,
        ),
        ParamSpec(
            'lockstep.min_command_subscribers',
            1,
            'lockstep: matched hvac/command subscriptions (the plant; ceco run: plant and recorder) before a '
            'command is sent; until then it is held, so no subscriber misses a step [-]',
            int_range=(1, 100),
        ),
        ParamSpec(
            'max_state_age_s',
            10.0,
            'realtime: oldest usable cabin state, by its stamp [s]',
            float_range=(0.01, 3600.0),
            read_only=False,
        ),
        *INPUT_WINDOW_PARAMETERS,
        CLOCK_AHEAD_PARAMETER,
        log_throttle_parameter(),
        ParamSpec(
            'qos.command_deadline_periods',
            2.0,
            'realtime: offered deadline of hvac/command [control '
            'periods]; must not exceed the plant\'s fallback.command_timeout_periods',
            float_range=(0.1, 1000.0),
        ),
        DIAGNOSTICS_PERIOD_PARAMETER,
        ParamSpec(
            'diagnostics.solve_time_warn_fraction',
            0.5,
            'WARN when a step takes longer than this fraction of the control period (ERROR above the period) [-]',
            float_range=(0.01, 1.0),
            read_only=False,
        ),
    )


DYNAMIC = {
    'preview_timeout_s',
    'max_state_age_s',
    'inputs.max_clock_ahead_s',
    'inputs.log_throttle_s',
    'diagnostics.solve_time_warn_fraction',
}
"""Parameters that ``ros2 param set`` changes at run time (the rest are read-only)."""


@dataclasses.dataclass(frozen=True)
class ControllerNodeConfig(NodeConfig):
    """Validated parameters of mpc_node / baseline_node."""

    strategy: str
    """baseline, ceco, ceco-e, ceco-c or ceco-ioch."""
    scenario: str
    """Scenario: the occupant (met, clo) and the PMV comfort bounds (the occupant's settings)."""
    timing: str
    """lockstep or realtime."""
    control_period_s: float
    """Control period Ts [s]."""
    horizon_steps: int
    """Prediction horizon Np [steps]."""
    preview_timeout_s: float = 2.0
    """lockstep: wall-clock wait for the previews of a step before solving without them [s]."""
    max_state_age_s: float = 10.0
    """realtime: oldest usable state [s]."""
    min_command_subscribers: int = 1
    """lockstep: matched hvac/command subscriptions before a command is sent (held until then) [-]."""
    controller_config: str = ''
    """NMPC settings file ('' : the package's config/controller.yaml)."""
    measurements: str = 'full'
    """'full' or 'vehicle' (production sensors + estimator)."""
    autostart: bool = False
    """Configure and activate without a lifecycle manager."""
    window_s: float = 60.0
    """How far ahead of the last accepted scenario time a state is accepted [s]."""
    confirm_count: int = 3
    """Consecutive agreeing out-of-window states that establish a new time base [-]."""
    restart_silence_s: float = 3.0
    """A new time base only after no state was accepted for this long [s, wall clock]."""
    max_clock_ahead_s: float = 1.0
    """realtime: how far a stamp may lead the node clock [s]."""
    log_throttle_s: float = 2.0
    """Shortest time between two log lines about one kind of rejection [s]."""
    command_deadline_periods: float = 2.0
    """realtime: offered deadline of hvac/command [control periods]."""
    diagnostics_period_s: float = 1.0
    """/diagnostics period [s]."""
    solve_time_warn_fraction: float = 0.5
    """WARN above this fraction of Ts per step [-]."""

    PARAM_FIELDS = {
        **SHARED_FIELDS,
        'qos.command_deadline_periods': 'command_deadline_periods',
        'lockstep.min_command_subscribers': 'min_command_subscribers',
        'diagnostics.solve_time_warn_fraction': 'solve_time_warn_fraction',
    }
    POSITIVE = (
        'control_period_s',
        'preview_timeout_s',
        'max_state_age_s',
        'window_s',
        'command_deadline_periods',
        'diagnostics_period_s',
        'solve_time_warn_fraction',
    )

    @classmethod
    def from_params(cls, values: dict[str, Any], fixed_strategy: str | None = None) -> ControllerNodeConfig:
        """From the declared parameters (``{name: value}``), validated."""
        kw = cls.fields_of(values)
        kw.setdefault('strategy', fixed_strategy)
        cfg = cls(**kw)
        cfg.validate()
        return cfg

    def validate(self) -> None:
        """Raise ValueError naming the parameter."""
        allowed = CECO_STRATEGIES + ('baseline',)
        if self.strategy not in allowed:
            raise ValueError(
                f'invalid parameter strategy={self.strategy!r}: unknown strategy, '
                f'must be one of {", ".join(CECO_STRATEGIES)}'
            )
        super().validate()

    @property
    def window_steps(self) -> int:
        """The state window in control steps (previews of a later step are not buffered) [-]."""
        return max(1, int(math.ceil(self.window_s / self.control_period_s)))
