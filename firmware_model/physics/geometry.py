"""Geometry of the gearbox derived from the parameter set: wheels, meshes, shaft radii and the oil level (seed
sections 2.2, 3.1, 3.3).

The thermal network (:mod:`firmware_model.network`) and the loss model
(:mod:`firmware_model.physics.gearbox_losses`) are both built from this one description, so the network depends on
the physics and never the other way round. Lengths in m, angles in rad.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from firmware_model.components import LAYSHAFT_WHEELS, PAIRS
from firmware_model.parameters import Parameters
from firmware_model.physics.losses import ADDENDUM_COEF, DEDENDUM_COEF, mesh_geometry

#: the shaft each shaft bearing carries (input, layshaft, main, output shaft)
SHAFT_OF_BEARING = {"BIF": "IS", "BLF": "LS", "BLR": "LS", "BIM": "MS", "BMR": "MS", "BO": "OS"}
#: the housing each shaft bearing sits in (BIM, the pilot bearing, sits inside the input shaft)
HOUSING_OF_BEARING = {"BIF": "H1", "BLF": "H1", "BLR": "H2", "BMR": "H2", "BO": "H3"}
#: layshaft wheels cut into the layshaft (no bore, no web: seed 2.2, 3.3)
CUT_WHEELS = ("1L", "CL", "RL")


@dataclass(frozen=True)
class Wheel:
    """Geometry of one gear wheel (radii in m)."""

    name: str
    z: int
    m_n: float
    beta: float
    width: float
    R_p: float
    R_a: float
    R_f: float
    R_b: float
    R_in: float  # inner radius (bore, or a fraction of the base radius for wheels cut into the layshaft)
    h_t: float
    x: float  # axial position


@dataclass(frozen=True)
class Geometry:
    """Every derived geometric quantity the network and the loss model need."""

    wheels: dict  # wheel id -> Wheel (idle, layshaft, reverse idler RI, sun PS, planet PP)
    meshes: dict  # mesh id (kinematics.MESHES) -> losses.GearMesh
    immersion_m: dict  # layshaft wheel or RI -> immersion depth of its tip circle [m]
    level_drop_m: float  # oil level below nominal (oil_level_low effect) [m]
    R_shaft_m: dict  # shaft (IS, LS, MS, OS) -> outer radius [m]


def wheel(name: str, z: int, m_n: float, beta: float, alpha_n: float, width: float, R_in: float, x: float) -> Wheel:
    """A wheel of the ISO 53 basic rack without profile shift: tip and root one addendum / dedendum from the pitch
    circle, base circle from the transverse pressure angle."""
    R_p = m_n * z / (2.0 * math.cos(beta))
    alpha_t = math.atan(math.tan(alpha_n) / math.cos(beta))
    return Wheel(
        name,
        z,
        m_n,
        beta,
        width,
        R_p,
        R_p + ADDENDUM_COEF * m_n,
        R_p - DEDENDUM_COEF * m_n,
        R_p * math.cos(alpha_t),
        R_in,
        (ADDENDUM_COEF + DEDENDUM_COEF) * m_n,
        x,
    )


def _pair_wheels(p: Parameters, wheels: dict, meshes: dict) -> None:
    """The six layshaft pairs: idle wheel (input / main shaft) and layshaft wheel, and the five forward meshes."""
    an, a = p["gear.alpha_n"], p["gear.center_distance"]
    R_ls = p["shaft.LS.d_out"] / 2
    for pair, (iw, lw) in PAIRS.items():
        g = f"gear.{pair}"
        m_n, beta = p[f"{g}.m_n"], p[f"{g}.beta"]
        x = p[f"wheel.x_{iw}"]
        bore = (p["wheel.bore_LI"] if iw == "LI" else p["wheel.bore_main"]) / 2
        wheels[iw] = wheel(iw, int(p[f"{g}.z1"]), m_n, beta, an, p[f"{g}.width1"], bore, x)
        lw_g = wheel(lw, int(p[f"{g}.z2"]), m_n, beta, an, p[f"{g}.width2"], R_ls, x)
        if lw in CUT_WHEELS:
            # cut into the layshaft: inner diameter a fraction (70 %) of the base diameter (seed 3.3)
            lw_g = replace(lw_g, R_in=max(p["heat.cut_wheel_inner_frac"] * lw_g.R_b, R_ls))
        wheels[lw] = lw_g
        if pair != "R":
            meshes[pair] = mesh_geometry(
                int(p[f"{g}.z1"]), int(p[f"{g}.z2"]), m_n, an, beta, a, min(p[f"{g}.width1"], p[f"{g}.width2"])
            )


def _reverse_wheels(p: Parameters, wheels: dict, meshes: dict) -> None:
    """Reverse: RL (layshaft) drives the idler RI, RI drives RM; standard centre distances (no profile shift)."""
    an = p["gear.alpha_n"]
    m_r, b_r = p["gear.R.m_n"], p["gear.R.beta"]
    zRL, zRI, zRM = int(p["gear.R.z2"]), int(p["gear.R.z_idler"]), int(p["gear.R.z1"])
    wr = min(p["gear.R.width1"], p["gear.R.width2"], p["gear.R.width_idler"])
    meshes["R"] = mesh_geometry(zRL, zRI, m_r, an, b_r, m_r * (zRL + zRI) / (2 * math.cos(b_r)), wr)
    meshes["RI"] = mesh_geometry(zRI, zRM, m_r, an, b_r, m_r * (zRI + zRM) / (2 * math.cos(b_r)), wr)
    wheels["RI"] = wheel("RI", zRI, m_r, b_r, an, p["gear.R.width_idler"], p["wheel.bore_RI"] / 2, p["wheel.x_RM"])


def _planetary_wheels(p: Parameters, wheels: dict, meshes: dict) -> None:
    """Planetary: the sun drives the planets; a planet drives the (fixed) ring relative to the carrier."""
    an = p["gear.alpha_n"]
    zs, zp, zr = int(p["planetary.z_sun"]), int(p["planetary.z_planet"]), int(p["planetary.z_ring"])
    mp, bp, wp = p["planetary.m_n"], p["planetary.beta"], p["planetary.width"]
    a_p = mp * (zs + zp) / (2 * math.cos(bp))
    meshes["PSP"] = mesh_geometry(zs, zp, mp, an, bp, a_p, wp)
    meshes["PPR"] = mesh_geometry(zp, zr, mp, an, bp, a_p, wp, internal=True)
    wheels["PS"] = wheel("PS", zs, mp, bp, an, wp, p["shaft.MS.d_out"] / 2, p["shaft.MS.x_PS"])
    wheels["PP"] = wheel("PP", zp, mp, bp, an, wp, p["planetary.planet_bore_frac"] * mp * zp / 2, p["shaft.MS.x_PS"])


def oil_level_drop_m(p: Parameters) -> float:
    """How far the oil surface lies below its nominal level: the volume deficit over the free surface [m]."""
    vol = p["oil.volume"]
    return max(0.0, (p.get("oil.nominal_volume", vol) - vol)) / p["oil.free_surface_area"]


def _immersion(p: Parameters, wheels: dict, level_drop_m: float) -> dict:
    """Immersion depth of the layshaft wheels: the oil surface lies below the layshaft axis at BLF and rises toward
    the rear (5 deg tilt, seed 2.2); the reverse idler has its own depth."""
    x_blf = p["shaft.LS.x_BLF"]
    immersion = {}
    for w in LAYSHAFT_WHEELS:
        d_below = p["oil.level_below_ls_axis"] + level_drop_m - (wheels[w].x - x_blf) * math.tan(p["oil.inclination"])
        immersion[w] = float(np.clip(wheels[w].R_a - d_below, 0.0, 2 * wheels[w].R_a))
    immersion["RI"] = max(0.0, p["gear.R.idler_immersion"] - level_drop_m)
    return immersion


def build_geometry(p: Parameters) -> Geometry:
    """Every derived geometric quantity of the parameter set."""
    wheels: dict = {}
    meshes: dict = {}
    _pair_wheels(p, wheels, meshes)
    _reverse_wheels(p, wheels, meshes)
    _planetary_wheels(p, wheels, meshes)
    drop = oil_level_drop_m(p)
    R_shaft = {s: p[f"shaft.{s}.d_out"] / 2 for s in ("IS", "LS", "MS", "OS")}
    return Geometry(wheels, meshes, _immersion(p, wheels, drop), drop, R_shaft)
