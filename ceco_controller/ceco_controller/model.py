"""Control-oriented A/C and cabin model (method paper eqs. (1)-(3), power models, eta_AC(V)).

It holds eqs. (1)-(3) of the method paper, the compressor and blower power
models and the efficiency multiplier eta_AC(V).

Written once; every function evaluates numpy arrays (broadcasting) and CasADi
symbols alike (``ceco_core.mathops.backend``), so the closed-loop
simulator, the identification and the NMPC share the same equations.

Temperatures are in degC here (the paper writes kelvin; eqs. (1)-(3) are
affine in temperature, so only the offsets tau_1..tau_3 depend on that choice,
and they are identified in degC). One model step is ``ts_s`` seconds (the
sample time the parameters were identified at, 5 s).

Equations (Wang et al., DSCC 2019, Sec. 2; docs/controller.md):

    (1) T_cab(k+1)  = T_cab + g1 (T_int - T_cab) + g2 (T_shell - T_cab)
                      + g3 (T_ain - T_cab) mdot_bl + tau1 [+ d_cab]
    (2) T_evap(k+1) = g4 T_evap + g5 (T_evap - T_evap_sp) + tau2
    (3) T_ain(k)    = g6 T_evap + g7 mdot_bl + tau3 [+ d_ain]

    Q_evap  = softplus(mdot_bl c_p (T_mix - T_ain) + C_w (T_evap - T_evap(k+1)) / Ts),
              T_mix = T_cab + phi (T_amb - T_cab)
    P_comp  = Q_evap (c0 + c1 softplus(T_amb - T_evap)) / eta_AC(V)
    P_bl    = b0 + b1 mdot_bl + b3 mdot_bl^3
    eta_AC  = 1 + a_eta (1 - exp(-V / v_eta))   >= 1

where mdot_bl [kg/s] is the blower flow, T_evap_sp [degC] the evaporator
set-point, T_int/T_shell [degC] the interior/shell temperatures (held at their
measured values over the horizon: they have no dynamics in the paper), T_amb
[degC] ambient, V [m/s] vehicle speed, phi [-] the fresh-air fraction of the
evaporator inlet, C_w [J/K] the effective heat capacity of the evaporator wall
and refrigerant charge (pulling the wall down to a lower set-point costs
compressor work before the air sees it), c_p [J/(kg K)] the specific heat of air, c0 [-] the
reciprocal of the COP at zero lift, c1 [1/K] its growth with the lift
T_amb - T_evap (the condensing/evaporating temperature difference rises with
it), b0/b1/b3 the blower fan-law coefficients [W, W s/kg, W s^3/kg^3], and
a_eta [-], v_eta [m/s] the speed sensitivity of the A/C efficiency (condenser
ram air). d_cab, d_ain [K] are optional output-bias corrections estimated
online by the NMPC (offset-free MPC); 0 when identifying.
"""

from __future__ import annotations

import dataclasses
import math
import pathlib
from typing import Any

import numpy as np
import yaml

from ceco_core import yamlio
from ceco_core.control_grid import whole_steps
from ceco_core.mathops import backend, softplus

__all__ = [
    "ControlModelParams",
    "DEFAULT_PARAMS_PATH",
    "package_config_path",
    "t_ain_c",
    "t_cab_next_c",
    "t_evap_next_c",
    "eta_ac",
    "door_fresh_fraction",
    "q_evap_w",
    "p_comp_w",
    "p_blower_w",
    "step",
    "simulate",
    "load_params",
    "save_params",
    "co2_estimator_params",
]

DEFAULT_PARAMS_PATH = pathlib.Path(__file__).resolve().parent.parent / "config" / "model_params.yaml"
"""The identified parameter file in the source tree (``ceco_controller/config``)."""

CP_AIR_JPKGK = 1006.0
"""Specific heat of dry air at 25 degC [J/(kg K)] (Incropera, Table A.4)."""

_SOFTPLUS_K = 2.0
"""Sharpness of the smooth max(.,0) in the power model [1/K]: error <= ln2/2 = 0.35 K."""


OPTIONAL_FIELD_PREFIXES = ("co2_", "moist_", "provenance")
"""ControlModelParams fields a parameter file may leave out (its defaults: the plant's nominal CO2 and moisture
values, added after the first identified files); every other field is the fitted model and must be there."""


@dataclasses.dataclass(frozen=True)
class ControlModelParams:
    """Parameters of the control-oriented model (identified, never hand-typed).

    See ``docs/controller.md`` for the identification and the fit report.
    """

    ts_s: float = 5.0
    """Model sample time the parameters are identified at [s]."""
    gamma_1: float = 0.01
    """Interior-to-cabin-air coupling per step [-] (eq. 1)."""
    gamma_2: float = 0.01
    """Shell-to-cabin-air coupling per step [-] (eq. 1)."""
    gamma_3: float = 0.3
    """Vent-air mixing gain per step and per unit blower flow [s/kg] (eq. 1)."""
    gamma_4: float = 1.0
    """Evaporator wall autoregressive coefficient [-] (eq. 2)."""
    gamma_5: float = -0.3
    """Evaporator set-point tracking gain [-] (eq. 2; negative: pulls T_evap to T_evap_sp)."""
    gamma_6: float = 1.0
    """Vent air temperature per evaporator wall temperature [-] (eq. 3)."""
    gamma_7: float = 10.0
    """Vent air temperature per blower flow [K s/kg] (eq. 3)."""
    tau_1: float = 0.0
    """Cabin air offset per step [K] (eq. 1; absorbs the mean direct solar and occupant gains)."""
    tau_2: float = 0.0
    """Evaporator offset per step [K] (eq. 2)."""
    tau_3: float = 1.0
    """Vent air offset [degC] (eq. 3)."""
    fresh_air_fraction: float = 0.2
    """Fresh-air share of the evaporator inlet air phi [-] (power model) of the identification data: 1 - the
    door's recirculated share there (not fitted, ``identification.fit_intervals``). The NMPC passes the measured
    door instead (NLP parameter ``recirc``); this value is its fallback when the door is not measured."""
    comp_c_wall_jpk: float = 5000.0
    """Effective evaporator wall heat capacity C_w in the refrigerant load [J/K]."""
    comp_c0: float = 0.2
    """Compressor electrical power per evaporator heat at zero lift (1/COP) [-]."""
    comp_c1_per_k: float = 0.01
    """Growth of 1/COP with the lift T_amb - T_evap [1/K]."""
    blower_b0_w: float = 20.0
    """Blower power at zero flow (electronics) [W]."""
    blower_b1_w_per_kgps: float = 100.0
    """Linear blower power coefficient [W/(kg/s)]."""
    blower_b3_w_per_kgps3: float = 50000.0
    """Cubic (fan law) blower power coefficient [W/(kg/s)^3]."""
    eta_gain: float = 0.3
    """Largest relative A/C efficiency gain at high speed a_eta [-] (eta_AC <= 1 + a_eta)."""
    eta_speed_scale_mps: float = 15.0
    """Speed scale of the efficiency gain v_eta [m/s]."""
    co2_m_air_kg: float = 3.48
    """Cabin dry-air mass of the CO2 balance [kg] (the CO2 estimator's and the door's model,
    :class:`ceco_core.co2_estimator.Co2EstimatorParams`; identified by ``ceco identify``, the default is docs/plant.md's
    nominal 3.0 m3 x 1.16 kg/m3, what a file without it gets)."""
    co2_leak_0_kgps: float = 0.0015
    """Cabin leakage at rest of the CO2 balance [kg/s] (identified; default the nominal value)."""
    co2_leak_per_mps_kgps: float = 0.0002
    """Growth of the leakage with vehicle speed [kg/s per m/s] (identified; default the nominal value)."""
    moist_coil_bypass_factor: float = 0.06
    """Bypass factor of the evaporator for the cabin moisture the door NLP predicts (its fog margin) [-]: the share
    of the air that passes the coil without touching the wall (nominal, not identified: exp(-UA/(mdot c_p)) of
    docs/plant.md's coil at 0.10 kg/s, 0.063; 0.04-0.08 over 0.05-0.17 kg/s)."""
    moist_occ_latent_w: float = 55.0
    """Latent heat of one occupant for the moisture the door NLP predicts [W] (nominal: ASHRAE Fundamentals 2017
    ch. 18 table 1, moderately active office work, docs/plant.md)."""
    provenance: str = "defaults (not identified)"
    """How the values were obtained (command and data); not used in computations."""

    def validate(self) -> None:
        """Raise ValueError naming the field if a value is not usable."""
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name == "provenance":
                if not isinstance(v, str):
                    raise ValueError("ControlModelParams.provenance must be a string")
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"ControlModelParams.{f.name} must be a finite number, got {v!r}")
        if not self.ts_s > 0:
            raise ValueError(f"ControlModelParams.ts_s must be > 0, got {self.ts_s}")
        if not 0.0 <= self.fresh_air_fraction <= 1.0:
            raise ValueError("ControlModelParams.fresh_air_fraction must be in [0, 1]")
        if not self.eta_gain >= 0.0:
            raise ValueError("ControlModelParams.eta_gain must be >= 0 (eta_AC >= 1)")
        if not self.eta_speed_scale_mps > 0.0:
            raise ValueError("ControlModelParams.eta_speed_scale_mps must be > 0")
        if not self.comp_c0 > 0.0:
            raise ValueError("ControlModelParams.comp_c0 must be > 0")
        for name in ("blower_b0_w", "blower_b1_w_per_kgps", "blower_b3_w_per_kgps3", "co2_leak_per_mps_kgps"):
            if getattr(self, name) < 0.0:
                raise ValueError(f"ControlModelParams.{name} must be >= 0")
        for name in ("co2_m_air_kg", "co2_leak_0_kgps"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"ControlModelParams.{name} must be > 0")
        if not 0.0 <= self.moist_coil_bypass_factor < 1.0:
            raise ValueError("ControlModelParams.moist_coil_bypass_factor must be in [0, 1)")
        if not self.moist_occ_latent_w >= 0.0:
            raise ValueError("ControlModelParams.moist_occ_latent_w must be >= 0")

    def to_dict(self) -> dict:
        """Plain dict of the fields (Python floats; for YAML)."""
        return {k: (v if isinstance(v, str) else float(v)) for k, v in dataclasses.asdict(self).items()}

    @classmethod
    def from_dict(cls, data: dict) -> ControlModelParams:
        """Build and validate from a mapping; unknown keys are an error."""
        if not isinstance(data, dict):
            raise ValueError("ControlModelParams: expected a mapping")
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ValueError(f"ControlModelParams: unknown field(s) {unknown}")
        # the fitted model must be whole; the CO2 and moisture fields came later and default to the plant's
        # nominal values in older files (tests/test_co2_identification.py)
        missing = [n for n in sorted(names - set(data)) if not n.startswith(OPTIONAL_FIELD_PREFIXES)]
        if missing:
            raise ValueError(
                f"ControlModelParams: missing field(s) {missing}: a file `ceco identify` wrote has them all"
            )
        kwargs: dict[str, Any] = {}
        for k, v in data.items():
            kwargs[k] = v if k == "provenance" else float(v)
        p = cls(**kwargs)
        p.validate()
        return p


def co2_estimator_params(params: ControlModelParams):
    """The CO2 estimator's and the door's model with the cabin air mass and leakage of ``params``.

    A :class:`ceco_core.co2_estimator.Co2EstimatorParams` with the values ``ceco identify`` wrote; the rest its
    defaults.
    """
    from ceco_core.co2_estimator import Co2EstimatorParams

    return Co2EstimatorParams(
        m_air_kg=params.co2_m_air_kg,
        leak_0_kgps=params.co2_leak_0_kgps,
        leak_per_mps_kgps=params.co2_leak_per_mps_kgps,
    ).validate()


def package_config_path(filename: str) -> pathlib.Path:
    """A file of the package's ``config/``.

    The source tree's, else an installed ``share/ceco_controller/config`` on
    AMENT_PREFIX_PATH; FileNotFoundError if neither has it.
    """
    src = DEFAULT_PARAMS_PATH.parent / filename
    if src.exists():
        return src
    import os

    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        cand = pathlib.Path(prefix) / "share" / "ceco_controller" / "config" / filename
        if prefix and cand.exists():
            return cand
    raise FileNotFoundError(
        f"{filename} not found in {src.parent} nor under AMENT_PREFIX_PATH (share/ceco_controller/config)"
    )


def default_params_path() -> pathlib.Path:
    """The parameter file: the source tree's ``config/``, else an installed ``share/ceco_controller/config``."""
    try:
        return package_config_path("model_params.yaml")
    except FileNotFoundError as exc:
        raise FileNotFoundError(f"{exc}; run `ceco identify` or pass the path") from None


def load_params(path: str | pathlib.Path | None = None) -> ControlModelParams:
    """Load the identified parameters (default: :func:`default_params_path`)."""
    path = pathlib.Path(path) if path is not None else default_params_path()
    doc = yamlio.load_file(path)
    if not isinstance(doc, dict) or "params" not in doc:
        raise ValueError(f"{path}: expected a mapping with a 'params' key")
    return ControlModelParams.from_dict(doc["params"])


def save_params(
    params: ControlModelParams, path: str | pathlib.Path, header: str = "", extra: dict | None = None
) -> None:
    """Write the parameters (and optional extra mappings, e.g. the fit report) as YAML."""
    params.validate()
    write_params_yaml(params.to_dict(), path, header, extra)


def write_params_yaml(params: dict, path: str | pathlib.Path, header: str = "", extra: dict | None = None) -> None:
    """An identified parameter file: ``params: {name: value}`` and ``extra``, under ``header`` as '# ' lines.

    numpy scalars are written as plain numbers. Used by this model's and the estimator's files.
    """

    def plain(v):
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        if isinstance(v, (np.floating, np.integer)):
            return v.item()
        return v

    doc = {"params": plain(params)}
    if extra:
        doc.update(plain(extra))
    text = yaml.safe_dump(doc, sort_keys=False, default_flow_style=False)
    if header:
        text = "".join(f"# {line}\n" if line else "#\n" for line in header.splitlines()) + text
    pathlib.Path(path).write_text(text, encoding="utf-8")


# ---------------------------------------------------------------------------
# Equations (backend-neutral)
# ---------------------------------------------------------------------------


def t_ain_c(p: ControlModelParams, t_evap_c, mdot_bl_kgps, d_ain_k=0.0):
    """Vent (discharge) air temperature, eq. (3) [degC]."""
    return p.gamma_6 * t_evap_c + p.gamma_7 * mdot_bl_kgps + p.tau_3 + d_ain_k


def t_cab_next_c(p: ControlModelParams, t_cab_c, t_int_c, t_shell_c, t_ain, mdot_bl_kgps, d_cab_k=0.0):
    """Cabin air temperature one model step ahead, eq. (1) [degC]."""
    return (
        t_cab_c
        + p.gamma_1 * (t_int_c - t_cab_c)
        + p.gamma_2 * (t_shell_c - t_cab_c)
        + p.gamma_3 * (t_ain - t_cab_c) * mdot_bl_kgps
        + p.tau_1
        + d_cab_k
    )


def t_evap_next_c(p: ControlModelParams, t_evap_c, t_evap_sp_c):
    """Evaporator wall temperature one model step ahead, eq. (2) [degC]."""
    return p.gamma_4 * t_evap_c + p.gamma_5 * (t_evap_c - t_evap_sp_c) + p.tau_2


def eta_ac(p: ControlModelParams, speed_mps):
    """A/C efficiency multiplier eta_AC(V) = 1 + a_eta (1 - exp(-V/v_eta)) >= 1 [-].

    Monotone in speed, 1 at standstill, saturating at 1 + a_eta (condenser
    ram-air benefit, Wang et al. ACC 2018). ``speed_mps`` must be >= 0 (the
    NMPC clips previews to >= 0 before they enter the NLP as parameters).
    """
    ops = backend(speed_mps)
    return 1.0 + p.eta_gain * (1.0 - ops.exp(-speed_mps / p.eta_speed_scale_mps))


def door_fresh_fraction(p: ControlModelParams, recirc_share):
    """The power model's fresh-air fraction phi [-] at a recirculated share ``recirc_share`` [0..1]: 1 - r.

    The plant's mixing box, T_mix = r T_cab + (1 - r) T_amb (docs/plant.md). Every NLP uses it: the door NLP with
    its share u_i, the others with the measured door held over the horizon (parameter ``recirc``). The compressor
    coefficients are identified with the same phi = 1 - r of the data's door (``identification.fit_intervals``),
    so the identified constant ``fresh_air_fraction`` is the value at the identification's door (0.2 at the
    plant's 0.8). ``p`` is unused (the model functions' signature).
    """
    del p
    return 1.0 - recirc_share


def q_evap_w(
    p: ControlModelParams, t_cab_c, t_amb_c, t_ain, mdot_bl_kgps, t_evap_c, t_evap_next_c, fresh_fraction=None
):
    """Refrigerant-side evaporator load [W]: air-side sensible heat plus the wall cool-down, >= 0.

    ``softplus(mdot c_p (T_mix - T_ain) + C_w (T_evap - T_evap_next)/ts, k)`` with the
    softplus sharpness k = 2/(c_p * 0.1 kg/s) so its error is <= 0.35 K x 0.1 kg/s x c_p = 35 W.
    T_mix = T_cab + phi (T_amb - T_cab), phi = ``fresh_fraction`` [-] (None: the identified
    ``fresh_air_fraction``; the door NLP passes :func:`door_fresh_fraction` of its share).
    """
    phi = p.fresh_air_fraction if fresh_fraction is None else fresh_fraction
    t_mix_c = t_cab_c + phi * (t_amb_c - t_cab_c)
    q = mdot_bl_kgps * CP_AIR_JPKGK * (t_mix_c - t_ain) + p.comp_c_wall_jpk * (t_evap_c - t_evap_next_c) / p.ts_s
    return softplus(q, _SOFTPLUS_K / (CP_AIR_JPKGK * 0.1))


def p_comp_w(p: ControlModelParams, q_w, t_amb_c, t_evap_c, speed_mps):
    """Compressor electrical power [W] from the evaporator heat and the lift, / eta_AC(V)."""
    lift_k = softplus(t_amb_c - t_evap_c, _SOFTPLUS_K)
    return q_w * (p.comp_c0 + p.comp_c1_per_k * lift_k) / eta_ac(p, speed_mps)


def p_blower_w(p: ControlModelParams, mdot_bl_kgps):
    """Blower electrical power [W]: b0 + b1 mdot + b3 mdot^3 (fan law)."""
    return p.blower_b0_w + p.blower_b1_w_per_kgps * mdot_bl_kgps + p.blower_b3_w_per_kgps3 * mdot_bl_kgps**3


def substeps(p: ControlModelParams, dt_s: float) -> int:
    """Number of model steps in ``dt_s``; ``dt_s`` must be a whole multiple of ``ts_s``."""
    n = whole_steps(dt_s, p.ts_s)
    if n is None or n < 1:
        raise ValueError(f"control period {dt_s} s must be a whole multiple of the model step {p.ts_s} s")
    return n


def step(
    p: ControlModelParams,
    t_cab_c,
    t_evap_c,
    mdot_bl_kgps,
    t_evap_sp_c,
    t_int_c,
    t_shell_c,
    t_amb_c,
    speed_mps,
    n_sub: int = 1,
    d_cab_k=0.0,
    d_ain_k=0.0,
    d_evap_k=0.0,
    recirc_share=None,
):
    """Advance the model over ``n_sub`` model steps with the inputs held.

    ``recirc_share`` [0..1]: the door's share in the power model (:func:`door_fresh_fraction`; None: the identified
    fresh-air fraction, the model of every strategy without the door in its NLP).
    Returns ``(t_cab_next_c, t_evap_next_c, t_ain_c, p_comp_w, p_blower_w)`` where the temperatures are at
    the end of the interval and ``t_ain_c`` and the powers are the means over the interval (sampled at each
    sub-step start).
    """
    t_ain_sum = 0.0
    pc_sum = 0.0
    phi = None if recirc_share is None else door_fresh_fraction(p, recirc_share)
    for _ in range(int(n_sub)):
        t_ain = t_ain_c(p, t_evap_c, mdot_bl_kgps, d_ain_k)
        t_evap_n = t_evap_next_c(p, t_evap_c, t_evap_sp_c) + d_evap_k
        q = q_evap_w(p, t_cab_c, t_amb_c, t_ain, mdot_bl_kgps, t_evap_c, t_evap_n, phi)
        pc_sum = pc_sum + p_comp_w(p, q, t_amb_c, t_evap_c, speed_mps)
        t_ain_sum = t_ain_sum + t_ain
        t_cab_c, t_evap_c = (t_cab_next_c(p, t_cab_c, t_int_c, t_shell_c, t_ain, mdot_bl_kgps, d_cab_k), t_evap_n)
    return t_cab_c, t_evap_c, t_ain_sum / n_sub, pc_sum / n_sub, p_blower_w(p, mdot_bl_kgps)


def simulate(
    p: ControlModelParams,
    t_cab0_c: float,
    t_evap0_c: float,
    mdot_bl_kgps,
    t_evap_sp_c,
    t_int_c,
    t_shell_c,
    t_amb_c,
    speed_mps,
    n_sub: int = 1,
):
    """Numpy multi-step prediction from an initial state over given input/exogenous sequences.

    All sequence arguments are arrays of length N (or scalars, broadcast).
    Returns a dict of arrays: ``t_cab_c`` and ``t_evap_c`` (N+1 values,
    starting at the initial state), ``t_ain_c``, ``p_comp_w``, ``p_blower_w`` (N).
    """
    seqs = np.broadcast_arrays(
        *(
            np.atleast_1d(np.asarray(a, dtype=float))
            for a in (mdot_bl_kgps, t_evap_sp_c, t_int_c, t_shell_c, t_amb_c, speed_mps)
        )
    )
    n = seqs[0].size
    t_cab = np.empty(n + 1)
    t_evap = np.empty(n + 1)
    t_ain = np.empty(n)
    pc = np.empty(n)
    pb = np.empty(n)
    t_cab[0], t_evap[0] = t_cab0_c, t_evap0_c
    for i in range(n):
        m, sp, ti, ts, ta, v = (s[i] for s in seqs)
        t_cab[i + 1], t_evap[i + 1], t_ain[i], pc[i], pb[i] = step(
            p, t_cab[i], t_evap[i], m, sp, ti, ts, ta, v, n_sub=n_sub
        )
    return {"t_cab_c": t_cab, "t_evap_c": t_evap, "t_ain_c": t_ain, "p_comp_w": pc, "p_blower_w": pb}
