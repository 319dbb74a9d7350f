"""Offset-free correction of the NMPC (docs/controller.md 4.4): additive bias estimates.

d_ain = filter(T_vent,meas - eq. (3)) and the one-step prediction errors of T_cab and T_evap
(measured minus the model's prediction made one control step earlier with the applied command),
each filtered by a first-order filter of gain a and limited to |d| <= d_max:

    d(k) = clip((1 - a) d(k-1) + a e(k), -d_max, d_max)

where e [K] is the error, a = ``StrategySettings.bias_filter`` [-] and d_max =
``StrategySettings.bias_limit_k`` [K].
"""

from __future__ import annotations

import math

import numpy as np

from . import model as cm

__all__ = ["BiasEstimator"]


def _clip(x: float, lim: float) -> float:
    """The finite value ``x`` limited to [-lim, lim]."""
    return min(max(float(x), -lim), lim)


class BiasEstimator:
    """The three bias estimates (d_cab [K per control step], d_evap [K per control step], d_ain [K])."""

    def __init__(
        self, model_params: cm.ControlModelParams, gain: float, limit_k: float, n_sub: int, enabled: bool = True
    ):
        self.model_params = model_params
        self.gain = float(gain)
        self.limit_k = float(limit_k)
        self.n_sub = int(n_sub)
        self.enabled = bool(enabled)
        self.reset()

    def reset(self) -> None:
        """Forget the estimates and the last prediction."""
        self.bias = np.zeros(3)
        """(d_cab, d_evap, d_ain)."""
        self.last_pred: tuple | None = None
        """(T_cab, T_evap) predicted one control step ahead without the T_cab/T_evap biases [degC]."""

    @property
    def values(self) -> np.ndarray:
        """The estimates entering the NLP (zeros when disabled)."""
        return self.bias if self.enabled else np.zeros(3)

    def update(self, t_cab_c: float, t_evap_c: float, t_vent_c: float, mdot_bl_prev_kgps: float) -> None:
        """One filter step from the measurements and the command applied over the last period."""
        if not self.enabled:
            return
        a, lim, mp = self.gain, self.limit_k, self.model_params
        # vent air: measured vs model at the measured evaporator temperature and the applied flow
        e_ain = t_vent_c - float(cm.t_ain_c(mp, t_evap_c, mdot_bl_prev_kgps))
        if math.isfinite(e_ain):  # a non-finite error never enters the state (the caller checks too)
            self.bias[2] = _clip((1 - a) * self.bias[2] + a * e_ain, lim)
        if self.last_pred is not None:
            e_cab = t_cab_c - self.last_pred[0]
            e_evap = t_evap_c - self.last_pred[1]
            if math.isfinite(e_cab) and math.isfinite(e_evap):
                self.bias[0] = _clip((1 - a) * self.bias[0] + a * e_cab, lim)
                self.bias[1] = _clip((1 - a) * self.bias[1] + a * e_evap, lim)

    def predict(
        self,
        t_cab_c: float,
        t_evap_c: float,
        mdot: float,
        sp: float,
        t_int_c: float,
        t_shell_c: float,
        t_amb_c: float,
        speed_mps: float,
    ) -> None:
        """Remember the model's one-period prediction (without the T_cab/T_evap biases) for the next update."""
        t_cab, t_evap, *_ = cm.step(
            self.model_params,
            t_cab_c,
            t_evap_c,
            mdot,
            sp,
            t_int_c,
            t_shell_c,
            t_amb_c,
            speed_mps,
            n_sub=self.n_sub,
            d_ain_k=self.bias[2] if self.enabled else 0.0,
        )
        pred = (float(t_cab), float(t_evap))
        self.last_pred = pred if all(math.isfinite(v) for v in pred) else None

    def forget_prediction(self) -> None:
        """No prediction for the next update (e.g. after an unusable observation)."""
        self.last_pred = None
