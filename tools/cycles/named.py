"""Named SYNTHETIC drive cycles modelled on the thesis's load cases (seed sections 2.4, 4.4, 5.1-5.5): none of these
is a measurement, each is deterministic for a given seed.

``steady:gear=4L,rpm=1300,nm=2000,s=3600,oil=100`` (one gear at constant load, sections 5.3, 5.4), ``all_gears`` (the
gear sweep of Figure 4), ``long_haul`` (~1 h, Table 11 load case 1), ``uphill`` (2 h, load case 2) and ``mining``
(3 h haul cycle, section 5.2). The road cycles are driven by the vehicle model of :mod:`tools.cycles.vehicle`,
:mod:`tools.cycles.route` and :mod:`tools.cycles.driver`; this module defines the named cycles on top of them. Every
table has the columns of :data:`COLUMNS` plus ``meta['initial_temp_c']`` and ``meta['hold_oil_c']``. docs/cycles.md
describes each cycle, the vehicle model and its assumed values, and the noise ``noise=True`` adds.
"""

from __future__ import annotations

import math
import os
from functools import lru_cache
from pathlib import Path

import numpy as np

from firmware_model.errors import InputError
from firmware_model.physics.kinematics import GEAR_NAMES, parse_gear
from firmware_model.physics.oil import check_temperature_c
from tools.cycles.driver import DriveTrace, drive
from tools.cycles.fit import fit_cycle, gear_list, gear_ratios, nearest_gear, own_gears, with_own_boundaries
from tools.cycles.route import Segment
from tools.cycles.vehicle import KMH_PER_M_S, Vehicle, gearbox_kinematics, total_ratios, vehicle_speed_kmh
from tools.runtable import RunTable

__all__ = [
    "BC_COLUMNS",
    "COLUMNS",
    "CYCLE_HELP",
    "CYCLE_NAMES",
    "TABLE11_LC1",
    "TABLE11_LC2",
    "AMBIENT_C",
    "Segment",
    "Vehicle",
    "all_gears",
    "check_cycle_hold",
    "cold_start",
    "get_cycle",
    "gearbox_kinematics",
    "long_haul",
    "mining",
    "parse_steady_spec",
    "road_profile",
    "steady",
    "summarize",
    "total_ratios",
    "uphill",
]

CYCLE_NAMES = ("steady", "all_gears", "long_haul", "uphill", "mining")
CYCLE_HELP = {
    "steady": "steady:gear=4L,rpm=1300,nm=2000,s=3600,oil=100 - one gear at constant speed and torque "
    "(seed 5.3/5.4); oil= holds the sump in place of the cooler",
    "all_gears": "RL to 6H, 100 s each at 1300 rpm / 1000 Nm, sump held at 100 degC (seed Fig 4), 1600 s",
    "long_haul": "1 h level cruising, 40 t, mostly 6H at ~1300 rpm and 300-900 Nm, cold start 33.5 degC "
    "(seed 4.4 load case 1)",
    "uphill": "2 h: ~900 m climb in the first hour at 1800-2500 Nm in low range, then high gears, start 68.3 degC "
    "(seed 4.4 load case 2)",
    "mining": "3 h mine haul cycles: loaded climbs in low gears, empty descents on engine brake and retarder, "
    "stops in neutral, start 40 degC (seed 5.2)",
}

BC_COLUMNS = (
    "bc_engine_shaft_c",
    "bc_flywheel_cover_c",
    "bc_support_beam_c",
    "bc_end_yoke_c",
    "bc_hot_surroundings_c",
    "bc_cold_surroundings_c",
)
COLUMNS = (
    "time_s",
    "engine_speed_rpm",
    "engine_torque_nm",
    "gear",
    "vehicle_speed_kmh",
    "ambient_temp_c",
    "coolant_temp_c",
    "retarder_torque_nm",
) + BC_COLUMNS

#: seed Table 11: final boundary temperatures (degC) of load case 1 (long haul) and 2 (uphill), in BC_COLUMNS order
TABLE11_LC1 = (90.0, 90.0, 80.0, 80.0, 90.0, 40.0)
TABLE11_LC2 = (100.0, 100.0, 90.0, 90.0, 100.0, 60.0)
#: ambient air (seed Table 8)
AMBIENT_C = 25.0
# ----------------------------------------------------------------------------------------------------------------
# routes of the named cycles


def _long_haul_route(rng: np.random.Generator) -> tuple[list[Segment], Vehicle]:
    u = lambda lo, hi: float(rng.uniform(lo, hi))  # noqa: E731
    segs = [Segment(600, 0.0, 40), Segment(1500, 0.0, 60)]
    # open road with three slowdowns (village, roundabout, road works) at seeded places
    for lim, ln in ((50, u(1200, 1800)), (30, u(150, 250)), (60, u(1500, 2500))):
        segs.append(Segment(u(11000, 19000), 0.0, 80, hills=u(0.0055, 0.0075)))
        segs.append(Segment(ln, 0.0, lim, hills=0.002))
    segs.append(Segment(60000, 0.0, 80, hills=u(0.0055, 0.0075)))
    return segs, Vehicle()


def _jitter(
    rng: np.random.Generator,
    sections,
    piece_m: float = 500.0,
    grade_rel: float = 0.15,
    limit_kmh: float = 3.0,
    hills: float = 0.0,
) -> list[Segment]:
    """Cut (length, grade, limit) sections into ~piece_m pieces with seeded grade and speed-limit variation."""
    out = []
    for length, grade, limit in sections:
        k = max(1, int(round(length / piece_m)))
        for _ in range(k):
            out.append(
                Segment(
                    length / k,
                    grade * float(rng.uniform(1 - grade_rel, 1 + grade_rel)),
                    max(8.0, limit + float(rng.uniform(-limit_kmh, limit_kmh))),
                    hills=hills,
                )
            )
    return out


def _uphill_route(rng: np.random.Generator) -> tuple[list[Segment], Vehicle]:
    f = lambda: float(rng.uniform(0.9, 1.1))  # noqa: E731
    climb = [  # (length m, grade, limit km/h): ~900 m up in ~45 min, steep bends at low speed
        (1000 * f(), 0.005, 50),
        (3000 * f(), 0.040, 40),
        (2500 * f(), 0.065, 18),
        (1500 * f(), 0.030, 50),
        (3000 * f(), 0.070, 18),
        (1000 * f(), 0.085, 15),
        (2000 * f(), 0.050, 30),
        (2000 * f(), 0.060, 19),
        (3000 * f(), 0.020, 60),
    ]
    segs = _jitter(rng, climb, hills=0.006)
    # plateau: lighter running in high gears for the rest of the run, two slowdowns
    for lim in (60, 50):
        segs.append(Segment(float(rng.uniform(25000, 40000)), 0.0, 80, hills=float(rng.uniform(0.008, 0.011))))
        segs.append(Segment(float(rng.uniform(1000, 2000)), 0.0, lim, hills=0.003))
    segs.append(Segment(100000, 0.0, 80, hills=float(rng.uniform(0.008, 0.011))))
    return segs, Vehicle(mass_kg=60000.0)


MINING_LOADED_KG = 50000.0
MINING_EMPTY_KG = 22000.0


def _mining_route(rng: np.random.Generator) -> tuple[list[Segment], Vehicle]:
    u = lambda lo, hi: float(rng.uniform(lo, hi))  # noqa: E731
    segs = [Segment(1200, 0.005, 40)]  # from the workshop to the portal
    for _ in range(12):
        depth_grade = u(0.095, 0.11)
        ramp = u(1500, 2000)
        segs += [
            Segment(ramp, -depth_grade, u(18, 24)),  # empty descent
            Segment(
                300,
                0.0,
                15,
                stop_s=u(150, 240),
                reverse_m=u(25, 40),  # to the loader, reverse in, load
                mass_after_kg=MINING_LOADED_KG,
                start_gear=1,
            ),
            Segment(300, 0.0, 15),
            Segment(250, 0.12, 8),  # steep bend out of the loading area
            Segment(ramp - 250 * 0.12 / depth_grade, depth_grade, 20),  # loaded climb back to the portal
            Segment(
                1500,
                0.005,
                u(30, 40),
                stop_s=u(60, 110),
                reverse_m=u(20, 35),  # haul to the tip, dump
                mass_after_kg=MINING_EMPTY_KG,
            ),
            Segment(1500, -0.005, u(30, 40)),
        ]
    return segs, Vehicle(mass_kg=MINING_EMPTY_KG, crr=0.012)


_ROAD = {
    # name: (route builder, duration s, idle at start s, initial temp degC)
    "long_haul": (_long_haul_route, 3600.0, 30.0, 33.5),
    "uphill": (_uphill_route, 7200.0, 20.0, 68.3),
    "mining": (_mining_route, 10800.0, 60.0, 40.0),
}


@lru_cache(maxsize=8)
def _road_cycle(name: str, seed: int) -> DriveTrace:
    build, duration, idle, _ = _ROAD[name]
    rng = np.random.default_rng([seed, sum(map(ord, name))])
    segs, veh = build(rng)
    return drive(segs, veh, duration, rng, idle_start_s=idle)


# ----------------------------------------------------------------------------------------------------------------
# boundary conditions (seed Table 11)


def _ramp(t: np.ndarray, points: list[tuple[float, float]]) -> np.ndarray:
    tp, vp = zip(*points)
    return np.interp(t, tp, vp)


def _boundaries(name: str, t: np.ndarray) -> dict:
    cols = {"ambient_temp_c": np.full(t.size, AMBIENT_C)}
    if name == "long_haul":
        # seed 4.4 LC1: surroundings rise linearly from the initial 33.5 degC to Table 11 in 2000 s, coolant in 1000 s
        for c, v in zip(BC_COLUMNS, TABLE11_LC1):
            cols[c] = _ramp(t, [(0.0, 33.5), (2000.0, v)])
        cols["coolant_temp_c"] = _ramp(t, [(0.0, 33.5), (1000.0, 80.0)])
    elif name == "uphill":
        # seed 4.4 LC2: constant surroundings; coolant 80 -> 100 in 1000 s, held 2000 s, -> 90 in 500 s
        for c, v in zip(BC_COLUMNS, TABLE11_LC2):
            cols[c] = np.full(t.size, v)
        cols["coolant_temp_c"] = _ramp(t, [(0.0, 80.0), (1000.0, 100.0), (3000.0, 100.0), (3500.0, 90.0)])
    elif name == "mining":
        # not in the seed (its mining run used the measured oil temperature): assumed like LC1, from 40 degC to
        # Table 11 load case 2 (a harsh duty) over 2000 s, coolant 40 -> 85 over 1000 s
        for c, v in zip(BC_COLUMNS, TABLE11_LC2):
            cols[c] = _ramp(t, [(0.0, 40.0), (2000.0, v)])
        cols["coolant_temp_c"] = _ramp(t, [(0.0, 40.0), (1000.0, 85.0)])
    else:
        # rig-like cases (steady, all_gears): Table 11 load case 1 steady values
        for c, v in zip(BC_COLUMNS, TABLE11_LC1):
            cols[c] = np.full(t.size, v)
        cols["coolant_temp_c"] = np.full(t.size, 80.0)
    return cols


# ----------------------------------------------------------------------------------------------------------------
# assembling tables


def _out_time(duration_s: float, rate_hz: float) -> np.ndarray:
    n = int(round(duration_s * rate_hz))
    return np.arange(n) / rate_hz


def _resample(src: DriveTrace, t_out: np.ndarray) -> dict:
    """The driven trace at the output times: speeds and torques interpolated, the gear held."""
    t = src.time_s
    idx = np.clip(np.searchsorted(t, t_out + 1e-9, side="right") - 1, 0, t.size - 1)
    out = {"time_s": t_out}
    for c in ("engine_speed_rpm", "engine_torque_nm", "vehicle_speed_kmh", "retarder_torque_nm"):
        out[c] = np.interp(t_out, t, getattr(src, c))
    out["gear"] = src.gear[idx]
    return out


def _add_noise(cols: dict, seed: int) -> None:
    rng = np.random.default_rng([seed, 0x5EED])
    n = cols["time_s"].size
    tq = cols["engine_torque_nm"]
    cols["engine_torque_nm"] = tq + rng.standard_normal(n) * (0.02 * np.abs(tq) + 5.0)
    cols["engine_speed_rpm"] = np.maximum(cols["engine_speed_rpm"] + rng.standard_normal(n) * 3.0, 0.0)
    cols["vehicle_speed_kmh"] = np.maximum(cols["vehicle_speed_kmh"] + rng.standard_normal(n) * 0.1, 0.0)


def _table(name: str, cols: dict, meta: dict, rate_hz: float, noise: bool, seed: int, description=None) -> RunTable:
    t = cols["time_s"]
    cols.update(_boundaries(name, t))
    cols = {c: cols[c] for c in COLUMNS}
    if own_gears(description):  # its own boundary temperatures, not the GRS905's Table 11 (tools.cycles.fit)
        cols = with_own_boundaries(cols, description)
    if meta.get("ambient_c") is not None:  # a steady spec's ambient=
        cols["ambient_temp_c"] = np.full(t.size, float(meta["ambient_c"]))
    if noise:
        _add_noise(cols, seed)
    meta = dict(
        meta, cycle=meta.get("cycle", name), rate_hz=float(rate_hz), noise=bool(noise), seed=int(seed), synthetic=True
    )
    return RunTable(cols, meta=meta)


STEADY_KEYS = {
    "gear": "gear number or Table 1 name",
    "rpm": "engine speed",
    "nm": "engine torque",
    "s": "duration in seconds",
    "oil": "held sump temperature in degC",
    "init": "initial temperature in degC",
    "ambient": "air temperature in degC (default: the gearbox description's ambient)",
}


def check_cycle_hold(meta: dict, hold_oil_c: float | None, cooler: str | None) -> None:
    """InputError when a cycle that holds its sump (``meta["hold_oil_c"]``: a steady spec's oil=, all_gears) meets
    a configured cooler other than hold (the plant holds the sump in place of the cooler: a liquid cooler would carry
    0 W, a measured sump would drop the hold) or a configured held temperature that differs (it silently won)."""
    held_c = meta.get("hold_oil_c")
    if held_c is None:
        return
    cycle = str(meta.get("cycle", "of this run"))
    steady = cycle.startswith("steady")
    what = f"the cycle {cycle} holds the sump at {float(held_c):g} degC" + (" (its oil=)" if steady else "")
    if hold_oil_c is not None and float(hold_oil_c) != float(held_c):
        raise InputError(
            f"{what} and hold_oil_c {float(hold_oil_c):g} degC ([simulate] hold_oil_c, --hold-oil) another "
            "temperature: give the held sump once"
        )
    if hold_oil_c is None and cooler not in (None, "hold"):
        raise InputError(
            f"{what}, which replaces the cooler, and this run's cooler is {cooler} ([cooler] kind): use "
            '[cooler] kind = "hold" or no [cooler] to hold the sump'
            + (f", or leave oil= out to {LET_SET.get(cooler, 'let the cooler set it')}" if steady else "")
            + ("" if steady else " (this cycle always holds it)")
        )


#: what leaving a steady spec's oil= out gives, by cooler (check_cycle_hold)
LET_SET = {
    "liquid": "let the liquid cooler set it",
    "air": "let the air cooler set it",
    "none": "let it run free (no cooler)",
    "measured": "take it from the run table's oil_temp_c",
}


def parse_steady_spec(spec: str, max_rpm: float = 4000.0, max_nm: float = 4200.0) -> dict:
    """'steady:gear=4L,rpm=1300,nm=2000,s=3600,oil=100' -> dict (defaults gear 4L, 1300 rpm, 2000 Nm, 3600 s); rpm
    and nm within the gearbox's drive limits (its description's max_speed and max_torque; the GRS905's by default)."""
    out = {"gear": 9, "rpm": 1300.0, "nm": 2000.0, "s": 3600.0, "oil": None, "init": None, "ambient": None}
    _, _, rest = spec.partition(":")
    given = set()
    for item in filter(None, (p.strip() for p in rest.split(","))):
        key, eq, val = item.partition("=")
        key = key.strip().lower()
        if not eq or key not in STEADY_KEYS:
            raise InputError(
                f"steady cycle spec {spec!r}: {item!r} is not one of "
                + ", ".join(f"{k}=<{v}>" for k, v in STEADY_KEYS.items())
            )
        if key in given:
            raise InputError(f"steady cycle spec {spec!r}: {key} is given twice; give it once")
        given.add(key)
        if key == "gear":
            try:
                out["gear"] = parse_gear(val)
            except InputError as e:
                raise InputError(f"steady cycle spec {spec!r}: {e}") from None
            continue
        try:
            x = float(val)
        except ValueError:
            raise InputError(f"steady cycle spec {spec!r}: {key}={val!r} is not a number") from None
        if not math.isfinite(x):
            raise InputError(f"steady cycle spec {spec!r}: {key}={val!r} must be finite")
        out[key] = x
    if out["rpm"] < 0 or out["rpm"] > max_rpm:
        raise InputError(f"steady cycle spec {spec!r}: rpm={out['rpm']:g} must be in 0..{max_rpm:.0f}")
    if out["gear"] == 0 and "nm" not in given:
        out["nm"] = 0.0  # neutral idles: the default 2000 Nm would reach no gear (the plant drops it)
    if out["gear"] == 0 and out["nm"] != 0:
        # in neutral the engine's torque reaches no gear: the plant drops it (the gearbox idles); said, not dropped
        raise InputError(
            f"steady cycle spec {spec!r}: nm={out['nm']:g} in neutral (gear=0) reaches no gear; give nm=0 for an "
            "idling gearbox, or a gear"
        )
    if abs(out["nm"]) > max_nm:
        raise InputError(f"steady cycle spec {spec!r}: nm={out['nm']:g} must be within -{max_nm:.0f}..{max_nm:.0f} Nm")
    if out["s"] <= 0 or out["s"] > 7 * 86400:
        raise InputError(f"steady cycle spec {spec!r}: s={out['s']:g} must be a positive duration up to a week")
    for key in ("oil", "init", "ambient"):
        if out[key] is not None:
            check_temperature_c(f"steady cycle spec {spec!r}: {key}", out[key])
    return out


def steady(
    gear=9,
    rpm: float = 1300.0,
    nm: float = 2000.0,
    s: float = 3600.0,
    oil: float | None = None,
    init: float | None = None,
    rate_hz: float = 10.0,
    noise: bool = False,
    seed: int = 0,
    spec: str | None = None,
    description=None,
    ambient: float | None = None,
) -> RunTable:
    """One gear at constant engine speed and torque (seed 5.3/5.4). SYNTHETIC. Initial temperature: the held oil
    temperature, else 20 degC (seed 5.4). ``description``: a gearbox outside the GRS905 family (tools.cycles.fit):
    ``gear`` is its gear number, the vehicle speed its ratio's, the boundaries its own."""
    own = own_gears(description)
    gear = int(gear) if own else parse_gear(gear)
    t = _out_time(s, rate_hz)
    g = np.full(t.size, float(gear))
    n_rpm = np.full(t.size, float(rpm))
    cols = {
        "time_s": t,
        "engine_speed_rpm": n_rpm,
        "engine_torque_nm": np.full(t.size, float(nm)),
        "gear": g,
        "vehicle_speed_kmh": vehicle_speed_kmh(g, n_rpm, ratio=gear_ratios(description) if own else None),
        "retarder_torque_nm": np.zeros(t.size),
    }
    init_c = init if init is not None else (oil if oil is not None else 20.0)
    spec = spec or f"steady:gear={gear if own else GEAR_NAMES[gear]},rpm={rpm:g},nm={nm:g},s={s:g}" + (
        f",oil={oil:g}" if oil is not None else ""
    )
    hold = None if oil is None else float(oil)
    return _table(
        "steady",
        cols,
        {"cycle": spec, "initial_temp_c": float(init_c), "hold_oil_c": hold, "ambient_c": ambient},
        rate_hz,
        noise,
        seed,
        description,
    )


ALL_GEARS_ORDER = (-2, -1) + tuple(range(1, 15))


def all_gears(
    rate_hz: float = 10.0,
    noise: bool = False,
    seed: int = 0,
    rpm: float = 1300.0,
    nm: float = 1000.0,
    step_s: float = 100.0,
    hold_oil_c: float = 100.0,
) -> RunTable:
    """RL to 6H, `step_s` each at `rpm` and `nm` (reverse and crawler limited to 700 Nm), sump held (seed Fig 4).
    SYNTHETIC. Each change has a 0.6 s torque interruption (1.0 s for range changes)."""
    n_g = len(ALL_GEARS_ORDER)
    t = _out_time(n_g * step_s, rate_hz)
    k = np.minimum((t // step_s).astype(int), n_g - 1)
    g = np.array(ALL_GEARS_ORDER, dtype=float)[k]
    limited = g <= 2
    tq = np.where(limited, min(nm, 700.0), nm)
    # torque interruption around each change: ramp down over the last part of the step, up after
    ts = t - k * step_s
    for i in range(1, n_g):
        dur = 1.0 if (ALL_GEARS_ORDER[i] >= 9) != (ALL_GEARS_ORDER[i - 1] >= 9) else 0.6
        tc = i * step_s
        d = t - tc
        m = np.abs(d) < dur / 2
        frac = np.clip((np.abs(d[m]) - dur / 4) / (dur / 4), 0.0, 1.0)
        tq[m] = tq[m] * frac
    del ts
    n_rpm = np.full(t.size, float(rpm))
    cols = {
        "time_s": t,
        "engine_speed_rpm": n_rpm,
        "engine_torque_nm": tq,
        "gear": g,
        "vehicle_speed_kmh": vehicle_speed_kmh(g, n_rpm),
        "retarder_torque_nm": np.zeros(t.size),
    }
    return _table(
        "all_gears", cols, {"initial_temp_c": float(hold_oil_c), "hold_oil_c": float(hold_oil_c)}, rate_hz, noise, seed
    )


def _road(name: str, rate_hz: float, noise: bool, seed: int) -> RunTable:
    src = _road_cycle(name, int(seed))
    duration = _ROAD[name][1]
    cols = _resample(src, _out_time(duration, rate_hz))
    return _table(name, cols, {"initial_temp_c": _ROAD[name][3], "hold_oil_c": None}, rate_hz, noise, seed)


def long_haul(rate_hz: float = 10.0, noise: bool = False, seed: int = 0) -> RunTable:
    """SYNTHETIC ~1 h level cruising of a 40 t truck, mostly in 6H (seed 4.4 load case 1); cold start 33.5 degC,
    boundaries ramping to Table 11 load case 1 over 2000 s, coolant to 80 degC over 1000 s."""
    return _road("long_haul", rate_hz, noise, seed)


def uphill(rate_hz: float = 10.0, noise: bool = False, seed: int = 0) -> RunTable:
    """SYNTHETIC 2 h: ~900 m climb at high torque in low range in the first hour, then high gears (seed 4.4 load
    case 2); start 68.3 degC, Table 11 load case 2 boundaries, coolant 80 -> 100 -> 90 degC."""
    return _road("uphill", rate_hz, noise, seed)


def mining(rate_hz: float = 10.0, noise: bool = False, seed: int = 0) -> RunTable:
    """SYNTHETIC 3 h of mine haul cycles (seed 5.2): loaded climbs in low gears, empty descents on engine brake and
    retarder, loading and dumping stops in neutral; start 40 degC."""
    return _road("mining", rate_hz, noise, seed)


def cold_start(T0_c: float, rate_hz: float = 1.0, duration_s: float = 900.0) -> RunTable:
    """SYNTHETIC cold start (not a named cycle): two minutes of idle in neutral (600 rpm, 100 Nm), then 4L at
    1300 rpm and 1500 Nm at 30 km/h; ambient at ``T0_c``, the coolant warming from ``T0_c`` to 85 degC (time
    constant 400 s). Start the plant at ``T0_c`` (every node at the ambient)."""
    t = np.arange(0.0, duration_s + 1e-9, 1.0 / rate_hz)
    load = t >= 120.0
    return RunTable(
        {
            "time_s": t,
            "engine_speed_rpm": np.where(load, 1300.0, 600.0),
            "engine_torque_nm": np.where(load, 1500.0, 100.0),
            "gear": np.where(load, 4.0, 0.0),
            "vehicle_speed_kmh": np.where(load, 30.0, 0.0),
            "ambient_temp_c": np.full(t.size, T0_c),
            "coolant_temp_c": 85.0 + (T0_c - 85.0) * np.exp(-t / 400.0),
        },
        meta={"initial_temp_c": float(T0_c), "cycle": f"cold_start:{T0_c:g}", "synthetic": True},
    )


def road_profile(name: str, seed: int = 0) -> dict:
    """Distance, grade and altitude of a road cycle at the vehicle model's 10 Hz (for plots and docs)."""
    if name not in _ROAD:
        raise InputError(f"{name!r} has no road profile; road cycles are {', '.join(_ROAD)}")
    src = _road_cycle(name, int(seed))
    return {k: getattr(src, k).copy() for k in ("time_s", "distance_m", "grade", "altitude_m")}


def _check_rate(rate_hz) -> float:
    try:
        r = float(rate_hz)
    except (TypeError, ValueError):
        raise InputError(f"sample rate {rate_hz!r} is not a number") from None
    if not math.isfinite(r) or r <= 0 or r > 1000:
        raise InputError(f"sample rate {rate_hz!r} Hz must be in (0, 1000]")
    return r


def get_cycle(
    spec: str | os.PathLike, rate_hz: float = 10.0, noise: bool = False, seed: int = 0, description=None
) -> RunTable:
    """A named cycle, a 'steady:...' spec, or a CSV run table (read and validated; rate, noise and seed ignored; a
    fixed-ratio drive's mapped for ``description``, the gearbox's: tools.drive_table; None: the GRS905)."""
    s = os.fspath(spec).strip() if not isinstance(spec, str) else spec.strip()
    rate_hz = _check_rate(rate_hz)
    low = s.lower()
    is_file = low.endswith(".csv") or os.sep in s or "/" in s or Path(s).is_file()
    if not is_file and description is not None and description.drive.kind != "vehicle":
        if low.startswith("steady:"):  # its input shaft's speed and torque held, as a rig holds them
            return _fixed_steady(s, description, rate_hz)
        # the named cycles drive a truck (engine speed, torque, gear): another drive takes its own run table
        raise InputError(
            f"drive cycle {s!r} is a truck's, but gearbox {description.name} has a {description.drive.kind} drive: "
            f"give a CSV run table with time_s, input_speed_rpm, input_torque_nm, ambient_temp_c, or "
            f"'steady:rpm=N,nm=N' (its input shaft held)"
        )
    if low == "steady" or low.startswith("steady:"):
        limits = {}
        if description is not None:  # the gearbox's own drive limits (the plant refuses rows beyond them)
            limits = {
                "max_rpm": description.drive.max_speed_rad_s * 30.0 / math.pi,
                "max_nm": description.drive.max_torque_nm,
            }
        if own_gears(description):  # its gear numbers and names, not the GRS905's Table 1 (tools.cycles.fit)
            s_grs, gear = _own_steady_gear(s, description)
            p = dict(parse_steady_spec(s_grs, **limits), gear=gear)
            neutral = gear in (g.number for g in description.gears if not math.isfinite(g.ratio))
            if neutral and "nm=" not in s_grs.replace(" ", "").lower():
                p["nm"] = 0.0  # neutral idles, as the GRS905's gear=0
            if neutral and p["nm"] != 0:
                raise InputError(f"steady cycle spec {s!r}: nm={p['nm']:g} in neutral reaches no gear; give nm=0")
        else:
            p = parse_steady_spec(s, **limits)
        return steady(**p, rate_hz=rate_hz, noise=noise, seed=seed, spec=s, description=description)
    if low == "all_gears":
        table = all_gears(rate_hz=rate_hz, noise=noise, seed=seed)
        return fit_cycle(table, description) if own_gears(description) else table
    if low in _ROAD:
        table = _road(low, rate_hz, noise, seed)
        return fit_cycle(table, description) if own_gears(description) else table
    if is_file:
        from tools.drive_table import read_drive_table

        return read_drive_table(s, description)
    raise InputError(
        f"unknown drive cycle {s!r}: give one of {', '.join(CYCLE_NAMES)} "
        f"(steady:gear=4L,rpm=1300,nm=2000,s=3600,oil=100) or the path of a CSV run table"
    )


#: the air around a fixed-ratio drive's steady spec [degC] (the start's default too, as a truck's steady spec)
FIXED_STEADY_AMBIENT_C = 20.0


def _fixed_steady(spec: str, description, rate_hz: float) -> RunTable:
    """A fixed-ratio drive's 'steady:rpm=N,nm=N[,s=..,oil=..,init=..,ambient=..]': its input shaft at that speed
    [rpm] and torque [N m] (both given: the truck's defaults are no other drive's) in the air of ambient=, else of
    its description's ambient boundary, mapped as its CSV run table is (tools.drive_table)."""
    from tools.drive_table import map_fixed_ratio
    from tools.runtable import validate_run_table

    keys = [p.partition("=")[0].strip().lower() for p in spec.partition(":")[2].split(",") if p.strip()]
    if "gear" in keys:
        raise InputError(f"steady cycle spec {spec!r}: gearbox {description.name} has one gear; leave gear= out")
    if not {"rpm", "nm"} <= set(keys):
        raise InputError(
            f"steady cycle spec {spec!r}: give rpm= and nm= of gearbox {description.name}'s input shaft (its drive "
            f"turns up to {description.drive.max_speed_rad_s * 30.0 / math.pi:.4g} rpm and "
            f"{description.drive.max_torque_nm:.4g} N m)"
        )
    p = parse_steady_spec(
        spec, max_rpm=description.drive.max_speed_rad_s * 30.0 / math.pi, max_nm=description.drive.max_torque_nm
    )
    t = _out_time(p["s"], rate_hz)
    # the air: ambient=, else the description's ambient boundary (a reducer's steady run took 20 degC for its
    # description's 25: a trial), else FIXED_STEADY_AMBIENT_C
    own_air = next((b.temperature_c for b in description.boundaries if b.id == "ambient"), FIXED_STEADY_AMBIENT_C)
    air_c = float(p["ambient"] if p["ambient"] is not None else own_air)
    cols = {
        "time_s": t,
        "input_speed_rpm": np.full(t.size, p["rpm"]),
        "input_torque_nm": np.full(t.size, p["nm"]),
        "ambient_temp_c": np.full(t.size, air_c),
    }
    init_c = p["init"] if p["init"] is not None else (p["oil"] if p["oil"] is not None else air_c)
    meta = {"cycle": spec, "initial_temp_c": float(init_c), "hold_oil_c": p["oil"], "rate_hz": float(rate_hz)}
    meta.update(noise=False, seed=0, synthetic=True)
    return validate_run_table(map_fixed_ratio(RunTable(cols, meta=meta), description, spec), name=spec)


def _own_steady_gear(spec: str, description) -> tuple[str, int]:
    """(the spec without its gear, the gear number) of a steady spec on a gearbox outside the GRS905 family: gear= is
    one of its gear numbers or names; left out, its forward gear nearest the GRS905's 4L in ratio (the default)."""
    head, _, rest = spec.partition(":")
    items = [p for p in (q.strip() for q in rest.split(",")) if p]
    given = [p for p in items if p.partition("=")[0].strip().lower() == "gear"]
    others = ",".join(p for p in items if p not in given)
    if not given:
        return f"{head}:{others}", nearest_gear(description, total_ratios()[parse_gear("4L")])
    token = given[0].partition("=")[2].strip()
    by_name = {g.name.lower(): g.number for g in description.gears}
    numbers = {g.number for g in description.gears}
    try:
        gear = by_name[token.lower()] if token.lower() in by_name else int(token)
    except ValueError:
        gear = None
    if gear not in numbers or len(given) > 1:
        why = "is given twice; give it once" if len(given) > 1 else f"is no gear of {description.name}"
        raise InputError(f"steady cycle spec {spec!r}: gear={token} {why}; its gears: {gear_list(description)}")
    return f"{head}:{others}", gear


# ----------------------------------------------------------------------------------------------------------------
# summaries (docs, --help, tests)

GEAR_GROUPS = (
    ("reverse", (-2, -1)),
    ("neutral", (0,)),
    ("crawler CL-CH", (1, 2)),
    ("low range 1L-3H", range(3, 9)),
    ("4L-5L", (9, 10, 11)),
    ("5H-6L", (12, 13)),
    ("6H direct", (14,)),
)


def summarize(table: RunTable) -> dict:
    """Duration, time share per gear group, torque statistics of a cycle (time-weighted by sample spacing)."""
    t = table.time_s
    dt = np.diff(t, append=t[-1] + (t[-1] - t[-2] if t.size > 1 else 1.0))
    g = table["gear"]
    tq = table["engine_torque_nm"]
    total = float(dt.sum())
    share = {name: float(dt[np.isin(g, list(gs))].sum() / total) for name, gs in GEAR_GROUPS}
    res = {
        "duration_s": total,
        "share": share,
        "mean_torque_nm": float(np.sum(tq * dt) / total),
        "max_torque_nm": float(tq.max()),
        "min_torque_nm": float(tq.min()),
        "max_rpm": float(table["engine_speed_rpm"].max()),
        "shifts": int(np.count_nonzero(np.diff(g))),
    }
    if table.has("retarder_torque_nm"):
        res["retarder_share"] = float(dt[table["retarder_torque_nm"] > 1.0].sum() / total)
    if table.has("vehicle_speed_kmh"):
        res["distance_km"] = float(np.sum(table["vehicle_speed_kmh"] / KMH_PER_M_S * dt) / 1000.0)
    return res


def boundaries_a_log_cannot_carry(table, description) -> str | None:
    """The rest of a note ("... carries no boundary temperatures ...") when the cycle's boundary temperatures
    (bc_<id>_c: the named cycles' engine-side ones) differ from the gearbox's own by more than 0.5 K: a CAN log or
    bus carries none of them, so a sensor reading the frames takes the description's, and the difference shows as a
    gap (an effect-free uphill log diagnosed as hot_surroundings_offset +29.5 K); None: they agree."""
    differ = []
    for b in description.boundaries:
        col = f"bc_{b.id}_c"
        if table.has(col):
            v = np.asarray(table[col], dtype=float)
            v = v[np.isfinite(v)]
            if v.size and abs(float(np.mean(v)) - b.temperature_c) > 0.5:
                differ.append(f"{b.id} {float(np.mean(v)):.0f} (its own {b.temperature_c:g})")
    if not differ:
        return None
    return (
        f"carries no boundary temperatures, and this cycle's differ from the gearbox's own: {', '.join(differ)} "
        "degC; a sensor reading its frames (replay, run, diagnose) takes its own, so the difference shows as a gap "
        "there (the run table keeps them as bc_ columns)"
    )
