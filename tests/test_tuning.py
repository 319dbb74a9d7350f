"""The gain-tuning objective of the baseline families (ceco_bringup.benchmark.tuning.front_objective), by hand."""

import pytest

from ceco_bringup.benchmark import front as fr
from ceco_bringup.benchmark import tuning


def test_objective_levels_and_mean_energy():
    # A: (0.10, 0.40) -> (0.15, 0.30); B starts later (0.104) and is cheaper; C cannot come within 10 %.
    a = fr.build_front({"a1": (0.10, 0.40), "a2": (0.15, 0.30)})
    b = fr.build_front({"b1": (0.104, 0.38), "b2": (0.12, 0.31)})
    c = fr.build_front({"c1": (0.12, 0.20)})
    levels, obj = tuning.front_objective({"A": a, "B": b, "C": c}, n_levels=3)
    # D_a = max(0.10, 0.104) = 0.104 (C is out: 0.12 > 1.1 x 0.10); D_b = 1.5 x 0.10; excess doubles: 0, 1/3, 1
    assert levels == pytest.approx([0.104, 0.104 + 0.046 / 3.0, 0.15])
    assert obj["C"] is None
    ea = [0.40 - 2.0 * (x - 0.10) for x in levels]  # A: E = 0.40 - 2 (D - 0.10)
    assert obj["A"] == pytest.approx(sum(ea) / 3.0)
    # B: on its segment, then its last vertex's energy past 0.12
    assert levels[1] < 0.12  # the middle level lies on B's segment
    eb = [0.38, 0.38 - (0.07 / 0.016) * (levels[1] - 0.104), 0.31]
    assert obj["B"] == pytest.approx(sum(eb) / 3.0)
    assert obj["B"] < obj["A"]
    with pytest.raises(ValueError):
        tuning.front_objective({})


def test_default_levels_concentrate_at_the_comfortable_end():
    f = fr.build_front({"x": (0.1, 0.4), "y": (0.2, 0.2)})
    levels, _ = tuning.front_objective({"X": f})
    frac = [(x - levels[0]) / (levels[-1] - levels[0]) for x in levels]
    assert (
        len(levels) == tuning.N_LEVELS == 11
        and frac[1] == pytest.approx(1.0 / 1023.0)
        and frac[-2] == pytest.approx(511.0 / 1023.0)
    )
    assert levels[-1] == pytest.approx(1.5 * 0.1)
