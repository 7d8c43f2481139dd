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

import numpy as np

from firmware_model.components import IDLE_WHEELS, LAYSHAFT_WHEELS, PAIRS
from firmware_model.errors import InputError, ParameterError

GEAR_MIN, GEAR_MAX = -2, 14
GEARS = tuple(range(GEAR_MIN, GEAR_MAX + 1))
N_GEARS = len(GEARS)

#: Table 1: gear -> (split 'low'/'high', main pair, range 'low'/'high'); 0 = neutral
GEAR_TABLE = {
    -2: ("low", "R", "low"), -1: ("high", "R", "low"),
    1: ("low", "C", "low"), 2: ("high", "C", "low"),
    3: ("low", "1", "low"), 4: ("high", "1", "low"),
    5: ("low", "2", "low"), 6: ("high", "2", "low"),
    7: ("low", "3", "low"), 8: ("high", "3", "low"),
    9: ("low", "1", "high"), 10: ("high", "1", "high"),
    11: ("low", "2", "high"), 12: ("high", "2", "high"),
    13: ("low", "3", "high"), 14: ("high", "3", "high"),
}
#: short names of Table 1
GEAR_NAMES = {-2: "RL", -1: "RH", 0: "N", 1: "CL", 2: "CH", 3: "1L", 4: "1H", 5: "2L", 6: "2H", 7: "3L", 8: "3H",
              9: "4L", 10: "4H", 11: "5L", 12: "5H", 13: "6L", 14: "6H"}
GEAR_BY_NAME = {v: k for k, v in GEAR_NAMES.items()}

#: meshes whose losses are computed: the six layshaft pairs, the reverse idler's second mesh, the planetary
MESHES = ("L", "3", "2", "1", "C", "R", "RI", "PSP", "PPR")
#: synchronizer ring interfaces (seed: all gears but crawler and reverse; plus the range synchronizer)
SYNCS = ("LI/IS", "3M/IS", "3M/MS", "2M/MS", "1M/MS", "PR/range")


@dataclass(frozen=True)
class GearState:
    gear: int
    split_pair: str | None   # 'L' or '3'
    main_pair: str | None    # '3', '2', '1', 'C', 'R'
    range: str | None        # 'low' or 'high'

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
            raise InputError(f"gear {value!r} is neither a number in {GEAR_MIN}..{GEAR_MAX} nor a Table 1 name "
                             f"such as 4L or 6H") from None
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
    idle: dict          # idle wheel id -> z
    layshaft: dict      # layshaft wheel id -> z
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
    speed: np.ndarray           # (N_GEARS, n_speeds)
    mesh_torque: np.ndarray     # (N_GEARS, len(MESHES))
    mesh_omega2: np.ndarray     # (N_GEARS, len(MESHES))
    wheel_bearing_rel: np.ndarray  # (N_GEARS, 6): |wheel - shaft under it| for LB, 3B, 2B, 1B, CB, RB
    sync_rel: np.ndarray        # (N_GEARS, len(SYNCS)): |relative speed| of open synchronizer rings (0 if engaged)
    active_pair: np.ndarray     # (N_GEARS, 6) bool: pair carries torque (L, 3, 2, 1, C, R)
    ratio: np.ndarray           # (N_GEARS,) input speed / output speed (inf in neutral)
    low_range: np.ndarray       # (N_GEARS,) bool
    split_inverted: bool

    def index(self, gear) -> np.ndarray:
        return np.asarray(gear, dtype=np.int64) - GEAR_MIN

    def speeds(self, gear, omega_in_rad_s) -> dict:
        row = self.speed[self.index(gear)]
        w = np.asarray(omega_in_rad_s, dtype=float)
        return {n: row[..., i] * w for i, n in enumerate(self.speed_names)}


SPEED_NAMES = ("IS", "LS", "MS", "OS", "LI", "3M", "2M", "1M", "CM", "RM", "RI", "PS", "PP_rel", "PR")


def build_table(teeth: Teeth, split_inverted: bool = False) -> KinematicTable:
    """Evaluate the kinematics of every gear for unit input speed and unit input torque."""
    z_i, z_l = teeth.idle, teeth.layshaft
    for w in IDLE_WHEELS:
        if w not in z_i:
            raise ParameterError(f"teeth of idle wheel {w} are missing from the parameter set")
    for w in LAYSHAFT_WHEELS:
        if w not in z_l:
            raise ParameterError(f"teeth of layshaft wheel {w} are missing from the parameter set")
    R = teeth.range_ratio
    n_sp = len(SPEED_NAMES)
    speed = np.zeros((N_GEARS, n_sp))
    mtq = np.zeros((N_GEARS, len(MESHES)))
    mw2 = np.zeros((N_GEARS, len(MESHES)))
    wbr = np.zeros((N_GEARS, 6))
    syn = np.zeros((N_GEARS, len(SYNCS)))
    act = np.zeros((N_GEARS, 6), dtype=bool)
    ratio = np.full(N_GEARS, np.inf)
    lowr = np.zeros(N_GEARS, dtype=bool)
    pair_keys = tuple(PAIRS)
    for g in GEARS:
        st = gear_state(g, split_inverted)
        r = g - GEAR_MIN
        w_is = 1.0
        # layshaft speed from the engaged split pair (the idle wheel of that pair is locked to the input shaft)
        iw, lw = PAIRS[st.split_pair]
        w_ls = w_is * z_i[iw] / z_l[lw]
        # every idle wheel meshes permanently with its layshaft wheel
        w_idle = {}
        for p, (iw_, lw_) in PAIRS.items():
            if p == "R":
                w_idle[iw_] = -w_ls * z_l[lw_] / z_i[iw_]   # through the idler: reversed
            else:
                w_idle[iw_] = w_ls * z_l[lw_] / z_i[iw_]
        w_ri = -w_ls * z_l["RL"] / teeth.z_RI
        if st.main_pair is None:
            w_ms = 0.0
        else:
            w_ms = w_idle[PAIRS[st.main_pair][0]]
        if st.direct:
            w_ms = w_is
        low = st.range == "low"
        lowr[r] = low
        w_os = w_ms / R if low else w_ms
        # planetary (low range: ring fixed, carrier = output)
        w_ring = 0.0 if low else w_ms
        w_carrier = w_os
        w_sun_rel = w_ms - w_carrier
        w_planet_rel = -w_sun_rel * teeth.z_sun / teeth.z_planet
        speed[r] = [w_is, w_ls, w_ms, w_os, *(w_idle[w] for w in IDLE_WHEELS), w_ri, w_ms, w_planet_rel, w_ring]
        if st.main_pair is not None and w_os != 0:
            ratio[r] = w_is / w_os
        # torques (unit input torque) on the driving wheel of each loaded mesh
        T_is = 1.0
        if st.main_pair is not None:
            if st.direct:
                T_ms = T_is
            else:
                T_ls = T_is * z_l[lw] / z_i[iw]
                # split mesh: idle wheel (on input shaft) drives layshaft wheel
                mtq[r, MESHES.index(st.split_pair)] = T_is
                mw2[r, MESHES.index(st.split_pair)] = abs(w_ls)
                act[r, pair_keys.index(st.split_pair)] = True
                mp = st.main_pair
                miw, mlw = PAIRS[mp]
                if mp == "R":
                    # layshaft RL drives RI, RI drives RM
                    mtq[r, MESHES.index("R")] = T_ls
                    mw2[r, MESHES.index("R")] = abs(w_ri)
                    mtq[r, MESHES.index("RI")] = T_ls * teeth.z_RI / z_l["RL"]
                    mw2[r, MESHES.index("RI")] = abs(w_idle["RM"])
                else:
                    # mesh geometry has the idle wheel as wheel 1 and the layshaft wheel as wheel 2 whatever the
                    # power direction: torque on wheel 1, speed of wheel 2 (same tangential force either way)
                    mtq[r, MESHES.index(mp)] = T_ls * z_i[miw] / z_l[mlw]
                    mw2[r, MESHES.index(mp)] = abs(w_ls)
                act[r, pair_keys.index(mp)] = True
                T_ms = T_ls * z_i[miw] / z_l[mlw]
            if low:
                # sun drives the planets (torque per planet is applied by the loss model: it sums n_planets meshes)
                mtq[r, MESHES.index("PSP")] = T_ms
                mw2[r, MESHES.index("PSP")] = abs(w_planet_rel)
                mtq[r, MESHES.index("PPR")] = T_ms * teeth.z_planet / teeth.z_sun
                mw2[r, MESHES.index("PPR")] = abs(w_carrier)   # ring relative to the carrier
        # needle bearings: relative speed between each idle wheel and the shaft it sits on
        shaft_under = {"LI": w_is, "3M": w_ms, "2M": w_ms, "1M": w_ms, "CM": w_ms, "RM": w_ms}
        for k, w in enumerate(IDLE_WHEELS):
            wbr[r, k] = abs(w_idle[w] - shaft_under[w])
        # synchronizer rings: open interfaces drag at the relative speed; the engaged one is locked
        sync_pairs = {"LI/IS": (w_idle["LI"], w_is), "3M/IS": (w_idle["3M"], w_is), "3M/MS": (w_idle["3M"], w_ms),
                      "2M/MS": (w_idle["2M"], w_ms), "1M/MS": (w_idle["1M"], w_ms)}
        for k, s in enumerate(SYNCS):
            if s == "PR/range":
                # open side of the range synchronizer: ring vs sun at low range, ring vs housing at high range
                syn[r, k] = abs(w_ms) if low else abs(w_ring)
            else:
                a, b = sync_pairs[s]
                syn[r, k] = abs(a - b)
    return KinematicTable(SPEED_NAMES, speed, mtq, mw2, wbr, syn, act, ratio, lowr, split_inverted)


def total_ratio(table: KinematicTable, gear: int) -> float:
    return float(table.ratio[parse_gear(gear) - GEAR_MIN])
