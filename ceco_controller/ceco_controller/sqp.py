"""ceco's SQP for the CECO NLP: exact Hessian, exact eigenvalue convexification, a dense or a Riccati QP.

Solves  min f(w)  s.t.  lbg <= g(w) <= ubg,  lbw <= w <= ubw  (parameters p fixed) by

    QP_k:  min_d  1/2 d' H_k d + grad f(w_k)' d
           s.t.   lbg - g(w_k) <= J(w_k) d <= ubg - g(w_k),   lbw - w_k <= d <= ubw - w_k

with H_k the Hessian of the Lagrangian f + lam_g' g made positive definite block by block: each
diagonal block of its sparsity pattern (the connected components of its graph: at Np = 6 in
single shooting one 12 x 12 input block; in multiple shooting one block per stage; the IOCH
slacks are 1 x 1 blocks; the comfort/T_evap slacks enter linearly and have none) is decomposed
exactly (LAPACK ``syevd`` via ``numpy.linalg.eigh``, blocks of one size in one batched call) and
its eigenvalues are clipped from below at ``eig_floor`` (Nocedal & Wright, *Numerical
Optimization*, 2nd ed., 2006, Sec. 3.4); a block whose eigenvalues are all >= ``eig_floor`` is
left as it is (a lone block of its size, as single shooting's input block, is first tried by a
Cholesky factorisation of H - eig_floor I, LAPACK ``dpotrf``: when it exists no eigenvectors are
needed; about half of the SC03 blocks). Unlike an iterative Jacobi eigen-solver with an iteration limit, the
decomposition cannot stop short; should LAPACK ever report non-convergence, the block is shifted
by its Gershgorin bound instead, which is positive definite by construction.

The QP (``qpsol``):

* ``qpoases``: dense qpOASES (active set) on the whole QP; for the single-shooting NLP (32-39
  variables at Np = 6), where the dense set-up is cheapest.
* ``hpipm``: HPIPM's interior-point method on the optimal-control structure of the
  multiple-shooting NLP (Frison & Diehl, IFAC 2020): a Riccati recursion per iteration, so the
  cost grows linearly with Np. The stages are those of the transcription
  (:meth:`~ceco_controller.transcription.NlpProblem.ocp_structure`): stage i holds x_i (none at
  i = 0, where the state is a parameter), then u_i and the slacks s_i (only s_N at the last grid
  point, an extra stage without dynamics), its gap rows first, then its comfort/T_evap rows.
* ``qrqp``: CasADi's active-set QP (dense), kept for comparisons.

Globalisation: the l1 merit function phi(w) = f(w) + sigma * theta(w), theta the sum of the
constraint violations (the QP keeps w inside its bounds), with sigma >= 1.1 max |lam_QP|, and a
non-monotone Armijo backtracking line search (Nocedal & Wright Alg. 18.3; memory of
``merit_memory`` values as in CasADi's ``sqpmethod``). The full step's trial evaluates the whole
linearisation there (``jac``, with the multipliers of a full step), which is the next iteration's when
the full step is taken (nearly always): one NLP evaluation per iteration fewer than a merit-only trial,
the same numbers to the bit (``tests/test_sqp.py``). Converged when the constraint violation is
<= ``tol_pr`` and the Lagrangian gradient's infinity norm is <= ``tol_du``, or when the QP step
vanishes at a feasible point (then w is a KKT point whatever H is).

Bounded cost: at most ``max_iter`` QPs, and a wall-clock deadline checked before every QP and
every line-search trial. ``rti=True`` is the real-time iteration (Diehl, Bock, Schloeder, SIAM J.
Control Optim. 43(5), 2005): exactly one full QP step from the (shifted) warm start.

The NLP functions are three CasADi Functions built once (:func:`sqp_functions`: ``jac`` f, g,
grad f, J and the Lagrangian gradient; ``hess`` H on its block pattern; ``fg`` f, g), evaluated in
place on preallocated arrays (their non-zeros, in CasADi's column-major order, are what the QP
solver reads), in-process or from compiled C (:mod:`ceco_controller.codegen`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from typing import Any

import casadi
import numpy as np
from scipy.linalg.lapack import dpotrf as _dpotrf
from scipy.sparse.csgraph import connected_components

from .buffered import BufferedFunction
from .nlp_layout import OcpStructure

__all__ = ["SqpOptions", "Sqp", "SqpFunctions", "sqp_functions", "hessian_blocks", "QP_SOLVERS"]

QP_SOLVERS = ("qpoases", "hpipm", "qrqp")
"""QP solvers the SQP can use (module docstring)."""

HPIPM_INF = 1e4
"""What HPIPM reads for an infinite bound of a QP step [variable or constraint unit]. The steps of
this NLP are temperatures, flows and PMV slacks, far below it; HPIPM's default 1e8 made its
complementarity residual stall (100 iterations without its stopping test on every instance tried)."""


@dataclasses.dataclass(frozen=True)
class SqpOptions:
    """Settings of :class:`Sqp`."""

    max_iter: int = 20
    """QP iterations per solve [-]."""
    tol_pr: float = 1e-6
    """Constraint violation at convergence [constraint units: PMV, K]."""
    tol_du: float = 1e-4
    """Infinity norm of the Lagrangian gradient at convergence [kJ per variable unit]."""
    min_step: float = 1e-9
    """Relative QP step (inf norm / (1 + |w|_inf)) below which a feasible iterate is a KKT point [-]."""
    eig_floor: float = 1e-7
    """Smallest eigenvalue of each convexified Hessian block [kJ per variable unit^2] (CasADi's default margin)."""
    armijo: float = 1e-4
    """Sufficient-decrease constant of the line search [-]."""
    backtrack: float = 0.5
    """Step reduction per line-search trial [-]."""
    max_ls: int = 8
    """Line-search trials per iteration [-]; when all fail the last (smallest) step is taken."""
    merit_memory: int = 4
    """Merit values the non-monotone line search compares against [-]."""
    rti: bool = False
    """Real-time iteration: one full QP step, no line search, no convergence test."""
    qp_cpu_time_s: float = 0.05
    """CPU-time limit of one QP (qpOASES ``CPUtime``) [s]."""
    qpsol: str = "qpoases"
    """QP solver (:data:`QP_SOLVERS`)."""


@dataclasses.dataclass
class SqpFunctions:
    """What :func:`sqp_functions` builds: the Functions, the Hessian's blocks and the output patterns."""

    functions: dict[str, casadi.Function]
    """``jac(w, p, lam_g) -> (f, g, grad_f, jac_g, grad_lag)``, ``hess(w, p, lam_g) -> hess_l``,
    ``fg(w, p) -> (f, g)``."""
    blocks: list[np.ndarray]
    """Variable indices of each diagonal block of the Hessian with curvature (connected components)."""
    hess_sparsity: casadi.Sparsity
    """Pattern of ``hess_l``: dense (dense QP) or the union of the dense blocks (HPIPM)."""
    jac_sparsity: casadi.Sparsity
    """Pattern of ``jac_g``: dense (dense QP) or its structural pattern (HPIPM)."""
    structure: OcpStructure | None = None
    """The stage structure (HPIPM), None for a dense QP."""


def hessian_blocks(pattern: casadi.Sparsity) -> list[np.ndarray]:
    """Variable indices of the connected components of a symmetric pattern that have any entry."""
    n = pattern.size1()
    rows, cols = pattern.get_triplet()
    adj = np.zeros((n, n), bool)
    adj[rows, cols] = True
    ncomp, label = connected_components(adj, directed=False)
    has_curv = np.zeros(n, bool)
    has_curv[rows] = True
    blocks = [np.flatnonzero(label == c) for c in range(ncomp)]
    return [b for b in blocks if has_curv[b].any()]


def sqp_functions(nlp: dict, structure: OcpStructure | None = None) -> SqpFunctions:
    """The Functions the SQP evaluates and the patterns of their matrix outputs.

    ``jac(w, p, lam_g) -> (f, g, grad_f, jac_g, grad_lag)`` with grad_lag = grad_f + J' lam_g,
    ``hess(w, p, lam_g) -> hess_l`` (the Hessian of f + lam_g' g, symmetric) and ``fg(w, p) -> (f, g)``
    (line search). Without ``structure`` (dense QP) the matrices are dense (column-major buffers);
    with it (HPIPM) ``jac_g`` has its structural pattern and ``hess_l`` the union of the dense blocks of
    the Hessian's pattern (the convexified blocks are dense).
    """
    w, p, f, g = nlp["x"], nlp["p"], nlp["f"], nlp["g"]
    lam = casadi.SX.sym("lam_g", g.numel())
    hess, _ = casadi.hessian(f + casadi.dot(lam, g), w)
    jac = casadi.jacobian(g, w)
    grad_f = casadi.gradient(f, w)
    grad_lag = grad_f + casadi.mtimes(jac.T, lam)
    blocks = hessian_blocks(hess.sparsity())
    if structure is None:
        hess_out, jac_out = casadi.densify(hess), casadi.densify(jac)
    else:
        nw = w.numel()
        r: list[int] = []
        c: list[int] = []
        for b in blocks:
            rr, cc = np.meshgrid(b, b, indexing="ij")
            r += rr.ravel().tolist()
            c += cc.ravel().tolist()
        hess_out = casadi.project(hess, casadi.Sparsity.triplet(nw, nw, r, c))
        jac_out = jac
    d = casadi.densify
    return SqpFunctions(
        functions={
            "jac": casadi.Function(
                "ceco_sqp_jac",
                [w, p, lam],
                [f, g, d(grad_f), jac_out, d(grad_lag)],
                ["w", "p", "lam_g"],
                ["f", "g", "grad_f", "jac_g", "grad_lag"],
            ),
            "hess": casadi.Function("ceco_sqp_hess", [w, p, lam], [hess_out], ["w", "p", "lam_g"], ["hess_l"]),
            "fg": casadi.Function("ceco_sqp_fg", [w, p], [f, g], ["w", "p"], ["f", "g"]),
        },
        blocks=blocks,
        hess_sparsity=hess_out.sparsity(),
        jac_sparsity=jac_out.sparsity(),
        structure=structure,
    )


@dataclasses.dataclass
class SqpOutcome:
    """One :meth:`Sqp.solve` result (converted to a SolveResult by the caller)."""

    success: bool
    status: str
    iterations: int
    w: np.ndarray
    f: float
    lam_x: np.ndarray
    lam_g: np.ndarray
    g: np.ndarray
    primal_infeasibility: float
    """Largest constraint violation at ``w`` (``w`` is always inside its bounds) [constraint units]."""
    dual_infeasibility: float
    line_search_failures: int


def _nonzero_index(sp: casadi.Sparsity) -> np.ndarray:
    """(n, n) array: the non-zero index of each entry of a pattern (-1 where structurally zero)."""
    idx = np.full((sp.size1(), sp.size2()), -1, dtype=np.intp)
    rows, cols = sp.get_triplet()
    idx[rows, cols] = np.arange(sp.nnz())
    return idx


def _same_point(a: np.ndarray, b: np.ndarray) -> bool:
    """The two arrays hold the same bits (-0.0 and 0.0 differ; about 1 us against 5 for ``numpy.array_equal``)."""
    return a.tobytes() == b.tobytes()


class Sqp:
    """The SQP for one NLP, built once; :meth:`solve` solves one instance."""

    def __init__(
        self,
        functions: SqpFunctions,
        lbw,
        ubw,
        lbg,
        ubg,
        options: SqpOptions | None = None,
        clock: Callable[[], float] = time.perf_counter,
    ):
        self.options = o = options or SqpOptions()
        self.clock = clock
        self.lbw, self.ubw = np.asarray(lbw, float), np.asarray(ubw, float)
        self.lbg, self.ubg = np.asarray(lbg, float), np.asarray(ubg, float)
        nw, ng = self.lbw.size, self.lbg.size
        self.nw, self.ng = nw, ng
        fns = functions.functions
        self._jac = BufferedFunction(fns["jac"])
        self._hess = BufferedFunction(fns["hess"])
        self._fg = BufferedFunction(fns["fg"])
        self.hess_sparsity = functions.hess_sparsity
        """Pattern of the Hessian's non-zeros as :meth:`convexify` and the QP read them."""
        # the diagonal blocks with curvature: 1 x 1 blocks clipped elementwise, the others by an
        # eigendecomposition, batched per block size; all addressed by their non-zero indices
        nz = _nonzero_index(functions.hess_sparsity)
        blocks = functions.blocks
        self._diag1 = np.array([b[0] for b in blocks if b.size == 1], dtype=int)
        """Variables of the 1 x 1 blocks."""
        self._diag1_nz = nz[self._diag1, self._diag1]
        self._dense = [(b, np.ix_(b, b)) for b in blocks if b.size > 1]
        """(variables, index) of each dense block."""
        by_size: dict[int, list[np.ndarray]] = {}
        for b, ix in self._dense:
            by_size.setdefault(b.size, []).append(nz[ix])
        self._groups = [np.stack(g) for g in by_size.values()]
        """Per block size: the non-zero indices of every block of that size, shape (m, k, k)."""
        self._floor_eye = {k: o.eig_floor * np.eye(k) for k in by_size}
        """eig_floor I per block size (the Cholesky test of :meth:`_above_floor`)."""
        if np.any(self._diag1_nz < 0) or any(np.any(g < 0) for g in self._groups):
            raise ValueError("Sqp: the Hessian's pattern does not hold its diagonal blocks")
        # error_on_fail: a failed QP raises (caught below), so a solved one needs no stats() call
        h_sp, a_sp = functions.hess_sparsity, functions.jac_sparsity
        qp_opts: dict[str, Any]
        if o.qpsol == "qpoases":
            qp_opts = {"printLevel": "none", "sparse": False, "error_on_fail": True, "CPUtime": o.qp_cpu_time_s}
        elif o.qpsol == "hpipm":
            if functions.structure is None:
                raise ValueError("Sqp: qpsol 'hpipm' needs the NLP's stage structure (multiple shooting)")
            s = functions.structure
            qp_opts = {"N": len(s.nx) - 1, "nx": list(s.nx), "nu": list(s.nu), "ng": list(s.ng)}
            qp_opts.update({"inf": HPIPM_INF, "error_on_fail": True})
        elif o.qpsol == "qrqp":
            qp_opts = {"print_iter": False, "print_header": False, "error_on_fail": True}
        else:
            raise ValueError(f"SqpOptions.qpsol must be one of {QP_SOLVERS}, got {o.qpsol!r}")
        if o.qpsol != "hpipm" and not (h_sp.is_dense() and a_sp.is_dense()):
            raise ValueError(f"Sqp: qpsol {o.qpsol!r} needs the dense functions (sqp_functions without structure)")
        self._qp_spec = ({"h": h_sp, "a": a_sp}, qp_opts)
        self.reset()
        self.n_eig_fallbacks = 0
        """Blocks convexified by the Gershgorin shift because LAPACK reported non-convergence."""

    def reset(self) -> None:
        """A new QP solver, as at construction.

        CasADi's qpOASES interface hot-starts each QP from the previous call's active set, so the
        iterates (not the solution) depend on every QP solved before; a new solver makes the next
        solves what a freshly built controller's are, bit for bit.
        """
        from .codegen import stdout_silenced  # qpOASES prints its banner when the QP is created

        o = self.options
        patterns, qp_opts = self._qp_spec
        with stdout_silenced():
            self.qp = casadi.conic("ceco_sqp_qp", o.qpsol, patterns, qp_opts)
            # qpOASES: h, g, a, lba, uba, lbx, ubx bound (no initial guess). HPIPM: every input bound (it reads
            # the guess), on a new buffer per call: CasADi 3.8.2's hpipm conic reads its QP data when the
            # buffer is set up and would solve the first QP again (tests/test_long_horizon.py)
            hpipm = o.qpsol == "hpipm"
            self._qp = BufferedFunction(self.qp, n_args=None if hpipm else 7, fresh_buffer=hpipm)

    # ------------------------------------------------------------ pieces
    def convexify(self, h: np.ndarray) -> np.ndarray:
        """The Hessian made positive definite per block (eigenvalues clipped at ``eig_floor``).

        ``h``: its non-zeros (as ``hess`` returns them) or, for the dense functions, the (nw, nw)
        matrix; the result has the same shape.
        """
        shape = h.shape
        hnz = h.ravel(order="F") if h.ndim == 2 else h
        out = hnz.copy()
        floor = self.options.eig_floor
        out[self._diag1_nz] = np.maximum(hnz[self._diag1_nz], floor)
        for gix in self._groups:
            hb = hnz[gix]
            hb = 0.5 * (hb + hb.transpose(0, 2, 1))
            if len(hb) == 1 and self._above_floor(hb[0]):  # (single shooting's one input block)
                out[gix] = hb
                continue
            try:
                lam, vec = np.linalg.eigh(hb)
            except np.linalg.LinAlgError:  # LAPACK did not converge on some block: one by one
                out[gix] = np.stack([self._convexify_block(b) for b in hb])
                continue
            rec = np.matmul(vec * np.maximum(lam, floor)[:, None, :], vec.transpose(0, 2, 1))
            keep = lam.min(axis=1) >= floor  # already convex enough: left as it is
            rec[keep] = hb[keep]
            out[gix] = rec
        return out.reshape(shape, order="F") if h.ndim == 2 else out

    def _above_floor(self, hb: np.ndarray) -> bool:
        """Every eigenvalue of the symmetric block ``hb`` is above ``eig_floor``: hb - floor I has a Cholesky factor.

        LAPACK ``dpotrf`` called directly (about 2 us on a 12 x 12 block, against 13 us for ``numpy.linalg.eigh``);
        a block it factors is left as it is, as :meth:`convexify` leaves one whose eigenvalues are all >= the floor.
        """
        _, info = _dpotrf(hb - self._floor_eye[len(hb)], overwrite_a=1, clean=0)
        return info == 0

    def _convexify_block(self, hb: np.ndarray) -> np.ndarray:
        floor = self.options.eig_floor
        try:
            lam, vec = np.linalg.eigh(hb)
        except np.linalg.LinAlgError:
            self.n_eig_fallbacks += 1
            radius = np.sum(np.abs(hb), axis=1) - np.abs(np.diag(hb))
            shift = max(0.0, float(np.max(radius - np.diag(hb)))) + floor
            return hb + shift * np.eye(hb.shape[0])
        return hb if lam.min() >= floor else (vec * np.maximum(lam, floor)) @ vec.T

    def _violation(self, g: np.ndarray) -> np.ndarray:
        return np.maximum(np.maximum(self.lbg - g, g - self.ubg), 0.0)

    def _clip(self, w: np.ndarray) -> np.ndarray:
        return np.minimum(np.maximum(w, self.lbw), self.ubw)

    def _linearise(self, w, p, lam_g):
        f_buf, g, gf, jac, glag = self._jac(w, p, lam_g)
        f = float(f_buf[0])
        # one sum per array: NaN and inf propagate (an overflow of huge finite values is flagged too)
        ok = math.isfinite(f + float(g.sum()) + float(gf.sum()) + float(jac.sum()))
        return ok, f, g.copy(), gf.copy(), jac.copy(), glag

    def _merit_eval(self, w, p):
        f_buf, g = self._fg(w, p)
        return float(f_buf[0]), g.copy()

    # ------------------------------------------------------------ solve
    def solve(self, w0, p, lam_x0=None, lam_g0=None, deadline: float | None = None) -> SqpOutcome:
        """Solve from ``w0`` (clipped into the bounds) with multipliers ``lam_*0`` (default 0).

        ``deadline``: absolute time on ``clock`` after which no further QP or line-search trial starts.
        """
        o = self.options
        w = self._clip(np.asarray(w0, float))
        lam_g = np.zeros(self.ng) if lam_g0 is None else np.array(lam_g0, float)
        lam_x = np.zeros(self.nw) if lam_x0 is None else np.array(lam_x0, float)
        p = np.asarray(p, float)
        sigma = 0.0
        merits: list[float] = []
        n_ls_fail = 0
        status, success = "Maximum_Iterations_Exceeded", False
        f, g = math.nan, np.full(self.ng, math.nan)
        pr = du = math.inf
        it = 0
        max_it = 1 if o.rti else o.max_iter
        lin_next = None  # the linearisation at the next iterate, when the line search made it (below)
        while True:
            if lin_next is None:
                ok, f, g, gf, jac, glag = self._linearise(w, p, lam_g)
            else:
                ok, f, g, gf, jac, glag = lin_next
                lin_next = None
            if not ok:
                status = "Invalid_Number_Detected"
                pr = float(self._violation(g).max(initial=0.0)) if math.isfinite(float(g.sum())) else math.inf
                break
            viol = self._violation(g)
            pr = float(viol.max(initial=0.0))
            du = float(np.abs(glag + lam_x).max(initial=0.0))
            if not o.rti and pr <= o.tol_pr and du <= o.tol_du:
                status, success = "Solve_Succeeded", True
                break
            if it >= max_it:
                break
            if deadline is not None and self.clock() >= deadline:
                status = "Maximum_Wall_Time_Exceeded"
                break
            (hess,) = self._hess(w, p, lam_g)
            if not math.isfinite(float(hess.sum())):
                status = "Invalid_Number_Detected"
                break
            try:
                x_qp, _, lam_a_qp, lam_x_qp = self._qp(
                    self.convexify(hess), gf, jac, self.lbg - g, self.ubg - g, self.lbw - w, self.ubw - w
                )
            except RuntimeError:
                status = f"QP_Failed ({self._qp.buf.stats().get('return_status', 'unknown')})"
                break
            d = x_qp.copy()
            if not math.isfinite(float(d.sum())):
                status = "QP_Failed (non-finite step)"
                break
            lam_g_qp, lam_x_qp = lam_a_qp.copy(), lam_x_qp.copy()
            it += 1
            if o.rti:
                w = self._clip(w + d)
                lam_g, lam_x = lam_g_qp, lam_x_qp
                f, g = self._merit_eval(w, p)
                pr = float(self._violation(g).max(initial=0.0)) if math.isfinite(float(g.sum())) else math.inf
                du = math.nan
                success = math.isfinite(f) and math.isfinite(pr)
                status = "RTI_Step" if success else "Invalid_Number_Detected"
                break
            if float(np.abs(d).max(initial=0.0)) <= o.min_step * (1.0 + float(np.abs(w).max())) and pr <= o.tol_pr:
                lam_g, lam_x = lam_g_qp, lam_x_qp
                # the multipliers returned are the QP's: the stationarity reported is theirs, at w (the jac
                # function's Lagrangian gradient with them)
                du = float(np.abs(self._jac(w, p, lam_g)[4] + lam_x).max(initial=0.0))
                status, success = "Solve_Succeeded", True
                break
            # l1 merit, non-monotone Armijo backtracking
            sigma = max(sigma, 1.1 * float(np.abs(lam_g_qp).max(initial=0.0)) + 1e-8)
            theta = float(viol.sum())
            phi = f + sigma * theta
            merits = (merits + [phi])[-o.merit_memory :]
            slope = float(gf @ d) - sigma * theta
            alpha, accepted = 1.0, False
            # the full step's trial is a whole linearisation (with the multipliers a full step gives, as updated
            # below): when the full step is taken it is the next iteration's, and no second evaluation at that
            # point is made. A shorter trial only needs the merit (f, g).
            lam_g_full = lam_g + alpha * (lam_g_qp - lam_g)
            lin_full = None
            for _ in range(o.max_ls):
                w_trial = w + alpha * d
                if lin_full is None:
                    lin_full = self._linearise(w_trial, p, lam_g_full)
                    ft, gt = lin_full[1], lin_full[2]
                else:
                    ft, gt = self._merit_eval(w_trial, p)
                if math.isfinite(ft + float(gt.sum())):
                    phit = ft + sigma * float(self._violation(gt).sum())
                    if phit <= max(merits) + o.armijo * alpha * min(slope, 0.0):
                        accepted = True
                        break
                if deadline is not None and self.clock() >= deadline:
                    break
                alpha *= o.backtrack
            n_ls_fail += not accepted
            w_step = w + alpha * d
            w = self._clip(w_step)
            lam_x = lam_x + alpha * (lam_x_qp - lam_x)
            if alpha == 1.0:
                lam_g = lam_g_full
                if lin_full is not None and _same_point(w, w_step):  # (the clip changed nothing)
                    lin_next = lin_full
            else:
                lam_g = lam_g + alpha * (lam_g_qp - lam_g)
        return SqpOutcome(
            success=success,
            status=status,
            iterations=it,
            w=w,
            f=f,
            lam_x=lam_x,
            lam_g=lam_g,
            g=g,
            primal_infeasibility=pr,
            dual_infeasibility=du,
            line_search_failures=n_ls_fail,
        )
