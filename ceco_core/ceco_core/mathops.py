"""Backend-neutral maths for code evaluated by numpy *and* CasADi.

The comfort model and the controller's cabin model are written once and run
both numerically (plant simulation, numpy arrays with broadcasting) and
symbolically (NMPC, CasADi ``SX``/``MX``). :func:`backend` picks the
namespace from the argument types; the smooth helpers below replace the
non-differentiable ``max``/``abs`` so that the NLP sees C-infinity functions.

Error bounds (exact, all ``k > 0``, ``eps > 0``):

* ``smooth_max(a, b, k) = log(exp(k a) + exp(k b)) / k`` satisfies
  ``max(a, b) <= smooth_max <= max(a, b) + ln(2)/k``; the gap is largest
  (``ln 2 / k``) at ``a == b`` and decays like ``exp(-k |a - b|) / k``.
* ``smooth_min(a, b, k) = -smooth_max(-a, -b, k)``: ``min - ln(2)/k <= smooth_min <= min``.
* ``softplus(x, k) = smooth_max(x, 0, k)``: ``max(x, 0) <= softplus <= max(x, 0) + ln(2)/k``.
* ``smooth_abs(x, eps) = sqrt(x**2 + eps**2)``: ``|x| <= smooth_abs <= |x| + eps``
  (gap ``eps`` at 0, about ``eps**2 / (2|x|)`` for ``|x| >> eps``).
* ``sigmoid(x, w) = 1 / (1 + exp(-x / w))``, a smooth unit step H(x):
  ``|sigmoid - H(x)| <= exp(-|x| / w)`` (1/2 at ``x == 0``).
"""

import math
import types

import casadi
import numpy as np

__all__ = [
    "backend",
    "is_casadi",
    "smooth_max",
    "smooth_min",
    "softplus",
    "smooth_abs",
    "smooth_clip",
    "sigmoid",
    "LN2",
]

LN2 = math.log(2.0)
"""ln(2): the worst-case error of smooth_max/softplus is LN2 / k."""

_CASADI_TYPES = (casadi.SX, casadi.MX, casadi.DM)


def is_casadi(*args):
    """Return True if any argument is a CasADi ``SX``, ``MX`` or ``DM``."""
    return any(isinstance(a, _CASADI_TYPES) for a in args)


def _np_logaddexp(a, b):
    return np.logaddexp(a, b)


def _ca_logaddexp(a, b):
    # Stable log(exp(a) + exp(b)) = m + log(exp(a - m) + exp(b - m)),
    # m = fmax(a, b). The value and its derivative are exact whichever branch
    # AD takes through fmax at a == b (the dm terms cancel).
    m = casadi.fmax(a, b)
    return m + casadi.log(casadi.exp(a - m) + casadi.exp(b - m))


def _np_if_else(cond, a, b):
    return np.where(cond, a, b)


_NUMPY_NS = types.SimpleNamespace(
    name="numpy",
    is_casadi=False,
    exp=np.exp,
    log=np.log,
    log1p=np.log1p,
    sqrt=np.sqrt,
    fabs=np.fabs,
    power=np.power,
    tanh=np.tanh,
    sin=np.sin,
    cos=np.cos,
    fmax=np.fmax,
    fmin=np.fmin,
    sign=np.sign,
    logaddexp=_np_logaddexp,
    if_else=_np_if_else,
)

_CASADI_NS = types.SimpleNamespace(
    name="casadi",
    is_casadi=True,
    exp=casadi.exp,
    log=casadi.log,
    log1p=casadi.log1p,
    sqrt=casadi.sqrt,
    fabs=casadi.fabs,
    power=casadi.power,
    tanh=casadi.tanh,
    sin=casadi.sin,
    cos=casadi.cos,
    fmax=casadi.fmax,
    fmin=casadi.fmin,
    sign=casadi.sign,
    logaddexp=_ca_logaddexp,
    if_else=casadi.if_else,
)


def smooth_max(a, b, k):
    """Smooth maximum by log-sum-exp: ``log(exp(k a) + exp(k b)) / k``.

    Args:
        a: first operand (float, numpy array broadcasting with ``b``, or CasADi symbol),
            in the same unit as ``b``.
        b: second operand (float, numpy array broadcasting with ``a``, or CasADi symbol).
        k: sharpness [1/unit of a], ``k > 0``. Larger is closer to max.

    Returns:
        A C-infinity upper bound of ``max(a, b)`` with
        ``0 <= smooth_max - max(a, b) <= ln(2)/k`` (equality at ``a == b``).
    """
    if not k > 0:
        raise ValueError(f"smooth_max: k must be > 0, got {k!r}")
    ops = backend(a, b)
    return ops.logaddexp(k * a, k * b) / k


def smooth_min(a, b, k):
    """Smooth minimum ``-smooth_max(-a, -b, k)``; ``min - ln(2)/k <= result <= min``."""
    return -smooth_max(-a, -b, k)


def softplus(x, k):
    """Smooth ``max(x, 0)``: ``log(1 + exp(k x)) / k``; error in ``[0, ln(2)/k]``."""
    return smooth_max(x, 0.0 * x, k)


def smooth_abs(x, eps):
    """Smooth ``|x|``: ``sqrt(x**2 + eps**2)``; error in ``[0, eps]``, largest at 0."""
    if not eps > 0:
        raise ValueError(f"smooth_abs: eps must be > 0, got {eps!r}")
    ops = backend(x)
    return ops.sqrt(x * x + eps * eps)


def smooth_clip(x, lo, hi, k):
    """Smooth clip of ``x`` into ``[lo, hi]`` (``lo < hi``): ``smooth_min(smooth_max(x, lo), hi)``.

    The result lies within ``ln(2)/k`` of ``clip(x, lo, hi)`` when
    ``hi - lo >> 1/k``.
    """
    return smooth_min(smooth_max(x, lo, k), hi, k)


def sigmoid(x, w):
    """Smooth unit step: the logistic ``1 / (1 + exp(-x / w))``, computed as ``(1 + tanh(x / (2 w))) / 2``.

    Args:
        x: argument (float, numpy array or CasADi symbol); the step is at ``x = 0``.
        w: width [unit of x], ``w > 0``.

    Returns:
        A C-infinity value in (0, 1) with ``|sigmoid - H(x)| <= exp(-|x| / w)`` (H = 0 below 0, 1 above).
    """
    if not w > 0:
        raise ValueError(f"sigmoid: w must be > 0, got {w!r}")
    ops = backend(x)
    return 0.5 * (1.0 + ops.tanh(x / (2.0 * w)))


def backend(*args):
    """Return the maths namespace for the given arguments.

    CasADi's namespace if any argument is a ``casadi.SX``, ``MX`` or ``DM``,
    else numpy's. Both offer ``exp, log, log1p, sqrt, fabs, power, tanh, sin,
    cos, fmax, fmin, sign, logaddexp, if_else`` with the same meaning
    (``if_else(cond, a, b)`` is ``numpy.where`` / ``casadi.if_else``), plus
    the smooth helpers ``smooth_max``/``fmax_smooth``, ``smooth_min``,
    ``softplus``, ``smooth_abs`` and the flag ``is_casadi``.
    """
    return _CASADI_NS if is_casadi(*args) else _NUMPY_NS


for _ns in (_NUMPY_NS, _CASADI_NS):
    _ns.smooth_max = smooth_max
    _ns.fmax_smooth = smooth_max
    _ns.smooth_min = smooth_min
    _ns.softplus = softplus
    _ns.smooth_abs = smooth_abs
    _ns.smooth_clip = smooth_clip
    _ns.sigmoid = sigmoid
del _ns
