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

from firmware_model.components import LAYSHAFT_WHEELS
from firmware_model.description import Description, description_of
from firmware_model.errors import ParameterError
from firmware_model.parameters import Parameters
from firmware_model.physics.losses import ADDENDUM_COEF, DEDENDUM_COEF, mesh_geometry


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
    R_shaft_m: dict  # shaft id -> outer radius [m]
    description: Description | None = None  # the gearbox description it is built from


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


def _wheel_of(p: Parameters, d: Description, w) -> Wheel:
    """A wheel of the description: an idle wheel or an idler on a pin turns on its bore; a wheel fixed to its
    shaft has the shaft's radius inside, one cut into it a fraction (70 %) of its base radius (seed 3.3)."""
    R_in = w.bore_m / 2 if w.mount in ("idle", "pin") else d.shaft(w.shaft).d_out_m / 2
    g = wheel(w.id, w.teeth, w.module_m, w.helix_rad, p["gear.alpha_n"], w.width_m, R_in, w.x_m)
    if w.mount == "cut":
        g = replace(g, R_in=max(p["heat.cut_wheel_inner_frac"] * g.R_b, R_in))
    return g


def _planetary_wheels(p: Parameters, d: Description, wheels: dict) -> None:
    """Each planetary set's sun (on its shaft) and planets (a bore a fraction of their pitch diameter)."""
    an = p["gear.alpha_n"]
    for ps in d.planetary:
        mp, bp, wp, zp = ps.module_m, ps.helix_rad, ps.width_m, ps.z_planet
        R_sun_in = d.shaft(ps.sun_shaft).d_out_m / 2
        wheels[ps.sun] = wheel(ps.sun, ps.z_sun, mp, bp, an, wp, R_sun_in, ps.x_m)
        wheels[ps.planet] = wheel(ps.planet, zp, mp, bp, an, wp, p["planetary.planet_bore_frac"] * mp * zp / 2, ps.x_m)


def _meshes(p: Parameters, d: Description) -> dict:
    """Every mesh of the description at its centre distance (stated, or the standard one), over the narrower of
    its two face widths; a ring gear meshes internally."""
    an = p["gear.alpha_n"]
    size = {w.id: (w.teeth, w.module_m, w.helix_rad, w.width_m) for w in d.wheels}
    for ps in d.planetary:
        size.update({m: (ps.teeth(m), ps.module_m, ps.helix_rad, ps.width_m) for m in (ps.sun, ps.planet, ps.ring)})
    meshes = {}
    for m in d.meshes:
        (z1, m_n, beta, b1), (z2, _, _, b2) = size[m.wheels[0]], size[m.wheels[1]]
        try:
            meshes[m.id] = mesh_geometry(z1, z2, m_n, an, beta, m.centre_distance_m, min(b1, b2), internal=m.internal)
        except ParameterError as exc:  # the sentence names the mesh, its wheels and their teeth
            raise ParameterError(f"mesh {m.id} ({m.wheels[0]} z {z1}, {m.wheels[1]} z {z2}): {exc}") from None
    return meshes


def oil_level_drop_m(p: Parameters) -> float:
    """How far the oil surface lies below its nominal level: the volume deficit over the free surface [m]."""
    vol = p.get("oil.volume")
    if vol is None or p.get("oil.nominal_volume", vol) <= vol:
        return 0.0  # no deficit (a description's own volume, without the parameter, is its nominal one)
    return (p["oil.nominal_volume"] - vol) / p["oil.free_surface_area"]


#: the parameters the GRS905's immersion depths take
IMMERSION_KEYS = ("shaft.LS.x_BLF", "oil.level_below_ls_axis", "oil.inclination", "gear.R.idler_immersion")


def _immersion(p: Parameters, wheels: dict, level_drop_m: float) -> dict:
    """Immersion depth of the layshaft wheels: the oil surface lies below the layshaft axis at BLF and rises toward
    the rear (5 deg tilt, seed 2.2); the reverse idler has its own depth. Another gearbox (without the GRS905's
    layshaft wheels and oil level parameters) has none computed: the network names a dipping wheel it lacks."""
    if not set(LAYSHAFT_WHEELS) | {"RI"} <= set(wheels) or not set(IMMERSION_KEYS) <= set(p.values):
        return {}
    x_blf = p["shaft.LS.x_BLF"]
    immersion = {}
    for w in LAYSHAFT_WHEELS:
        d_below = p["oil.level_below_ls_axis"] + level_drop_m - (wheels[w].x - x_blf) * math.tan(p["oil.inclination"])
        immersion[w] = float(np.clip(wheels[w].R_a - d_below, 0.0, 2 * wheels[w].R_a))
    immersion["RI"] = max(0.0, p["gear.R.idler_immersion"] - level_drop_m)
    return immersion


def build_geometry(p: Parameters) -> Geometry:
    """Every derived geometric quantity of the parameter set."""
    d = description_of(p)
    wheels = {w.id: _wheel_of(p, d, w) for w in d.wheels}
    _planetary_wheels(p, d, wheels)
    meshes = _meshes(p, d)
    drop = oil_level_drop_m(p)
    R_shaft = {s.id: s.d_out_m / 2 for s in d.shafts}
    immersion = _immersion(p, wheels, drop)
    for w in d.wheels:  # a wheel whose description states its immersed share of its tip diameter
        if w.id not in immersion and w.immersion is not None:
            immersion[w.id] = w.immersion * 2 * wheels[w.id].R_a
    return Geometry(wheels, meshes, immersion, drop, R_shaft, d)
