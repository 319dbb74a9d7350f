"""Tests of the ISO 7730:2005 draught rating (ceco_core.draught).

Reference data: tests/data/iso7730_draught.csv (the DR = 20 % / Tu = 40 %
speed limits of ISO 7730 Figure A.2 as tabulated in the Danish BR18 guidance).
"""

import csv
import pathlib

import casadi
import numpy as np
import pytest
from scipy.optimize import brentq

from ceco_core.draught import DR_CATEGORY_LIMITS_PCT, DR_EXACT, DraughtSmoothing, draught_rating, draught_validity

DATA = pathlib.Path(__file__).parent / "data"


def _worked_values():
    with open(DATA / "iso7730_draught.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    return [{k: float(v) for k, v in r.items()} for r in rows]


@pytest.mark.parametrize("smoothing", [DR_EXACT, DraughtSmoothing()], ids=["exact", "smooth"])
def test_speed_limits_for_category_b_match_the_published_table(smoothing):
    # the speed giving DR = 20 % rounds to the printed 2-decimal value (|error| <= 0.005 m/s)
    rows = _worked_values()
    assert len(rows) == 11
    for r in rows:

        def excess(v, r=r):
            return float(draught_rating(r["ta_c"], v, r["tu_pct"], smoothing=smoothing)) - r["dr_pct"]

        v = brentq(excess, 0.06, 1.0, xtol=1e-9)
        assert abs(v - r["vel_max_mps"]) <= 0.0051, (r, v)
    # category B is the 20 % line
    assert DR_CATEGORY_LIMITS_PCT["B"] == 20.0


def test_formula_values_floor_and_cap():
    # hand arithmetic: (34 - 20) * 0.1**0.62 * (0.37*0.15*40 + 3.14) = 14 * 0.239883 * 5.36
    assert float(draught_rating(20.0, 0.15, 40.0, smoothing=DR_EXACT)) == pytest.approx(18.0008, abs=1e-3)
    # the comfort-zone jet: 21 degC, 0.70 m/s, 40 % -> 134 % uncapped, 100 % capped
    assert float(draught_rating(21.0, 0.70, 40.0, cap=False, smoothing=DR_EXACT)) == pytest.approx(134.36, abs=0.01)
    assert float(draught_rating(21.0, 0.70, 40.0, smoothing=DR_EXACT)) == 100.0
    assert float(draught_rating(21.0, 0.70, 40.0)) == pytest.approx(100.0, abs=1e-12)
    # v below 0.05 m/s is taken as 0.05 m/s: DR = 0
    assert float(draught_rating(22.0, 0.01, 40.0, smoothing=DR_EXACT)) == 0.0
    assert 0.0 < float(draught_rating(22.0, 0.01, 40.0)) <= 0.36
    # air warmer than 34 degC: no draught (the formula's sign change is floored at 0)
    assert float(draught_rating(40.0, 0.5, 40.0, smoothing=DR_EXACT)) == 0.0
    # monotone: more speed or turbulence or colder air -> more draught
    base = float(draught_rating(23.0, 0.2, 30.0))
    assert float(draught_rating(23.0, 0.25, 30.0)) > base
    assert float(draught_rating(23.0, 0.2, 40.0)) > base
    assert float(draught_rating(22.0, 0.2, 30.0)) > base


def test_smoothing_error_bounds():
    t, v, tu = np.meshgrid(np.linspace(10, 40, 61), np.linspace(0, 2, 801), np.linspace(0, 100, 11), indexing="ij")
    exact = draught_rating(t, v, tu, smoothing=DR_EXACT)
    smooth = draught_rating(t, v, tu)
    err = np.abs(smooth - exact)
    assert err.max() <= 0.95
    model = (t >= 20) & (t <= 26) & (v <= 0.5) & (tu >= 10) & (tu <= 60)
    assert err[model].max() <= 0.61
    mid = (exact >= 10) & (exact <= 90)
    assert err[mid].max() < 1e-8
    # the uncapped form keeps growing beyond saturation (a gradient for a penalty)
    assert float(draught_rating(20.0, 2.0, 40.0, cap=False)) > float(draught_rating(20.0, 1.0, 40.0, cap=False)) > 100


def test_casadi_matches_numpy_with_finite_gradients():
    x = casadi.SX.sym("x", 3)
    for cap in (True, False):
        f = casadi.Function("dr", [x], [draught_rating(x[0], x[1], x[2], cap=cap)])
        g = casadi.Function("g", [x], [casadi.gradient(f(x), x)])
        rng = np.random.default_rng(1)
        for _ in range(50):
            p = [rng.uniform(15, 36), rng.uniform(0.0, 1.5), rng.uniform(5, 70)]
            assert float(f(p)) == pytest.approx(float(draught_rating(*p, cap=cap)), abs=1e-9)
            assert np.all(np.isfinite(np.asarray(g(p))))
        # at the corner itself (v = 0.05 m/s) the gradient is finite too
        assert np.all(np.isfinite(np.asarray(g([22.0, 0.05, 40.0]))))


def test_input_errors_and_validity():
    with pytest.raises(ValueError, match="vel_mps"):
        draught_rating(22.0, -0.1, 40.0)
    with pytest.raises(ValueError, match="tu_pct"):
        draught_rating(22.0, 0.2, 140.0)
    with pytest.raises(ValueError, match="ta_c"):
        draught_rating(float("nan"), 0.2, 40.0)
    with pytest.raises(ValueError, match="broadcast"):
        draught_rating(np.ones(2), np.ones(3), 40.0)
    with pytest.raises(ValueError, match="k_cap_per_pct"):
        draught_rating(22.0, 0.2, 40.0, smoothing=DraughtSmoothing(k_cap_per_pct=0.0))
    ok = draught_validity([22.0, 19.0, 22.0, 22.0], [0.2, 0.2, 0.7, 0.2], [40.0, 40.0, 40.0, 5.0])
    assert ok.all.tolist() == [True, False, False, False]
    assert ok.ta_c.tolist() == [True, False, True, True]
    assert ok.vel_mps.tolist() == [True, True, False, True]
    assert ok.tu_pct.tolist() == [True, True, True, False]
