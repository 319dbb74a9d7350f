"""The three evaluations of the plant's equations: numeric, exact-symbolic, smooth-symbolic.

The plant's equations (:mod:`ceco_plant_sim.plant_equations`, the refrigerant cycle in
:mod:`ceco_plant_sim.refrigerant`) are written once against an ``ops`` object that supplies every
operation whose meaning depends on the evaluation:

* elementary functions ``exp``, ``sqrt``, ``fabs``, and ``scalar`` (a value of the evaluation's
  type: numerically a Python float, whose arithmetic is the same IEEE arithmetic as numpy's
  float64 scalars, only several times cheaper);
* branches: ``where(c, a, b)`` (both evaluated; also over tuples) and ``cond(c, then, otherwise)``
  (numerically only the branch taken is evaluated);
* logic on conditions: ``logic_and``, ``logic_or``, ``logic_not``;
* kinks and switches of the physics, through a view of one smoothing scale,
  ``ops.scaled(key)`` with ``fmin``, ``fmax``, ``gt``, ``ge``, ``lt``, ``le`` (``key`` is ``speed``
  [rpm], ``duty`` [-], ``err`` [K], ``water`` [kg/kg] or ``door`` [1/s]; the numeric and exact views
  are exact);
* the refrigerant solve's table interpolation (``interp1``, ``interp2``), iterations (``loop``),
  failures (``check``) and repeated pieces (``call``). That code runs numerically and exactly only
  and uses the comparison operators directly (CasADi overloads them).

The evaluations:

* :data:`NUMERIC`: Python floats with the operations the plant used before its equations were
  written once (``math``, ``min``/``max``, real ``if``, loops that stop), in the same order: the
  simulator (:class:`~ceco_plant_sim.plant.CabinPlant`) is bit-identical to it. Where it can, it uses
  C builtins (``operator``, ``min``, ``max``) so that the indirection costs little.
* :class:`ExactOps`: CasADi ``SX`` with exact branches (``if_else``), the table cell by ``floor``
  and its values fetched by index, iterations unrolled to their cap and masked once done (the
  refrigerant Newton solve with its stopping rule and warm start, the power-limit secant). A CasADi
  Function built with it evaluates to the numeric path's values (to rounding: the numeric path takes
  the water saturation pressure from numpy, whose SIMD ``exp`` can differ from libm's in the last
  bit) and is what a compiled fast path is generated from.
* :class:`SmoothOps`: CasADi with the kinks by log-sum-exp and the switches by logistic indicators in
  [0, 1] and blended branches, for gradient-based optimisation (the refrigerant cycle is then a smooth
  table, not the Newton solve). The widths are :class:`SmoothSettings`; the error bounds are in
  docs/plant.md ("Smooth model").
"""

from __future__ import annotations

import dataclasses
import math
import operator
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import casadi

from ceco_core import mathops

__all__ = [
    "NUMERIC",
    "NumericOps",
    "ExactOps",
    "CompiledOps",
    "SymbolicParams",
    "SmoothOps",
    "SmoothSettings",
    "select",
    "PlantStepError",
    "SIMULATION_STOPPED",
    "cycle_failure_message",
]


class PlantStepError(RuntimeError):
    """The plant cannot simulate the step: its refrigerant cycle's solve did not converge.

    The state lies outside the cycle model's tables (docs/scenarios.md, "What the plant can simulate"); the run
    cannot go on: a failed run. Raised by :meth:`NumericOps.check` and by the compiled step on its flag.
    """

    @property
    def run_error(self) -> str:
        """The failed run's reason, in the words of every verb: ``the simulation stopped: <message>``."""
        return SIMULATION_STOPPED + str(self)


SIMULATION_STOPPED = "the simulation stopped: "
"""The start of the reason of a run whose plant could not simulate a step (every verb, plant_node's log)."""


def cycle_failure_message(max_iter: int, where: str) -> str:
    """Why a :class:`PlantStepError`: the cycle solve did not converge in ``max_iter`` iterations (at ``where``)."""
    return f"refrigerant cycle did not converge in {max_iter} iterations ({where})"


class NumericOps:
    """Python floats: ``math`` functions, real branches, loops that stop, failures raised."""

    name = "numeric"
    symbolic = False
    fog_deposition = True
    """The cabin fog's deposition sink is in the water balance (the plant's equations, "cabin fog")."""
    scalar = float
    exp = math.exp
    sqrt = math.sqrt
    fabs = abs
    fmin = min
    fmax = max
    gt = operator.gt
    ge = operator.ge
    lt = operator.lt
    le = operator.le
    logic_and = operator.and_
    logic_or = operator.or_
    logic_not = operator.not_

    def scaled(self, key: str) -> NumericOps:
        """The operations of one smoothing scale: exact here (the numeric evaluation itself)."""
        return self

    @staticmethod
    def where(c, a, b):
        """``a if c else b`` (both already evaluated; also for tuples)."""
        return a if c else b

    @staticmethod
    def cond(c, then: Callable, otherwise: Callable):
        """Evaluate only the branch taken."""
        return then() if c else otherwise()

    @staticmethod
    def interp1(table, x):
        """(y(x), dy/dx) of a 1-D table (uniform grid, linear, linear extrapolation from the end cells)."""
        u = (x - table.x0) * table.inv_dx
        i = int(math.floor(u))
        if i < 0:
            i = 0
        elif i > table.n - 2:
            i = table.n - 2
        f = u - i
        y = table.y
        d = y[i + 1] - y[i]
        return y[i] + f * d, d * table.inv_dx

    @staticmethod
    def interp2(table, x, y):
        """(z(x, y), dz/dx, dz/dy) of a 2-D table (uniform grid, bilinear, linear extrapolation)."""
        u = (x - table.x0) * table.inv_dx
        i = int(math.floor(u))
        if i < 0:
            i = 0
        elif i > table.nx - 2:
            i = table.nx - 2
        v = (y - table.y0) * table.inv_dy
        j = int(math.floor(v))
        if j < 0:
            j = 0
        elif j > table.ny - 2:
            j = table.ny - 2
        f = u - i
        g = v - j
        r0 = table.z[i]
        r1 = table.z[i + 1]
        z00, z01, z10, z11 = r0[j], r0[j + 1], r1[j], r1[j + 1]
        a = z00 + g * (z01 - z00)
        b = z10 + g * (z11 - z10)
        dzdy = ((1.0 - f) * (z01 - z00) + f * (z11 - z10)) * table.inv_dy
        return a + f * (b - a), (b - a) * table.inv_dx, dzdy

    @staticmethod
    def loop(n: int, body: Callable, state, *args):
        """``state = body(state, *args)`` until ``state.done``, at most ``n`` times."""
        k = 0
        while k < n and not state.done:
            state = body(state, *args)
            k += 1
        return state

    @staticmethod
    def check(ok, message: Callable[[], str]):
        """Raise :class:`PlantStepError` (a RuntimeError) with ``message()`` unless ``ok``; return True."""
        if not ok:
            raise PlantStepError(message())
        return True

    @staticmethod
    def call(name: str, fn: Callable, *args):
        """``fn(*args)`` (the symbolic evaluations wrap ``fn`` into a CasADi Function called here)."""
        return fn(*args)


NUMERIC = NumericOps()
"""The numeric evaluation (the simulator)."""


def _flatten(tree) -> list:
    if isinstance(tree, tuple):
        out = []
        for t in tree:
            out.extend(_flatten(t))
        return out
    return [tree]


def _rebuild(template, flat: list, pos: int = 0):
    if isinstance(template, tuple):
        items = []
        for t in template:
            item, pos = _rebuild(t, flat, pos)
            items.append(item)
        if hasattr(template, "_fields"):  # namedtuple
            return type(template)(*items), pos
        return tuple(items), pos
    return flat[pos], pos + 1


def select(if_else: Callable, c, a, b):
    """Elementwise ``if_else(c, a_i, b_i)`` over equal (named)tuple trees ``a``, ``b``."""
    if isinstance(a, tuple):
        items = [select(if_else, c, x, y) for x, y in zip(a, b, strict=True)]
        return type(a)(*items) if hasattr(a, "_fields") else tuple(items)
    if a is b:
        return a
    return if_else(c, a, b)


def _sx(v):
    return casadi.SX(float(v)) if isinstance(v, (bool, int, float)) else v


class _CasadiOps:
    """What the two CasADi evaluations share: elementary functions, logic on 0/1 values, Function calls."""

    symbolic = True
    fog_deposition = True
    exp = staticmethod(casadi.exp)

    @staticmethod
    def scalar(v):
        """A value of this evaluation (a CasADi expression as it is)."""
        return v

    sqrt = staticmethod(casadi.sqrt)
    fabs = staticmethod(casadi.fabs)

    def __init__(self) -> None:
        self._functions: dict[str, tuple[casadi.Function, object]] = {}

    @staticmethod
    def _if_else(c, a, b):
        """How a branch is selected: ``casadi.if_else`` (the smooth evaluation blends instead)."""
        return casadi.if_else(c, a, b)

    def where(self, c, a, b):
        """``a`` where ``c`` else ``b``, elementwise (over tuples too)."""
        return select(self._if_else, c, a, b)

    def cond(self, c, then: Callable, otherwise: Callable):
        """Both branches evaluated, the taken one selected (NaN or inf in the other does not leak)."""
        return select(self._if_else, c, then(), otherwise())

    def call(self, name: str, fn: Callable, *args):
        """``fn(*args)`` through a CasADi Function traced once with SX scalars (cached by ``name``).

        Keeps a repeated piece (the refrigerant solve) one node of the caller's graph. ``fn`` must
        depend on its arguments only (its constants are captured when first traced).
        """
        if name not in self._functions:
            syms = [casadi.SX.sym(f"a{i}") for i in range(len(args))]
            out = fn(*syms)
            self._functions[name] = (
                casadi.Function(name, syms, [_sx(v) for v in _flatten(out)], {"never_inline": True}),
                out,
            )
        f, template = self._functions[name]
        return _rebuild(template, f.call([_sx(a) for a in args]))[0]

    def functions(self) -> dict[str, casadi.Function]:
        """The Functions traced so far (name -> Function)."""
        return {k: v[0] for k, v in self._functions.items()}


class ExactOps(_CasadiOps):
    """CasADi SX with the numeric path's branches exactly (``if_else``), cells by floor, masked loops."""

    name = "exact"
    fmin = staticmethod(casadi.fmin)
    fmax = staticmethod(casadi.fmax)
    gt = operator.gt
    ge = operator.ge
    lt = operator.lt
    le = operator.le
    logic_and = staticmethod(casadi.logic_and)
    logic_or = staticmethod(casadi.logic_or)
    logic_not = staticmethod(casadi.logic_not)

    def __init__(self) -> None:
        super().__init__()
        self._tables: dict[int, casadi.Function] = {}

    def scaled(self, key: str) -> ExactOps:
        """Exact comparisons and kinks whatever the scale."""
        return self

    def _lookup(self, table, values, offsets) -> casadi.Function:
        """A Function k -> values[k + offset] for each offset (the table's values fetched by index)."""
        key = id(table)
        if key not in self._tables:
            v = casadi.MX(casadi.DM(values))
            k = casadi.MX.sym("k")
            self._tables[key] = casadi.Function(
                f"table{len(self._tables)}", [k], [v[k + d] for d in offsets], {"never_inline": True}
            )
        return self._tables[key]

    @staticmethod
    def _floor_clip(u, last: int):
        return casadi.fmin(casadi.fmax(casadi.floor(u), 0.0), float(last))

    def interp1(self, table, x):
        """:meth:`NumericOps.interp1` with the cell by floor and its values fetched by index."""
        u = (x - table.x0) * table.inv_dx
        i = self._floor_clip(u, table.n - 2)
        f = u - i
        y0, y1 = self._lookup(table, table.y, (0, 1)).call([i])
        d = y1 - y0
        return y0 + f * d, d * table.inv_dx

    def interp2(self, table, x, y):
        """:meth:`NumericOps.interp2` with the cell by floor and its corners fetched by the flat index i ny + j."""
        u = (x - table.x0) * table.inv_dx
        i = self._floor_clip(u, table.nx - 2)
        v = (y - table.y0) * table.inv_dy
        j = self._floor_clip(v, table.ny - 2)
        f = u - i
        g = v - j
        ny = table.ny
        flat = [z for row in table.z for z in row]
        z00, z01, z10, z11 = self._lookup(table, flat, (0, 1, ny, ny + 1)).call([i * ny + j])
        a = z00 + g * (z01 - z00)
        b = z10 + g * (z11 - z10)
        dzdy = ((1.0 - f) * (z01 - z00) + f * (z11 - z10)) * table.inv_dy
        return a + f * (b - a), (b - a) * table.inv_dx, dzdy

    @staticmethod
    def loop(n: int, body: Callable, state, *args):
        """``n`` masked applications of ``body``: a state with ``done`` passes through unchanged."""
        for _ in range(n):
            state = select(casadi.if_else, state.done, state, body(state, *args))
        return state

    @staticmethod
    def check(ok, message: Callable[[], str]):
        """The flag itself (the caller reports it as an output)."""
        return ok


@dataclasses.dataclass(frozen=True)
class SmoothSettings:
    """Widths of the smoothed kinks and switches of the plant (errors: docs/plant.md, "Smooth model")."""

    k_speed_per_rpm: float = 0.05
    """Log-sum-exp sharpness of the compressor speed limits (min/max speed, power limit) [1/rpm];
    error <= ln 2 / k = 13.9 rpm."""
    k_duty: float = 200.0
    """Log-sum-exp sharpness of the duty-cycle clip of N_cmd / N_min into [0, 1] [-]; error <= ln 2 / k = 0.0035."""
    k_water_per_kgkg: float = 2.0e5
    """Log-sum-exp (softplus) sharpness of the condensation switch max(0, W_mix - W_s,wall) [kg/kg]^-1;
    error <= ln 2 / k = 3.5e-6 kg/kg."""
    w_speed_rpm: float = 10.0
    """Logistic width of the speed comparisons of the compressor's anti-windup [rpm];
    error <= exp(-|dN| / w) away from the switch."""
    w_err_k: float = 0.02
    """Logistic width of the sign of the evaporator error in the anti-windup [K]; error <= exp(-|e| / w)."""
    k_door_s: float = 500.0
    """Log-sum-exp sharpness of the door actuator's rate limit [1/(1/s)] = [s]; error <= ln 2 / k = 0.0014 /s
    of door speed (the limit is 0.2 /s)."""

    def validate(self) -> SmoothSettings:
        """Raise ValueError naming the first field that is not a finite number > 0; return self."""
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0.0:
                raise ValueError(f"SmoothSettings.{f.name}: must be a finite number > 0, got {v!r}")
        return self


class _SmoothScale:
    """Kinks (log-sum-exp, sharpness k) and comparisons (logistic, width w) of one smoothing scale."""

    def __init__(self, key: str, k: float | None, w: float | None) -> None:
        self.key, self.k, self.w = key, k, w

    def _need(self, value, what):
        if value is None:
            raise ValueError(f"smoothing scale {self.key!r} has no {what}")
        return value

    def fmin(self, a, b):
        """Smooth min (log-sum-exp, error <= ln 2 / k)."""
        return mathops.smooth_min(a, b, self._need(self.k, "sharpness"))

    def fmax(self, a, b):
        """Smooth max (log-sum-exp, error <= ln 2 / k)."""
        return mathops.smooth_max(a, b, self._need(self.k, "sharpness"))

    def gt(self, a, b):
        """Soft indicator of a > b (logistic of width w)."""
        return mathops.sigmoid(a - b, self._need(self.w, "width"))

    ge = gt

    def lt(self, a, b):
        """Soft indicator of a < b (logistic of width w)."""
        return mathops.sigmoid(b - a, self._need(self.w, "width"))

    le = lt


class SmoothOps(_CasadiOps):
    """CasADi with smoothed kinks (log-sum-exp) and switches (logistic indicators in [0, 1], blends)."""

    name = "smooth"
    fog_deposition = False
    """The whole-drive optimum's model leaves the cabin fog's deposition out: its drives are hot and never saturate
    the cabin, and with the sink IPOPT's trial states reached it and the door optimum stopped at its iteration
    limit (docs/plant.md, "cabin fog")."""

    def __init__(self, settings: SmoothSettings | None = None) -> None:
        super().__init__()
        s = (settings or SmoothSettings()).validate()
        self.settings = s
        self._scales = {
            "speed": _SmoothScale("speed", s.k_speed_per_rpm, s.w_speed_rpm),
            "duty": _SmoothScale("duty", s.k_duty, None),
            "water": _SmoothScale("water", s.k_water_per_kgkg, None),
            "err": _SmoothScale("err", None, s.w_err_k),
            "door": _SmoothScale("door", s.k_door_s, None),
        }

    def scaled(self, key: str) -> _SmoothScale:
        """The smoothed kinks and comparisons of scale ``key`` (``speed``, ``duty``, ``water``, ``err``, ``door``)."""
        return self._scales[key]

    @staticmethod
    def _if_else(c, a, b):
        """The blend c a + (1 - c) b of a soft indicator c in [0, 1]."""
        return c * a + (1.0 - c) * b

    @staticmethod
    def logic_and(a, b):
        """A b of soft indicators."""
        return a * b

    @staticmethod
    def logic_or(a, b):
        """A + b - a b of soft indicators."""
        return a + b - a * b

    @staticmethod
    def logic_not(a):
        """1 - a of a soft indicator."""
        return 1.0 - a


def _fresh_inputs(tree, syms: list, values: list):
    """``tree`` with every CasADi leaf a fresh scalar symbol (appended to ``syms``, its value to ``values``).

    Walks tuples, named tuples and dataclass instances; other leaves (floats, tables, ops) stay as they are.
    """
    if isinstance(tree, casadi.SX):
        s = casadi.SX.sym(f"a{len(syms)}")
        syms.append(s)
        values.append(tree)
        return s
    if isinstance(tree, tuple):
        items = [_fresh_inputs(t, syms, values) for t in tree]
        return type(tree)(*items) if hasattr(tree, "_fields") else tuple(items)
    if dataclasses.is_dataclass(tree) and not isinstance(tree, type):
        changes = {f.name: _fresh_inputs(getattr(tree, f.name), syms, values) for f in dataclasses.fields(tree)}
        return dataclasses.replace(tree, **changes)
    return tree


def _closed_over(fn: Callable) -> list:
    """The CasADi values a function captured from its enclosing scopes (must be primitive symbols)."""
    out = []
    for cell in getattr(fn, "__closure__", None) or ():
        try:
            v = cell.cell_contents
        except ValueError:  # an empty cell
            continue
        if isinstance(v, casadi.SX):
            out.append(v)
    return out


class CompiledOps(ExactOps):
    """:class:`ExactOps` shaped for generated C: iterations that stop, pieces that take their free symbols as inputs.

    * ``loop``: the body is traced once into a Function (state, inputs) -> state; the ``n`` iterations
      are conditional calls (``Function.if_else``) that skip the body once ``state.done``: the C code
      runs the iterations the numeric evaluation runs (2-4 per refrigerant solve instead of 30).
      The body's CasADi arguments become explicit inputs; what it captures from enclosing scopes must be
      primitive symbols (the parameters, :class:`SymbolicParams`), which are passed through.
    * ``call``: as :class:`ExactOps`, with the free symbols of the traced piece (the parameters) added as
      inputs.

    Values equal the exact evaluation's: a skipped iteration is the masked one.
    """

    name = "compiled"

    def __init__(self) -> None:
        super().__init__()
        self._loops: dict = {}

    def call(self, name: str, fn: Callable, *args):
        """``fn(*args)`` through a Function traced once (cached by ``name``); its free symbols become inputs."""
        if name not in self._functions:
            syms = [casadi.SX.sym(f"a{i}") for i in range(len(args))]
            out = fn(*syms)
            flat = [_sx(v) for v in _flatten(out)]
            free = casadi.Function(name, syms, flat, {"allow_free": True}).free_sx()
            f = casadi.Function(name, syms + free, flat, {"never_inline": True})
            self._functions[name] = (f, (out, free))
        f, stored = self._functions[name]
        tree: Any = stored
        return _rebuild(tree[0], f.call([_sx(a) for a in args] + tree[1]))[0]  # (output tree, free symbols)

    def loop(self, n: int, body: Callable, state, *args):  # type: ignore[override]  # needs its cache
        """At most ``n`` applications of ``body`` as conditional calls: an iteration with ``state.done`` is skipped."""
        for v in _closed_over(body):
            if not v.is_symbolic():
                raise ValueError(f"{body.__qualname__}: captures a computed CasADi value; pass it as an argument")
        arg_syms: list = []
        arg_vals: list = []
        args_in = _fresh_inputs(args, arg_syms, arg_vals)
        flat_state = [_sx(v) for v in _flatten(state)]
        constants = tuple(id(v) for v in _flatten(args_in) if not isinstance(v, casadi.SX))
        closure = tuple(id(c.cell_contents) for c in (getattr(body, "__closure__", None) or ()))
        key = (body.__code__, n, len(flat_state), len(arg_syms), constants, closure)
        if key not in self._loops:
            s_syms = [casadi.SX.sym(f"s{i}") for i in range(len(flat_state))]
            s_tree = _rebuild(state, s_syms)[0]
            out = [_sx(v) for v in _flatten(body(s_tree, *args_in))]
            if len(out) != len(s_syms):
                raise ValueError(f"{body.__qualname__}: returns {len(out)} values for a state of {len(s_syms)}")
            free = casadi.Function("body", s_syms + arg_syms, out, {"allow_free": True}).free_sx()
            done_at = _flatten(_rebuild(state, list(range(len(s_syms))))[0]._replace(done=-1)).index(-1)
            tag = f"{body.__name__.strip('_')}_{len(self._loops)}"
            s_in, a_in = casadi.vertcat(*s_syms), casadi.vertcat(*arg_syms, *free)
            f_body = casadi.Function(f"{tag}_body", [s_in, a_in], [casadi.vertcat(*out)])
            f_skip = casadi.Function(f"{tag}_skip", [s_in, a_in], [s_in])
            f_step = casadi.Function.if_else(f"{tag}_step", f_skip, f_body)
            s_mx = casadi.MX.sym("s", len(s_syms))
            a_mx = casadi.MX.sym("a", a_in.numel())
            st = s_mx
            for _ in range(n):
                st = f_step(st[done_at], st, a_mx)
            self._loops[key] = (casadi.Function(f"{tag}_loop", [s_mx, a_mx], [st], {"never_inline": True}), free)
        f, free = self._loops[key]
        res = f(casadi.vertcat(*flat_state), casadi.vertcat(*arg_vals, *free))
        return _rebuild(state, casadi.vertsplit(res, 1))[0]


class SymbolicParams:
    """Parameters as inputs of a traced Function: every float a traced code reads from a parameter object is a symbol.

    ``proxy(obj)`` wraps a (frozen) dataclass: reading a float attribute (a field or a property, e.g.
    ``SolarParams.w_rad_per_irradiance``) returns a scalar symbol, the same one for the same path;
    nested dataclasses are proxied too; names in ``structural`` (per class name) and non-float values
    (ints, bools, strings) are returned as they are (they shape the code: sub-step length, iteration
    counts, table choice, smoothing widths); ``validate()`` returns the proxy (the real object is
    validated by its owner). :meth:`values` reads the recorded paths from real objects: the numeric
    parameter vector of :attr:`symbols`.
    """

    def __init__(self, structural: Mapping[str, Iterable[str]] | None = None) -> None:
        self.structural = {k: frozenset(v) for k, v in (structural or {}).items()}
        self.paths: list[tuple[str, ...]] = []
        """Recorded attribute paths, (root, name, ...), in symbol order."""
        self.symbols: list[casadi.SX] = []
        """The symbols, in the order of :attr:`paths`."""
        self._by_path: dict[tuple[str, ...], casadi.SX] = {}

    def proxy(self, obj, root: str):
        """A stand-in for ``obj`` whose float attributes are symbols (paths start with ``root``)."""
        return _ParamProxy(self, obj, (root,))

    def _symbol(self, path: tuple[str, ...]) -> casadi.SX:
        if path not in self._by_path:
            s = casadi.SX.sym(".".join(path))
            self._by_path[path] = s
            self.paths.append(path)
            self.symbols.append(s)
        return self._by_path[path]

    def values(self, roots: Mapping[str, object]) -> list[float]:
        """The numeric values of :attr:`symbols` read from the real objects ``{root: obj}``."""
        out = []
        for path in self.paths:
            v: Any = roots[path[0]]
            for name in path[1:]:
                v = getattr(v, name)
            out.append(float(v))
        return out


class _ParamProxy:
    __slots__ = ("_owner", "_obj", "_path")

    def __init__(self, owner: SymbolicParams, obj, path: tuple[str, ...]) -> None:
        object.__setattr__(self, "_owner", owner)
        object.__setattr__(self, "_obj", obj)
        object.__setattr__(self, "_path", path)

    def __getattr__(self, name: str):
        if name == "validate":
            return lambda: self
        v = getattr(self._obj, name)
        if name in self._owner.structural.get(type(self._obj).__name__, ()):
            return v
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            return _ParamProxy(self._owner, v, (*self._path, name))
        if isinstance(v, float) or (
            isinstance(v, int) and not isinstance(v, bool) and _declared_float(self._obj, name)
        ):
            return self._owner._symbol((*self._path, name))
        return v

    def __setattr__(self, name, value):
        raise AttributeError(f"{type(self._obj).__name__} parameters are read-only")


def _declared_float(obj, name: str) -> bool:
    for f in dataclasses.fields(obj):
        if f.name == name:
            return f.type in (float, "float")
    return False
