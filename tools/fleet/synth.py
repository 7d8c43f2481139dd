"""A synthetic fleet for tests and benchmarks: N trucks, a daily candump log each, some with effects that grow.

Each truck has a payload (a factor on the engine torque), a home climate and a drive type (long haul, uphill,
mining: the named cycles with the truck's own route seeds); each day's log is ``minutes`` of one of its drives on that
day's ambient: with probability ``cold_share`` the day's first trip from key-on after a night parked (the drive from
its start, the oil and every part 0-4 K above ambient, the coolant warming from ambient to its thermostat in ~5 min),
otherwise a window caught mid-shift (started warm: the oil at 55-85 degC, the coolant at 82-90 degC). A cold start
shows the oil's heat capacity, but weakly: a 4 L leak moves the plant's oil by 0.25-0.37 K rms over 10 minutes from
cold on the named drives, 0.14-0.24 K in a warm window (docs/fleet.md, benchmarks/bench_oil_level_signal.py). The
reference plant (tools/plant/reference.py) gives the true temperatures with the truck's effects of that day, and the
log is its J1939 traffic (tools/can/logsynth.py; no rig thermocouples: a truck has one oil sensor). Effects start at a
random
day and grow linearly to their final value over ``growth_days`` (a fouling cooler, an oil leak). The truth (effects,
onsets, values per day) is written beside the manifest as ``truth.json``; the fleet command never reads it.
"""

from __future__ import annotations

import datetime as dt
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from firmware_model.errors import InputError

DRIVES = ("long_haul", "uphill", "mining")
#: the effects a synthetic fleet injects: (effect id, its parameter at full growth range)
FAULT_RANGES = {"cooler_effectiveness_scale": (0.35, 0.5), "oil_level_low": (9.0, 10.0)}
START_DATE = dt.date(2026, 1, 5)
#: time constant of the coolant warming from ambient to its thermostat after a cold start [s]
COOLANT_WARMUP_S = 300.0
#: the level sensor (SPN 124) of the trucks that send it: slosh noise at standstill and driving [%], the spread of
#: each sensor's fixed offset [%], the oil's volumetric expansion [1/K] (mineral gear oil ~7e-4; assumed)
LEVEL_NOISE_PCT = (0.5, 4.0)
#: what the sensor reads with the nominal fill at 40 degC [%] (100 % is the top of its range, above the fill plug)
LEVEL_AT_NOMINAL_PCT = 90.0
LEVEL_OFFSET_PCT = 2.0
OIL_EXPANSION_PER_K = 7e-4
LEVEL_STREAM = 0x1E7E1


@dataclass
class FleetSpec:
    """How many trucks and days, how long each day's log, which trucks get which effect (chosen at random)."""

    vehicles: int = 10
    days: int = 7
    minutes: float = 10.0
    fouling: int = 0
    low_oil: int = 0
    growth_days: float = 21.0
    seed: int = 0
    cold_share: float = 0.5  # share of the days whose log starts at key-on after a night parked
    level_share: float = 0.0  # share of the trucks whose transmission sends its oil level (SPN 124)
    start_date: dt.date = START_DATE
    faults: dict = field(default_factory=dict)  # vehicle -> (effect, onset day, final value); filled by plan()

    def plan(self) -> FleetSpec:
        if self.fouling + self.low_oil > self.vehicles:
            raise InputError("more faulty trucks than trucks")
        rng = np.random.default_rng(self.seed + 7919)
        chosen = rng.choice(self.vehicles, self.fouling + self.low_oil, replace=False).tolist()
        for j, v in enumerate(chosen):
            effect = "cooler_effectiveness_scale" if j < self.fouling else "oil_level_low"
            lo, hi = FAULT_RANGES[effect]
            onset = int(rng.integers(max(1, self.days // 4), max(2, self.days // 2)))
            self.faults[vehicle_name(v)] = (effect, onset, float(rng.uniform(lo, hi)))
        return self


def vehicle_name(i: int) -> str:
    return f"truck{i:03d}"


def effect_on_day(fault, day: int, growth_days: float) -> dict:
    """The effect dict of a truck on ``day`` (empty before the onset)."""
    if fault is None or day < fault[1]:
        return {}
    effect, onset, final = fault
    from firmware_model.effects import CATALOG

    neutral = CATALOG[effect].neutral
    frac = min(1.0, (day - onset + 1) / growth_days)
    return {effect: neutral + frac * (final - neutral)}


def _truck(spec: FleetSpec, v: int) -> dict:
    rng = np.random.default_rng(spec.seed * 1000 + v)
    return {
        "payload": float(rng.uniform(0.7, 1.25)),
        "climate_c": float(rng.uniform(2.0, 22.0)),
        "drive": DRIVES[int(rng.integers(len(DRIVES)))],
        "route_seed": int(rng.integers(0, 4)),
    }


def sends_level(spec: FleetSpec, v: int) -> bool:
    """Whether truck ``v``'s transmission sends its oil level (its own random stream: nothing else moves)."""
    return bool(np.random.default_rng([spec.seed, v, LEVEL_STREAM]).uniform() < spec.level_share)


def oil_level_pct(spec: FleetSpec, v: int, day: int, cols: dict, plant_table, volume_l: float) -> np.ndarray:
    """What the truck's level sensor reads (SPN 124) at each time of ``cols``: the oil volume as a share of the
    nominal, the oil's thermal expansion from 40 degC, the sensor's own fixed offset, and the slosh of a moving
    sump (standstill: :data:`LEVEL_NOISE_PCT` [0], driving: [1], gaussian per sample)."""
    nominal_l = _nominal_volume_l()
    truck = np.random.default_rng([spec.seed, v, LEVEL_STREAM + 1])
    offset_pct = float(truck.normal(0.0, LEVEL_OFFSET_PCT))
    rng = np.random.default_rng([spec.seed, v, day, LEVEL_STREAM + 2])
    t = cols["time_s"]
    oil_c = np.interp(t, np.asarray(plant_table["time_s"], float), np.asarray(plant_table["T_oil_c"], float))
    moving = np.asarray(cols.get("vehicle_speed_kmh", np.zeros(t.size)), float) > 1.0
    noise = rng.normal(0.0, 1.0, t.size) * np.where(moving, LEVEL_NOISE_PCT[1], LEVEL_NOISE_PCT[0])
    expansion = 1.0 + OIL_EXPANSION_PER_K * (oil_c - 40.0)
    return LEVEL_AT_NOMINAL_PCT * volume_l / nominal_l * expansion + offset_pct + noise


def _nominal_volume_l() -> float:
    from firmware_model.effects import CATALOG

    return float(CATALOG["oil_level_low"].neutral)


def _day_job(job) -> tuple[str, dict]:
    """One truck-day: plant with that day's effects, J1939 log; returns (log path, truth row)."""
    spec, v, day, out = job
    from firmware_model.config import load_config
    from tools.can.logsynth import write_can_log
    from tools.cycles.named import get_cycle
    from tools.plant.reference import ReferencePlant
    from tools.runtable import RunTable

    truck = _truck(spec, v)
    rng = np.random.default_rng(spec.seed * 100000 + v * 1000 + day)
    cyc = get_cycle(truck["drive"], seed=truck["route_seed"] + int(rng.integers(0, 3)))
    t = np.asarray(cyc["time_s"], dtype=float)
    span_s = spec.minutes * 60.0
    off = float(rng.uniform(0.0, max(t[-1] - span_s, 0.0)))
    # cold or warm: its own stream, so that the rest of the day does not depend on cold_share
    cold = bool(np.random.default_rng([spec.seed, v, day, 0xC01D]).uniform() < spec.cold_share)
    if cold:
        off = 0.0
    keep = (t >= off) & (t < off + span_s)
    cols = {c: np.asarray(cyc[c])[keep] for c in cyc.columns}
    cols["time_s"] = cols["time_s"] - cols["time_s"][0]
    cols["engine_torque_nm"] = cols["engine_torque_nm"] * truck["payload"]
    season = 8.0 * np.sin(2 * np.pi * (day + 20) / 365.0)
    amb = truck["climate_c"] + season + float(rng.normal(0.0, 3.0))
    cols["ambient_temp_c"] = np.full(cols["time_s"].size, amb)
    coolant_c = float(rng.uniform(82.0, 90.0))
    cols["coolant_temp_c"] = np.full(cols["time_s"].size, coolant_c)
    table = RunTable(cols)
    name = vehicle_name(v)
    effects = effect_on_day(spec.faults.get(name), day, spec.growth_days)
    oil0 = float(rng.uniform(55.0, 85.0))
    if cold:
        oil0 = amb + float(np.random.default_rng([spec.seed, v, day, 0xC01E]).uniform(0.0, 4.0))
        cols["coolant_temp_c"] = coolant_c - (coolant_c - oil0) * np.exp(-cols["time_s"] / COOLANT_WARMUP_S)
        table = RunTable(cols)
    plant = ReferencePlant(load_config(None).load_params(), effects=effects, dt_s=1.0).run(
        table, initial_temp_c=oil0, progress=False
    )
    date = spec.start_date + dt.timedelta(days=day)
    start = dt.datetime(date.year, date.month, date.day, 6, tzinfo=dt.timezone.utc).timestamp() + float(
        rng.uniform(0, 8 * 3600)
    )
    path = Path(out) / name / f"{name}_{date.isoformat()}.log"
    level = sends_level(spec, v)
    if level:
        volume_l = float(effects.get("oil_level_low", _nominal_volume_l()))
        table = RunTable({**cols, "oil_level_pct": oil_level_pct(spec, v, day, cols, plant.table, volume_l)})
    path.parent.mkdir(parents=True, exist_ok=True)
    write_can_log(table, plant.table, path, rig=False, start_timestamp_s=start, seed=day)
    return os.fspath(path), {
        "vehicle": name,
        "day": day,
        "date": date.isoformat(),
        "effects": effects,
        "drive": truck["drive"],
        "payload": truck["payload"],
        "ambient_c": amb,
        "cold": cold,
        "oil_start_c": oil0,
        "level_signal": level,
    }


def synth_fleet(
    out: str | os.PathLike, spec: FleetSpec, processes: int | None = None, show_progress: bool | None = None
) -> Path:
    """Write the fleet's logs under ``out/<vehicle>/``, ``out/manifest.csv`` and ``out/truth.json``; returns the
    manifest's path."""
    import multiprocessing as mp

    from tools.progress import progress

    spec.plan()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(spec, v, d, os.fspath(out)) for v in range(spec.vehicles) for d in range(spec.days)]
    n = processes or min(len(jobs), os.cpu_count() or 1)
    results = []
    with progress(len(jobs), "synthetic fleet", show_progress, unit="log") as bar:
        if n <= 1:
            for j in jobs:
                results.append(_day_job(j))
                bar.update(1)
        else:
            ctx = mp.get_context("spawn")
            with ctx.Pool(n) as pool:
                for r in pool.imap(_day_job, jobs, chunksize=4):
                    results.append(r)
                    bar.update(1)
    manifest = out / "manifest.csv"
    with open(manifest, "w", encoding="utf-8") as fh:
        fh.write("log,vehicle\n")
        for path, truth in results:
            fh.write(f"{Path(path).relative_to(out).as_posix()},{truth['vehicle']}\n")
    truth = {
        "spec": {
            "vehicles": spec.vehicles,
            "days": spec.days,
            "minutes": spec.minutes,
            "cold_share": spec.cold_share,
            "level_share": spec.level_share,
            "growth_days": spec.growth_days,
            "seed": spec.seed,
            "start_date": spec.start_date.isoformat(),
        },
        "faults": {
            v: {
                "effect": f[0],
                "onset_day": f[1],
                "onset_date": (spec.start_date + dt.timedelta(days=f[1])).isoformat(),
                "final": f[2],
            }
            for v, f in spec.faults.items()
        },
        "days": [t for _, t in results],
    }
    (out / "truth.json").write_text(json.dumps(truth, indent=1))
    return manifest


__all__ = [
    "DRIVES",
    "FAULT_RANGES",
    "FleetSpec",
    "effect_on_day",
    "oil_level_pct",
    "sends_level",
    "synth_fleet",
    "vehicle_name",
]


def main(argv=None) -> int:
    """``python -m tools.fleet.synth OUT [--vehicles N ...]``: write a synthetic fleet and its manifest."""
    import argparse

    ap = argparse.ArgumentParser(
        prog="python -m tools.fleet.synth", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("out", help="folder for the logs, manifest.csv and truth.json")
    ap.add_argument("--vehicles", type=int, default=10)
    ap.add_argument("--days", type=int, default=7)
    ap.add_argument("--minutes", type=float, default=10.0, help="length of each day's log")
    ap.add_argument("--fouling", type=int, default=0, help="trucks whose cooler fouls from a random day")
    ap.add_argument("--low-oil", type=int, default=0, help="trucks that lose oil from a random day")
    ap.add_argument("--growth-days", type=float, default=21.0, help="days from onset to the final value")
    ap.add_argument(
        "--cold-share",
        type=float,
        default=0.5,
        help="share of the days whose log starts at key-on after a night parked (default 0.5)",
    )
    ap.add_argument(
        "--level-share",
        type=float,
        default=0.0,
        help="share of the trucks whose transmission sends its oil level, J1939 SPN 124 (default 0)",
    )
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--processes", type=int, help="processes (default: one per core)")
    a = ap.parse_args(argv)
    for name in ("vehicles", "days"):
        if getattr(a, name) < 1:
            ap.error(f"--{name} must be at least 1")
    if not a.minutes > 0:
        ap.error("--minutes must be positive")
    for name in ("cold_share", "level_share"):
        if not 0.0 <= getattr(a, name) <= 1.0:
            ap.error(f"--{name.replace('_', '-')} must be between 0 and 1")
    spec = FleetSpec(
        a.vehicles, a.days, a.minutes, a.fouling, a.low_oil, a.growth_days, a.seed, a.cold_share, a.level_share
    )
    try:
        print(synth_fleet(a.out, spec, a.processes))
    except InputError as exc:
        ap.error(str(exc))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
