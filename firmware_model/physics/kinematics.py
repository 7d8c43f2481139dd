"""Gear selection and kinematics of the range-splitter gearbox (seed section 2.3, Table 1).

The gearbox is a splitter (L or H/3 pair from the input shaft to the layshaft), a main box (H/3, 2, 1, C or R pair
from the layshaft to the main shaft) and a range planetary (ring locked to the housing: low range, ratio
1 + z_R / z_S; ring locked to the sun: high range, 1:1). High split with 3rd is direct drive (input shaft locked to
the main shaft through the 3M wheel).

For a given gear every speed in the box is proportional to the input speed and every torque on a driving wheel is
proportional to the input torque (losses neglected in the force calculation). This module computes those
coefficients once per gear into lookup tables, so that the plant and the onboard model evaluate a whole array of
samples with one fancy-indexing operation.

Gear numbers (Table 1): -2 RL, -1 RH, 0 neutral, 1 CL, 2 CH, 3 1L, 4 1H, 5 2L, 6 2H, 7 3L, 8 3H, 9 4L, 10 4H,
11 5L, 12 5H, 13 6L, 14 6H. The overdrive variant (GRSO905) inverts the split: "low split" then engages the H/3
pair and "high split" the L pair (seed section 4.3 and 5.2).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from firmware_model.components import IDLE_WHEELS, LAYSHAFT_WHEELS, PAIRS
from firmware_model.errors import InputError, ParameterError

GEAR_MIN, GEAR_MAX = -2, 14
GEARS = tuple(range(GEAR_MIN, GEAR_MAX + 1))
N_GEARS = len(GEARS)

#: Table 1: gear -> (split 'low'/'high', main pair, range 'low'/'high'); 0 = neutral
GEAR_TABLE = {
    -2: ("low", "R", "low"),
    -1: ("high", "R", "low"),
    1: ("low", "C", "low"),
    2: ("high", "C", "low"),
    3: ("low", "1", "low"),
    4: ("high", "1", "low"),
    5: ("low", "2", "low"),
    6: ("high", "2", "low"),
    7: ("low", "3", "low"),
    8: ("high", "3", "low"),
    9: ("low", "1", "high"),
    10: ("high", "1", "high"),
    11: ("low", "2", "high"),
    12: ("high", "2", "high"),
    13: ("low", "3", "high"),
    14: ("high", "3", "high"),
}
#: short names of Table 1
GEAR_NAMES = {
    -2: "RL",
    -1: "RH",
    0: "N",
    1: "CL",
    2: "CH",
    3: "1L",
    4: "1H",
    5: "2L",
    6: "2H",
    7: "3L",
    8: "3H",
    9: "4L",
    10: "4H",
    11: "5L",
    12: "5H",
    13: "6L",
    14: "6H",
}
GEAR_BY_NAME = {v: k for k, v in GEAR_NAMES.items()}

#: meshes whose losses are computed: the six layshaft pairs, the reverse idler's second mesh, the planetary
MESHES = ("L", "3", "2", "1", "C", "R", "RI", "PSP", "PPR")
#: synchronizer ring interfaces (seed: all gears but crawler and reverse; plus the range synchronizer)
SYNCS = ("LI/IS", "3M/IS", "3M/MS", "2M/MS", "1M/MS", "PR/range")


@dataclass(frozen=True)
class GearState:
    gear: int
    split_pair: str | None  # 'L' or '3'
    main_pair: str | None  # '3', '2', '1', 'C', 'R'
    range: str | None  # 'low' or 'high'

    @property
    def direct(self) -> bool:
        return self.split_pair == "3" and self.main_pair == "3"


def parse_gear(value) -> int:
    """Accept an int in -2..14 or a Table 1 short name ('4L', 'RH', 'N')."""
    if isinstance(value, str):
        s = value.strip()
        if s.upper() in {k.upper(): v for k, v in GEAR_BY_NAME.items()}:
            return {k.upper(): v for k, v in GEAR_BY_NAME.items()}[s.upper()]
        try:
            value = int(float(s))
        except ValueError:
            raise InputError(
                f"gear {value!r} is neither a number in {GEAR_MIN}..{GEAR_MAX} nor a Table 1 name such as 4L or 6H"
            ) from None
    if isinstance(value, float):
        if not np.isfinite(value) or value != int(value):
            raise InputError(f"gear {value!r} must be an integer in {GEAR_MIN}..{GEAR_MAX}")
        value = int(value)
    if not GEAR_MIN <= int(value) <= GEAR_MAX:
        raise InputError(f"gear {value} is outside Table 1's range {GEAR_MIN}..{GEAR_MAX}")
    return int(value)


def gear_state(gear: int, split_inverted: bool = False) -> GearState:
    gear = parse_gear(gear)
    if gear == 0:
        # neutral: clutch engaged, layshaft turned through the (low) split pair, main shaft standing
        return GearState(0, "3" if split_inverted else "L", None, None)
    split, main, rng = GEAR_TABLE[gear]
    low_pair, high_pair = ("3", "L") if split_inverted else ("L", "3")
    return GearState(gear, low_pair if split == "low" else high_pair, main, rng)


@dataclass(frozen=True)
class Teeth:
    """Tooth numbers needed by the kinematics (from the parameter set)."""

    idle: dict  # idle wheel id -> z
    layshaft: dict  # layshaft wheel id -> z
    z_RI: int
    z_sun: int
    z_planet: int
    z_ring: int
    n_planets: int

    @property
    def range_ratio(self) -> float:
        return 1.0 + self.z_ring / self.z_sun


@dataclass(frozen=True)
class KinematicTable:
    """Per-gear coefficients; row index = gear - GEAR_MIN. Multiply by the input speed (or torque).

    speed columns (rad/s per rad/s of input): named in `speed_names`
    mesh torque columns (N m on the driving wheel per N m of input): named in MESHES; 0 when the mesh is unloaded
    mesh speed columns: speed of wheel 2 of the mesh geometry (the layshaft wheel for the six pairs; the driven wheel
    relative to the planet carrier for planetary meshes); mesh torque is the torque on wheel 1
    """

    speed_names: tuple
    speed: np.ndarray  # (N_GEARS, n_speeds)
    mesh_torque: np.ndarray  # (N_GEARS, len(MESHES))
    mesh_omega2: np.ndarray  # (N_GEARS, len(MESHES))
    wheel_bearing_rel: np.ndarray  # (N_GEARS, 6): |wheel - shaft under it| for LB, 3B, 2B, 1B, CB, RB
    sync_rel: np.ndarray  # (N_GEARS, len(SYNCS)): |relative speed| of open synchronizer rings (0 if engaged)
    active_pair: np.ndarray  # (N_GEARS, 6) bool: pair carries torque (L, 3, 2, 1, C, R)
    ratio: np.ndarray  # (N_GEARS,) input speed / output speed (inf in neutral)
    low_range: np.ndarray  # (N_GEARS,) bool
    split_inverted: bool

    def index(self, gear) -> np.ndarray:
        return np.asarray(gear, dtype=np.int64) - GEAR_MIN

    def speeds(self, gear, omega_in_rad_s) -> dict:
        row = self.speed[self.index(gear)]
        w = np.asarray(omega_in_rad_s, dtype=float)
        return {n: row[..., i] * w for i, n in enumerate(self.speed_names)}


SPEED_NAMES = ("IS", "LS", "MS", "OS", "LI", "3M", "2M", "1M", "CM", "RM", "RI", "PS", "PP_rel", "PR")


class GearSpeeds(NamedTuple):
    """Every speed of one gear per rad/s of input speed."""

    w_is: float
    w_ls: float
    w_ms: float
    w_os: float
    w_idle: dict  # idle wheel -> speed
    w_ri: float
    w_ring: float
    w_carrier: float
    w_planet_rel: float  # planets relative to the carrier
    low_range: bool


class GearRow(NamedTuple):
    """One row of the KinematicTable (one gear)."""

    speed: list
    mesh_torque: np.ndarray
    mesh_omega2: np.ndarray
    wheel_bearing_rel: np.ndarray
    sync_rel: np.ndarray
    active_pair: np.ndarray
    ratio: float


def _check_teeth(teeth: Teeth) -> None:
    for w in IDLE_WHEELS:
        if w not in teeth.idle:
            raise ParameterError(f"teeth of idle wheel {w} are missing from the parameter set")
    for w in LAYSHAFT_WHEELS:
        if w not in teeth.layshaft:
            raise ParameterError(f"teeth of layshaft wheel {w} are missing from the parameter set")


def gear_speeds(teeth: Teeth, st: GearState) -> GearSpeeds:
    """Speeds of a gear for unit input speed: the engaged split pair drives the layshaft, every idle wheel meshes
    permanently with its layshaft wheel, the main pair (or direct drive) drives the main shaft, the range planetary
    the output (low range: ring fixed, carrier = output; high range: locked 1:1)."""
    z_i, z_l = teeth.idle, teeth.layshaft
    w_is = 1.0
    iw, lw = PAIRS[st.split_pair]
    w_ls = w_is * z_i[iw] / z_l[lw]
    w_idle = {}
    for p, (iw_, lw_) in PAIRS.items():
        if p == "R":
            w_idle[iw_] = -w_ls * z_l[lw_] / z_i[iw_]  # through the idler: reversed
        else:
            w_idle[iw_] = w_ls * z_l[lw_] / z_i[iw_]
    w_ri = -w_ls * z_l["RL"] / teeth.z_RI
    w_ms = 0.0 if st.main_pair is None else w_idle[PAIRS[st.main_pair][0]]
    if st.direct:
        w_ms = w_is
    low = st.range == "low"
    w_os = w_ms / teeth.range_ratio if low else w_ms
    w_ring = 0.0 if low else w_ms
    w_carrier = w_os
    w_sun_rel = w_ms - w_carrier
    w_planet_rel = -w_sun_rel * teeth.z_sun / teeth.z_planet
    return GearSpeeds(w_is, w_ls, w_ms, w_os, w_idle, w_ri, w_ring, w_carrier, w_planet_rel, low)


def _mesh_loads(teeth: Teeth, st: GearState, s: GearSpeeds):
    """(torque on wheel 1 per unit input torque, speed of wheel 2, pair carries torque) of every mesh."""
    z_i, z_l = teeth.idle, teeth.layshaft
    mtq = np.zeros(len(MESHES))
    mw2 = np.zeros(len(MESHES))
    act = np.zeros(len(PAIRS), dtype=bool)
    pair_keys = tuple(PAIRS)
    T_is = 1.0
    if st.main_pair is None:
        return mtq, mw2, act
    if st.direct:
        T_ms = T_is
    else:
        iw, lw = PAIRS[st.split_pair]
        T_ls = T_is * z_l[lw] / z_i[iw]
        # split mesh: idle wheel (on input shaft) drives layshaft wheel
        mtq[MESHES.index(st.split_pair)] = T_is
        mw2[MESHES.index(st.split_pair)] = abs(s.w_ls)
        act[pair_keys.index(st.split_pair)] = True
        mp = st.main_pair
        miw, mlw = PAIRS[mp]
        if mp == "R":
            # layshaft RL drives RI, RI drives RM
            mtq[MESHES.index("R")] = T_ls
            mw2[MESHES.index("R")] = abs(s.w_ri)
            mtq[MESHES.index("RI")] = T_ls * teeth.z_RI / z_l["RL"]
            mw2[MESHES.index("RI")] = abs(s.w_idle["RM"])
        else:
            # mesh geometry has the idle wheel as wheel 1 and the layshaft wheel as wheel 2 whatever the
            # power direction: torque on wheel 1, speed of wheel 2 (same tangential force either way)
            mtq[MESHES.index(mp)] = T_ls * z_i[miw] / z_l[mlw]
            mw2[MESHES.index(mp)] = abs(s.w_ls)
        act[pair_keys.index(mp)] = True
        T_ms = T_ls * z_i[miw] / z_l[mlw]
    if s.low_range:
        # sun drives the planets (torque per planet is applied by the loss model: it sums n_planets meshes)
        mtq[MESHES.index("PSP")] = T_ms
        mw2[MESHES.index("PSP")] = abs(s.w_planet_rel)
        mtq[MESHES.index("PPR")] = T_ms * teeth.z_planet / teeth.z_sun
        mw2[MESHES.index("PPR")] = abs(s.w_carrier)  # ring relative to the carrier
    return mtq, mw2, act


def _gear_row(teeth: Teeth, st: GearState) -> GearRow:
    s = gear_speeds(teeth, st)
    mtq, mw2, act = _mesh_loads(teeth, st, s)
    # needle bearings: relative speed between each idle wheel and the shaft it sits on
    shaft_under = {"LI": s.w_is, "3M": s.w_ms, "2M": s.w_ms, "1M": s.w_ms, "CM": s.w_ms, "RM": s.w_ms}
    wbr = np.array([abs(s.w_idle[w] - shaft_under[w]) for w in IDLE_WHEELS])
    # synchronizer rings: open interfaces drag at the relative speed; the engaged one is locked
    sync_pairs = {
        "LI/IS": (s.w_idle["LI"], s.w_is),
        "3M/IS": (s.w_idle["3M"], s.w_is),
        "3M/MS": (s.w_idle["3M"], s.w_ms),
        "2M/MS": (s.w_idle["2M"], s.w_ms),
        "1M/MS": (s.w_idle["1M"], s.w_ms),
    }
    syn = np.zeros(len(SYNCS))
    for k, name in enumerate(SYNCS):
        if name == "PR/range":
            # open side of the range synchronizer: ring vs sun at low range, ring vs housing at high range
            syn[k] = abs(s.w_ms) if s.low_range else abs(s.w_ring)
        else:
            a, b = sync_pairs[name]
            syn[k] = abs(a - b)
    speed = [
        s.w_is,
        s.w_ls,
        s.w_ms,
        s.w_os,
        *(s.w_idle[w] for w in IDLE_WHEELS),
        s.w_ri,
        s.w_ms,
        s.w_planet_rel,
        s.w_ring,
    ]
    ratio = s.w_is / s.w_os if st.main_pair is not None and s.w_os != 0 else np.inf
    return GearRow(speed, mtq, mw2, wbr, syn, act, ratio)


def build_table(teeth: Teeth, split_inverted: bool = False) -> KinematicTable:
    """Evaluate the kinematics of every gear for unit input speed and unit input torque."""
    _check_teeth(teeth)
    states = [gear_state(g, split_inverted) for g in GEARS]
    rows = [_gear_row(teeth, st) for st in states]
    return KinematicTable(
        SPEED_NAMES,
        np.array([r.speed for r in rows], dtype=float),
        np.array([r.mesh_torque for r in rows]),
        np.array([r.mesh_omega2 for r in rows]),
        np.array([r.wheel_bearing_rel for r in rows]),
        np.array([r.sync_rel for r in rows]),
        np.array([r.active_pair for r in rows]),
        np.array([r.ratio for r in rows], dtype=float),
        np.array([st.range == "low" for st in states]),
        split_inverted,
    )


def total_ratio(table: KinematicTable, gear: int) -> float:
    return float(table.ratio[parse_gear(gear) - GEAR_MIN])
