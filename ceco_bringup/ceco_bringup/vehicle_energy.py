"""Vehicle-level energy of the A/C load with NREL FASTSim 3.1 (optional extra).

What it answers: how much fuel (hybrid) or battery energy (electric car) the
A/C electrical energy of a run costs over the run's drive cycle, and how the
strategies' A/C savings translate into vehicle savings (the paper's -6.4 /
-1.8 / -3.1 % on a Prius HEV).

Method (docs/analysis.md, "Vehicle-level energy"):

* FASTSim 3.1 takes the auxiliary electrical load as one constant,
  ``pwr_aux_base_watts`` [W]. The A/C enters as the run's mean A/C
  electrical power ``P_ac = E_tot / T`` [W] (compressor + blower) added to
  the vehicle's shipped base load. Spreading the same energy differently over
  the cycle changed Prius fuel by < 0.4 % in a check (seed notes).
* Fuel versus aux load is not smooth (engine on/off decisions), so one
  FASTSim evaluation per strategy would bury a 1 % difference in noise.
  Every strategy of a comparison is therefore read off ONE straight line,
  ``E_veh(P) = a + b * P``, fitted by least squares to FASTSim evaluations at
  ``fit_points`` loads spanning ``[min P_ac - margin, max P_ac + margin]``
  (averaging over load levels). The residual scatter of that fit is reported
  as the noise level; the direct evaluation at each ``P_ac`` is reported too.
* Hybrid fuel is charge-sustaining-corrected: ``E_fuel,corr = E_fuel +
  E_res / eta_fc``, where ``E_res`` [J] is the battery's net chemical energy
  out over the cycle and ``eta_fc`` the engine's mean efficiency over the
  cycle (SAE J1711 style net-energy correction). FASTSim 3.1 already
  balances SOC for its HEV, so the correction is typically < 0.2 %.
* Electric car: battery chemical energy out [J]. Range over repeated cycles
  ``R = E_usable / (E_res / d)``, ``E_usable = E_cap (soc_max - soc_min)``;
  range lost to A/C = ``R(base aux) - R(base aux + P_ac)``.

Vehicles: ``2016_TOYOTA_Prius_Two`` (the paper used a 2017 Prius HEV) and
``2022_Renault_Zoe_ZE50_R135``: the only battery-electric car shipped with
fastsim 3.1.0 without FASTSim's own cabin/HVAC model (the ``thrml`` Leaf,
Bolt and Model 3 files carry one, which would count the A/C twice and which
the seed notes found unusable), a compact car of the Prius' mass (1600 vs
1635 kg).

Pure Python; ``fastsim`` is imported lazily, so importing this module never
needs it (nor does the ROS runtime).
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from collections.abc import Mapping, Sequence

import numpy as np

from ceco_core.metrics import relative_change_pct

__all__ = [
    'PRIUS',
    'ZOE',
    'PAPER_VEHICLE_CHANGE_PCT',
    'GASOLINE_J_PER_L',
    'VehicleEnergySettings',
    'VehicleRun',
    'FastsimMissingError',
    'import_fastsim',
    'simulate_vehicle',
    'fit_energy_vs_aux',
    'vehicle_energy_table',
    'drive_cycle_for_run',
]

PRIUS = '2016_TOYOTA_Prius_Two'
"""FASTSim 3.1.0 resource of the hybrid (the paper's vehicle class)."""
ZOE = '2022_Renault_Zoe_ZE50_R135'
"""FASTSim 3.1.0 resource of the electric car (no FASTSim cabin/HVAC model)."""

PAPER_VEHICLE_CHANGE_PCT = {'ceco-e': -6.4, 'ceco-c': -1.8, 'ceco-ioch': -3.1}
"""Vehicle energy change against the baseline on SC03, Prius HEV [%] (paper, Sec. 5)."""

GASOLINE_J_PER_L = 33.705 * 3.6e6 / 3.785411784
"""Gasoline energy per litre [J/L]: EPA's 33.705 kWh per US gallon (the
gasoline-gallon equivalent used for MPGe labels), 3.785 L per gallon."""


class FastsimMissingError(ImportError):
    """The optional ``fastsim`` extra is not installed."""


def import_fastsim():
    """Import ``fastsim`` or raise :class:`FastsimMissingError` saying how to install it.

    The install command is ``pip install -r requirements/analysis.txt``.
    """
    try:
        import fastsim  # lazy: optional extra
    except ImportError as exc:
        raise FastsimMissingError(
            'vehicle-level energy needs the optional FASTSim extra: '
            'pip install -r requirements/analysis.txt (fastsim==3.1.0)'
        ) from exc
    return fastsim


@dataclasses.dataclass(frozen=True)
class VehicleEnergySettings:
    """How the A/C load is translated into vehicle energy."""

    vehicles: tuple = (PRIUS, ZOE)
    """FASTSim 3.1 vehicle resources (file name without ``.yaml``)."""
    fit_points: int = 7
    """Aux-load levels of the least-squares line [-], >= 2."""
    fit_margin_w: float = 300.0
    """Fit range beyond the smallest and largest mean A/C power [W], >= 0."""
    baseline: str = 'baseline'
    """Strategy the changes are taken against."""

    def validate(self) -> None:
        """Check every field; raise ValueError naming the first bad one."""
        if not self.vehicles or not all(isinstance(v, str) and v for v in self.vehicles):
            raise ValueError('vehicles: must be a non-empty tuple of FASTSim resource names')
        if isinstance(self.fit_points, bool) or int(self.fit_points) != self.fit_points or self.fit_points < 2:
            raise ValueError(f'fit_points: must be an integer >= 2, got {self.fit_points!r}')
        if not (math.isfinite(self.fit_margin_w) and self.fit_margin_w >= 0.0):
            raise ValueError(f'fit_margin_w: must be finite and >= 0, got {self.fit_margin_w!r}')
        if not isinstance(self.baseline, str) or not self.baseline:
            raise ValueError('baseline: must be a non-empty strategy name')


@dataclasses.dataclass(frozen=True)
class VehicleRun:
    """One FASTSim evaluation of a vehicle over a cycle with an added aux load."""

    vehicle: str
    """FASTSim resource name."""
    powertrain: str
    """FASTSim powertrain type: ``HEV``, ``BEV`` or ``Conv``."""
    p_aux_added_w: float
    """A/C load added to the shipped base aux load [W]."""
    p_aux_base_w: float
    """The vehicle's shipped base aux load [W]."""
    energy_j: float
    """Vehicle energy over the cycle [J]: charge-corrected fuel (HEV, Conv) or
    battery chemical energy out (BEV)."""
    fuel_raw_j: float
    """Fuel energy before the charge correction [J] (NaN for a BEV)."""
    res_net_out_j: float
    """Battery net chemical energy out over the cycle [J] (0 without battery)."""
    distance_m: float
    """Distance FASTSim drove [m]."""
    trace_miss_max_mps: float
    """Largest shortfall of achieved against prescribed speed [m/s]."""
    usable_battery_j: float
    """Usable battery energy ``E_cap (soc_max - soc_min)`` [J] (NaN for a HEV)."""
    wall_time_s: float
    """Wall-clock time of this evaluation [s] (vehicle build + simulation)."""
    soc_balance: str = 'none'
    """Hybrid: 'balanced', 'balanced_more_iterations' or 'corrected'; else 'none'."""


def _check_cycle(time_s, speed_mps):
    t = np.asarray(time_s, dtype=float)
    v = np.asarray(speed_mps, dtype=float)
    if t.ndim != 1 or t.shape != v.shape or t.size < 2:
        raise ValueError(f'time_s/speed_mps: need equal-length 1-D arrays of >= 2 samples, got {t.shape} and {v.shape}')
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
        raise ValueError('time_s/speed_mps: NaN or infinite value')
    if t[0] != 0.0 or np.any(np.diff(t) <= 0.0):
        raise ValueError('time_s: must start at 0 and increase strictly')
    if np.any(v < 0.0) or np.any(v > 70.0):
        raise ValueError('speed_mps: must be within 0..70 m/s')
    return t, v


def _powertrain(vdict: Mapping) -> tuple[str, Mapping]:
    ((kind, body),) = vdict['pt_type'].items()
    return kind, body


_SOC_BALANCE_ATTEMPTS = ('balanced', 'balanced_more_iterations', 'corrected')
"""How a hybrid's charge is sustained, tried in turn: FASTSim's own SOC
balancing (initial SOC iterated, 5 iterations), the same with 20, and none
(the net battery energy is then converted by the charge correction alone).
FASTSim's balancing fails to converge at some loads on short cycles."""


def _with_soc_balance(vdict: dict, attempt: str) -> dict:
    pt = vdict['pt_type']
    if 'HEV' not in pt or 'sim_params' not in pt['HEV']:
        return vdict
    hev = dict(pt['HEV'])
    sp = dict(hev['sim_params'])
    if attempt == 'balanced_more_iterations':
        sp['soc_balance_iter_err'] = 20
    elif attempt == 'corrected':
        sp['balance_soc'] = False
    hev['sim_params'] = sp
    return {**vdict, 'pt_type': {'HEV': hev}}


def simulate_vehicle(vehicle: str, time_s, speed_mps, p_ac_w: float) -> VehicleRun:
    """Run FASTSim 3.1 for ``vehicle`` over a drive cycle with ``p_ac_w`` [W] added to its base aux load.

    The cycle is ``(time_s [s], speed_mps [m/s])``.

    A hybrid's charge is sustained as in :data:`_SOC_BALANCE_ATTEMPTS`.
    Speed-trace misses are allowed within FASTSim's checked tolerance
    (``AllowChecked``; at loads of several kW the Prius falls a few hundredths
    of a m/s short on the hardest accelerations) and the largest miss is
    returned. Raises ValueError for a bad cycle or a non-finite load.
    """
    if not math.isfinite(p_ac_w):
        raise ValueError(f'p_ac_w: must be finite, got {p_ac_w!r}')
    t, v = _check_cycle(time_s, speed_mps)
    fs = import_fastsim()
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', DeprecationWarning)
        vdict = fs.Vehicle.from_resource(vehicle + '.yaml').to_dict()
        base_w = float(vdict['pwr_aux_base_watts'])
        if base_w + p_ac_w < 0.0:
            raise ValueError(f'p_ac_w: base aux {base_w} W + {p_ac_w} W is negative')
        vdict['pwr_aux_base_watts'] = base_w + float(p_ac_w)
        cyc = fs.Cycle.from_dict({'time_seconds': t.tolist(), 'speed_meters_per_second': v.tolist()})
        params = fs.SimParams.default().to_dict()
        params['trace_miss_opts'] = 'AllowChecked'
        sim_params = fs.SimParams.from_dict(params)
        out, balance = None, 'none'
        for attempt in _SOC_BALANCE_ATTEMPTS:
            vd = _with_soc_balance(vdict, attempt)
            sd = fs.SimDrive(fs.Vehicle.from_dict(vd), cyc, sim_params)
            try:
                sd.run()
            except RuntimeError as exc:
                if 'SOC balancing' in str(exc) and attempt != _SOC_BALANCE_ATTEMPTS[-1]:
                    continue
                raise
            out, balance = sd.to_dict(), attempt
            break
    wall_s = time.perf_counter() - t0
    kind, pt = _powertrain(out['veh'])
    hist = out['veh']['history']
    v_ach = np.asarray(hist['speed_ach_meters_per_second'], dtype=float)
    miss = float(np.max(v[: v_ach.size] - v_ach)) if v_ach.size else float('nan')
    distance_m = float(out['veh']['state']['dist_meters'])
    res_out_j, usable_j, fuel_raw_j = 0.0, float('nan'), float('nan')
    if 'res' in pt:
        res = pt['res']
        res_out_j = float(res['state']['energy_out_chemical_joules'])
        usable_j = float(res['energy_capacity_joules']) * (float(res['max_soc']) - float(res['min_soc']))
    if 'fc' in pt:
        fc = pt['fc']['state']
        fuel_raw_j = float(fc['energy_fuel_joules'])
        eta_fc = float(fc['energy_prop_joules']) / fuel_raw_j if fuel_raw_j > 0 else float('nan')
        energy_j = fuel_raw_j + (res_out_j / eta_fc if res_out_j and eta_fc > 0 else 0.0)
        if kind == 'HEV':
            usable_j = float('nan')
    else:
        energy_j = res_out_j
    return VehicleRun(
        vehicle=vehicle,
        powertrain=kind,
        p_aux_added_w=float(p_ac_w),
        p_aux_base_w=base_w,
        energy_j=float(energy_j),
        fuel_raw_j=fuel_raw_j,
        res_net_out_j=res_out_j,
        distance_m=distance_m,
        trace_miss_max_mps=max(miss, 0.0),
        usable_battery_j=usable_j,
        wall_time_s=wall_s,
        soc_balance=balance if kind == 'HEV' else 'none',
    )


def fit_energy_vs_aux(vehicle: str, time_s, speed_mps, loads_w: Sequence[float]):
    """Evaluate ``vehicle`` at each added load [W] and fit ``E = a + b P``.

    Returns ``(a_j, b_j_per_w, noise_j, runs)``: intercept [J], slope [J/W]
    (``b / T`` is the marginal vehicle energy per joule of A/C), the residual
    standard deviation [J] (the non-smooth part) and the FASTSim runs.
    """
    loads = np.asarray(loads_w, dtype=float)
    if loads.ndim != 1 or loads.size < 2 or np.unique(loads).size < 2:
        raise ValueError('loads_w: need at least two distinct loads')
    runs = [simulate_vehicle(vehicle, time_s, speed_mps, float(p)) for p in loads]
    e = np.array([r.energy_j for r in runs])
    b, a = np.polyfit(loads, e, 1)
    resid = e - (a + b * loads)
    dof = max(loads.size - 2, 1)
    noise = float(np.sqrt(np.sum(resid**2) / dof)) if loads.size > 2 else 0.0
    return float(a), float(b), noise, runs


def drive_cycle_for_run(scenario_name: str, duration_s: float):
    """The scenario's bundled drive cycle over ``[0, duration_s]`` at 1 s.

    Returns ``(time_s, speed_mps)``; the speed holds its last value past the
    cycle's end, as in the simulator (``Scenario.speed_mps``).
    """
    from ceco_v2x_preview.scenario import load_scenario

    if not (math.isfinite(duration_s) and duration_s >= 1.0):
        raise ValueError(f'duration_s: must be finite and >= 1, got {duration_s!r}')
    sc = load_scenario(scenario_name)
    t = np.arange(0.0, math.floor(duration_s) + 1.0)
    return t, np.asarray(sc.speed_mps(t), dtype=float)


def vehicle_energy_table(
    p_ac_mean_w: Mapping[str, float], time_s, speed_mps, settings: VehicleEnergySettings = VehicleEnergySettings()
) -> list[dict]:
    """Vehicle energy of each strategy and its change against the baseline, for each vehicle.

    ``p_ac_mean_w`` maps strategy -> mean A/C electrical power over the run
    [W]. Returns one row (dict) per (vehicle, strategy) with: ``vehicle,
    powertrain, strategy, p_ac_mean_w, energy_fit_j, energy_direct_j,
    change_fit_pct, change_direct_pct`` (signed change against ``settings.baseline`` as
    measured: negative = less energy; NaN without a baseline), ``paper_change_pct`` (the
    paper's, same sign; NaN where the paper has none),
    ``noise_pct`` (fit residual std / mean energy), ``ac_share_pct`` (share of
    the vehicle energy due to the A/C), ``j_per_j_ac`` (marginal vehicle
    energy per joule of A/C), ``l_per_100km`` (hybrid: fuel litres per
    100 km), ``kwh_per_100km`` (electric car), ``range_km, range_no_ac_km,
    range_lost_km, range_lost_pct`` (electric car), ``trace_miss_max_mps``,
    ``fit_wall_time_s`` (all FASTSim runs of that vehicle), ``n_evals``,
    ``n_soc_unbalanced`` (hybrid runs where FASTSim's SOC balancing did not
    converge and the charge correction alone was used).
    """
    settings.validate()
    if not p_ac_mean_w:
        raise ValueError('p_ac_mean_w: no strategy given')
    for name, p in p_ac_mean_w.items():
        if not (isinstance(p, (int, float, np.floating)) and math.isfinite(p) and p >= 0.0):
            raise ValueError(f'p_ac_mean_w[{name!r}]: must be finite and >= 0 W, got {p!r}')
    t, v = _check_cycle(time_s, speed_mps)
    duration_s = float(t[-1] - t[0])
    p_vals = np.array([float(p) for p in p_ac_mean_w.values()])
    lo = max(0.0, float(p_vals.min()) - settings.fit_margin_w)
    hi = float(p_vals.max()) + settings.fit_margin_w
    loads = np.linspace(lo, hi, int(settings.fit_points))
    rows = []
    for vehicle in settings.vehicles:
        t0 = time.perf_counter()
        a, b, noise_j, fit_runs = fit_energy_vs_aux(vehicle, t, v, loads)
        zero = simulate_vehicle(vehicle, t, v, 0.0)
        direct = {name: simulate_vehicle(vehicle, t, v, float(p)) for name, p in p_ac_mean_w.items()}
        wall_s = time.perf_counter() - t0
        runs = fit_runs + [zero] + list(direct.values())
        e_fit = {name: a + b * float(p) for name, p in p_ac_mean_w.items()}
        base = settings.baseline
        for name, p in p_ac_mean_w.items():
            run = direct[name]
            row = {
                'vehicle': vehicle,
                'powertrain': run.powertrain,
                'strategy': name,
                'p_ac_mean_w': float(p),
                'energy_fit_j': e_fit[name],
                'energy_direct_j': run.energy_j,
                'change_fit_pct': float('nan'),
                'change_direct_pct': float('nan'),
                'paper_change_pct': PAPER_VEHICLE_CHANGE_PCT.get(name, float('nan'))
                if run.powertrain == 'HEV'
                else float('nan'),
                'noise_pct': 100.0 * noise_j / float(np.mean([r.energy_j for r in fit_runs])),
                'ac_share_pct': 100.0 * b * float(p) / e_fit[name] if e_fit[name] > 0 else float('nan'),
                'j_per_j_ac': b / duration_s if duration_s > 0 else float('nan'),
                'distance_km': run.distance_m / 1e3,
                'l_per_100km': float('nan'),
                'kwh_per_100km': float('nan'),
                'range_km': float('nan'),
                'range_no_ac_km': float('nan'),
                'range_lost_km': float('nan'),
                'range_lost_pct': float('nan'),
                'trace_miss_max_mps': max(r.trace_miss_max_mps for r in runs),
                'fit_wall_time_s': wall_s,
                'n_evals': len(runs),
                'n_soc_unbalanced': sum(r.soc_balance == 'corrected' for r in runs),
            }
            if base in e_fit and name != base:
                row['change_fit_pct'] = relative_change_pct(e_fit[name], e_fit[base])
                row['change_direct_pct'] = relative_change_pct(run.energy_j, direct[base].energy_j)
            elif name == base:
                row['change_fit_pct'] = row['change_direct_pct'] = 0.0
            dist_km = run.distance_m / 1e3
            if run.powertrain == 'BEV':
                row['kwh_per_100km'] = e_fit[name] / 3.6e6 / dist_km * 100.0 if dist_km > 0 else float('nan')
                if dist_km > 0 and e_fit[name] > 0 and a > 0:
                    row['range_km'] = run.usable_battery_j / (e_fit[name] / dist_km)
                    row['range_no_ac_km'] = run.usable_battery_j / (a / dist_km)
                    row['range_lost_km'] = row['range_no_ac_km'] - row['range_km']
                    row['range_lost_pct'] = 100.0 * row['range_lost_km'] / row['range_no_ac_km']
            elif dist_km > 0:
                row['l_per_100km'] = e_fit[name] / GASOLINE_J_PER_L / dist_km * 100.0
            rows.append(row)
    return rows
