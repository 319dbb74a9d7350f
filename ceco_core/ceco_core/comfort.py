"""Occupant thermal comfort: ISO 7730:2005 PMV/PPD (with the paper's solar term) and its validity.

The automotive layer (the environment at the occupant in a cabin, the scored
PMV, draught and fog) is :mod:`ceco_core.cabin_comfort`.

One implementation evaluates numpy arrays (with broadcasting) and CasADi
``SX``/``MX`` symbols (for the NMPC): the maths namespace is chosen by
:func:`ceco_core.mathops.backend`. The model is C-infinity in the
continuous inputs: the implicit clothing-temperature equation is solved by a
fixed number of Newton steps (no data-dependent loop), and the hard ``max``
and ``|.|`` of ISO 7730 are replaced by smooth approximations whose error is
bounded and documented (``docs/comfort.md``).

References:
    ISO 7730:2005, Ergonomics of the thermal environment: analytical
    determination and interpretation of thermal comfort using calculation of
    the PMV and PPD indices and local thermal comfort criteria. Clause 4
    (eqs. (1)-(4), applicability ranges), Clause 5 (PPD, eq. (5)), Annex D (computer program, the
    vapour-pressure formula and Table D.1 check values).
    ANSI/ASHRAE Standard 55-2020, Normative Appendix C (SolarCal: effective
    radiant field of solar gain on an occupant).
    Wang et al., DSCC 2019 (``shared/papers/ceco-dscc2019.tex``), Sec. 3, eqs. (5)-(13):
    modified heat balance M + W_rad = H + E_c + C_res + E_res.
"""

import dataclasses
import math
import time

import casadi
import numpy as np

from ceco_core import mathops, units
from ceco_core.psychro import saturation_vapour_pressure_pa, vapour_pressure_pa

__all__ = [
    "MET_TO_WM2",
    "CLO_TO_M2KPW",
    "PmvSmoothing",
    "DEFAULT_SMOOTHING",
    "EXACT",
    "pmv",
    "ppd",
    "clothing_temperature_c",
    "pmv_explicit_paper",
    "saturation_vapour_pressure_pa",
    "vapour_pressure_pa",
    "Iso7730Validity",
    "iso7730_validity",
]

MET_TO_WM2 = 58.15
"""1 met in W/m2 of body (DuBois) surface area (ISO 7730:2005, 3.1 note)."""

CLO_TO_M2KPW = 0.155
"""1 clo in m2.K/W (ISO 7730:2005, 3.2 note)."""

_ISO_KELVIN_OFFSET = 273.0
"""ISO 7730 eqs. (1)-(2) write ``t + 273``. This is part of the empirical
formula whose radiation constant 3.96e-8 was fitted with it; it is kept
literally so that the model reproduces ISO 7730 (using 273.15 moves PMV by
about 1e-3). It is not a unit conversion (those live in ``units.py``)."""

_SIGMA_FCL = 3.96e-8
"""ISO 7730 radiation constant [W/(m2.K4)] (emissivity 0.97 x Stefan-
Boltzmann 5.67e-8 x effective radiating fraction 0.72, per m2 of DuBois area)."""

_ICL_FCL_BREAK = 0.078
"""Clothing insulation at which ISO 7730 eq. (4) switches f_cl [m2.K/W]."""

# ISO 7730:2005 Clause 4 applicability ranges (inclusive).
_ISO_RANGES = {
    "ta_c": (10.0, 30.0),
    "tr_c": (10.0, 40.0),
    "vel_mps": (0.0, 1.0),
    "pa_pa": (0.0, 2700.0),
    "met": (0.8, 4.0),  # 46 to 232 W/m2
    "clo": (0.0, 2.0),  # 0 to 0.310 m2.K/W
    "pmv": (-2.0, 2.0),
}


@dataclasses.dataclass(frozen=True)
class PmvSmoothing:
    """Smoothing of the non-differentiable parts of ISO 7730 (all > 0 unless exact)."""

    k_hc_m2kpw: float = 100.0
    """Log-sum-exp sharpness for h_c = max(natural, forced) [m2.K/W]; h_c error <= ln2/k = 0.0069 W/(m2.K)."""
    eps_dt_k: float = 0.1
    """Smoothing of |T_cl - T_a| as sqrt(dT**2 + eps**2) [K]."""
    vel_floor_mps: float = 0.01
    """Air speed inside sqrt(v) is smooth_max(v, floor): keeps dh_c/dv finite at v = 0 [m/s]."""
    k_vel_spm: float = 500.0
    """Log-sum-exp sharpness of that floor [s/m]; v error <= ln2/k = 0.0014 m/s, < 1e-10 m/s above 0.06 m/s."""
    k_sweat_m2pw: float = 20.0
    """Softplus sharpness for the clip max(0, M - 58.15) of the sweat term [m2/W]; error <= 0.42 ln2/k = 0.015 W/m2."""
    newton_steps: int = 4
    """Fixed number of Newton steps on the clothing-temperature equation."""
    exact: bool = False
    """If True, use the hard max/abs/clip of ISO 7730 (non-smooth; for error measurement, not for NLPs)."""

    def validate(self):
        """Raise ValueError naming the first invalid field."""
        for name in ("k_hc_m2kpw", "eps_dt_k", "vel_floor_mps", "k_vel_spm", "k_sweat_m2pw"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"PmvSmoothing.{name} must be a finite number > 0, got {value!r}")
        if not (isinstance(self.newton_steps, int) and 1 <= self.newton_steps <= 50):
            raise ValueError(f"PmvSmoothing.newton_steps must be an int in [1, 50], got {self.newton_steps!r}")
        return self


DEFAULT_SMOOTHING = PmvSmoothing()
"""The smoothing used by the product (plant truth and NMPC)."""

EXACT = PmvSmoothing(newton_steps=12, exact=True)
"""Hard max/abs/clip as written in ISO 7730 (numpy use; reference for error measurement)."""


# --------------------------------------------------------------------------
# input handling


def _as_numeric(name, value):
    """Return a float ndarray; raise ValueError naming ``name`` if not finite."""
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN/inf), got {value!r}")
    return arr


def _prepare(named, lower_bounds):
    """Validate/convert inputs for the numpy path, pass CasADi inputs through.

    ``named`` maps argument names to values; ``lower_bounds`` maps names to
    (bound, inclusive) checked only on the numpy path. Returns (ops, dict).
    """
    ops = mathops.backend(*named.values())
    if ops.is_casadi:
        out = {}
        for name, value in named.items():
            if isinstance(value, np.ndarray):
                value = casadi.DM(value)
            out[name] = value
        return ops, out
    out = {name: _as_numeric(name, value) for name, value in named.items()}
    try:
        np.broadcast_shapes(*(a.shape for a in out.values()))
    except ValueError as exc:
        shapes = ", ".join(f"{n}{a.shape}" for n, a in out.items())
        raise ValueError(f"input shapes do not broadcast: {shapes}") from exc
    for name, (bound, inclusive) in lower_bounds.items():
        arr = out[name]
        bad = arr < bound if inclusive else arr <= bound
        if np.any(bad):
            rel = ">=" if inclusive else ">"
            raise ValueError(f"{name} must be {rel} {bound}, got min {arr.min()!r}")
    return ops, out


_PMV_BOUNDS = {
    "vel_mps": (0.0, True),
    "pa_pa": (0.0, True),
    "met": (0.0, False),
    "clo": (0.0, True),
}


# --------------------------------------------------------------------------
# building blocks (shared by the ISO and the explicit paper variants)


def _clothing_area_factor(ops, icl):
    """ISO 7730 eq. (4): f_cl [-] from I_cl [m2.K/W].

    Kept exact (piecewise): clo is an occupant parameter, never an NMPC
    decision variable. Note the ISO branches do not meet: at I_cl = 0.078
    they give 1.10062 and 1.10031 (a 3.1e-4 step in f_cl).
    """
    return ops.if_else(icl <= _ICL_FCL_BREAK, 1.0 + 1.29 * icl, 1.05 + 0.645 * icl)


def _forced_hc(ops, vel_mps, sm):
    """Forced convection 12.1 sqrt(v) [W/(m2.K)], v kept away from 0 smoothly."""
    if sm.exact:
        return 12.1 * ops.sqrt(vel_mps)
    return 12.1 * ops.sqrt(mathops.smooth_max(vel_mps, sm.vel_floor_mps + 0.0 * vel_mps, sm.k_vel_spm))


def _hc_and_slope(ops, tcl_c, ta_c, hc_forced, sm):
    """h_c = max(2.38 |T_cl - T_a|^0.25, h_forced) and dh_c/dT_cl (ISO 7730 eq. (3))."""
    d = tcl_c - ta_c
    if sm.exact:
        ad = ops.fabs(d)
        hn = 2.38 * ops.power(ad, 0.25)
        hc = ops.fmax(hn, hc_forced)
        # d|d|^0.25/dT = 0.25 sign(d) |d|^-0.75; guard d = 0 (slope unused there)
        dhn = 2.38 * 0.25 * ops.sign(d) * ops.power(ops.fmax(ad, 1e-12), -0.75)
        w = ops.if_else(hn > hc_forced, 1.0 + 0.0 * d, 0.0 * d)
        return hc, w * dhn
    s = d * d + sm.eps_dt_k**2  # |d| ~ s^0.5
    hn = 2.38 * ops.power(s, 0.125)
    hc = mathops.smooth_max(hn, hc_forced, sm.k_hc_m2kpw)
    dhn = 2.38 * 0.25 * d * ops.power(s, -0.875)
    # d/dhn of log-sum-exp is the logistic weight of hn
    w = 0.5 * (1.0 + ops.tanh(0.5 * sm.k_hc_m2kpw * (hn - hc_forced)))
    return hc, w * dhn


def _sweat_loss(ops, m_wm2, sm):
    """ISO 7730 eq. (1) sweat term 0.42 max(0, M - 58.15) [W/m2] (W_mech = 0)."""
    x = m_wm2 - MET_TO_WM2
    if sm.exact:
        return 0.42 * ops.fmax(x, 0.0 * x)
    return 0.42 * mathops.softplus(x, sm.k_sweat_m2pw)


def _pmv_from_tcl(ops, *, tcl_c, ta_c, tr_c, hc, fcl, pa_pa, m_wm2, w_rad_wm2, sm):
    """ISO 7730 eq. (1) with the paper's W_rad on the gain side (W_mech = 0)."""
    diffusion = 3.05e-3 * (5733.0 - 6.99 * m_wm2 - pa_pa)
    sweat = _sweat_loss(ops, m_wm2, sm)
    resp_latent = 1.7e-5 * m_wm2 * (5867.0 - pa_pa)
    resp_dry = 0.0014 * m_wm2 * (34.0 - ta_c)
    radiation = _SIGMA_FCL * fcl * (ops.power(tcl_c + _ISO_KELVIN_OFFSET, 4) - ops.power(tr_c + _ISO_KELVIN_OFFSET, 4))
    convection = fcl * hc * (tcl_c - ta_c)
    sensitivity = 0.303 * ops.exp(-0.036 * m_wm2) + 0.028
    load = (m_wm2 + w_rad_wm2) - (diffusion + sweat + resp_latent + resp_dry + radiation + convection)
    return sensitivity * load


def _pmv_at_tcl(ops, a, *, tcl, fcl, m_wm2, hc_forced, sm):
    """PMV (ISO 7730 eq. (1)) at the clothing temperature ``tcl`` [degC]: h_c there, then the heat balance.

    ``a`` holds the prepared inputs (``ta_c``, ``tr_c``, ``pa_pa``, ``w_rad_wm2``) of :func:`pmv`.
    """
    hc, _ = _hc_and_slope(ops, tcl, a["ta_c"], hc_forced, sm)
    return _pmv_from_tcl(
        ops,
        tcl_c=tcl,
        ta_c=a["ta_c"],
        tr_c=a["tr_c"],
        hc=hc,
        fcl=fcl,
        pa_pa=a["pa_pa"],
        m_wm2=m_wm2,
        w_rad_wm2=a["w_rad_wm2"],
        sm=sm,
    )


def _solve_tcl(ops, *, ta_c, tr_c, hc_forced, icl, fcl, m_wm2, w_rad_wm2, sm):
    """Clothing surface temperature [degC], ISO 7730 eq. (2) with W_rad at the surface.

    Solves g(T) = T - T_sk + I_cl [R(T) + C(T) - W_rad] = 0 with
    T_sk = 35.7 - 0.028 M, R = 3.96e-8 f_cl ((T+273)^4 - (T_r+273)^4),
    C = f_cl h_c(T) (T - T_a), by ``sm.newton_steps`` Newton steps from the
    solution of the equation linearised about the mean of T_sk and T_r.
    g' >= 1, so every step is well defined.
    """
    tsk_c = 35.7 - 0.028 * m_wm2
    tr_k4 = ops.power(tr_c + _ISO_KELVIN_OFFSET, 4)
    # linearised start: radiation slope at the mean of skin and radiant
    # temperatures, convection at the blend of forced and natural (guessing
    # |T_cl - T_a| as half the skin-to-air difference)
    t_mid = 0.5 * (tsk_c + tr_c) + _ISO_KELVIN_OFFSET
    hr0 = 4.0 * _SIGMA_FCL * t_mid * t_mid * t_mid
    hc0, _ = _hc_and_slope(ops, 0.5 * (tsk_c + ta_c), ta_c, hc_forced, sm)
    a = icl * fcl
    tcl = (tsk_c + a * (hr0 * tr_c + hc0 * ta_c) + icl * w_rad_wm2) / (1.0 + a * (hr0 + hc0))
    for _ in range(sm.newton_steps):
        tk = tcl + _ISO_KELVIN_OFFSET
        hc, dhc = _hc_and_slope(ops, tcl, ta_c, hc_forced, sm)
        g = tcl - tsk_c + icl * (_SIGMA_FCL * fcl * (tk * tk * tk * tk - tr_k4) + fcl * hc * (tcl - ta_c) - w_rad_wm2)
        dg = 1.0 + a * (4.0 * _SIGMA_FCL * tk * tk * tk + hc + dhc * (tcl - ta_c))
        tcl = tcl - g / dg
    return tcl


def _clothing_state(ops, a, sm: PmvSmoothing):
    """``(T_cl [degC], f_cl [-], M [W/m2], h_c,forced [W/(m2 K)])`` of prepared inputs ``a``."""
    icl = CLO_TO_M2KPW * a["clo"]
    fcl = _clothing_area_factor(ops, icl)
    m = MET_TO_WM2 * a["met"]
    hf = _forced_hc(ops, a["vel_mps"], sm)
    tcl = _solve_tcl(
        ops,
        ta_c=a["ta_c"],
        tr_c=a["tr_c"],
        hc_forced=hf,
        icl=icl,
        fcl=fcl,
        m_wm2=m,
        w_rad_wm2=a["w_rad_wm2"],
        sm=sm,
    )
    return tcl, fcl, m, hf


# --------------------------------------------------------------------------
# public functions


def clothing_temperature_c(*, ta_c, tr_c, vel_mps, met, clo, w_rad_wm2=0.0, smoothing=DEFAULT_SMOOTHING):
    """Clothing surface temperature T_cl [degC] (ISO 7730:2005 eq. (2) + W_rad).

    Same inputs as :func:`pmv` (``pa_pa`` does not enter T_cl in ISO 7730).
    """
    ops, a = _prepare(
        dict(ta_c=ta_c, tr_c=tr_c, vel_mps=vel_mps, met=met, clo=clo, w_rad_wm2=w_rad_wm2),
        {k: v for k, v in _PMV_BOUNDS.items() if k != "pa_pa"},
    )
    return _clothing_state(ops, a, smoothing)[0]


def pmv(*, ta_c, tr_c, vel_mps, pa_pa, met, clo, w_rad_wm2=0.0, smoothing=DEFAULT_SMOOTHING):
    """Predicted mean vote, ISO 7730:2005 eqs. (1)-(4), with the paper's solar term.

    Args:
        ta_c: air temperature T_a [degC]; ISO range 10..30.
        tr_c: mean radiant temperature T_r [degC]; ISO range 10..40.
        vel_mps: relative air speed v_ar [m/s], >= 0; ISO range 0..1.
        pa_pa: water vapour partial pressure p_a [Pa], >= 0; ISO range 0..2700.
        met: metabolic rate [met] (1 met = 58.15 W/m2), > 0; ISO range 0.8..4.
            External work W_mech = 0 (seated occupant).
        clo: basic clothing insulation [clo] (1 clo = 0.155 m2.K/W), >= 0;
            ISO range 0..2.
        w_rad_wm2: absorbed short-wave (solar) flux per m2 of body surface
            [W/m2], the paper's W_rad (eqs. (12)-(13)); 0 gives ISO 7730 exactly.
            It is a heat gain at the clothing surface: it enters the surface
            balance that fixes T_cl and the gain side of the body balance;
            skin diffusion, sweating, respiration and the sensitivity
            coefficient stay functions of M only (see docs/comfort.md).
        smoothing: :class:`PmvSmoothing`; the default is the product's.

    Returns:
        PMV [-], same shape as the broadcast inputs (numpy) or a CasADi
        expression. Inputs outside the ISO ranges are computed (see
        :func:`iso7730_validity` for flags).

    Raises:
        ValueError: (numpy inputs) non-finite values, shapes that do not
            broadcast, vel/pa/clo < 0, met <= 0.
    """
    ops, a = _prepare(
        dict(ta_c=ta_c, tr_c=tr_c, vel_mps=vel_mps, pa_pa=pa_pa, met=met, clo=clo, w_rad_wm2=w_rad_wm2),
        _PMV_BOUNDS,
    )
    tcl, fcl, m, hf = _clothing_state(ops, a, smoothing)
    return _pmv_at_tcl(ops, a, tcl=tcl, fcl=fcl, m_wm2=m, hc_forced=hf, sm=smoothing)


def ppd(pmv):  # the argument shadows the function on purpose
    """Predicted percentage dissatisfied [%], ISO 7730:2005 Clause 5, eq. (5).

    ``PPD = 100 - 95 exp(-0.03353 PMV^4 - 0.2179 PMV^2)``; minimum 5 % at PMV = 0.
    Accepts numpy arrays and CasADi expressions.
    """
    ops = mathops.backend(pmv)
    if not ops.is_casadi:
        pmv = _as_numeric("pmv", pmv)
    p2 = pmv * pmv
    return 100.0 - 95.0 * ops.exp(-0.03353 * p2 * p2 - 0.2179 * p2)


def _explicit_tcl_c(m_wm2, icl, ta_c, pa_in_tcl, skin_slope=0.0275, resp_latent_coeff=0.0173):
    """The paper's eq. (10) clothing temperature (Fanger's explicit form) [degC].

    ``pa_in_tcl`` must be in kPa for the printed constants 3.05, 5.73,
    0.007, 0.0173, 5.87 to be consistent (ISO 7730 eq. (1) in kPa units).
    The printed ``skin_slope`` 0.0275 and ``resp_latent_coeff`` 0.0173 differ
    from ISO 7730's 0.028 and 0.017 (1.7e-5 per Pa); with the ISO values the
    expression equals the ISO T_cl exactly where PMV = 0.
    """
    brace = (
        m_wm2
        - 3.05 * (5.73 - 0.007 * m_wm2 - pa_in_tcl)
        - 0.42 * (m_wm2 - MET_TO_WM2)
        - resp_latent_coeff * m_wm2 * (5.87 - pa_in_tcl)
        - 0.0014 * m_wm2 * (34.0 - ta_c)
    )
    return 35.7 - skin_slope * m_wm2 - icl * brace


def pmv_explicit_paper(*, ta_c, tr_c, vel_mps, pa_pa, met, clo, w_rad_wm2=0.0, smoothing=DEFAULT_SMOOTHING):
    """PMV with the paper's explicit clothing temperature (eqs. (5)-(13)): NOT ISO 7730.

    For reproducing the method paper only. T_cl is Fanger's explicit
    expression, which assumes the body is already in heat balance; it equals
    the ISO 7730 T_cl only where PMV = 0 and elsewhere scales PMV by about
    1.4-4.4 relative to ISO 7730. ``pa_pa`` is in Pa as everywhere; it is
    converted to kPa inside the T_cl expression, whose constants need kPa
    (copied literally with Pa the result is off by orders of magnitude).
    h_c, the clip of the sweat term and v near 0 are smoothed as in
    :func:`pmv`. W_rad enters only the gain side, as printed in eq. (13).
    Arguments and units as :func:`pmv`.
    """
    ops, a = _prepare(
        dict(ta_c=ta_c, tr_c=tr_c, vel_mps=vel_mps, pa_pa=pa_pa, met=met, clo=clo, w_rad_wm2=w_rad_wm2),
        _PMV_BOUNDS,
    )
    icl = CLO_TO_M2KPW * a["clo"]
    fcl = _clothing_area_factor(ops, icl)
    m = MET_TO_WM2 * a["met"]
    hf = _forced_hc(ops, a["vel_mps"], smoothing)
    tcl = _explicit_tcl_c(m, icl, a["ta_c"], units.pa_to_kpa(a["pa_pa"]))
    return _pmv_at_tcl(ops, a, tcl=tcl, fcl=fcl, m_wm2=m, hc_forced=hf, sm=smoothing)


@dataclasses.dataclass(frozen=True)
class Iso7730Validity:
    """Per-input flags: True where the value lies inside ISO 7730:2005 Clause 4 ranges."""

    ta_c: np.ndarray
    """10 <= T_a <= 30 degC."""
    tr_c: np.ndarray
    """10 <= T_r <= 40 degC."""
    vel_mps: np.ndarray
    """0 <= v_ar <= 1 m/s."""
    pa_pa: np.ndarray
    """0 <= p_a <= 2700 Pa."""
    met: np.ndarray
    """0.8 <= met <= 4 (46..232 W/m2)."""
    clo: np.ndarray
    """0 <= clo <= 2 (0..0.310 m2.K/W)."""
    pmv: np.ndarray
    """-2 <= PMV <= 2."""

    @property
    def all(self):
        """True where every input and the PMV are inside the ISO ranges (a 0/1 expression with CasADi flags)."""
        if mathops.is_casadi(*(getattr(self, f.name) for f in dataclasses.fields(self))):
            flags = [getattr(self, f.name) for f in dataclasses.fields(self)]
            out = flags[0]
            for flag in flags[1:]:
                out = casadi.logic_and(out, flag)
            return out
        out = np.ones(
            np.broadcast_shapes(*(np.shape(getattr(self, f.name)) for f in dataclasses.fields(self))), dtype=bool
        )
        for f in dataclasses.fields(self):
            out = out & getattr(self, f.name)
        return out


def iso7730_validity(ta_c, tr_c, vel_mps, pa_pa, met, clo, pmv):
    """Flag which inputs are inside the ISO 7730:2005 Clause 4 applicability ranges.

    Numeric inputs (numpy broadcasting; NaN is flagged invalid) or CasADi expressions (0/1 flags).
    Returns an :class:`Iso7730Validity`.
    """
    values = dict(ta_c=ta_c, tr_c=tr_c, vel_mps=vel_mps, pa_pa=pa_pa, met=met, clo=clo, pmv=pmv)
    flags = {}
    if mathops.is_casadi(*values.values()):  # 0/1 expressions (the compiled plant)
        for name, value in values.items():
            lo, hi = _ISO_RANGES[name]
            flags[name] = casadi.logic_and(value >= lo, value <= hi)
        return Iso7730Validity(**flags)
    for name, value in values.items():
        arr = np.asarray(value, dtype=float)
        lo, hi = _ISO_RANGES[name]
        flags[name] = (arr >= lo) & (arr <= hi)
    return Iso7730Validity(**flags)


# --------------------------------------------------------------------------
# benchmark (python -m ceco_core.comfort)


def _benchmark(n=10_000, repeats=20, seed=0):
    """Print the numpy cost per point and the CasADi Function evaluation time."""
    rng = np.random.default_rng(seed)
    args = dict(
        ta_c=rng.uniform(18, 45, n),
        tr_c=rng.uniform(18, 60, n),
        vel_mps=rng.uniform(0.05, 1.5, n),
        pa_pa=rng.uniform(500, 2500, n),
        met=rng.uniform(1.0, 1.4, n),
        clo=rng.uniform(0.3, 1.0, n),
        w_rad_wm2=rng.uniform(0, 40, n),
    )
    pmv(**args)
    t0 = time.perf_counter()
    for _ in range(repeats):
        pmv(**args)
    per_point_us = (time.perf_counter() - t0) / repeats / n * 1e6
    print(f"numpy pmv: {per_point_us:.3f} us/point ({n} points, mean of {repeats} calls)")

    syms = [casadi.SX.sym(k) for k in args]
    f = casadi.Function("pmv", syms, [pmv(**dict(zip(args, syms)))])
    x = [float(v[0]) for v in args.values()]
    f(*x)
    reps = 2000
    t0 = time.perf_counter()
    for _ in range(reps):
        f(*x)
    print(
        f"casadi SX Function call (scalar, incl. Python overhead): "
        f"{(time.perf_counter() - t0) / reps * 1e6:.1f} us; {f.n_instructions()} instructions"
    )
    fm = f.map(n)
    cols = [np.asarray(v).reshape(1, -1) for v in args.values()]
    fm(*cols)
    t0 = time.perf_counter()
    for _ in range(5):
        fm(*cols)
    print(f"casadi Function.map({n}): {(time.perf_counter() - t0) / 5 / n * 1e6:.3f} us/point")
    tsyms = [casadi.SX.sym(k) for k in args]
    expr = pmv(**dict(zip(args, tsyms)))
    fj = casadi.Function("dpmv", tsyms, [casadi.jacobian(expr, casadi.vertcat(*tsyms))])
    fj(*x)
    t0 = time.perf_counter()
    for _ in range(reps):
        fj(*x)
    print(f"casadi gradient Function call (scalar): {(time.perf_counter() - t0) / reps * 1e6:.1f} us")


if __name__ == "__main__":
    _benchmark()
