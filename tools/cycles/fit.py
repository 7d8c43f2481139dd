"""The named cycles on a vehicle gearbox outside the GRS905 family: its own gears, drive limits and boundaries.

The named cycles are the GRS905's (its gear numbers -2..14, its engine, its thermal boundaries of seed Table 11). A
vehicle gearbox whose gear numbers are the GRS905's (the GRS905 family: GRS905, GRSO905) runs them as they are. Any
other vehicle gearbox (a user's 6-speed truck box) gets them fitted (:func:`fit_cycle`, docs/cycles.md "Another
gearbox"):

- each GRS905 gear becomes the gearbox's gear whose total ratio is nearest in log (reverse onto its reverse gears,
  where it has any; neutral onto its neutral);
- driving torque is scaled by its max_torque / the GRS905's, braking torque by its min_torque / the GRS905's, the
  retarder torque (on the output shaft) as driving torque: the same share of the rating;
- engine speed is kept (the engine is a truck's whatever the gearbox), compressed only where the cycle's peak exceeds
  the gearbox's max_speed;
- the vehicle speed is the one its own gear's ratio implies, through the same axle and wheel as the GRS905 cycles'
  truck (tools.cycles.vehicle.Vehicle: final drive 3.07, wheel radius 0.5 m; assumed);
- the thermal boundaries are its description's own (every ``bc_<id>_c`` at its description's temperature; the
  ambient its ``ambient`` boundary's): the GRS905's Table 11 values are the GRS905 test rig's and truck's, not its.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from firmware_model.errors import InputError
from firmware_model.physics.kinematics import GEARS
from tools.cycles.vehicle import total_ratios, vehicle_speed_kmh
from tools.runtable import RunTable

#: the GRS905's gear numbers (seed Table 1): a gearbox with these is of its family and runs the cycles as they are
GRS905_GEAR_NUMBERS = frozenset(GEARS)


def own_gears(description) -> bool:
    """True for a vehicle gearbox outside the GRS905 family (its gear numbers are not the GRS905's)."""
    if description is None or description.drive.kind != "vehicle":
        return False
    return {g.number for g in description.gears} != GRS905_GEAR_NUMBERS


@lru_cache(maxsize=1)
def _grs905_drive():
    from firmware_model.description import description_of
    from firmware_model.parameters import load_parameters

    return description_of(load_parameters("GRS905")).drive


def gear_ratios(description) -> dict[int, float]:
    """Gear number -> |input speed / output speed| of the description (inf in neutral)."""
    return {g.number: abs(float(g.ratio)) for g in description.gears}


def gear_list(description) -> str:
    return ", ".join(f"{g.number} ({g.name})" for g in sorted(description.gears, key=lambda g: g.number))


def nearest_gear(description, ratio: float, reverse: bool = False) -> int:
    """The description's gear whose |ratio| is nearest ``ratio`` in log: among its reverse gears for ``reverse``
    (its forward gears where it has none: the box turns and carries the load the same), else its forward gears."""
    fwd = [g for g in description.gears if g.number > 0 and math.isfinite(g.ratio)]
    rev = [g for g in description.gears if g.number < 0 and math.isfinite(g.ratio)]
    pool = (rev or fwd) if reverse else fwd
    if not pool:
        raise InputError(f"gearbox {description.name} has no forward gear to drive a named cycle in")
    return min(pool, key=lambda g: (abs(math.log(abs(g.ratio) / ratio)), g.number)).number


def gear_map(description) -> dict[int, int]:
    """GRS905 gear number -> the description's gear number (module doc)."""
    grs = total_ratios()
    neutral = [g.number for g in description.gears if not math.isfinite(g.ratio)]
    out = {}
    for n, r in grs.items():
        if n == 0:
            out[n] = neutral[0] if neutral else None
        else:
            out[n] = nearest_gear(description, r, reverse=n < 0)
    return out


def torque_factors(description) -> tuple[float, float]:
    """(driving, braking) torque scale: the description's max_torque and min_torque over the GRS905's."""
    grs, d = _grs905_drive(), description.drive
    braking = d.min_torque_nm / grs.min_torque_nm if grs.min_torque_nm < 0 else 0.0
    return d.max_torque_nm / grs.max_torque_nm, braking


def boundary_columns(description, n: int) -> dict:
    """The description's boundary temperatures as run-table columns (constant, ``n`` rows): ``ambient_temp_c`` and
    ``coolant_temp_c`` for its ambient and coolant boundaries, ``bc_<id>_c`` for the others."""
    cols = {}
    for b in description.boundaries:
        name = f"{b.id}_temp_c" if b.id in ("ambient", "coolant") else f"bc_{b.id}_c"
        cols[name] = np.full(n, float(b.temperature_c))
    return cols


def with_own_boundaries(cols: dict, description) -> dict:
    """``cols`` with the GRS905's boundary columns replaced by the description's own (:func:`boundary_columns`); a
    column the description has no boundary for (the coolant of a box without a cooler) keeps the cycle's."""
    n = cols["time_s"].size
    out = {c: v for c, v in cols.items() if not c.startswith("bc_")}
    out.update(boundary_columns(description, n))
    return out


def fit_cycle(table: RunTable, description) -> RunTable:
    """A named cycle of the GRS905 fitted to ``description``'s gears, drive limits and boundaries (module doc)."""
    gmap = gear_map(description)
    gear = np.asarray(table["gear"], dtype=float)
    if gmap[0] is None and np.any(gear == 0):
        raise InputError(
            f"cycle {table.meta.get('cycle')} stands in neutral, and gearbox {description.name} has no neutral "
            f"(a gear of infinite ratio) to stand in; its gears: {gear_list(description)}"
        )
    own = np.array([gmap[int(g)] for g in gear], dtype=float)
    drive_f, brake_f = torque_factors(description)
    tq = np.asarray(table["engine_torque_nm"], dtype=float)
    rpm = np.asarray(table["engine_speed_rpm"], dtype=float)
    max_rpm = description.drive.max_speed_rad_s * 30.0 / math.pi
    speed_f = min(1.0, max_rpm / float(rpm.max())) if rpm.size and rpm.max() > 0 else 1.0
    cols = {c: np.asarray(table[c], dtype=float) for c in table.columns}
    cols["gear"] = own
    cols["engine_torque_nm"] = np.where(tq >= 0, tq * drive_f, tq * brake_f)
    cols["engine_speed_rpm"] = rpm * speed_f
    cols["retarder_torque_nm"] = cols["retarder_torque_nm"] * drive_f
    cols["vehicle_speed_kmh"] = vehicle_speed_kmh(own, cols["engine_speed_rpm"], ratio=gear_ratios(description))
    cols = with_own_boundaries(cols, description)
    note = (
        f"cycle {table.meta.get('cycle')} is the GRS905's, fitted to {description.name}: its gears by nearest ratio, "
        f"driving torque x{drive_f:.3g}, braking x{brake_f:.3g}"
        + (f", engine speed x{speed_f:.3g}" if speed_f < 1 else "")
        + f", boundaries {boundary_text(description)} (docs/cycles.md)"
    )
    return RunTable(cols, meta=dict(table.meta, fitted=note))


def boundary_text(description) -> str:
    """'ambient 20, engine_shaft 90 degC': the description's boundary temperatures, for notes."""
    return ", ".join(f"{b.id} {b.temperature_c:g}" for b in description.boundaries) + " degC"
