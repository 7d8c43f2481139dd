"""Operating regimes: where the model misses. The residual's square apportioned to regimes (gear range x torque,
gear, engine speed, transients, cold/warm, retarder, cooler) and to 120-s episodes; the test files' residual before
and after the verdict per regime."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from tools.diagnosis.options import OIL, Options, json_number
from tools.diagnosis.prepare import Channel, Dataset

#: the primary partition (the JSON's "where")
PRIMARY = "range x torque"
#: the partitions of the test files' before/after table
TEST_PARTITIONS = (PRIMARY, "transient / steady", "cold / warm", "retarder", "cooler")
#: episode window [s]
EPISODE_S = 120.0
#: a transient: a gear change or a torque step of more than this in the last TRANSIENT_S
TORQUE_STEP_NM = 400.0
TRANSIENT_S = 60.0


def gear_group(g):
    """Gear -> 'neutral', 'reverse', 'low range' (1..8) or 'high range'."""
    g = np.asarray(g)
    return np.where(g == 0, "neutral", np.where(g < 0, "reverse", np.where(g <= 8, "low range", "high range")))


def torque_bin(tq):
    return np.where(
        tq < 0,
        "engine braking (torque < 0)",
        np.where(tq < 800, "torque 0-800 Nm", np.where(tq < 1500, "torque 800-1500 Nm", "torque > 1500 Nm")),
    )


def speed_bin(rpm):
    return np.where(
        rpm < 1000,
        "speed < 1000 rpm",
        np.where(rpm < 1400, "speed 1000-1400 rpm", np.where(rpm < 1800, "speed 1400-1800 rpm", "speed > 1800 rpm")),
    )


def cell_inputs(ds: Dataset, ch: Channel):
    """Gear (held), engine torque and engine speed (interpolated) at the cells of channel `ch`."""
    tin = ds.inputs["time_s"]
    idx = np.clip(np.searchsorted(tin, ch.cell_t_s, side="right") - 1, 0, tin.size - 1)
    gear = ds.inputs["gear"][idx].astype(int)
    tq = np.interp(ch.cell_t_s, tin, ds.inputs["engine_torque_nm"])
    rpm = np.interp(ch.cell_t_s, tin, ds.inputs["engine_speed_rpm"])
    return gear, tq, rpm


def _last_before(event_t: np.ndarray, ct: np.ndarray) -> np.ndarray:
    """Per cell time: the time of the last event at or before it (-inf when none)."""
    last = np.full(ct.size, -np.inf)
    if event_t.size:
        j = np.searchsorted(event_t, ct, side="right") - 1
        last = np.where(j >= 0, event_t[np.maximum(j, 0)], -np.inf)
    return last


def transient_cells(ds: Dataset, ct: np.ndarray) -> np.ndarray:
    """True at the cells with a gear change or a torque step > 400 Nm in the last 60 s."""
    tin = ds.inputs["time_s"]
    gi = ds.inputs["gear"]
    tqi = ds.inputs["engine_torque_nm"]
    last_change = _last_before(tin[1:][np.diff(gi) != 0], ct)
    # torque moving average over 60 s
    dtin = float(np.median(np.diff(tin))) if tin.size > 1 else 1.0
    n60 = max(int(TRANSIENT_S / dtin), 1)
    tq_ma = np.convolve(np.pad(tqi, (n60 - 1, 0), mode="edge"), np.ones(n60) / n60, mode="valid")
    last_step = _last_before(tin[np.abs(tqi - tq_ma) > TORQUE_STEP_NM], ct)
    return (ct - np.maximum(last_change, last_step)) < TRANSIENT_S


def _cooler_labels(ct: np.ndarray, base_out: dict, params, cooler: str):
    """Thermostat state (air cooler) or the sign of the cooler's heat (liquid); None for other coolers."""
    if cooler == "air":
        to, tf = params["cooler.thermostat_open"], params["cooler.thermostat_full"]
        moil = np.interp(ct, base_out["time_s"], base_out["T_oil_c"])
        return np.where(moil < to, "thermostat closed", np.where(moil < tf, "thermostat opening", "thermostat open"))
    if cooler == "liquid":
        qc = np.interp(ct, base_out["time_s"], base_out.get("Q_out_cooler_w", np.zeros(base_out["time_s"].size)))
        return np.where(
            qc > 300, "cooler cooling", np.where(qc < -300, "cooler heating the oil", "cooler near balance")
        )
    return None


def regime_labels(ds: Dataset, ch: Channel, base_out: dict, params, cooler: str, opts: Options) -> dict:
    """Partition name -> label per cell of channel `ch`."""
    from firmware_model.physics.kinematics import GEAR_NAMES

    tin = ds.inputs["time_s"]
    ct = ch.cell_t_s
    gear, tq, rpm = cell_inputs(ds, ch)
    lab = {PRIMARY: np.char.add(np.char.add(gear_group(gear).astype(str), ", "), torque_bin(tq).astype(str))}
    lab[PRIMARY] = np.where(gear == 0, "neutral", lab[PRIMARY])
    lab["gear"] = np.array([f"gear {GEAR_NAMES[int(g)]}" for g in gear])
    lab["engine speed"] = speed_bin(rpm)
    lab["speed x torque"] = np.char.add(np.char.add(speed_bin(rpm).astype(str), ", "), torque_bin(tq).astype(str))
    lab["transient / steady"] = np.where(
        transient_cells(ds, ct), "transient (gear change or torque step in the last 60 s)", "steady"
    )
    oil = np.interp(ct, base_out["time_s"], base_out["oil_temp_c"])
    if OIL in ds.channels:
        o = ds.channels[OIL]
        oil = np.interp(ct, o.t_s, o.y_c)
    lab["cold / warm"] = np.where(oil < opts.cold_c, f"cold (oil < {opts.cold_c:g} degC)", "warm")
    if ds.inputs.has("retarder_torque_nm"):
        ret = np.interp(ct, tin, np.nan_to_num(ds.inputs["retarder_torque_nm"]))
        lab["retarder"] = np.where(ret > 100, "retarder active", "retarder off")
    cool = _cooler_labels(ct, base_out, params, cooler)
    if cool is not None:
        lab["cooler"] = cool
    return lab


# ----------------------------------------------------------------------------------------------------------------
# the residual by regime


@dataclass
class RegimeSum:
    """The residual accumulated over the cells of one regime."""

    sq_c2: float = 0.0  # sum of r^2
    cells: int = 0
    sum_c: float = 0.0  # sum of r


class Episode(NamedTuple):
    """A 120-s window of one file and channel: its sum of r^2 and mean residual."""

    channel: str
    file: str
    t_start_s: float
    t_end_s: float
    sq_c2: float
    mean_c: float


def _by_regime(datasets, outs, resid, params, cooler, opts) -> tuple:
    """(channel -> partition -> regime -> RegimeSum, the Episodes)."""
    parts = {}
    ep = []
    k = 0
    for ds, out in zip(datasets, outs):
        for cid, ch in ds.channels.items():
            r = resid[k]
            k += 1
            labs = regime_labels(ds, ch, out, params, cooler, opts)
            for part, lab in labs.items():
                d = parts.setdefault(cid, {}).setdefault(part, {})
                for L in np.unique(lab):
                    m = lab == L
                    a = d.setdefault(str(L), RegimeSum())
                    a.sq_c2 += float(np.sum(r[m] ** 2))
                    a.cells += int(m.sum())
                    a.sum_c += float(np.sum(r[m]))
            w = EPISODE_S
            kk = np.floor((ch.cell_t_s - ds.t_start_s) / w).astype(int)
            e2 = np.bincount(kk, r**2)
            for j in np.flatnonzero(e2):
                ep.append(
                    Episode(
                        cid,
                        ds.name,
                        ds.t_start_s + j * w,
                        min(ds.t_start_s + (j + 1) * w, ds.t_end_s),
                        float(e2[j]),
                        float(np.sum(r[kk == j]) / max((kk == j).sum(), 1)),
                    )
                )
    return parts, ep


def _shares(regs: dict) -> list:
    tot = sum(a.sq_c2 for a in regs.values()) or 1.0
    ntot = sum(a.cells for a in regs.values()) or 1
    lst = [
        {
            "regime": L,
            "share": json_number(a.sq_c2 / tot, 4),
            "time_share": json_number(a.cells / ntot, 4),
            "rms_c": json_number(math.sqrt(a.sq_c2 / max(a.cells, 1))),
            "mean_c": json_number(a.sum_c / max(a.cells, 1)),
        }
        for L, a in regs.items()
    ]
    lst.sort(key=lambda x: -x["share"])
    return lst


class Where(NamedTuple):
    where: list  # the primary partition, every channel, largest share first
    where_by: dict  # channel -> partition -> regimes
    episodes: list  # the 10 episodes with the largest share


def where_residual(datasets: list, outs: list, resid: list, params, cooler: str, opts: Options) -> Where:
    """(where, where_by, episodes) of the JSON: the residual's square by regime (the primary partition ranked over
    channels), by every partition per channel, and the 10 episodes with the largest share."""
    parts, ep = _by_regime(datasets, outs, resid, params, cooler, opts)
    where, where_by = [], {}
    for cid, d in parts.items():
        where_by[cid] = {}
        for part, regs in d.items():
            lst = _shares(regs)
            where_by[cid][part] = lst
            if part == PRIMARY:
                for x in lst:
                    where.append({"channel": cid, **x})
    where.sort(key=lambda x: (-x["share"], x["channel"], x["regime"]))
    tot_ch = {}
    for e in ep:
        tot_ch[e.channel] = tot_ch.get(e.channel, 0.0) + e.sq_c2
    ep.sort(key=lambda e: -e.sq_c2 / (tot_ch[e.channel] or 1.0))
    episodes = [
        {
            "channel": e.channel,
            "file": e.file,
            "t_start_s": json_number(e.t_start_s, 1),
            "t_end_s": json_number(e.t_end_s, 1),
            "share": json_number(e.sq_c2 / (tot_ch[e.channel] or 1.0), 4),
            "mean_c": json_number(e.mean_c),
        }
        for e in ep[:10]
    ]
    return Where(where, where_by, episodes)


def regimes_before_after(
    datasets: list, outs: list, res0: list, res1: list, params, cooler: str, opts: Options
) -> list:
    """The test files' residual before (res0) and after (res1) per regime of the TEST_PARTITIONS."""
    acc = {}
    k = 0
    for ds, out in zip(datasets, outs):
        for cid, ch in ds.channels.items():
            labs = regime_labels(ds, ch, out, params, cooler, opts)
            r0, r1 = res0[k], res1[k]
            k += 1
            for part in TEST_PARTITIONS:
                if part not in labs:
                    continue
                for L in np.unique(labs[part]):
                    m = labs[part] == L
                    a = acc.setdefault((cid, part, str(L)), [0.0, 0.0, 0, 0.0, 0.0])
                    a[0] += float(np.sum(r0[m] ** 2))
                    a[1] += float(np.sum(r1[m] ** 2))
                    a[2] += int(m.sum())
                    a[3] = max(a[3], float(np.max(np.abs(r0[m]))))
                    a[4] = max(a[4], float(np.max(np.abs(r1[m]))))
    out = [
        {
            "channel": c,
            "partition": p,
            "regime": L,
            "rms_before_c": json_number(math.sqrt(a[0] / a[2])),
            "rms_after_c": json_number(math.sqrt(a[1] / a[2])),
            "max_before_c": json_number(a[3]),
            "max_after_c": json_number(a[4]),
            "cells": a[2],
        }
        for (c, p, L), a in acc.items()
    ]
    out.sort(key=lambda x: (x["channel"] != OIL, x["channel"], x["partition"], -x["rms_before_c"]))
    return out


#: regimes that hold less than this share of a channel's time are left out of its residual structure
STRUCTURE_MIN_TIME_SHARE = 0.05
#: a residual is "the same everywhere" when its regime means spread by at most this share of its overall mean
STRUCTURE_CONSTANT_SPREAD = 0.5


def residual_structure(where_by: dict, gap_channels) -> dict:
    """Per channel with a real gap: how the baseline residual (measured - model) varies over the operating regimes
    of the primary partition. ``constant``: every regime's mean has the sign of the overall mean and they spread by
    at most STRUCTURE_CONSTANT_SPREAD of it (a sensor offset or placement looks like this: the same error whatever
    the load); ``load-dependent`` otherwise (a heat-flow effect grows with the load or the speed)."""
    out = {}
    for cid in gap_channels:
        regs = [
            r
            for r in where_by.get(cid, {}).get(PRIMARY, [])
            if (r.get("time_share") or 0.0) >= STRUCTURE_MIN_TIME_SHARE and r.get("mean_c") is not None
        ]
        if not regs:
            continue
        w = np.array([r["time_share"] for r in regs])
        means = np.array([r["mean_c"] for r in regs])
        overall = float(np.sum(w * means) / np.sum(w))
        spread = float(means.max() - means.min())
        same_sign = bool(np.all(np.sign(means) == np.sign(overall))) and overall != 0.0
        kind = "constant" if same_sign and spread <= STRUCTURE_CONSTANT_SPREAD * abs(overall) else "load-dependent"
        out[cid] = {
            "kind": kind,
            "mean_c": json_number(overall),
            "spread_c": json_number(spread),
            "regimes": [
                {"regime": r["regime"], "mean_c": r["mean_c"], "time_share": r["time_share"]}
                for r in sorted(regs, key=lambda r: -r["time_share"])
            ],
        }
    return out


def structure_sentence(cid: str, st: dict, better: str | None = None) -> str:
    """One sentence on a channel's residual structure, with the evidence (the largest regimes' means). `better`: the
    best-ranked candidate when it is not this channel's sensor effect; then a constant residual is no evidence of a
    sensor fault (a drive over few regimes leaves a heat flow's residual constant too) and none is claimed."""
    name = "oil sensor" if cid == "oil" else f"{cid} thermocouple"
    regs = ", ".join(f"{r['mean_c']:+.1f} K in {r['regime']}" for r in st["regimes"][:3])
    if st["kind"] == "constant" and better:
        return (
            f"the {name}'s residual is about the same in every operating regime met ({regs}; spread "
            f"{st['spread_c']:.1f} K around {st['mean_c']:+.1f} K), as a sensor offset's would be, but the best "
            f"candidate is {better}, not this sensor's own effect, so no sensor fault is claimed"
        )
    if st["kind"] == "constant":
        return (
            f"the {name}'s residual is about the same in every operating regime ({regs}; spread "
            f"{st['spread_c']:.1f} K around {st['mean_c']:+.1f} K): the same error whatever the load, the "
            f"signature of a sensor or placement fault (an offset, or a gain over a narrow span of temperatures) "
            f"rather than of a heat flow"
        )
    return (
        f"the {name}'s residual depends on the operating regime ({regs}; spread {st['spread_c']:.1f} K): a "
        f"heat-flow effect rather than a sensor offset"
    )
