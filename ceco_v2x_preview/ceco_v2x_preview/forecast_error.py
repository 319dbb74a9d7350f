"""Forecast-uncertainty levels of the benchmark: seeded AR(1) errors along the lead time.

The structure is BOPTEST's weather-forecast uncertainty emulator (Zheng, Zabala,
Febres, Blum, Wang 2025, "Quantifying and simulating the weather forecast
uncertainty for advanced building control", J. Building Performance Simulation,
doi:10.1080/19401493.2025.2453537; ibpsa/project1-boptest ``forecast/``): the
error of a forecast along its lead time is a first-order autoregressive process,
Gaussian for the air temperature and Laplace (heavy-tailed) for the solar
irradiance, with four levels ``none``, ``low``, ``medium``, ``high``. BOPTEST steps
it hourly over 48 h; a car's previews cover 30 s (Np = 6, Ts = 5 s) to a few
minutes, and the car measures ambient temperature and sun load itself, so here
the process is the continuous-time AR(1) (Ornstein-Uhlenbeck) process in the lead
time tau, anchored at the measurement:

    e(0) = 0,   e(tau + h) = phi e(tau) + eps,   phi = exp(-h / theta),
    E[eps] = mu (1 - phi),   Var[eps] = sigma_inf^2 (1 - phi^2)
    =>  E[e(tau)] = mu (1 - exp(-tau/theta)),
        Var[e(tau)] = sigma_inf^2 (1 - exp(-2 tau/theta))

where tau is the lead time [s], h = 1 s the simulation grid of the error (values
at other leads by linear interpolation), theta the correlation time [s],
sigma_inf the stationary standard deviation and mu the stationary mean (the
quantity's unit). A level fixes, per quantity, the error's standard deviation
``sigma_ref`` and mean ``bias_ref`` at the reference lead ``ref_lead_s`` = 30 s
and theta; sigma_inf and mu follow (:class:`ErrorModel`). The forecast is
``truth + e`` (BOPTEST subtracts its error: its signs are converted).

Values and sources (docs/benchmark.md, "Forecast uncertainty"): ambient
temperature and solar magnitudes are BOPTEST's one-hour-ahead statistics of the
same level (temperature K0/F0, solar Laplace bg0/ag0 with std = sqrt(2) bg0),
applied at 30 s: conservative. Speed-preview errors from receding-horizon speed
predictors (Topic, Skugor, Deur 2022, Sustainability 14(17):10674: R^2 ~ 0.6 at
25 s on city-bus data; Khanalipour et al. 2026, Amirkabir J. Mech. Eng. 57(11):
0.24 m/s MAE over 6 s on the highway with preceding-vehicle data).

Physical limits (as :mod:`ceco_v2x_preview.preview`): forecast solar and speed
are floored at 0; no solar error where the true irradiance is 0 (night, tunnel),
as BOPTEST.

Determinism: the error of the forecast issued at ``t_issue_s`` for quantity q is
drawn from ``numpy.random.default_rng([seed, round(t_issue_s * 1000), q, 1])``,
so it depends only on the seed, the issue time, the quantity and the lead time
(the simulator and preview_node give identical previews).

Pure numpy; no ROS import.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np

__all__ = [
    "LEVELS",
    "QUANTITIES",
    "REF_LEAD_S",
    "ErrorModel",
    "LEVEL_MODELS",
    "level_models",
    "lead_errors",
    "forecast_errors",
    "apply_errors",
]

LEVELS = ("none", "low", "medium", "high")
"""Forecast-uncertainty levels, from perfect previews to the worst."""

QUANTITIES = ("t_amb_c", "solar_wm2", "speed_mps")
"""Previewed quantities with an error model (index = the noise stream's q)."""

REF_LEAD_S = 30.0
"""Reference lead time at which a level states its error statistics [s] (Np * Ts of the paper)."""

_GRID_S = 1.0
"""Lead-time step on which the error process is simulated [s]."""

_STREAM = 1
"""Last element of the seed sequence: keeps these streams apart from the 'noisy' model's."""

DISTRIBUTIONS = ("normal", "laplace")
"""Innovation distributions (BOPTEST: normal for temperature, Laplace for irradiance)."""


@dataclasses.dataclass(frozen=True)
class ErrorModel:
    """Forecast error of one quantity: an OU / AR(1) process in the lead time (module docstring)."""

    sigma_ref: float
    """Standard deviation of the error at the reference lead ref_lead_s [unit of the quantity], >= 0."""
    bias_ref: float = 0.0
    """Mean of the error (forecast - truth) at the reference lead [unit of the quantity]."""
    corr_time_s: float = 60.0
    """Correlation time theta of the process [s], > 0."""
    distribution: str = "normal"
    """Innovation distribution: 'normal' or 'laplace' (same mean and variance)."""
    ref_lead_s: float = REF_LEAD_S
    """Lead time at which sigma_ref and bias_ref hold [s], > 0."""

    def validate(self) -> ErrorModel:
        """Raise ValueError naming the first bad field; return self."""
        for name in ("sigma_ref", "bias_ref", "corr_time_s", "ref_lead_s"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"ErrorModel.{name}: must be a finite number, got {v!r}")
        if self.sigma_ref < 0.0:
            raise ValueError(f"ErrorModel.sigma_ref: must be >= 0, got {self.sigma_ref}")
        for name in ("corr_time_s", "ref_lead_s"):
            if getattr(self, name) <= 0.0:
                raise ValueError(f"ErrorModel.{name}: must be > 0, got {getattr(self, name)}")
        if self.distribution not in DISTRIBUTIONS:
            raise ValueError(f"ErrorModel.distribution: must be one of {DISTRIBUTIONS}, got {self.distribution!r}")
        return self

    @property
    def sigma_inf(self) -> float:
        """Stationary standard deviation sigma_inf = sigma_ref / sqrt(1 - exp(-2 L_ref / theta))."""
        return self.sigma_ref / math.sqrt(-math.expm1(-2.0 * self.ref_lead_s / self.corr_time_s))

    @property
    def mu(self) -> float:
        """Stationary mean mu = bias_ref / (1 - exp(-L_ref / theta))."""
        return self.bias_ref / -math.expm1(-self.ref_lead_s / self.corr_time_s)

    @property
    def is_zero(self) -> bool:
        """True when the model adds no error at all."""
        return self.sigma_ref == 0.0 and self.bias_ref == 0.0

    def mean(self, lead_s):
        """E[e(tau)] = mu (1 - exp(-tau/theta)) at lead times ``lead_s`` [s] (>= 0)."""
        tau = np.asarray(lead_s, dtype=float)
        return -self.mu * np.expm1(-tau / self.corr_time_s)

    def std(self, lead_s):
        """sqrt(Var[e(tau)]) = sigma_inf sqrt(1 - exp(-2 tau/theta)) at ``lead_s`` [s] (>= 0)."""
        tau = np.asarray(lead_s, dtype=float)
        return self.sigma_inf * np.sqrt(-np.expm1(-2.0 * tau / self.corr_time_s))


_NONE = ErrorModel(0.0)

LEVEL_MODELS: Mapping[str, Mapping[str, ErrorModel]] = {
    "none": {"t_amb_c": _NONE, "solar_wm2": _NONE, "speed_mps": _NONE},
    # BOPTEST temperature low: F0 = 0, K0 = 0.6 K; solar low: ag0 = 4.44, bg0 = 57.42 W/m2 (Laplace).
    "low": {
        "t_amb_c": ErrorModel(0.6, 0.0, 3600.0, "normal"),
        "solar_wm2": ErrorModel(math.sqrt(2.0) * 57.42, -4.44, 60.0, "laplace"),
        "speed_mps": ErrorModel(1.0, 0.0, 20.0, "normal"),
    },
    # BOPTEST temperature medium: F0 = 0.15, K0 = 1.2 K; solar medium: ag0 = 15.02, bg0 = 122.6 W/m2.
    "medium": {
        "t_amb_c": ErrorModel(1.2, -0.15, 3600.0, "normal"),
        "solar_wm2": ErrorModel(math.sqrt(2.0) * 122.6, -15.02, 60.0, "laplace"),
        "speed_mps": ErrorModel(2.5, 0.0, 20.0, "normal"),
    },
    # BOPTEST temperature high: F0 = -0.58, K0 = 1.5 K; solar high: ag0 = 32.09, bg0 = 119.94 W/m2.
    "high": {
        "t_amb_c": ErrorModel(1.5, 0.58, 3600.0, "normal"),
        "solar_wm2": ErrorModel(math.sqrt(2.0) * 119.94, -32.09, 60.0, "laplace"),
        "speed_mps": ErrorModel(4.0, -0.5, 20.0, "normal"),
    },
}
"""The error model of every quantity at every level (sources in the module docstring).
BOPTEST's biases are of ``truth - forecast``; here they are of ``forecast - truth``.
As published by BOPTEST, the solar ``medium`` and ``high`` levels have nearly the same
spread (Laplace scale 122.6 vs 119.94 W/m2); ``high`` has the larger under-forecast bias."""


def level_models(level: str) -> Mapping[str, ErrorModel]:
    """The error models of a level; ValueError naming the level if unknown."""
    if level not in LEVEL_MODELS:
        raise ValueError(f"forecast uncertainty level: must be one of {LEVELS}, got {level!r}")
    return LEVEL_MODELS[level]


def _innovations(model: ErrorModel, n: int, rng: np.random.Generator) -> np.ndarray:
    phi = math.exp(-_GRID_S / model.corr_time_s)
    mean = model.mu * (1.0 - phi)
    std = model.sigma_inf * math.sqrt(1.0 - phi * phi)
    if model.distribution == "laplace":
        return rng.laplace(mean, std / math.sqrt(2.0), n)
    return rng.normal(mean, std, n)


def lead_errors(model: ErrorModel, lead_s, rng: np.random.Generator) -> np.ndarray:
    """One realisation of the error e(tau) at the lead times ``lead_s`` [s] (>= 0).

    The process is simulated on a 1-s lead grid from e(0) = 0 (exact OU
    transition per step) and interpolated linearly to ``lead_s``.
    """
    model.validate()
    tau = np.asarray(lead_s, dtype=float)
    if tau.size == 0:
        return np.zeros(0)
    if not np.all(np.isfinite(tau)) or np.any(tau < 0.0):
        raise ValueError("lead_s: must be finite and >= 0")
    if model.is_zero:
        return np.zeros_like(tau)
    n = int(math.ceil(float(np.max(tau)) / _GRID_S))
    phi = math.exp(-_GRID_S / model.corr_time_s)
    eps = _innovations(model, n, rng)
    e = np.zeros(n + 1)
    for i in range(n):
        e[i + 1] = phi * e[i] + eps[i]
    return np.interp(tau, _GRID_S * np.arange(n + 1, dtype=float), e)


def forecast_errors(level: str, seed: int, t_issue_s: float, lead_s) -> dict:
    """The errors of every quantity of one forecast (deterministic; module docstring).

    The forecast issued at ``t_issue_s`` [s], at the lead times ``lead_s`` [s], for
    ``level`` and ``seed``. Returns ``{quantity: array}`` for :data:`QUANTITIES`.
    """
    models = level_models(level)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed: must be a non-negative integer, got {seed!r}")
    if not (math.isfinite(t_issue_s) and t_issue_s >= 0.0):
        raise ValueError(f"t_issue_s: must be finite and >= 0, got {t_issue_s!r}")
    key = int(round(float(t_issue_s) * 1000.0))
    out = {}
    for q_index, q in enumerate(QUANTITIES):
        rng = np.random.default_rng([int(seed), key, q_index, _STREAM])
        out[q] = lead_errors(models[q], lead_s, rng)
    return out


def apply_errors(values: Mapping[str, np.ndarray], level: str, seed: int, t_issue_s: float, lead_s) -> dict:
    """Forecast = truth + error, with the physical limits.

    For the quantities of :data:`QUANTITIES` present in ``values`` (true values at the
    preview's sample times): solar and speed floored at 0, no solar error where the true
    irradiance is 0. Other entries of ``values`` are returned unchanged (copies).
    """
    out = {k: np.array(v, dtype=float) for k, v in values.items()}
    if level == "none":
        level_models(level)
        return out
    errors = forecast_errors(level, seed, t_issue_s, lead_s)
    for q in QUANTITIES:
        if q not in out:
            continue
        e = errors[q]
        if q == "solar_wm2":
            e = np.where(out[q] > 0.0, e, 0.0)
        out[q] = out[q] + e
    if "solar_wm2" in out:
        out["solar_wm2"] = np.maximum(out["solar_wm2"], 0.0)
    if "speed_mps" in out:
        out["speed_mps"] = np.maximum(out["speed_mps"], 0.0)
    return out
