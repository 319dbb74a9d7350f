"""Initial guesses of the CECO NLP: the cold model-rollout guess and the shifted warm start.

Pure numpy on top of an :class:`~ceco_controller.transcription.NlpProblem`.
"""

from __future__ import annotations

import numpy as np

from .transcription import CO2_SCALE_PPM, NlpProblem

__all__ = ["SLACK_GUESS_MARGIN", "initial_guess", "repair_slacks"]

SLACK_GUESS_MARGIN = 1e-5
"""Margin of the guessed comfort/T_evap slacks above their smallest feasible value [PMV or K]: near
the warm solver's barrier (slack x multiplier ~ 1e-5 x rho); 1e-3 started the warm solves with a
complementarity of ~1 and cost one IPOPT iteration (docs/controller.md 4.6)."""


def initial_guess(problem: NlpProblem, p: np.ndarray, w_prev: np.ndarray | None = None, stages: int = 1) -> np.ndarray:
    """Primal guess, consistent with the dynamics and the comfort constraints at ``p``.

    Inputs: the previous solution ``w_prev`` shifted by ``stages`` stages if given, else the
    previous command (parameter ``u_prev``) held. States (multiple shooting): rolled out by the
    model from the measured state (so the guess closes every gap). Slacks: the smallest values
    that satisfy the comfort and T_evap constraints at the guess (plus a small margin).
    ``eps`` (ioch): shifted, or eps_UB/2.
    """
    s, pl, vl, lim = problem.settings, problem.params, problem.vars, problem.limits
    if w_prev is not None:
        w = vl.shift(w_prev, stages)
    else:
        w = np.zeros(vl.n)
        u_prev = pl.get(p, "u_prev")
        u = np.array(lim.clip(u_prev[0], u_prev[1]))
        if problem.door:  # the previous door share (a parameter in [0, 1] by construction) held too
            u = np.append(u, min(max(float(u_prev[2]), 0.0), 1.0))
        vl.set_blocks(w, "u", u)
        if s.ioch:
            vl.set_blocks(w, "eps", 0.5 * s.eps_ub)
    w = np.minimum(np.maximum(w, problem.lbw), problem.ubw)  # np.clip's own, without its wrapper's cost
    if vl.count("x"):  # multiple shooting: the states rolled out by the model
        vl.set_blocks(w, "x", problem.rollout_states(vl.blocks(w, "u"), p))
    margin = SLACK_GUESS_MARGIN
    for key, need in zip(_SLACK_KEYS, _smallest_slacks(problem, w, p)):
        w[vl.indices(key)] = need + margin
    return np.minimum(np.maximum(w, problem.lbw), problem.ubw)


_SLACK_KEYS = ("s_lo", "s_up", "s_ev", "s_co2", "s_fog")
"""The slacks of :func:`_smallest_slacks`, in its order."""


def _smallest_slacks(problem: NlpProblem, w: np.ndarray, p: np.ndarray):
    """The smallest slacks that satisfy their rows: comfort, T_evap, CO2 and fog (the last two: door NLP)."""
    s, pl, vl = problem.settings, problem.params, problem.vars
    ev = problem.evaluate(w, p)
    lb = pl.get(p, "pmv_lb")
    ub = pl.get(p, "pmv_ub") - s.pmv_margin
    eps = w[vl.indices("eps")] if s.ioch else 0.0
    return (
        np.maximum(lb - ev.pmv, 0.0),
        np.maximum(ev.pmv + eps - ub, 0.0),
        np.maximum(np.maximum(s.t_evap_lb_c - ev.t_evap, ev.t_evap - s.t_evap_ub_c), 0.0),
        np.maximum(ev.co2 - pl.get(p, "co2_max"), 0.0) / CO2_SCALE_PPM if problem.door else np.zeros(0),
        np.maximum(-ev.fog_row, 0.0) if problem.door else np.zeros(0),
    )


def repair_slacks(problem: NlpProblem, w: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``w`` with every comfort/T_evap slack raised to the smallest value that satisfies its row.

    For single shooting this makes any point within the variable bounds feasible; the objective at
    the result is the true cost of applying its inputs (used to measure the optimality loss of the
    real-time iteration, docs/controller.md 4.6). Multiple shooting: the gap rows stay as they are.
    """
    out = np.array(w, float)
    vl = problem.vars
    for key, need in zip(_SLACK_KEYS, _smallest_slacks(problem, out, p)):
        ix = vl.indices(key)
        out[ix] = np.maximum(out[ix], need)
    return out
