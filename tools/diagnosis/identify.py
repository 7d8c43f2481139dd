"""Identifiability: can an effect be seen at all with the channels measured, and from which magnitude on."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from firmware_model.effects import CATALOG
from tools.diagnosis.baseline import Baseline
from tools.diagnosis.context import Context
from tools.diagnosis.options import ANALYTIC, OIL, json_number


class Identifiability(NamedTuple):
    identifiable: bool
    from_oil_alone: bool | None  # None when the oil is not measured
    max_signature_c: dict  # channel -> largest RMS change over the effect's range
    threshold_c: dict  # channel -> what a channel must see
    detectable_from_fraction: float | None  # the smallest fraction of the range a channel sees
    note: str

    def to_json(self) -> dict:
        return {
            "identifiable": self.identifiable,
            "identifiable_from_oil_alone": self.from_oil_alone,
            "max_signature_c": {c: json_number(v) for c, v in sorted(self.max_signature_c.items())},
            "threshold_c": {c: json_number(self.threshold_c[c]) for c in sorted(self.max_signature_c)},
            "detectable_from_fraction": (
                json_number(self.detectable_from_fraction, 3) if self.detectable_from_fraction is not None else None
            ),
            "note": self.note,
        }


def why_invisible(eid: str, cooler: str, train: list, base_tr: list | None = None, params=None) -> str:
    """Why an effect cannot show in these training files ('' when there is no particular reason)."""
    if eid == "thermostat_offset" and cooler != "air":
        return f"the {cooler} cooler has no thermostat"
    if eid == "cooler_effectiveness_scale" and cooler not in ("liquid", "air"):
        return f"cooler kind '{cooler}' has no cooler model"
    if eid in ("thermostat_offset", "cooler_effectiveness_scale") and cooler == "air" and base_tr and params:
        top = max(float(np.max(o["T_oil_c"])) for o in base_tr)
        if top < params["cooler.thermostat_open"] + 10.0:
            return (
                f"the oil stays below {top:.0f} degC in the training files, near or under the air cooler's "
                f"thermostat ({params['cooler.thermostat_open']:g}-{params['cooler.thermostat_full']:g} degC)"
            )
    if eid == "retarder_heat":
        used = any(
            ds.inputs.has("retarder_torque_nm") and np.any(np.nan_to_num(ds.inputs["retarder_torque_nm"]) > 100)
            for ds in train
        )  # an all-NaN column (no retarder frames) is no use, without numpy's warning
        if not used:
            return "the retarder is never used in the training files"
    if eid == "synchronizer_shift_heat":
        shifts = sum(int(np.count_nonzero(np.diff(ds.inputs["gear"]))) for ds in train)
        return f"{shifts} gear changes in the training files"
    if eid in ("planet_oil_h_scale", "teeth_oil_h_scale"):
        return "it moves heat between components and the oil, barely changing the oil itself"
    return ""


class Signature(NamedTuple):
    max_rms_c: dict  # channel -> largest RMS change
    frac_min: float | None  # smallest fraction of the range some channel sees


def _signature(eid: str, grid: dict, pairs: list, p0: list, thr: dict) -> Signature:
    """The largest RMS change per channel over the grid of `eid`, and the smallest fraction some channel sees."""
    e = CATALOG[eid]
    per_ch = {}
    frac_min = None
    for v, preds in grid.items():
        if v == e.neutral:
            continue
        span = (e.high if v > e.neutral else e.low) - e.neutral
        frac = (v - e.neutral) / span if span else 0.0
        acc = {}
        for cid, p, p00 in zip(pairs, preds, p0):
            a = acc.setdefault(cid, [0.0, 0])
            a[0] += float(np.sum((p - p00) ** 2))
            a[1] += p.size
        for cid, a in acc.items():
            rms = math.sqrt(a[0] / max(a[1], 1))
            per_ch[cid] = max(per_ch.get(cid, 0.0), rms)
            if rms >= thr[cid] and (frac_min is None or frac < frac_min):
                frac_min = frac
    return Signature(per_ch, frac_min)


def identifiability(ctx: Context, base: Baseline, fits: list) -> dict:
    """Per effect: the largest RMS change its parameter can make on each channel over its range (from the
    grid re-simulations) against the 'none' threshold; identifiable when some channel sees it, and from which
    magnitude on. Effect -> Identifiability."""
    o = ctx.opts
    train = base.train.datasets
    thr = {c: max(o.ident_k * base.sigma[c], o.none_floor_c, base.floor[c]) for c in base.sigma}
    pairs = [cid for ds in train for cid in ds.channels]
    out = {}
    for f in fits:
        e = CATALOG[f.effect]
        grid = dict(f.grid)
        if f.effect in ANALYTIC:
            # the lag half-way and at its bound, exact on the baseline sump
            grid = {
                v: base.scorer.preds(train, base.base_tr, f.effect, v)
                for v in (e.neutral + 0.5 * (e.high - e.neutral), e.high)
            }
        sig = _signature(f.effect, grid, pairs, base.p0_hp, thr)
        seen = {c: (sig.max_rms_c.get(c, 0.0) >= thr[c]) for c in thr if c in pairs}
        identifiable = any(seen.values())
        oil_only = sig.max_rms_c.get(OIL, 0.0) >= thr.get(OIL, float("inf"))
        note = ""
        if not identifiable:
            note = (
                "not identifiable from oil alone" if sorted(seen) == [OIL] else "not identifiable with these channels"
            )
            why = why_invisible(f.effect, ctx.cooler, train, base.base_tr, ctx.params)
            if why:
                note += f" ({why})"
        out[f.effect] = Identifiability(
            bool(identifiable), bool(oil_only) if OIL in thr else None, sig.max_rms_c, thr, sig.frac_min, note
        )
    return out
