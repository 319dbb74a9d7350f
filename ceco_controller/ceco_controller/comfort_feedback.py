"""Comfort-output feedback of ``ceco-pmv`` (docs/controller.md 4.7): PMV bias, adaptive back-off, preview shrinkage.

The NLP of every CECO strategy predicts the scored PMV (:func:`ceco_core.cabin_comfort.cabin_pmv`) from
the control model's cabin and vent air. The temperature biases of :mod:`.offset_free` make those
offset-free; what remains between the predicted and the experienced PMV (the mean radiant temperature
and humidity held over the horizon, the vent air's duct lag, the estimator's surfaces, forecast errors)
is corrected here on the comfort output itself:

* :class:`PmvFeedback`: the *measured* PMV y(k) is the scored comfort model evaluated on the
  controller's observation (:func:`ceco_core.acc_law.feedback_pmv`, the function the comfort-feedback
  baseline regulates). Each step the model's one-step prediction of it, y0(k+1|k) (cabin air, vent air
  and blower flow of the applied command, one model step ahead, without the PMV bias), is kept; at the
  next step

      e(k) = y(k) - y0(k|k-1)                      one-step error of the unbiased prediction [PMV]
      r(k) = e(k) - d(k-1)                          residual of the prediction the NLP used [PMV]
      d(k) = clip((1 - a) d(k-1) + a e(k), -d_max, d_max)

  with a = ``pmv_bias_filter``, d_max = ``pmv_bias_limit``. The NLP adds d to its PMV (equivalently:
  both comfort bounds are moved by -d), so a constant PMV offset is removed in closed loop.
* the adaptive back-off of the upper bound on the NLP grid i = 0..N:

      m_i = clip(Q_q{r(k-W+1) .. r(k)}, m_min, m_max) + z sigma_G,i |dy/dG|

  Q_q the empirical q-quantile (``backoff_quantile``) of the last W = ``backoff_window_steps`` residuals
  (``backoff_init_pmv`` until ``backoff_min_samples`` exist); sigma_G,i = sqrt(max(0, v_i - v_1)) the
  growth of the solar estimate's mean squared error from lead 1 to lead i (v_i: the smaller of the
  measured forecast and persistence errors at lead i, :class:`PreviewSkill`), |dy/dG| the PMV's
  sensitivity to the direct irradiance at the current state, z = ``backoff_forecast_z``. The first term
  is measured at lead 1 and already holds the first step's forecast error; the second adds what the
  forecast uncertainty adds further out. Larger with larger prediction errors, larger with a worse
  forecast.
* :class:`PreviewSkill` (``preview_rule`` 'shrink'): per previewed quantity (ambient temperature, solar
  irradiance, speed) and lead i, the exponentially weighted mean squared error of the forecast issued i
  steps ago against the value measured now, v_i; each previewed change from the measured value p is
  shrunk by it (positive-part James-Stein):

      x_i = p + s_i (f_i - p),   s_i = max(0, 1 - c^2 v_i / (f_i - p)^2)

  A perfect preview (v = 0) passes unchanged; a change within the forecast's own noise is dropped (the
  preview would only add noise); a change well beyond it (a tunnel, a shade edge, a stop) passes almost
  whole. c = ``preview_shrink_c``.

numpy and Python floats (the short per-lead series element by element); no solver, no ROS. Deterministic (no clock,
no random numbers).
"""

from __future__ import annotations

import collections
import math

import numpy as np

from ceco_core.acc_law import feedback_pmv
from ceco_core.cabin_comfort import PAPER_PA_PA, ComfortParams, cabin_w_rad_wm2
from ceco_core.contracts import Observation

__all__ = [
    "PmvFeedback",
    "PreviewSkill",
    "measured_pmv",
    "pmv_solar_sensitivity",
    "held",
    "linear_quantile",
    "PREVIEW_SERIES",
]

PREVIEW_SERIES = ("t_amb", "solar", "speed")
"""The NLP's previewed series (keys of :func:`ceco_controller.observation.fill_previews`)."""

_MEASURED = {"t_amb": "t_amb_c", "solar": "solar_wm2", "speed": "speed_mps"}
_PREVIEW = {"t_amb": "preview_t_amb_c", "solar": "preview_solar_wm2", "speed": "preview_speed_mps"}


def measured_pmv(
    obs: Observation, params: ComfortParams, t_glass_c: float, rh_cab: float, pmv_fn=None, t_mr_c: float | None = None
) -> float:
    """The PMV of the observation [-]: the scored comfort model on the measured (or estimated) cabin.

    :func:`ceco_core.acc_law.feedback_pmv` with the observation's cabin air, vent air, interior and shell
    temperatures, the glazing ``t_glass_c`` (the interior temperature where the glazing is not measured,
    as the NLP's T_mr does), the cabin humidity ``rh_cab`` (the paper's 1700 Pa of vapour pressure where it is not
    measured, as the NLP's PMV has then: ``StrategySettings.pmv_pa_source``), the sun-load sensor and the blower
    flow held over the last period. ``t_glass_c`` and ``rh_cab`` are the checked values
    (:class:`ceco_core.observation_check.ObservationCheck`: NaN when not measured or implausible). NaN when another
    input is missing. ``pmv_fn``: the PMV evaluator at ``params``
    (:class:`~ceco_controller.pmv_function.CabinPmvFunction`; None: ``cabin_pmv`` on numpy); ``t_mr_c``: the mean
    radiant temperature of the same observation and glazing when the caller has it (None: computed).
    """
    t_glass = t_glass_c if math.isfinite(t_glass_c) else obs.t_int_c
    return feedback_pmv(
        t_cab_c=obs.t_cab_c,
        t_vent_c=obs.t_vent_c,
        t_int_c=obs.t_int_c,
        t_shell_c=obs.t_shell_c,
        t_glass_c=t_glass,
        rh_cab=rh_cab,
        mdot_bl_kgps=obs.mdot_bl_prev_kgps,
        solar_wm2=obs.solar_wm2,
        params=params,
        pa_pa=None if math.isfinite(rh_cab) else PAPER_PA_PA,
        pmv_fn=pmv_fn,
        t_mr_c=t_mr_c,
    )


def pmv_solar_sensitivity(
    t_cab_c: float,
    t_vent_c: float,
    mdot_bl_kgps: float,
    t_mr_c: float,
    pa_pa: float,
    solar_wm2: float,
    params,
    pmv_fn,
) -> float:
    """|dPMV/dG| [PMV per W/m2]: the PMV's sensitivity to the direct irradiance G at a state.

    A difference over 20 W/m2 (central, one-sided at G < 10 W/m2) of ``pmv_fn``, the PMV at ``params``
    (:class:`~ceco_controller.pmv_function.CabinPmvFunction`).
    """
    g = max(solar_wm2 - 10.0, 0.0)
    y = [
        pmv_fn(t_cab_c, t_vent_c, mdot_bl_kgps, t_mr_c, float(cabin_w_rad_wm2(x, params)), pa_pa) for x in (g, g + 20.0)
    ]
    d = abs(float(y[1] - y[0])) / 20.0
    return d if math.isfinite(d) else 0.0


def linear_quantile(values_sorted, q: float) -> float:
    """The q-quantile of finite ``values_sorted`` (ascending, not empty), linear between order statistics.

    ``numpy.quantile``'s default method (Hyndman & Fan's 7th: index (n - 1) q, its interpolation written as numpy
    writes it, so the value is the same to the bit; ``tests/test_comfort_feedback.py``) without its array set-up:
    1.3 us against 24 us for ``numpy.quantile`` on the back-off's 60 residuals (``timeit``).
    """
    n = len(values_sorted)
    v = (n - 1) * q
    if v >= n - 1:
        return float(values_sorted[-1])
    if v < 0:
        return float(values_sorted[0])
    i = math.floor(v)
    a, b, t = float(values_sorted[i]), float(values_sorted[i + 1]), v - i
    d = b - a
    return b - d * (1 - t) if t >= 0.5 else a + d * t


class PmvFeedback:
    """The PMV bias d and the adaptive back-off of the upper comfort bound (module docstring).

    Args:
        bias_filter: a, the bias filter gain per control step (0..1].
        bias_limit: d_max [PMV].
        quantile: q of the residual quantile [-].
        window: W, residuals kept [control steps].
        min_samples: residuals needed before the quantile is used [-].
        init: back-off until then [PMV].
        lo, hi: m_min, m_max [PMV].
        forecast_z: z of the forecast term [-].
    """

    def __init__(
        self,
        bias_filter: float,
        bias_limit: float,
        quantile: float,
        window: int,
        min_samples: int,
        init: float,
        lo: float,
        hi: float,
        forecast_z: float,
    ):
        self.a = float(bias_filter)
        self.d_max = float(bias_limit)
        self.q = float(quantile)
        self.min_samples = int(min_samples)
        self.init, self.lo, self.hi, self.z = float(init), float(lo), float(hi), float(forecast_z)
        self.residuals: collections.deque = collections.deque(maxlen=int(window))
        """The last W residuals r [PMV]."""
        self.reset()

    def reset(self) -> None:
        """Key-on: no bias, no residuals, no prediction."""
        self.bias = 0.0
        """d [PMV]."""
        self.residuals.clear()
        self._pred: float | None = None
        self.last_error: float | None = None
        """e of the last update [PMV] (None: no prediction to compare)."""
        self.last_measured: float | None = None
        """y of the last update [PMV]."""

    def update(self, y: float) -> None:
        """One step with the measured PMV ``y`` (NaN: not measured; the bias and residuals are kept)."""
        pred, self._pred = self._pred, None
        self.last_measured = y if math.isfinite(y) else None
        self.last_error = None
        if pred is None or not math.isfinite(y):
            return
        e = y - pred
        self.last_error = e
        self.residuals.append(e - self.bias)
        self.bias = float(np.clip((1.0 - self.a) * self.bias + self.a * e, -self.d_max, self.d_max))

    def remember(self, y0_next: float) -> None:
        """The unbiased model prediction y0(k+1|k) of the next measured PMV (non-finite: none)."""
        self._pred = float(y0_next) if math.isfinite(y0_next) else None

    def forget(self) -> None:
        """No prediction for the next update (an unusable step)."""
        self._pred = None

    @property
    def measured_backoff(self) -> float:
        """The residual quantile clipped to [m_min, m_max], or the initial back-off [PMV]."""
        if len(self.residuals) < self.min_samples:
            return self.init
        return min(max(linear_quantile(sorted(self.residuals), self.q), self.lo), self.hi)

    def backoff(self, solar_mse: np.ndarray, dy_dg: float) -> np.ndarray:
        """m_i on the NLP grid (one value per point of ``solar_mse``, v_i [(W/m2)^2] at leads i = 0..N) [PMV]."""
        v = np.asarray(solar_mse, float)
        grow = np.sqrt(np.maximum(0.0, v - (v[1] if v.size > 1 else v[0])))
        grow[:2] = 0.0
        return self.measured_backoff + self.z * abs(float(dy_dg)) * grow


class PreviewSkill:
    """Measured forecast and persistence errors per lead, and the preview shrinkage (module docstring).

    Args:
        n_preview: Np + 1, points of a received preview.
        window: forgetting time of the error statistics [control steps] (weight 1 - 1/window per step).
        c: shrinkage threshold [forecast-error standard deviations].
    """

    def __init__(self, n_preview: int, window: float, c: float):
        self.n1 = int(n_preview)
        self.beta = 1.0 - 1.0 / float(window)
        self.c = float(c)
        self.reset()

    def reset(self) -> None:
        """Key-on: no stored previews, no statistics (every preview trusted until measured)."""
        self._history: collections.deque = collections.deque(maxlen=self.n1)
        n1 = self.n1
        # (Python lists of floats: updated element by element at every step, read as arrays by *_mse)
        self.se_f = {q: [0.0] * n1 for q in PREVIEW_SERIES}
        """Weighted sums of squared forecast errors per lead."""
        self.se_p = {q: [0.0] * n1 for q in PREVIEW_SERIES}
        """Weighted sums of squared persistence errors per lead."""
        self.sw_f = {q: [0.0] * n1 for q in PREVIEW_SERIES}
        self.sw_p = {q: [0.0] * n1 for q in PREVIEW_SERIES}

    def update(self, obs: Observation, valid: np.ndarray) -> None:
        """Score the previews received 0..Np steps ago against this step's measurements, then store this one.

        ``valid``: the entries of ``obs``'s previews the controller trusts (valid and plausible).
        """
        meas = {q: float(getattr(obs, _MEASURED[q])) for q in PREVIEW_SERIES}
        ok_now = np.asarray(valid, bool).tolist()  # (Python lists: the scoring below reads them element by element)
        cur = {q: (np.asarray(getattr(obs, _PREVIEW[q]), float).tolist(), ok_now) for q in PREVIEW_SERIES}
        hist = list(self._history) + [(meas, cur)]
        for lead in range(min(len(hist), self.n1)):
            old_meas, old_prev = hist[-1 - lead]
            for q in PREVIEW_SERIES:
                now = meas[q]
                if not math.isfinite(now):
                    continue
                f, ok = old_prev[q]
                if ok[lead] and math.isfinite(f[lead]):
                    self._acc(self.se_f[q], self.sw_f[q], lead, (f[lead] - now) ** 2)
                if math.isfinite(old_meas[q]):
                    self._acc(self.se_p[q], self.sw_p[q], lead, (old_meas[q] - now) ** 2)
        self._history.append((meas, cur))

    def _acc(self, se: list, sw: list, lead: int, e2: float) -> None:
        se[lead] = self.beta * se[lead] + e2
        sw[lead] = self.beta * sw[lead] + 1.0

    @staticmethod
    def _mse(se: list, sw: list) -> list:
        """Mean squared error se / sw per lead, 0 where nothing was measured yet (numpy's operations on floats)."""
        return [e / (w if w >= 1e-300 else 1e-300) if w > 0.0 else 0.0 for e, w in zip(se, sw)]

    def forecast_mse(self, q: str) -> np.ndarray:
        """Measured mean squared forecast error per lead 0..Np (0 where nothing was measured yet)."""
        return np.array(self._mse(self.se_f[q], self.sw_f[q]))

    def persistence_mse(self, q: str) -> np.ndarray:
        """Measured mean squared error of holding the measured value, per lead 0..Np."""
        return np.array(self._mse(self.se_p[q], self.sw_p[q]))

    def estimate_mse(self, q: str, n_grid: int) -> np.ndarray:
        """v_i: the smaller of the forecast's and persistence's measured errors, on an NLP grid of ``n_grid`` points.

        Leads beyond Np (the horizon extension) hold lead Np's value.
        """
        # (the errors are finite or +inf, never NaN: min is numpy's minimum here)
        v = [min(a, b) for a, b in zip(self._mse(self.se_f[q], self.sw_f[q]), self._mse(self.se_p[q], self.sw_p[q]))]
        return held(v, n_grid)

    def shrink(self, series: dict, obs: Observation) -> dict:
        """The previewed series (``fill_previews``'s, possibly extended), each change from the measured value shrunk."""
        out = {}
        c2 = self.c**2
        for q, x in series.items():
            x = np.asarray(x, float)
            p = float(getattr(obs, _MEASURED[q])) if q in _MEASURED else math.nan
            if q not in PREVIEW_SERIES or not math.isfinite(p):
                out[q] = x
                continue
            # element by element on Python floats (7-13 values; numpy's per-call cost was most of the time): the
            # same IEEE operations in the same order, and NaN propagates as through numpy's maximum
            v = held(self._mse(self.se_f[q], self.sw_f[q]), x.size).tolist()  # (the horizon extension: held)
            y = []
            for i, xi in enumerate(x.tolist()):
                dx = xi - p
                s = 1.0
                if dx != 0.0:
                    dd = dx * dx
                    s = 1.0 - c2 * v[i] / (dd if not dd < 1e-300 else 1e-300)
                    s = s if not s < 0.0 else 0.0
                y.append(p + s * dx)
            out[q] = np.array(y)
        return out


def held(a, n: int) -> np.ndarray:
    """``a`` on ``n`` grid points: cut, or extended by holding its last value (the horizon extension)."""
    a = np.asarray(a, float).ravel()
    if a.size >= n:
        return a[:n].copy()
    return np.concatenate([a, np.full(n - a.size, a[-1])])
