"""Withheld-effect benchmark of the gap diagnosis (`gearbox-vsensor bench-diagnosis`).

Each scenario plants one catalog effect (or none) at a random magnitude in the reference plant, drives it over
SYNTHETIC training cycles and DIFFERENT synthetic test cycles, turns the plant's temperatures into measurements like
real sensors (first-order sensor lag of a few seconds, Gaussian noise, J1939 quantisation 0.03125 degC, a few dropped
samples) with only the channels a real set-up has (truck: the oil sensor; rig: the oil plus three thermocouples),
and hands the measured run tables to the diagnosis with the effect's identity withheld. The score: top-1
identification (a declared confusable group counts only when the true effect is in it), false alarms on the null
scenarios, the test-set RMS shrink and the time per scenario.

The cycles are short parameterised mixes (:func:`mixed_cycle`) of blocks modelled on the seed's load cases: loaded
climbs in low range, cruising in high range, descents on engine brake and retarder, stop-and-go with many shifts,
idling in neutral. They are NOT measurements.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from firmware_model.effects import CATALOG, CHANNEL_EFFECTS, PHYSICAL_EFFECT_IDS, channel_effect, effect_channel
from firmware_model.units import RAD_S_PER_RPM
from tools.cycles.vehicle import KMH_PER_M_S, total_ratios
from tools.runtable import RunTable

#: the J1939 temperature resolution (TRF1 SPN 177, rig thermocouples)
J1939_TEMP_RES_C = 0.03125
#: thermocouples of the rig set-up (seed section 4.3 measured a main-shaft wheel; the sun wheel is the hottest)
RIG_CHANNELS = ("PS", "LI.teeth", "BLR")
#: vehicle (assumed, as in tools/cycles/vehicle.py): final drive, wheel radius
FINAL_DRIVE = 3.07
WHEEL_RADIUS_M = 0.5


# ----------------------------------------------------------------------------------------------------------------
# synthetic cycles


def _vehicle_kmh(gear: np.ndarray, rpm: np.ndarray) -> np.ndarray:
    r = total_ratios()
    rt = np.array([r[int(g)] for g in gear])
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.where(
            np.isfinite(rt) & (rt != 0),
            rpm * RAD_S_PER_RPM / (np.abs(rt) * FINAL_DRIVE) * WHEEL_RADIUS_M * KMH_PER_M_S,
            0.0,
        )
    return v


def _block(kind: str, rng: np.random.Generator, dt: float):
    """One block of a mixed cycle: arrays (rpm, torque, gear, retarder) at `dt`."""
    if kind == "climb":
        dur = rng.uniform(180, 360)
        g = int(rng.choice([3, 4, 5, 6, 7, 8, 9, 10]))
        rpm0 = rng.uniform(1100, 1600)
        tq0 = rng.uniform(1500, 2600)
        n = int(dur / dt)
        t = np.arange(n) * dt
        rpm = rpm0 + 80 * np.sin(2 * np.pi * t / rng.uniform(40, 90))
        tq = tq0 + 150 * np.sin(2 * np.pi * t / rng.uniform(30, 70) + 1.0)
        gear = np.full(n, g)
        if rng.random() < 0.6:  # one upshift half way
            gear[n // 2 :] = min(g + 1, 10)
        ret = np.zeros(n)
    elif kind == "cruise":
        dur = rng.uniform(180, 420)
        g = int(rng.choice([12, 13, 14, 14]))
        n = int(dur / dt)
        t = np.arange(n) * dt
        rpm = rng.uniform(1150, 1450) + 40 * np.sin(2 * np.pi * t / rng.uniform(60, 120))
        tq = rng.uniform(300, 1100) + 200 * np.sin(2 * np.pi * t / rng.uniform(40, 100))
        gear = np.full(n, g)
        ret = np.zeros(n)
    elif kind == "descent":
        dur = rng.uniform(120, 240)
        g = int(rng.choice([12, 13, 14]))
        n = int(dur / dt)
        t = np.arange(n) * dt
        rpm = rng.uniform(1300, 1800) + 50 * np.sin(2 * np.pi * t / 50.0)
        tq = np.full(n, -rng.uniform(250, 600))
        gear = np.full(n, g)
        ret = np.clip(rng.uniform(1200, 3500) + 400 * np.sin(2 * np.pi * t / rng.uniform(30, 60)), 0, 3500)
    elif kind == "stopgo":
        rpm_l, tq_l, g_l = [], [], []
        n_launch = int(rng.integers(2, 4))
        for _ in range(n_launch):
            top = int(rng.integers(8, 12))
            for g in range(3, top + 1):
                ns = int(rng.uniform(4, 9) / dt)
                rpm_l.append(np.linspace(1000, rng.uniform(1450, 1750), ns))
                tq_l.append(np.full(ns, rng.uniform(1300, 2300)))
                g_l.append(np.full(ns, g))
            ns = int(rng.uniform(20, 50) / dt)  # short cruise
            rpm_l.append(np.full(ns, rng.uniform(1100, 1400)))
            tq_l.append(np.full(ns, rng.uniform(400, 900)))
            g_l.append(np.full(ns, top))
            for g in range(top, 2, -2):  # braking with downshifts
                ns = int(rng.uniform(3, 6) / dt)
                rpm_l.append(np.linspace(1500, 1000, ns))
                tq_l.append(np.full(ns, -rng.uniform(150, 400)))
                g_l.append(np.full(ns, g))
            ns = int(rng.uniform(15, 40) / dt)  # standing in neutral
            rpm_l.append(np.full(ns, 600.0))
            tq_l.append(np.full(ns, 40.0))
            g_l.append(np.zeros(ns))
        rpm, tq, gear = np.concatenate(rpm_l), np.concatenate(tq_l), np.concatenate(g_l)
        ret = np.zeros(rpm.size)
    elif kind == "idle":
        n = int(rng.uniform(60, 150) / dt)
        rpm, tq, gear, ret = np.full(n, 600.0), np.full(n, 40.0), np.zeros(n), np.zeros(n)
    else:  # pragma: no cover - programming error
        raise ValueError(kind)
    return rpm, tq, gear.astype(float), ret


BLOCKS = ("climb", "cruise", "descent", "stopgo", "idle")


def mixed_cycle(
    seed: int,
    duration_s: float = 1500.0,
    rate_hz: float = 1.0,
    initial_temp_c: float | None = None,
    ambient_c: float | None = None,
    coolant_c: float | None = None,
) -> RunTable:
    """A SYNTHETIC mix of the blocks in BLOCKS (every block type at least once, random order, magnitudes and
    durations), `duration_s` long at `rate_hz`. Deterministic for a seed. Columns: the contract's inputs (engine
    speed and torque, gear, vehicle speed, retarder torque, ambient and coolant temperature); the coolant signal is
    whole degrees (J1939 ET1 resolution) warming from the initial temperature to its running value. The initial
    temperature is carried in ``meta['initial_temp_c']``."""
    rng = np.random.default_rng([int(seed), 0xD1A6])
    dt = 1.0 / rate_hz
    kinds = list(BLOCKS)
    rng.shuffle(kinds)
    parts = []
    total = 0.0
    while total < duration_s:
        for k in kinds:
            b = _block(k, rng, dt)
            parts.append(b)
            total += b[0].size * dt
            if total >= duration_s:
                break
        kinds = list(rng.permutation(BLOCKS))
    rpm, tq, gear, ret = (np.concatenate([p[i] for p in parts]) for i in range(4))
    n = int(round(duration_s * rate_hz))
    rpm, tq, gear, ret = rpm[:n], tq[:n], gear[:n], ret[:n]
    t = np.arange(n) * dt
    # 1 s ramps of torque at every gear change (torque interruption)
    ch = np.flatnonzero(np.diff(gear) != 0) + 1
    for i in ch:
        lo, hi = max(i - int(0.5 / dt), 0), min(i + int(0.5 / dt) + 1, n)
        tq[lo:hi] *= 0.2
    tq = np.clip(tq, -600, 2700)
    if initial_temp_c is None:
        initial_temp_c = float(rng.choice([rng.uniform(15, 40), rng.uniform(55, 80)]))
    if ambient_c is None:
        ambient_c = float(rng.uniform(5, 30))
    if coolant_c is None:
        coolant_c = float(rng.uniform(82, 92))
    tau_c = rng.uniform(400, 900)
    cool = coolant_c + (min(initial_temp_c, coolant_c) - coolant_c) * np.exp(-t / tau_c)
    cols = {
        "time_s": t,
        "engine_speed_rpm": rpm,
        "engine_torque_nm": tq,
        "gear": gear,
        "vehicle_speed_kmh": _vehicle_kmh(gear, rpm),
        "retarder_torque_nm": ret,
        "ambient_temp_c": np.round(np.full(n, ambient_c) / J1939_TEMP_RES_C) * J1939_TEMP_RES_C,
        "coolant_temp_c": np.round(cool),
    }
    return RunTable(cols, meta={"initial_temp_c": float(initial_temp_c), "cycle": f"mix:{seed}", "synthetic": True})


# ----------------------------------------------------------------------------------------------------------------
# scenarios


@dataclass
class Scenario:
    index: int
    seed: int
    setup: str  # 'truck' (oil only) or 'rig' (oil + RIG_CHANNELS)
    effect: str | None  # the withheld effect (None: null scenario)
    value: float | None
    cooler: str
    train: list = field(default_factory=list)
    test: list = field(default_factory=list)
    sensor: dict = field(default_factory=dict)
    truth_s: float = 0.0
    initial_temps_c: list = field(default_factory=list)
    also: dict = field(default_factory=dict)  # further effects planted at the same time (family "pair")


def planted_value(eid: str, rng: np.random.Generator, min_frac: float = 0.3) -> float:
    """A magnitude at least `min_frac` of the way from neutral to a bound (the side chosen at random)."""
    e = CATALOG[eid]
    sides = [b for b in (e.low, e.high) if b != e.neutral]
    bound = sides[int(rng.integers(len(sides)))]
    frac = rng.uniform(min_frac, 1.0)
    return float(e.neutral + frac * (bound - e.neutral))


def measure(
    truth: RunTable, cycle: RunTable, setup: str, rng: np.random.Generator, sensor: dict, offsets_c: dict | None = None
) -> RunTable:
    """Turn a plant output into what a truck or a rig logs: lagged, noisy, quantised, a few dropped samples, noisy
    inputs; only the channels of the set-up; `offsets_c`: {measured column: offset} of miscalibrated thermocouples."""
    from tools.diagnosis.measurement import lag_filter

    t = cycle["time_s"]
    n = t.size
    cols = {"time_s": t}
    tq = cycle["engine_torque_nm"]
    cols["engine_speed_rpm"] = np.maximum(cycle["engine_speed_rpm"] + rng.standard_normal(n) * 3.0, 0.0)
    cols["engine_torque_nm"] = tq + rng.standard_normal(n) * (0.02 * np.abs(tq) + 5.0)
    cols["gear"] = cycle["gear"]
    for c in ("vehicle_speed_kmh", "retarder_torque_nm", "ambient_temp_c", "coolant_temp_c"):
        if cycle.has(c):
            cols[c] = cycle[c]
    chans = {"oil_temp_c": "oil_temp_c"}
    if setup == "rig":
        chans.update({f"meas_T_{c}_c": f"T_{c}_c" for c in RIG_CHANNELS})
    dt = float(np.median(np.diff(truth["time_s"])))
    for col, src in chans.items():
        lag_s, sig = sensor[col]
        x = lag_filter(np.asarray(truth[src], float), lag_s, dt)
        x = np.interp(t, truth["time_s"], x)
        y = x + rng.standard_normal(n) * sig + (offsets_c or {}).get(col, 0.0)
        y = np.round(y / J1939_TEMP_RES_C) * J1939_TEMP_RES_C
        drop = rng.random(n) < 0.005
        drop[0] = False
        y[drop] = np.nan
        cols[col] = y
    return RunTable(cols)


def make_scenario(
    index: int,
    seed: int,
    setup: str,
    effect: str | None,
    value: float | None,
    params,
    cooler: str = "liquid",
    n_train: int = 2,
    train_s: float = 1500.0,
    test_s: float = 1500.0,
    truth_dt_s: float = 0.5,
    also: dict | None = None,
    rate_hz: float = 1.0,
) -> Scenario:
    """Generate one scenario: truth by the reference plant (fine step) with the withheld effect (and the effects
    `also` = {id: value} at the same time)."""
    import warnings

    from tools.plant.reference import ReferencePlant

    rng = np.random.default_rng([int(seed), int(index), 0xBE7C])
    sensor = {"oil_temp_c": (float(rng.uniform(1.0, 5.0)), float(rng.uniform(0.1, 0.2)))}
    if setup == "rig":
        for c in RIG_CHANNELS:
            sensor[f"meas_T_{c}_c"] = (float(rng.uniform(0.5, 3.0)), float(rng.uniform(0.1, 0.2)))
    sc = Scenario(index, seed, setup, effect, value, cooler, sensor=sensor, also=dict(also or {}))
    planted = ({effect: value} if effect else {}) | dict(also or {})
    # a thermocouple's offset is in the measurement, not in the plant
    offsets = {f"meas_T_{effect_channel(e)}_c": v for e, v in planted.items() if effect_channel(e) is not None}
    plant = ReferencePlant(
        params, {e: v for e, v in planted.items() if effect_channel(e) is None}, cooler=cooler, dt_s=truth_dt_s
    )
    t0 = time.perf_counter()
    cyc_seeds = rng.integers(0, 2**31, size=n_train + 1)
    for k, cs in enumerate(cyc_seeds):
        role = "train" if k < n_train else "test"
        if cooler == "air":
            # an air cooler only acts above its thermostat (80-95 degC): air-cooled runs start warm
            t_init = float(rng.uniform(55, 75)) if k == 0 else float(rng.uniform(72, 88))
        else:
            t_init = float(rng.uniform(15, 35)) if k == 0 else float(rng.uniform(45, 80))
        cyc = mixed_cycle(int(cs), train_s if role == "train" else test_s, rate_hz=rate_hz, initial_temp_c=t_init)
        sc.initial_temps_c.append(t_init)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            truth = plant.run(cyc, out_dt_s=1.0, progress=False).table
        meas = measure(truth, cyc, setup, rng, sensor, offsets)
        meas.source = f"s{index:02d}_{role}{k + 1 if role == 'train' else 1}.csv"
        (sc.train if role == "train" else sc.test).append(meas)
    sc.truth_s = time.perf_counter() - t0
    return sc


# ----------------------------------------------------------------------------------------------------------------
# the benchmark

#: scenario families of the benchmark: which effects each plants (nulls are planted in every family); "pair" plants
#: two at once: a physical effect and another physical or sensor effect (PAIR_SECOND)
FAMILIES = {
    "single": PHYSICAL_EFFECT_IDS,
    "sensor": ("oil_sensor_offset", "oil_sensor_gain", "thermocouple_offset"),
    "pair": tuple(e for e in PHYSICAL_EFFECT_IDS if e not in ("synchronizer_shift_heat", "oil_sensor_lag")),
}
PAIR_SECOND = FAMILIES["pair"] + ("oil_sensor_offset", "oil_sensor_gain")


def _pair_item(eid: str, setup: str, rng: np.random.Generator) -> tuple:
    """A two-effect scenario: `eid` and a second effect (not the same family of heat), both at least half-way to a
    bound so that each matters."""
    second = [
        e for e in PAIR_SECOND if e != eid and not (eid == "thermostat_offset" and e == "cooler_effectiveness_scale")
    ]
    e2 = second[int(rng.integers(len(second)))]
    cooler = "air" if "thermostat_offset" in (eid, e2) or rng.random() < 1 / 3 else "liquid"
    if e2 == "thermostat_offset" and cooler != "air":
        cooler = "air"
    return (setup, eid, planted_value(eid, rng, 0.5), cooler, {e2: planted_value(e2, rng, 0.5)})


def plan(n: int, seed: int, null_frac: float = 0.2, family: str = "single") -> list:
    """The scenario list: about `null_frac` null scenarios (at least 8 when n >= 40), the family's effects in turn
    (``single``: the physical effects; ``sensor``: the oil sensor's offset and gain), half truck and half rig
    (alternating within every effect), the air cooler for thermostat_offset and a third of the others."""
    rng = np.random.default_rng([int(seed), 0x91A] + ([] if family == "single" else [len(family), ord(family[0])]))
    n_null = max(int(round(null_frac * n)), min(8, n // 5) if n >= 10 else 1)
    n_eff = n - n_null
    items = []
    effects = list(FAMILIES[family])
    for k in range(n_eff):
        eid = effects[k % len(effects)]
        setup = "truck" if (k // len(effects) + k) % 2 == 0 else "rig"
        if family == "pair":
            items.append(_pair_item(eid, setup, rng))
            continue
        if eid in CHANNEL_EFFECTS:  # a rig thermocouple's offset: on a rig, on one of its channels
            setup = "rig"
            eid = channel_effect(eid, RIG_CHANNELS[int(rng.integers(len(RIG_CHANNELS)))])
        cooler = "air" if eid == "thermostat_offset" or rng.random() < 1 / 3 else "liquid"
        items.append((setup, eid, planted_value(eid, rng), cooler, {}))
    for k in range(n_null):
        items.append(("truck" if k % 2 == 0 else "rig", None, None, "air" if rng.random() < 1 / 3 else "liquid", {}))
    order = rng.permutation(len(items))
    return [items[i] for i in order]


@dataclass
class Row:
    index: int
    setup: str
    cooler: str
    effect: str | None
    value: float | None
    frac: float | None
    verdict: str
    fitted: float | None
    confusable: list
    shrink: float
    rms_before: float
    rms_after: float
    status: str
    ok: bool | None  # identified (effect) / no false alarm (null); None when excluded
    diag_s: float
    truth_s: float
    note: str = ""
    declared: bool | None = None  # pair: every missed effect listed as not excluded beside the verdict
    covered: bool | None = None  # ... with its planted value inside the listed interval
    n_not_excluded: int = 0  # effects the verdict lists as not excluded beside it
    files: int = 0  # the scenario's files (its JSON's starts)
    running: int = 0  # ... of them scored as starting while the gearbox runs


def found_set(v: dict) -> tuple:
    """(the effects a verdict names: the set, or the one effect; every effect declared confusable with one of them)."""
    if "effects" in v:
        found = [e["effect"] for e in v["effects"]]
        conf = [c for e in v["effects"] for c in e.get("confusable_with", [])]
        return found, conf
    return ([v["effect"]] if v["effect"] in CATALOG else []), list(v.get("confusable_with", []))


def _score_set(sc: Scenario, res: dict) -> tuple:
    """(ok, status) of a scenario with several planted effects: every identifiable one named (in the set, or declared
    confusable with a member); None when none of them is identifiable with the scenario's channels."""
    truth = [sc.effect] + list(sc.also)
    found, conf = found_set(res["verdict"])
    ident = {e: res["identifiability"].get(e, {}).get("identifiable", True) for e in truth}
    need = [e for e in truth if ident[e]]
    if not need:
        return None, "not identifiable"
    missed = [e for e in need if e not in found and e not in conf]
    if not missed:
        exact = set(found) == set(truth)
        return True, "both named" if exact else "named (" + ", ".join(
            e if e in found else f"{e} as confusable" for e in truth
        ) + ")"
    return False, "missed: " + ", ".join(missed) + f" (found {' + '.join(found) or res['verdict']['effect']})"


def not_excluded_of(v: dict) -> dict:
    """effect -> (low, high, indicated) of the verdict's not_excluded list (exclude.py)."""
    return {n["effect"]: (n["range"][0], n["range"][1], n["indicated"]) for n in v.get("not_excluded", [])}


def _declared(sc: Scenario, res: dict, missed: list) -> tuple:
    """(every missed effect listed as not excluded beside the verdict, and each planted value inside its interval;
    a note) for a pair scenario's misses."""
    if not missed:
        return None, None, ""
    nex = not_excluded_of(res["verdict"])
    planted = {sc.effect: sc.value, **sc.also}
    listed = [e for e in missed if e in nex]
    inside = [e for e in listed if nex[e][0] - 1e-9 <= planted[e] <= nex[e][1] + 1e-9]
    note = "; ".join(
        f"{e} {'indicated' if nex[e][2] else 'not excluded'} beside the verdict at {nex[e][0]:.3g}-"
        f"{nex[e][1]:.3g} (planted {planted[e]:.3g})"
        for e in listed
    )
    return len(listed) == len(missed), len(inside) == len(missed), note


def _below_detectable(sc: Scenario, res: dict, missed: list) -> str:
    """A note for each missed effect planted closer to neutral than the fraction of its range from which its own
    signature clears the detection threshold alone (the identifiability analysis' detectable_from_fraction)."""
    from firmware_model.effects import fraction_of_range

    planted = {sc.effect: sc.value, **sc.also}
    out = []
    for e in missed:
        dff = res["identifiability"].get(e, {}).get("detectable_from_fraction")
        frac = abs(fraction_of_range(e, planted[e]))
        if dff is not None and frac < dff:
            out.append(f"{e} planted at {frac:.2f} of its range, detectable alone from {dff:.2f}")
    return "; ".join(out)


def score_row(sc: Scenario, res: dict, diag_s: float) -> Row:
    """The scenario's row: the verdict scored against what was planted; how its files were taken to start."""
    from dataclasses import replace

    starts = res.get("starts") or {}
    return replace(
        _score_verdict(sc, res, diag_s),
        files=len(starts),
        running=sum(x.get("start") == "running" for x in starts.values()),
    )


def _score_set_verdict(sc: Scenario, res: dict, diag_s: float) -> Row:
    """The row of a scenario that plants several effects together."""
    v = res["verdict"]
    ok, status = _score_set(sc, res)
    found, conf = found_set(v)
    e = CATALOG[sc.effect]
    bound = e.high if sc.value > e.neutral else e.low
    below = _below_detectable(sc, res, [x for x in [sc.effect, *sc.also] if x not in found and x not in conf])
    note = "planted " + ", ".join(f"{k} {x:.4g}" for k, x in ({sc.effect: sc.value} | sc.also).items())
    ident = res["identifiability"]
    declared, covered, dnote = _declared(
        sc,
        res,
        [
            x
            for x in [sc.effect, *sc.also]
            if x not in found and x not in conf and ident.get(x, {}).get("identifiable", True)
        ]
        if ok is False
        else [],
    )
    note += "".join(f" ({x})" for x in (below if ok is False else "", dnote) if x)
    return Row(
        sc.index,
        sc.setup,
        sc.cooler,
        " + ".join([sc.effect] + list(sc.also)),
        sc.value,
        (sc.value - e.neutral) / (bound - e.neutral),
        " + ".join(found) or v["effect"],
        None,
        conf,
        float(v["shrink"] or 0.0),
        float(v["test_rms_before_c"] or 0.0),
        float(v["test_rms_after_c"] or 0.0),
        status,
        ok,
        diag_s,
        sc.truth_s,
        note,
        declared,
        covered,
        len(v.get("not_excluded", [])),
    )


def _score_verdict(sc: Scenario, res: dict, diag_s: float) -> Row:
    v = res["verdict"]
    if sc.also:
        return _score_set_verdict(sc, res, diag_s)
    eff = sc.effect
    conf = list(v.get("confusable_with", []))
    fitted = None
    if v["effect"] in CATALOG:
        fitted = float(next(iter(v["parameters"].values())))
    frac = None
    if eff:
        e = CATALOG[eff]
        bound = e.high if sc.value > e.neutral else e.low
        frac = (sc.value - e.neutral) / (bound - e.neutral)
    note = ""
    if eff is None:
        ok = v["effect"] == "none"
        status = "correct: none" if ok else f"FALSE ALARM: {v['effect']}"
    else:
        ident = res["identifiability"].get(eff, {})
        hit = v["effect"] == eff or (v["effect"] in CATALOG and eff in conf)
        if not ident.get("identifiable", True):
            ok = None
            status = ident.get("note") or "not identifiable"
            if v["effect"] in CATALOG and not hit:
                status += f"; but claimed {v['effect']}"
                ok = False
        elif hit:
            ok = True
            status = "identified" if v["effect"] == eff else f"identified (confusable with {v['effect']})"
        else:
            ok = False
            dff = ident.get("detectable_from_fraction")
            status = f"missed: {v['effect']}"
            if dff is not None and frac is not None and frac < dff:
                note = f"planted at {frac:.2f} of its range, detectable from {dff:.2f}"
    return Row(
        sc.index,
        sc.setup,
        sc.cooler,
        eff,
        sc.value,
        frac,
        v["effect"],
        fitted,
        conf,
        float(v["shrink"] or 0.0),
        float(v["test_rms_before_c"] or 0.0),
        float(v["test_rms_after_c"] or 0.0),
        status,
        ok,
        diag_s,
        sc.truth_s,
        note,
        n_not_excluded=len(v.get("not_excluded", [])),
    )


def summarize(rows: list) -> dict:
    eff_rows = [r for r in rows if r.effect]
    null_rows = [r for r in rows if not r.effect]
    scored = [r for r in eff_rows if r.ok is not None]
    excluded = [r for r in eff_rows if r.ok is None]
    hits = [r for r in scored if r.ok]
    shrinks = [r.shrink for r in eff_rows if r.verdict.split(" + ")[0] in CATALOG]
    shr_all = [r.shrink for r in eff_rows if r.ok is not None]
    return {
        "scenarios": len(rows),
        "effect_scenarios": len(eff_rows),
        "null_scenarios": len(null_rows),
        "truck": sum(r.setup == "truck" for r in rows),
        "rig": sum(r.setup == "rig" for r in rows),
        "top1": len(hits) / len(scored) if scored else float("nan"),
        "top1_hits": len(hits),
        "top1_scored": len(scored),
        "not_identifiable": len(excluded),
        "top1_all": len(hits) / len(eff_rows) if eff_rows else float("nan"),
        "missed_below_detectable": sum(r.ok is False and "detectable alone from" in r.note for r in eff_rows),
        "false_alarms": sum(not r.ok for r in null_rows),
        "median_shrink_identified": float(np.median(shrinks)) if shrinks else float("nan"),
        "median_shrink_scored": float(np.median(shr_all)) if shr_all else float("nan"),
        "median_diag_s": float(np.median([r.diag_s for r in rows])) if rows else float("nan"),
        "max_diag_s": float(np.max([r.diag_s for r in rows])) if rows else float("nan"),
        "median_total_s": float(np.median([r.diag_s + r.truth_s for r in rows])) if rows else float("nan"),
        "declared": sum(r.ok or bool(r.declared) for r in scored),
        "covered": sum(r.ok or bool(r.covered) for r in scored),
        "not_excluded_mean": float(
            np.mean([r.n_not_excluded for r in eff_rows if r.verdict.split(" + ")[0] in CATALOG] or [float("nan")])
        ),
        "files": sum(r.files for r in rows),
        "running_files": sum(r.running for r in rows),
    }


def _pct(k: int, n: int) -> str:
    return f"{100 * k / n:.0f} %" if n else "-"


def format_table(rows: list, summary: dict) -> str:
    head = (
        "| # | set-up | cooler | withheld effect | planted | verdict | fitted | test RMS before -> after [degC] "
        "| shrink | s | result |\n|---|---|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = []
    for r in sorted(rows, key=lambda r: r.index):
        planted = "-" if r.effect is None else f"{r.value:.4g} ({100 * r.frac:.0f} %)"
        fitted = "-" if r.fitted is None else f"{r.fitted:.4g}"
        verdict = r.verdict + (f" (~ {', '.join(r.confusable)})" if r.confusable else "")
        res = r.status + (f"; {r.note}" if r.note else "")
        lines.append(
            f"| {r.index} | {r.setup} | {r.cooler} | {r.effect or 'none'} | {planted} | {verdict} | {fitted} "
            f"| {r.rms_before:.3f} -> {r.rms_after:.3f} | {100 * r.shrink:.0f} % | {r.diag_s:.0f} | {res} |"
        )
    s = summary
    pair = any(" + " in (r.effect or "") for r in rows)
    ident = (
        ("both named strictly (the planted set, or a missed one in a member's confusable_with)", "-")
        if pair
        else ("top-1 identification (identifiable effects)", ">= 90 %")
    )
    foot = (
        f"\n\n| figure | measured | target |\n|---|---|---|\n"
        f"| scenarios (effect / null; truck / rig) | {s['scenarios']} ({s['effect_scenarios']} / "
        f"{s['null_scenarios']}; "
        f"{s['truck']} / {s['rig']}) | >= 40, >= 8 null, half truck |\n"
        f"| {ident[0]} | {100 * s['top1']:.0f} % ({s['top1_hits']} of {s['top1_scored']}) | {ident[1]} |\n"
        f"| top-1 over all effect scenarios (not identifiable counted as misses) | {100 * s['top1_all']:.0f} % | - |\n"
        f"| effect scenarios reported as not identifiable with their channels | {s['not_identifiable']} | - |\n"
        + (
            f"| misses with an effect planted below the fraction of its range it is detectable from alone | "
            f"{s['missed_below_detectable']} | - |\n"
            f"| **both named or declared confusable**: every missed one in a member's confusable_with or listed "
            f"beside the verdict as not excluded with its planted value inside the listed interval (the data "
            f"cannot tell it apart) | {_pct(s['covered'], s['top1_scored'])} ({s['covered']} of "
            f"{s['top1_scored']}; listed at all: {s['declared']}) | >= 80 % |\n"
            if pair
            else ""
        )
        + f"| effects listed as not excluded beside an effect verdict (mean per verdict) | "
        f"{s['not_excluded_mean']:.1f} | - |\n"
        + f"| files scored as starting while the gearbox runs (--start) | {s['running_files']} of {s['files']} | - |\n"
        f"| false alarms on null scenarios | {s['false_alarms']} of {s['null_scenarios']} | 0 |\n"
        f"| median test-set RMS shrink (verdict = an effect) | {100 * s['median_shrink_identified']:.0f} % | >= 70 % "
        "|\n"
        f"| median diagnosis time per scenario (max) | {s['median_diag_s']:.0f} s ({s['max_diag_s']:.0f} s) | <= 60 "
        "s |\n"
        f"| median time per scenario incl. generating the truth | {s['median_total_s']:.0f} s | - |\n"
    )
    return head + "\n".join(lines) + foot


def _write_scenario(outp, i: int, sc: Scenario, res: dict, row: Row, write_scenarios: bool) -> None:
    """The scenario's JSON (with what was planted) and, with `write_scenarios`, its measured run tables."""
    import json

    from tools.runtable import write_run_table

    if write_scenarios:
        d = outp / f"scenario_{i:02d}"
        d.mkdir(exist_ok=True)
        for k, tb in enumerate(sc.train):
            write_run_table(tb, d / f"train{k + 1}.csv")
        for k, tb in enumerate(sc.test):
            write_run_table(tb, d / f"test{k + 1}.csv")
    res["bench"] = {
        "setup": sc.setup,
        "withheld_effect": sc.effect,
        "value": sc.value,
        "cooler": sc.cooler,
        "sensor": sc.sensor,
        "status": row.status,
    }
    (outp / f"scenario_{i:02d}.json").write_text(json.dumps(res, indent=1))


def _write_summary(outp, rows: list, summary: dict) -> None:
    """bench.md (the table) and bench.csv (the rows)."""
    import csv

    (outp / "bench.md").write_text(format_table(rows, summary))
    with open(outp / "bench.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(
            [
                "index",
                "setup",
                "cooler",
                "effect",
                "value",
                "frac",
                "verdict",
                "fitted",
                "confusable",
                "shrink",
                "rms_before_c",
                "rms_after_c",
                "status",
                "ok",
                "diag_s",
                "truth_s",
            ]
        )
        for r in rows:
            w.writerow(
                [
                    r.index,
                    r.setup,
                    r.cooler,
                    r.effect or "none",
                    r.value,
                    r.frac,
                    r.verdict,
                    r.fitted,
                    ";".join(r.confusable),
                    r.shrink,
                    r.rms_before,
                    r.rms_after,
                    r.status,
                    r.ok,
                    r.diag_s,
                    r.truth_s,
                ]
            )


def result_line(i: int, n: int, row: Row) -> str:
    """The printed result of one scenario."""
    val = row.value
    return (
        f"[{i + 1}/{n}] {row.setup:5s} {row.cooler:6s} {row.effect or 'none':27s} "
        f"{'' if val is None else f'{val:8.4g}':8s} -> {row.verdict:27s} shrink {100 * row.shrink:4.0f} % "
        f"{row.diag_s:5.1f} s  {row.status}"
    )


def run_bench(
    n: int = 40,
    seed: int = 0,
    out_dir=None,
    params=None,
    progress=print,
    model: str = "plant",
    train_s: float = 1500.0,
    test_s: float = 1500.0,
    only=None,
    opts=None,
    custom=None,
    write_scenarios: bool = False,
    bar: bool | None = None,
    family: str = "single",
) -> tuple:
    """Generate and diagnose `n` scenarios (or the one `custom` = (setup, effect, value, cooler)); returns
    (rows, summary). Writes per-scenario JSON, the table (Markdown) and a CSV of the rows into `out_dir` when given,
    and with `write_scenarios` each scenario's measured run tables. `progress` receives each scenario's result line
    (:func:`result_line`); `bar`: a progress bar over the scenarios (None: when stderr is a terminal)."""
    from pathlib import Path

    from tools.diagnosis.core import diagnose
    from tools.progress import progress as progress_bar

    if params is None:
        from firmware_model.parameters import load_parameters

        params = load_parameters("GRS905")
    items = [custom] if custom is not None else plan(n, seed, family=family)
    chosen = [i for i in range(len(items)) if only is None or i in only]
    rows = []
    outp = Path(out_dir) if out_dir else None
    if outp:
        outp.mkdir(parents=True, exist_ok=True)
    with progress_bar(len(chosen), "bench-diagnosis", enabled=bar, unit="scenario") as pbar:
        for i in chosen:
            setup, eid, val, cooler, also = (tuple(items[i]) + ({},))[:5]
            sc = make_scenario(
                i, seed, setup, eid, val, params, cooler=cooler, train_s=train_s, test_s=test_s, also=also
            )
            t0 = time.perf_counter()
            res = diagnose(sc.train, sc.test, params, model=model, cooler=cooler, opts=opts)
            row = score_row(sc, res, time.perf_counter() - t0)
            rows.append(row)
            if outp:
                _write_scenario(outp, i, sc, res, row, write_scenarios)
            pbar.update(1)
            progress(result_line(i, len(items), row))
    summary = summarize(rows)
    if outp:
        _write_summary(outp, rows, summary)
    return rows, summary
