"""The scored PMV at fixed comfort parameters as a CasADi Function, for the controllers' per-step comfort reads.

:func:`ceco_core.cabin_comfort.cabin_pmv` is written once for numpy and CasADi (``ceco_core.mathops``). On
numpy scalars one evaluation costs about 100 us (input checks, the Newton steps of the clothing temperature on
0-d arrays); ceco-pmv reads it three times per control step (the measured PMV, its sensitivity to the sun, the
one-step prediction) and the PMV feedback law once. :class:`CabinPmvFunction` evaluates the same code on CasADi
symbols once, at construction, and then the Function in place (:class:`~ceco_controller.buffered.BufferedFunction`):
about 2 us. Its values agree with the numpy evaluation to about 1e-14 relative (the operations' order;
``tests/test_comfort_feedback.py``). Unlike the numpy path it does not raise on a NaN or out-of-range input:
NaN in, NaN out; its callers check their inputs first.
"""

from __future__ import annotations

import casadi
import numpy as np

from ceco_core.cabin_comfort import ComfortParams, cabin_pmv

from .buffered import BufferedFunction

__all__ = ["CabinPmvFunction"]


class CabinPmvFunction:
    """``cabin_pmv(t_cab_c, t_vent_c, mdot_bl_kgps, t_mr_c, w_rad_wm2, pa_pa)`` at ``params`` [-] (module docstring)."""

    def __init__(self, params: ComfortParams):
        self.params = params.validate()
        x = casadi.SX.sym("x", 6)
        y = cabin_pmv(
            t_cab_c=x[0], t_vent_c=x[1], mdot_bl_kgps=x[2], t_mr_c=x[3], w_rad_wm2=x[4], pa_pa=x[5], params=params
        )
        self._fn = BufferedFunction(casadi.Function("ceco_cabin_pmv", [x], [y]))
        self._x = np.zeros(6)

    def __call__(self, t_cab_c, t_vent_c, mdot_bl_kgps, t_mr_c, w_rad_wm2, pa_pa) -> float:
        """The PMV at one state [-] (inputs as :func:`~ceco_core.cabin_comfort.cabin_pmv`'s, scalars)."""
        x = self._x
        x[0], x[1], x[2], x[3], x[4], x[5] = t_cab_c, t_vent_c, mdot_bl_kgps, t_mr_c, w_rad_wm2, pa_pa
        return float(self._fn(x)[0][0])
