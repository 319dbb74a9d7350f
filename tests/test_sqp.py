"""ceco's dense SQP and the NLP layout: exact convexification, deadline, real-time iteration, named slices."""

import numpy as np
import pytest
from observations import observation

from ceco_controller.nlp_layout import ParamLayout, RowLayout, VariableLayout
from ceco_controller.nmpc import NmpcController
from ceco_controller.strategies import SolverSettings, strategy_settings
from ceco_controller.warmstart import repair_slacks

N1 = 7


def _obs(k=0, t_cab=27.0, speed=10.0):
    return observation(N1, k, t_cab=t_cab, speed=speed)


def _optimum_hessians(strategy, steps=6):
    """Hessians of the Lagrangian at the solutions of a few closed-loop-like steps."""
    ctrl = NmpcController(strategy)
    sqp = ctrl.solver.sqp
    out = []
    for k in range(steps):
        ctrl.compute(_obs(k, t_cab=27.0 - 0.2 * k, speed=3.0 * k))
        good = ctrl._good
        (h,) = sqp._hess(good.w, ctrl.last_nlp().p, good.lam_g)
        out.append(h.reshape(sqp.nw, sqp.nw).copy())
    return sqp, out


def test_convexification_is_exact_on_the_ill_conditioned_input_block():
    """ceco-c's optimum Hessians (the 12 x 12 input block that CasADi's 50-rotation Jacobi eigen-clip
    could not decompose): the convexified matrix has every eigenvalue >= eig_floor and leaves each
    eigen-direction with eigenvalue >= eig_floor unchanged."""
    sqp, hessians = _optimum_hessians("ceco-c")
    floor = sqp.options.eig_floor
    ((block, ix),) = sqp._dense  # one dense block: the inputs
    assert block.size == 12
    conds = []
    for h in hessians:
        hb = 0.5 * (h[ix] + h[ix].T)
        lam, vec = np.linalg.eigh(hb)
        conds.append(abs(lam).max() / max(abs(lam).min(), 1e-300))
        hc = sqp.convexify(h)[ix]
        lam_c = np.linalg.eigvalsh(hc)
        assert lam_c.min() >= floor - 1e-12 * abs(lam).max()  # (rounding of V diag(lam) V')
        keep = lam >= floor
        np.testing.assert_allclose(hc @ vec[:, keep], vec[:, keep] * lam[keep], atol=1e-9 * abs(lam).max())
        # ... and puts each direction below the floor at the floor (clipped, not mirrored or shifted)
        low = ~keep
        assert low.any()
        np.testing.assert_allclose(hc @ vec[:, low], floor * vec[:, low], atol=1e-9 * abs(lam).max())
        # entries outside the blocks with curvature stay zero (the linear slacks)
        rest = np.setdiff1d(np.arange(sqp.nw), np.concatenate([block, sqp._diag1]))
        assert not np.any(sqp.convexify(h)[np.ix_(rest, rest)])
    assert max(conds) > 1e6  # ill-conditioned indeed


def test_convexification_falls_back_to_a_gershgorin_shift(monkeypatch):
    sqp, hessians = _optimum_hessians("ceco", steps=1)

    def fail(_):
        raise np.linalg.LinAlgError("Eigenvalues did not converge")

    monkeypatch.setattr(np.linalg, "eigh", fail)
    monkeypatch.setattr(sqp, "_above_floor", lambda hb: False)  # (the Cholesky shortcut for blocks above the floor)
    ((block, ix),) = sqp._dense
    hb = hessians[0][ix]
    hb = 0.5 * (hb + hb.T)
    hc = sqp.convexify(hessians[0])[ix]
    assert sqp.n_eig_fallbacks == 1
    # a pure diagonal shift of the symmetric block: H + s I with s >= 0 ...
    shift = hc - hb
    s_ = float(shift[0, 0])
    np.testing.assert_allclose(shift, s_ * np.eye(block.size), rtol=0, atol=1e-9 * max(1.0, abs(s_)))
    # ... by the Gershgorin bound, no more: s = max(0, max_i(R_i - h_ii)) + floor, R_i the off-diagonal row sums
    floor = sqp.options.eig_floor
    radius = np.abs(hb).sum(axis=1) - np.abs(np.diag(hb))
    assert s_ == pytest.approx(max(0.0, float((radius - np.diag(hb)).max())) + floor, rel=1e-12)
    assert s_ > 10.0 * floor  # (the block is indefinite here: the shift is the bound's, not the floor alone)
    # ... large enough that every eigenvalue is at least the floor
    assert np.linalg.eigvalsh(hc).min() >= floor * (1 - 1e-6) - 1e-9 * np.abs(hb).max()


def test_sqp_from_its_own_solution_needs_no_qp_and_stops_at_the_deadline():
    ctrl = NmpcController("ceco-ioch")
    for k in range(3):
        ctrl.compute(_obs(k))
    sqp, data, good = ctrl.solver.sqp, ctrl.last_nlp(), ctrl._good
    out = sqp.solve(good.w, data.p, good.lam_x, good.lam_g)
    assert out.success and out.status == "Solve_Succeeded" and out.iterations == 0
    # from the shifted guess with the deadline already passed: no QP, the guess returned, named status
    out = sqp.solve(data.x0, data.p, data.lam_x0, data.lam_g0, deadline=sqp.clock() - 1.0)
    assert not out.success and out.status == "Maximum_Wall_Time_Exceeded" and out.iterations == 0
    np.testing.assert_array_equal(out.w, np.clip(data.x0, sqp.lbw, sqp.ubw))


def test_real_time_iteration_is_one_full_qp_step():
    rti = NmpcController(strategy_settings("ceco", solver=SolverSettings(rti=True)))
    full = NmpcController("ceco")
    for k in range(4):
        c_r, d_r = rti.compute(_obs(k, t_cab=27.0 - 0.3 * k))
    assert d_r.status == "RTI_Step" and d_r.iterations == 1 and d_r.success and d_r.fallback == ""
    assert rti.counters.rti_steps == 3 and rti.counters.cold_solves == 1
    # one QP from the shifted solution lands on the converged optimum of the SAME instance (the RTI's last NLP,
    # solved to convergence by the full SQP from the same start): the true cost of applying the RTI plan (slacks
    # raised to feasibility) is that optimum to 1e-8, and the step took at least 90 % of the way from the start
    # (a half step failed this, run by hand)
    data, prob = rti.last_nlp(), rti.problem
    ref = full.solve_nlp(data)
    assert ref.success and ref.iterations >= 1

    def true_cost(w):
        ev = prob.evaluate(repair_slacks(prob, w, data.p), data.p)
        return ev.J_e + ev.J_c + ev.J_i + ev.J_s + ev.J_du

    sqp = rti.solver.sqp
    j_rti, j0 = true_cost(rti._good.w), true_cost(np.clip(data.x0, sqp.lbw, sqp.ubw))
    assert ref.f * (1 - 1e-9) <= j_rti <= ref.f * (1 + 1e-8)
    assert j0 - j_rti >= 0.9 * (j0 - ref.f) > 0.0


def test_parameter_layout_names_every_slice():
    pl = ParamLayout(4)
    assert pl.names() == (
        "x0",
        "t_int",
        "t_shell",
        "d_cab",
        "d_evap",
        "d_ain",
        "u_prev",
        "t_amb",
        "solar",
        "speed",
        "pmv_lb",
        "pmv_ub",
        "t_mr",
        "pa",
        "recirc",
    )
    assert pl.size == 9 + 5 * 4 + 3
    p = pl.pack(
        x0=[1, 2],
        t_int=3,
        t_shell=4,
        d_cab=5,
        d_evap=6,
        d_ain=7,
        u_prev=[8, 9],
        t_amb=np.arange(4),
        solar=10 + np.arange(4),
        speed=20 + np.arange(4),
        pmv_lb=-1,
        pmv_ub=1,
        t_mr=30,
        pa=1700,
        recirc=0.8,
    )
    assert pl.scalar(p, "pa") == 1700 and p[-2] == 1700 and p[-1] == 0.8
    assert pl.scalar(p, "t_shell") == 4 and list(pl.get(p, "speed")) == [20, 21, 22, 23]
    assert list(pl.get(p, "u_prev")) == [8, 9] and list(pl.get(p, "pmv_lb")) == [-1] * 4
    with pytest.raises(ValueError, match="missing"):
        pl.pack(x0=[1, 2])
    with pytest.raises(ValueError, match="not 1"):
        pl.scalar(p, "x0")


def test_variable_and_row_layouts_shift_stage_blocks():
    vl = VariableLayout()
    for _ in range(3):
        vl.add("u", 2, 0.0, 1.0)
        vl.add("s_lo", 1, 0.0, np.inf)
    w = np.arange(vl.n, dtype=float)  # u blocks at 0, 3, 6; slacks at 2, 5, 8
    assert list(vl.starts("u")) == [0, 3, 6] and list(vl.indices("s_lo")) == [2, 5, 8]
    np.testing.assert_array_equal(vl.shift(w, 1), [3, 4, 5, 6, 7, 8, 6, 7, 8])
    np.testing.assert_array_equal(vl.shift(w, 2), [6, 7, 8, 6, 7, 8, 6, 7, 8])
    with pytest.raises(ValueError, match="blocks of 2"):
        vl.add("u", 3, 0.0, 1.0)
    import casadi

    rows = RowLayout()
    x = casadi.SX.sym("x", 2)
    for i in range(3):
        rows.add(i, 1, "pmv", x, [0, 0], [1, 1])
        rows.add(i, 0, "gap", x[0], [0], [0])
    rows.finalize()
    assert [list(b) for b in rows.rows["gap"]] == [[0], [3], [6]]
    lam = np.arange(9, dtype=float)
    np.testing.assert_array_equal(rows.shift(lam, 1), [3, 4, 5, 6, 7, 8, 6, 7, 8])


def test_a_converged_sqp_reports_the_stationarity_of_the_multipliers_it_returns(monkeypatch):
    """Every solve that reports success reports the Lagrangian gradient of the multipliers it returns, also when it
    stopped on a vanishing QP step (then the QP's multipliers, checked at the last linearisation): <= tol_du on the
    first 300 s of SC03 with ceco-ioch, where 21 of 59 solves end so (they reported 1.4-22: the previous
    multipliers')."""
    from ceco_controller import sqp as sqp_module
    from ceco_controller.closed_loop import SimSettings, simulate

    outcomes = []
    solve = sqp_module.Sqp.solve

    def recording(self, *a, **kw):
        out = solve(self, *a, **kw)
        outcomes.append((out, self.options.tol_du))
        return out

    monkeypatch.setattr(sqp_module.Sqp, "solve", recording)
    simulate("sc03", "ceco-ioch", SimSettings(progress=False, duration_s=300.0))
    done = [(o, tol) for o, tol in outcomes if o.success]
    assert len(done) >= 50 and sum(o.iterations == 2 for o, _ in done) >= 10
    assert all(o.dual_infeasibility <= tol for o, tol in done), max(o.dual_infeasibility for o, _ in done)


def _rosenbrock_sqp(**options):
    """The Rosenbrock function inside a disc (x² + y² <= 1.5), from the classic start (-1.2, 1): the full
    QP step is rejected by the line search in early iterations (backtracking), accepted near the optimum."""
    import casadi

    from ceco_controller.sqp import Sqp, SqpOptions, sqp_functions

    w, p = casadi.SX.sym("w", 2), casadi.SX.sym("p", 1)
    nlp = {"x": w, "p": p, "f": (p[0] - w[0]) ** 2 + 100 * (w[1] - w[0] ** 2) ** 2, "g": w[0] ** 2 + w[1] ** 2}
    sqp = Sqp(sqp_functions(nlp), [-2, -2], [2, 2], [-np.inf], [1.5], SqpOptions(**options))
    ipopt = casadi.nlpsol("ref", "ipopt", nlp, {"print_time": False, "ipopt": {"print_level": 0, "tol": 1e-12}})
    ref = ipopt(x0=[-1.2, 1.0], p=[1.0], lbx=[-2, -2], ubx=[2, 2], lbg=[-np.inf], ubg=[1.5])
    return sqp, np.array(ref["x"]).ravel()


class _Counting:
    def __init__(self, fn):
        self.fn, self.calls, self.buf = fn, 0, fn.buf

    def __call__(self, *args):
        self.calls += 1
        return self.fn(*args)


def test_a_full_step_is_linearised_once_and_the_iterates_are_those_of_a_fresh_linearisation(monkeypatch):
    """The line search's full-step trial evaluates the whole linearisation (f, g, gradients, Jacobian, with the
    multipliers of a full step); when that step is taken it is the next iteration's, not evaluated again. The
    iterates, multipliers and residuals are those of a solve that linearises afresh at every iterate, to the bit,
    through backtracking steps too, and the optimum is IPOPT's."""
    from ceco_controller import sqp as sqp_module

    sqp, x_ref = _rosenbrock_sqp()
    jac, fg = _Counting(sqp._jac), _Counting(sqp._fg)
    sqp._jac, sqp._fg = jac, fg
    out = sqp.solve([-1.2, 1.0], [1.0])
    assert out.success and out.status == "Solve_Succeeded" and out.iterations >= 5
    np.testing.assert_allclose(out.w, x_ref, atol=1e-6)
    # one linearisation at the start, one per QP (the full step's trial), one more after each backtracked step;
    # shorter trials need only the merit (f, g). Measured: 15 QPs, 5 of them backtracked, 21 linearisations.
    backtracked = jac.calls - 1 - out.iterations
    assert 1 <= backtracked <= fg.calls and backtracked < out.iterations

    fresh, _ = _rosenbrock_sqp()
    fresh_jac = _Counting(fresh._jac)
    fresh._jac = fresh_jac
    with monkeypatch.context() as m:  # the trial's linearisation is never taken over: every iterate afresh
        m.setattr(sqp_module, "_same_point", lambda a, b: False)
        ref = fresh.solve([-1.2, 1.0], [1.0])
    assert fresh_jac.calls == 1 + 2 * ref.iterations  # (each iterate linearised twice: as a trial and afresh)
    for name in ("w", "lam_g", "lam_x", "g"):
        np.testing.assert_array_equal(getattr(out, name), getattr(ref, name), err_msg=name)
    assert (out.f, out.iterations, out.primal_infeasibility, out.dual_infeasibility, out.line_search_failures) == (
        ref.f,
        ref.iterations,
        ref.primal_infeasibility,
        ref.dual_infeasibility,
        ref.line_search_failures,
    )


def test_the_reused_linearisation_gives_the_iterates_of_a_fresh_one_on_the_ceco_nlp(monkeypatch):
    """On the CECO NLP (ceco-ioch and ceco at Np = 6, a pull-down and a comfort-zone instance each), each solve
    with the full step's linearisation taken over equals, to the bit, the solve that linearises afresh at every
    iterate (a new QP solver before each: qpOASES hot-starts from the previous call's active set)."""
    from ceco_controller import sqp as sqp_module

    compared = 0
    for strategy in ("ceco-ioch", "ceco"):
        ctrl = NmpcController(strategy)
        sqp = ctrl.solver.sqp
        for k, t_cab in enumerate((29.0, 28.0, 24.5, 24.4)):
            ctrl.compute(_obs(k, t_cab=t_cab, speed=4.0 * k))
            data = ctrl.last_nlp()
            sqp.reset()
            out = sqp.solve(data.x0, data.p, data.lam_x0, data.lam_g0)
            with monkeypatch.context() as m:
                m.setattr(sqp_module, "_same_point", lambda a, b: False)
                sqp.reset()
                ref = sqp.solve(data.x0, data.p, data.lam_x0, data.lam_g0)
            assert out.success and out.iterations >= 1, (strategy, k, out.status)
            for name in ("w", "lam_g", "lam_x", "g"):
                np.testing.assert_array_equal(getattr(out, name), getattr(ref, name), err_msg=f"{strategy} {k} {name}")
            assert (out.f, out.iterations, out.dual_infeasibility) == (ref.f, ref.iterations, ref.dual_infeasibility)
            compared += out.iterations >= 2  # (a taken-over linearisation was used by a second QP)
    assert compared >= 2
