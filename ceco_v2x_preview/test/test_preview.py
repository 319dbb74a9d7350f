"""V2X preview generation: perfect, noisy, delayed and missing previews."""

import math

import numpy as np
import pytest

from ceco_v2x_preview.preview import (
    DEFAULT_NOISE,
    FAULT_RANGES,
    PERFECT,
    SEED_RANGE,
    PreviewQuality,
    make_previews,
    no_preview_warning,
    parse_quality,
    summarize,
    usable_steps,
)
from ceco_v2x_preview.scenario import load_scenario


@pytest.fixture(scope="module")
def sc03():
    return load_scenario("sc03")


def test_perfect_equals_truth(sc03):
    p = make_previews(sc03, 100.0, 5.0, 7, PERFECT)
    wp = sc03.weather_preview(100.0, 5.0, 7)
    np.testing.assert_array_equal(p.solar_wm2, wp.solar_wm2)
    np.testing.assert_array_equal(p.t_amb_c, wp.t_amb_c)
    np.testing.assert_array_equal(p.rh, wp.rh)
    np.testing.assert_array_equal(p.speed_mps, sc03.speed_preview(100.0, 5.0, 7))
    assert p.valid.all() and p.trusted_steps == 7 and p.age_s == 0.0 and p.issued_s == 100.0
    np.testing.assert_allclose(p.t_s, wp.t_s)
    assert PERFECT.mode == "perfect" and PERFECT.describe() == "perfect"


NOISY = PreviewQuality(noise_std_t_amb_c=0.5, noise_std_solar_wm2=50.0, noise_std_speed_mps=1.5, seed=3)


def test_noise_deterministic_and_order_independent(sc03):
    times = np.arange(0.0, 100.0, 5.0)
    forward = [make_previews(sc03, t, 5.0, 7, NOISY).solar_wm2 for t in times]
    backward = [make_previews(sc03, t, 5.0, 7, NOISY).solar_wm2 for t in times[::-1]][::-1]
    for a, b in zip(forward, backward):
        np.testing.assert_array_equal(a, b)
    # The forecast issued at t0 does not depend on how many samples are asked.
    long = make_previews(sc03, 50.0, 5.0, 13, NOISY)
    short = make_previews(sc03, 50.0, 5.0, 4, NOISY)
    np.testing.assert_array_equal(long.speed_mps[:4], short.speed_mps)
    other = make_previews(sc03, 50.0, 5.0, 7, PreviewQuality(noise_std_solar_wm2=50.0, seed=4))
    assert not np.array_equal(other.solar_wm2, forward[10])
    # seed=None takes the scenario's seed (0 for sc03).
    q_none = PreviewQuality(noise_std_solar_wm2=50.0)
    q_zero = PreviewQuality(noise_std_solar_wm2=50.0, seed=0)
    np.testing.assert_array_equal(
        make_previews(sc03, 50.0, 5.0, 7, q_none).solar_wm2, make_previews(sc03, 50.0, 5.0, 7, q_zero).solar_wm2
    )


def test_noise_grows_with_lead_time(sc03):
    times = np.arange(0.0, 560.0, 1.0)
    err = np.array([make_previews(sc03, t, 5.0, 7, NOISY).t_amb_c - 35.0 for t in times])
    std = err.std(axis=0)
    assert std[0] == 0.0  # the present is known
    expected = 0.5 * np.sqrt(5.0 * np.arange(7) / 30.0)
    # 560 overlapping forecasts: about 6 % standard error on each std.
    np.testing.assert_allclose(std[1:], expected[1:], rtol=0.2)
    assert std[6] > 2.0 * std[1]
    assert abs(err[:, 6].mean()) < 0.15


def test_physical_limits_with_large_noise(sc03):
    q = PreviewQuality(noise_std_solar_wm2=2000.0, noise_std_speed_mps=50.0, noise_std_rh=2.0, seed=1)
    clipped = 0
    for t in np.arange(0.0, 300.0, 7.0):
        p = make_previews(sc03, t, 5.0, 13, q)
        assert np.all(p.solar_wm2 >= 0.0) and np.all(p.speed_mps >= 0.0)
        assert np.all((p.rh >= 0.0) & (p.rh <= 1.0))
        clipped += int(np.sum(p.solar_wm2 == 0.0))
    assert clipped > 0  # the limit was actually exercised


def test_delayed_preview_is_stale_and_shorter(sc03):
    q = parse_quality("delayed:12")
    p = make_previews(sc03, 100.0, 5.0, 6, q)
    # Issued at 88 s, it covers 88..113 s: samples at 100, 105, 110 only.
    assert p.issued_s == 88.0 and p.age_s == 12.0
    np.testing.assert_array_equal(p.valid, [True, True, True, False, False, False])
    assert p.trusted_steps == 3
    # A perfect forecast stays right where it covers; the rest is NaN.
    np.testing.assert_allclose(p.solar_wm2[:3], sc03.weather_preview(100.0, 5.0, 3).solar_wm2)
    assert np.all(np.isnan(p.solar_wm2[3:])) and np.all(np.isnan(p.speed_mps[3:]))
    # Nothing has been issued yet at the start.
    p0 = make_previews(sc03, 5.0, 5.0, 6, q)
    assert not p0.valid.any() and p0.age_s == math.inf and math.isnan(p0.issued_s)
    # A stale noisy forecast carries the error of the longer lead.
    qn = parse_quality("noisy:solar=50,seed=2+delayed:10")
    pn = make_previews(sc03, 100.0, 5.0, 6, qn)
    assert pn.solar_wm2[0] != sc03.env_at(100.0).solar_wm2


def test_missing_span_hold_last_and_drop(sc03):
    q = parse_quality("missing:100-200")
    before = make_previews(sc03, 95.0, 5.0, 7, q)
    assert before.valid.all() and before.age_s == 0.0
    inside = make_previews(sc03, 110.0, 5.0, 7, q)
    # Last forecast received: issued at 100 s, covering 100..130 s.
    assert inside.issued_s == 100.0 and inside.age_s == 10.0
    np.testing.assert_array_equal(inside.valid, [True] * 5 + [False] * 2)
    np.testing.assert_allclose(inside.solar_wm2[:5], sc03.weather_preview(110.0, 5.0, 5).solar_wm2)
    late = make_previews(sc03, 140.0, 5.0, 7, q)
    assert late.trusted_steps == 0 and not late.valid.any()
    after = make_previews(sc03, 200.0, 5.0, 7, q)  # half-open span: fresh again
    assert after.valid.all() and after.age_s == 0.0

    dropped = make_previews(sc03, 110.0, 5.0, 7, parse_quality("missing:100-200,policy=drop"))
    assert not dropped.valid.any() and np.all(np.isnan(dropped.t_amb_c))

    # Overlapping spans merge: the last forecast is the one before 100 s.
    q2 = PreviewQuality(missing_spans_s=((100.0, 150.0), (140.0, 300.0)))
    assert q2.merged_spans() == [(100.0, 300.0)]
    assert make_previews(sc03, 250.0, 5.0, 7, q2).issued_s == 100.0


def test_persistence_holds_the_last_measured_value():
    """persistence: every quantity holds its value at the issue time over the horizon (no forecast)."""
    tunnel = load_scenario("tunnel")  # the sun drops to 0 at 482 s: a forecast would see it, persistence not
    q = parse_quality("persistence")
    assert q.persistence and q.mode == "persistence"
    p = make_previews(tunnel, 470.0, 5.0, 7, q)
    now = tunnel.env_at(470.0)
    for arr, value in ((p.solar_wm2, now.solar_wm2), (p.t_amb_c, now.t_amb_c), (p.speed_mps, now.speed_mps)):
        np.testing.assert_array_equal(arr, np.full(7, value))
    assert p.solar_wm2[0] > 700.0 and p.valid.all() and p.age_s == 0.0
    truth = make_previews(tunnel, 470.0, 5.0, 7, PERFECT)
    assert truth.solar_wm2[-1] == 0.0 and truth.solar_wm2[0] == p.solar_wm2[0]  # same now, not the same later
    speed = make_previews(tunnel, 470.0, 5.0, 7, PERFECT).speed_mps
    assert np.ptp(speed) > 1.0 and np.ptp(p.speed_mps) == 0.0
    # delayed: the value measured when the (stale) forecast was issued, the uncovered tail invalid
    late = make_previews(tunnel, 470.0, 5.0, 7, parse_quality("persistence+delayed:10"))
    np.testing.assert_array_equal(late.solar_wm2[:5], np.full(5, tunnel.env_at(460.0).solar_wm2))
    assert late.valid.tolist() == [True] * 5 + [False] * 2 and np.isnan(late.solar_wm2[5:]).all()
    # missing with hold_last: the value measured at the span's start, held
    held = make_previews(tunnel, 490.0, 5.0, 7, parse_quality("persistence+missing:480-600"))
    assert held.solar_wm2[0] == tunnel.env_at(480.0).solar_wm2 > 700.0
    for text in ("persistence", "persistence+delayed:10", "persistence+missing:480-600,policy=drop"):
        assert parse_quality(parse_quality(text).describe()) == parse_quality(text)
    seeded = PreviewQuality(persistence=True, seed=3)
    assert parse_quality(seeded.describe()) == seeded
    with pytest.raises(ValueError, match="persistence"):
        parse_quality("persistence+uncertain:medium")
    with pytest.raises(ValueError, match="persistence"):
        PreviewQuality(persistence=True, noise_std_solar_wm2=10.0).validate()


def test_preview_summary(sc03):
    p = make_previews(sc03, 110.0, 5.0, 7, parse_quality("missing:100-200"))
    s = summarize([p, make_previews(sc03, 0.0, 5.0, 7)])
    assert s["valid_fraction"] == pytest.approx(12 / 14)
    assert s["mean_age_s"] == pytest.approx(5.0)


def test_parse_quality_and_round_trip():
    q = parse_quality("noisy:solar=50,speed=1.5,seed=3")
    assert (q.noise_std_solar_wm2, q.noise_std_speed_mps, q.noise_std_t_amb_c, q.seed) == (50.0, 1.5, 0.0, 3)
    assert q.mode == "noisy"
    bare = parse_quality("noisy")
    assert bare.noise_std_solar_wm2 == DEFAULT_NOISE["noise_std_solar_wm2"]
    combo = parse_quality("noisy:t_amb=0.3,ref=60+delayed:10+missing:100-200,300-350,policy=drop")
    assert combo.mode == "noisy+delayed+missing"
    assert combo.missing_spans_s == ((100.0, 200.0), (300.0, 350.0)) and combo.missing_policy == "drop"
    assert combo.noise_ref_lead_s == 60.0
    for quality in (q, bare, combo, parse_quality("perfect"), parse_quality("delayed:2.5")):
        assert parse_quality(quality.describe()) == quality


@pytest.mark.parametrize(
    "text, message",
    [
        ("fuzzy", "unknown part"),
        ("noisy:solar=lots", "noisy solar"),
        ("noisy:wind=3", "unknown key"),
        ("delayed:-5", "delay_s"),
        ("missing:200-100", "missing_spans_s[0]"),
        ("missing:100", "START-END"),
        ("missing:1-2,policy=maybe", "missing_policy"),
        ("noisy:solar=-1", "noise_std_solar_wm2"),
        ("", "empty"),
        ("delayed:5+delayed:10", "delayed given twice"),  # was delayed:10 without a word
        ("noisy+perfect+noisy:solar=5", "noisy given twice"),
    ],
)
def test_parse_quality_errors(text, message):
    with pytest.raises(ValueError) as err:
        parse_quality(text)
    assert message in str(err.value)


GRAMMAR = {
    "noise_std_t_amb_c": ("noisy:t_amb={}", "noisy t_amb", "K"),
    "noise_std_solar_wm2": ("noisy:solar={}", "noisy solar", "W/m2"),
    "noise_std_speed_mps": ("noisy:speed={}", "noisy speed", "m/s"),
    "noise_std_rh": ("noisy:rh={}", "noisy rh", "-"),
    "noise_ref_lead_s": ("noisy:ref={}", "noisy ref", "s"),
    "delay_s": ("delayed:{}", "delayed", "s"),
}
"""Field -> (its preview string, the part and unit its range error names)."""


@pytest.mark.parametrize("field", sorted(GRAMMAR))
def test_a_fault_beyond_the_nodes_range_is_refused_naming_the_range(field):
    """Each end of preview_node's declared range is taken; just beyond either end is refused in one line naming the
    range (delayed:1e12 passed, then preview_node exited on faults.delay_s out of range: a FAILED run)."""
    lo, hi = FAULT_RANGES[field]
    text, part, unit = GRAMMAR[field]
    for end in (lo, hi):
        assert getattr(parse_quality(text.format(end)), field) == end
    for beyond in (lo - 0.01, hi + 0.5):
        with pytest.raises(ValueError) as err:
            parse_quality(text.format(beyond))
        assert str(err.value) == (
            f"preview quality: {part}: {beyond:g} {unit} is outside {lo:g}..{hi:g} {unit}, the range of "
            f"preview_node's faults.{field}"
        )
    assert set(GRAMMAR) == set(FAULT_RANGES)  # every ranged fault is checked here


def test_the_tester_s_delay_and_a_seed_beyond_32_bits_are_refused():
    with pytest.raises(ValueError) as err:
        parse_quality("delayed:1e12")
    assert str(err.value) == (
        "preview quality: delayed: 1e+12 s is outside 0..86400 s, the range of preview_node's faults.delay_s"
    )
    assert parse_quality("noisy:solar=5,seed=2147483647").seed == SEED_RANGE[1] == 2**31 - 1
    with pytest.raises(ValueError) as err:
        parse_quality("uncertain:low,seed=2147483648")
    assert str(err.value) == (
        "preview quality: seed: 2147483648 is outside 0..2147483647, the range of preview_node's faults.seed"
    )


def test_preview_node_declares_the_ranges_the_parser_checks():
    """One table: the node's parameter ranges are the parser's (a range changed in one place only would let a
    string pass the parser that the node refuses)."""
    from ceco_v2x_preview.preview_io import PREVIEW_PARAMETERS

    declared = {s.name: s.float_range or s.int_range for s in PREVIEW_PARAMETERS}
    assert {f: declared[f"faults.{f}"] for f in FAULT_RANGES} == FAULT_RANGES
    assert FAULT_RANGES["delay_s"] == (0.0, 86400.0)
    assert declared["faults.seed"] == (-1, SEED_RANGE[1])


def test_bad_arguments(sc03):
    with pytest.raises(ValueError, match="t0_s"):
        make_previews(sc03, -1.0, 5.0, 6)
    with pytest.raises(ValueError, match="n:"):
        make_previews(sc03, 0.0, 5.0, 0)
    with pytest.raises(ValueError, match="noise_ref_lead_s"):
        make_previews(sc03, 0.0, 5.0, 6, PreviewQuality(noise_ref_lead_s=0.0))
    with pytest.raises(ValueError, match="missing_spans_s"):
        PreviewQuality(missing_spans_s=(100.0, 200.0))  # a pair, not a list of pairs


@pytest.mark.parametrize(
    "text",
    [
        "perfect",
        "delayed:10",
        "delayed:29",
        "delayed:30",
        "delayed:31",
        "delayed:40",
        "missing:0-1000",
        "missing:0-1000,policy=drop",
        "missing:20-1000,policy=drop",
        "delayed:10+missing:50-200",
        "delayed:25+missing:0-40,policy=drop",
    ],
)
def test_usable_steps_counts_what_make_previews_gives(sc03, text):
    """usable_steps (times only) equals the count of control steps whose make_previews has a valid sample, over
    120 steps of SC03 at Ts 5 s and Np 6; no_preview_warning speaks exactly when that count is 0."""
    q = parse_quality(text)
    n_steps, ts, n_p = 120, 5.0, 6
    counted = sum(bool(make_previews(sc03, k * ts, ts, n_p + 1, q).valid.any()) for k in range(n_steps))
    assert usable_steps(q, n_steps, ts, n_p + 1) == counted
    warning = no_preview_warning(q, n_steps * ts, ts, n_p)
    assert bool(warning) == (counted == 0)
    if warning:
        assert f"with {q.describe()} (Ts 5 s, Np 6: every forecast is missing or older than its 30 s horizon" in warning


def test_no_preview_warning_for_the_obvious_cases():
    """A 40-s delay at Np = 6 (30 s horizon) and previews dropped over the whole run give no preview; 30 s and a
    span that ends before the run does leave some."""
    assert no_preview_warning(parse_quality("delayed:40"), 600.0, 5.0, 6)
    assert no_preview_warning(parse_quality("missing:0-600,policy=drop"), 600.0, 5.0, 6)
    assert not no_preview_warning(parse_quality("delayed:30"), 600.0, 5.0, 6)
    assert not no_preview_warning(parse_quality("missing:0-590,policy=drop"), 600.0, 5.0, 6)
    assert not no_preview_warning(parse_quality("delayed:40"), 600.0, 5.0, 8)  # a 40 s horizon covers it
    # a run of 24 s has control steps at 0, 5, ..., 20 (k Ts < 24 s): the one at 20 s holds the forecast issued
    # at 0 s; a run of 20 s ends before it (the count was floor(24 / 5) = 4 steps: a false warning)
    assert not no_preview_warning(parse_quality("delayed:20"), 24.0, 5.0, 6)
    assert "in all 4 steps" in no_preview_warning(parse_quality("delayed:20"), 20.0, 5.0, 6)
