"""Long horizons: the SQP with HPIPM's Riccati QPs on the multiple-shooting stages reaches IPOPT's optimum.

The instances are recorded warm NLP instances of closed-loop SC03 runs at Np = 24 and 60
(``tests/data/nlp_instances.npz``, written by ``tools/record_nlp_instances.py``: the parameters and
the shifted primal-dual warm start the controller's solve chain used). Each is solved by the
product's warm solver (``name: auto`` beyond ``single_shooting_max_steps``) and, cold, by IPOPT with
its default settings (the benchmark's reference); the optima must agree.
"""

from pathlib import Path

import numpy as np
import pytest

from ceco_controller.nmpc import NmpcController
from ceco_controller.solvers import NlpData
from ceco_controller.strategies import CECO_STRATEGIES, SolverSettings, strategy_settings

DATA = Path(__file__).parent / "data" / "nlp_instances.npz"
REGENERATE = "regenerate with `python tools/record_nlp_instances.py` (the NLP changed)"


@pytest.fixture(scope="module")
def instances():
    with np.load(DATA, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


@pytest.mark.parametrize("horizon", [24, 60])
@pytest.mark.parametrize("strategy", CECO_STRATEGIES)
def test_hpipm_sqp_reaches_ipopts_optimum_on_recorded_instances(instances, strategy, horizon):
    key = f"{strategy}_np{horizon}"
    ctrl = NmpcController(strategy_settings(strategy, horizon_steps=horizon))
    s = ctrl.settings.solver
    assert (s.name, s.qpsol, ctrl.transcription) == ("sqp", "hpipm", "multiple-shooting")
    structure = ctrl.problem.ocp_structure()
    n = ctrl.settings.nlp_steps  # the horizon, plus ceco-pmv's extension beyond the previews
    assert len(structure.nx) == n + 2 and sum(structure.nx) + sum(structure.nu) == ctrl.problem.nw
    ps, x0s = instances[f"{key}_p"], instances[f"{key}_x0"]
    assert ps.shape[0] >= 5
    assert ps.shape[1] == ctrl.problem.params.size and x0s.shape[1] == ctrl.problem.nw, REGENERATE
    reference = ctrl.make_solver(SolverSettings(name="ipopt", default_options=True))
    for i in range(ps.shape[0]):
        p = ps[i]
        warm = NlpData(p=p, x0=x0s[i], lam_x0=instances[f"{key}_lam_x0"][i], lam_g0=instances[f"{key}_lam_g0"][i])
        ours = ctrl.solver.solve(warm)
        ref = reference.solve(NlpData(p=p, x0=ctrl.initial_guess(p)))
        assert ours.success and ours.status == "Solve_Succeeded", (i, ours.status)
        assert ref.success, (i, ref.status)
        assert 1 <= ours.iterations <= 6  # warm: one or a few QPs (IPOPT's defaults: 8-15 iterations)
        assert ours.violation <= 1e-6 and ref.violation <= 1e-6
        # the same optimum: cost to 1e-5 relative (the warm solvers stop at a stationarity of 1e-4 kJ; the
        # Np = 6 product is within 6.2e-6 of IPOPT's defaults, docs/controller.md), the command to 1e-3 of its range
        assert ours.f == pytest.approx(ref.f, rel=1e-5), (i, ours.f, ref.f)
        u_ours, u_ref = ctrl.problem.plan(ours.w)[0], ctrl.problem.plan(ref.w)[0]
        assert abs(u_ours[0] - u_ref[0]) <= 1e-3 * 0.12 and abs(u_ours[1] - u_ref[1]) <= 1e-3 * 7.0, (i, u_ours, u_ref)


def test_hpipm_is_called_afresh_on_every_qp(instances):
    """Two different QPs in turn through the SQP's QP call give each its own solution (CasADi 3.8.2's
    hpipm conic reads its QP data when a buffer is set up, so a reused buffer solves the first QP
    again; the SQP binds a new buffer per call), and HPIPM's step equals dense qpOASES' on the same QP."""
    from ceco_controller.sqp import Sqp, SqpOptions, sqp_functions

    ctrl = NmpcController(strategy_settings("ceco", horizon_steps=24))
    prob, sqp = ctrl.problem, ctrl.solver.sqp
    dense = Sqp(sqp_functions(prob.nlp), prob.lbw, prob.ubw, prob.lbg, prob.ubg, SqpOptions(qpsol="qpoases"))
    steps = []
    for i in (0, 3, 0):
        p, w = instances["ceco_np24_p"][i], instances["ceco_np24_x0"][i]
        lam = instances["ceco_np24_lam_g0"][i]
        qps = []
        for s in (sqp, dense):
            _, _, g, gf, jac, _ = s._linearise(w, p, lam)
            (hess,) = s._hess(w, p, lam)
            d, *_ = s._qp(s.convexify(hess), gf, jac, s.lbg - g, s.ubg - g, s.lbw - w, s.ubw - w)
            qps.append(np.array(d))
        np.testing.assert_allclose(qps[0], qps[1], rtol=0, atol=1e-6 * max(1.0, np.abs(qps[1]).max()))
        steps.append(qps[0])
    assert np.abs(steps[0] - steps[1]).max() > 1e-3  # different instances, different steps
    np.testing.assert_allclose(steps[2], steps[0], rtol=0, atol=1e-9)  # ... and the first again
