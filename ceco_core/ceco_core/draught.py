"""Local thermal discomfort by draught: the ISO 7730:2005 draught rating DR.

One implementation for numpy arrays (the plant, the metrics) and CasADi
``SX``/``MX`` symbols (an optional NMPC penalty or constraint); the maths
namespace comes from :func:`mathops.backend`. The two hard corners of the
standard's formula (the air-speed floor at 0.05 m/s and the cap at 100 %)
are replaced by smooth approximations with documented, bounded errors; the
exact standard is available with ``smoothing=DR_EXACT``.

Reference:
    ISO 7730:2005, Clause 6.2 (draught rating, its equation and applicability)
    and Annex A, Table A.1 and Figure A.2 (categories A/B/C: DR < 10/20/30 %).
    Fanger, Melikov, Hanzawa & Ring, "Air turbulence and sensation of
    draught", Energy and Buildings 12 (1988) 21-39 (the model's origin).
"""

import dataclasses
import math

import casadi
import numpy as np

from ceco_core import mathops
from ceco_core.metrics import DR_CATEGORY_LIMITS_PCT  # re-exported: the table lives with the metrics (no CasADi)

__all__ = [
    "DR_VEL_FLOOR_MPS",
    "DR_CATEGORY_LIMITS_PCT",
    "DraughtSmoothing",
    "DR_DEFAULT_SMOOTHING",
    "DR_EXACT",
    "draught_rating",
    "DraughtValidity",
    "draught_validity",
]

DR_VEL_FLOOR_MPS = 0.05
"""ISO 7730:2005 6.2: for v_a,l < 0.05 m/s use v_a,l = 0.05 m/s [m/s]."""


_T_SKIN_DR_C = 34.0
"""The 34 degC of ISO 7730 eq. (DR): the local skin temperature the model refers to [degC]."""

_X_MIN_MPS = 1e-12
"""Lower bound of the smooth v - 0.05 m/s [m/s] (keeps the power's derivative finite)."""

# ISO 7730:2005 6.2 applicability of the DR model (inclusive)
_DR_RANGES = {
    "ta_c": (20.0, 26.0),
    "vel_mps": (0.0, 0.5),
    "tu_pct": (10.0, 60.0),
}


@dataclasses.dataclass(frozen=True)
class DraughtSmoothing:
    """Smoothing of the two non-differentiable corners of the DR formula."""

    k_vel_spm: float = 2000.0
    """Softplus sharpness of the speed floor v - 0.05 -> softplus(v - 0.05) [s/m]; v error <= ln2/k = 3.5e-4 m/s."""
    k_cap_per_pct: float = 2.0
    """Log-sum-exp sharpness of the clip of DR into [0, 100] [1/%]; DR error <= ln2/k = 0.35 %-points at 0 and 100 %."""
    exact: bool = False
    """If True, the hard floor and clip of ISO 7730 (non-smooth; reference, not for NLPs)."""

    def validate(self):
        """Raise ValueError naming the first invalid field; return self."""
        for name in ("k_vel_spm", "k_cap_per_pct"):
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"DraughtSmoothing.{name} must be a finite number > 0, got {value!r}")
        if not isinstance(self.exact, bool):
            raise ValueError(f"DraughtSmoothing.exact must be a bool, got {self.exact!r}")
        return self


DR_DEFAULT_SMOOTHING = DraughtSmoothing()
"""The smoothing used by the product (plant, metrics and NMPC)."""

DR_EXACT = DraughtSmoothing(exact=True)
"""The hard floor and cap exactly as written in ISO 7730 (numpy use; reference)."""


def _prepare(ta_c, vel_mps, tu_pct):
    ops = mathops.backend(ta_c, vel_mps, tu_pct)
    if ops.is_casadi:
        return ops, [casadi.DM(v) if isinstance(v, np.ndarray) else v for v in (ta_c, vel_mps, tu_pct)]
    out = []
    for name, value in (("ta_c", ta_c), ("vel_mps", vel_mps), ("tu_pct", tu_pct)):
        arr = np.asarray(value, dtype=float)
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} must be finite (no NaN/inf), got {value!r}")
        out.append(arr)
    try:
        np.broadcast_shapes(*(a.shape for a in out))
    except ValueError as exc:
        raise ValueError(
            f"input shapes do not broadcast: ta_c{out[0].shape}, vel_mps{out[1].shape}, tu_pct{out[2].shape}"
        ) from exc
    if np.any(out[1] < 0.0):
        raise ValueError(f"vel_mps must be >= 0, got min {out[1].min()!r}")
    if np.any((out[2] < 0.0) | (out[2] > 100.0)):
        raise ValueError(f"tu_pct must be a percentage in [0, 100], got {tu_pct!r}")
    return ops, out


def draught_rating(ta_c, vel_mps, tu_pct, *, cap=True, smoothing=DR_DEFAULT_SMOOTHING):
    """Draught rating DR [%], ISO 7730:2005 6.2 (predicted percentage dissatisfied by draught).

    ``DR = (34 - t_a,l) (v_a,l - 0.05)^0.62 (0.37 v_a,l Tu + 3.14)``, with
    ``v_a,l < 0.05 m/s`` taken as 0.05 m/s and DR capped at 100 %. A DR below
    0 (local air warmer than 34 degC, where the formula changes sign) is 0.

    Args:
        ta_c: local air temperature t_a,l [degC]; model range 20..26.
        vel_mps: local mean air speed v_a,l [m/s], >= 0; model range < 0.5.
        tu_pct: local turbulence intensity Tu [%] (standard deviation of the
            speed over its mean x 100), 0..100; model range 10..60 (ISO 7730:
            40 % if unknown).
        cap: if False, the value is only floored at 0, not capped at 100 %:
            a draught intensity that keeps a gradient beyond saturation (for
            a penalty in an optimiser). True gives ISO 7730's DR.
        smoothing: :class:`DraughtSmoothing`; default smooth (C-infinity in
            all inputs: speed floor by softplus, clip by log-sum-exp), or
            ``DR_EXACT`` for the hard corners of the standard.

    Returns:
        DR [%] with the broadcast shape of the inputs (numpy) or a CasADi
        expression. Inputs outside the model's ranges are computed; see
        :func:`draught_validity` for flags.

    Smoothing error (default; measured on a grid t_a,l 10..40 degC, v 0..2 m/s,
    Tu 0..100 %, tests/test_draught.py): the speed floor moves v by at most
    ln2/k_vel = 3.5e-4 m/s (at v = 0.05 m/s, where DR itself is near 0), the
    clip moves DR by at most ln2/k_cap = 0.35 %-points at DR = 0 or 100 %;
    together at most 0.95 %-points anywhere (at v = 0.05 m/s), 0.61 within
    the model's range, and below 1e-8 %-points wherever 10 <= DR <= 90 %.

    Raises:
        ValueError: (numpy inputs) non-finite values, shapes that do not
            broadcast, vel_mps < 0, tu_pct outside [0, 100].
    """
    smoothing.validate()
    ops, (ta, vel, tu) = _prepare(ta_c, vel_mps, tu_pct)
    if smoothing.exact:
        x = ops.fmax(vel - DR_VEL_FLOOR_MPS, 0.0 * vel)
    else:
        # + 1e-12 m/s keeps x > 0 where the softplus underflows (CasADi's log-sum-exp rounds
        # 1 + e^-78 to 1), so d(x^0.62)/dx stays finite; it moves DR by < 1e-5 %-points
        x = mathops.softplus(vel - DR_VEL_FLOOR_MPS, smoothing.k_vel_spm) + _X_MIN_MPS
    v_eff = DR_VEL_FLOOR_MPS + x
    dr = (_T_SKIN_DR_C - ta) * ops.power(x, 0.62) * (0.37 * v_eff * tu + 3.14)
    if smoothing.exact:
        dr = ops.fmax(dr, 0.0 * dr)
        return ops.fmin(dr, 100.0 + 0.0 * dr) if cap else dr
    k = smoothing.k_cap_per_pct
    dr = mathops.softplus(dr, k)
    return mathops.smooth_min(dr, 100.0 + 0.0 * dr, k) if cap else dr


@dataclasses.dataclass(frozen=True)
class DraughtValidity:
    """Per-input flags: True where the value lies inside the ISO 7730:2005 6.2 range of the DR model."""

    ta_c: np.ndarray
    """20 <= t_a,l <= 26 degC."""
    vel_mps: np.ndarray
    """v_a,l <= 0.5 m/s."""
    tu_pct: np.ndarray
    """10 <= Tu <= 60 %."""

    @property
    def all(self):
        """True where every input is inside the model's range."""
        return self.ta_c & self.vel_mps & self.tu_pct


def draught_validity(ta_c, vel_mps, tu_pct):
    """Flag the inputs inside the ISO 7730:2005 6.2 range of the DR model (numpy; NaN is invalid).

    The standard also restricts the model to light, mostly sedentary activity
    with a whole-body thermal sensation close to neutral, and says it predicts
    draught at the neck (it may overestimate at arms and feet, and draught is
    felt less at activity above 1.2 met or when feeling warmer than neutral).
    Those conditions are not flagged here.
    """
    flags = {}
    for name, value in (("ta_c", ta_c), ("vel_mps", vel_mps), ("tu_pct", tu_pct)):
        arr = np.asarray(value, dtype=float)
        lo, hi = _DR_RANGES[name]
        flags[name] = (arr >= lo) & (arr <= hi)
    return DraughtValidity(**flags)
