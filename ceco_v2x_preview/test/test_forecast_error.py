"""The benchmark's forecast-uncertainty levels (ceco_v2x_preview.forecast_error).

Moments are checked against the Ornstein-Uhlenbeck formulas over many seeded
realisations; tolerances are ~5 standard errors of the estimates, so a wrong
phi, innovation variance or bias fails while sampling noise does not.
"""

import math

import numpy as np
import pytest

from ceco_v2x_preview import forecast_error as fe

N = 4000
LEADS = np.array([0.0, 1.0, 5.0, 30.0, 120.0, 300.0])


def _realisations(model, leads=LEADS, n=N):
    return np.array([fe.lead_errors(model, leads, np.random.default_rng([s, 7])) for s in range(n)])


@pytest.mark.parametrize(
    "model",
    [
        fe.ErrorModel(1.2, -0.15, 3600.0, "normal"),
        fe.ErrorModel(173.4, -15.0, 60.0, "laplace"),
        fe.ErrorModel(2.5, 0.4, 20.0, "normal"),
    ],
)
def test_moments_follow_the_ou_formulas(model):
    e = _realisations(model)
    assert np.all(e[:, 0] == 0.0)  # anchored at the measurement
    for j, tau in enumerate(LEADS[1:], start=1):
        sd = float(model.std(tau))
        assert abs(e[:, j].std() - sd) < 5 * sd / math.sqrt(2 * N) + 1e-12, (tau, e[:, j].std(), sd)
        assert abs(e[:, j].mean() - float(model.mean(tau))) < 5 * sd / math.sqrt(N), tau


def test_reference_lead_statistics_are_the_stated_ones():
    m = fe.ErrorModel(0.6, 0.3, 600.0)
    assert float(m.std(fe.REF_LEAD_S)) == pytest.approx(0.6, rel=1e-12)
    assert float(m.mean(fe.REF_LEAD_S)) == pytest.approx(0.3, rel=1e-12)
    # stationary values: sigma_inf > sigma_ref, std saturates far beyond theta
    assert m.sigma_inf == pytest.approx(0.6 / math.sqrt(1 - math.exp(-60 / 600)))
    assert float(m.std(1e6)) == pytest.approx(m.sigma_inf)
    assert float(m.mean(1e6)) == pytest.approx(0.3 / (1 - math.exp(-30 / 600)))


def test_laplace_innovations_have_heavy_tails():
    e = _realisations(fe.ErrorModel(100.0, 0.0, 60.0, "laplace"), leads=np.array([1.0]))[:, 0]
    kurt = float(np.mean((e - e.mean()) ** 4) / e.var() ** 2)
    assert kurt > 4.5  # Laplace: 6; normal: 3 (standard error ~0.5 here)
    g = _realisations(fe.ErrorModel(100.0, 0.0, 60.0, "normal"), leads=np.array([1.0]))[:, 0]
    assert float(np.mean((g - g.mean()) ** 4) / g.var() ** 2) < 3.5


def test_errors_depend_only_on_seed_issue_time_quantity_and_lead():
    short = fe.forecast_errors("medium", 3, 125.0, np.arange(0.0, 31.0, 5.0))
    long_ = fe.forecast_errors("medium", 3, 125.0, np.arange(0.0, 301.0, 5.0))
    again = fe.forecast_errors("medium", 3, 125.0, np.arange(0.0, 31.0, 5.0))
    for q in fe.QUANTITIES:
        np.testing.assert_array_equal(short[q], again[q])
        np.testing.assert_array_equal(short[q], long_[q][:7])  # the horizon length does not matter
    other_seed = fe.forecast_errors("medium", 4, 125.0, np.arange(0.0, 31.0, 5.0))
    other_time = fe.forecast_errors("medium", 3, 130.0, np.arange(0.0, 31.0, 5.0))
    for q in fe.QUANTITIES:
        assert not np.array_equal(short[q][1:], other_seed[q][1:])
        assert not np.array_equal(short[q][1:], other_time[q][1:])
    assert not np.array_equal(short["t_amb_c"][1:] / 1.2, short["speed_mps"][1:] / 2.5)  # separate streams


def test_levels_are_ordered_and_none_is_perfect():
    none = fe.forecast_errors("none", 0, 0.0, LEADS)
    assert all(np.all(v == 0.0) for v in none.values())
    for q in ("t_amb_c", "speed_mps"):
        s = [fe.LEVEL_MODELS[lv][q].sigma_ref for lv in fe.LEVELS]
        assert s == sorted(s) and s[0] == 0.0 and s[-1] > 0.0, q
    # BOPTEST's solar medium and high levels have nearly the same spread (bg0 122.6 vs 119.94 W/m2);
    # high differs by its larger under-forecast bias. Kept as published.
    solar = [fe.LEVEL_MODELS[lv]["solar_wm2"] for lv in fe.LEVELS]
    assert [abs(m.bias_ref) for m in solar] == sorted(abs(m.bias_ref) for m in solar)
    assert solar[1].sigma_ref < solar[3].sigma_ref < solar[2].sigma_ref
    # the BOPTEST magnitudes at the reference lead (sign converted: forecast - truth)
    assert fe.LEVEL_MODELS["high"]["t_amb_c"].bias_ref == 0.58
    assert fe.LEVEL_MODELS["medium"]["solar_wm2"].sigma_ref == pytest.approx(math.sqrt(2) * 122.6)
    with pytest.raises(ValueError, match="level"):
        fe.level_models("extreme")


def test_apply_errors_keeps_the_physical_limits():
    leads = np.arange(0.0, 61.0, 5.0)
    truth = {
        "t_amb_c": np.full(leads.size, 35.0),
        "solar_wm2": np.r_[np.full(6, 800.0), np.zeros(7)],
        "speed_mps": np.full(leads.size, 0.5),
        "rh": np.full(leads.size, 0.4),
    }
    lows = []
    for seed in range(200):
        f = fe.apply_errors(truth, "high", seed, 40.0, leads)
        assert f["t_amb_c"][0] == 35.0 and f["solar_wm2"][0] == 800.0 and f["speed_mps"][0] == 0.5
        assert np.all(f["solar_wm2"][6:] == 0.0)  # no error where the truth is 0
        assert np.all(f["solar_wm2"] >= 0.0) and np.all(f["speed_mps"] >= 0.0)
        np.testing.assert_array_equal(f["rh"], truth["rh"])
        lows.append(f["speed_mps"].min())
    assert min(lows) == 0.0  # the floor was needed
    np.testing.assert_array_equal(fe.apply_errors(truth, "none", 0, 40.0, leads)["solar_wm2"], truth["solar_wm2"])


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"sigma_ref": -1.0}, "sigma_ref"),
        ({"sigma_ref": 1.0, "corr_time_s": 0.0}, "corr_time_s"),
        ({"sigma_ref": 1.0, "distribution": "cauchy"}, "distribution"),
        ({"sigma_ref": math.nan}, "sigma_ref"),
    ],
)
def test_bad_models_are_rejected(kwargs, field):
    with pytest.raises(ValueError, match=field):
        fe.ErrorModel(**kwargs).validate()
    with pytest.raises(ValueError, match="lead_s"):
        fe.lead_errors(fe.ErrorModel(1.0), [-1.0], np.random.default_rng(0))


def test_previews_with_an_uncertainty_level():
    from ceco_v2x_preview.preview import PERFECT, PreviewQuality, make_previews, parse_quality
    from ceco_v2x_preview.scenario import load_scenario

    sc = load_scenario("sc03")
    q = parse_quality("uncertain:medium,seed=3")
    assert q == PreviewQuality(uncertainty="medium", seed=3) and parse_quality(q.describe()) == q
    assert q.mode == "uncertain" and parse_quality("uncertain:high+delayed:10").mode == "uncertain+delayed"
    p = make_previews(sc, 100.0, 5.0, 7, q)
    truth = make_previews(sc, 100.0, 5.0, 7, PERFECT)
    e = fe.forecast_errors("medium", 3, 100.0, truth.t_s - 100.0)
    np.testing.assert_allclose(p.t_amb_c - truth.t_amb_c, e["t_amb_c"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(p.speed_mps, np.maximum(truth.speed_mps + e["speed_mps"], 0.0), atol=1e-12)
    assert p.t_amb_c[0] == truth.t_amb_c[0] and np.any(p.solar_wm2[1:] != truth.solar_wm2[1:])
    np.testing.assert_array_equal(p.rh, truth.rh)
    # the level's seed falls back to the scenario's seed
    np.testing.assert_array_equal(
        make_previews(sc, 100.0, 5.0, 7, PreviewQuality(uncertainty="medium")).t_amb_c,
        make_previews(sc, 100.0, 5.0, 7, PreviewQuality(uncertainty="medium", seed=sc.seed)).t_amb_c,
    )
    with pytest.raises(ValueError, match="uncertain"):
        parse_quality("uncertain:extreme")
    with pytest.raises(ValueError, match="uncertainty"):
        PreviewQuality(uncertainty="huge").validate()
