"""FROZEN REFERENCE: the plant of commit 8546529 (before its equations were written once), for ``ceco bench plant``.

Copied once, unchanged in its numbers, from ``git show 8546529:ceco_plant_sim/ceco_plant_sim/refrigerant.py``
(``CompressorModel``, ``CycleSolution``, ``solve_cycle`` and its helpers) and ``.../plant.py`` (``CabinPlant``
and its helpers), with the table lookups of 8546529's ``refrigerant_tables.py`` (the inline
``value_slope`` / ``value_grad``, now :func:`_value_slope` / :func:`_value_grad`) and the imports pointed at
the modules that still hold the same objects (``PlantParams``, ``PlantState``, ``PlantOutputs``,
``cycle_tables``). Used only by the plant benchmark (:mod:`ceco_plant_sim.bench_plant`: "today's
implementation" timed against the numeric and the compiled paths) and the equality tests
(tests/test_compiled_plant.py). Do not edit, do not import it from the product: the plant is
:mod:`ceco_plant_sim.plant_equations` (docs/plant.md).
"""

# ruff: noqa
# mypy: ignore-errors
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields

from ceco_core.contracts import AcInput
from ceco_core.contracts import check_finite as _check_finite
from ceco_core.psychro import EPS_W as _EPS_W
from ceco_core.psychro import relative_humidity, saturation_vapour_pressure_pa
from ceco_plant_sim.plant_params import PlantParams
from ceco_plant_sim.plant_state import PlantOutputs, PlantState, validate_environment
from ceco_plant_sim.refrigerant_table_file import cycle_tables
from ceco_plant_sim.refrigerant_tables import CycleTables

__all__ = ["CabinPlant", "solve_cycle"]


def _value_slope(table, x: float) -> tuple[float, float]:
    """Return (y(x), dy/dx) of the interpolant (the plant's hot path: kept inline)."""
    u = (x - table.x0) * table.inv_dx
    i = int(math.floor(u))
    if i < 0:
        i = 0
    elif i > table.n - 2:
        i = table.n - 2
    f = u - i
    y = table.y
    d = y[i + 1] - y[i]
    return y[i] + f * d, d * table.inv_dx


def _value_grad(table, x: float, y: float) -> tuple[float, float, float]:
    """Return (z(x, y), dz/dx, dz/dy) of the bilinear interpolant (the plant's hot path: kept inline)."""
    u = (x - table.x0) * table.inv_dx
    i = int(math.floor(u))
    if i < 0:
        i = 0
    elif i > table.nx - 2:
        i = table.nx - 2
    v = (y - table.y0) * table.inv_dy
    j = int(math.floor(v))
    if j < 0:
        j = 0
    elif j > table.ny - 2:
        j = table.ny - 2
    f = u - i
    g = v - j
    r0 = table.z[i]
    r1 = table.z[i + 1]
    z00, z01, z10, z11 = r0[j], r0[j + 1], r1[j], r1[j + 1]
    a = z00 + g * (z01 - z00)
    b = z10 + g * (z11 - z10)
    dzdy = ((1.0 - f) * (z01 - z00) + f * (z11 - z10)) * table.inv_dy
    return a + f * (b - a), (b - a) * table.inv_dx, dzdy


@dataclass(frozen=True)
class CompressorModel:
    """Electric scroll compressor efficiencies (pressure-ratio maps, typical of automotive scrolls)."""

    displacement_m3: float
    """Swept volume per revolution [m3]."""
    eta_vol_0: float
    """Volumetric efficiency extrapolated to pressure ratio 1 [-]."""
    eta_vol_slope: float
    """Volumetric efficiency loss per unit of pressure ratio above 1 [-]."""
    eta_is_max: float
    """Peak isentropic efficiency [-]."""
    eta_is_curv: float
    """Isentropic efficiency loss per (pressure ratio - optimum)^2 [-]."""
    pr_opt: float
    """Pressure ratio of peak isentropic efficiency (built-in volume ratio) [-]."""
    eta_motor_inverter: float
    """Motor and inverter efficiency (electrical -> shaft) [-]."""

    def eta_vol(self, pr: float) -> float:
        """Volumetric efficiency at pressure ratio ``pr`` (floored at 0.3)."""
        return max(0.3, self.eta_vol_0 - self.eta_vol_slope * (max(pr, 1.0) - 1.0))

    def eta_is(self, pr: float) -> float:
        """Isentropic efficiency at pressure ratio ``pr`` (floored at 0.3)."""
        d = max(pr, 1.0) - self.pr_opt
        return max(0.3, self.eta_is_max - self.eta_is_curv * d * d)


@dataclass(frozen=True)
class CycleSolution:
    """Quasi-steady refrigerant cycle at one instant."""

    t_evap_sat_c: float
    """Evaporating (saturation) temperature [degC]."""
    t_cond_c: float
    """Condensing temperature [degC]."""
    mdot_ref_kgps: float
    """Refrigerant mass flow [kg/s]."""
    q_evap_ref_w: float
    """Heat absorbed by the refrigerant in the evaporator [W]."""
    w_shaft_w: float
    """Compressor shaft power [W]."""
    p_comp_w: float
    """Compressor electrical power (shaft / motor-inverter efficiency) [W]."""
    q_cond_w: float
    """Heat rejected at the condenser [W]."""
    pressure_ratio: float
    """Discharge / suction pressure ratio [-]."""
    mop_active: bool
    """True when the expansion valve's MOP caps the evaporating temperature."""
    head_pressure_control: bool
    """True when head-pressure control holds the pressure ratio at its minimum (cold condenser air)."""
    iterations: int
    """Newton iterations used."""


def _cycle_eval(
    tab: CycleTables,
    comp: CompressorModel,
    vn: float,
    t_e: float,
    t_c: float,
    t_wall_c: float,
    ua_er_wpk: float,
    t_air_c: float,
    epsc_wpk: float,
):
    """Residuals (r1, r2) [W], their analytic Jacobian, and the cycle quantities at (t_e, t_c).

    The Jacobian is exact for the piecewise-linear / bilinear interpolants.
    """
    p_e, p_e1 = _value_slope(tab.p_evap_pa, t_e)
    rho, rho1 = _value_slope(tab.rho_suc_kgm3, t_e)
    h1, h11 = _value_slope(tab.h_suc_jpkg, t_e)
    p_c, p_c1 = _value_slope(tab.p_cond_pa, t_c)
    h3, h31 = _value_slope(tab.h_liq_jpkg, t_c)
    dhs, dhs_e, dhs_c = _value_grad(tab.dh_is_jpkg, t_e, t_c)
    pr = p_c / p_e
    pr_e = -p_c * p_e1 / (p_e * p_e)
    pr_c = p_c1 / p_e
    # volumetric efficiency and its slope in pr (0 where floored / pr < 1)
    prc = pr if pr > 1.0 else 1.0
    ev = comp.eta_vol_0 - comp.eta_vol_slope * (prc - 1.0)
    if ev < 0.3:
        ev, ev1 = 0.3, 0.0
    else:
        ev1 = -comp.eta_vol_slope if pr > 1.0 else 0.0
    d = prc - comp.pr_opt
    ei = comp.eta_is_max - comp.eta_is_curv * d * d
    if ei < 0.3:
        ei, ei1 = 0.3, 0.0
    else:
        ei1 = -2.0 * comp.eta_is_curv * d if pr > 1.0 else 0.0
    m = rho * vn * ev
    m_e = vn * (rho1 * ev + rho * ev1 * pr_e)
    m_c = vn * rho * ev1 * pr_c
    dh = h1 - h3
    w = dhs / ei
    w_e = dhs_e / ei - dhs * ei1 * pr_e / (ei * ei)
    w_c = dhs_c / ei - dhs * ei1 * pr_c / (ei * ei)
    q_e = m * dh
    r1 = q_e - ua_er_wpk * (t_wall_c - t_e)
    r2 = m * (dh + w) - epsc_wpk * (t_c - t_air_c)
    j11 = m_e * dh + m * h11 + ua_er_wpk
    j12 = m_c * dh - m * h31
    j21 = m_e * (dh + w) + m * (h11 + w_e)
    j22 = m_c * (dh + w) + m * (-h31 + w_c) - epsc_wpk
    return r1, r2, j11, j12, j21, j22, m, q_e, m * w, pr, p_e, p_e1, p_c, p_c1


def solve_cycle(
    tab: CycleTables,
    comp: CompressorModel,
    speed_rpm: float,
    t_wall_c: float,
    ua_er_wpk: float,
    t_air_cond_c: float,
    epsc_cond_wpk: float,
    te_mop_c: float,
    guess: tuple[float, float] | None = None,
    tol_k: float = 1e-7,
    max_iter: int = 30,
    pr_min: float = 1.0,
) -> CycleSolution:
    """Solve the quasi-steady cycle for (T_e, T_c) by Newton's method.

    Args:
        tab: the refrigerant property tables.
        comp: the compressor's efficiencies and displacement.
        speed_rpm: compressor speed [rpm] (>= 0; 0 means off).
        t_wall_c: evaporator wall temperature [degC].
        ua_er_wpk: wall-to-refrigerant conductance of the evaporator [W/K].
        t_air_cond_c: condenser inlet air temperature [degC].
        epsc_cond_wpk: condenser effectiveness times air heat-capacity rate [W/K].
        te_mop_c: expansion valve MOP cap on the evaporating temperature [degC].
        guess: starting (T_e, T_c) [degC]; None for a built-in start.
        tol_k: convergence tolerance on the Newton update [K].
        max_iter: largest number of property evaluations [-].
        pr_min: minimum pressure ratio held by head-pressure control [-] (1 = none).

    Newton on (r1, r2) with the analytic Jacobian of the interpolated
    properties, each update limited to 10 K; converged at the first iterate
    whose Newton update is below ``tol_k`` in both temperatures (that iterate
    and its evaluated flows are returned: it lies within ~tol_k of the root).
    ``iterations`` counts property evaluations.
    If the solution exceeds ``te_mop_c``, T_e is pinned at the MOP and only
    the condenser equation is solved for T_c. If the pressure ratio falls
    below ``pr_min`` (condenser air colder than the evaporator), the
    condenser balance r2 is replaced by p_c = pr_min p_e (head-pressure
    control throttles the condenser air; the condenser then rejects
    Q_ref + W at that pressure). Raises RuntimeError if ``max_iter``
    evaluations are reached.
    """
    if speed_rpm <= 0.0:
        return CycleSolution(t_wall_c, t_air_cond_c, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, False, False, 0)
    vn = comp.displacement_m3 * speed_rpm / 60.0
    if guess is None:
        t_e = min(t_wall_c - 5.0, te_mop_c)
        t_c = t_air_cond_c + 15.0
    else:
        t_e, t_c = guess
    args = (t_wall_c, ua_er_wpk, t_air_cond_c, epsc_cond_wpk)
    mop = False
    hp = False
    it = 0
    for _ in range(3):  # constraint flags only get added: at most 3 solves
        converged = False
        while it < max_iter:
            (r1, r2, j11, j12, j21, j22, mdot, q_e, w_sh, pr, p_e, p_e1, p_c, p_c1) = _cycle_eval(
                tab, comp, vn, t_e, t_c, *args
            )
            it += 1
            if hp:  # head-pressure control: condenser air reduced so that p_c = pr_min p_e
                r2 = p_c - pr_min * p_e
                j21 = -pr_min * p_e1
                j22 = p_c1
            if mop:  # T_e pinned at the MOP: the condenser (or head-pressure) equation alone
                de = 0.0
                dc = -r2 / j22
            else:
                det = j11 * j22 - j12 * j21
                de = -(j22 * r1 - j12 * r2) / det
                dc = -(-j21 * r1 + j11 * r2) / det
            if abs(de) < tol_k and abs(dc) < tol_k:
                converged = True  # this point is within ~tol_k of the root: keep its evaluated quantities
                break
            t_e += max(-10.0, min(10.0, de))
            t_c += max(-10.0, min(10.0, dc))
        if not converged:
            raise RuntimeError(
                f"refrigerant cycle did not converge in {max_iter} iterations "
                f"(speed {speed_rpm:.0f} rpm, wall {t_wall_c:.2f} degC)"
            )
        new_mop = mop or t_e > te_mop_c
        new_hp = hp or pr < pr_min * (1.0 - 1e-9)
        if new_mop == mop and new_hp == hp:
            break
        if new_mop:
            t_e = te_mop_c
        mop, hp = new_mop, new_hp
    return CycleSolution(
        t_evap_sat_c=t_e,
        t_cond_c=t_c,
        mdot_ref_kgps=mdot,
        q_evap_ref_w=q_e,
        w_shaft_w=w_sh,
        p_comp_w=w_sh / comp.eta_motor_inverter,
        q_cond_w=q_e + w_sh,
        pressure_ratio=pr,
        mop_active=mop,
        head_pressure_control=hp,
        iterations=it,
    )


def condenser_eps_c_wpk(params: PlantParams, speed_mps: float) -> float:
    """Condenser effectiveness x air heat-capacity rate [W/K] at vehicle speed ``speed_mps``.

    Face velocity v = sqrt(v_fan^2 + (k_ram V)^2) (fan and ram pressure add
    across the quadratic core resistance), mdot_air = rho A v, UA = UA_ref
    (v / v_ref)^n, eps = 1 - exp(-UA / (mdot_air cp)) (condensing side
    isothermal, C_r = 0; Incropera & DeWitt, eq. 11.35a).
    """
    p = params
    v = math.sqrt(p.v_face_fan_mps**2 + (p.ram_face_ratio * speed_mps) ** 2)
    c_air = p.rho_air_kgm3 * p.a_cond_face_m2 * v * p.cp_air_jpkgk
    ua = p.ua_cond_ref_wpk * (v / p.v_face_ref_mps) ** p.ua_cond_exp
    return c_air * (1.0 - math.exp(-ua / c_air))


def _compressor_model(p: PlantParams) -> CompressorModel:
    return CompressorModel(
        displacement_m3=p.displacement_m3,
        eta_vol_0=p.eta_vol_0,
        eta_vol_slope=p.eta_vol_slope,
        eta_is_max=p.eta_is_max,
        eta_is_curv=p.eta_is_curv,
        pr_opt=p.pr_opt,
        eta_motor_inverter=p.eta_motor_inverter,
    )


def _tables(p: PlantParams):
    return cycle_tables(p.refrigerant, float(p.superheat_k), float(p.subcool_k))


def steady_cycle_at_load(
    params: PlantParams, q_evap_w: float, t_wall_c: float, t_amb_c: float, speed_mps: float
) -> tuple[float, CycleSolution]:
    """Compressor speed and cycle state that deliver ``q_evap_w`` at a fixed evaporator wall temperature.

    Used for the efficiency-versus-vehicle-speed map (fixed cooling load):
    bisection on the compressor speed (60 halvings) between 1 rpm and
    ``comp_speed_max_rpm``. Raises ValueError if the load exceeds the
    capacity at maximum speed. Returns (speed_rpm, CycleSolution).
    """
    p = params.validate()
    tab = _tables(p)
    comp = _compressor_model(p)
    epsc = condenser_eps_c_wpk(p, speed_mps)

    def q_at(n):
        s = solve_cycle(
            tab,
            comp,
            n,
            t_wall_c,
            p.ua_evap_ref_wpk,
            t_amb_c,
            epsc,
            p.te_mop_c,
            tol_k=p.cycle_tol_k,
            max_iter=p.cycle_max_iter,
            pr_min=p.pr_min,
        )
        return s.q_evap_ref_w, s

    q_max, _ = q_at(p.comp_speed_max_rpm)
    if q_evap_w > q_max:
        raise ValueError(f"q_evap_w: {q_evap_w:.0f} W exceeds the capacity {q_max:.0f} W at maximum speed")
    lo, hi = 1.0, p.comp_speed_max_rpm
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if q_at(mid)[0] < q_evap_w:
            lo = mid
        else:
            hi = mid
    n = 0.5 * (lo + hi)
    return n, q_at(n)[1]


class CabinPlant:
    """The cabin + A/C plant. ``step(command, env, dt_s)`` advances time with the command held.

    Args:
        params: the plant's :class:`PlantParams` (validated here).
        state: the initial :class:`PlantState`, e.g.
            ``PlantState.from_initial(scenario.initial, params, env)``.
    """

    def __init__(self, params: PlantParams, state: PlantState) -> None:
        if not isinstance(params, PlantParams):
            raise ValueError(f"params: must be PlantParams, got {type(params).__name__}")
        if not isinstance(state, PlantState):
            raise ValueError(f"state: must be PlantState, got {type(state).__name__}")
        self.params = params.validate()
        self._x = state.validate().as_tuple()
        self._tab = _tables(params)
        self._comp = _compressor_model(params)
        self._guess: tuple[float, float] | None = None
        self._t_s = 0.0
        self._last: PlantOutputs | None = None
        p = params
        self._m_air_kg = p.rho_air_kgm3 * p.cabin_volume_m3
        self._c_cab_jpk = self._m_air_kg * p.cp_air_jpkgk

    # ------------------------------------------------------------------ API
    @property
    def state(self) -> PlantState:
        """Current state (a new frozen PlantState)."""
        return PlantState(*self._x)

    @property
    def t_s(self) -> float:
        """Simulated time since construction [s] (sum of dt_s)."""
        return self._t_s

    @property
    def tables_source(self) -> str:
        """Where the refrigerant property tables come from (the shipped file or a CoolProp build)."""
        return self._tab.source

    def outputs(self) -> PlantOutputs:
        """Outputs of the last step; RuntimeError before the first step."""
        if self._last is None:
            raise RuntimeError("outputs: no step taken yet (call step() first)")
        return self._last

    def step(self, command: AcInput, env, dt_s: float) -> PlantOutputs:
        """Advance the plant by ``dt_s`` seconds with ``command`` and ``env`` held; return the outputs.

        The interval is split into ceil(dt_s / substep_s) equal RK4 sub-steps,
        so dt_s = 1 and dt_s = 5 integrate the same way when substep_s
        divides 1 s. Raises ValueError for a bad command, environment or dt_s.
        """
        if not isinstance(command, AcInput):
            raise ValueError(f"command: must be AcInput, got {type(command).__name__}")
        command.validate()
        dt = _check_finite("dt_s", dt_s)
        if dt <= 0.0:
            raise ValueError(f"dt_s: must be > 0, got {dt}")
        if dt > 3600.0:
            raise ValueError(f"dt_s: must be <= 3600 s, got {dt}")
        envt = validate_environment(env)
        n_sub = max(1, math.ceil(dt / self.params.substep_s - 1e-9))
        h = dt / n_sub
        x = self._x
        acc = [0.0] * 8  # e_comp, e_fan, q_evap_air, q_latent, q_ref [J]; water in, out, condensate [kg]
        p_bl = self._blower_power_w(float(command.mdot_bl_kgps))
        u = (float(command.mdot_bl_kgps), float(command.t_evap_sp_c), p_bl)
        for _ in range(n_sub):
            k1, a1 = self._rhs(x, u, envt)
            x2 = tuple(xi + 0.5 * h * ki for xi, ki in zip(x, k1))
            k2, a2 = self._rhs(x2, u, envt)
            x3 = tuple(xi + 0.5 * h * ki for xi, ki in zip(x, k2))
            k3, a3 = self._rhs(x3, u, envt)
            x4 = tuple(xi + h * ki for xi, ki in zip(x, k3))
            k4, a4 = self._rhs(x4, u, envt)
            x = tuple(xi + h / 6.0 * (q1 + 2.0 * q2 + 2.0 * q3 + q4) for xi, q1, q2, q3, q4 in zip(x, k1, k2, k3, k4))
            for j in range(8):
                acc[j] += h / 6.0 * (a1[j] + 2.0 * a2[j] + 2.0 * a3[j] + a4[j])
        for i, v in enumerate(x):
            if not math.isfinite(v):
                raise RuntimeError(f"plant state {fields(PlantState)[i].name} became non-finite")
        self._x = x
        self._t_s += dt
        e_comp, e_fan, e_q, e_lat, e_ref = acc[:5]
        out = dataclasses.replace(
            self._outputs(x, u, envt, dt, e_comp, e_fan, e_q, e_lat, e_ref),
            m_water_in_kg=acc[5],
            m_water_out_kg=acc[6],
            m_condensate_kg=acc[7],
        )
        self._last = out
        return out

    def snapshot(self, command: AcInput, env) -> PlantOutputs:
        """Instantaneous outputs at the current state for ``command`` and ``env``, without advancing time.

        Same fields as :meth:`step`; powers are instantaneous values (not step
        means), energies are 0 and ``cop`` is the instantaneous ratio. Useful
        for the measurements at t = 0 (e.g. the vent temperature before the
        first step). Does not change the plant (state, time, warm start).
        """
        if not isinstance(command, AcInput):
            raise ValueError(f"command: must be AcInput, got {type(command).__name__}")
        command.validate()
        envt = validate_environment(env)
        p_bl = self._blower_power_w(float(command.mdot_bl_kgps))
        u = (float(command.mdot_bl_kgps), float(command.t_evap_sp_c), p_bl)
        return self._outputs(self._x, u, envt, 0.0, *self._rhs(self._x, u, envt, final=True)[0][:5])

    def _outputs(self, x, u, envt, dt, e_comp, e_fan, e_q, e_lat, e_ref) -> PlantOutputs:
        """Build PlantOutputs at state x: energies over dt (dt = 0: the arguments are instantaneous powers)."""
        powers, alg = self._rhs(x, u, envt, final=True)
        p_bl = u[2]
        if dt > 0.0:
            mean = (e_comp / dt, e_fan / dt, e_q / dt, e_lat / dt, e_ref / dt)
            energies = (e_comp, p_bl * dt)
        else:
            mean = (e_comp, e_fan, e_q, e_lat, e_ref)
            energies = (0.0, 0.0)
        t_cab, t_int, t_sh, t_gl, t_ev, t_du, w_cab, _ = x
        return PlantOutputs(
            t_cab_c=t_cab,
            t_int_c=t_int,
            t_shell_c=t_sh,
            t_glass_c=t_gl,
            t_evap_c=t_ev,
            t_duct_c=t_du,
            t_vent_c=alg["t_vent_c"],
            t_evap_out_c=alg["t_evap_out_c"],
            t_evap_sat_c=alg["t_evap_sat_c"],
            t_cond_c=alg["t_cond_c"],
            rh_cab=relative_humidity(t_cab, w_cab, self.params.p_atm_pa),
            w_cab_kgkg=w_cab,
            p_comp_w=mean[0],
            p_blower_w=p_bl,
            p_cond_fan_w=mean[1],
            e_comp_j=energies[0],
            e_blower_j=energies[1],
            q_evap_w=mean[2],
            q_latent_w=mean[3],
            q_evap_ref_w=mean[4],
            cop=(mean[4] / mean[0]) if mean[0] > 0.0 else 0.0,
            comp_speed_rpm=alg["comp_speed_rpm"],
            comp_duty=alg["comp_duty"],
            capacity_limited=alg["capacity_limited"],
            mop_active=alg["mop_active"],
            mdot_ref_kgps=alg["mdot_ref_kgps"],
            cycle_iterations=alg["iterations"],
        )

    # -------------------------------------------------------------- physics
    def _blower_power_w(self, mdot_kgps: float) -> float:
        """Fan law: P = dp(mdot) * Vdot / eta + P_fixed, dp = dp_ref (mdot/mdot_ref)^2  =>  P ~ mdot^3."""
        p = self.params
        r = mdot_kgps / p.mdot_bl_ref_kgps
        return p.dp_blower_ref_pa * r * r * (mdot_kgps / p.rho_air_kgm3) / p.eta_blower + p.p_blower_fixed_w

    def _rhs(self, x, u, envt, final: bool = False):
        p = self.params
        t_cab, t_int, t_sh, t_gl, t_ev, t_du, w_cab, pi_i = x
        mdot, t_sp, p_bl = u
        t_amb, solar, speed, rh_amb = envt
        cp_a = p.cp_air_jpkgk
        wsat = saturation_vapour_pressure_pa
        patm = p.p_atm_pa

        # ambient humidity ratio
        pw_amb = rh_amb * wsat(t_amb)
        w_amb = _EPS_W * pw_amb / (patm - pw_amb)

        # --- air loop: mixing box -> blower -> evaporator -> ducts -> vents
        r = p.recirc_fraction
        t_mix = r * t_cab + (1.0 - r) * t_amb
        w_mix = r * w_cab + (1.0 - r) * w_amb
        cp_m = cp_a + w_mix * p.cp_vap_jpkgk
        c_air = mdot * cp_m
        rr = mdot / p.mdot_bl_ref_kgps
        t_in = t_mix + p_bl / c_air  # blow-through module: all blower power ends as heat in the air
        ua_air = p.ua_evap_air_ref_wpk * rr**p.ua_evap_air_exp
        bf = math.exp(-ua_air / c_air)  # bypass factor = 1 - effectiveness
        t_out = t_ev + bf * (t_in - t_ev)
        pws_w = wsat(t_ev)
        w_sw = _EPS_W * pws_w / (patm - pws_w)
        excess = w_mix - w_sw
        w_out = w_mix - (1.0 - bf) * excess if excess > 0.0 else w_mix
        q_sens = c_air * (t_in - t_out)
        q_lat = mdot * (w_mix - w_out) * p.h_fg_jpkg
        # HVAC case and ducts: the supply air exchanges with their wall, which exchanges with the panel
        ua_da = p.ua_duct_air_ref_wpk * rr**p.ua_evap_air_exp
        t_vent = t_out + (t_du - t_out) * (1.0 - math.exp(-ua_da / c_air))
        q_duct = c_air * (t_vent - t_out)  # duct wall -> supply air
        q_duct_int = p.ua_duct_wpk * (t_int - t_du)  # instrument panel (interior mass) -> duct wall

        # --- compressor: A/C ECU PI on the evaporator wall temperature
        err = t_ev - t_sp
        n_cmd = p.comp_kp_rpm_per_k * err + pi_i
        n_max = p.comp_speed_max_rpm
        n_min = p.comp_speed_min_rpm
        if n_cmd >= n_max:
            n_run, duty = n_max, 1.0
        elif n_cmd >= n_min:
            n_run, duty = n_cmd, 1.0
        elif n_cmd > 0.0:
            n_run, duty = n_min, n_cmd / n_min
        else:
            n_run, duty = 0.0, 0.0
        epsc = condenser_eps_c_wpk(p, speed)
        sol = solve_cycle(
            self._tab,
            self._comp,
            n_run,
            t_ev,
            p.ua_evap_ref_wpk,
            t_amb,
            epsc,
            p.te_mop_c,
            guess=self._guess,
            tol_k=p.cycle_tol_k,
            max_iter=p.cycle_max_iter,
            pr_min=p.pr_min,
        )
        power_limited = False
        if duty == 1.0 and sol.p_comp_w > p.p_comp_max_w:
            # inverter power limit: the ECU lowers the speed until P_el = P_max. Secant iteration on
            # P_el(N) - P_max from N and N*P_max/P_el(N); stops within 0.05 % of the limit (cap 6).
            power_limited = True
            n0, f0 = n_run, sol.p_comp_w - p.p_comp_max_w
            n_run = n_run * p.p_comp_max_w / sol.p_comp_w
            for _ in range(6):
                sol = solve_cycle(
                    self._tab,
                    self._comp,
                    n_run,
                    t_ev,
                    p.ua_evap_ref_wpk,
                    t_amb,
                    epsc,
                    p.te_mop_c,
                    guess=(sol.t_evap_sat_c, sol.t_cond_c),
                    tol_k=p.cycle_tol_k,
                    max_iter=p.cycle_max_iter,
                    pr_min=p.pr_min,
                )
                f1 = sol.p_comp_w - p.p_comp_max_w
                if abs(f1) < 5e-4 * p.p_comp_max_w or f1 == f0:
                    break
                n0, f0, n_run = n_run, f1, n_run - f1 * (n_run - n0) / (f1 - f0)
        saturated_high = n_cmd >= n_max or power_limited
        if (saturated_high and err > 0.0) or (n_cmd <= 0.0 and err < 0.0):
            dpi = 0.0  # conditional integration (anti-windup)
        else:
            dpi = p.comp_ki_rpm_per_ks * err
        if n_run > 0.0 and not final:
            # warm start of the next solve; the end-of-step report does not touch it, so splitting
            # an interval into more calls of step() reproduces the same sub-step sequence bit for bit
            self._guess = (sol.t_evap_sat_c, sol.t_cond_c)
        q_ref = duty * sol.q_evap_ref_w
        p_comp = duty * sol.p_comp_w
        p_fan = duty * p.p_cond_fan_w if n_run > 0.0 else 0.0

        # --- cabin network
        h_in = p.h_in_natural_wm2k + (p.h_in_forced_wm2k - p.h_in_natural_wm2k) * rr**0.8
        h_out = p.h_out_natural_wm2k + p.h_out_speed_coef * speed**0.8
        m_inf = p.infiltration_0_kgps + p.infiltration_per_mps_kgps * speed
        g_int = h_in * p.a_int_m2
        g_sh_in = p.u_shell_in_wm2k * p.a_shell_m2
        g_gl_in = h_in * p.a_glass_m2
        q_int_cab = g_int * (t_int - t_cab)
        q_sh_cab = g_sh_in * (t_sh - t_cab)
        q_gl_cab = g_gl_in * (t_gl - t_cab)
        q_rad_sh = p.g_rad_int_shell_wpk * (t_int - t_sh)
        q_rad_gl = p.g_rad_int_glass_wpk * (t_int - t_gl)
        n_occ = p.n_occupants
        cp_cab = cp_a + w_cab * p.cp_vap_jpkgk
        d_cab = (
            mdot * cp_cab * (t_vent - t_cab)
            + m_inf * cp_cab * (t_amb - t_cab)
            + q_int_cab
            + q_sh_cab
            + q_gl_cab
            + n_occ * p.occ_sensible_w
        ) / (self._m_air_kg * cp_cab)
        # water balance of the cabin air [kg/s]: in with the fresh share of the supply, the leakage and
        # the occupants; out with the exfiltrated air (both leave at the cabin state); the condensate
        # leaves the supply air on the coil. (Identical to mdot (W_out - W_cab) + mdot_inf (W_amb - W_cab) + ...)
        fresh = (1.0 - r) * mdot + m_inf
        water_in = fresh * w_amb + n_occ * p.occ_latent_w / p.h_fg_jpkg
        water_out = fresh * w_cab
        condensate = mdot * (w_mix - w_out)
        d_w = (water_in - water_out - condensate) / self._m_air_kg
        d_int = (p.tau_glass * p.a_glass_sun_m2 * solar - q_int_cab - q_rad_sh - q_rad_gl - q_duct_int) / p.c_int_jpk
        d_du = (q_duct_int - q_duct) / p.c_duct_jpk
        d_sh = (
            p.alpha_shell * p.a_shell_sun_m2 * solar + h_out * p.a_shell_m2 * (t_amb - t_sh) - q_sh_cab + q_rad_sh
        ) / p.c_shell_jpk
        d_gl = (
            p.alpha_glass * p.a_glass_sun_m2 * solar + h_out * p.a_glass_m2 * (t_amb - t_gl) - q_gl_cab + q_rad_gl
        ) / p.c_glass_jpk
        d_ev = (q_sens + q_lat - q_ref) / p.c_evap_jpk

        dx = (d_cab, d_int, d_sh, d_gl, d_ev, d_du, d_w, dpi)
        powers = (p_comp, p_fan, q_sens + q_lat, q_lat, q_ref, water_in, water_out, condensate)
        if not final:
            return dx, powers
        # final=True: the end-of-step / snapshot report (powers and algebraic variables, no derivatives)
        alg = {
            "t_vent_c": t_vent,
            "t_evap_out_c": t_out,
            "t_evap_sat_c": sol.t_evap_sat_c,
            "t_cond_c": sol.t_cond_c,
            "comp_speed_rpm": n_run,
            "comp_duty": duty,
            "capacity_limited": saturated_high,
            "mop_active": sol.mop_active,
            "mdot_ref_kgps": duty * sol.mdot_ref_kgps,
            "iterations": sol.iterations,
        }
        return powers, alg


# ---------------------------------------------------------------------------------------------------------
# Not part of the copy: the simulator's plant step of 8546529 on this plant (its scored comfort is the numeric
# ceco_core.cabin_comfort.evaluate_cabin_comfort, whose numbers did not change since).


class _InScenarioPlant(CabinPlant):
    """8546529's plant where today's ``ScenarioPlant`` holds it (issue 21 added the door and cabin CO2 after it).

    It takes the first 8 states (8546529's) of today's state and has no door: the door command reads as
    the fixed ``recirc_fraction`` 8546529 ran with; CO2 is not modelled (its outputs keep their defaults).
    """

    def __init__(self, params: PlantParams, state: PlantState) -> None:
        super().__init__(params, state)
        self._x = tuple(self._x[:8])

    def equation_input(self, command: AcInput):
        from ceco_plant_sim.plant_equations import Input

        return Input(float(command.mdot_bl_kgps), float(command.t_evap_sp_c), float(self.params.recirc_fraction))


def reference_scenario_plant(scenario, plant_dt_s: float, **kwargs):
    """A ``ScenarioPlant`` (Python evaluation) whose plant is this module's :class:`CabinPlant`: 8546529's step."""
    from ceco_plant_sim.compiled_plant import PlantEvaluation
    from ceco_plant_sim.scenario_plant import ScenarioPlant

    sp = ScenarioPlant(scenario, plant_dt_s, evaluation=PlantEvaluation("python"), **kwargs)
    sp.plant = _InScenarioPlant(sp.plant.params, sp.plant.state)
    return sp
