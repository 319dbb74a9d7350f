"""The CECO NLP (docs/controller.md 4.1) as a CasADi problem: model, cost, constraints, layout.

Built once per controller, parametric in the initial state, the held interior/shell
temperatures, the bias estimates, the previous command, the weather and speed previews and the
PMV bounds (:class:`~ceco_controller.nlp_layout.ParamLayout`). Two transcriptions of the same
problem, stage-wise ordered so the multiple-shooting NLP has the optimal-control structure:

    w = [u_0, s_0, x_1, u_1, s_1, ..., x_N, s_N]   (x_0 is the measured state, a parameter;
                                                    single shooting: no x_i)
    x_i = (T_cab, T_evap [degC], mdot_{i-1} [kg/s], T_evap_sp_{i-1} [degC]),
    u_i = (mdot_bl [kg/s], T_evap_sp [degC])
    s_i = (s_lo, s_up [PMV], s_ev [K] (i >= 1), eps [PMV] (ceco-ioch))

With the door in the NLP (``door_control`` 'nlp', docs/controller.md 4.9) u_i gains the recirculated share
r_i [-], x_i the previous share r_{i-1}, the cabin CO2 C_i and the cabin humidity ratio W_i
(x_i = (T_cab, T_evap, u_{i-1}, C_i, W_i)), s_i the CO2 slack s_co2 and the fog slack s_fog (i >= 1) of the
soft constraints C_i - s_co2 <= limit - margin and T_glass - T_dp(W_i) + s_fog >= fog bound + back-off; C and
s_co2 in units of :data:`CO2_SCALE_PPM` (1000 ppm), W in g/kg (:data:`W_SCALE_KGKG`) inside the NLP, ppm and
kg/kg in :class:`Evaluation`.

* ``multiple-shooting``: the x_i are variables tied by gap constraints x_i - f(x_{i-1}, u_{i-1}) = 0.
* ``single-shooting``: the x_i are the model's rollout expressions of (x_0, u_0 .. u_{i-1}).

The problem knows nothing about solvers (:mod:`ceco_controller.solvers`) or the control loop
(:mod:`ceco_controller.nmpc`).
"""

from __future__ import annotations

import dataclasses

import casadi
import numpy as np

from ceco_core import psychro
from ceco_core.air_quality import cabin_water_flows_kgps, coil_outlet_humidity_ratio, fog_margin_k, leakage_kgps
from ceco_core.cabin_comfort import ComfortParams, cabin_draught_pct, cabin_pmv, cabin_w_rad_wm2
from ceco_core.co2_door import co2_after_ppm
from ceco_core.contracts import ACTUATOR_LIMITS, ActuatorLimits
from ceco_core.mathops import smooth_max

from . import model as cm
from .buffered import BufferedFunction
from .nlp_layout import OcpStructure, ParamLayout, RowLayout, VariableLayout
from .strategies import StrategySettings

__all__ = ["NlpProblem", "Evaluation", "build_problem", "TRANSCRIPTIONS", "CO2_SCALE_PPM", "W_SCALE_KGKG"]

TRANSCRIPTIONS = ("single-shooting", "multiple-shooting")
"""The transcriptions :func:`build_problem` knows."""

CO2_SCALE_PPM = 1000.0
"""The door NLP carries the cabin CO2 (state, slack, limit row) in units of this [ppm]: its rows then weigh like
the PMV and temperature rows in the SQP's l1 merit function (one sigma for all rows, about 1.1 x the largest
multiplier, the comfort rows' 1000 kJ/PMV); in ppm a 0.1 ppm linearisation error of the CO2 cost 110 kJ of merit and
the line search took 1/64 steps (docs/controller.md 4.9)."""

W_SCALE_KGKG = 1e-3
"""The door NLP carries the cabin humidity ratio in g/kg (units of this [kg/kg]): values of 5-20 like the others."""

W_SUBSTEP_S = 1.0
"""Explicit Euler substep of the door NLP's moisture balance [s] (time constant m_air / mdot_bl >= 20 s)."""

W_SMOOTH_K = 1e5
"""Sharpness of the smooth max of the coil's condensation [1/(kg/kg)]: error <= ln 2 / k = 0.007 g/kg."""

_STATE_BOUNDS_C = (-50.0, 150.0)
"""Box on the temperature states of the multiple-shooting NLP [degC] (never active; keeps IPOPT's
iterates in the model's range)."""


@dataclasses.dataclass
class Evaluation:
    """Cost terms and predicted trajectories at one primal point."""

    J_e: float
    """Energy term [kJ]."""
    J_c: float
    """Comfort terms: gamma sum PMV^2 Ts and the draught penalty [kJ-equivalent]."""
    J_i: float
    """IOCH term [kJ-equivalent]."""
    J_s: float
    """Exact-penalty slack term [kJ-equivalent]."""
    J_du: float
    """Move penalty [kJ-equivalent]."""
    pmv: np.ndarray
    """Predicted PMV on the N + 1 grid points [-]."""
    t_cab: np.ndarray
    """Predicted cabin air temperature on the grid [degC]."""
    t_ain: np.ndarray
    """Predicted vent air temperature on the grid [degC]."""
    t_evap: np.ndarray
    """Predicted evaporator wall temperature at grid points 1..N [degC]."""
    co2: np.ndarray
    """Predicted cabin CO2 at grid points 1..N [ppm] (the door NLP; empty otherwise)."""
    fog: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    """Predicted fog margin at grid points 1..N [K] (the door NLP; empty otherwise)."""
    w_cab: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    """Predicted cabin humidity ratio at grid points 1..N [kg/kg] (the door NLP; empty otherwise)."""
    fog_row: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    """The fog rows' values at grid points 1..N, >= 0 where the margin meets the NLP's bound [K near the bound]
    (the door NLP; empty otherwise)."""


@dataclasses.dataclass
class NlpProblem:
    """One transcribed NLP: the CasADi expressions, their bounds and the named layout."""

    settings: StrategySettings
    """The strategy settings the problem was built from (solver 'auto' choices resolved)."""
    transcription: str
    """'single-shooting' or 'multiple-shooting'."""
    model_params: cm.ControlModelParams
    """The control-oriented model's parameters."""
    n_sub: int
    """Model steps per control period."""
    nlp: dict
    """CasADi NLP: {'x': w, 'p': p, 'f': J, 'g': g}."""
    params: ParamLayout
    """Named slices of p."""
    vars: VariableLayout
    """Stage-wise blocks of w."""
    rows: RowLayout
    """Stage-wise blocks of g."""
    lbw: np.ndarray
    ubw: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    evaluator: casadi.Function
    """(w, p) -> cost terms and trajectories (:meth:`evaluate`)."""
    rollout: casadi.Function
    """(u_0..u_{N-1} stacked, p) -> the augmented states x_1..x_N stacked (:meth:`rollout_states`)."""
    limits: ActuatorLimits = ACTUATOR_LIMITS
    """Hard actuator bounds on u."""
    compiled: dict = dataclasses.field(default_factory=dict, repr=False)
    """Compiled NLP functions per (plugin, flags): path or None (filled by the solver builder)."""

    def __post_init__(self) -> None:
        self._evaluator = BufferedFunction(self.evaluator)
        self._rollout = BufferedFunction(self.rollout)
        # the constant bounds as CasADi matrices, converted once (not on every solve: ~0.1 ms)
        self.bounds_dm = {
            "lbx": casadi.DM(self.lbw),
            "ubx": casadi.DM(self.ubw),
            "lbg": casadi.DM(self.lbg),
            "ubg": casadi.DM(self.ubg),
        }

    def use_compiled(self, evaluator: casadi.Function, rollout: casadi.Function) -> None:
        """:meth:`evaluate` and :meth:`rollout_states` by compiled copies of :attr:`evaluator` and :attr:`rollout`.

        The copies are the same expressions in C (``casadi.external`` of the SQP's compiled object, which the SQP's
        builder generates from these Functions): with flags that keep IEEE arithmetic as written (the default ``-O1``;
        not ``-ffast-math``, nor a target that fuses multiply-adds) equal to the bit on random points
        (``tests/test_nmpc.py::test_codegen_compiles_once_and_matches_in_process``, ``-O0``) and in SC03's closed loops
        (``-O1``, docs/controller.md 4.6), about 3x faster than CasADi's virtual machine.
        """
        for mine, theirs in ((self.evaluator, evaluator), (self.rollout, rollout)):
            if (mine.name_in(), mine.name_out()) != (theirs.name_in(), theirs.name_out()):
                raise ValueError(f"NlpProblem.use_compiled: {theirs.name()} does not match {mine.name()}")
        self._evaluator = BufferedFunction(evaluator)
        self._rollout = BufferedFunction(rollout)

    @property
    def horizon_steps(self) -> int:
        """N [steps]."""
        return self.params.n_grid - 1

    @property
    def door(self) -> bool:
        """Whether the door is an input of this NLP (``door_control`` 'nlp')."""
        return self.params.door

    @property
    def nu(self) -> int:
        """Inputs per stage: 2, 3 with the door."""
        return self.vars.width("u")

    @property
    def nx(self) -> int:
        """Augmented states per stage: 4, 7 with the door."""
        return 2 + self.nu + (2 if self.door else 0)

    @property
    def nw(self) -> int:
        """Number of variables."""
        return self.vars.n

    @property
    def ng(self) -> int:
        """Number of constraint rows."""
        return self.rows.n

    def evaluate(self, w: np.ndarray, p: np.ndarray) -> Evaluation:
        """Cost terms and predicted trajectories of a primal point."""
        out = self._evaluator(w, p)
        return Evaluation(
            J_e=float(out[0][0]),
            J_c=float(out[1][0]),
            J_i=float(out[2][0]),
            J_s=float(out[3][0]),
            J_du=float(out[4][0]),
            pmv=out[5].copy(),
            t_cab=out[6].copy(),
            t_ain=out[7].copy(),
            t_evap=out[8].copy(),
            co2=out[9].copy(),
            fog=out[10].copy(),
            w_cab=out[11].copy(),
            fog_row=out[12].copy(),
        )

    def rollout_states(self, u: np.ndarray, p: np.ndarray) -> np.ndarray:
        """The augmented states x_1..x_N the model gives from the measured state under inputs ``u`` (N, nu).

        Shape (N, nx): (T_cab, T_evap [degC], mdot_bl [kg/s], T_evap_sp [degC]) after each stage; with the door
        (N, 7): then the share [-], the cabin CO2 [:data:`CO2_SCALE_PPM`] and humidity ratio [g/kg].
        """
        (x,) = self._rollout(np.asarray(u, float).ravel(), p)
        return x.reshape(self.horizon_steps, self.nx).copy()

    def ocp_structure(self) -> OcpStructure | None:
        """The stage structure of the multiple-shooting NLP as HPIPM reads it (None for single shooting).

        Stage i (i = 0..N) holds x_i (4 states for i >= 1, none at i = 0 where the state is a
        parameter), then its controls: u_i (i < N) and the slacks s_i; its rows are its gap rows
        (x_{i+1} - f(x_i, u_i), i < N), then its comfort and T_evap rows. A last stage N + 1 without
        states, controls or rows closes the horizon (the slacks s_N are controls of stage N).
        """
        if self.transcription != "multiple-shooting":
            return None
        n, vl = self.horizon_steps, self.vars
        starts = [0, *vl.starts("x").tolist(), self.nw]
        nx = [0] + [vl.width("x")] * n + [0]
        nu = [starts[i + 1] - starts[i] - nx[i] for i in range(n + 1)] + [0]
        rr = self.rows.rows
        ng = [
            len(rr["pmv"][i])
            + (len(rr["evap"][i - 1]) if i >= 1 else 0)
            + (len(rr["co2"][i - 1]) if i >= 1 and rr["co2"] else 0)
            + (len(rr["fog"][i - 1]) if i >= 1 and rr["fog"] else 0)
            for i in range(n + 1)
        ] + [0]
        return OcpStructure(tuple(nx), tuple(int(v) for v in nu), tuple(ng))

    def plan(self, w: np.ndarray) -> np.ndarray:
        """The input sequence u_0..u_{N-1} of a primal point, shape (N, nu) (nu = 3 with the door)."""
        return self.vars.blocks(w, "u")

    def max_violation(self, w: np.ndarray, g: np.ndarray) -> float:
        """Largest violation of the variable bounds and the constraint bounds at (w, g(w))."""
        v = max(float(np.max(self.lbw - w, initial=0.0)), float(np.max(w - self.ubw, initial=0.0)))
        if g.size:
            v = max(v, float(np.max(self.lbg - g, initial=0.0)), float(np.max(g - self.ubg, initial=0.0)))
        return v


def build_problem(
    settings: StrategySettings,
    model_params: cm.ControlModelParams,
    comfort_params: ComfortParams,
    transcription: str,
    limits: ActuatorLimits = ACTUATOR_LIMITS,
) -> NlpProblem:
    """Transcribe the strategy's NLP (docs/controller.md 4.1).

    Args:
        settings: validated strategy settings (horizon, weights, bounds).
        model_params: the identified control-oriented model.
        comfort_params: the NLP's PMV parameters (met, clo, smoothing with the NLP's Newton steps).
        transcription: 'single-shooting' or 'multiple-shooting'.
        limits: the hard actuator bounds.
    """
    if transcription not in TRANSCRIPTIONS:
        raise ValueError(f"transcription must be one of {TRANSCRIPTIONS}, got {transcription!r}")
    s, mp, cp = settings, model_params, comfort_params
    n = s.nlp_steps  # the preview horizon Np plus the extension (held previews)
    n_sub = cm.substeps(mp, s.control_period_s)
    ts_kj = s.control_period_s / 1000.0  # W -> kJ over one control period
    SX = casadi.SX
    inf = np.inf

    door = s.door_control == "nlp"
    nu = 3 if door else 2
    nx = 2 + nu + (2 if door else 0)
    i_co2, i_w = 2 + nu, 3 + nu  # the door NLP's CO2 and humidity states
    params = ParamLayout(n + 1, door=door)
    P, p = params.symbols(SX.sym)
    vars_ = VariableLayout()
    rows = RowLayout()
    w: list = []

    def add_var(sym, lo, hi, key):
        vars_.add(key, sym.numel(), lo, hi)
        w.append(sym)

    e_terms, c_terms, i_terms, sl_terms, du_terms = [], [], [], [], []
    pmv_all, tcab_all, tain_all, tevap_all, co2_all, fog_all, wcab_all, fogrow_all = ([] for _ in range(8))
    if door:
        # the fog row in vapour pressure: T_glass - T_dp(p_w) >= M  <=>  p_w <= p_ws(T_glass - M) (T_dp rises with
        # p_w), divided by the saturation curve's slope there [Pa/K] so that its slack is in kelvin near the bound;
        # both depend on parameters only (the dew point's Newton steps on the variables cost 3 ms a solve)
        t_fog = P["t_glass"] - P["fog_min"]
        p_w_fog_max = psychro.saturation_vapour_pressure_pa(t_fog)
        p_w_per_k = psychro.saturation_vapour_pressure_pa(t_fog + 0.5) - psychro.saturation_vapour_pressure_pa(
            t_fog - 0.5
        )

    # Augmented state x_i = (T_cab, T_evap, mdot_{i-1}, sp_{i-1}): the move penalty and the comfort at
    # the last grid point (which uses u_{N-1}) stay stage-local, so the multiple-shooting NLP has the
    # exact optimal-control structure (needed by fatrop, harmless for IPOPT). Single shooting: x_i is
    # the model's rollout expression of (x_0, u_0..u_{i-1}), no state variables, no gap constraints.
    single = transcription == "single-shooting"

    def stage_step(x, u, i):
        """One model step over interval i: (T_cab, T_evap) at its end and the interval's powers."""
        t_cab_n, t_evap_n, _, pc, pb = cm.step(
            mp,
            x[0],
            x[1],
            u[0],
            u[1],
            P["t_int"],
            P["t_shell"],
            P["t_amb"][i],
            P["speed"][i],
            n_sub=n_sub,
            d_cab_k=P["d_cab"] / n_sub,
            d_ain_k=P["d_ain"],
            d_evap_k=P["d_evap"] / n_sub,
            recirc_share=u[2] if door else P["recirc"],
        )
        return t_cab_n, t_evap_n, pc, pb

    def co2_step(x, u, i):
        """The cabin CO2 at the end of interval i [ppm] (door NLP): the exact balance with the flows held."""
        leak = leakage_kgps(P["leak_0"], P["leak_v"], P["speed"][i])
        fresh = (1.0 - u[2]) * u[0]
        c_ppm = co2_after_ppm(
            x[i_co2] * CO2_SCALE_PPM, P["co2_amb"], fresh, leak, P["co2_gen"], P["m_air"], s.control_period_s
        )
        return c_ppm / CO2_SCALE_PPM

    n_w = max(1, int(np.ceil(s.control_period_s / W_SUBSTEP_S - 1e-9)))

    def w_step(x, u, t_evap_end, i):
        """The cabin humidity ratio at the end of interval i [g/kg] (door NLP).

        The plant's water balance and coil (``ceco_core.air_quality``: ``cabin_water_flows_kgps``,
        ``coil_outlet_humidity_ratio``), the wall at the interval's mean evaporator temperature, the flows held,
        ``n_w`` explicit Euler steps.
        """
        r, mdot = u[2], u[0]
        fresh = (1.0 - r) * mdot + leakage_kgps(P["leak_0"], P["leak_v"], P["speed"][i])
        w_amb = P["w_amb"] * W_SCALE_KGKG
        w_sw = psychro.humidity_ratio(0.5 * (x[1] + t_evap_end), 1.0)
        gen = P["w_gen"] * W_SCALE_KGKG
        dt = s.control_period_s / n_w
        w = x[i_w] * W_SCALE_KGKG
        for _ in range(n_w):
            w_mix = r * w + (1.0 - r) * w_amb
            w_out = coil_outlet_humidity_ratio(
                w_mix, w_sw, mp.moist_coil_bypass_factor, lambda a, b: smooth_max(a, b, W_SMOOTH_K)
            )
            f = cabin_water_flows_kgps(w, w_amb, w_mix, w_out, fresh, mdot, gen)
            w = w + dt * (f.into - f.out - f.condensate) / P["m_air"]
        return w / W_SCALE_KGKG

    def x_start():
        """x_0: the measured state and the previous command (and the CO2 estimate), all parameters."""
        if door:
            return casadi.vertcat(P["x0"], P["u_prev"], P["co2_0"] / CO2_SCALE_PPM, P["w_0"])
        return casadi.vertcat(P["x0"], P["u_prev"])

    def x_after(x, u, i):
        """The augmented state at the end of interval i and the interval's powers."""
        t_cab_n, t_evap_n, pc, pb = stage_step(x, u, i)
        parts = [t_cab_n, t_evap_n, u] + ([co2_step(x, u, i), w_step(x, u, t_evap_n, i)] if door else [])
        return casadi.vertcat(*parts), pc, pb

    x_next = None
    for i in range(n + 1):
        if i == 0:
            x = x_start()  # the initial state is a parameter, not a variable
        elif single:
            x = x_next
        else:
            assert x_next is not None  # (set by stage i - 1)
            x = SX.sym(f"x_{i}", nx)
            x_lo = [_STATE_BOUNDS_C[0]] * 2 + [-inf] * nu + ([0.0, 0.0] if door else [])
            add_var(x, x_lo, [_STATE_BOUNDS_C[1]] * 2 + [inf] * (nx - 2), "x")
            rows.add(i - 1, 0, "gap", x - x_next, [0.0] * nx, [0.0] * nx)
        if i < n:
            u = SX.sym(f"u_{i}", nu)
            add_var(
                u,
                [limits.mdot_bl_min_kgps, limits.t_evap_sp_min_c] + ([0.0] if door else []),
                [limits.mdot_bl_max_kgps, limits.t_evap_sp_max_c] + ([1.0] if door else []),
                "u",
            )
            # one model step over interval i: the next state and the interval's power
            x_next, pc, pb = x_after(x, u, i)
            e_terms.append(ts_kj * (pc + pb))
            du_parts = [
                (u[0] - x[2]) / (limits.mdot_bl_max_kgps - limits.mdot_bl_min_kgps),
                (u[1] - x[3]) / (limits.t_evap_sp_max_c - limits.t_evap_sp_min_c),
            ]
            if door:  # the door's move over its full range 0..1, weighted like the others
                du_parts.append(u[2] - x[4])
            du_terms.append(s.du_weight_kj * casadi.sumsqr(casadi.vertcat(*du_parts)))
        else:
            u = x[2 : 2 + nu]  # u_{N-1}, carried in the state
        # comfort at stage i
        tain = cm.t_ain_c(mp, x[1], u[0], P["d_ain"])
        pmv = cabin_pmv(
            t_cab_c=x[0],
            t_vent_c=tain,
            mdot_bl_kgps=u[0],
            t_mr_c=P["t_mr"],
            w_rad_wm2=cabin_w_rad_wm2(P["solar"][i], cp),
            pa_pa=P["pa"],
            params=cp,
        )
        pmv_all.append(pmv)
        tcab_all.append(x[0])
        tain_all.append(tain)
        s_lo = SX.sym(f"s_lo_{i}")
        s_up = SX.sym(f"s_up_{i}")
        add_var(s_lo, 0.0, inf, "s_lo")
        add_var(s_up, 0.0, inf, "s_up")
        sl_terms.append(s.slack_weight_kj * (s_lo + s_up))
        eps: object = 0.0
        if s.ioch:
            eps_sym = SX.sym(f"eps_{i}")
            add_var(eps_sym, 0.0, s.eps_ub, "eps")
            eps = eps_sym
            eta = cm.eta_ac(mp, P["speed"][i])
            i_terms.append(ts_kj * s.beta_w * (eta - 1.0) / (eps_sym + s.xi))
        rows.add(
            i,
            1,
            "pmv",
            casadi.vertcat(pmv + s_lo - P["pmv_lb"][i], pmv - s_up + eps - (P["pmv_ub"][i] - s.pmv_margin)),
            [0.0, -inf],
            [inf, 0.0],
        )
        if s.gamma_w > 0:
            c_terms.append(ts_kj * s.gamma_w * pmv**2)
        if s.draught_weight_kj > 0:
            dr = cabin_draught_pct(t_cab_c=x[0], t_vent_c=tain, mdot_bl_kgps=u[0], params=cp, cap=False)
            c_terms.append(s.draught_weight_kj * (dr / 100.0) ** 2)
        if i >= 1:
            tevap_all.append(x[1])
            s_ev = SX.sym(f"s_ev_{i}")
            add_var(s_ev, 0.0, inf, "s_ev")
            sl_terms.append(s.slack_weight_kj * s_ev)
            rows.add(
                i,
                2,
                "evap",
                casadi.vertcat(x[1] + s_ev - s.t_evap_lb_c, x[1] - s_ev - s.t_evap_ub_c),
                [0.0, -inf],
                [inf, 0.0],
            )
            if door:  # the soft CO2 limit and the soft fog margin, exact L1 penalties (docs/controller.md 4.9)
                co2_all.append(x[i_co2] * CO2_SCALE_PPM)
                s_co2 = SX.sym(f"s_co2_{i}")
                add_var(s_co2, 0.0, inf, "s_co2")
                sl_terms.append(s.co2_slack_weight_kj_per_ppm * CO2_SCALE_PPM * s_co2)
                rows.add(i, 3, "co2", x[i_co2] - s_co2 - P["co2_max"] / CO2_SCALE_PPM, [-inf], [0.0])
                w_kgkg = x[i_w] * W_SCALE_KGKG
                p_w = psychro.vapour_pressure_from_humidity_ratio_pa(w_kgkg)
                fog_all.append(fog_margin_k(P["t_glass"], p_w))  # the true margin (evaluator, diagnostics)
                wcab_all.append(w_kgkg)
                fog_row = (p_w_fog_max - p_w) / p_w_per_k  # >= 0 <=> margin >= bound (K near the bound)
                fogrow_all.append(fog_row)
                s_fog = SX.sym(f"s_fog_{i}")
                add_var(s_fog, 0.0, inf, "s_fog")
                sl_terms.append(s.fog_slack_weight_kj_per_k * s_fog)
                rows.add(i, 4, "fog", fog_row + s_fog, [0.0], [inf])

    def total(terms):
        return casadi.sum1(casadi.vertcat(*terms)) if terms else SX(0)

    J_e, J_c, J_i, J_s, J_du = (total(t) for t in (e_terms, c_terms, i_terms, sl_terms, du_terms))
    J = J_e + J_c + J_i + J_s + J_du
    g, lbg, ubg = rows.finalize()
    w_all = casadi.vertcat(*w)
    g_all = casadi.vertcat(*g)
    # the model's rollout from the measured state under given inputs (the warm start's states)
    u_seq = SX.sym("u_seq", nu * n)
    x_roll, xr = [], x_start()
    for i in range(n):
        xr, _, _ = x_after(xr, u_seq[nu * i : nu * i + nu], i)
        x_roll.append(xr)
    rollout = casadi.Function("ceco_rollout", [u_seq, p], [casadi.vertcat(*x_roll)], ["u", "p"], ["x"])
    evaluator = casadi.Function(
        "ceco_eval",
        [w_all, p],
        [
            J_e,
            J_c,
            J_i,
            J_s,
            J_du,
            casadi.vertcat(*pmv_all),
            casadi.vertcat(*tcab_all),
            casadi.vertcat(*tain_all),
            casadi.vertcat(*tevap_all),
            casadi.vertcat(*co2_all) if co2_all else SX(0, 1),
            casadi.vertcat(*fog_all) if fog_all else SX(0, 1),
            casadi.vertcat(*wcab_all) if wcab_all else SX(0, 1),
            casadi.vertcat(*fogrow_all) if fogrow_all else SX(0, 1),
        ],
        ["w", "p"],
        ["J_e", "J_c", "J_i", "J_s", "J_du", "pmv", "t_cab", "t_ain", "t_evap", "co2", "fog", "w_cab", "fog_row"],
    )
    return NlpProblem(
        settings=settings,
        transcription=transcription,
        model_params=mp,
        n_sub=n_sub,
        nlp={"x": w_all, "p": p, "f": J, "g": g_all},
        params=params,
        vars=vars_,
        rows=rows,
        lbw=vars_.lb,
        ubw=vars_.ub,
        lbg=np.array(lbg),
        ubg=np.array(ubg),
        evaluator=evaluator,
        rollout=rollout,
        limits=limits,
    )
