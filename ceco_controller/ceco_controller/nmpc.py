"""CECO nonlinear MPC (CasADi): ceco, ceco-e, ceco-c, ceco-ioch.

The NLP (written out in docs/controller.md) is built once per controller,
parametric in the initial state, the held interior/shell temperatures, the
bias estimates, the previous command, the weather and speed previews and the
PMV bounds; it is re-solved every control period, warm-started from the
shifted previous primal-dual solution, and bounded in iterations and CPU time.

Transcription (``SolverSettings.transcription``, default 'auto'): single
shooting up to Np = 12 (the states are the model's rollout expressions of the
inputs), multiple shooting beyond, with stage-wise variable order so the
problem has the optimal-control structure that IPOPT's sparse linear algebra
and fatrop exploit:

    w = [u_0, s_0, x_1, u_1, s_1, ..., x_N, s_N]   (x_0 is the measured state, a parameter;
                                                    single shooting: no x_i)
    x_i = (T_cab, T_evap [degC], mdot_{i-1} [kg/s], T_evap_sp_{i-1} [degC]),
    u_i = (mdot_bl [kg/s], T_evap_sp [degC])
    s_i = (s_lo, s_up [PMV], s_ev [K] (i >= 1), eps [PMV] (ceco-ioch))

Solvers (``SolverSettings.name``): warm ``sqpmethod`` (default: exact Hessian,
eigen-clip, dense qpOASES) or fatrop, with IPOPT doing the cold solves and
retrying at once any warm solve they fail (``n_ipopt_fallbacks``); or warm IPOPT.

Fallbacks: a failed or invalid solve applies the previous plan shifted by
one step; with no plan left, or no usable measurement, the production
ACC law (run alongside so its integrator is warm) is applied. Every command
is validated against the hard actuator bounds before it is returned.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import hashlib
import io
import logging
import math
import os
import pathlib
import shutil
import subprocess
import tempfile
import time

import casadi
import numpy as np

from ceco_core.acc_law import AccLaw, AccSettings
from ceco_core import psychro
from ceco_core.cabin_comfort import (
    PAPER_PA_PA,
    ComfortParams,
    cabin_draught_pct,
    cabin_mrt_c,
    cabin_pmv,
    cabin_w_rad_wm2,
)
from ceco_core.contracts import AcInput

from . import model as cm
from ceco_core.contracts import ACTUATOR_LIMITS, Diagnostics, Observation
from .strategies import StrategySettings, auto_solver_name, resolve_auto, strategy_settings

__all__ = ["NmpcController", "NlpData", "codegen_cache_dir", "compile_nlp"]

_LOG = logging.getLogger(__name__)

_BOUND_TOL = 1e-6
"""Numerical tolerance on the solver's actuator bounds [same unit]: within it a
command is clipped to the bound; beyond it the solve counts as failed."""

_SLACK_GUESS_MARGIN = 1e-5
"""Margin of the guessed comfort/T_evap slacks above their smallest feasible value [PMV or K]: near
the warm solver's barrier (slack x multiplier ~ 1e-5 x rho); 1e-3 started the warm solves with a
complementarity of ~1 and cost one IPOPT iteration (docs/controller.md 4.6)."""

_N_P_FIXED = 9
"""Scalar parameters before the per-stage ones (x0[2], t_int, t_shell, d_cab, d_evap, d_ain, u_prev[2]).
After the per-stage ones come the comfort scalars t_mr [degC] and p_a [Pa] (``_N_P_COMFORT``)."""

_N_P_COMFORT = 2
"""Scalar parameters after the per-stage ones: the mean radiant temperature and the vapour pressure."""


@dataclasses.dataclass
class NlpData:
    """The numeric data of one NLP instance (for benchmarks and tests)."""

    p: np.ndarray
    """Parameter vector."""
    x0: np.ndarray
    """Primal initial guess."""
    lam_x0: np.ndarray | None = None
    """Initial guess of the bound multipliers."""
    lam_g0: np.ndarray | None = None
    """Initial guess of the constraint multipliers."""


class NmpcController:
    """One CECO strategy as a receding-horizon controller.

    Args:
        strategy: a name (``ceco``, ``ceco-e``, ``ceco-c``, ``ceco-ioch``) or
            a :class:`StrategySettings`.
        model_params: identified :class:`ControlModelParams` (default: the file).
        comfort_params: :class:`ComfortParams` (met/clo of the occupant inside).
        acc_settings: settings of the fallback ACC law.
    """

    def __init__(self, strategy: str | StrategySettings = "ceco",
                 model_params: cm.ControlModelParams | None = None,
                 comfort_params: ComfortParams | None = None,
                 acc_settings: AccSettings | None = None):
        settings = strategy_settings(strategy) if isinstance(strategy, str) else strategy
        settings.validate()
        self.settings = resolve_auto(settings)
        """The settings with the solver's 'auto' choices resolved (concrete name and transcription)."""
        self.model_params = model_params if model_params is not None else cm.load_params()
        self.model_params.validate()
        self.comfort_params = comfort_params if comfort_params is not None else ComfortParams()
        self.comfort_params.validate()
        # the NLP's PMV: the same function as the plant's, with settings.pmv_newton_steps on T_cl
        self._nlp_comfort_params = dataclasses.replace(
            self.comfort_params, smoothing=dataclasses.replace(self.comfort_params.smoothing,
                                                               newton_steps=self.settings.pmv_newton_steps))
        self.n_sub = cm.substeps(self.model_params, self.settings.control_period_s)
        self.transcription = self.settings.solver.transcription
        """The NLP transcription built: 'single-shooting' or 'multiple-shooting'."""
        self.lim = ACTUATOR_LIMITS
        self._acc = AccLaw(acc_settings)
        self._build()
        self.reset()

    # ------------------------------------------------------------------ build
    def _build(self) -> None:
        s, mp, cp = self.settings, self.model_params, self._nlp_comfort_params
        n = s.horizon_steps
        ts_kj = s.control_period_s / 1000.0  # W -> kJ over one control period
        lim = self.lim
        SX = casadi.SX

        x0p = SX.sym("x0", 2)
        t_int = SX.sym("t_int")
        t_shell = SX.sym("t_shell")
        d_cab = SX.sym("d_cab")
        d_evap = SX.sym("d_evap")
        d_ain = SX.sym("d_ain")
        u_prev = SX.sym("u_prev", 2)
        t_amb = SX.sym("t_amb", n + 1)
        solar = SX.sym("solar", n + 1)
        speed = SX.sym("speed", n + 1)
        lb_pmv = SX.sym("pmv_lb", n + 1)
        ub_pmv = SX.sym("pmv_ub", n + 1)
        t_mr = SX.sym("t_mr")
        pa = SX.sym("pa_pa")
        p = casadi.vertcat(x0p, t_int, t_shell, d_cab, d_evap, d_ain, u_prev, t_amb, solar, speed,
                           lb_pmv, ub_pmv, t_mr, pa)
        assert p.numel() == _N_P_FIXED + 5 * (n + 1) + _N_P_COMFORT

        w, lbw, ubw = [], [], []
        g, lbg, ubg = [], [], []
        idx = {"x": [], "u": [], "s_lo": [], "s_up": [], "s_ev": [], "eps": []}
        e_terms, c_terms, i_terms, sl_terms, du_terms = [], [], [], [], []
        pmv_all, tcab_all, tain_all, tevap_all = [], [], [], []
        inf = np.inf

        cons = []  # (stage, order, kind, expr, lo, hi); sorted so each stage starts with its gap constraint

        def add_con(stage, order, kind, expr, lo, hi):
            cons.append((stage, order, len(cons), kind, expr, lo, hi))

        def add_var(sym, lo, hi, key):
            idx[key].append(sum(v.numel() for v in w))
            w.append(sym)
            lbw.extend(np.atleast_1d(lo).tolist())
            ubw.extend(np.atleast_1d(hi).tolist())

        # Augmented state x_i = (T_cab, T_evap, mdot_{i-1}, sp_{i-1}): the move penalty and the comfort at
        # the last grid point (which uses u_{N-1}) stay stage-local, so the multiple-shooting NLP has the
        # exact optimal-control structure (needed by fatrop, harmless for IPOPT). Single shooting: x_i is
        # the model's rollout expression of (x_0, u_0..u_{i-1}), no state variables, no gap constraints.
        single = self.transcription == "single-shooting"
        x_next = None
        for i in range(n + 1):
            if i == 0:
                x = casadi.vertcat(x0p, u_prev)  # the initial state is a parameter, not a variable
            elif single:
                x = x_next
            else:
                x = SX.sym(f"x_{i}", 4)
                add_var(x, [-50.0, -50.0, -inf, -inf], [150.0, 150.0, inf, inf], "x")
                add_con(i - 1, 0, "gap", x - x_next, [0.0] * 4, [0.0] * 4)
            if i < n:
                u = SX.sym(f"u_{i}", 2)
                add_var(u, [lim.mdot_bl_min_kgps, lim.t_evap_sp_min_c],
                        [lim.mdot_bl_max_kgps, lim.t_evap_sp_max_c], "u")
                # one model step over interval i: the next state and the interval's power
                t_cab_n, t_evap_n, _, pc, pb = cm.step(
                    mp, x[0], x[1], u[0], u[1], t_int, t_shell, t_amb[i], speed[i], n_sub=self.n_sub,
                    d_cab_k=d_cab / self.n_sub, d_ain_k=d_ain, d_evap_k=d_evap / self.n_sub)
                x_next = casadi.vertcat(t_cab_n, t_evap_n, u)
                e_terms.append(ts_kj * (pc + pb))
                du = casadi.vertcat((u[0] - x[2]) / (lim.mdot_bl_max_kgps - lim.mdot_bl_min_kgps),
                                    (u[1] - x[3]) / (lim.t_evap_sp_max_c - lim.t_evap_sp_min_c))
                du_terms.append(s.du_weight_kj * casadi.sumsqr(du))
            else:
                u = x[2:4]  # u_{N-1}, carried in the state
            # comfort at stage i
            tain = cm.t_ain_c(mp, x[1], u[0], d_ain)
            pmv = cabin_pmv(t_cab_c=x[0], t_vent_c=tain, mdot_bl_kgps=u[0], t_mr_c=t_mr,
                            w_rad_wm2=cabin_w_rad_wm2(solar[i], cp), pa_pa=pa, params=cp)
            pmv_all.append(pmv)
            tcab_all.append(x[0])
            tain_all.append(tain)
            s_lo = SX.sym(f"s_lo_{i}")
            s_up = SX.sym(f"s_up_{i}")
            add_var(s_lo, 0.0, inf, "s_lo")
            add_var(s_up, 0.0, inf, "s_up")
            sl_terms.append(s.slack_weight_kj * (s_lo + s_up))
            eps = 0.0
            if s.ioch:
                eps_sym = SX.sym(f"eps_{i}")
                add_var(eps_sym, 0.0, s.eps_ub, "eps")
                eps = eps_sym
                eta = cm.eta_ac(mp, speed[i])
                i_terms.append(ts_kj * s.beta_w * (eta - 1.0) / (eps_sym + s.xi))
            add_con(i, 1, "pmv", casadi.vertcat(pmv + s_lo - lb_pmv[i], pmv - s_up + eps - (ub_pmv[i] - s.pmv_margin)),
                    [0.0, -inf], [inf, 0.0])
            if s.gamma_w > 0:
                c_terms.append(ts_kj * s.gamma_w * pmv ** 2)
            if s.draught_weight_kj > 0:
                dr = cabin_draught_pct(t_cab_c=x[0], t_vent_c=tain, mdot_bl_kgps=u[0], params=cp, cap=False)
                c_terms.append(s.draught_weight_kj * (dr / 100.0) ** 2)
            if i >= 1:
                tevap_all.append(x[1])
                s_ev = SX.sym(f"s_ev_{i}")
                add_var(s_ev, 0.0, inf, "s_ev")
                sl_terms.append(s.slack_weight_kj * s_ev)
                add_con(i, 2, "evap", casadi.vertcat(x[1] + s_ev - s.t_evap_lb_c, x[1] - s_ev - s.t_evap_ub_c),
                        [0.0, -inf], [inf, 0.0])

        def total(terms):
            return casadi.sum1(casadi.vertcat(*terms)) if terms else SX(0)

        J_e, J_c, J_i, J_s, J_du = (total(t) for t in (e_terms, c_terms, i_terms, sl_terms, du_terms))
        J = J_e + J_c + J_i + J_s + J_du
        rows = {"gap": [], "pmv": [], "evap": []}
        r = 0
        for _, _, _, kind, expr, lo, hi in sorted(cons, key=lambda c: c[:3]):
            rows[kind].append(np.arange(r, r + expr.numel()))
            r += expr.numel()
            g.append(expr)
            lbg.extend(lo)
            ubg.extend(hi)
        self._grows = rows
        w_all = casadi.vertcat(*w)
        g_all = casadi.vertcat(*g)
        self._nw = w_all.numel()
        self._ng = g_all.numel()
        self._lbw = np.array(lbw)
        self._ubw = np.array(ubw)
        self._lbg = np.array(lbg)
        self._ubg = np.array(ubg)
        # the constant bounds as CasADi matrices, converted once (not on every solve: ~0.1 ms)
        self._bounds_dm = {"lbx": casadi.DM(self._lbw), "ubx": casadi.DM(self._ubw),
                           "lbg": casadi.DM(self._lbg), "ubg": casadi.DM(self._ubg)}
        self._idx = {k: np.array(v, dtype=int) for k, v in idx.items()}
        self._nlp = {"x": w_all, "p": p, "f": J, "g": g_all}
        self._np = p.numel()
        self._eval = casadi.Function(
            "ceco_eval", [w_all, p],
            [J_e, J_c, J_i, J_s, J_du, casadi.vertcat(*pmv_all), casadi.vertcat(*tcab_all),
             casadi.vertcat(*tain_all), casadi.vertcat(*tevap_all)],
            ["w", "p"], ["J_e", "J_c", "J_i", "J_s", "J_du", "pmv", "t_cab", "t_ain", "t_evap"])
        self._compiled: dict = {}  # codegen flags -> path of the compiled NLP functions (or None)
        ss = self.settings.solver
        self.solver = self.make_solver(ss)
        self.n_ipopt_fallbacks = 0
        """Warm sqpmethod/fatrop solves that failed and were retried with warm IPOPT (since construction)."""
        self.solver_fallback = None
        if ss.name != "ipopt" and ss.ipopt_fallback:
            # the default IPOPT path, same codegen: retries failed warm solves and does the cold ones
            ipopt_ss = dataclasses.replace(ss, name="ipopt")
            self.solver_fallback = self.make_solver(ipopt_ss)
            ss = ipopt_ss
        # cold solves (first step, after a failure): robust IPOPT settings, no warm start, on the
        # multiple-shooting NLP: from a cold guess single shooting is more nonlinear and IPOPT can stop
        # in a worse local optimum (sc03_mild k = 0: 2.3 % higher cost); its solution is mapped back
        self._cold_ctrl = self
        if self.transcription == "single-shooting":
            self._cold_ctrl = NmpcController(
                dataclasses.replace(self.settings, solver=dataclasses.replace(
                    ss, name="ipopt", transcription="multiple-shooting", warm_start=False)),
                self.model_params, self.comfort_params, self._acc.settings)
            self.solver_cold = self._cold_ctrl.solver
            ms_idx = self._cold_ctrl._idx
            self._cold_w_map = np.setdiff1d(np.arange(self._cold_ctrl._nw),
                                            np.concatenate([np.arange(j, j + 4) for j in ms_idx["x"]]))
            self._cold_g_map = np.setdiff1d(np.arange(self._cold_ctrl._ng),
                                            np.concatenate(self._cold_ctrl._grows["gap"]))
            assert self._cold_w_map.size == self._nw and self._cold_g_map.size == self._ng
        else:
            self.solver_cold = (self.make_solver(dataclasses.replace(ss, warm_start=False))
                                if ss.warm_start and ss.name == "ipopt"
                                else self.solver)
        """The cold solver (IPOPT): on the multiple-shooting NLP when this controller's is single shooting."""

    def make_solver(self, solver_settings) -> casadi.Function:
        """Build a CasADi nlpsol for this NLP with the given solver settings."""
        ss = solver_settings
        ss.validate()
        if ss.transcription not in ("auto", self.transcription):
            raise ValueError(f"SolverSettings.transcription {ss.transcription!r} does not match this controller's "
                             f"NLP ({self.transcription}); build another controller for it")
        if ss.name == "auto":
            ss = dataclasses.replace(ss, name=auto_solver_name(self.transcription))
        opts: dict = {"print_time": False}
        nlp = self._nlp
        if ss.codegen and ss.name in ("ipopt", "sqpmethod") and not ss.default_options:
            so = self._compiled_nlp(ss)
            if so is not None:
                nlp = so
        if ss.jit and not isinstance(nlp, str):
            opts.update({"jit": True, "compiler": "shell",
                         "jit_options": {"flags": ["-O2"], "verbose": False}})
        if ss.name == "ipopt":
            if ss.default_options:
                ipopt = {"print_level": 0, "sb": "yes"}
            else:
                ipopt = {
                    "print_level": 0, "sb": "yes",
                    "max_iter": ss.max_iter, "max_cpu_time": ss.max_cpu_time_s,
                    "tol": ss.tol, "acceptable_tol": min(ss.acceptable_tol, 1e-6), "acceptable_iter": 5,
                    "linear_solver": ss.linear_solver,
                    "hessian_approximation": "exact",
                    "mu_strategy": "adaptive", "mu_oracle": "quality-function",
                    "nlp_scaling_method": "gradient-based",
                }
                if ss.warm_start:
                    # warm-started re-solves start near the optimum: a small adaptive barrier, no
                    # gradient scaling, stop at the first point optimal to acceptable_tol with the
                    # constraints met to 1e-6 (measured fastest with the same optimum, docs/controller.md)
                    ipopt.update({"warm_start_init_point": "yes", "warm_start_bound_push": 1e-9,
                                  "warm_start_bound_frac": 1e-9, "warm_start_slack_bound_frac": 1e-9,
                                  "warm_start_slack_bound_push": 1e-9, "warm_start_mult_bound_push": 1e-9,
                                  "mu_init": 1e-5, "nlp_scaling_method": "none",
                                  "acceptable_tol": ss.acceptable_tol, "acceptable_iter": 1,
                                  "acceptable_constr_viol_tol": 1e-6, "acceptable_compl_inf_tol": 1e-4})
            opts["ipopt"] = ipopt
            if isinstance(nlp, str):
                try:
                    return casadi.nlpsol("ceco_nlp", "ipopt", nlp, opts)
                except RuntimeError as exc:  # unloadable object: the in-process functions
                    _LOG.warning("NMPC codegen: cannot load %s (%s); using the in-process NLP functions", nlp, exc)
                    nlp = self._nlp
            return casadi.nlpsol("ceco_nlp", "ipopt", nlp, opts)
        if ss.name == "fatrop":
            opts.update({"structure_detection": "auto", "expand": True,
                         "equality": [bool(a == b) for a, b in zip(self._lbg, self._ubg)],
                         "fatrop": {"print_level": 0, "max_iter": ss.max_iter, "tol": ss.tol,
                                    "mu_init": 1e-2}})
            # (fatrop 0.0.x in CasADi 3.8 accepts no warm-start option; the primal guess is still used)
            return casadi.nlpsol("ceco_nlp", "fatrop", self._nlp, opts)
        # sqpmethod: exact Hessian convexified (eigen-clip), one dense QP per iteration, line search;
        # bounded by sqp_max_iter SQP iterations and a CPU-time limit per QP (qpOASES). Like the warm IPOPT:
        # constraints met to tol (1e-6), stationarity to acceptable_tol (1e-4; 3 instead of 5 median
        # iterations on SC03 with the same optimum, docs/controller.md 4.6)
        if ss.qpsol == "qpoases":
            qp_opts = {"printLevel": "none", "sparse": False, "error_on_fail": False,
                       "CPUtime": ss.max_cpu_time_s / ss.sqp_max_iter}
        else:
            qp_opts = {"print_iter": False, "print_header": False, "error_on_fail": False}
        opts.update({"qpsol": ss.qpsol, "qpsol_options": qp_opts,
                     "max_iter": ss.sqp_max_iter, "print_iteration": False, "print_header": False,
                     "print_status": False, "tol_pr": ss.tol, "tol_du": ss.acceptable_tol if ss.warm_start else ss.tol,
                     "convexify_strategy": ss.convexify_strategy, "max_iter_eig": float(ss.max_iter_eig),
                     "error_on_fail": False})
        if isinstance(nlp, str):
            try:
                with _c_stdout_silenced():
                    return casadi.nlpsol("ceco_nlp", "sqpmethod", nlp, opts)
            except RuntimeError as exc:
                _LOG.warning("NMPC codegen: cannot load %s (%s); using the in-process NLP functions", nlp, exc)
                nlp = self._nlp
        with _c_stdout_silenced():
            return casadi.nlpsol("ceco_nlp", "sqpmethod", nlp, opts)

    def _compiled_nlp(self, ss) -> str | None:
        """Path of the compiled NLP functions for ``ss.codegen_flags`` (cached), or None (logged)."""
        key = (ss.name, tuple(ss.codegen_flags))
        if key not in self._compiled:
            self._compiled[key] = compile_nlp(self._nlp, ss.codegen_flags, ss.codegen_cache_dir, plugin=ss.name)
        return self._compiled[key]

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget the previous plan, the warm start and the bias estimates."""
        self._plan_u: np.ndarray | None = None  # (N, 2) of the last successful solve
        self._plan_age = 0
        self._warm: tuple | None = None  # (w, lam_x, lam_g)
        self._bias = np.zeros(3)  # d_cab [K per control step], d_evap [K per step], d_ain [K]
        self._last_pred: tuple | None = None  # (t_cab_next, t_evap_next) predicted w/o bias
        self._acc.reset()

    @property
    def horizon_steps(self) -> int:
        """Np [steps]."""
        return self.settings.horizon_steps

    # -------------------------------------------------------------- internals
    def _exogenous(self, obs: Observation):
        """Fill the previews: hold the last trusted value, else the measured current value."""
        n1 = self.settings.horizon_steps + 1
        if obs.n_preview != n1:
            raise ValueError(f"Observation previews have {obs.n_preview} points; this controller needs Np+1 = {n1}")
        series = {"t_amb": (obs.preview_t_amb_c, obs.t_amb_c), "solar": (obs.preview_solar_wm2, obs.solar_wm2),
                  "speed": (obs.preview_speed_mps, obs.speed_mps)}
        ok = np.asarray(obs.preview_valid, bool).copy()
        for arr, _ in series.values():
            ok &= np.isfinite(arr)
        trusted = int(np.argmin(ok)) if not ok.all() else n1
        out = {}
        for key, (arr, now) in series.items():
            a = np.empty(n1)
            if trusted > 0:
                a[:trusted] = arr[:trusted]
                a[trusted:] = arr[trusted - 1]
            else:
                a[:] = now
            out[key] = a
        if not self.settings.use_speed_preview:
            out["speed"] = np.full(n1, float(obs.speed_mps))
        out["speed"] = np.maximum(out["speed"], 0.0)
        out["solar"] = np.maximum(out["solar"], 0.0)
        return out, trusted

    def _update_bias(self, obs: Observation) -> None:
        s, mp = self.settings, self.model_params
        if not s.offset_free:
            return
        a, lim = s.bias_filter, s.bias_limit_k
        # vent air: measured vs model at the measured evaporator temperature and the applied flow
        e_ain = obs.t_vent_c - float(cm.t_ain_c(mp, obs.t_evap_c, obs.mdot_bl_prev_kgps))
        self._bias[2] = np.clip((1 - a) * self._bias[2] + a * e_ain, -lim, lim)
        if self._last_pred is not None:
            e_cab = obs.t_cab_c - self._last_pred[0]
            e_evap = obs.t_evap_c - self._last_pred[1]
            self._bias[0] = np.clip((1 - a) * self._bias[0] + a * e_cab, -lim, lim)
            self._bias[1] = np.clip((1 - a) * self._bias[1] + a * e_evap, -lim, lim)

    def _predict_unbiased(self, obs: Observation, mdot: float, sp: float, ex: dict) -> tuple:
        """One control period of the model without the T_cab/T_evap biases (for the next bias update)."""
        t_cab, t_evap, *_ = cm.step(self.model_params, obs.t_cab_c, obs.t_evap_c, mdot, sp, obs.t_int_c,
                                    obs.t_shell_c, ex["t_amb"][0], ex["speed"][0], n_sub=self.n_sub,
                                    d_ain_k=self._bias[2] if self.settings.offset_free else 0.0)
        return float(t_cab), float(t_evap)

    def parameters(self, obs: Observation, ex: dict) -> np.ndarray:
        """The NLP parameter vector for an observation (previews already filled)."""
        b = self._bias if self.settings.offset_free else np.zeros(3)
        return np.concatenate([
            [obs.t_cab_c, obs.t_evap_c, obs.t_int_c, obs.t_shell_c, b[0], b[1], b[2],
             obs.mdot_bl_prev_kgps, obs.t_evap_sp_prev_c],
            ex["t_amb"], ex["solar"], ex["speed"], obs.pmv_lb, obs.pmv_ub,
            self.comfort_parameters(obs)])

    def comfort_parameters(self, obs: Observation) -> np.ndarray:
        """The NLP's comfort scalars [t_mr (degC), p_a (Pa)] held over the horizon.

        t_mr: from the measured glazing, shell and interior temperatures
        (:func:`ceco_core.cabin_comfort.cabin_mrt_c`; T_int alone while the glazing is not
        measured). p_a: ``settings.pmv_pa_source`` ('paper': 1700 Pa; 'measured': RH x p_ws(T_cab),
        1700 Pa while the RH is not measured).
        """
        t_glass = obs.t_glass_c if math.isfinite(obs.t_glass_c) else obs.t_int_c
        t_mr = float(cabin_mrt_c(t_cab_c=obs.t_cab_c, t_int_c=obs.t_int_c, t_shell_c=obs.t_shell_c,
                                 t_glass_c=t_glass, params=self.comfort_params))
        pa = PAPER_PA_PA
        if self.settings.pmv_pa_source == "measured" and math.isfinite(obs.rh_cab) and 0.0 <= obs.rh_cab <= 1.0:
            pa = float(psychro.vapour_pressure_pa(obs.t_cab_c, obs.rh_cab))
        return np.array([t_mr, pa])

    def initial_guess(self, p: np.ndarray, w_prev: np.ndarray | None = None) -> np.ndarray:
        """Primal guess, consistent with the dynamics and the comfort constraints at ``p``.

        Inputs: the previous solution shifted by one stage if ``w_prev`` is given, else the
        previous command held. States (multiple shooting): rolled out by the model from the
        measured state (so the guess closes every gap). Slacks: the smallest values that satisfy the comfort and T_evap
        constraints at the guess (plus a small margin). ``eps`` (ioch): shifted, or eps_UB/2.
        """
        n = self.settings.horizon_steps
        if w_prev is not None:
            w = self._shift(w_prev)
        else:
            w = np.zeros(self._nw)
            u = np.array([np.clip(p[7], self.lim.mdot_bl_min_kgps, self.lim.mdot_bl_max_kgps),
                          np.clip(p[8], self.lim.t_evap_sp_min_c, self.lim.t_evap_sp_max_c)])
            for i in range(n):
                w[self._idx["u"][i]:self._idx["u"][i] + 2] = u
            if self.settings.ioch:
                w[self._idx["eps"]] = 0.5 * self.settings.eps_ub
        w = np.clip(w, self._lbw, self._ubw)
        off = _N_P_FIXED
        if self._idx["x"].size:  # multiple shooting: the states rolled out by the model
            x = p[0:2].copy()
            for i in range(n):
                u = w[self._idx["u"][i]:self._idx["u"][i] + 2]
                tc, te, *_ = cm.step(self.model_params, x[0], x[1], u[0], u[1], p[2], p[3], p[off + i],
                                     p[off + 2 * (n + 1) + i], n_sub=self.n_sub, d_cab_k=p[4] / self.n_sub,
                                     d_ain_k=p[6], d_evap_k=p[5] / self.n_sub)
                x = np.array([tc, te])
                j = self._idx["x"][i]
                w[j:j + 4] = np.concatenate([x, u])
        ev = self.evaluate(w, p)
        pmv = ev["pmv"]
        lb = p[off + 3 * (n + 1): off + 4 * (n + 1)]
        ub = p[off + 4 * (n + 1): off + 5 * (n + 1)] - self.settings.pmv_margin
        eps = w[self._idx["eps"]] if self.settings.ioch else 0.0
        margin = _SLACK_GUESS_MARGIN
        w[self._idx["s_lo"]] = np.maximum(lb - pmv, 0.0) + margin
        w[self._idx["s_up"]] = np.maximum(pmv + eps - ub, 0.0) + margin
        t_evap = ev["t_evap"]
        w[self._idx["s_ev"]] = np.maximum(np.maximum(self.settings.t_evap_lb_c - t_evap,
                                                     t_evap - self.settings.t_evap_ub_c), 0.0) + margin
        return np.clip(w, self._lbw, self._ubw)

    def _shift(self, vec: np.ndarray) -> np.ndarray:
        """Shift a stage-ordered primal (or bound-multiplier) vector one stage forward."""
        out = vec.copy()
        for key in ("x", "u", "s_lo", "s_up", "s_ev", "eps"):
            ix = self._idx[key]
            if ix.size == 0:
                continue
            width = {"x": 4, "u": 2}.get(key, 1)
            blocks = [vec[j:j + width] for j in ix]
            shifted = blocks[1:] + [blocks[-1]]
            for j, b in zip(ix, shifted):
                out[j:j + width] = b
        return out

    def _shift_g(self, lam_g: np.ndarray) -> np.ndarray:
        """Shift constraint multipliers one stage forward (per constraint kind; the last stage is kept)."""
        out = lam_g.copy()
        for blocks in self._grows.values():
            for a, b in zip(blocks[:-1], blocks[1:]):
                out[a] = lam_g[b]
        return out

    def solve_nlp(self, data: NlpData, solver: casadi.Function | None = None) -> dict:
        """Solve one NLP instance; return a dict with the solution, stats and wall time [ms]."""
        solver = solver or self.solver
        args = {"x0": data.x0, "p": data.p, **self._bounds_dm}
        if data.lam_x0 is not None:
            args["lam_x0"] = data.lam_x0
        if data.lam_g0 is not None:
            args["lam_g0"] = data.lam_g0
        t0 = time.perf_counter()
        sol = solver(**args)
        dt_ms = 1e3 * (time.perf_counter() - t0)
        try:
            stats = solver.stats()
        except RuntimeError as exc:  # CasADi 3.8.2 sqpmethod: no stats after an error in iteration 0
            last = (str(exc).splitlines() or [type(exc).__name__])[-1]
            stats = {"success": False, "return_status": f"no solver statistics ({last})"}
        return {"w": np.array(sol["x"]).ravel(), "f": float(sol["f"]),
                "lam_x": np.array(sol["lam_x"]).ravel(), "lam_g": np.array(sol["lam_g"]).ravel(),
                "stats": stats, "time_ms": dt_ms,
                "success": bool(stats.get("success", False)),
                "status": str(stats.get("return_status", "unknown")),
                "iterations": int(stats.get("iter_count", -1)) if "iter_count" in stats else None}

    def evaluate(self, w: np.ndarray, p: np.ndarray) -> dict:
        """Cost terms and predicted trajectories of a primal point."""
        out = self._eval(w, p)
        keys = ("J_e", "J_c", "J_i", "J_s", "J_du", "pmv", "t_cab", "t_ain", "t_evap")
        return {k: np.array(v).ravel() if k in ("pmv", "t_cab", "t_ain", "t_evap") else float(v)
                for k, v in zip(keys, out)}

    def last_nlp(self) -> NlpData | None:
        """The data of the last NLP solved by :meth:`compute` (for benchmarks)."""
        return getattr(self, "_last_nlp", None)

    # ---------------------------------------------------------------- compute
    def compute(self, obs: Observation):
        """One control step: returns ``(AcInput, Diagnostics)``; never raises on solver trouble."""
        s = self.settings
        diag = Diagnostics(k=obs.k, t_s=obs.t_s)
        acc_cmd = self._acc.step(obs.t_cab_c, s.control_period_s)  # keep the fallback law warm
        if not obs.measurements_finite():
            diag.status = "invalid_measurement"
            diag.success = False
            diag.message = "non-finite measurement: production ACC law applied"
            return self._fallback_baseline(diag, acc_cmd)
        ex, trusted = self._exogenous(obs)
        diag.trusted_horizon = trusted
        if trusted < obs.n_preview:
            diag.message = (f"preview valid for {trusted}/{obs.n_preview} points; "
                            + ("held last valid value" if trusted else "held measured values"))
        self._update_bias(obs)
        p = self.parameters(obs, ex)
        if s.solver.warm_start and self._warm is not None and not s.solver.default_options:
            data = NlpData(p=p, x0=self.initial_guess(p, self._warm[0]), lam_x0=self._shift(self._warm[1]),
                           lam_g0=self._shift_g(self._warm[2]))
        else:
            data = NlpData(p=p, x0=self.initial_guess(p))
        self._last_nlp = data
        warm = data.lam_g0 is not None
        res = self._try_solve(data, self.solver) if warm else self._cold_solve(data)
        if not res["success"] and self.solver_fallback is not None and warm:
            # sqpmethod/fatrop failed: the same instance with the warm IPOPT solver
            self.n_ipopt_fallbacks += 1
            first = res
            res = self._try_solve(data, self.solver_fallback)
            res["status"] = f"{s.solver.name}: {first['status']}; ipopt: {res['status']}"
            if first["time_ms"] is not None and res["time_ms"] is not None:
                res["time_ms"] += first["time_ms"]
            diag.message = (diag.message + "; " if diag.message else "") + \
                f"{s.solver.name} failed ({first['status']}): retried with IPOPT"
        diag.status = res["status"]
        diag.success = res["success"]
        diag.iterations = res["iterations"]
        diag.solve_time_ms = res["time_ms"]
        cmd = None
        if res["success"] and res["w"] is not None and np.all(np.isfinite(res["w"])):
            u = self._plan_from(res["w"])
            if self._valid_command(u[0]):
                cmd = u[0]
                self._plan_u, self._plan_age = u, 0
                self._warm = (res["w"], res["lam_x"], res["lam_g"])
                ev = self.evaluate(res["w"], p)
                diag.cost_energy, diag.cost_comfort, diag.cost_ioch = ev["J_e"], ev["J_c"], ev["J_i"]
                diag.cost_slack, diag.cost_total = ev["J_s"], res["f"]
                diag.pred_pmv, diag.pred_t_cab_c = ev["pmv"], ev["t_cab"]
                if s.ioch:
                    diag.eps = res["w"][self._idx["eps"]]
            else:
                diag.message = (diag.message + "; " if diag.message else "") + "solution outside actuator bounds"
        if cmd is None:
            self._warm = None
            if self._plan_u is not None and self._plan_age + 1 < len(self._plan_u):
                self._plan_age += 1
                cmd = self._plan_u[self._plan_age]
                diag.fallback = "shifted_plan"
                diag.message = (diag.message + "; " if diag.message else "") + \
                    f"solve failed ({diag.status}): plan of step k-{self._plan_age} applied"
            else:
                diag.message = (diag.message + "; " if diag.message else "") + \
                    f"solve failed ({diag.status}), no plan left: production ACC law applied"
                return self._fallback_baseline(diag, acc_cmd, obs, ex)
        cmd = self._clip_checked(cmd)
        self._last_pred = self._predict_unbiased(obs, cmd[0], cmd[1], ex)
        diag.mdot_bl_kgps, diag.t_evap_sp_c = float(cmd[0]), float(cmd[1])
        return AcInput(mdot_bl_kgps=float(cmd[0]), t_evap_sp_c=float(cmd[1])), diag

    def _cold_solve(self, data: NlpData) -> dict:
        """A cold solve of ``data`` (this controller's NLP) by ``solver_cold``, on the multiple-shooting
        NLP when this one is single shooting (guess: its model rollout; solution mapped back)."""
        cold = self._cold_ctrl
        if cold is self:
            return self._try_solve(data, self.solver_cold)
        res = cold._try_solve(NlpData(p=data.p, x0=cold.initial_guess(data.p)), self.solver_cold)
        if res["w"] is not None:
            res["w"] = res["w"][self._cold_w_map]
            res["lam_x"] = res["lam_x"][self._cold_w_map]
            res["lam_g"] = res["lam_g"][self._cold_g_map]
        return res

    def _try_solve(self, data: NlpData, solver: casadi.Function) -> dict:
        """:meth:`solve_nlp`, with CasADi evaluation errors returned as a failed result."""
        try:
            return self.solve_nlp(data, solver)
        except RuntimeError as exc:
            return {"success": False, "status": f"exception: {exc}", "iterations": None, "time_ms": None,
                    "w": None, "f": math.nan}

    def _plan_from(self, w: np.ndarray) -> np.ndarray:
        return np.array([w[j:j + 2] for j in self._idx["u"]])

    def _valid_command(self, u) -> bool:
        lim = self.lim
        return bool(np.all(np.isfinite(u))
                    and lim.mdot_bl_min_kgps - _BOUND_TOL <= u[0] <= lim.mdot_bl_max_kgps + _BOUND_TOL
                    and lim.t_evap_sp_min_c - _BOUND_TOL <= u[1] <= lim.t_evap_sp_max_c + _BOUND_TOL)

    def _clip_checked(self, u) -> np.ndarray:
        if not self._valid_command(u):
            raise AssertionError(f"internal error: command {u} outside the actuator bounds")
        lim = self.lim
        return np.array([min(max(u[0], lim.mdot_bl_min_kgps), lim.mdot_bl_max_kgps),
                         min(max(u[1], lim.t_evap_sp_min_c), lim.t_evap_sp_max_c)])

    def _fallback_baseline(self, diag: Diagnostics, acc_cmd, obs: Observation | None = None,
                           ex: dict | None = None):
        diag.fallback = "baseline"
        self._plan_u = None
        self._warm = None
        u = self._clip_checked(np.array([acc_cmd.mdot_bl_kgps, acc_cmd.t_evap_sp_c]))
        if obs is not None and ex is not None:
            self._last_pred = self._predict_unbiased(obs, u[0], u[1], ex)
        else:
            self._last_pred = None
        diag.mdot_bl_kgps, diag.t_evap_sp_c = float(u[0]), float(u[1])
        return AcInput(mdot_bl_kgps=float(u[0]), t_evap_sp_c=float(u[1])), diag


@contextlib.contextmanager
def _c_stdout_silenced():
    """Silence standard output for the block: Python's ``sys.stdout`` and the process's fd 1.

    qpOASES prints its licence banner whenever a solver object is created, whatever
    ``printLevel`` is set; CasADi routes that text to Python's ``sys.stdout`` (and C code may
    write to fd 1 directly). In a node it would interleave with the node's output on every
    controller build. Only solver construction is wrapped, never a solve. fd 1 is process-wide:
    output other threads write to stdout during the construction (a few hundred ms at start-up)
    is lost too; ROS 2 logs go to stderr unless RCUTILS_LOGGING_USE_STDOUT=1.
    """
    with contextlib.redirect_stdout(io.StringIO()):
        try:
            saved = os.dup(1)
        except OSError:  # no usable fd 1 (e.g. closed): the Python-level redirect is all we can do
            saved = None
        if saved is None:
            yield
            return
        try:
            _libc_fflush()  # what C stdio buffered before the block still goes to the real stdout
            with open(os.devnull, "wb") as devnull:
                os.dup2(devnull.fileno(), 1)
                try:
                    yield
                finally:
                    _libc_fflush()  # what C stdio buffered inside the block goes to /dev/null too
        finally:
            os.dup2(saved, 1)
            os.close(saved)


def _libc_fflush() -> None:
    """fflush(NULL): flush every C stdio output stream (no-op where libc cannot be loaded)."""
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError, TypeError):  # TypeError: no CDLL(None) on Windows
        pass


def codegen_cache_dir(path: str | None = None) -> pathlib.Path:
    """Directory of compiled NLPs: ``path``, else $CECO_CACHE_DIR, else $XDG_CACHE_HOME/ceco, else ~/.cache/ceco."""
    if path:
        return pathlib.Path(path)
    if os.environ.get("CECO_CACHE_DIR"):
        return pathlib.Path(os.environ["CECO_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return pathlib.Path(base) / "ceco"


def compile_nlp(nlp: dict, flags=("-O1",), cache_dir: str | None = None, plugin: str = "ipopt") -> str | None:
    """Generate C for an NLP's functions as ``plugin`` needs them and compile it into a cached shared object.

    ``plugin``: 'ipopt' (f, g, grad_f, jac_g, hess_l) or 'sqpmethod' (fg, grad, jac_fg, hess_l).

    The file name is a hash of the generated C code, the flags and the CasADi version, so a
    changed NLP never loads a stale object. Concurrent processes do not race: each compiles to
    its own temporary name and renames it into place atomically (``os.replace``). Returns the
    path, or None (with a log warning) when no C compiler is found or anything fails; the
    caller then uses the in-process functions.
    """
    cc = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        _LOG.warning("NMPC codegen: no C compiler found (gcc/cc/$CC); using the in-process NLP functions")
        return None
    try:
        with tempfile.TemporaryDirectory(prefix="ceco_cg_") as tmp:
            quiet = {"print_header": False, "qpsol_options": {"printLevel": "none"}} if plugin == "sqpmethod" else {}
            with _c_stdout_silenced():
                gen = casadi.nlpsol("ceco_nlp", plugin, nlp, {"print_time": False, **quiet})
            src = os.path.join(tmp, "ceco_nlp.c")
            cwd = os.getcwd()
            os.chdir(tmp)  # generate_dependencies writes relative to the working directory
            try:
                gen.generate_dependencies("ceco_nlp.c")
            finally:
                os.chdir(cwd)
            code = pathlib.Path(src).read_bytes()
            # (the plugin is in the code: IPOPT's and sqpmethod's function sets differ)
            digest = hashlib.sha256(code + repr((list(flags), casadi.__version__, cc)).encode()).hexdigest()[:20]
            cache = codegen_cache_dir(cache_dir)
            target = cache / f"ceco_nlp_{digest}.so"
            if target.is_file():
                return str(target)
            cache.mkdir(parents=True, exist_ok=True)
            part = cache / f".ceco_nlp_{digest}.{os.getpid()}.tmp.so"
            t0 = time.perf_counter()
            res = subprocess.run([cc, "-shared", "-fPIC", *flags, src, "-o", str(part), "-lm"],
                                 capture_output=True, text=True, timeout=600)
            if res.returncode != 0:
                part.unlink(missing_ok=True)
                _LOG.warning("NMPC codegen: compilation failed (%s); using the in-process NLP functions",
                             res.stderr.strip()[-500:])
                return None
            os.replace(part, target)
            _LOG.info("NMPC codegen: compiled %s in %.1f s", target, time.perf_counter() - t0)
            return str(target)
    except (OSError, RuntimeError, subprocess.SubprocessError) as exc:
        _LOG.warning("NMPC codegen failed (%s); using the in-process NLP functions", exc)
        return None
