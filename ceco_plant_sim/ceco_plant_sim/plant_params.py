"""Parameters of the cabin + A/C plant (a mid-size car), as one frozen dataclass.

Every field has its unit in the name and a one-line docstring; the values,
their sources and the reasoning behind them are tabulated in
``docs/plant.md`` (section "Parameters"). Change values with
``dataclasses.replace(PlantParams(), field=value)``; ``validate()`` is called
by :class:`ceco_plant_sim.plant.CabinPlant`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from ceco_core.air_quality import CO2_AMB_PPM_DEFAULT, RECIRC_SHARE_DEFAULT
from ceco_core.cabin_comfort import GLAZING_TAU, SHELL_U_IN_WM2K
from ceco_core.psychro import CP_DRY_AIR_JPKGK, CP_VAPOUR_JPKGK, P_ATM_PA

__all__ = ["PlantParams"]


@dataclass(frozen=True)
class PlantParams:
    """Physical parameters of the cabin + A/C plant (defaults: mid-size sedan, R-1234yf electric A/C)."""

    # --- integration -------------------------------------------------------
    substep_s: float = 0.5
    """Largest RK4 sub-step [s]; a step dt_s is split into ceil(dt_s/substep_s) equal sub-steps."""
    cycle_tol_k: float = 1e-6
    """Newton tolerance of the refrigerant loop (update size) [K]."""
    cycle_max_iter: int = 30
    """Iteration cap of the refrigerant loop Newton solve [-] (RuntimeError beyond)."""

    # --- air ---------------------------------------------------------------
    p_atm_pa: float = P_ATM_PA
    """Atmospheric pressure [Pa] (standard atmosphere, sea level)."""
    cp_air_jpkgk: float = CP_DRY_AIR_JPKGK
    """Specific heat of dry air [J/(kg K)] (ASHRAE Fundamentals 2017, ch. 1: 1006; ``psychro.CP_DRY_AIR_JPKGK``)."""
    cp_vap_jpkgk: float = CP_VAPOUR_JPKGK
    """Specific heat of water vapour [J/(kg K)] (ASHRAE Fundamentals 2017, ch. 1: 1860; ``psychro.CP_VAPOUR_JPKGK``)."""
    h_fg_jpkg: float = 2.45e6
    """Latent heat of condensation of water near 20 degC [J/kg] (IAPWS; ASHRAE Fundamentals)."""
    rho_air_kgm3: float = 1.16
    """Air density for volumes and fan volume flow [kg/m3] (30 degC, 1 atm)."""

    # --- cabin air ---------------------------------------------------------
    cabin_volume_m3: float = 3.0
    """Cabin air volume [m3] (mid-size sedan, 2.8-3.2 m3)."""
    recirc_fraction: float = RECIRC_SHARE_DEFAULT
    """Recirculated share of the blower flow where no controller commands the door, and the door's position at
    key-on [-] (0 fresh air .. 1 full recirculation)."""
    door_travel_s: float = 5.0
    """Full-stroke travel time of the fresh/recirculation door actuator [s] (0 -> 1 at the rate limit)."""
    door_tau_s: float = 0.5
    """Time constant of the door servo's position loop near its target [s] (proportional zone of the rate limit)."""
    infiltration_0_kgps: float = 0.0015
    """Leakage air exchange at standstill [kg/s] (~1.5 air changes per hour)."""
    infiltration_per_mps_kgps: float = 0.0002
    """Growth of leakage air exchange with vehicle speed [kg/s per m/s]."""

    # --- occupants ---------------------------------------------------------
    n_occupants: int = 1
    """Number of occupants [-] (SC03: the driver)."""
    occ_sensible_w: float = 75.0
    """Sensible heat gain per occupant [W] (ASHRAE Fundamentals 2017 ch. 18 tab. 1, office work)."""
    occ_latent_w: float = 55.0
    """Latent heat gain per occupant [W] (same source)."""
    fog_removal_tau_s: float = 60.0
    """Time constant with which water condensed in the cabin air (beyond saturation: fog) deposits on the cabin
    surfaces [s] (judgement, docs/plant.md "cabin humidity"; rh, dew point and comfort do not depend on it)."""
    occ_met: float = 1.2
    """Metabolic rate of each occupant for the CO2 they exhale [met] (ISO 7730 sedentary; driving 1.0-2.0)."""
    occ_body_area_m2: float = 1.8
    """DuBois body surface area of each occupant [m2] (70 kg, 1.73 m adult)."""
    occ_rq: float = 0.83
    """Respiratory quotient of the occupants [-] (CO2 exhaled per O2 consumed, sedentary adults)."""
    co2_amb_ppm: float = CO2_AMB_PPM_DEFAULT
    """Ambient CO2 [ppm] (mole fraction in dry air; set from the scenario)."""

    # --- interior mass (seats, dashboard, trim) ----------------------------
    c_int_jpk: float = 90000.0
    """Effective heat capacity of the interior mass [J/K] (~70 kg of seats, dashboard, carpet, trim, ~1300 J/(kg K))."""
    a_int_m2: float = 14.0
    """Convective area of the interior mass [m2] (seats both faces, dashboard, carpet, parcel shelf)."""
    h_in_natural_wm2k: float = 3.0
    """Inside convection coefficient without blower flow [W/(m2 K)] (natural convection)."""
    h_in_forced_wm2k: float = 10.0
    """Inside convection coefficient at the reference blower flow [W/(m2 K)]."""
    mdot_bl_ref_kgps: float = 0.17
    """Reference blower flow for the inside convection and the evaporator UA [kg/s]."""

    # --- shell (roof, doors, pillars, floor) -------------------------------
    c_shell_jpk: float = 30000.0
    """Heat capacity of the shell [J/K] (~30 kg steel at 460 J/(kg K) + ~12 kg trim)."""
    a_shell_m2: float = 9.0
    """Shell area (inside = outside) [m2] (roof 2, doors 3.5, pillars 0.5, floor/firewall 3)."""
    a_shell_sun_m2: float = 2.5
    """Shell area projected normal to the sun [m2] (roof + part of the sides)."""
    alpha_shell: float = 0.6
    """Solar absorptance of the painted shell [-] (mid-tone paint 0.5-0.7)."""
    u_shell_in_wm2k: float = SHELL_U_IN_WM2K
    """Conductance shell sheet -> cabin air through trim and insulation, incl. inner film [W/(m2 K)]."""

    # --- glazing -----------------------------------------------------------
    c_glass_jpk: float = 34000.0
    """Heat capacity of the glazing [J/K] (3.6 m2 x 4.5 mm x 2500 kg/m3 x 840 J/(kg K))."""
    a_glass_m2: float = 3.6
    """Glazing area [m2] (windshield 1.1, backlight 0.7, side windows 1.8)."""
    a_glass_sun_m2: float = 1.6
    """Glazing area projected normal to the sun [m2]."""
    tau_glass: float = GLAZING_TAU
    """Solar transmittance of the glazing [-], 0.45 (the one value shared with the comfort model)."""
    alpha_glass: float = 0.30
    """Solar absorptance of the glazing [-]."""

    # --- inside long-wave radiation (linearised) ---------------------------
    g_rad_int_shell_wpk: float = 25.0
    """Radiative conductance interior mass <-> shell [W/K] (h_r ~5.5 W/(m2 K) x ~4.5 m2)."""
    g_rad_int_glass_wpk: float = 15.0
    """Radiative conductance interior mass <-> glazing [W/K] (h_r ~5.5 W/(m2 K) x ~2.7 m2)."""

    # --- outside convection h = h_nat + c V^0.8 ----------------------------
    h_out_natural_wm2k: float = 5.0
    """Outside convection coefficient at standstill [W/(m2 K)] (natural convection + light wind)."""
    h_out_speed_coef: float = 5.1
    """Forced-convection coefficient c in c*V^0.8 [W/(m2 K) / (m/s)^0.8] (turbulent flat plate, L = 2 m)."""

    # --- blower ------------------------------------------------------------
    dp_blower_ref_pa: float = 700.0
    """HVAC module + duct pressure drop at the reference blower flow [Pa] (quadratic system curve)."""
    eta_blower: float = 0.33
    """Blower wheel x motor x controller efficiency [-]."""
    p_blower_fixed_w: float = 15.0
    """Speed-independent blower losses while running (motor friction, PWM controller) [W]."""
    ua_duct_wpk: float = 8.0
    """Conductance of the HVAC case and duct walls to the instrument panel (interior mass) [W/K]."""
    c_duct_jpk: float = 7000.0
    """Heat capacity of the HVAC case, doors, ducts and outlets downstream of the evaporator [J/K]."""
    ua_duct_air_ref_wpk: float = 35.0
    """Supply air -> case and duct wall conductance at the reference blower flow [W/K] (scales with mdot^0.8)."""

    # --- evaporator --------------------------------------------------------
    c_evap_jpk: float = 2500.0
    """Heat capacity of evaporator core + held refrigerant and water [J/K]."""
    ua_evap_air_ref_wpk: float = 430.0
    """Air-side UA of the evaporator at the reference blower flow [W/K] (NTU 2.5 -> bypass factor 0.08)."""
    ua_evap_air_exp: float = 0.8
    """Exponent of air-side UA on air flow [-] (Colburn j ~ Re^-0.2 => h ~ mdot^0.8)."""
    ua_evap_ref_wpk: float = 1500.0
    """Wall-to-refrigerant conductance (flow boiling) [W/K]."""

    # --- compressor (electric scroll) --------------------------------------
    refrigerant: str = "R1234yf"
    """CoolProp name of the refrigerant."""
    displacement_m3: float = 33.0e-6
    """Scroll displacement [m3/rev] (33 cm3 class, mid-size electric A/C)."""
    comp_speed_min_rpm: float = 800.0
    """Minimum continuous compressor speed [rpm]; below, the ECU cycles at this speed (duty-averaged)."""
    comp_speed_max_rpm: float = 8600.0
    """Maximum compressor speed [rpm]."""
    eta_vol_0: float = 0.95
    """Volumetric efficiency extrapolated to pressure ratio 1 [-]."""
    eta_vol_slope: float = 0.025
    """Volumetric efficiency loss per unit pressure ratio [-]."""
    eta_is_max: float = 0.70
    """Peak isentropic efficiency of the scroll [-]."""
    eta_is_curv: float = 0.01
    """Isentropic efficiency loss per (pr - pr_opt)^2 [-]."""
    pr_opt: float = 3.0
    """Pressure ratio of peak isentropic efficiency [-]."""
    p_comp_max_w: float = 3500.0
    """Electrical power limit of the compressor inverter [W]; the ECU lowers the speed to respect it."""
    eta_motor_inverter: float = 0.90
    """Motor x inverter efficiency [-] (PMSM + SiC/IGBT inverter)."""
    superheat_k: float = 5.0
    """Evaporator-exit superheat held by the TXV [K]."""
    subcool_k: float = 5.0
    """Condenser-exit subcooling [K]."""
    pr_min: float = 2.0
    """Minimum pressure ratio held by head-pressure control (condenser air throttled) at low ambient [-]."""
    te_mop_c: float = 12.0
    """MOP cap of the evaporating temperature by the expansion valve [degC]."""
    comp_kp_rpm_per_k: float = 600.0
    """Proportional gain of the A/C ECU's evaporator-wall PI [rpm/K]."""
    comp_ki_rpm_per_ks: float = 60.0
    """Integral gain of the A/C ECU's evaporator-wall PI [rpm/(K s)]."""

    # --- condenser ---------------------------------------------------------
    a_cond_face_m2: float = 0.30
    """Condenser frontal (face) area [m2]."""
    v_face_fan_mps: float = 1.8
    """Face velocity from the condenser fan alone at standstill [m/s]."""
    ram_face_ratio: float = 0.17
    """Face velocity from ram air per unit vehicle speed [-] (grille/bumper blockage, radiator in series)."""
    ua_cond_ref_wpk: float = 700.0
    """Air-side UA of the condenser at the reference face velocity [W/K]."""
    v_face_ref_mps: float = 3.0
    """Reference face velocity of ua_cond_ref_wpk [m/s]."""
    ua_cond_exp: float = 0.6
    """Exponent of condenser UA on face velocity [-] (louvered fins, j ~ Re^-0.4)."""
    p_cond_fan_w: float = 150.0
    """Condenser fan electrical power while the compressor runs [W]."""

    def validate(self) -> PlantParams:
        """Check every field; raise ValueError naming the first bad field. Returns self."""
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "refrigerant":
                if not isinstance(v, str) or not v:
                    raise ValueError(f"refrigerant: must be a CoolProp fluid name, got {v!r}")
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ValueError(f"{f.name}: must be a number, got {v!r}")
            if not math.isfinite(v):
                raise ValueError(f"{f.name}: must be finite, got {v!r}")
        nonneg = {
            "infiltration_0_kgps",
            "infiltration_per_mps_kgps",
            "n_occupants",
            "occ_sensible_w",
            "occ_latent_w",
            "g_rad_int_shell_wpk",
            "g_rad_int_glass_wpk",
            "h_out_speed_coef",
            "ua_duct_wpk",
            "p_blower_fixed_w",
            "a_shell_sun_m2",
            "a_glass_sun_m2",
            "p_cond_fan_w",
            "eta_vol_slope",
            "eta_is_curv",
            "comp_speed_min_rpm",
            "superheat_k",
            "subcool_k",
            "ram_face_ratio",
        }
        fractions = {"recirc_fraction", "alpha_shell", "tau_glass", "alpha_glass"}
        # n_occupants >= 0 above; ambient CO2 and the occupants' metabolism checked below
        efficiencies = {"eta_blower", "eta_vol_0", "eta_is_max", "eta_motor_inverter"}
        free = {"te_mop_c"}
        for f in fields(self):
            name = f.name
            if name == "refrigerant" or name in free:
                continue
            v = getattr(self, name)
            if name in fractions:
                if not 0.0 <= v <= 1.0:
                    raise ValueError(f"{name}: must be in [0, 1], got {v}")
            elif name in efficiencies:
                if not 0.0 < v <= 1.0:
                    raise ValueError(f"{name}: must be in (0, 1], got {v}")
            elif name in nonneg:
                if v < 0.0:
                    raise ValueError(f"{name}: must be >= 0, got {v}")
            elif v <= 0.0:
                raise ValueError(f"{name}: must be > 0, got {v}")
        if self.tau_glass + self.alpha_glass > 1.0:
            raise ValueError("alpha_glass: tau_glass + alpha_glass must be <= 1")
        if self.comp_speed_min_rpm >= self.comp_speed_max_rpm:
            raise ValueError("comp_speed_min_rpm: must be below comp_speed_max_rpm")
        if not -20.0 <= self.te_mop_c <= 25.0:
            raise ValueError(f"te_mop_c: must be in [-20, 25] degC, got {self.te_mop_c}")
        if self.pr_min < 1.0:
            raise ValueError(f"pr_min: must be >= 1, got {self.pr_min}")
        if self.substep_s > 2.0:
            raise ValueError(f"substep_s: must be <= 2 s for the explicit RK4 scheme, got {self.substep_s}")
        if int(self.cycle_max_iter) != self.cycle_max_iter:
            raise ValueError(f"cycle_max_iter: must be an integer, got {self.cycle_max_iter}")
        if int(self.n_occupants) != self.n_occupants or self.n_occupants > 9:
            raise ValueError(f"n_occupants: must be an integer in [0, 9], got {self.n_occupants}")
        if not 300.0 <= self.co2_amb_ppm <= 5000.0:
            raise ValueError(f"co2_amb_ppm: must be in [300, 5000] ppm, got {self.co2_amb_ppm}")
        if not 0.7 <= self.occ_rq <= 1.0:
            raise ValueError(f"occ_rq: must be in [0.7, 1.0] (fat .. carbohydrate oxidation), got {self.occ_rq}")
        if not 0.7 <= self.occ_met <= 4.0:
            raise ValueError(f"occ_met: must be in [0.7, 4] met, got {self.occ_met}")
        return self
