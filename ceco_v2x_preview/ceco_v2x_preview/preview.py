"""V2X previews (weather and traffic forecasts) of a given quality.

The paper assumed perfect previews. Real V2X forecasts are noisy, arrive late,
or stop arriving; :class:`PreviewQuality` describes such faults and
:func:`make_previews` produces what a controller would receive at ``t0_s``.

Model (docs/scenarios.md, "Preview quality")
--------------------------------------------
* A forecast is *issued* at ``t_issue`` and covers lead times
  ``0 .. (n-1)*step_s`` after it.
* Forecast error grows with lead time: for each quantity x with
  ``noise_std_x`` the error is a scaled Brownian motion in the lead time L,
  ``e_x(L) = noise_std_x * W(L) / sqrt(noise_ref_lead_s)``, so
  ``std(e_x(L)) = noise_std_x * sqrt(L / noise_ref_lead_s)``: zero for the
  present, ``noise_std_x`` at the reference lead, correlated along the
  horizon (a forecast that is too high now stays too high a little later).
  W is drawn on a 1 s lead grid and interpolated linearly.
* ``uncertainty`` (the benchmark's levels none/low/medium/high): BOPTEST-style
  seeded AR(1) errors along the lead time, :mod:`ceco_v2x_preview.forecast_error`
  (applied to the truth first; the ``noise_std_*`` errors above add to them).
* ``delay_s``: the forecast received at ``t0_s`` was issued at
  ``t0_s - delay_s`` (stale). It is re-sampled on the controller's grid
  ``t0_s + i*step_s``: its errors are those of the longer lead times, and the
  last ``ceil(delay_s/step_s)`` or so samples lie beyond what was issued and
  are marked invalid (NaN).
* ``persistence``: no forecast at all: every sample of the horizon holds the value measured at
  the issue time (the naive "no preview" predictor a controller falls back to; issue 20). It
  replaces the forecast, so it excludes ``uncertainty`` and ``noise_std_*``; delay and missing
  spans still apply (the value held is the one measured at the issue time).
* ``missing_spans_s``: while ``t0_s`` is in a half-open span ``[a, b)`` no
  new forecast arrives. With ``missing_policy='hold_last'`` (default) the
  controller keeps the last forecast received, the one issued at
  ``a - delay_s``: it ages, its trusted part shrinks and, once ``t0_s`` is
  past its horizon, every sample is invalid. With ``'drop'`` nothing at all
  is available inside the span.
* Before any forecast has been issued (``t0_s - delay_s < 0``) nothing is
  available.

Physical limits (not silent clamps): a forecast of negative irradiance or
negative speed is not a forecast any provider would publish, so noisy solar
and speed are floored at 0 and noisy relative humidity is kept in [0, 1].
This makes the error distribution one-sided near those limits (its mean is
slightly positive at night or at standstill); it is documented, and
:class:`Previews` keeps no hidden state about it.

Determinism: the noise of the forecast issued at ``t_issue`` is drawn from
``numpy.random.default_rng([seed, round(t_issue_s*1000), quantity])``, so the
numbers depend only on the seed, the issue time and the lead time, never on
the call order, on ``n`` or on the process that asks.

Pure Python (numpy); no ROS import.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from ceco_core.contracts import NOISE_SEED_RANGE, PREVIEW_QUANTITIES, Previews
from ceco_core.control_grid import control_step_count
from ceco_v2x_preview import forecast_error
from ceco_v2x_preview.scenario import Scenario

__all__ = [
    "PreviewQuality",
    "Previews",
    "PERFECT",
    "DEFAULT_NOISE",
    "make_previews",
    "no_preview_warning",
    "parse_quality",
    "FAULT_RANGES",
    "SEED_RANGE",
    "usable_steps",
    "summarize",
]

MISSING_POLICIES = ("hold_last", "drop")
"""What the receiver does while previews are missing (see module docstring)."""

_NOISE_GRID_S = 1.0
"""Lead-time resolution of the simulated forecast error [s]."""

_QUANTITIES = PREVIEW_QUANTITIES
"""Previewed quantities, in the order used as the noise stream index."""

_KEYS = {
    "t_amb": "noise_std_t_amb_c",
    "solar": "noise_std_solar_wm2",
    "speed": "noise_std_speed_mps",
    "rh": "noise_std_rh",
}
"""Short names used by :func:`parse_quality` for the noise fields."""

FAULT_RANGES: dict[str, tuple[float, float]] = {
    "noise_std_t_amb_c": (0.0, 20.0),
    "noise_std_solar_wm2": (0.0, 1000.0),
    "noise_std_speed_mps": (0.0, 30.0),
    "noise_std_rh": (0.0, 1.0),
    "noise_ref_lead_s": (0.1, 86400.0),
    "delay_s": (0.0, 86400.0),
}
"""Closed range of each numeric fault of :class:`PreviewQuality`, in the field's unit.

preview_node declares its parameter ``faults.<field>`` with it (``preview_io.PREVIEW_PARAMETERS``) and
:func:`parse_quality` refuses a value outside it, so that a preview string ``ceco run`` takes is one the node
takes (the node would exit on a value outside its declared range)."""

SEED_RANGE = NOISE_SEED_RANGE
"""Range of a noise seed [-] (:data:`ceco_core.contracts.NOISE_SEED_RANGE`: preview_node's ``faults.seed``)."""

_PART_OF = {
    "noise_std_t_amb_c": ("noisy t_amb", "K"),
    "noise_std_solar_wm2": ("noisy solar", "W/m2"),
    "noise_std_speed_mps": ("noisy speed", "m/s"),
    "noise_std_rh": ("noisy rh", "-"),
    "noise_ref_lead_s": ("noisy ref", "s"),
    "delay_s": ("delayed", "s"),
}
"""Field -> (its part of the :func:`parse_quality` grammar, its unit), for the range errors."""


@dataclasses.dataclass(frozen=True)
class PreviewQuality:
    """Quality of the V2X previews; the default is a perfect preview.

    The faults compose: a noisy forecast may also be delayed and missing
    for some spans.
    """

    noise_std_t_amb_c: float = 0.0
    """Std of the ambient-temperature forecast error at lead noise_ref_lead_s [K], >= 0."""
    noise_std_solar_wm2: float = 0.0
    """Std of the solar-irradiance forecast error at lead noise_ref_lead_s [W/m2], >= 0."""
    noise_std_speed_mps: float = 0.0
    """Std of the vehicle-speed forecast error at lead noise_ref_lead_s [m/s], >= 0."""
    noise_std_rh: float = 0.0
    """Std of the relative-humidity forecast error at lead noise_ref_lead_s [-], >= 0."""
    noise_ref_lead_s: float = 30.0
    """Lead time at which the error std equals noise_std_* [s], > 0 (default Np*Ts = 6*5 s)."""
    delay_s: float = 0.0
    """Age of the forecast when it is received [s], >= 0."""
    missing_spans_s: tuple = ()
    """Half-open spans ((start_s, end_s), ...) of t0 during which no forecast arrives."""
    missing_policy: str = "hold_last"
    """'hold_last' (keep the last forecast received) or 'drop' (nothing available)."""
    seed: int | None = None
    """Noise seed, >= 0; None uses the scenario's seed."""
    uncertainty: str = "none"
    """Forecast-uncertainty level of the benchmark (``forecast_error.LEVELS``: none, low, medium,
    high): seeded AR(1) errors of ambient temperature, solar irradiance and speed along the lead
    time (:mod:`ceco_v2x_preview.forecast_error`); composes with the other faults."""
    persistence: bool = False
    """No forecast: each previewed quantity holds, over the whole horizon, its value at the issue
    time (the last measured value); excludes ``uncertainty`` and the ``noise_std_*`` errors."""

    def __post_init__(self):
        try:
            spans = tuple((float(a), float(b)) for a, b in self.missing_spans_s)
        except (TypeError, ValueError):
            raise ValueError(
                f"missing_spans_s: must be a sequence of (start_s, end_s) number pairs, got {self.missing_spans_s!r}"
            ) from None
        object.__setattr__(self, "missing_spans_s", spans)

    def validate(self) -> None:
        """Raise ValueError naming the first bad field."""
        for name in (*_KEYS.values(), "delay_s"):
            x = getattr(self, name)
            if not (isinstance(x, (int, float)) and math.isfinite(x) and x >= 0.0):
                raise ValueError(f"{name}: must be finite and >= 0, got {x!r}")
        r = self.noise_ref_lead_s
        if not (isinstance(r, (int, float)) and math.isfinite(r) and r > 0.0):
            raise ValueError(f"noise_ref_lead_s: must be finite and > 0, got {r!r}")
        for i, (a, b) in enumerate(self.missing_spans_s):
            if not (math.isfinite(a) and math.isfinite(b) and 0.0 <= a < b):
                raise ValueError(f"missing_spans_s[{i}]: need finite 0 <= start < end, got ({a}, {b})")
        if self.missing_policy not in MISSING_POLICIES:
            raise ValueError(f"missing_policy: must be one of {MISSING_POLICIES}, got {self.missing_policy!r}")
        if self.seed is not None and (isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0):
            raise ValueError(f"seed: must be a non-negative integer or None, got {self.seed!r}")
        if self.uncertainty not in forecast_error.LEVELS:
            raise ValueError(f"uncertainty: must be one of {forecast_error.LEVELS}, got {self.uncertainty!r}")
        if not isinstance(self.persistence, bool):
            raise ValueError(f"persistence: must be a bool, got {self.persistence!r}")
        if self.persistence and (self.uncertainty != "none" or self.noisy):
            raise ValueError(
                "persistence: holds the measured value instead of a forecast; it cannot be combined with "
                "uncertainty or noisy (forecast errors)"
            )

    @property
    def noisy(self) -> bool:
        """True when any noise std is positive."""
        return any(getattr(self, f) > 0.0 for f in _KEYS.values())

    @property
    def uses_seed(self) -> bool:
        """True when the previews depend on the seed: forecast errors (``uncertainty`` or ``noisy``).

        Perfect, persistence, delayed and missing previews are the same for every seed.
        """
        return self.uncertainty != "none" or self.noisy

    @property
    def mode(self) -> str:
        """'perfect', or the faults present joined by '+' ('noisy+delayed')."""
        parts = [
            name
            for name, on in (
                ("persistence", self.persistence),
                ("uncertain", self.uncertainty != "none"),
                ("noisy", self.noisy),
                ("delayed", self.delay_s > 0.0),
                ("missing", bool(self.missing_spans_s)),
            )
            if on
        ]
        return "+".join(parts) or "perfect"

    def describe(self) -> str:
        """Canonical text form; ``parse_quality(q.describe()) == q``."""
        parts = []
        if self.persistence:
            parts.append("persistence")
        if self.uncertainty != "none":
            seed = f",seed={self.seed}" if self.seed is not None and not self.noisy else ""
            parts.append(f"uncertain:{self.uncertainty}{seed}")
        if self.noisy or (self.seed is not None and self.uncertainty == "none"):
            kv = [f"{k}={_fmt(getattr(self, f))}" for k, f in _KEYS.items()]
            kv.append(f"ref={_fmt(self.noise_ref_lead_s)}")
            if self.seed is not None:
                kv.append(f"seed={self.seed}")
            parts.append("noisy:" + ",".join(kv))
        if self.delay_s > 0.0:
            parts.append(f"delayed:{_fmt(self.delay_s)}")
        if self.missing_spans_s:
            spans = ",".join(f"{_fmt(a)}-{_fmt(b)}" for a, b in self.missing_spans_s)
            parts.append(f"missing:{spans},policy={self.missing_policy}")
        return "+".join(parts) or "perfect"

    def merged_spans(self) -> list[tuple[float, float]]:
        """Missing spans sorted, with overlapping or touching spans merged."""
        merged: list[list[float]] = []
        for a, b in sorted(self.missing_spans_s):
            if merged and a <= merged[-1][1]:
                merged[-1][1] = max(merged[-1][1], b)
            else:
                merged.append([a, b])
        return [(a, b) for a, b in merged]


def _fmt(x: float) -> str:
    return repr(float(x)).removesuffix(".0") if float(x).is_integer() else repr(float(x))


PERFECT = PreviewQuality()
"""The paper's assumption: previews equal the truth over the whole horizon."""

DEFAULT_NOISE = {"noise_std_t_amb_c": 0.5, "noise_std_solar_wm2": 50.0, "noise_std_speed_mps": 1.5}
"""Noise used by ``parse_quality('noisy')`` (at the 30 s reference lead):
illustrative values for a short-range V2X forecast (docs/scenarios.md), not
measured forecast statistics."""


def _issue_time(quality: PreviewQuality, t0_s: float) -> float:
    """When the forecast held at ``t0_s`` [s] was issued [s]; negative when none is held (module docstring)."""
    for a, b in quality.merged_spans():
        if a <= t0_s < b:
            return a - quality.delay_s if quality.missing_policy == "hold_last" else -math.inf
    return t0_s - quality.delay_s


def _within_issued(lead_s, horizon_s: float):
    """Leads [s] inside what a forecast of ``horizon_s`` [s] covers (True where valid)."""
    return lead_s <= horizon_s * (1.0 + 1e-12) + 1e-9


def usable_steps(quality: PreviewQuality, n_steps: int, step_s: float, n: int) -> int:
    """How many control steps receive a preview with at least one valid sample.

    The steps at t0 = k ``step_s`` [s], k < ``n_steps``, previews of ``n`` points; :func:`make_previews`' rule
    (no scenario needed: validity depends on the times only).
    """
    count = 0
    for k in range(int(n_steps)):
        t0_s = k * step_s
        t_issue = _issue_time(quality, t0_s)
        count += bool(t_issue >= 0.0 and _within_issued(t0_s - t_issue, (n - 1) * step_s))
    return count


def no_preview_warning(quality: PreviewQuality, duration_s: float, step_s: float, horizon_steps: int) -> str:
    """A sentence when no control step of a run receives a usable preview of this quality ('' when some step does).

    The run: ``duration_s`` [s], Ts ``step_s`` [s], Np ``horizon_steps`` (previews of Np + 1 points). A delay
    beyond the horizon, or missing spans over the whole run, leave the NMPC the measured weather alone, which
    the run's label would not say.
    """
    n_steps = control_step_count(duration_s, step_s)
    if usable_steps(quality, n_steps, step_s, horizon_steps + 1):
        return ""
    return (
        f"no control step of the run receives a usable preview with {quality.describe()} (Ts {step_s:g} s, "
        f"Np {horizon_steps}: every forecast is missing or older than its {horizon_steps * step_s:g} s horizon "
        f"in all {n_steps} steps): the CECO strategies run on the measured weather alone"
    )


def make_previews(
    scenario: Scenario, t0_s: float, step_s: float, n: int, quality: PreviewQuality = PERFECT
) -> Previews:
    """The previews a controller receives at ``t0_s`` [s], for the given quality (module docstring).

    They lie on the grid ``t0_s + i*step_s``, i = 0..n-1.
    """
    quality.validate()
    if not (isinstance(t0_s, (int, float, np.floating, np.integer)) and math.isfinite(t0_s) and t0_s >= 0.0):
        raise ValueError(f"t0_s: must be finite and >= 0, got {t0_s!r}")
    if not (math.isfinite(step_s) and step_s > 0.0):
        raise ValueError(f"step_s: must be finite and > 0, got {step_s!r}")
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise ValueError(f"n: must be an integer >= 1, got {n!r}")
    t0_s, step_s, n = float(t0_s), float(step_s), int(n)
    t_s = t0_s + step_s * np.arange(n, dtype=float)

    t_issue = _issue_time(quality, t0_s)
    if t_issue < 0.0:  # nothing issued yet, or dropped
        nan = np.full(n, np.nan)
        return Previews(
            t0_s=t0_s,
            step_s=step_s,
            t_amb_c=nan,
            solar_wm2=nan.copy(),
            speed_mps=nan.copy(),
            rh=nan.copy(),
            valid=np.zeros(n, dtype=bool),
            age_s=math.inf,
            issued_s=math.nan,
        )

    lead_s = t_s - t_issue
    valid = _within_issued(lead_s, (n - 1) * step_s)
    if quality.persistence:  # the value measured at the issue time, held over the horizon
        env = scenario.env_series(np.full(n, t_issue))
    else:
        env = scenario.env_series(t_s)
    values = {q: np.array(getattr(env, q), dtype=float) for q in _QUANTITIES}

    if quality.uncertainty != "none":
        seed = scenario.seed if quality.seed is None else quality.seed
        values = forecast_error.apply_errors(values, quality.uncertainty, seed, t_issue, lead_s)

    if quality.noisy:
        seed = scenario.seed if quality.seed is None else quality.seed
        issue_key = int(round(t_issue * 1000.0))
        n_grid = int(math.ceil(float(np.max(lead_s)) / _NOISE_GRID_S)) + 1
        grid_s = _NOISE_GRID_S * np.arange(n_grid + 1, dtype=float)
        for index, (q, field) in enumerate(
            zip(_QUANTITIES, (_KEYS["t_amb"], _KEYS["solar"], _KEYS["speed"], _KEYS["rh"]))
        ):
            sigma = getattr(quality, field)
            if sigma == 0.0:
                continue
            rng = np.random.default_rng([seed, issue_key, index])
            walk = np.concatenate(([0.0], np.cumsum(rng.standard_normal(n_grid)) * math.sqrt(_NOISE_GRID_S)))
            err = sigma * np.interp(lead_s, grid_s, walk) / math.sqrt(quality.noise_ref_lead_s)
            values[q] = values[q] + err
        # Physical limits of a published forecast (module docstring).
        values["solar_wm2"] = np.maximum(values["solar_wm2"], 0.0)
        values["speed_mps"] = np.maximum(values["speed_mps"], 0.0)
        values["rh"] = np.clip(values["rh"], 0.0, 1.0)

    for q in _QUANTITIES:
        values[q][~valid] = np.nan
    return Previews(t0_s=t0_s, step_s=step_s, valid=valid, age_s=t0_s - t_issue, issued_s=t_issue, **values)


def parse_quality(text: str) -> PreviewQuality:
    """Parse a preview quality from a command-line string.

    Grammar: parts joined by ``+``; each part one of

    * ``perfect``
    * ``persistence`` (no forecast: the value measured at the issue time held over the horizon)
    * ``uncertain:LEVEL[,seed=N]`` with LEVEL in none, low, medium, high (the benchmark's
      forecast-uncertainty levels, :mod:`ceco_v2x_preview.forecast_error`)
    * ``noisy`` or ``noisy:KEY=VALUE,...`` with KEY in t_amb [K], solar
      [W/m2], speed [m/s], rh [-], ref (reference lead, s), seed; keys not
      given are 0 except that a bare ``noisy`` uses :data:`DEFAULT_NOISE`
    * ``delayed:SECONDS``
    * ``missing:START-END[,START-END...][,policy=hold_last|drop]`` (seconds)

    Examples: ``"noisy:solar=50,speed=1.5,seed=3"``, ``"delayed:10"``,
    ``"missing:100-200"``, ``"noisy+delayed:10+missing:100-200,policy=drop"``.
    Raises ValueError naming the bad part, also for a value outside preview_node's range
    (:data:`FAULT_RANGES`, :data:`SEED_RANGE`): ``ceco sim`` and ``ceco run`` take the same strings.
    """
    if not isinstance(text, str) or not text.strip():
        raise ValueError("preview quality: empty string")
    fields: dict = {}
    spans: list = []
    seen: set = set()
    for part in text.strip().split("+"):
        kind, _, arg = part.strip().partition(":")
        kind = kind.strip().lower()
        if kind in seen:  # the second would replace the first without a word
            raise ValueError(f"preview quality: {kind} given twice in {text!r}: give each part once")
        seen.add(kind)
        if kind == "perfect" and not arg:
            continue
        if kind == "persistence" and not arg:
            fields["persistence"] = True
            continue
        if kind == "noisy":
            if not arg.strip():
                fields.update(DEFAULT_NOISE)
                continue
            for item in arg.split(","):
                key, eq, value = item.partition("=")
                key = key.strip()
                if not eq:
                    raise ValueError(f"preview quality: noisy: expected KEY=VALUE, got {item!r}")
                if key == "seed":
                    fields["seed"] = _parse_int(value, "noisy seed")
                elif key == "ref":
                    fields["noise_ref_lead_s"] = _parse_float(value, "noisy ref")
                elif key in _KEYS:
                    fields[_KEYS[key]] = _parse_float(value, f"noisy {key}")
                else:
                    raise ValueError(f"preview quality: noisy: unknown key {key!r} (use {sorted(_KEYS)} , ref, seed)")
        elif kind == "uncertain":
            level, *rest = [x.strip() for x in arg.split(",")]
            if level not in forecast_error.LEVELS:
                raise ValueError(
                    f"preview quality: uncertain: level must be one of {forecast_error.LEVELS}, got {level!r}"
                )
            fields["uncertainty"] = level
            for item in rest:
                key, eq, value = item.partition("=")
                if key.strip() != "seed" or not eq:
                    raise ValueError(f"preview quality: uncertain: expected seed=N after the level, got {item!r}")
                fields["seed"] = _parse_int(value, "uncertain seed")
        elif kind == "delayed":
            fields["delay_s"] = _parse_float(arg, "delayed")
        elif kind == "missing":
            for item in arg.split(","):
                item = item.strip()
                if item.startswith("policy="):
                    fields["missing_policy"] = item.partition("=")[2].strip()
                    continue
                a, dash, b = item.partition("-")
                if not dash:
                    raise ValueError(f"preview quality: missing: expected START-END, got {item!r}")
                spans.append((_parse_float(a, "missing start"), _parse_float(b, "missing end")))
            if not spans:
                raise ValueError("preview quality: missing: needs at least one START-END span")
        else:
            raise ValueError(
                f"preview quality: unknown part {part.strip()!r} "
                "(use perfect, persistence, uncertain:LEVEL, noisy[:...], delayed:S, missing:A-B)"
            )
    quality = PreviewQuality(missing_spans_s=tuple(spans), **fields)
    _check_node_ranges(quality)
    quality.validate()
    return quality


def _check_node_ranges(quality: PreviewQuality) -> None:
    """Raise ValueError (one line, the part, the value, the range) for a fault outside preview_node's range."""
    for name, (lo, hi) in FAULT_RANGES.items():
        x = getattr(quality, name)
        if not lo <= x <= hi:
            part, unit = _PART_OF[name]
            raise ValueError(
                f"preview quality: {part}: {x:g} {unit} is outside {lo:g}..{hi:g} {unit}, the range of "
                f"preview_node's faults.{name}"
            )
    lo_seed, hi_seed = SEED_RANGE
    if quality.seed is not None and not lo_seed <= quality.seed <= hi_seed:
        raise ValueError(
            f"preview quality: seed: {quality.seed} is outside {lo_seed}..{hi_seed}, the range of preview_node's "
            "faults.seed"
        )


def _parse_float(text: str, what: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise ValueError(f"preview quality: {what}: not a number: {text!r}") from None
    if not math.isfinite(x):
        raise ValueError(f"preview quality: {what}: must be finite, got {text!r}")
    return x


def _parse_int(text: str, what: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"preview quality: {what}: not an integer: {text!r}") from None


def summarize(previews: Sequence[Previews]) -> dict:
    """Share of valid samples and mean age over a run's previews (for reports)."""
    if not previews:
        return {"valid_fraction": math.nan, "mean_age_s": math.nan}
    valid = np.concatenate([p.valid for p in previews])
    ages = np.array([p.age_s for p in previews if math.isfinite(p.age_s)])
    return {"valid_fraction": float(valid.mean()), "mean_age_s": float(ages.mean()) if ages.size else math.nan}
