"""The truck of the synthetic road cycles: longitudinal vehicle, engine curves and the driveline's force relations.

All values are assumed (not from the seed); the list is in the docstring of :mod:`tools.cycles.named`. The gearbox
ratios are the real ones of the parameter set (its kinematics).
"""

from __future__ import annotations

import bisect
import importlib.util
import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from firmware_model.physics.kinematics import GEAR_MIN, GEARS, KinematicTable, Teeth, build_table
from firmware_model.units import RPM_PER_RAD_S

G_M_S2 = 9.81
#: km/h per m/s
KMH_PER_M_S = 3.6

#: tooth numbers used when no parameter loader is available (GRS905, as in the parameter file)
FALLBACK_TEETH = Teeth(
    idle={"LI": 28, "3M": 31, "2M": 35, "1M": 38, "CM": 42, "RM": 42},
    layshaft={"LL": 38, "3L": 34, "2L": 24, "1L": 17, "CL": 13, "RL": 14},
    z_RI=23,
    z_sun=32,
    z_planet=28,
    z_ring=88,
    n_planets=5,
)


@lru_cache(maxsize=1)
def gearbox_kinematics() -> KinematicTable:
    """The GRS905 kinematics: from `firmware_model.parameters` when it exists, else the seed's tooth numbers."""
    if importlib.util.find_spec("firmware_model.parameters") is not None:
        from firmware_model.parameters import load_parameters

        return load_parameters("GRS905").kinematics
    return build_table(FALLBACK_TEETH)


def total_ratios() -> dict[int, float]:
    """Gear -> |input speed / output speed| (inf in neutral)."""
    kin = gearbox_kinematics()
    return {g: abs(float(kin.ratio[g - GEAR_MIN])) for g in GEARS}


@dataclass(frozen=True)
class Vehicle:
    """Longitudinal model of the truck (all values assumed, see the docstring of tools.cycles.named)."""

    mass_kg: float = 40000.0
    crr: float = 0.0055  # rolling resistance coefficient [-]
    cda_m2: float = 5.5
    rho_air_kg_m3: float = 1.2
    wheel_radius_m: float = 0.5
    final_drive: float = 3.07
    driveline_eff: float = 0.95
    engine_inertia_kg_m2: float = 3.5  # engine, flywheel, clutch
    rotating_mass_factor: float = 0.03  # wheels, axles, propeller shaft as a fraction of the mass
    retarder_max_nm: float = 3500.0  # on the output shaft
    retarder_full_rpm: float = 800.0  # output-shaft speed from which the full retarder torque is available


# ----------------------------------------------------------------------------------------------------------------
# engine

#: engine full-load torque (rpm, Nm): 3000 Nm 1000-1300 rpm, ~430 kW at 1900 rpm
FULL_LOAD_RPM = (500.0, 600.0, 800.0, 1000.0, 1300.0, 1900.0, 2100.0, 2300.0)
FULL_LOAD_NM = (900.0, 1400.0, 2400.0, 3000.0, 3000.0, 2150.0, 1750.0, 0.0)
IDLE_RPM = 600.0
MAX_RPM = 2100.0
#: engine torque cap in the gears below 4L and in reverse (propeller-shaft limit, seed 2.4; value assumed)
LOW_GEAR_CAP_NM = 2700.0


def engine_max_torque_nm(rpm: float, gear: int) -> float:
    """Full-load torque at `rpm`, capped in the gears below 4L."""
    x = min(max(rpm, FULL_LOAD_RPM[0]), FULL_LOAD_RPM[-1])
    k = min(bisect.bisect_right(FULL_LOAD_RPM, x), len(FULL_LOAD_RPM) - 1)
    x0, x1, y0, y1 = FULL_LOAD_RPM[k - 1], FULL_LOAD_RPM[k], FULL_LOAD_NM[k - 1], FULL_LOAD_NM[k]
    t = y0 + (y1 - y0) * (x - x0) / (x1 - x0)
    if gear < 9:
        t = min(t, LOW_GEAR_CAP_NM)
    return t


def engine_min_torque_nm(rpm: float) -> float:
    """Friction plus engine brake (exhaust brake / compression release): -150 Nm at idle, -600 Nm at 2100 rpm."""
    return -(150.0 + 450.0 * min(max((rpm - IDLE_RPM) / (MAX_RPM - IDLE_RPM), 0.0), 1.0))


# ----------------------------------------------------------------------------------------------------------------
# driveline: engine torque <-> wheel force, engine speed <-> vehicle speed, driving resistance


@dataclass(frozen=True)
class Drivetrain:
    """The force and speed relations of `vehicle` through the gearbox's total ratios (gear -> ratio)."""

    vehicle: Vehicle
    ratio: dict

    @classmethod
    def of(cls, vehicle: Vehicle) -> Drivetrain:
        return cls(vehicle, total_ratios())

    def sync_rpm(self, gear: int, v_m_s: float) -> float:
        """Engine speed at vehicle speed `v_m_s` in `gear` (clutch closed)."""
        veh = self.vehicle
        return v_m_s / veh.wheel_radius_m * veh.final_drive * self.ratio[gear] * RPM_PER_RAD_S

    def output_shaft_rpm(self, v_m_s: float) -> float:
        veh = self.vehicle
        return v_m_s / veh.wheel_radius_m * veh.final_drive * RPM_PER_RAD_S

    def retarder_available_nm(self, v_m_s: float) -> float:
        """Retarder torque available on the output shaft (full from retarder_full_rpm, proportional below)."""
        veh = self.vehicle
        return veh.retarder_max_nm * min(1.0, self.output_shaft_rpm(v_m_s) / veh.retarder_full_rpm)

    def road_force_n(self, v_m_s: float, grade: float, mass_kg: float) -> float:
        """Driving resistance: rolling, grade (rise/run) and aerodynamic drag."""
        veh = self.vehicle
        c = 1.0 / math.sqrt(1.0 + grade * grade)
        return mass_kg * G_M_S2 * (veh.crr * c + grade * c) + 0.5 * veh.rho_air_kg_m3 * veh.cda_m2 * v_m_s * v_m_s

    def equivalent_mass_kg(self, gear: int | None, mass_kg: float) -> float:
        """Mass plus rotating masses, plus the engine's inertia through the ratio when a gear is engaged."""
        veh = self.vehicle
        m = mass_kg * (1.0 + veh.rotating_mass_factor)
        if gear:
            i = self.ratio[gear] * veh.final_drive / veh.wheel_radius_m
            m += veh.engine_inertia_kg_m2 * i * i
        return m

    def torque_for_nm(self, force_n: float, gear: int) -> float:
        """Engine torque that puts `force_n` on the wheels in `gear` (losses against the flow of power)."""
        veh = self.vehicle
        i = self.ratio[gear] * veh.final_drive / veh.wheel_radius_m
        return force_n / (i * veh.driveline_eff) if force_n >= 0 else force_n * veh.driveline_eff / i

    def wheel_force_n(self, torque_nm: float, gear: int) -> float:
        """Force on the wheels of engine torque `torque_nm` in `gear`."""
        veh = self.vehicle
        i = self.ratio[gear] * veh.final_drive / veh.wheel_radius_m
        return torque_nm * i * veh.driveline_eff if torque_nm >= 0 else torque_nm * i / veh.driveline_eff

    def start_gear_for(self, grade: float, mass_kg: float) -> int:
        """Highest of 1L..2H that pulls away at 0.4 m/s2 on half the capped torque (crawler when none does)."""
        need = self.road_force_n(0.0, grade, mass_kg) + mass_kg * 0.4
        best = 1
        for g in (3, 4, 5, 6):
            if self.wheel_force_n(0.5 * LOW_GEAR_CAP_NM, g) >= need:
                best = g
        if best == 1 and self.wheel_force_n(0.5 * LOW_GEAR_CAP_NM, 3) < need:
            best = 1 if self.wheel_force_n(0.5 * LOW_GEAR_CAP_NM, 2) < need else 2
        return best


def vehicle_speed_kmh(gear, rpm, vehicle: Vehicle = Vehicle(), ratio: dict | None = None):
    """Vehicle speed [km/h] that engine speed `rpm` implies in `gear` (arrays; 0 in neutral), through `vehicle`'s
    axle and wheel; `ratio`: gear -> |total ratio| of the gearbox (None: the GRS905's, total_ratios)."""
    ratio = total_ratios() if ratio is None else ratio
    rt = np.array([ratio[int(g)] for g in gear])
    # rpm / RPM_PER_RAD_S (not * RAD_S_PER_RPM): the same bits as the cycles always had
    return np.where(
        np.isfinite(rt), rpm / RPM_PER_RAD_S / (rt * vehicle.final_drive) * vehicle.wheel_radius_m * KMH_PER_M_S, 0.0
    )
