"""The matched-comfort front (ceco_bringup.benchmark.front): analytic cases.

Every expected value is worked out by hand from the two or three points of the
family; the geometry (interpolation on a segment, the inverse, the dominated
test beyond the front's ends) is where a wrong sign or index would show.
"""

import math

import numpy as np
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
    assert not fr.dominates_front(more.as_dict())  # more comfortable, but at more energy
    best = fr.match(f, 0.05, 0.1)  # more comfortable and cheaper than every vertex: it dominates the front
    assert best.energy_saving_pct is None and best.dominated is False and fr.dominates_front(best.as_dict())
    assert not fr.dominates_front(None) and not fr.dominates_front(fr.match(f, 0.4, 0.1).as_dict())
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


# Three families: A on E = 0.5 - D over D in [0.1, 0.3]; B from (0.12, 0.39) to (0.4, 0.25)
# (E = 0.39 - 0.5 (D - 0.12)); C from (0.5, 0.2) to (0.6, 0.1).
FAM_A = {"a@1": (0.1, 0.4), "a@2": (0.3, 0.2)}
FAM_B = {"b@1": (0.12, 0.39), "b@2": (0.4, 0.25)}
FAM_C = {"c@1": (0.5, 0.2), "c@2": (0.6, 0.1)}


def _env():
    return fr.Envelope.of(
        {"A": fr.build_front(FAM_A), "B": fr.build_front(FAM_B), "C": fr.build_front(FAM_C), "D": None}
    )


def test_envelope_is_the_least_energy_at_a_discomfort_budget():
    env = _env()
    assert [n for n, _ in env.fronts] == ["A", "B", "C"]  # an empty family is left out
    # D = 0.11: only A covers it (B starts at 0.12): E = 0.39
    assert env.energy_at(0.11) == pytest.approx(0.39) and env.family_at(0.11) == "A"
    # D = 0.2: A gives 0.3; B gives 0.39 - 0.5 * 0.08 = 0.35 -> A
    assert env.energy_at(0.2) == pytest.approx(0.3) and env.family_at(0.2) == "A"
    # D = 0.35: past A's last vertex (0.3, 0.2) A keeps 0.2; B gives 0.275 -> A, with its 0.3 vertex
    assert env.energy_at(0.35) == pytest.approx(0.2) and env.family_at(0.35) == "A"
    # D = 0.55: C (0.15) beats A and B kept at their ends (0.2, 0.25)
    assert env.energy_at(0.55) == pytest.approx(0.15) and env.family_at(0.55) == "C"
    # outside [0.1, 0.6]: undefined
    assert env.energy_at(0.09) is None and env.energy_at(0.61) is None and env.family_at(0.7) is None
    assert env.d_range == (0.1, 0.6) and env.e_range == (0.1, 0.4)
    # the inverse: E = 0.25 -> A: 0.25, B: 0.4, C: 0.5 (its most comfortable point uses 0.2 <= 0.25) -> 0.25
    assert env.discomfort_at(0.25) == pytest.approx(0.25)
    assert env.discomfort_at(0.15) == pytest.approx(0.55) and env.discomfort_at(0.41) is None
    with pytest.raises(ValueError, match="no family"):
        fr.Envelope.of({"A": None})


def test_matching_against_the_strongest_family():
    env = _env()
    # at D = 0.2 the envelope is A's 0.30: a controller at 0.27 saves 10 %, at 0.33 is dominated
    m = fr.match(env, 0.2, 0.27)
    assert m.energy_saving_pct == pytest.approx(10.0) and m.dominated is False
    assert fr.match(env, 0.2, 0.33).dominated is True
    # at D = 0.35 the envelope's 0.2 (A's last vertex) is the reference: a controller at 0.26 spends 30 % more,
    # and is dominated by that vertex, although B alone (0.275 there) would call it a 5.5 % saving
    d = fr.match(env, 0.35, 0.26)
    assert d.energy_saving_pct == pytest.approx(-30.0) and d.dominated is True
    assert fr.match(fr.build_front(FAM_B), 0.35, 0.26).energy_saving_pct == pytest.approx(100.0 * 0.015 / 0.275)
    # matched energy: at E = 0.26 the envelope reaches D = 0.24 (A) -> (0.24 - 0.35) / 0.24
    assert d.discomfort_reduction_pct == pytest.approx(100.0 * (0.24 - 0.35) / 0.24)
    out = fr.match(env, 0.65, 0.3)
    assert out.energy_saving_pct is None and fr.NOTE_LESS_COMFORTABLE in out.note


def test_strongest_by_level_counts_the_family_that_is_lowest_most_often():
    env = _env()
    r = fr.strongest_by_level(env, [0.11, 0.2, 0.52, 0.55, 0.7])
    assert [x["family"] for x in r["levels"]] == ["A", "A", "C", "C", None]
    assert r["levels"][3]["energy"] == pytest.approx(0.15) and r["levels"][4]["energy"] is None
    assert r["family"] == "A"  # 2 : 2, ties go to the envelope's order
    assert fr.strongest_by_level(env, [0.52, 0.55, 0.2])["family"] == "C"
    assert fr.strongest_by_level(env, [0.7])["family"] is None


def test_headroom_captured_on_hand_made_fronts():
    env = _env()
    bound = fr.build_front({"o1": (0.1, 0.3), "o2": (0.4, 0.15)})  # E = 0.3 - 0.5 (D - 0.1)
    # D = 0.2: envelope A 0.30, bound 0.25: the bound saves 0.05 kWh; a controller at 0.28 saves 0.02 -> 0.4
    h = fr.headroom(env, bound, 0.2, 0.28)
    assert h.headroom_captured == pytest.approx(0.4)
    assert h.saving_pct == pytest.approx(100.0 * 0.02 / 0.3)
    assert h.bound_saving_pct == pytest.approx(100.0 * 0.05 / 0.3)
    assert h.strongest == "A" and h.note == ""
    # on the bound: 1; on the envelope: 0; above the envelope: negative
    assert fr.headroom(env, bound, 0.2, 0.25).headroom_captured == pytest.approx(1.0)
    assert fr.headroom(env, bound, 0.2, 0.30).headroom_captured == pytest.approx(0.0, abs=1e-12)
    assert fr.headroom(env, bound, 0.2, 0.31).headroom_captured == pytest.approx(-0.2)
    # undefined: the bound does not cover D, the envelope does not, or the bound saves nothing
    assert fr.headroom(env, bound, 0.5, 0.1).headroom_captured is None
    assert fr.NOTE_NO_BOUND in fr.headroom(env, bound, 0.5, 0.1).note
    out = fr.headroom(env, bound, 0.05, 0.1)
    assert out.headroom_captured is None and fr.NOTE_MORE_COMFORTABLE in out.note
    worse = fr.build_front({"o1": (0.1, 0.45), "o2": (0.3, 0.35)})
    w = fr.headroom(env, worse, 0.2, 0.28)
    assert w.headroom_captured is None and fr.NOTE_NO_HEADROOM in w.note and w.bound_saving_pct < 0
    # several bounds (one per seed): their mean at D; 0.25 and 0.27 -> 0.26, saving 0.04; the controller 0.02
    other = fr.build_front({"o1": (0.1, 0.32), "o2": (0.4, 0.17)})
    assert fr.headroom(env, [bound, other], 0.2, 0.28).headroom_captured == pytest.approx(0.5)


def test_headroom_seeds_pairs_each_seed_with_its_bound():
    env = _env()
    b0 = fr.build_front({"o1": (0.1, 0.3), "o2": (0.4, 0.15)})  # 0.25 at D = 0.2
    b1 = fr.build_front({"o1": (0.1, 0.32), "o2": (0.4, 0.17)})  # 0.27 at D = 0.2
    r = fr.headroom_seeds(env, {0: b0, 1: b1}, [(0, 0.2, 0.28), (1, 0.2, 0.28)])
    assert r["seeds"]["headroom_captured"] == pytest.approx([0.4, 2.0 / 3.0])
    assert r["headroom_captured"] == pytest.approx(0.5) and r["n_seeds"] == 2
    # a seed-invariant bound (key None) serves every seed; a missing one is reported
    assert fr.headroom_seeds(env, {None: b0}, [(3, 0.2, 0.28)])["headroom_captured"] == pytest.approx(0.4)
    miss = fr.headroom_seeds(env, {0: b0}, [(0, 0.2, 0.28), (1, 0.2, 0.28)])
    assert miss["headroom_captured"] is None and miss["seeds"]["headroom_captured"][1] is None


def test_by_phase_reads_the_strongest_family_and_the_bound_at_the_controllers_discomfort():
    env = _env()
    b0 = fr.build_front({"o1": (0.1, 0.3), "o2": (0.4, 0.15)})
    b1 = fr.build_front({"o1": (0.1, 0.32), "o2": (0.4, 0.17)})
    # the band-phase energy and PMV at each vertex (the whole run's energy is the front's own)
    members = {
        "a@1": {"energy_kwh": 0.4, "energy_band_kwh": 0.2, "pmv_mean_band": 0.30},
        "a@2": {"energy_kwh": 0.2, "energy_band_kwh": 0.1, "pmv_mean_band": 0.50},
        "b@1": {"energy_kwh": 0.39, "energy_band_kwh": 0.3, "pmv_mean_band": 0.0},
        "b@2": {"energy_kwh": 0.25, "energy_band_kwh": 0.2, "pmv_mean_band": 0.1},
    }
    bound_kpis = {
        0: {
            "o1": {"energy_kwh": 0.3, "energy_band_kwh": 0.12, "pmv_mean_band": 0.40},
            "o2": {"energy_kwh": 0.15, "energy_band_kwh": 0.03, "pmv_mean_band": 0.70},
        },
        1: {
            "o1": {"energy_kwh": 0.32, "energy_band_kwh": 0.16, "pmv_mean_band": 0.44},
            "o2": {"energy_kwh": 0.17, "energy_band_kwh": 0.07, "pmv_mean_band": 0.74},
        },
    }
    keys = ("energy_kwh", "energy_band_kwh", "pmv_mean_band")
    # A at D = 0.2 is half-way between a@1 and a@2: band 0.15, PMV 0.40; at D = 0.15 a quarter: band 0.175, PMV 0.35
    assert fr.value_at(env.front_of("A"), 0.2, {n: v["energy_band_kwh"] for n, v in members.items()}) == pytest.approx(
        0.15
    )
    assert fr.value_at(env.front_of("A"), 0.35, {n: v["pmv_mean_band"] for n, v in members.items()}) == pytest.approx(
        0.5
    )
    assert fr.value_at(env.front_of("A"), 0.2, {"a@1": 0.2}) is None  # a neighbouring vertex without a value
    three = fr.build_front({"x1": (0.1, 0.4), "x2": (0.2, 0.3), "x3": (0.3, 0.25)})
    assert fr.value_at(three, 0.15, {"x1": 1.0, "x2": 3.0}) == pytest.approx(2.0)  # x3's value is not needed
    assert fr.value_at(three, 0.25, {"x1": 1.0, "x2": 3.0}) is None
    assert fr.value_at(three, 0.35, {"x2": 3.0, "x3": 5.0}) == pytest.approx(5.0)  # held past the end
    assert fr.value_at(fr.build_front({"y": (0.1, 0.4)}), 0.3, {"y": 7.0}) == 7.0  # a one-point front
    pts = [
        (0, 0.2, {"energy_kwh": 0.28, "energy_band_kwh": 0.14, "pmv_mean_band": 0.45}),
        (1, 0.15, {"energy_kwh": 0.33, "energy_band_kwh": 0.16, "pmv_mean_band": 0.41}),
    ]
    out = fr.by_phase(env, {0: b0, 1: b1}, pts, members, bound_kpis, keys)
    assert out["families"] == ["A", "A"] and out["n_seeds"] == 2
    assert out["controller"] == pytest.approx({"energy_kwh": 0.305, "energy_band_kwh": 0.15, "pmv_mean_band": 0.43})
    assert out["strongest"] == pytest.approx({"energy_kwh": 0.325, "energy_band_kwh": 0.1625, "pmv_mean_band": 0.375})
    # seed 0 at D = 0.2 on b0 (a third of o1 -> o2): band 0.09, PMV 0.5; seed 1 at 0.15 on b1 (a sixth): 0.145, 0.49
    assert out["bound"]["energy_kwh"] == pytest.approx((0.25 + 0.295) / 2)
    assert out["bound"]["energy_band_kwh"] == pytest.approx((0.09 + 0.145) / 2)
    assert out["bound"]["pmv_mean_band"] == pytest.approx((0.5 + 0.49) / 2)
    # the bound's whole-run energy read so equals the front's own energy (what headroom divides by)
    assert out["bound"]["energy_kwh"] == pytest.approx((b0.energy_at(0.2) + b1.energy_at(0.15)) / 2)
    # a seed whose bound does not cover its discomfort, or has no KPIs, reads None for the bound
    far = fr.by_phase(env, {0: b0}, [(0, 0.45, pts[0][2])], members, bound_kpis, keys)
    assert far["bound"] == dict.fromkeys(keys) and far["families"] == ["A"]
    # past A's least comfortable vertex the envelope keeps it (0.2 kWh, below B's 0.25), and so does the reading
    assert far["strongest"] == pytest.approx({"energy_kwh": 0.2, "energy_band_kwh": 0.1, "pmv_mean_band": 0.5})
    assert fr.by_phase(env, {0: b0}, pts[:1], members, {}, keys)["bound"] == dict.fromkeys(keys)
    with pytest.raises(ValueError, match="no points"):
        fr.by_phase(env, {0: b0}, [], members, bound_kpis, keys)


# Saturation: a family whose two warmest members sit at the ceiling C = 0.5 (PMV at the clip the whole run).
# Without the rule: vertices (0.1, 0.4), (0.3, 0.2), (0.5, 0.05); (0.5, 0.1) is dominated by (0.5, 0.05).
CEIL = 0.5
SAT = {"s@1": (0.1, 0.4), "s@2": (0.3, 0.2), "s@3": (0.5, 0.1), "s@4": (0.5, 0.05)}


def test_saturated_members_are_no_vertices_and_anchor_no_match():
    plain = fr.build_front(SAT)
    assert [p.name for p in plain.vertices] == ["s@1", "s@2", "s@4"]
    # the defect: a controller at the ceiling that spends 0.02 kWh is credited 60 % against s@4's 0.05
    assert fr.match(plain, CEIL, 0.02).energy_saving_pct == pytest.approx(60.0)
    f = fr.build_front(SAT, ceiling=CEIL)
    assert [p.name for p in f.vertices] == ["s@1", "s@2"] and f.d_range == (0.1, 0.3)
    assert {p.name: (p.efficient, p.saturated) for p in f.points} == {
        "s@1": (True, False),
        "s@2": (True, False),
        "s@3": (False, True),
        "s@4": (False, True),
    }
    at = fr.match(f, CEIL, 0.02)
    assert at.energy_saving_pct is None and at.discomfort_reduction_pct is None and at.note == fr.NOTE_SATURATED
    assert at.dominated is False  # no vertex spends <= 0.02
    # within rounding of the ceiling is at it; a vertex below it with less energy still dominates
    assert fr.match(f, CEIL * (1.0 - 1e-12), 0.02).note == fr.NOTE_SATURATED
    assert fr.match(f, CEIL, 0.3).dominated is True  # s@2: D 0.3 < 0.5, E 0.2 <= 0.3
    # between s@2 and the ceiling: no longer interpolated toward s@4 (it was 0.125 kWh there: a -20 % "saving")
    assert fr.match(plain, 0.4, 0.15).energy_saving_pct == pytest.approx(-20.0)
    near = fr.match(f, 0.4, 0.15)
    assert near.energy_saving_pct is None and near.note.startswith(fr.NOTE_LESS_COMFORTABLE)
    # below the ceiling nothing changes: D 0.2 -> E 0.3 on both
    assert fr.match(f, 0.2, 0.27).energy_saving_pct == pytest.approx(10.0)
    assert fr.match(f, 0.2, 0.27) == fr.match(plain, 0.2, 0.27)
    with pytest.raises(ValueError, match="ceiling"):
        fr.build_front(SAT, ceiling=0.0)


def test_saturation_in_the_envelope_the_seeds_and_the_headroom():
    sat_only = fr.build_front({"z@1": (CEIL, 0.01), "z@2": (CEIL, 0.02)}, ceiling=CEIL)
    assert sat_only.vertices == () and sat_only.energy_at(CEIL) is None and not sat_only.dominates(CEIL, 1.0)
    assert fr.match(sat_only, 0.2, 0.1).note == fr.NOTE_NO_VERTEX
    env = fr.Envelope.of({"S": fr.build_front(SAT, ceiling=CEIL), "Z": sat_only})
    assert [n for n, _ in env.fronts] == ["S"] and env.ceiling == CEIL
    m = fr.match(env, CEIL, 0.02)
    assert m.energy_saving_pct is None and m.note == fr.NOTE_SATURATED and env.family_at(CEIL) is None
    assert fr.match(env, 0.2, 0.27).energy_saving_pct == pytest.approx(10.0)  # S below the ceiling
    empty = fr.Envelope.of({"Z": sat_only})
    assert empty.fronts == () and fr.match(empty, 0.2, 0.1).note == fr.NOTE_NO_VERTEX
    assert fr.strongest_by_level(empty, [0.2])["family"] is None
    # two seeds, one saturated: the mean (0.35) would read 0.175 kWh on the plain front; it is not matched
    r = fr.match_seeds(env, [(0.2, 0.27), (CEIL, 0.02)])
    assert r["energy_saving_pct"] is None and r["note"] == fr.NOTE_SATURATED
    assert r["seeds"]["energy_saving_pct"] == [pytest.approx(10.0), None]
    bound = fr.build_front({"o1": (0.1, 0.3), "o2": (0.4, 0.15)})
    h = fr.headroom(env, bound, CEIL, 0.02)
    assert h.headroom_captured is None and h.saving_pct is None and h.note == fr.NOTE_SATURATED
    hs = fr.headroom_seeds(env, {None: bound}, [(0, 0.2, 0.28), (1, CEIL, 0.02)])
    assert hs["headroom_captured"] is None and hs["note"] == fr.NOTE_SATURATED
    assert hs["seeds"]["headroom_captured"][0] == pytest.approx(0.02 / 0.05)  # bound 0.25 at D 0.2, envelope 0.3


def test_the_ceiling_is_what_a_run_at_the_clip_scores():
    from ceco_core.kpis import compute_kpis, discomfort_ceiling

    # 60 samples 1 s apart at PMV +3.4 (clipped to +3): 60 s x 2.5 PMV = 150 PMV s = 1/24 PMV h; I_PMV 9 x 60
    n = 60
    cols = {
        "t_s": np.arange(n, dtype=float),
        "p_comp_w": np.full(n, 1000.0),
        "p_blower_w": np.full(n, 50.0),
        "pmv": np.full(n, 3.4),
        "pmv_lb": np.r_[np.full(20, -1.0), np.full(n - 20, -0.5)],  # the band applies from 20 s
        "pmv_ub": np.full(n, 0.5),
        "mdot_bl_kgps": np.full(n, 0.05),
        "t_evap_sp_c": np.full(n, 10.0),
    }
    k, _ = compute_kpis(cols)
    assert discomfort_ceiling(k) == pytest.approx(1.0 / 24.0, rel=1e-12)
    assert discomfort_ceiling(k, "i_pmv_clipped") == pytest.approx(540.0, rel=1e-12)
    assert discomfort_ceiling(k, "discomfort_band_pmvh") == pytest.approx(40.0 * 2.5 / 3600.0, rel=1e-12)
    assert discomfort_ceiling(k, "i_pmv") is None and discomfort_ceiling({"duration_s": None}) is None
    for key in ("discomfort_pmvh", "i_pmv_clipped", "discomfort_band_pmvh"):
        c = fr.saturation_ceiling([k], key)
        assert fr.saturated(fr.build_front({"x": (0.0, 1.0)}, ceiling=c), k[key]), key
    # one sample inside the band takes the run off the ceiling (2.5 PMV s less, 1/60 of it)
    cols["pmv"] = np.r_[0.0, np.full(n - 1, 3.4)]
    k2, _ = compute_kpis(cols)
    assert k2["discomfort_pmvh"] == pytest.approx(59 * 2.5 / 3600.0)
    assert not fr.saturated(fr.build_front({"x": (0.0, 1.0)}, ceiling=discomfort_ceiling(k2)), k2["discomfort_pmvh"])
    # a case's runs: the least ceiling of those that have one
    assert fr.saturation_ceiling([{"duration_s": 72.0}, {"duration_s": 60.0}, {}], "discomfort_pmvh") == pytest.approx(
        1.0 / 24.0
    )
    assert fr.saturation_ceiling([{}], "discomfort_pmvh") is None


# The exploratory tester's case (c60: SC03, 60 s, seed 0): the allowance family's members from 27.5 degC up sit at
# the ceiling 60 x 2.5 / 3600 PMV h with less and less energy, as does a controller that does not cool ('const').
C60_CEIL = 0.041666666666666664
C60_ALLOWANCE = {
    "baseline-allowance@25.0": (0.041093432378712685, 0.06525357064674053),
    "baseline-allowance@25.5": (0.04118369110620491, 0.06497702999046019),
    "baseline-allowance@26.0": (0.041531593213006195, 0.06312796350907543),
    "baseline-allowance@26.5": (0.041553272552393, 0.06301823369583645),
    "baseline-allowance@27.0": (0.04166508801149208, 0.06117656824567467),
    "baseline-allowance@27.5": (C60_CEIL, 0.05852177526846963),
    "baseline-allowance@28.0": (C60_CEIL, 0.05827411381659335),
    "baseline-allowance@28.5": (C60_CEIL, 0.05404407779206099),
    "baseline-allowance@29.0": (C60_CEIL, 0.0537435302912003),
}
C60_PLAIN = {"baseline@22.0": (0.041093432378712685, 0.06525357064674053)}
C60_CONST = (C60_CEIL, 0.019833987284092622)


def test_a_controller_that_does_not_cool_is_not_credited_on_the_c60_case():
    ceiling = fr.saturation_ceiling([{"duration_s": 60.0}], "discomfort_pmvh")
    assert ceiling == pytest.approx(C60_CEIL, rel=1e-12)
    # before: 100 (0.053744 - 0.019834) / 0.053744 = 63.1 % against the allowance family's 29 degC member
    assert fr.match(fr.build_front(C60_ALLOWANCE), *C60_CONST).energy_saving_pct == pytest.approx(63.0951164, abs=1e-6)
    fronts = {"plain": fr.build_front(C60_PLAIN, ceiling), "allowance": fr.build_front(C60_ALLOWANCE, ceiling)}
    assert fronts["allowance"].d_range[1] == C60_ALLOWANCE["baseline-allowance@27.0"][0]
    for f in (*fronts.values(), fr.Envelope.of(fronts)):
        m = fr.match_seeds(f, [C60_CONST])
        assert m["energy_saving_pct"] is None and m["discomfort_reduction_pct"] is None, m
        assert m["note"] == fr.NOTE_SATURATED and m["dominated"] is False
    # a member of the family below the ceiling still matches itself: 0 %
    assert fr.match(fronts["allowance"], *C60_ALLOWANCE["baseline-allowance@26.0"]).energy_saving_pct == pytest.approx(
        0.0, abs=1e-9
    )


def test_the_benchmark_report_says_a_controller_dominates_every_baseline():
    """The quick benchmark's mild day: ceco-pmv more comfortable and cheaper than every baseline read `n/a`,
    `dominated: no`, `n/a` like no result at all. Its dominated cells now say it dominates every baseline."""
    from ceco_bringup.benchmark import report as brep

    f = fr.build_front(LINE)
    best, worse = fr.match(f, 0.05, 0.1).as_dict(), fr.match(f, 0.05, 0.45).as_dict()
    assert brep._match_cells(best)[2] == brep.DOMINATES_WORDS and brep._match_cells(worse)[2] == 'no'
    assert brep._strongest_cells({'strongest': {**best, 'family': 'plain'}})[1:] == [brep.DOMINATES_WORDS, 'plain']
    assert brep._match_cells(fr.match(f, 0.4, 0.25).as_dict())[2] == '**yes**'
