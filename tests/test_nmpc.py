"""CECO NMPC: valid commands, forced solver failures fall back, IOCH eps follows speed, missing previews."""

import dataclasses

import casadi
import numpy as np
import pytest
from observations import observation

from ceco_controller.nmpc import NmpcController
from ceco_controller.solvers import SolveResult
from ceco_controller.strategies import SolverSettings, resolve_auto, strategy_settings
from ceco_core.contracts import ACTUATOR_LIMITS

N1 = 7  # Np + 1


def _obs(k=0, speed=10.0, valid=None, t_cab=28.0, **kw):
    return observation(N1, k, t_cab=t_cab, speed=speed, valid=valid, **kw)


_ZONE = dict(t_int_c=32.0, t_shell_c=32.0)
"""Interior and shell temperatures of a cabin that a comfort-zone PMV is reachable in (T_mr 31 degC)."""


def _valid(cmd):
    return ACTUATOR_LIMITS.contains(cmd.mdot_bl_kgps, cmd.t_evap_sp_c)


def test_forced_failure_falls_back_to_baseline_then_shifted_plan():
    # max_iter = 0: IPOPT cannot converge -> no plan yet -> the production ACC law
    bad = NmpcController(
        strategy_settings("ceco", solver=SolverSettings(name="ipopt", max_iter=0, transcription="single-shooting"))
    )
    cmd, diag = bad.compute(_obs(0))
    assert diag.fallback == "baseline" and not diag.success and _valid(cmd)
    assert "ACC law" in diag.message
    # a working controller, then a poisoned solve: the shifted previous plan is applied
    ctrl = NmpcController("ceco")
    cmd0, d0 = ctrl.compute(_obs(0))
    assert d0.success and d0.fallback == ""
    plan = ctrl._good.plan.copy()
    # same NLPs, solvers that always fail (the cold one works on the multiple-shooting NLP)
    ctrl.solver = ctrl.solver_fallback = bad.solver
    ctrl.solver_cold = bad.solver_cold
    cmd1, d1 = ctrl.compute(_obs(1))
    assert d1.fallback == "shifted_plan" and _valid(cmd1)
    # (exactly: the plan's step 1, clipped into the actuator range it may pass by the solver's bound tolerance)
    assert (cmd1.mdot_bl_kgps, cmd1.t_evap_sp_c) == tuple(float(v) for v in ctrl.lim.clip(plan[1][0], plan[1][1]))
    assert np.abs(np.asarray(ctrl.lim.clip(plan[1][0], plan[1][1])) - plan[1]).max() < 1e-6
    # the plan's later steps one by one; after Np - 1 = 5 failures it is exhausted: the baseline
    fallbacks = [ctrl.compute(_obs(k))[1].fallback for k in range(2, 8)]
    assert fallbacks == ["shifted_plan"] * 4 + ["baseline"] * 2


def test_nan_measurement_uses_baseline():
    ctrl = NmpcController("ceco-c")
    cmd, diag = ctrl.compute(_obs(0, t_cab=float("nan")))
    assert diag.fallback == "baseline" and diag.status == "invalid_measurement" and _valid(cmd)


def test_ioch_eps_larger_at_high_speed():
    eps = {}
    for speed in (0.0, 30.0):
        ctrl = NmpcController("ceco-ioch")
        vals = []
        for k in range(4):
            # a cabin inside the comfort zone (PMV 0.2 at 0.1 kg/s: T_mr 31 degC), so tightening is possible
            cmd, diag = ctrl.compute(_obs(k, speed=speed, t_cab=24.0, **_ZONE))
            assert diag.success and _valid(cmd)
            vals.append(diag.eps_mean)
        eps[speed] = float(np.mean(vals))
    assert eps[0.0] < 0.02  # eta_AC(0) = 1: no incentive to tighten at standstill
    assert eps[30.0] > eps[0.0] + 0.05


def test_missing_preview_degrades_gracefully():
    for strat in ("ceco", "ceco-e", "ceco-c", "ceco-ioch"):
        ctrl = NmpcController(strat)
        partial = np.array([True, True, True, False, False, False, False])
        nan_tail = np.where(partial, 35.0, np.nan)
        cmd, diag = ctrl.compute(_obs(0, valid=partial, preview_t_amb_c=nan_tail))
        assert _valid(cmd) and diag.trusted_horizon == 3 and "preview valid for 3/7" in diag.message
        none = np.zeros(N1, bool)
        cmd, diag = ctrl.compute(
            _obs(
                1,
                valid=none,
                preview_t_amb_c=np.full(N1, np.nan),
                preview_solar_wm2=np.full(N1, np.nan),
                preview_speed_mps=np.full(N1, np.nan),
            )
        )
        assert _valid(cmd) and diag.trusted_horizon == 0 and diag.success


def test_long_horizon_builds_and_solves():
    ctrl = NmpcController(strategy_settings("ceco-ioch", horizon_steps=60))
    n1 = 61
    obs = _obs(
        0,
        preview_t_amb_c=np.full(n1, 35.0),
        preview_solar_wm2=np.full(n1, 800.0),
        preview_speed_mps=np.linspace(0, 30, n1),
        preview_valid=np.ones(n1, bool),
        pmv_lb=np.full(n1, -0.5),
        pmv_ub=np.full(n1, 0.5),
    )
    cmd, diag = ctrl.compute(obs)
    assert diag.success and _valid(cmd) and diag.pred_pmv.size == n1


def test_wrong_preview_length_hands_the_step_to_the_acc_law():
    ctrl = NmpcController("ceco")
    n1 = 5
    obs = _obs(
        0,
        preview_t_amb_c=np.full(n1, 35.0),
        preview_solar_wm2=np.full(n1, 800.0),
        preview_speed_mps=np.full(n1, 1.0),
        preview_valid=np.ones(n1, bool),
        pmv_lb=np.full(n1, -0.5),
        pmv_ub=np.full(n1, 0.5),
    )
    cmd, diag = ctrl.compute(obs)
    assert diag.fallback == "baseline" and diag.status == "invalid_measurement" and _valid(cmd)
    assert "previews have 5 points" in diag.message and "Np+1 = 7" in diag.message


def test_settings_validation_names_field():
    with pytest.raises(ValueError, match="horizon_steps"):
        strategy_settings("ceco", horizon_steps=0)
    with pytest.raises(ValueError, match="max_cpu_time_s"):
        strategy_settings("ceco", solver=SolverSettings(max_cpu_time_s=10.0))
    with pytest.raises(ValueError, match="unknown CECO strategy"):
        strategy_settings("ceco-x")
    assert dataclasses.replace(strategy_settings("ceco-c")).gamma_w > 0
    # a switch given as text (a hand-typed override) is refused, not read as true
    for name in ("ioch", "use_speed_preview", "offset_free", "pmv_feedback"):
        with pytest.raises(ValueError, match=f"StrategySettings.{name} must be true or false, got 'false'"):
            strategy_settings("ceco-pmv", **{name: "false"})
    assert strategy_settings("ceco-pmv", use_speed_preview=False).use_speed_preview is False
    for name in ("rti", "warm_start", "jit", "codegen", "default_options", "ipopt_fallback"):
        with pytest.raises(ValueError, match=f"SolverSettings.{name} must be true or false, got 'false'"):
            SolverSettings(**{name: "false"}).validate()
    SolverSettings(codegen=False).validate()


def test_controller_yaml_matches_code_defaults():
    from ceco_controller.strategies import load_strategy_settings

    for name in ("ceco", "ceco-e", "ceco-c", "ceco-ioch"):
        assert load_strategy_settings(name) == strategy_settings(name)


def test_a_controller_file_np_or_ts_the_run_would_ignore_is_refused(tmp_path):
    """Np and Ts come from the run (scenario, flags, node parameters), which always passes them: a controller file
    giving another value was ignored without a word; now refused naming the key, the file's and the run's
    value. The same value, or none, is accepted."""
    from ceco_controller.model import package_config_path
    from ceco_controller.strategies import load_strategy_settings

    text = package_config_path("controller.yaml").read_text()
    assert "\n  horizon_steps:" not in text and "\n  control_period_s:" not in text  # the run's, not the file's
    for key, file_value, run_value in (("horizon_steps", 9, 6), ("control_period_s", 10.0, 5.0)):
        path = tmp_path / f"{key}.yaml"
        path.write_text(text.replace("common:\n", f"common:\n  {key}: {file_value}\n", 1))
        with pytest.raises(ValueError, match=rf"{key}: {file_value} is not what this run uses \({run_value}\)"):
            load_strategy_settings("ceco-pmv", path, **{key: run_value})
        assert getattr(load_strategy_settings("ceco-pmv", path, **{key: file_value}), key) == file_value
        assert getattr(load_strategy_settings("ceco-pmv", path), key) == file_value  # no run value: the file's
    assert load_strategy_settings("ceco", horizon_steps=9).horizon_steps == 9


@pytest.mark.parametrize(
    ("edit", "says"),
    [
        (lambda t: t.replace("\nstrategies:\n", "\nstrategy:\n", 1), "unknown top-level key(s) 'strategy': "),
        (lambda t: t.replace("\ncommon:\n", "\ncommons:\n", 1), "unknown top-level key(s) 'commons': "),
        (lambda t: t.replace("\n  ceco-pmv:", "\n  ceco-pmw:", 1), "strategies: unknown strategy 'ceco-pmw': "),
        (lambda t: t.replace("gamma_w: 0.0", "gamma_ww: 0.0", 1), "strategies.ceco-e: unknown setting(s) 'gamma_ww'"),
        (lambda t: t.replace("du_weight_kj:", "du_weight_kJ:", 1), "common: unknown setting(s) 'du_weight_kJ'"),
        (lambda t: t.replace("ipopt_fallback:", "ipopt_fallbak:", 1), "common.solver: unknown setting(s) 'ipopt_fa"),
        (lambda t: t.replace("\ncommon:\n", "\nname: ceco\ncommon:\n", 1), "unknown top-level key(s) 'name'"),
    ],
)
def test_a_controller_file_key_nothing_reads_is_refused(edit, says, tmp_path):
    """A copy of controller.yaml with `strategies:` misspelt `strategy:` ran every strategy on its defaults without
    a word (ceco and ceco-pmv gave identical results), and a scenario file passed as a controller file was accepted.
    Now a top-level key other than common and strategies, an unknown strategy under strategies (ceco-pmv then ran
    on its defaults) and an unknown setting in any block (not only the loaded strategy's) are refused, one line
    naming the file, the key and what is allowed."""
    from ceco_bringup import provenance
    from ceco_controller.model import package_config_path
    from ceco_controller.strategies import load_strategy_settings

    path = tmp_path / "controller.yaml"
    path.write_text(edit(package_config_path("controller.yaml").read_text()))
    with pytest.raises(ValueError) as err:
        load_strategy_settings("ceco-pmv", path)
    msg = str(err.value)
    assert msg.startswith(f"{path}: ") and says in msg and "\n" not in msg, msg
    if "top-level" in says:
        shared = " (and acc_law, the baseline's, in a file both read)"
        assert msg.endswith("a controller file has common and strategies only" + shared), msg
    if "unknown strategy" in says:
        assert msg.endswith("choose from ceco, ceco-e, ceco-c, ceco-ioch, ceco-pmv"), msg
    scenario = provenance.copy_scenario("sc03", tmp_path / "sc")  # a scenario file is no controller file
    with pytest.raises(ValueError, match=r"unknown top-level key\(s\) 'name', 'description', "):
        load_strategy_settings("ceco", scenario)


def test_codegen_falls_back_without_compiler(monkeypatch, tmp_path, caplog):
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    ss = SolverSettings(codegen=True, codegen_cache_dir=str(tmp_path / "cache"))
    with caplog.at_level("WARNING", logger="ceco_controller"):
        ctrl = NmpcController(strategy_settings("ceco", solver=ss))
    assert "in-process NLP functions" in caplog.text
    cmd, diag = ctrl.compute(_obs(0))
    assert diag.success and _valid(cmd)
    assert not list((tmp_path / "cache").glob("*.so"))


def test_codegen_compiles_once_and_matches_in_process(tmp_path, monkeypatch, caplog):
    """Compiled NLP functions (cached by code hash) give the in-process solution; a second
    controller with the same NLP reuses the cached object; an object whose evaluator cannot be
    loaded leaves every function in-process (none half-swapped)."""
    cache = tmp_path / "cache"
    ss = SolverSettings(codegen=True, codegen_flags=("-O0",), codegen_cache_dir=str(cache))
    comp = NmpcController(strategy_settings("ceco-ioch", solver=ss))
    objs = sorted(cache.glob("ceco_*.so"))
    # one object per solver and NLP: the SQP's functions when that is the warm solver, IPOPT's (its
    # retry), and the cold solver's multiple-shooting NLP (IPOPT) when the controller's NLP is single shooting
    n_sqp = int(comp.settings.solver.name == "sqp")
    assert len(list(cache.glob("ceco_sqp_*.so"))) == n_sqp == 1
    n_expected = n_sqp + 1 + (comp.transcription == "single-shooting")
    assert len(objs) == n_expected == 3 and not list(cache.glob(".*tmp*"))
    ref = NmpcController("ceco-ioch")
    for k in range(3):
        c1, d1 = comp.compute(_obs(k, speed=20.0))
        c2, d2 = ref.compute(_obs(k, speed=20.0))
        assert d1.success and d2.success
        assert abs(c1.mdot_bl_kgps - c2.mdot_bl_kgps) < 1e-6 and abs(c1.t_evap_sp_c - c2.t_evap_sp_c) < 1e-5
        assert d1.cost_total == pytest.approx(d2.cost_total, rel=1e-8)
    # the problem's evaluator (diagnostics, warm start) and rollout come from the SQP's object: the same numbers
    # as CasADi's virtual machine, to the bit
    assert comp.problem._evaluator.fn.class_name() == comp.problem._rollout.fn.class_name() == "External"
    assert ref.problem._evaluator.fn.class_name() == "SXFunction"
    prob, rng, p = comp.problem, np.random.default_rng(7), comp.last_nlp().p
    lo = np.where(np.isfinite(prob.lbw), prob.lbw, -1.0)
    span = np.minimum(np.where(np.isfinite(prob.ubw), prob.ubw, lo + 2.0) - lo, 10.0)
    for _ in range(20):
        w = lo + rng.random(prob.nw) * span
        e1, e2 = prob.evaluate(w, p), ref.problem.evaluate(w, p)
        for f in dataclasses.fields(e1):
            np.testing.assert_array_equal(getattr(e1, f.name), getattr(e2, f.name), err_msg=f.name)
        u = prob.plan(w)
        np.testing.assert_array_equal(prob.rollout_states(u, p), ref.problem.rollout_states(u, p))
    assert np.isfinite(prob.evaluate(w, p).pmv).all()
    mtime = objs[0].stat().st_mtime_ns
    NmpcController(strategy_settings("ceco-ioch", solver=ss))
    assert sorted(cache.glob("ceco_*.so")) == objs and objs[0].stat().st_mtime_ns == mtime
    # the cached object loads, but its evaluator does not: the SQP's functions and the problem's stay in-process
    import ceco_controller.solvers as solvers_mod

    external = solvers_mod.casadi.external

    def no_eval(name, *args):
        if name == "ceco_eval":
            raise RuntimeError("cannot load ceco_eval (test)")
        return external(name, *args)

    monkeypatch.setattr(solvers_mod.casadi, "external", no_eval)
    with caplog.at_level("WARNING", logger="ceco_controller"):
        half = NmpcController(strategy_settings("ceco-ioch", solver=ss))
    assert "in-process NLP functions" in caplog.text
    assert half.problem._evaluator.fn.class_name() == "SXFunction"
    assert half.solver.sqp._jac.fn.class_name() == "SXFunction"
    cmd, diag = half.compute(_obs(0, speed=20.0))
    assert diag.success and _valid(cmd)


class _FailingSolver:
    """A solver stub that always fails (the chain must retry, then fall back)."""

    name = "sqp"

    def solve(self, data, deadline=None):
        return SolveResult.failed("sqp", "QP_Failed (stub)")


def test_sqp_matches_ipopt_and_falls_back_to_ipopt():
    # warm SQP (exact Hessian, exact eigenvalue convexification, dense qpOASES) reaches IPOPT's optimum
    sqp = NmpcController(strategy_settings("ceco-ioch", solver=SolverSettings(name="sqp")))
    ipo = NmpcController(strategy_settings("ceco-ioch", solver=SolverSettings(name="ipopt")))
    costs = {}
    for name, ctrl in (("sqp", sqp), ("ipopt", ipo)):
        for k in range(3):
            # inside the comfort zone (T_mr 31 degC): the comfort constraint and the IOCH slack are active
            cmd, diag = ctrl.compute(_obs(k, t_cab=24.5 - 0.3 * k, **_ZONE))
            assert diag.success and _valid(cmd)
        costs[name] = diag.cost_total
    assert sqp.n_ipopt_fallbacks == 0  # step 0 is a cold (IPOPT) solve, steps 1-2 warm sqpmethod
    assert abs(costs["sqp"] - costs["ipopt"]) <= 1e-4 * abs(costs["ipopt"])
    # the same warm instance solved by both solvers directly: same optimum
    data = sqp.last_nlp()
    f_sqp = sqp.solve_nlp(data, sqp.solver)
    f_ipo = sqp.solve_nlp(data, sqp.solver_fallback)
    assert f_sqp.success and f_ipo.success
    assert abs(f_sqp.f - f_ipo.f) <= 1e-4 * abs(f_ipo.f)
    # a failing SQP is retried by warm IPOPT from the same start: valid command, counted
    sqp.solver = _FailingSolver()
    cmd, diag = sqp.compute(_obs(3, t_cab=24.0, **_ZONE))
    assert sqp.n_ipopt_fallbacks == 1 and sqp.counters.retries == 1 and diag.success and diag.fallback == ""
    assert _valid(cmd) and diag.status.startswith("sqp: QP_Failed (stub); ipopt: ")
    assert "not used: warm sqp: no finite primal-dual point (QP_Failed (stub))" in diag.message


def test_solver_settings_reject_unknown_qpsol_and_the_replaced_sqpmethod():
    with pytest.raises(ValueError, match="qpsol"):
        SolverSettings(name="sqp", qpsol="nope").validate()
    with pytest.raises(ValueError, match="'sqpmethod' .* replaced by 'sqp'"):
        SolverSettings(name="sqpmethod").validate()
    with pytest.raises(ValueError, match="rti"):
        SolverSettings(name="ipopt", rti=True).validate()
    with pytest.raises(ValueError, match="step_reserve_s"):
        SolverSettings(step_budget_s=0.1, step_reserve_s=0.2).validate()
    with pytest.raises(ValueError, match="step_budget_s must be below control_period_s"):
        strategy_settings("ceco", solver=SolverSettings(step_budget_s=5.0))
    # a YAML 1.1 '1e-05' arrives as text: the strategy names the solver's field (it was a TypeError from the check
    # against the control period, which ran before the solver's own)
    for field in ("step_budget_s", "max_cpu_time_s"):
        with pytest.raises(ValueError, match=f"SolverSettings.{field} must be finite and > 0, got '1e-05'"):
            strategy_settings("ceco", solver=SolverSettings(**{field: "1e-05"}))


def test_single_and_multiple_shooting_reach_the_same_optimum():
    """The single-shooting NLP (states eliminated) and the multiple-shooting one are the same
    problem: same commands and costs in closed-loop steps, the same optimum on one instance."""
    ctrls = {
        t: NmpcController(strategy_settings("ceco-ioch", solver=SolverSettings(transcription=t)))
        for t in ("single-shooting", "multiple-shooting")
    }
    assert ctrls["single-shooting"].problem.nw == ctrls["multiple-shooting"].problem.nw - 4 * 6  # no states
    assert ctrls["single-shooting"].problem.ng == ctrls["multiple-shooting"].problem.ng - 4 * 6  # no gaps
    out = {}
    for t, ctrl in ctrls.items():
        for k in range(4):
            cmd, diag = ctrl.compute(_obs(k, speed=5.0 * k, t_cab=27.0 - 0.3 * k))
            assert diag.success and _valid(cmd) and diag.fallback == ""
        out[t] = (cmd, diag)
    (c1, d1), (c2, d2) = out["single-shooting"], out["multiple-shooting"]
    assert abs(d1.cost_total - d2.cost_total) <= 1e-5 * abs(d2.cost_total)
    assert abs(c1.mdot_bl_kgps - c2.mdot_bl_kgps) < 1e-3 and abs(c1.t_evap_sp_c - c2.t_evap_sp_c) < 2e-2
    np.testing.assert_allclose(d1.pred_t_cab_c, d2.pred_t_cab_c, atol=2e-3)
    # IPOPT (the cold/fallback solver) on the single-shooting instance: the SQP's optimum
    ss = ctrls["single-shooting"]
    data = ss.last_nlp()
    f_sqp, f_ipo = ss.solve_nlp(data, ss.solver), ss.solve_nlp(data, ss.solver_fallback)
    assert f_sqp.success and f_ipo.success
    assert abs(f_sqp.f - f_ipo.f) <= 1e-4 * abs(f_ipo.f)


def test_transcription_settings_are_validated():
    with pytest.raises(ValueError, match="transcription"):
        SolverSettings(transcription="collocation").validate()
    with pytest.raises(ValueError, match="fatrop"):
        SolverSettings(name="fatrop", transcription="single-shooting").validate()  # no stage structure
    assert (
        resolve_auto(strategy_settings("ceco", solver=SolverSettings(name="fatrop"))).solver.transcription
        == "multiple-shooting"
    )
    with pytest.raises(ValueError, match="eig_floor"):
        SolverSettings(eig_floor=0.0).validate()
    # an SQP solve and then its IPOPT retry must both fit in the control period
    with pytest.raises(ValueError, match="control_period_s / 2"):
        strategy_settings("ceco", solver=SolverSettings(max_cpu_time_s=3.0))
    strategy_settings("ceco", solver=SolverSettings(name="ipopt", max_cpu_time_s=3.0))
    # a solver for another transcription than the controller's NLP is refused, not silently rebuilt
    ctrl = NmpcController("ceco")
    with pytest.raises(ValueError, match="does not match"):
        ctrl.make_solver(SolverSettings(transcription="multiple-shooting"))


def test_building_the_sqp_controller_prints_nothing(capfd):
    # qpOASES writes a licence banner to C stdout when a solver is created; the build silences it
    ctrl = NmpcController(strategy_settings("ceco", solver=SolverSettings(name="sqp")))
    cmd, diag = ctrl.compute(_obs(0))
    cmd, diag = ctrl.compute(_obs(1))
    out = capfd.readouterr().out
    assert diag.success and _valid(cmd)
    assert "qpOASES" not in out and out == ""


def test_auto_solver_follows_the_horizon():
    """'auto': the SQP with dense qpOASES QPs on the single-shooting NLP up to single_shooting_max_steps,
    the SQP with HPIPM's Riccati QPs on the multiple-shooting NLP beyond (the dense QP's cost grows
    cubically with Np); IPOPT retries and does the cold solves in both."""
    short = NmpcController(strategy_settings("ceco", horizon_steps=12))
    long_ = NmpcController(strategy_settings("ceco", horizon_steps=13))
    assert (short.settings.solver.name, short.settings.solver.qpsol, short.transcription) == (
        "sqp",
        "qpoases",
        "single-shooting",
    )
    assert (long_.settings.solver.name, long_.settings.solver.qpsol, long_.transcription) == (
        "sqp",
        "hpipm",
        "multiple-shooting",
    )
    assert long_.solver_fallback is not None and short.solver_fallback is not None
    assert long_.cold_path is None and long_.solver_cold.name == "ipopt"
    explicit = NmpcController(
        strategy_settings("ceco", horizon_steps=13, solver=SolverSettings(name="sqp", transcription="single-shooting"))
    )
    assert (explicit.settings.solver.name, explicit.transcription) == ("sqp", "single-shooting")
    # an explicit sparse solver gets the sparse (multiple-shooting) NLP at any horizon
    ipo = NmpcController(strategy_settings("ceco", solver=SolverSettings(name="ipopt")))
    assert ipo.transcription == "multiple-shooting" and ipo.cold_path is None


def test_cold_solves_use_the_multiple_shooting_nlp():
    """A single-shooting controller's cold solve (first step) runs IPOPT on the multiple-shooting
    NLP and maps the solution back: the same command and cost as a multiple-shooting controller."""
    ss = NmpcController("ceco")
    ms = NmpcController(strategy_settings("ceco", solver=SolverSettings(transcription="multiple-shooting")))
    assert ss.transcription == "single-shooting" and ss.cold_path.transcription == "multiple-shooting"
    (c1, d1), (c2, d2) = ss.compute(_obs(0, t_cab=30.0)), ms.compute(_obs(0, t_cab=30.0))
    assert d1.success and d2.success
    assert d1.cost_total == pytest.approx(d2.cost_total, rel=1e-9)
    assert (c1.mdot_bl_kgps, c1.t_evap_sp_c) == pytest.approx((c2.mdot_bl_kgps, c2.t_evap_sp_c), rel=1e-9)
    # the mapped point, evaluated on the single-shooting NLP's own functions (not the IPOPT solve that
    # produced it): feasible, its objective the reported cost, and its first input the command
    prob, w, p = ss.problem, ss._good.w, ss.last_nlp().p
    nlp = casadi.Function("ss", [prob.nlp["x"], prob.nlp["p"]], [prob.nlp["f"], prob.nlp["g"]])
    f, g = (np.array(v).ravel() for v in nlp(w, p))
    assert w.size == prob.nw and prob.max_violation(w, g) <= 1e-6
    assert float(f[0]) == pytest.approx(d1.cost_total, rel=1e-9)
    ev = ss.evaluate(w, p)
    assert ev.J_e + ev.J_c + ev.J_i + ev.J_s + ev.J_du == pytest.approx(d1.cost_total, rel=1e-9)
    assert tuple(prob.plan(w)[0]) == pytest.approx((c1.mdot_bl_kgps, c1.t_evap_sp_c), abs=1e-6)  # clipped to the bound
    # the mapped primal-dual point warm-starts the SQP at once
    c1, d1 = ss.compute(_obs(1, t_cab=29.8))
    assert d1.success and ss.n_ipopt_fallbacks == 0 and d1.status == "Solve_Succeeded"


def test_controller_file_is_what_the_simulator_and_nodes_build_from(tmp_path):
    """make_controller (used by the simulator and mpc_node) reads the controller file: a copy with
    another setting changes the built controller; a bad key fails with the file and key named."""
    import yaml

    from ceco_controller import closed_loop
    from ceco_controller.model import package_config_path
    from ceco_v2x_preview.scenario import load_scenario

    sc = load_scenario("sc03")
    default = closed_loop.make_controller("ceco-c", sc, 5.0, 6)
    assert default.settings.gamma_w == strategy_settings("ceco-c").gamma_w
    doc = yaml.safe_load(package_config_path("controller.yaml").read_text())
    doc["strategies"]["ceco-c"]["gamma_w"] = 2000.0
    doc["common"]["solver"]["name"] = "ipopt"
    cfg = tmp_path / "controller.yaml"
    cfg.write_text(yaml.safe_dump(doc))
    ctrl = closed_loop.make_controller("ceco-c", sc, 5.0, 6, config_path=str(cfg))
    assert ctrl.settings.gamma_w == 2000.0 and ctrl.settings.solver.name == "ipopt"
    assert ctrl.transcription == "multiple-shooting"  # an explicit IPOPT gets the sparse NLP
    doc["common"]["gama_w"] = 1.0
    cfg.write_text(yaml.safe_dump(doc))
    with pytest.raises(ValueError, match="gama_w"):
        closed_loop.make_controller("ceco-c", sc, 5.0, 6, config_path=str(cfg))


class _Clock:
    """An injected clock the test advances by hand [s]."""

    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def _poison(ctrl):
    real = (ctrl.solver, ctrl.solver_fallback, ctrl.solver_cold)
    ctrl.solver = ctrl.solver_fallback = ctrl.solver_cold = _FailingSolver()
    return real


def _restore(ctrl, real):
    ctrl.solver, ctrl.solver_fallback, ctrl.solver_cold = real


def test_after_a_failed_step_the_next_solve_is_warm_from_the_last_good_plan():
    """Issue 12 'Cold path under pressure': a failed step does not drop the warm start; the next
    solve starts from the last good solution shifted by two stages (not cold)."""
    from ceco_controller.warmstart import initial_guess

    ctrl = NmpcController("ceco")
    for k in range(3):
        ctrl.compute(_obs(k, t_cab=27.0 - 0.1 * k))
    good = ctrl._good
    real = _poison(ctrl)
    cmd, diag = ctrl.compute(_obs(3, t_cab=26.7))
    assert diag.fallback == "shifted_plan" and (cmd.mdot_bl_kgps, cmd.t_evap_sp_c) == tuple(good.plan[1])
    _restore(ctrl, real)
    cold = ctrl.counters.cold_solves
    cmd, diag = ctrl.compute(_obs(4, t_cab=26.6))
    assert diag.fallback == "" and diag.success and diag.status == "Solve_Succeeded"
    assert ctrl.counters.cold_solves == cold
    data = ctrl.last_nlp()
    np.testing.assert_array_equal(data.x0, initial_guess(ctrl.problem, data.p, good.w, 2))
    np.testing.assert_array_equal(data.lam_g0, ctrl.problem.rows.shift(good.lam_g, 2))


class _SlowQp:
    """Wraps the SQP's QP so that each QP 'takes' ``dt`` seconds on the injected clock."""

    def __init__(self, qp, clock, dt):
        self.qp, self.clock, self.dt, self.buf = qp, clock, dt, qp.buf

    def __call__(self, *args):
        self.clock.t += self.dt
        return self.qp(*args)


def test_an_iterate_cut_by_the_deadline_is_applied_when_its_violation_is_small():
    clock = _Clock()
    ctrl = NmpcController("ceco", clock=clock)
    for k in range(2):  # inside the comfort zone: the comfort constraint is active (3 QPs per solve)
        ctrl.compute(_obs(k, t_cab=24.5, **_ZONE))
    sqp = ctrl.solver.sqp
    sqp._qp = _SlowQp(sqp._qp, clock, 10.0)  # the first QP ends after the 1 s budget
    cmd, diag = ctrl.compute(_obs(2, t_cab=23.5, speed=25.0, **_ZONE))
    assert diag.status == "Maximum_Wall_Time_Exceeded" and diag.iterations == 1 and not diag.success
    assert diag.fallback == "" and _valid(cmd) and "sqp iterate applied at its limit" in diag.message
    c = ctrl.counters
    assert c.accepted_iterates == 1 and c.retries == 0 and c.cold_solves == 1 and c.deadline_hits == 1
    # no time at all: no iteration, no retry, no cold solve: the last good plan shifted
    cmd, diag = ctrl.compute(_obs(3, t_cab=23.5, **_ZONE), t_start=clock() - 10.0)
    assert diag.fallback == "shifted_plan" and "no iteration before the limit" in diag.message
    assert c.retries == 0 and c.cold_solves == 1 and c.deadline_hits == 2


def test_hand_over_to_the_acc_law_and_back_is_bumpless():
    """The ACC law tracks the applied command while the NMPC is in charge: its first command after the
    shifted plan runs out is the last applied one, the difference to its own output then decays with
    handover_tau_s (30 s); the NMPC then takes back control from the applied command."""
    import math

    ctrl = NmpcController("ceco")
    for k in range(3):  # inside the comfort zone: an interior command, far from the law's own (0.05, 10)
        ctrl.compute(_obs(k, t_cab=24.5, **_ZONE))
    real = _poison(ctrl)
    cmds, fallbacks, raw = [], [], []
    for k in range(3, 12):
        cmd, diag = ctrl.compute(_obs(k, t_cab=24.5, **_ZONE))
        cmds.append(np.array([cmd.mdot_bl_kgps, cmd.t_evap_sp_c]))
        fallbacks.append(diag.fallback)
        raw.append(np.array([ctrl._acc._raw.mdot_bl_kgps, ctrl._acc._raw.t_evap_sp_c]))
    assert fallbacks == ["shifted_plan"] * 5 + ["baseline"] * 4
    np.testing.assert_array_equal(cmds[5], cmds[4])  # the take-over: no bump
    assert abs(cmds[5][0] - raw[5][0]) > 0.03  # ... although the law's own output is elsewhere
    decay = math.exp(-5.0 / 30.0)
    for i in range(6, 9):
        np.testing.assert_allclose(cmds[i] - raw[i], (cmds[i - 1] - raw[i - 1]) * decay, atol=1e-12)
    _restore(ctrl, real)
    cmd, diag = ctrl.compute(_obs(12, t_cab=24.5, mdot_bl_prev_kgps=cmds[-1][0], t_evap_sp_prev_c=cmds[-1][1], **_ZONE))
    assert diag.fallback == "" and diag.success and _valid(cmd)
    # the NMPC plans from the applied command (its u_prev, move penalty); its first move is its own decision
    np.testing.assert_array_equal(ctrl.problem.params.get(ctrl.last_nlp().p, "u_prev"), cmds[-1])


def test_prepare_makes_the_first_step_warm_and_warm_up_leaves_no_trace():
    fresh, prepared, warmed = NmpcController("ceco"), NmpcController("ceco"), NmpcController("ceco")
    res = prepared.prepare(_obs(0, t_cab=30.0))
    assert res is not None and res.success
    assert warmed.warm_up() > 0 and warmed.counters.steps == 0 and warmed._good is None
    (c1, d1), (c2, d2), (c3, d3) = (c.compute(_obs(0, t_cab=30.0)) for c in (fresh, prepared, warmed))
    # the first step starts from the prepared (cold IPOPT) solution of the same instance: one QP polishes it
    assert prepared.counters.cold_solves == 0 and d2.iterations <= 1 and d2.status == "Solve_Succeeded"
    assert d2.cost_total == pytest.approx(d1.cost_total, rel=1e-6)
    assert (c2.mdot_bl_kgps, c2.t_evap_sp_c) == pytest.approx((c1.mdot_bl_kgps, c1.t_evap_sp_c), abs=1e-5)
    # warm_up changed nothing: bit-identical first step
    assert (c3.mdot_bl_kgps, c3.t_evap_sp_c) == (c1.mdot_bl_kgps, c1.t_evap_sp_c) and d3.cost_total == d1.cost_total
    assert warmed.warm_up_problem is None


def test_a_warm_up_whose_nominal_solve_fails_says_so():
    """The node's configured line says how the first solve went: 'NmpcController.warm_up' alone only when the nominal
    instance solved; a solver that cannot (IPOPT with no iteration) is named with the reason, and the controller
    still works (its first step falls back safely)."""
    from ceco_controller.controller_io import warm_up
    from ceco_v2x_preview.scenario import load_scenario

    scenario = load_scenario("sc03")
    good = NmpcController("ceco")
    assert warm_up(good, scenario, 5.0, 6) == "NmpcController.warm_up" and good.warm_up_problem is None
    bad = NmpcController(
        strategy_settings("ceco", solver=SolverSettings(name="ipopt", max_iter=0, transcription="single-shooting"))
    )
    said = warm_up(bad, scenario, 5.0, 6)
    assert said.startswith("NmpcController.warm_up (its nominal solve not usable: ipopt: ")
    assert bad.warm_up_problem is not None and bad.warm_up_problem in said
    cmd, d = bad.compute(_obs(0))
    assert d.fallback == "baseline" and _valid(cmd)


def test_comfort_parameters_humidity_setting_and_draught_penalty():
    from ceco_core import psychro
    from ceco_core.cabin_comfort import PAPER_PA_PA, cabin_mrt_c

    with pytest.raises(ValueError, match="pmv_pa_source"):
        strategy_settings("ceco", pmv_pa_source="sensor")
    with pytest.raises(ValueError, match="draught_weight_kj"):
        strategy_settings("ceco", draught_weight_kj=-1.0)
    paper = NmpcController("ceco")
    measured = NmpcController(strategy_settings("ceco", pmv_pa_source="measured"))
    obs = _obs(0, t_cab=25.0, rh_cab=0.3, t_glass_c=36.0)
    t_mr, pa = paper.comfort_parameters(obs)
    assert pa == PAPER_PA_PA
    assert t_mr == pytest.approx(
        float(cabin_mrt_c(t_cab_c=25.0, t_int_c=40.0, t_shell_c=38.0, t_glass_c=36.0, params=paper.comfort_params)),
        abs=1e-12,
    )
    assert measured.comfort_parameters(obs)[1] == pytest.approx(float(psychro.vapour_pressure_pa(25.0, 0.3)))
    assert measured.comfort_parameters(_obs(0, t_cab=25.0))[1] == PAPER_PA_PA  # no RH measured: 1700 Pa
    # p_a (the named slice 'pa'): the same plan predicted with a drier cabin is cooler (~0.15 PMV)
    _, d_paper = paper.compute(_obs(0, t_cab=24.0, rh_cab=0.3, **_ZONE))
    data = paper.last_nlp()
    p_dry = data.p.copy()
    p_dry[paper.problem.params.slices["pa"]] = float(psychro.vapour_pressure_pa(24.0, 0.3))
    w = data.x0
    drop = paper.evaluate(w, data.p).pmv - paper.evaluate(w, p_dry).pmv
    assert d_paper.success and np.all((drop > 0.1) & (drop < 0.25))
    # the draught penalty enters the comfort cost (off by default)
    dr = NmpcController(strategy_settings("ceco", draught_weight_kj=0.01))
    _, d_dr = dr.compute(_obs(0, t_cab=24.0, **_ZONE))
    assert d_paper.cost_comfort == 0.0 and d_dr.success and d_dr.cost_comfort > 0.0


def test_an_implausible_humidity_is_not_used_in_the_nlp():
    """rh_cab = 40 (per cent, not a fraction) is treated as not measured: the NLP gets 1700 Pa."""
    from ceco_core.cabin_comfort import PAPER_PA_PA

    ctrl = NmpcController(strategy_settings("ceco", pmv_pa_source="measured"))
    cmd, diag = ctrl.compute(_obs(0, t_cab=24.0, rh_cab=40.0, **_ZONE))
    assert diag.fallback == "" and "rh_cab=40.0" in diag.message
    assert ctrl.problem.params.scalar(ctrl.last_nlp().p, "pa") == PAPER_PA_PA
    cmd, diag = ctrl.compute(_obs(1, t_cab=24.0, rh_cab=0.4, **_ZONE))
    assert ctrl.problem.params.scalar(ctrl.last_nlp().p, "pa") != PAPER_PA_PA


def test_a_failed_cold_ipopt_is_followed_by_the_sqp_from_the_same_guess():
    ctrl = NmpcController("ceco")
    ctrl.solver_cold = _FailingSolver()
    cmd, diag = ctrl.compute(_obs(0, t_cab=24.5, **_ZONE))
    assert diag.fallback == "" and diag.success and _valid(cmd)
    assert diag.status.startswith("cold sqp: QP_Failed (stub); cold sqp: Solve_Succeeded")
    assert ctrl.counters.cold_solves == 2 and ctrl.counters.converged == 1
