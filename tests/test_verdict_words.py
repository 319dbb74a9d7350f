"""The verdict's words are true of the run they describe (exploratory test, 5 Dec 2026).

* "in -0.5..+0.5 from N s on" was printed for a run whose PMV left the band again (evening.yaml: below -0.5 from
  755 s to the end): the words now say when it left, from the run's PMV series;
* "a comparison at different comfort, not a saving" was printed when no strategy changed the discomfort; "over the
  last minute" for a 7-s run; the baseline's matched value as "-0.0 %";
* a run with a metabolic rate outside ISO 7730's validity (met 0.01: every sample invalid) ran without a word.

Pure and in-process (the simulator on the tester's scenarios, copied here, and hand-built series).
"""

import numpy as np
import pytest

from ceco_bringup import verdict as vd
from ceco_controller.closed_loop import SimSettings, simulate
from ceco_v2x_preview.scenario import load_scenario

EVENING = """\
name: evening
description: hot car at sunset, the air cools quickly after a storm front
drive_cycle: udds
duration_s: 900
weather:
  time_s: [0, 300, 600, 900]
  t_amb_c: [33.0, 28.0, 18.0, 15.0]
  solar_wm2: [600.0, 300.0, 0.0, 0.0]
  rh: [0.4, 0.5, 0.7, 0.8]
occupant: {met: 1.2, clo: 0.5}
comfort_bounds:
  time_s: [0, 30, 240]
  pmv_lb: -0.5
  pmv_ub: [3.0, 3.0, 0.5]
initial: {t_cab_c: 40.0, t_int_c: 42.0, t_shell_c: 43.0}
"""
"""An evening drive of an exploratory test (5 Dec 2026): the air cools after a storm, the PMV falls below the band."""

LIGHTMET = """\
name: lightmet
drive_cycle: us06
duration_s: 120
weather: {time_s: [0], t_amb_c: 35.0, solar_wm2: 850.0, rh: 0.4}
occupant: {met: 0.01, clo: 0}
comfort_bounds: {time_s: [0], pmv_lb: -0.5, pmv_ub: 0.5}
initial: {t_cab_c: 43.0}
"""
"""An exploratory test's scenario, met 0.01 (ISO 7730 covers 0.8-4 met; the scenario loader allows 0 < met <= 4)."""


def _baseline(tmp_path, text: str, name: str) -> dict:
    """The baseline run on the scenario ``text`` (written to tmp_path): its timeseries columns."""
    path = tmp_path / f'{name}.yaml'
    path.write_text(text, encoding='utf-8')
    return simulate(load_scenario(str(path)), 'baseline', SimSettings(progress=False)).timeseries


def _columns(pmv, valid=None, dt: float = 1.0) -> dict:
    """A run's timeseries columns with the PMV ``pmv`` (and ``iso7730_valid``), the rest constant."""
    y = np.asarray(pmv, dtype=float)
    n = y.size
    cols = {
        't_s': np.arange(n) * dt,
        'p_comp_w': np.full(n, 2000.0),
        'p_blower_w': np.full(n, 200.0),
        'p_cond_fan_w': np.full(n, 300.0),
        'pmv': y,
        'pmv_lb': np.full(n, -0.5),
        'pmv_ub': np.full(n, 0.5),
        'mdot_bl_kgps': np.full(n, 0.1),
        't_evap_sp_c': np.full(n, 5.0),
    }
    if valid is not None:
        cols['iso7730_valid'] = np.asarray(valid, dtype=float)
    return cols


def _text(points: dict, family: dict | None = None) -> str:
    """The verdict lines of ``points``, unwrapped (they are wrapped at 100 characters)."""
    lines = vd.verdict_lines(vd.build_verdict('sc', points, family))
    assert max(len(line) for line in lines) <= 100
    return ' '.join(' '.join(lines).split())


# ---------------------------------------------------------------------------------------- 1. the band
def test_a_pmv_that_leaves_the_band_again_is_not_in_it_from_n_s_on(tmp_path):
    """evening.yaml: the baseline's PMV is in -0.5..+0.5 from 211 s (for 60 s and on) until 755 s, below -0.5 from
    755 s to the end. The verdict said 'in -0.5..+0.5 from 211 s on'; it says 'from 211 s to 755 s'."""
    cols = _baseline(tmp_path, EVENING, 'evening')
    t, y = np.asarray(cols['t_s']), np.asarray(cols['pmv'])
    inside = (y >= -0.5) & (y <= 0.5)
    assert inside[(t >= 211) & (t < 755)].all() and not inside[t >= 755].any() and (y[t >= 755] < -0.5).all()
    p = vd.run_point(cols)
    assert p['time_to_comfort_s'] == 211.0 and p['pmv_left_band_s'] == 755.0
    assert p['pmv_out_after_comfort_s'] == pytest.approx(900.0 - 755.0)
    text = _text({'baseline': p})
    assert 'baseline 0.199 kWh, 0.051 PMV h: in -0.5..+0.5 from 211 s to 755 s (PMV -0.94 at the end)' in text
    assert 'from 211 s on' not in text


def test_band_words_from_the_pmv_series():
    """Stays in: 'from N s on' (the sc03 lines); leaves and comes back: the time out of it after and, when the run
    ends out of it, since when; a verdict.json from before these keys: no claim that it stayed."""
    stays = [1.0] * 100 + [0.2] * 200
    back = [1.0] * 100 + [0.2] * 100 + [0.8] * 30 + [0.2] * 70
    back_out = back[:-40] + [-0.7] * 40
    text = _text({n: vd.run_point(_columns(y)) for n, y in (('stays', stays), ('back', back), ('backout', back_out))})
    assert 'stays 0.208 kWh, 0.014 PMV h: in -0.5..+0.5 from 100 s on (PMV +0.20 at the end)' in text
    assert 'back 0.208 kWh, 0.016 PMV h: in -0.5..+0.5 from 100 s, out of it 30 of the 200 s after (PMV +0.20' in text
    assert 'in -0.5..+0.5 from 100 s, out of it 70 of the 200 s after, from 260 s to the end (PMV -0.40' in text
    old = {k: v for k, v in vd.run_point(_columns(back)).items() if k not in vd.AFTER_COMFORT_KEYS}
    assert 'in -0.5..+0.5 for 60 s from 100 s (PMV' in _text({'old': old})


# ---------------------------------------------------------------------------------------- 2. cosmetic but untrue
def _point(d, e, **kw):
    p = dict(energy_kwh=e, discomfort_pmvh=d, time_to_comfort_s=None, pmv_end=0.6, duration_s=600.0)
    p.update(kw)
    return p


def test_the_same_discomfort_is_not_called_a_comparison_at_different_comfort():
    """A mild day: every run in the band all the time (discomfort 0): the discomfort changes by +0.0 % and the
    closing words no longer say 'at different comfort'; with a different discomfort they still do."""
    same = {'baseline': _point(0.0, 0.30), 'ceco': _point(0.0, 0.27), 'ceco-e': _point(0.0, 0.31)}
    text = _text(same)
    assert 'the energy changes by -10.0..+3.3 % and the discomfort by +0.0 % (+ = more): the same discomfort' in text
    assert 'at different comfort' not in text and 'not a saving' not in text
    other = _text({**same, 'ceco-c': _point(0.01, 0.33)})
    assert 'a comparison at different comfort, not a saving.' in other
    # the same only because the PMV sat at the +-3 clip the whole run (a 7-s hot start): not called a saving either
    clip = 7.0 * 2.5 / 3600.0  # ceco_core.kpis.discomfort_ceiling of a 7-s run [PMV h]
    hot = _text({'baseline': _point(clip, 0.008, duration_s=7.0), 'ceco': _point(clip, 0.007, duration_s=7.0)})
    assert "by +0.0 % (+ = more): the same discomfort only because every run's PMV sat at the +-3 clip: not a" in hot
    # one run's change undefined (against a baseline of 0 PMV h): not called the same
    assert 'not a saving' in _text({'baseline': _point(0.0, 0.30), 'ceco': _point(0.0, 0.27), 'x': _point(0.2, 0.2)})


def test_a_run_shorter_than_a_minute_is_not_quoted_over_the_last_minute():
    """A 7-s run's end PMV is its mean over the run: 'over the run'; a 600-s run's over the last minute."""
    text = _text({'short': vd.run_point(_columns([2.0] * 7))})
    assert 'never stayed in -0.5..+0.5 (PMV +2.00 over the run)' in text and 'last minute' not in text
    assert 'over the last minute' in _text({'long': vd.run_point(_columns([2.0] * 600))})


FAMILY = {
    'baseline@25.0': _point(0.11, 0.40),
    'baseline@26.0': _point(0.13, 0.37),
    'baseline@27.0': _point(0.17, 0.34),
}
TUNED = {
    f'baseline-tuned@{k.split("@")[1]}': _point(p['discomfort_pmvh'], p['energy_kwh'] * 1.05) for k, p in FAMILY.items()
}


def test_the_baselines_matched_value_is_never_minus_zero():
    """The baseline a hair above its own front (-0.00003 %): printed +0.0 / +0.00, as the other signs."""
    points = {'baseline': _point(0.13, 0.37 * (1 + 3e-7)), 'ceco': _point(0.11, 0.38)}
    two = _text(points, {**FAMILY, **TUNED})
    assert 'same energy as the set-point family at matched comfort (+0.0 %, under 1 %); +0.0 % against the' in two
    one = _text(points, FAMILY)
    assert 'on the front (+0.00 % against it: the family holds this same law)' in one
    assert '-0.0' not in two + one


# ---------------------------------------------------------------------------------------- 3. ISO 7730 validity
def test_a_pmv_outside_iso_7730_validity_is_said_so(tmp_path):
    """lightmet.yaml (met 0.01, clo 0): every sample is outside ISO 7730's validity and the PMV is -22; the verdict
    says so with the share. Under ISO_INVALID_SAY_PCT of the samples nothing is said; above it the run is named."""
    p = vd.run_point(_baseline(tmp_path, LIGHTMET, 'lightmet'))
    assert p['iso7730_invalid_pct'] == 100.0 and p['pmv_end'] < -20.0
    text = _text({'baseline': p})
    assert (
        "ISO 7730: the PMV is outside the standard's validity (a PMV input or the PMV outside its Clause 4 ranges) in"
        ' 100.0 % of the samples of baseline, more than 10 %: every PMV number of theirs above is outside it.'
    ) in text
    y = [1.0] * 100 + [0.2] * 200
    few, many = ([0.0] * n + [1.0] * (300 - n) for n in (30, 33))  # 10.0 % and 11.0 % of the samples outside
    both = _text({'few': vd.run_point(_columns(y, few)), 'many': vd.run_point(_columns(y, many))})
    assert 'in 11.0 % of the samples of many, more than 10 %' in both and 'of few' not in both
    assert 'ISO 7730' not in _text({'few': vd.run_point(_columns(y, few))})
    every = _text({'a': vd.run_point(_columns(y, many)), 'b': vd.run_point(_columns(y, [0.0] * 90 + [1.0] * 210))})
    assert (
        'in 11.0-30.0 % of the samples of every run, more than 10 %: their PMV numbers above drawn from those samples'
        ' are outside it.'
    ) in every
