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

from ceco_core.contracts import MEASUREMENT_MODES, NODE_STRATEGIES
from ceco_core.control_grid import TIMING_MODES
from ceco_ros.params import (
    CLOCK_AHEAD_PARAMETER,
    CONTROL_PERIOD_RANGE_S,
    DIAGNOSTICS_PERIOD_PARAMETER,
    HORIZON_RANGE,
    INPUT_WINDOW_PARAMETERS,
    NMPC_CONTROL_PERIOD_RANGE_S,
    SHARED_FIELDS,
    NodeConfig,
    ParamSpec,
    liveliness_parameter,
    log_throttle_parameter,
)

__all__ = ['controller_parameters', 'ControllerNodeConfig', 'DYNAMIC']


def controller_parameters(fixed_strategy: str | None = None) -> tuple[ParamSpec, ...]:
    """The parameter table of mpc_node (``fixed_strategy`` None) or baseline_node ('baseline').

    The configuration (what configure builds: the controller, the inputs' gate, the entities) is
    settable while the node is unconfigured and applied on the next configure (``at_configure``);
    ``autostart`` and the /diagnostics period only at start; the rest at any time.
    """
    strategy = (
        ()
        if fixed_strategy
        else (
            ParamSpec(
                'strategy',
                'ceco-ioch',
                'CECO strategy: ceco (general), ceco-e (energy), ceco-c (comfort), ceco-ioch (speed-aware slack), '
                'ceco-pmv (comfort output held at its bound), ceco-pmv-aq (ceco-pmv with the CO2-holding recirculation '
                'door), ceco-pmv-door (ceco-pmv with the door in its NLP)',
                choices=NODE_STRATEGIES,
                at_configure=True,
            ),
        )
    )
    return strategy + (
        ParamSpec(
            'scenario',
            'sc03',
            'scenario name or YAML path: occupant (met, clo) and PMV comfort bounds',
            at_configure=True,
        ),
        ParamSpec(
            'timing',
            'lockstep',
            'lockstep (event driven, deterministic) or realtime (timer every Ts on the node clock)',
            choices=TIMING_MODES,
            at_configure=True,
        ),
        ParamSpec(
            'control_period_s',
            5.0,
            'control period Ts [s]; a whole multiple of the control model step (5 s)'
            + (' with measurements vehicle (its estimator steps the model)' if fixed_strategy else ''),
            float_range=CONTROL_PERIOD_RANGE_S if fixed_strategy else NMPC_CONTROL_PERIOD_RANGE_S,
            at_configure=True,
        ),
        ParamSpec('horizon_steps', 6, 'prediction horizon Np [steps]', int_range=HORIZON_RANGE, at_configure=True),
        ParamSpec(
            'controller_config',
            '',
            "baseline law file (acc_law: AccSettings fields, e.g. the package's config/baseline_pmv.yaml for the "
            "comfort-feedback PI; empty: the production law)"
            if fixed_strategy == 'baseline'
            else "NMPC settings file (solver, weights, bounds; empty: the package's config/controller.yaml); Np and "
            "Ts are horizon_steps and control_period_s, and a file giving other values is refused at configure",
            at_configure=True,
        ),
        ParamSpec(
            'measurements',
            'full',
            'full (every modelled state from cabin/state) or vehicle (only the '
            'production sensors; an EKF estimates the rest, ceco_controller.estimator)',
            choices=MEASUREMENT_MODES,
            at_configure=True,
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
            'lockstep: wall-clock wait for the previews of a step before solving without them; realtime: '
            'previews count as missed when none came for Ts + this [s]; keep it below the plant\'s '
            'lockstep.command_timeout_s',
            float_range=(0.1, 60.0),
            read_only=False,
        ),
        ParamSpec(
            'lockstep.min_command_subscribers',
            1,
            'lockstep: matched hvac/command subscriptions (the plant; ceco run: plant and recorder) before a '
            'command is sent; until then it is held, so no subscriber misses a step [-]',
            int_range=(1, 100),
            at_configure=True,
        ),
        ParamSpec(
            'max_state_age_s',
            10.0,
            'realtime: oldest usable cabin state, by its stamp; at least Ts (a state of the current control '
            'step is usable until the next one) [s]',
            float_range=(0.1, 3600.0),
            read_only=False,
        ),
        *(dataclasses.replace(p, at_configure=True) for p in INPUT_WINDOW_PARAMETERS),
        CLOCK_AHEAD_PARAMETER,
        log_throttle_parameter(),
        liveliness_parameter(
            'automatic liveliness lease offered on hvac/command and requested of the preview publishers: '
            'a dead peer is known within it; at most Ts and at most the plant\'s qos.liveliness_lease_s [s]',
            at_configure=True,
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
    """baseline, ceco, ceco-e, ceco-c, ceco-ioch or ceco-pmv."""
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
    liveliness_lease_s: float = 1.0
    """Automatic liveliness lease offered on hvac/command, requested of the preview publishers [s]."""
    diagnostics_period_s: float = 1.0
    """/diagnostics period [s]."""
    solve_time_warn_fraction: float = 0.5
    """WARN above this fraction of Ts per step [-]."""

    PARAM_FIELDS = {
        **SHARED_FIELDS,
        'lockstep.min_command_subscribers': 'min_command_subscribers',
        'diagnostics.solve_time_warn_fraction': 'solve_time_warn_fraction',
    }
    POSITIVE = (
        'control_period_s',
        'preview_timeout_s',
        'max_state_age_s',
        'window_s',
        'liveliness_lease_s',
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
        allowed = NODE_STRATEGIES + ('baseline',)
        if self.strategy not in allowed:
            raise ValueError(
                f'invalid parameter strategy={self.strategy!r}: unknown strategy, '
                f'must be one of {", ".join(NODE_STRATEGIES)}'
            )
        super().validate()
        ts = self.control_period_s
        # Ranges derived from the others: values that would keep the node from commanding.
        for name, value, floor, why in (
            ('max_state_age_s', self.max_state_age_s, ts, 'a state of the current control step must stay usable'),
            ('inputs.window_s', self.window_s, ts, 'the next control step\'s state must be inside the window'),
        ):
            if value < floor:
                raise ValueError(
                    f'invalid parameter {name}={value!r}: must be at least control_period_s={ts!r} ({why})'
                )
        if self.liveliness_lease_s > ts:
            raise ValueError(
                f'invalid parameter qos.liveliness_lease_s={self.liveliness_lease_s!r}: must be at most '
                f'control_period_s={ts!r} (a dead controller is to be noticed within a control period)'
            )
        self._check_model_step()

    def _check_model_step(self) -> None:
        """Ts a whole multiple of the control model's step where the model is stepped.

        The NMPC and the estimator of ``measurements: vehicle`` apply this rule at configure (``model.substeps``);
        here it is checked at start and on ``ros2 param set``. A model file that cannot be read is left to configure
        to report.
        """
        if self.strategy == 'baseline' and self.measurements != 'vehicle':
            return  # the ACC law runs at any Ts the plant step divides
        from . import model as cm  # here: casadi only for the nodes that step the model

        try:
            params = cm.load_params()
        except (OSError, ValueError):
            return
        try:
            cm.substeps(params, self.control_period_s)
        except ValueError as err:
            raise ValueError(f'invalid parameter control_period_s={self.control_period_s!r}: {err}') from None

    @property
    def window_steps(self) -> int:
        """The state window in control steps (previews of a later step are not buffered) [-]."""
        return max(1, int(math.ceil(self.window_s / self.control_period_s)))
