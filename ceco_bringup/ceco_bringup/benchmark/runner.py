"""Cases -> cells -> KPIs -> the results document (``ceco-benchmark/2``).

Every run of the benchmark is a cell of the sweep machinery
(:mod:`ceco_bringup.sweep.backends`: the resumable ``cells.jsonl`` log, the local
process pool or Ray): its id is the SHA-256 of its spec (the resolved scenario,
the controller and its settings, the preview quality and seed, the plant/comfort
overrides of a sensitivity run, the benchmark version and the simulator's code
fingerprint), so a rerun of the same command runs nothing and a changed
simulator reruns everything. Each cell runs ``closed_loop.simulate`` and scores
the run with ``ceco_core.kpis.compute_kpis`` in the worker; the driver then
builds the fronts and the matched-comfort results (:mod:`.front`).

Pure Python (no ROS import; the DDS path for external controllers is :mod:`.external`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from importlib import resources
from pathlib import Path

from ceco_bringup.sweep.cells import Cell, cell_id
from ceco_core import contracts, yamlio
from ceco_core.run_status import STATUS_FAILED, ControlCheck, check_control

from . import front as fr
from .cases import Case
from .schema import (
    BENCHMARK_VERSION,
    DOOR_CO2_HOLD,
    DOOR_FAMILY_BASES,
    DOOR_VARIANTS,
    FAMILIES,
    SEED_INVARIANT_KINDS,
    door_family,
    oracle_member,
    oracle_point_kpis,
)

__all__ = [
    'door_overrides',
    'SETPOINTS_C',
    'QUICK_SETPOINTS_C',
    'FRONT_AXIS',
    'ENERGY_AXIS',
    'SECONDARY_AXES',
    'STRATEGY_NAMES',
    'STRATEGY_VARIANTS',
    'DOOR_CASE_STRATEGIES',
    'PERSISTENCE_SUFFIX',
    'PERSISTENCE_TWINS',
    'SETPOINTS_PMV',
    'QUICK_SETPOINTS_PMV',
    'BASELINES_SCHEMA',
    'FamilySpec',
    'BaselineConstants',
    'load_baselines',
    'new_row',
    'external_identity',
    'mark_failed',
    'Sensitivity',
    'load_sensitivity',
    'ControllerSpec',
    'controllers',
    'case_controllers',
    'load_door_tuning',
    'DOOR_TUNED_KINDS',
    'case_cells',
    'run_benchmark_cell',
    'assemble_case',
]

SETPOINTS_C = tuple(22.0 + 0.5 * i for i in range(15))
"""Set-points of the temperature families [degC]: 22.0 ... 29.0 in 0.5 K steps (docs/benchmark.md, "Baselines")."""

QUICK_SETPOINTS_C = (24.0, 25.0, 26.0)
"""The temperature families of ``--quick`` [degC]."""

SETPOINTS_PMV = tuple(round(-0.3 + 0.1 * i, 10) for i in range(9))
"""Set-points of the comfort-feedback (PMV) families [-]: -0.3 ... +0.5 in steps of 0.1."""

QUICK_SETPOINTS_PMV = (0.0, 0.2, 0.4)
"""The PMV families of ``--quick`` [-]."""

FRONT_AXIS = 'discomfort_pmvh'
"""KPI of the front's discomfort axis."""

ENERGY_AXIS = 'energy_kwh'
"""KPI of the front's energy axis."""

SECONDARY_AXES = ('i_pmv_clipped', 'discomfort_band_pmvh')
"""Other discomfort KPIs the matched comfort is also computed on (plain front; shown in the report)."""

STRATEGY_NAMES = ('ceco', 'ceco-e', 'ceco-c', 'ceco-ioch', 'ceco-pmv')
"""The NMPC strategies scored by the benchmark (defaults, ``ceco_controller/config/controller.yaml``)."""

PERSISTENCE_SUFFIX = '-persistence'
"""Name suffix of the persistence twin of a strategy: the same strategy with every preview replaced by
persistence (the value measured at the issue time held over the horizon; preview quality ``persistence``)."""

PERSISTENCE_TWINS = ('ceco-pmv',)
"""The strategies run a second time with persistence previews (``ceco-pmv-persistence``): what the previews
are worth to them."""

STRATEGY_VARIANTS = contracts.STRATEGY_VARIANTS
"""The named variants of a strategy the benchmark scores on request (issue 21: ``ceco-pmv-aq``, ceco-pmv with the
CO2-holding door beside its NLP; ``ceco-pmv-door``, ceco-pmv with the door a third input of its NLP;
docs/controller.md 4.8, 4.9), the same names as mpc_node's ``strategy``: ``{name: (strategy, ((field, value),
...))}`` (:data:`ceco_core.contracts.STRATEGY_VARIANTS`)."""

DOOR_CASE_STRATEGIES = {'ceco-pmv': 'ceco-pmv-aq'}
"""On a case whose baselines drive the door (``baseline_door``), each scored strategy here brings its door variant
(:data:`STRATEGY_VARIANTS`) along, unless it is asked for already: where the baselines may move the door, a
strategy that may is scored too (:func:`case_controllers`)."""

SEED_INVARIANT = SEED_INVARIANT_KINDS
SCORED_KINDS = ('strategy', 'compensated', 'compensated-allowance', 'external')
SENSITIVITY_KINDS = ('baseline', 'baseline-allowance', *SCORED_KINDS)
"""What the tornado reruns at each end of a parameter: the production-gains families (the tornado shows the
saving against the production PI, as before issue 20) and the scored controllers; the tuned families are
not rerun (their cost would triple the tornado's)."""


BASELINES_SCHEMA = 'ceco-benchmark-baselines/2'
"""Value of the baselines file's ``schema`` key (written by :mod:`.tuning`)."""


@dataclasses.dataclass(frozen=True)
class FamilySpec:
    """A baseline family: one law (AccSettings overrides) at a range of set-points."""

    family: str
    """Its name in results.json's ``fronts`` (``plain``, ``tuned``, ``pmv-allowance``, ...; :data:`schema.FAMILIES`)."""
    overrides: Mapping
    """AccSettings fields common to the members (feedback, gains, allowance)."""
    measurements: str = 'full'
    """What the law reads (``closed_loop.SimSettings.measurements``): 'full', or 'vehicle' (the comfort-feedback
    families: the surfaces of the PMV estimated from the sensors a production car has)."""

    @property
    def kind(self) -> str:
        """The members' ``kind`` (and the prefix of their names)."""
        return FAMILIES[self.family]

    @property
    def feedback(self) -> str:
        """'cabin_temperature' or 'pmv'."""
        return str(self.overrides.get('feedback', 'cabin_temperature'))

    @property
    def setpoint_field(self) -> str:
        """The AccSettings field the family sweeps: ``setpoint_c`` or ``setpoint_pmv``."""
        return 'setpoint_pmv' if self.feedback == 'pmv' else 'setpoint_c'

    def member_name(self, setpoint: float) -> str:
        """``baseline-tuned@25.0`` [degC] or ``baseline-pmv@+0.10`` [PMV]."""
        return f'{self.kind}@{setpoint:+.2f}' if self.feedback == 'pmv' else f'{self.kind}@{setpoint:.1f}'

    def member_overrides(self, setpoint: float) -> tuple:
        """((field, value), ...) of the member at ``setpoint``, sorted."""
        return tuple(sorted({**dict(self.overrides), self.setpoint_field: float(setpoint)}.items()))


@dataclasses.dataclass(frozen=True)
class BaselineConstants:
    """The frozen constants of the baseline variants (``data/benchmark/baselines.yaml``)."""

    allowance_k_per_pmv: float
    """Set-point rise per PMV of relaxation of the upper bound [K/PMV] (AccSettings.allowance_k_per_pmv)."""
    compensation: Mapping
    """AccSettings overrides of the compensated law (set-point, sun/ambient gains, filter)."""
    tuned_on: str = ''
    """The case the constants were tuned on."""
    sha: str = ''
    """SHA-256 (16 hex digits) of the file."""
    families: Mapping = dataclasses.field(default_factory=dict)
    """``{family: (AccSettings overrides, measurements)}`` of the tuned families (tuned, tuned-allowance, pmv,
    pmv-allowance)."""

    def family_specs(self) -> list[FamilySpec]:
        """Every family of the benchmark: the production-gains ones, then the tuned ones (schema.FAMILIES order)."""
        base = {
            'plain': ({}, 'full'),
            'allowance': ({'allowance_k_per_pmv': float(self.allowance_k_per_pmv)}, 'full'),
            **{k: (dict(v[0]), str(v[1])) for k, v in self.families.items()},
        }
        return [FamilySpec(f, *base[f]) for f in FAMILIES if f in base]

    def door_family_specs(self) -> list[FamilySpec]:
        """The door families (issue 21).

        Each of :data:`schema.DOOR_FAMILY_BASES` with its tuned gains and each door of :data:`schema.DOOR_VARIANTS`:
        held at a share (``door_mode: fixed``, no fog or CO2 override), or the CO2-holding door of ``ceco-pmv-aq``
        (``door_mode: co2_hold``, with its fog, sensor-fault and economiser overrides).
        """
        out = []
        for b in DOOR_FAMILY_BASES:
            overrides, measurements = self.families[b]
            for v in DOOR_VARIANTS:
                out.append(FamilySpec(door_family(b, v), {**dict(overrides), **door_overrides(v)}, str(measurements)))
        return out


def door_overrides(variant: str) -> dict:
    """The RecircSettings fields of a door variant (:data:`schema.DOOR_VARIANTS`).

    Held at a share (``door_mode: fixed``, no fog or CO2 override) or the CO2-holding door of ``ceco-pmv-aq``
    (``door_mode: co2_hold``); the door families and the verdict's door laws (``ceco_bringup.verdict``) take them.
    """
    if variant == DOOR_CO2_HOLD:
        return {'door_mode': 'co2_hold'}
    return {'door_mode': 'fixed', 'door_fixed_share': int(variant) / 100.0}


TUNED_FAMILIES = ('tuned', 'tuned-allowance', 'pmv', 'pmv-allowance')
"""The families the tuning module writes (their gains are chosen by it)."""


def _frozen_file(name: str, path: str | Path | None, schema: str, what: str, module: str) -> tuple[str, Mapping]:
    """(text, mapping) of a frozen benchmark file: ``path`` or the bundled ``data/benchmark/<name>``.

    ValueError unless its ``schema`` is ``schema`` (``what``: the message's subject; ``module``: the rule that
    writes it).
    """
    if path is None:
        text = resources.files('ceco_bringup').joinpath('data', 'benchmark', name).read_text('utf-8')
    else:
        text = Path(path).read_text(encoding='utf-8')
    d = yamlio.safe_load(text)
    if not isinstance(d, Mapping) or d.get('schema') != schema:
        raise ValueError(f'{what}: not a {schema} file (rerun python -m {module})')
    return text, d


def load_baselines(path: str | Path | None = None) -> BaselineConstants:
    """Read the frozen baseline constants (default: the bundled file); ValueError naming what is wrong."""
    import hashlib

    text, d = _frozen_file('baselines.yaml', path, BASELINES_SCHEMA, 'baselines', 'ceco_bringup.benchmark.tuning')
    from ceco_core.acc_law import AccSettings

    comp = dict(d['compensation'])
    AccSettings(**comp, allowance_k_per_pmv=float(d['allowance_k_per_pmv'])).validate()
    fams = {}
    for name in TUNED_FAMILIES:
        entry = (d.get('families') or {}).get(name)
        if not isinstance(entry, Mapping) or not isinstance(entry.get('settings'), Mapping):
            raise ValueError(f'baselines: families.{name}.settings missing')
        settings = dict(entry['settings'])
        try:
            AccSettings(**settings).validate()
        except (TypeError, ValueError) as exc:
            raise ValueError(f'baselines: families.{name}.settings: {exc}') from exc
        measurements = str(entry.get('measurements', 'full'))
        if measurements not in ('full', 'vehicle'):
            raise ValueError(f'baselines: families.{name}.measurements: full or vehicle, got {measurements!r}')
        fams[name] = (settings, measurements)
    return BaselineConstants(
        allowance_k_per_pmv=float(d['allowance_k_per_pmv']),
        compensation=comp,
        tuned_on=str(d.get('tuned_on', '')),
        sha=hashlib.sha256(text.encode('utf-8')).hexdigest()[:16],
        families=fams,
    )


@dataclasses.dataclass(frozen=True)
class Sensitivity:
    """One parameter of the tornado: plant or comfort overrides at its two ends."""

    parameter: str
    """Name shown, e.g. ``comfort.a2``."""
    target: str
    """'plant' (PlantParams) or 'comfort' (ComfortParams of the scored PMV)."""
    nominal: Mapping
    """Fields and their default values (checked against the code)."""
    low: Mapping
    """Fields at the low end."""
    high: Mapping
    """Fields at the high end."""
    source: str = ''
    """Where the range comes from."""


def _default_value(target: str, name: str):
    """The code's default of a sensitivity field: PlantParams / ComfortParams (dotted parts), or pa_pa."""
    from ceco_core.cabin_comfort import ComfortParams
    from ceco_plant_sim.plant_params import PlantParams
    from ceco_plant_sim.scenario_plant import SCORED_PA_OVERRIDE

    if target == 'comfort' and name == SCORED_PA_OVERRIDE:
        return None  # default: the plant's moisture balance, no fixed value
    obj = ComfortParams() if target == 'comfort' else PlantParams()
    for part in name.split('.'):
        obj = getattr(obj, part)
    return obj


def load_sensitivity(path: str | Path | None = None) -> tuple[str, list[Sensitivity]]:
    """The tornado's case and parameters.

    Field names are PlantParams fields (target ``plant``) or ComfortParams fields with nested parts
    by dotted name, e.g. ``air.jet_body_fraction`` (target ``comfort``), or ``pa_pa`` (a fixed scored
    vapour pressure; its nominal is ``null``: the plant's moisture balance). ValueError naming the
    parameter and the field when a field is unknown, an end is not usable
    (``ceco_plant_sim.scenario_plant.check_overrides``), the nominal fields differ from the ends'
    fields, or a nominal value is not the code's default (the table must follow the code).
    """
    if path is None:
        text = resources.files('ceco_bringup').joinpath('data', 'benchmark', 'sensitivity.yaml').read_text('utf-8')
    else:
        text = Path(path).read_text(encoding='utf-8')
    d = yamlio.safe_load(text)
    from ceco_plant_sim.scenario_plant import check_overrides

    if not isinstance(d, Mapping) or d.get('schema') != 'ceco-benchmark-sensitivity/1':
        raise ValueError('sensitivity: not a ceco-benchmark-sensitivity/1 file')
    out = []
    for i, p in enumerate(d['parameters']):
        where = f"sensitivity.parameters[{i}] ({p.get('parameter')!r})"
        if p.get('target') not in ('plant', 'comfort'):
            raise ValueError(f"{where}.target: must be plant or comfort, got {p.get('target')!r}")
        for end in ('nominal', 'low', 'high'):
            if not isinstance(p.get(end), Mapping) or not p[end]:
                raise ValueError(f'{where}.{end}: must be a non-empty mapping of fields to values')
        s = Sensitivity(
            parameter=p['parameter'],
            target=p['target'],
            nominal=dict(p['nominal']),
            low=dict(p['low']),
            high=dict(p['high']),
            source=' '.join(str(p.get('source', '')).split()),
        )
        if not set(s.low) == set(s.high) == set(s.nominal):
            raise ValueError(f'{where}: nominal, low and high must set the same fields')
        for end in ('low', 'high'):
            kw = {'plant_overrides': getattr(s, end)} if s.target == 'plant' else {'comfort_overrides': getattr(s, end)}
            try:
                check_overrides(**kw)
            except ValueError as exc:
                raise ValueError(f'{where}.{end}: {exc}') from exc
        for k, v in s.nominal.items():
            try:
                default = _default_value(s.target, k)
            except AttributeError as exc:
                raise ValueError(f'{where}.nominal: no field {k!r} ({exc})') from exc
            same = (v is None and default is None) or (
                v is not None and default is not None and math.isclose(float(default), float(v), rel_tol=1e-12)
            )
            if not same:
                raise ValueError(
                    f"{where}.nominal: {k} = {v} differs from the code's default {default}: "
                    'update data/benchmark/sensitivity.yaml'
                )
        if s.low == s.high:
            raise ValueError(f'{where}: low and high are the same')
        out.append(s)
    return str(d['case']), out


@dataclasses.dataclass(frozen=True)
class ControllerSpec:
    """A controller of the benchmark."""

    name: str
    """Its name in results.json (``baseline@25.0``, ``baseline-pmv@+0.10``, ``ceco-c``, ...)."""
    kind: str
    """strategy | a family's kind (schema.FAMILIES) | compensated | compensated-allowance | external."""
    strategy: str
    """The simulator's strategy (``baseline`` for every baseline variant)."""
    overrides: tuple = ()
    """((field, value), ...) of the strategy's settings (AccSettings for the baselines)."""
    setpoint_c: float | None = None
    """Nominal cabin set-point of a temperature baseline [degC]."""
    setpoint_pmv: float | None = None
    """Nominal PMV set-point of a comfort-feedback baseline [-]."""
    measurements: str = 'full'
    """What the controller reads (``SimSettings.measurements``)."""
    preview: str | None = None
    """Preview quality of its runs (None: the case's forecast uncertainty; ``persistence`` for a twin)."""
    command: tuple[str, ...] = ()
    """external: the controller's command line (argv, ``--controller-cmd`` split as a shell would)."""
    cwd: str = ''
    """external: the directory the command runs in (a relative path in the command is relative to it)."""

    @property
    def seeded(self) -> bool:
        """True when the controller sees previews (one run per seed); baselines are seed-invariant."""
        return self.kind not in SEED_INVARIANT


def family_members(
    fam: FamilySpec, setpoints_c: Sequence[float] = SETPOINTS_C, setpoints_pmv: Sequence[float] = SETPOINTS_PMV
) -> list[ControllerSpec]:
    """The members of a family at the set-points of its controlled variable."""
    out = []
    for sp in setpoints_pmv if fam.feedback == 'pmv' else setpoints_c:
        sp = float(sp)
        out.append(
            ControllerSpec(
                fam.member_name(sp),
                fam.kind,
                'baseline',
                fam.member_overrides(sp),
                None if fam.feedback == 'pmv' else sp,
                sp if fam.feedback == 'pmv' else None,
                fam.measurements,
            )
        )
    return out


def controllers(
    baselines: BaselineConstants,
    setpoints_c: Sequence[float] = SETPOINTS_C,
    strategies: Sequence[str] = STRATEGY_NAMES,
    setpoints_pmv: Sequence[float] = SETPOINTS_PMV,
) -> list[ControllerSpec]:
    """The benchmark's controllers: every baseline family, both compensated laws, the strategies.

    The fixed-door families are added per case (:func:`case_controllers`).
    """
    out = []
    for fam in baselines.family_specs():
        out += family_members(fam, setpoints_c, setpoints_pmv)
    k = float(baselines.allowance_k_per_pmv)
    comp = tuple(sorted((str(a), float(b)) for a, b in baselines.compensation.items()))
    sp_c = float(dict(comp).get('setpoint_c', 26.0))
    out.append(ControllerSpec('baseline-compensated', 'compensated', 'baseline', comp, sp_c))
    out.append(
        ControllerSpec(
            'baseline-compensated-allowance',
            'compensated-allowance',
            'baseline',
            tuple(sorted(comp + (('allowance_k_per_pmv', k),))),
            sp_c,
        )
    )
    out += [ControllerSpec(s, 'strategy', *STRATEGY_VARIANTS.get(s, (s, ()))) for s in strategies]
    out += [
        ControllerSpec(s + PERSISTENCE_SUFFIX, 'strategy', s, preview='persistence')
        for s in strategies
        if s in PERSISTENCE_TWINS
    ]
    return out


DOOR_TUNING_SCHEMA = 'ceco-benchmark-door-tuning/1'
"""Value of the door tuning file's ``schema`` key (written by :mod:`.door_tuning`)."""

DOOR_TUNED_KINDS = {
    'baseline-tuned': 'tuned',
    'baseline-tuned-allowance': 'tuned',
    'baseline-pmv': 'pmv',
    'baseline-pmv-allowance': 'pmv',
}
"""Kinds whose production door logic takes the values tuned with their law (``door_tuning.yaml``: the law)."""


def load_door_tuning(path: str | Path | None = None) -> dict:
    """``{law: {door field: value}}`` of the frozen door tuning (default: the bundled file).

    ValueError naming what is wrong.
    """
    from ceco_core.recirc_law import RecircSettings

    _, d = _frozen_file(
        'door_tuning.yaml', path, DOOR_TUNING_SCHEMA, 'door tuning', 'ceco_bringup.benchmark.door_tuning'
    )
    out = {}
    for law in sorted(set(DOOR_TUNED_KINDS.values())):
        settings = ((d.get('laws') or {}).get(law) or {}).get('settings')
        if not isinstance(settings, Mapping) or not all(str(k).startswith('door_') for k in settings):
            raise ValueError(f'door tuning: laws.{law}.settings must be a mapping of door_* fields')
        try:
            RecircSettings(**settings).validate()
        except (TypeError, ValueError) as exc:
            raise ValueError(f'door tuning: laws.{law}.settings: {exc}') from exc
        out[law] = {str(k): float(v) for k, v in settings.items()}
    return out


def case_controllers(
    case: Case,
    specs: Sequence[ControllerSpec],
    door_specs: Sequence[ControllerSpec],
    door_tuning: Mapping | None = None,
) -> list:
    """The controllers of ``case``: ``specs``, plus the door family members ``door_specs``.

    Only when the case's baselines drive the door (``baseline_door`` set: the air-quality cases); then the
    door members come after the other families, the strategies of :data:`DOOR_CASE_STRATEGIES` bring their door
    variants (``ceco-pmv`` brings ``ceco-pmv-aq``), and where the case's door is the production logic
    (``door_mode: auto``) the members of :data:`DOOR_TUNED_KINDS` carry the door values tuned with their law
    (``door_tuning``: :func:`load_door_tuning`).
    """
    if not case.baseline_door:
        return list(specs)
    out = []
    auto = dict(case.baseline_door).get('door_mode') == 'auto'
    for c in specs:
        law = DOOR_TUNED_KINDS.get(c.kind)
        if auto and door_tuning and law in door_tuning:
            c = dataclasses.replace(c, overrides=tuple(sorted({**dict(c.overrides), **door_tuning[law]}.items())))
        out.append(c)
    names = {c.name for c in out}
    out += [
        ControllerSpec(v, 'strategy', *STRATEGY_VARIANTS[v])
        for c in specs
        if c.kind == 'strategy' and (v := DOOR_CASE_STRATEGIES.get(c.name)) and v not in names
    ]
    n_fam = sum(1 for c in out if c.kind in FAMILIES.values())
    return [*out[:n_fam], *door_specs, *out[n_fam:]]


def case_cells(
    case: Case,
    specs: Sequence[ControllerSpec],
    code: str,
    *,
    seeds: Sequence[int] | None = None,
    variant: str = 'nominal',
    plant_overrides: Mapping | None = None,
    comfort_overrides: Mapping | None = None,
) -> list[Cell]:
    """The cells of one case (one per controller, and per seed for the seeded ones)."""
    scenario = case.scenario_dict()
    sha = case.sha()
    out = []
    for c in specs:
        for seed in list(seeds if seeds is not None else case.seeds) if c.seeded else [None]:
            spec = {
                'benchmark_version': BENCHMARK_VERSION,
                'code': code,
                'case': case.name,
                'case_sha': sha,
                'scenario': scenario,
                'strategy': c.strategy,
                'strategy_overrides': {
                    **case.strategy_overrides(c.strategy),
                    **dict(c.overrides),
                },  # a member's own win
                'preview': c.preview or (case.preview if c.seeded else 'perfect'),
                'seed': seed,
                'duration_s': case.duration_s,
                'control_period_s': case.control_period_s,
                'horizon_steps': case.horizon_steps,
                'plant_overrides': dict(plant_overrides or {}),
                'comfort_overrides': dict(comfort_overrides or {}),
            }
            if c.measurements != 'full':
                spec['measurements'] = c.measurements
            if c.kind == 'external':
                spec['external'] = external_identity(c)
            axes = {
                'case': case.name,
                'controller': c.name,
                'kind': c.kind,
                'seed': seed,
                'variant': variant,
                'setpoint_c': c.setpoint_c,
                'setpoint_pmv': c.setpoint_pmv,
            }
            out.append(Cell(id=cell_id(spec), axes=axes, spec=spec))
    return out


def external_identity(c: ControllerSpec) -> dict:
    """What defines an external controller in its cells' spec, hence in their ids: its name, command and directory.

    Another name, command or directory is another controller: its cells run, never resumed from the rows
    of the one before in the same ``--out`` (docs/benchmark.md, "The command").
    """
    return {'name': c.name, 'command': list(c.command), 'cwd': c.cwd}


def new_row(cell: Mapping, source: str) -> dict:
    """The ``cells.jsonl`` row of a cell before it runs: status ok, no KPIs yet; ``source`` simulator or dds."""
    return {
        'cell_id': cell['id'],
        **cell['axes'],
        'status': 'ok',
        'error': '',
        'kpis': None,
        'kpi_notes': {},
        'source': source,
        'sim_time_s': math.nan,
    }


def mark_failed(row: dict, check: ControlCheck) -> None:
    """Mark ``row`` failed when its controller did not control the run (``ceco_core.run_status``).

    Its KPIs are kept; a failed run is never on a front nor matched (docs/benchmark.md, "Failed runs").
    """
    if row['status'] == 'ok' and not check.ok:
        row['status'], row['error'] = STATUS_FAILED, check.reason


def run_benchmark_cell(cell: Mapping, runs_dir: str | None = None, controller_cache=None) -> dict:
    """Run one benchmark cell in this process and score it; never raises (errors are data).

    ``controller_cache``: the worker's :class:`ceco_controller.factory.ControllerCache` (a warm
    worker reuses its controllers; the results are the same).

    Returns the row logged in ``cells.jsonl``: ``cell_id``, the axes, ``status``, ``error``,
    ``kpis``, ``kpi_notes``, ``code``, ``sim_time_s``, ``wall_time_s``, ``source``.
    """
    import os
    import socket
    import time

    t0 = time.perf_counter()
    row = new_row(cell, 'simulator')
    try:
        from ceco_bringup.sweep import cells as sweep_cells
        from ceco_controller.closed_loop import simulate, write_run
        from ceco_core.kpis import compute_kpis
        from ceco_v2x_preview.scenario import scenario_from_dict

        spec = cell['spec']
        row['code'] = sweep_cells.check_code(spec, 'benchmark')
        t_sim = time.perf_counter()
        settings = sweep_cells.settings_from_spec(spec)
        scenario = scenario_from_dict(spec['scenario'])
        res = simulate(scenario, spec['strategy'], settings, controller_cache=controller_cache)
        m = res.metrics
        kpis, notes = compute_kpis(
            res.timeseries,
            step_time_s=res.step_time_s,
            control_period_s=m['control_period_s'],
            fallback_steps=m['n_fallback_shifted'] + m['n_fallback_baseline'],
            air_limits=scenario.air_quality.limits,
        )
        row['sim_time_s'] = time.perf_counter() - t_sim
        row['kpis'], row['kpi_notes'] = kpis, notes
        mark_failed(row, check_control(m['n_control_steps'], m['n_fallback_shifted'] + m['n_fallback_baseline']))
        if runs_dir:
            write_run(res, Path(runs_dir) / cell['id'])
    except Exception as exc:  # a failed run is data, the benchmark goes on
        row['status'], row['error'] = 'error', f'{type(exc).__name__}: {exc}'
    row['wall_time_s'] = time.perf_counter() - t0
    row['host'], row['pid'] = socket.gethostname(), os.getpid()
    return row


def seed_matters(spec: Mapping) -> bool:
    """Whether a cell's run depends on its ``seed``.

    The simulator uses the seed for the preview errors only (``closed_loop.simulate`` hands it to the
    preview quality); a preview without errors (``PreviewQuality.uses_seed`` false: the persistence twin,
    perfect, delayed or missing previews) gives the same run for every seed. A spec without a preview (an
    oracle cell) is taken to depend on it.
    """
    from ceco_v2x_preview.preview import parse_quality

    if spec.get('seed') is None:
        return False
    return 'preview' not in spec or parse_quality(spec['preview']).uses_seed


def share_seed_invariant(items: Sequence[Mapping]) -> tuple[list, dict]:
    """The items to run, and ``{id of a run item: [items that reuse its row]}``.

    Of seeded items whose run does not depend on the seed (:func:`seed_matters`), only the first of each
    group with the same spec but the seed runs; the others reuse its row (:func:`reused_row`). Likewise of
    oracle cells that name their problem (:func:`oracle_cells`), only the first of each group with the same
    problem, levels, entry point and code.
    """
    run, reuse, first = [], {}, {}
    for item in items:
        spec = item['spec']
        if spec.get('kind') == 'oracle' and spec.get('problem'):
            key = cell_id({k: spec.get(k) for k in ('benchmark_version', 'code', 'kind', 'entry', 'levels', 'problem')})
        elif spec.get('seed') is None or seed_matters(spec):
            run.append(item)
            continue
        else:
            key = cell_id({**spec, 'seed': None})
        if key in first:
            reuse.setdefault(first[key], []).append(item)
        else:
            first[key] = item['id']
            run.append(item)
    return run, reuse


def reused_row(row: Mapping, item: Mapping) -> dict:
    """``row`` as the row of ``item``: its id and axes, no run time.

    ``row`` is a run of the same spec at another seed, or an oracle cell of the same problem.
    """
    return {
        **row,
        'cell_id': item['id'],
        **item['axes'],
        'reused_from': row['cell_id'],
        **({'sim_time_s': 0.0} if 'sim_time_s' in row else {}),
        'wall_time_s': 0.0,
    }


def _run_entry(row: Mapping) -> dict:
    kpis = row.get('kpis') or {}
    from .schema import REQUIRED_KPIS

    if row['status'] not in ('ok', STATUS_FAILED):  # an error: no KPIs; a failed run keeps its KPIs
        kpis = {k: None for k in REQUIRED_KPIS}
        notes = {k: 'the run failed' for k in REQUIRED_KPIS}
    else:
        notes = dict(row.get('kpi_notes') or {})
    clean = {
        k: (None if v is None or (isinstance(v, float) and not math.isfinite(v)) else float(v)) for k, v in kpis.items()
    }
    for k, v in kpis.items():
        if v is not None and clean[k] is None:
            notes.setdefault(k, 'not finite')
    return {
        'controller': row['controller'],
        'kind': row['kind'],
        'seed': row['seed'],
        'setpoint_c': row.get('setpoint_c'),
        'setpoint_pmv': row.get('setpoint_pmv'),
        'source': row.get('source', 'simulator'),
        'status': row['status'],
        'error': row.get('error', ''),
        'kpis': clean,
        'kpi_notes': notes,
    }


def breaks_air_quality(run: Mapping) -> bool:
    """True when a run passed the scenario's CO2 limit or fog bound (KPI ``air_quality_met`` 0).

    Such a run is never on a front nor matched; the rule of every verb (``ceco_core.kpis.breaks_air_quality``).
    """
    from ceco_core.kpis import breaks_air_quality as breaks

    return breaks(run.get('kpis') or {})


def air_quality_broken(runs: Sequence[Mapping]) -> list[str]:
    """The controllers of a case with at least one run that broke the air-quality limits (sorted)."""
    return sorted({r['controller'] for r in runs if r['status'] == 'ok' and breaks_air_quality(r)})


def fronts_of(runs: Sequence[Mapping], fx: str, ex: str) -> dict:
    """``{family: Front or None}`` of a case's run entries on the axes (``fx``, ``ex``) (schema.FAMILIES order).

    Only runs that meet the air-quality limits (:func:`breaks_air_quality`) make a front.
    """
    out = {}
    ceiling = fr.saturation_ceiling((r['kpis'] for r in runs if r['status'] == 'ok'), fx)
    for family, kind in FAMILIES.items():
        pts = [
            (r['controller'], r['kpis'][fx], r['kpis'][ex])
            for r in runs
            if r['kind'] == kind
            and r['status'] == 'ok'
            and not breaks_air_quality(r)
            and r['kpis'].get(fx) is not None
            and r['kpis'].get(ex) is not None
        ]
        out[family] = fr.build_front(pts, ceiling=ceiling) if pts else None
    return out


def envelope_of(fronts: Mapping) -> fr.Envelope | None:
    """The strongest of the families (:class:`front.Envelope`), None when no family has a front with a vertex.

    (No vertex: every member of every family at the discomfort ceiling, :func:`front.saturated`.)
    """
    if not any(f is not None and f.vertices for f in fronts.values()):
        return None
    return fr.Envelope.of(fronts)


def _scored_runs(runs: Sequence[Mapping], fx: str, ex: str) -> dict:
    """{controller: [its scored runs, by seed]}; a controller with a run that broke the air-quality limits has none."""
    out: dict = {}
    broken = set(air_quality_broken(runs))
    for r in sorted(runs, key=lambda r: -1 if r['seed'] is None else r['seed']):
        if r['kind'] in SCORED_KINDS and r['status'] == 'ok' and r['controller'] not in broken:
            if r['kpis'].get(fx) is not None and r['kpis'].get(ex) is not None:
                out.setdefault(r['controller'], []).append(r)
    return out


def _points(runs: Sequence[Mapping], fx: str, ex: str, with_seed: bool = False) -> dict:
    """The scored controllers' points (:func:`_scored_runs`): (seed, D, E), or (D, E)."""
    return {
        name: [(r['seed'], r['kpis'][fx], r['kpis'][ex]) if with_seed else (r['kpis'][fx], r['kpis'][ex]) for r in rs]
        for name, rs in _scored_runs(runs, fx, ex).items()
    }


def member_kpis(runs: Sequence[Mapping]) -> dict:
    """{controller: kpis} of the baseline families' members with status ok (the fronts' vertex names)."""
    return {r['controller']: r['kpis'] for r in runs if r['kind'] in FAMILIES.values() and r['status'] == 'ok'}


def _match_or_none(front, pts):
    return None if front is None else fr.match_seeds(front, pts)


def matched_of(
    runs: Sequence[Mapping], fx: str, ex: str, bounds: Mapping | None = None, bound_kpis: Mapping | None = None
) -> dict:
    """The matched-comfort entries of every scored controller of a case.

    Against the production fronts (top level: plain; ``allowance``), the strongest family (``strongest``,
    with the ``family`` at its seed-mean discomfort) and, with ``bounds`` ({seed: the oracle's Front}),
    ``headroom`` (:func:`front.headroom_seeds`; else None); with ``bound_kpis`` too ({seed: {vertex name:
    kpis}}, :func:`oracle_point_kpis`), ``by_phase`` (:func:`front.by_phase`: the controller, the strongest
    family and the bound at the controller's discomfort, band phase against the whole run; else None).
    """
    fronts = fronts_of(runs, fx, ex)
    env = envelope_of(fronts)
    out = {}
    if fronts['plain'] is None or env is None:
        return out
    members = member_kpis(runs)
    for name, rs in _scored_runs(runs, fx, ex).items():
        pts = [(r['seed'], r['kpis'][fx], r['kpis'][ex]) for r in rs]
        de = [(d, e) for _, d, e in pts]
        strongest = fr.match_seeds(env, de)
        strongest['family'] = env.family_at(sum(d for d, _ in de) / len(de))
        phase = [(r['seed'], r['kpis'][fx], r['kpis']) for r in rs]
        out[name] = {
            **fr.match_seeds(fronts['plain'], de),
            'allowance': _match_or_none(fronts['allowance'], de),
            'strongest': strongest,
            'headroom': fr.headroom_seeds(env, bounds, pts) if bounds else None,
            'by_phase': fr.by_phase(env, bounds, phase, members, bound_kpis) if bounds and bound_kpis else None,
        }
    return out


def oracle_levels(runs: Sequence[Mapping], n: int = 4) -> list[float]:
    """The discomfort levels [PMV h] the oracle is asked for on a case.

    ``n`` (>= 4) levels from D_lo, the least discomfort of any family's vertex or any scored controller, to
    the greatest of the scored controllers' and 1.5 D_lo (the range of the strategies and of the efficient
    baselines around them), spaced quadratically (D_lo + (hi - D_lo) (i / (n - 1))^2): the fronts are
    steepest near D_lo, where the strategies sit, and a bound read between two levels is a straight line
    that lies above the convex optimum (it understates the oracle's saving there). [] without a front.
    Not rounded: the first level is the envelope's own end (the runs are deterministic, so the levels and
    the oracle's cell ids are too).
    """
    if n < 4:
        raise ValueError(f'oracle_levels: at least 4 levels, got {n}')
    env = envelope_of(fronts_of(runs, FRONT_AXIS, ENERGY_AXIS))
    if env is None:
        return []
    ds = [d for pts in _points(runs, FRONT_AXIS, ENERGY_AXIS).values() for d, _ in pts]
    lo = min([env.d_range[0], *ds])
    hi = max([1.5 * lo, *ds])
    return [lo + (hi - lo) * (i / (n - 1)) ** 2 for i in range(n)]


def assemble_case(
    case: Case, rows: Sequence[Mapping], sensitivity: Sequence[tuple] = (), oracle: Mapping | None = None
) -> dict:
    """One case of results.json.

    From its finished rows (nominal variant), optionally ``sensitivity`` = [(Sensitivity, low rows,
    high rows), ...] and the case's ``oracle`` entry (:func:`oracle_entry`; None: status 'skipped').
    """
    runs = [_run_entry(r) for r in rows]
    runs.sort(key=lambda r: (r['controller'], -1 if r['seed'] is None else r['seed']))
    fronts = fronts_of(runs, FRONT_AXIS, ENERGY_AXIS)
    env = envelope_of(fronts)
    oracle = dict(oracle) if oracle is not None else oracle_entry('skipped', 'not requested', [], [])
    bounds = oracle_bounds(oracle)
    bound_kpis = oracle_point_kpis(oracle)
    sc = case.load_scenario()
    ts, n_p = sc.control.timing(case.control_period_s, case.horizon_steps)
    out = {
        'case': case.name,
        'version': case.version,
        'case_sha': case.sha(),
        'description': case.description,
        'scenario': case.scenario,
        'forecast_uncertainty': case.forecast_uncertainty,
        'seeds': list(case.seeds),
        'duration_s': float(sc.duration_s),
        'control_period_s': ts,
        'horizon_steps': n_p,
        'runs': runs,
        'fronts': {fam: _front_points(f) for fam, f in fronts.items()},
        'strongest': strongest_entry(env, oracle['levels'] or oracle_levels(runs)),
        'oracle': oracle,
        'matched': matched_of(runs, FRONT_AXIS, ENERGY_AXIS, bounds, bound_kpis),
        'air_quality': {
            'co2_limit_ppm': float(sc.air_quality.co2_limit_ppm),
            'fog_margin_min_k': float(sc.air_quality.fog_margin_min_k),
            'occupants': int(sc.occupants),
            'broken': air_quality_broken(runs),
        },
    }
    out['matched_by_axis'] = {
        ax: {
            n: {k: m[k] for k in ('energy_saving_pct', 'discomfort_reduction_pct', 'dominated', 'note')}
            for n, m in matched_of(runs, ax, ENERGY_AXIS).items()
        }
        for ax in SECONDARY_AXES
    }
    if sensitivity:
        out['sensitivity'] = []
        for s, low_rows, high_rows in sensitivity:
            entry = {
                'parameter': s.parameter,
                'target': s.target,
                'source': s.source,
                'nominal': _scalar(s.nominal),
                'low': _scalar(s.low),
                'high': _scalar(s.high),
            }
            for end, rs in (('low', low_rows), ('high', high_rows)):
                m = matched_of([_run_entry(r) for r in rs], FRONT_AXIS, ENERGY_AXIS)
                entry[f'matched_{end}'] = {
                    n: {k: v[k] for k in ('energy_saving_pct', 'discomfort_reduction_pct', 'dominated', 'note')}
                    for n, v in m.items()
                }
                entry[f'failed_{end}'] = sum(r['status'] != 'ok' for r in rs)
            out['sensitivity'].append(entry)
    return out


def _front_points(f: fr.Front | None) -> list:
    if f is None:
        return []
    return [
        {'controller': p.name, 'discomfort': p.discomfort, 'energy': p.energy, 'efficient': p.efficient}
        for p in f.points
    ]


def strongest_entry(env: fr.Envelope | None, levels: Sequence[float]) -> dict:
    """results.json's ``strongest`` of a case.

    The families of the envelope, and the strongest family per level (:func:`front.strongest_by_level`) at
    ``levels`` (the oracle's levels).
    """
    if env is None:
        return {'families': [], 'levels': [], 'family': None}
    return {'families': [name for name, _ in env.fronts], **fr.strongest_by_level(env, levels)}


def _scalar(fields: Mapping):
    """The first field's value: the parameter itself (coupled fields such as a second angle factor follow it).

    None where the nominal is "no fixed value" (the scored p_a from the plant's moisture balance).
    """
    v = next(iter(fields.values()))
    return None if v is None else float(v)


ORACLE_ENTRY = 'ceco_controller.oracle:solve_front'
"""The whole-drive optimum's entry point (docs/benchmark.md, "The oracle"):
``solve_front(case, seed, levels) -> list`` with ``case`` a :class:`~.cases.Case`, ``seed`` one of its
seeds (the truth the oracle knows; the forecast errors of that seed do not concern it), ``levels`` the
discomfort levels [PMV h, ``discomfort_pmvh``]; it returns one item per level, in order: a mapping of KPIs
(:func:`ceco_core.kpis.compute_kpis` of the optimum replayed on the plant; at least ``energy_kwh`` and
``discomfort_pmvh``) or None where that level was not solved."""


def oracle_unavailable(entry: str = ORACLE_ENTRY) -> str | None:
    """Why the oracle cannot be called (a sentence), or None when ``entry`` (``module:function``) imports."""
    import importlib
    import importlib.util

    mod, _, fn = entry.partition(':')
    try:
        if importlib.util.find_spec(mod) is None:
            return f'{mod} is not installed'
        if not callable(getattr(importlib.import_module(mod), fn, None)):
            return f'{mod} has no function {fn}'
    except ModuleNotFoundError as exc:
        if exc.name and (mod == exc.name or mod.startswith(exc.name + '.')):
            return f'{mod} is not installed'  # the module or a parent package is absent
        return f'{mod} does not import ({type(exc).__name__}: {exc})'
    except ImportError as exc:  # the module fails to import
        return f'{mod} does not import ({type(exc).__name__}: {exc})'
    return None


def oracle_problem(case: Case) -> str:
    """What ceco's oracle (:data:`ORACLE_ENTRY`) reads of a case, hashed.

    The drive's truth (the scenario with the case's overrides), the control period and the production door
    logic. Cases that differ only in what the oracle does not see (the forecast uncertainty, the seeds, the
    families) have the same problem.
    """
    truth = {'scenario': case.scenario_dict(), 'control_period_s': case.control_period_s, 'door': case.baseline_door}
    return cell_id(truth)


def oracle_cells(case: Case, seeds: Sequence[int], levels: Sequence[float], code: str, entry: str = ORACLE_ENTRY):
    """The oracle's cells of a case, one per seed.

    A cell's id covers the case, the levels, the entry point and the simulator's code fingerprint, so a
    rerun reuses it and a changed simulator recomputes it. With ceco's own entry point the spec also names
    the problem (:func:`oracle_problem`), so that cases with the same problem and levels solve it once
    (:func:`share_seed_invariant`; sc03-paper and its three uncertainty levels: one solve, not four).
    """
    out = []
    for seed in seeds:
        spec = {
            'benchmark_version': BENCHMARK_VERSION,
            'code': code,
            'kind': 'oracle',
            'entry': entry,
            'case': dataclasses.asdict(case),
            'case_sha': case.sha(),
            'seed': int(seed),
            'levels': [float(x) for x in levels],
        }
        if entry == ORACLE_ENTRY:
            spec['problem'] = oracle_problem(case)
        axes = {'case': case.name, 'controller': 'oracle', 'kind': 'oracle', 'seed': int(seed), 'variant': 'oracle'}
        out.append(Cell(id=cell_id(spec), axes=axes, spec=spec))
    return out


def oracle_cost_order(cells: Sequence[Cell], cases: Mapping[str, Case]) -> list[Cell]:
    """``cells`` (oracle cells of ``cases``, by name) with the longest expected solve first.

    The pool then ends on the short cells instead of waiting for a long one started last (longest processing
    time first). The expected cost is the drive's duration, doubled where the door is a decision: an IPOPT
    iteration costs in proportion to the drive's intervals, and the door cases' in the full benchmark with the
    oracle took 0.28-0.30 s of solve per second of drive against 0.11-0.19 s for the others (levels that did
    not converge aside; docs/oracle.md "Cost"). Only the order changes, never a result. Stable: cells of equal
    cost keep their order (the first of a shared problem stays the one solved, :func:`share_seed_invariant`).
    """

    def cost(cell: Cell) -> float:
        case = cases[cell.axes['case']]
        return float(case.load_scenario().duration_s) * (2.0 if case.baseline_door else 1.0)

    return sorted(cells, key=lambda c: -cost(c))


def _solver_account(solver: Mapping) -> dict:
    """The solver's account of one oracle level, checked.

    ``status`` (str), ``iterations`` (int >= 0), ``wall_time_s`` (finite, >= 0) [s] and, optionally,
    ``evaluation`` (a non-empty str: how the plant steps were evaluated) and ``form`` (a non-empty str: the NLP's
    form, ceco's ``lifted``, ``summed`` or ``lifted, then summed``); ValueError naming the field otherwise.
    """
    out = {k: solver.get(k) for k in ('status', 'iterations', 'wall_time_s')}
    for key in ('evaluation', 'form'):
        if key in solver:
            if not isinstance(solver[key], str) or not solver[key]:
                raise ValueError(f'the oracle\'s solver {key} must be a non-empty str, got {solver[key]!r}')
            out[key] = solver[key]
    if not isinstance(out['status'], str) or not out['status']:
        raise ValueError(f'the oracle\'s solver status must be a non-empty string, got {out["status"]!r}')
    if isinstance(out['iterations'], bool) or not isinstance(out['iterations'], int) or out['iterations'] < 0:
        raise ValueError(f'the oracle\'s solver iterations must be an int >= 0, got {out["iterations"]!r}')
    wall = out['wall_time_s']
    if isinstance(wall, bool) or not isinstance(wall, (int, float)) or not math.isfinite(wall) or wall < 0:
        raise ValueError(f'the oracle\'s solver wall_time_s must be finite and >= 0, got {wall!r}')
    out['wall_time_s'] = float(wall)
    return out


def run_oracle_cell(cell: Mapping, runs_dir: str | None = None, controller_cache=None) -> dict:
    """Call the oracle for one (case, seed); never raises (errors are data).

    ``runs_dir`` and ``controller_cache`` (a warm worker's, :class:`~ceco_bringup.sweep.backends.WarmWorker`)
    are unused.

    The entry point returns one item per level: None (not solved), the replayed run's KPIs, or
    ``{'kpis': KPIs or None, 'solver': {'status', 'iterations', 'wall_time_s'}}`` (ceco's oracle: the
    solver's account is kept in the point, so an unsolved level says why).

    The row: ``cell_id``, the axes, ``status`` ('ok' when the call returned one item per level),
    ``error``, ``points`` = [{'level', 'kpis' (or None), 'error', 'solver' (when given)}], ``wall_time_s``.
    """
    import importlib
    import time

    from .cases import Case as _Case

    t0 = time.perf_counter()
    row = {'cell_id': cell['id'], **cell['axes'], 'status': 'ok', 'error': '', 'points': []}
    try:
        from ceco_bringup.sweep import cells as sweep_cells

        spec = cell['spec']
        row['code'] = sweep_cells.check_code(spec, 'benchmark')
        fields = dict(spec['case'])
        fields['seeds'] = tuple(fields['seeds'])
        case = _Case(**fields)
        mod, _, fn = spec['entry'].partition(':')
        levels = list(spec['levels'])
        result = list(getattr(importlib.import_module(mod), fn)(case, spec['seed'], levels))
        if len(result) != len(levels):
            raise ValueError(f'the oracle returned {len(result)} item(s) for {len(levels)} level(s)')
        for level, item in zip(levels, result):
            point = {'level': level, 'kpis': None, 'error': ''}
            solver = None
            if isinstance(item, Mapping) and set(item) == {'kpis', 'solver'}:
                solver = _solver_account(item['solver'])
                point['solver'] = solver
                item = item['kpis']
            if item is None:
                point['error'] = (
                    f'not solved ({solver["status"]}, {solver["iterations"]} iterations, {solver["wall_time_s"]:.0f} s)'
                    if solver
                    else 'not solved'
                )
            else:
                kpis = {str(k): (None if v is None else float(v)) for k, v in dict(item).items() if k != 'error'}
                bad = [k for k in (FRONT_AXIS, ENERGY_AXIS) if kpis.get(k) is None or not math.isfinite(kpis[k])]
                if bad:
                    point['error'] = f'no finite {", ".join(bad)}'
                else:
                    point['kpis'] = {k: (v if v is None or math.isfinite(v) else None) for k, v in kpis.items()}
            row['points'].append(point)
    except Exception as exc:  # a failed oracle is data, the benchmark goes on
        row['status'], row['error'] = 'error', f'{type(exc).__name__}: {exc}'
    row['wall_time_s'] = time.perf_counter() - t0
    return row


def oracle_entry(status: str, note: str, levels: Sequence[float], rows: Sequence[Mapping]) -> dict:
    """results.json's ``oracle`` of a case from the oracle's rows (one per seed; :func:`run_oracle_cell`).

    ``status``: 'ok', 'unavailable' (the module is absent), 'skipped' (``--no-oracle``, or not asked for
    this case) or 'error' (no seed gave a front); ``fronts`` = per seed the points and the front built from
    the solved ones that meet the air-quality limits (members ``oracle@<level>``).
    """
    fronts = []
    for r in rows:
        # a level whose replay broke the air-quality limits is no bound (the oracle holds the door where the
        # plant leaves it; a saving bought with stale air is no saving): kept in points, not on the front
        pts = [p for p in r.get('points', []) if p.get('kpis') and not breaks_air_quality(p)]
        front = (
            fr.build_front([(oracle_member(p['level']), p['kpis'][FRONT_AXIS], p['kpis'][ENERGY_AXIS]) for p in pts])
            if pts and r['status'] == 'ok'
            else None
        )
        fronts.append(
            {
                'seed': r['seed'],
                'status': r['status'] if front is not None or r['status'] != 'ok' else 'error',
                'error': r.get('error', '') or ('' if front is not None else 'no level solved'),
                'points': [
                    {
                        'level': float(p['level']),
                        'kpis': p.get('kpis'),
                        'error': p.get('error', '')
                        or ('breaks the air-quality limits: not a bound' if breaks_air_quality(p) else ''),
                        **({'solver': dict(p['solver'])} if p.get('solver') else {}),
                    }
                    for p in r.get('points', [])
                ],
                'front': _front_points(front),
            }
        )
    if status == 'ok' and not any(f['front'] for f in fronts):
        status, note = 'error', note or 'the oracle solved no level'
    return {
        'status': status,
        'entry_point': ORACLE_ENTRY,
        'note': note,
        'levels': [float(x) for x in levels],
        'fronts': fronts,
    }


def oracle_bounds(oracle: Mapping) -> dict:
    """``{seed: Front}`` of a case's ``oracle`` entry (empty unless its status is 'ok')."""
    if oracle.get('status') != 'ok':
        return {}
    out = {}
    for f in oracle['fronts']:
        if f['front']:
            out[f['seed']] = fr.build_front([(p['controller'], p['discomfort'], p['energy']) for p in f['front']])
    return out
