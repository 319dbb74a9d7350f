"""The matched-comfort front (ceco_bringup.benchmark.front): analytic cases.

Every expected value is worked out by hand from the two or three points of the
family; the geometry (interpolation on a segment, the inverse, the dominated
test beyond the front's ends) is where a wrong sign or index would show.
"""

import math

import pytest

from ceco_bringup.benchmark import front as fr

# A family on a straight line: D = 0.1 -> E = 0.4, D = 0.3 -> E = 0.2 (E = 0.5 - D).
LINE = {"baseline@24.0": (0.1, 0.4), "baseline@26.0": (0.3, 0.2)}


def test_two_point_front_interpolates_and_inverts():
    f = fr.build_front(LINE)
    assert [p.name for p in f.vertices] == ["baseline@24.0", "baseline@26.0"]
    assert f.energy_at(0.2) == pytest.approx(0.3)
    assert f.discomfort_at(0.25) == pytest.approx(0.25)
    assert f.energy_at(0.05) is None and f.energy_at(0.31) is None
    assert f.discomfort_at(0.41) is None and f.discomfort_at(0.19) is None


def test_controller_below_the_front_saves_and_is_more_comfortable():
    m = fr.match(fr.build_front(LINE), 0.2, 0.27)
    # front at D = 0.2: E = 0.3 -> (0.3 - 0.27)/0.3 = 10 %; front at E = 0.27: D = 0.23 -> (0.23 - 0.2)/0.23
    assert m.energy_saving_pct == pytest.approx(10.0)
    assert m.discomfort_reduction_pct == pytest.approx(100.0 * 0.03 / 0.23)
    assert m.dominated is False and m.note == ""


def test_controller_above_the_front_is_dominated_with_negative_savings():
    m = fr.match(fr.build_front(LINE), 0.2, 0.33)
    assert m.energy_saving_pct == pytest.approx(-10.0)
    assert m.discomfort_reduction_pct == pytest.approx(100.0 * (0.17 - 0.2) / 0.17)
    assert m.dominated is True


def test_a_point_on_the_front_is_not_dominated_and_saves_nothing():
    f = fr.build_front(LINE)
    for d, e in ((0.2, 0.3), (0.1, 0.4), (0.3, 0.2)):
        m = fr.match(f, d, e)
        assert m.energy_saving_pct == pytest.approx(0.0, abs=1e-9)
        assert m.discomfort_reduction_pct == pytest.approx(0.0, abs=1e-9)
        assert m.dominated is False


def test_u_shaped_family_drops_its_cold_branch():
    # 22 degC: cold and expensive; 25 degC the comfort optimum; 27 degC warm and cheap.
    fam = {
        "baseline@22.0": (0.08, 0.44),
        "baseline@24.0": (0.05, 0.40),
        "baseline@25.0": (0.04, 0.37),
        "baseline@26.0": (0.05, 0.33),
        "baseline@27.0": (0.07, 0.30),
    }
    f = fr.build_front(fam)
    assert [p.name for p in f.vertices] == ["baseline@25.0", "baseline@26.0", "baseline@27.0"]
    assert {p.name: p.efficient for p in f.points} == {
        "baseline@22.0": False,
        "baseline@24.0": False,
        "baseline@25.0": True,
        "baseline@26.0": True,
        "baseline@27.0": True,
    }
    # between 26 and 27 degC: D = 0.06 -> E = 0.315
    m = fr.match(f, 0.06, 0.30)
    assert m.energy_saving_pct == pytest.approx(100.0 * 0.015 / 0.315)
    # the cold branch does not count: a point like 24 degC is dominated by the 25 degC vertex
    assert fr.match(f, 0.05, 0.40).dominated is True


def test_out_of_range_gives_none_with_a_reason_and_no_extrapolation():
    f = fr.build_front(LINE)
    more = fr.match(f, 0.05, 0.45)  # more comfortable than 24 degC, more energy too
    assert more.energy_saving_pct is None and more.discomfort_reduction_pct is None
    assert fr.NOTE_MORE_COMFORTABLE in more.note and fr.NOTE_MORE_ENERGY in more.note
    assert more.dominated is False  # nothing on the front is more comfortable
    less = fr.match(f, 0.4, 0.1)  # less comfortable and cheaper than 26 degC
    assert less.energy_saving_pct is None and less.discomfort_reduction_pct is None
    assert fr.NOTE_LESS_COMFORTABLE in less.note and fr.NOTE_LESS_ENERGY in less.note
    assert less.dominated is False
    # beyond D_max but using at least the energy of the warmest vertex: dominated by it
    assert fr.match(f, 0.4, 0.2).dominated is True
    assert fr.match(f, 0.4, 0.25).dominated is True
    # matched energy still defined where comfort is out of range
    m = fr.match(f, 0.05, 0.35)
    assert m.energy_saving_pct is None
    assert m.discomfort_reduction_pct == pytest.approx(100.0 * (0.15 - 0.05) / 0.15)


def test_single_point_family_and_duplicates():
    f = fr.build_front({"baseline@26.0": (0.2, 0.3)})
    assert fr.match(f, 0.2, 0.27).energy_saving_pct == pytest.approx(10.0)
    assert fr.match(f, 0.2, 0.33).dominated is True
    assert fr.match(f, 0.19, 0.5).energy_saving_pct is None
    dup = fr.build_front([("a", 0.1, 0.4), ("b", 0.1, 0.4), ("c", 0.3, 0.2)])
    assert [p.name for p in dup.vertices] == ["a", "c"]


def test_zero_discomfort_front_segment():
    f = fr.build_front({"baseline@25.0": (0.0, 0.37), "baseline@27.0": (0.1, 0.30)})
    m = fr.match(f, 0.0, 0.37)
    assert m.energy_saving_pct == pytest.approx(0.0) and m.discomfort_reduction_pct == 0.0
    z = fr.match(f, 0.01, 0.37)  # front has D = 0 at this energy: % undefined
    assert z.discomfort_reduction_pct is None and fr.NOTE_ZERO_DISCOMFORT in z.note
    assert z.dominated is True


def test_match_seeds_uses_the_mean_point_and_reports_each_seed():
    f = fr.build_front(LINE)
    r = fr.match_seeds(f, [(0.2, 0.27), (0.2, 0.33)])
    assert r["energy_saving_pct"] == pytest.approx(0.0, abs=1e-9)  # mean point (0.2, 0.30) on the front
    assert r["seeds"]["energy_saving_pct"] == pytest.approx([10.0, -10.0])
    assert r["seeds"]["dominated"] == [False, True] and r["n_seeds"] == 2


@pytest.mark.parametrize("bad", [{}, {"x": (math.nan, 0.1)}, {"x": (0.1, -1.0)}])
def test_bad_families_are_rejected(bad):
    with pytest.raises(ValueError):
        fr.build_front(bad)
    with pytest.raises(ValueError, match="not finite"):
        fr.match(fr.build_front(LINE), math.inf, 0.1)
