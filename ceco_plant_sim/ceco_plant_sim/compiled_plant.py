"""The plant's compiled fast path: one plant step with its scored comfort as generated C, compiled once and cached.

The simulator's plant step (:class:`~ceco_plant_sim.scenario_plant.ScenarioPlant`: the scored comfort
at t_n, then :class:`~ceco_plant_sim.plant.CabinPlant` over the step and its report) is the same code
evaluated by :class:`~ceco_plant_sim.plant_ops.CompiledOps` instead of Python floats:

* the plant's equations (:class:`~ceco_plant_sim.plant_equations.PlantEquations`: ``step`` then
  ``outputs``) and the comfort (:func:`ceco_core.cabin_comfort.evaluate_cabin_comfort`) are traced once
  into one CasADi Function (:func:`build_step_function`); every float parameter they read
  (:class:`~ceco_plant_sim.plant_params.PlantParams`, :class:`~ceco_core.cabin_comfort.ComfortParams`,
  e.g. a scenario's clothing or a sensitivity run's jet share) is an input (``theta``), so one compiled
  object serves every scenario and override; the values that shape the code (:data:`PLANT_STRUCTURAL`,
  :data:`COMFORT_STRUCTURAL`, integers, flags, the plant step) are constants of it;
* the refrigerant Newton solve and the inverter-power secant are conditional calls that stop where the
  numeric solve stops (:class:`~ceco_plant_sim.plant_ops.CompiledOps`);
* C is generated from that Function, compiled by the system C compiler and cached on disk under the
  SHA-256 of the generated code (:func:`ceco_core.codegen.compile_cached`: a changed code never loads a
  stale object, a corrupt one is rebuilt, concurrent builders do not clash), then loaded with
  ``casadi.external`` and called through a CasADi function buffer (no per-call conversions).

No compiler (or a failed compile): :func:`compiled_step` raises :class:`~ceco_core.codegen.CompileError`;
:class:`ScenarioPlant` then logs one warning and runs the Python evaluation. Equality with the
Python evaluation and the frozen reference plant: tests/test_compiled_plant.py, docs/plant.md
("The compiled fast path").

Pure logic: no rclpy, no message types.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import threading
from array import array

import casadi

from ceco_core.cabin_comfort import ComfortParams, OccupantComfort, evaluate_cabin_comfort
from ceco_core.codegen import Compiled, CompileError, check_compile_settings, compile_cached, generate_functions

from .plant_equations import ENV_NAMES, INPUT_NAMES, STATE_NAMES, Env, Guess, Input, NewtonCycle, PlantEquations, State
from .plant_ops import CompiledOps, SymbolicParams
from .plant_params import PlantParams
from .plant_state import PlantOutputs
from .refrigerant import cycle_tables

__all__ = [
    "PLANT_EVALUATIONS",
    "PLANT_STRUCTURAL",
    "COMFORT_STRUCTURAL",
    "OUTPUT_NAMES",
    "COMFORT_NAMES",
    "PlantEvaluation",
    "StepFunction",
    "build_step_function",
    "CompiledStep",
    "compiled_step",
]

_LOG = logging.getLogger(__name__)

PLANT_EVALUATIONS = ("compiled", "python")
"""How the simulator evaluates its plant step: the compiled fast path (default) or Python floats."""

PLANT_STRUCTURAL = {
    "PlantParams": ("substep_s", "cycle_max_iter", "refrigerant", "superheat_k", "subcool_k"),
}
"""PlantParams fields that shape the compiled code (sub-step count, iteration cap, the refrigerant tables)."""

COMFORT_STRUCTURAL = {
    "ComfortParams": ("smoothing",),
    "OccupantAirParams": ("a_outlet_m2", "k_smooth", "dr_in_jet"),
}
"""ComfortParams parts that shape the compiled code: the PMV's smoothing (widths and Newton steps), the
jet's smooth-cap sharpness, its outlet area (a square root taken in Python) and where the draught is rated."""

OUTPUT_NAMES = tuple(f.name for f in dataclasses.fields(PlantOutputs))
"""The step's report, in :class:`PlantOutputs` field order."""
COMFORT_NAMES = tuple(f.name for f in dataclasses.fields(OccupantComfort))
"""The scored comfort at t_n, in :class:`OccupantComfort` field order."""


@dataclasses.dataclass(frozen=True)
class PlantEvaluation:
    """How the simulator's plant step is evaluated (SimSettings, plant_node parameter ``plant_evaluation``)."""

    evaluation: str = "compiled"
    """``compiled`` (generated C, cached; the Python evaluation with one warning where it cannot be built)
    or ``python`` (the numeric evaluation)."""
    compiler: str | None = None
    """C compiler (a name on PATH or a path); None: $CC, gcc, cc."""
    flags: tuple[str, ...] = ("-O1",)
    """Compiler flags (part of the cache key)."""
    cache_dir: str | None = None
    """Cache of compiled objects; None: $CECO_CACHE_DIR, $XDG_CACHE_HOME/ceco or ~/.cache/ceco."""

    def validate(self) -> PlantEvaluation:
        """Raise ValueError naming the field; return self."""
        if self.evaluation not in PLANT_EVALUATIONS:
            raise ValueError(f"PlantEvaluation.evaluation: must be one of {PLANT_EVALUATIONS}, got {self.evaluation!r}")
        check_compile_settings("PlantEvaluation", self.compiler, self.flags, self.cache_dir)
        return self


@dataclasses.dataclass(frozen=True)
class StepFunction:
    """The traced plant step (:func:`build_step_function`)."""

    function: casadi.Function
    """(x, warm, u, env, meas, theta) -> (x_next, warm_next, out, comfort, ok); ``meas`` = (vent air
    temperature [degC], cabin rh [0..1], fixed scored vapour pressure [Pa] or unused) at t_n."""
    params: SymbolicParams
    """The parameter inputs (``theta``): the recorded paths into ``plant`` / ``comfort``."""
    fixed_pa: bool
    """The PMV is scored with a fixed vapour pressure (``meas[2]``) instead of the cabin's."""


def build_step_function(params: PlantParams, comfort: ComfortParams, plant_dt_s: float, fixed_pa: bool) -> StepFunction:
    """Trace the simulator's plant step into one CasADi Function (the code a compiled object is generated from).

    The comfort at t_n from the state at t_n (= the measurements), the vent air temperature and cabin
    rh measured at t_n and the command; then ``PlantEquations.step`` over ``plant_dt_s`` and its report
    ``PlantEquations.outputs`` with the warm start after the step, exactly as ``ScenarioPlant.step``
    and ``CabinPlant.step`` evaluate them.
    """
    p = params.validate()
    comfort.validate()
    sym = SymbolicParams({**PLANT_STRUCTURAL, **COMFORT_STRUCTURAL})
    pp = sym.proxy(p, "plant")
    cp = sym.proxy(comfort, "comfort")
    tab = cycle_tables(p.refrigerant, float(p.superheat_k), float(p.subcool_k))
    eq = PlantEquations(pp, NewtonCycle(pp, tab), CompiledOps())
    xs = casadi.SX.sym("x", len(STATE_NAMES))
    ws = casadi.SX.sym("warm", len(Guess._fields))
    us = casadi.SX.sym("u", len(INPUT_NAMES))
    es = casadi.SX.sym("env", len(ENV_NAMES))
    ms = casadi.SX.sym("meas", 3)
    x = State(*casadi.vertsplit(xs, 1))
    u = Input(*casadi.vertsplit(us, 1))
    env = Env(*casadi.vertsplit(es, 1))
    c = evaluate_cabin_comfort(
        t_cab_c=x.t_cab_c,
        t_vent_c=ms[0],
        t_int_c=x.t_int_c,
        t_shell_c=x.t_shell_c,
        t_glass_c=x.t_glass_c,
        rh_cab=ms[1],
        mdot_bl_kgps=u.mdot_bl_kgps,
        solar_wm2=env.solar_wm2,
        params=cp,
        # the scored vapour pressure: the fixed one of the comfort override (meas[2]), else the cabin's
        pa_pa=ms[2] if fixed_pa else None,
    )
    x1, acc, g1, ok_step = eq.step(x, u, env, float(plant_dt_s), Guess(*casadi.vertsplit(ws, 1)))
    out, ok_out = eq.outputs(x1, u, env, float(plant_dt_s), acc, g1)
    theta = casadi.vertcat(*sym.symbols)

    def vec(values):
        return casadi.vertcat(*[casadi.SX(float(v)) if isinstance(v, (bool, int, float)) else v for v in values])

    f = casadi.Function(
        "ceco_plant_step",
        [xs, ws, us, es, ms, theta],
        [
            vec(x1),
            vec(g1),
            vec(out[k] for k in OUTPUT_NAMES),
            vec(getattr(c, k) for k in COMFORT_NAMES),
            vec([casadi.logic_and(ok_step, ok_out)]),
        ],
        ["x", "warm", "u", "env", "meas", "theta"],
        ["x_next", "warm_next", "out", "comfort", "ok"],
    )
    return StepFunction(f, sym, fixed_pa)


def _structure(obj, structural, path=()) -> tuple:
    """The leaves of a parameter dataclass that a traced code holds as constants: structural or not floats."""
    out = []
    fixed = structural.get(type(obj).__name__, ())
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if f.name in fixed:
            out.append(((*path, f.name), repr(v)))
        elif dataclasses.is_dataclass(v) and not isinstance(v, type):
            out.extend(_structure(v, structural, (*path, f.name)))
        elif not isinstance(v, float):
            out.append(((*path, f.name), repr(v)))
    return tuple(out)


class CompiledStep:
    """A loaded compiled plant step bound to one parameter set: call :meth:`step` once per plant step.

    Not thread-safe (one function buffer); :func:`compiled_step` hands each caller its own.
    """

    def __init__(self, loaded: casadi.Function, traced: StepFunction, params: PlantParams, comfort: ComfortParams):
        self.function = loaded
        """The loaded compiled Function."""
        self.fixed_pa = traced.fixed_pa
        self._x = array("d", [0.0] * len(STATE_NAMES))
        self._w = array("d", [0.0] * len(Guess._fields))
        self._u = array("d", [0.0] * len(INPUT_NAMES))
        self._e = array("d", [0.0] * len(ENV_NAMES))
        self._m = array("d", [0.0] * 3)  # vent air [degC], cabin rh [-], fixed scored vapour pressure [Pa]
        self._theta = array("d", traced.params.values({"plant": params, "comfort": comfort}))
        self._x1 = array("d", [0.0] * len(STATE_NAMES))
        self._w1 = array("d", [0.0] * len(Guess._fields))
        self._out = array("d", [0.0] * len(OUTPUT_NAMES))
        self._c = array("d", [0.0] * len(COMFORT_NAMES))
        self._ok = array("d", [0.0])
        buf, self._eval = loaded.buffer()
        for i, a in enumerate((self._x, self._w, self._u, self._e, self._m, self._theta)):
            buf.set_arg(i, memoryview(a))  # type: ignore[call-arg]  # size from the view
        for i, a in enumerate((self._x1, self._w1, self._out, self._c, self._ok)):
            buf.set_res(i, memoryview(a))  # type: ignore[call-arg]
        self._buf = buf  # keeps the buffer (and the views into the arrays) alive

    def step(self, x, warm, u, env, t_vent_c: float, rh_cab: float, pa_pa: float):
        """(x_next, warm_next, outputs, comfort, ok) as float lists (:data:`OUTPUT_NAMES`, :data:`COMFORT_NAMES`)."""
        self._x[:] = array("d", x)
        self._w[:] = array("d", warm)
        self._u[:] = array("d", u)
        self._e[:] = array("d", env)
        m = self._m
        m[0], m[1], m[2] = t_vent_c, rh_cab, (pa_pa if self.fixed_pa else 0.0)
        self._eval()
        return self._x1.tolist(), self._w1.tolist(), self._out.tolist(), self._c.tolist(), self._ok[0] == 1.0


_TRACED: dict = {}
_LOADED: dict[str, casadi.Function] = {}
_LOCK = threading.Lock()


def compiled_step(
    params: PlantParams,
    comfort: ComfortParams,
    plant_dt_s: float,
    fixed_pa: bool = False,
    settings: PlantEvaluation | None = None,
) -> tuple[CompiledStep, Compiled | None]:
    """The compiled plant step for these parameters: traced once per process and structure, compiled once per code.

    Returns (the step bound to ``params`` and ``comfort``, the cache lookup of this call or None when
    the process already held it). Raises :class:`~ceco_core.codegen.CompileError` where no compiler
    works or the compile fails.
    """
    s = (settings or PlantEvaluation()).validate()
    key = (
        _structure(params, PLANT_STRUCTURAL),
        _structure(comfort, COMFORT_STRUCTURAL),
        float(plant_dt_s),
        bool(fixed_pa),
        s.compiler,
        s.flags,
        s.cache_dir,
    )
    lookup = None
    with _LOCK:
        if key not in _TRACED:
            traced = build_step_function(params, comfort, plant_dt_s, fixed_pa)
            lookup = _compile(traced, s)
            if lookup.path not in _LOADED:
                _LOADED[lookup.path] = casadi.external(traced.function.name(), lookup.path)
            _TRACED[key] = (traced, lookup.path)
        traced, path = _TRACED[key]
        loaded = _LOADED[path]
    return CompiledStep(loaded, traced, params, comfort), lookup


def _compile(traced: StepFunction, s: PlantEvaluation) -> Compiled:
    """The cached object of a traced step (keyed by its generated C)."""

    def generate(tmp: str) -> str:
        return generate_functions([traced.function], tmp, "ceco_plant")

    return compile_cached("ceco_plant", None, generate, s.flags, s.cache_dir, s.compiler)


def fallback_warning(exc: CompileError) -> None:
    """Log (once per process) that the plant runs its Python evaluation because the compiled one cannot be built."""
    if not _WARNED:
        _WARNED.append(True)
        _LOG.warning("compiled plant unavailable (%s); using the Python evaluation of the plant", exc)


_WARNED: list = []


def finite_state_or_raise(x_next) -> None:
    """RuntimeError naming the first non-finite state (as ``CabinPlant.step``)."""
    for name, v in zip(STATE_NAMES, x_next, strict=True):
        if not math.isfinite(v):
            raise RuntimeError(f"plant state {name} became non-finite")


def warm(cache_dir: str | None = None) -> list[Compiled]:
    """Compile (or find) the objects of the default runs: plant step 1 s, the cabin's or a fixed scored vapour pressure.

    Every bundled scenario and every float override share them (parameters are inputs); ``tools/setup.sh``
    calls this so that the first run, node or test does not compile.
    """
    s = PlantEvaluation(cache_dir=cache_dir)
    out = []
    for fixed_pa in (False, True):
        out.append(_compile(build_step_function(PlantParams(), ComfortParams(), 1.0, fixed_pa), s))
    return out


if __name__ == "__main__":  # python -m ceco_plant_sim.compiled_plant --warm
    import sys

    if sys.argv[1:] != ["--warm"]:
        sys.exit("usage: python -m ceco_plant_sim.compiled_plant --warm")
    try:
        for c in warm():
            print(f"compiled plant: {'built' if c.built else 'cached'} {c.path} in {c.seconds:.1f} s")
    except CompileError as exc:  # the plant runs its Python evaluation (with a warning) then
        print(f"compiled plant: not built ({exc}); the plant will use its Python evaluation", file=sys.stderr)
