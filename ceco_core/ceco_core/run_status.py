"""Did the controller control the run? The rule that makes a run *failed*, written once.

A run is a result of its controller only when the controller's own commands drove the plant. A
control step is a *fallback step* when the production ACC law drove at least one of its plant steps
(the plant's supervisor: no acceptable command in time, ``AcPower.fallback``) or when the command
applied for it came from the controller's own fallback chain (``AcCommand.fallback`` /
``Diagnostics.fallback``: a shifted previous plan or the baseline law after a failed solve). The
benchmark KPI ``fallback_steps`` counts the same steps.

A run with more fallback steps than :data:`MAX_FALLBACK_SHARE` of its control steps (and more than
:data:`KEY_ON_FALLBACK_STEPS`), or with no control step of the controller's own (every step a fallback
step, however short the run: the key-on allowance never makes a run whose controller never acted a
result), is **failed**:
``ceco run`` and ``ceco sim`` mark it in metrics.json (``status``, ``status_reason``) and exit 1,
``ceco benchmark`` keeps its KPIs with ``status: failed`` and never matches it against the baselines
(docs/benchmark.md, "Failed runs"). A controller that only publishes NaN, out-of-range or late
commands is then a failed run, not a copy of the plant's fallback law scored as a strategy.

Pure Python (numpy); no ROS import.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable

import numpy as np

__all__ = [
    'MAX_FALLBACK_SHARE',
    'KEY_ON_FALLBACK_STEPS',
    'STATUS_OK',
    'STATUS_FAILED',
    'ControlCheck',
    'check_control',
    'fallback_control_steps',
]

MAX_FALLBACK_SHARE = 0.05
"""Largest share of a run's control steps that may be fallback steps [-] (5 %: 6 of SC03's 120).

Room for a few missed solves; far below what a controller that does not control produces (all
steps). Every nominal NMPC run of the full benchmark has 0 fallback steps (docs/results.md)."""

KEY_ON_FALLBACK_STEPS = 2
"""Fallback steps a run may always have [-], whatever its length: the real-time key-on.

In real time the plant steps from t = 0 on its own clock and takes a command only at a control-step
boundary, so its law drives until the first accepted command applies: measured on `ceco run
--timing realtime` (30 s, baseline), plant steps 0-4, control step 0 (1 of 6); a first command that
misses the boundary at t = Ts adds step 1, hence 2. (Counted 2 before the time series flagged plant
steps by ``AcPower.fallback`` alone: the state at t = Ts, still in fallback, added plant step 5.)
Lockstep runs have none."""

STATUS_OK = 'ok'
"""Status of a run whose controller controlled it."""

STATUS_FAILED = 'failed'
"""Status of a finished run whose controller did not control it (its numbers are not a result)."""


@dataclasses.dataclass(frozen=True)
class ControlCheck:
    """How many control steps of a run were fallback steps, and the verdict."""

    n_control_steps: int
    """Control steps of the run [-]."""
    n_fallback_steps: int
    """Of them, fallback steps (module docstring) [-]."""
    max_share: float = MAX_FALLBACK_SHARE
    """The largest allowed share of fallback steps [-]."""

    @property
    def share(self) -> float:
        """Fallback steps over control steps [-] (1.0 for a run without control steps)."""
        return self.n_fallback_steps / self.n_control_steps if self.n_control_steps else 1.0

    @property
    def allowed(self) -> int:
        """Fallback steps this run may have [-]: the share of its steps, at least the key-on's."""
        return max(int(math.floor(self.max_share * self.n_control_steps + 1e-9)), KEY_ON_FALLBACK_STEPS)

    @property
    def ok(self) -> bool:
        """True when the controller controlled the run: fallbacks within :attr:`allowed`, at least one step its own."""
        return self.n_fallback_steps <= self.allowed and self.n_fallback_steps < self.n_control_steps

    @property
    def status(self) -> str:
        """:data:`STATUS_OK` or :data:`STATUS_FAILED`."""
        return STATUS_OK if self.ok else STATUS_FAILED

    @property
    def reason(self) -> str:
        """Why the run failed ('' when it did not)."""
        if self.ok:
            return ''
        if not self.n_control_steps:
            return 'the run has no control step'
        counted = f'the controller did not control the run: {self.n_fallback_steps} of {self.n_control_steps} '
        if self.n_fallback_steps == self.n_control_steps:
            return counted + (
                'control steps in fallback (none was its own; the production ACC law or the controller\'s '
                'fallback drove them all)'
            )
        return counted + (
            f'control steps in fallback ({100.0 * self.share:.1f} %; at most {self.allowed} allowed: '
            f'{100.0 * self.max_share:g} % of the steps, at least the {KEY_ON_FALLBACK_STEPS} of a real-time '
            'key-on; the production ACC law or the controller\'s fallback drove them)'
        )

    def as_metrics(self) -> dict:
        """The verdict as a run's metrics.json carries it.

        Keys ``status``, ``status_reason``, ``fallback_control_steps``, ``fallback_share``,
        ``max_fallback_share``.
        """
        return {
            'status': self.status,
            'status_reason': self.reason,
            'fallback_control_steps': int(self.n_fallback_steps),
            'fallback_share': float(self.share),
            'max_fallback_share': float(self.max_share),
        }


def check_control(n_control_steps: int, n_fallback_steps: int, max_share: float = MAX_FALLBACK_SHARE) -> ControlCheck:
    """The verdict on a run with ``n_fallback_steps`` fallback steps among ``n_control_steps``.

    Raises ValueError for negative counts, more fallback steps than control steps or a share
    outside [0, 1].
    """
    n, f = int(n_control_steps), int(n_fallback_steps)
    if n < 0 or f < 0 or f > n:
        raise ValueError(f'fallback steps {n_fallback_steps!r} of {n_control_steps!r} control steps: need 0 <= f <= n')
    if not (math.isfinite(max_share) and 0.0 <= max_share <= 1.0):
        raise ValueError(f'max_share: must be in [0, 1], got {max_share!r}')
    return ControlCheck(n, f, float(max_share))


def fallback_control_steps(
    plant_fallback: Iterable[bool], steps_per_control: int, controller_fallback_steps: Iterable[int] = ()
) -> tuple[int, int]:
    """``(control steps, fallback steps)`` of a run recorded per plant step.

    Args:
        plant_fallback: per plant step n = 0, 1, ...: True when the plant's ACC law drove it,
            [t_n, t_n+1) (``AcPower.fallback`` of step n; not ``CabinState.fallback`` at t_n, the
            plant's mode when that state went out, still True at the end of a fallback period).
        steps_per_control: plant steps per control period [-] (Ts / dt).
        controller_fallback_steps: control steps k whose applied command the controller marked as a
            fallback (``AcCommand.fallback``); steps beyond the run are ignored.

    Returns:
        The run's control steps (ceil(plant steps / steps_per_control)) and how many of them were
        fallback steps.
    """
    m = int(steps_per_control)
    if m < 1:
        raise ValueError(f'steps_per_control: must be >= 1, got {steps_per_control!r}')
    fb = np.asarray(list(plant_fallback), dtype=bool)
    n_ctrl = -(-fb.size // m)
    steps = {n // m for n in np.flatnonzero(fb).tolist()}
    steps |= {int(k) for k in controller_fallback_steps if 0 <= int(k) < n_ctrl}
    return n_ctrl, len(steps)
