"""Operating regimes of a SCADA record, and where a model's residual lies among them (docs/real-data.md, "The gap on
real data").

A regime is a boolean mask over the record's rows: the power bins (standstill and idling, then producing up to
rated), the first hour after a start, a cold or warm nacelle, and the thermostat (closed, opening, open) read from
the measured sump against the gearbox description's thermostat temperatures. :func:`where` splits a channel's
squared residual among them: its share of the sum over all channels (a row is in one power bin, and in any number
of the other regimes) and its mean, so that a gap concentrated at full load or with the cooler open shows as such.
"""

from __future__ import annotations

import numpy as np

from tools.scada.reader import ScadaRecord

#: the power bins [kW] (lower edge inclusive); below the first: standstill and idling (P <= 0 counts there too)
POWER_BINS_KW = (0.0, 250.0, 750.0, 1500.0)
#: a row counts as producing above this power [kW]
PRODUCING_KW = 10.0
#: the first rows after a start (the turbine producing after at least one row that did not) count as the start
START_ROWS = 6
#: the nacelle splits cold / warm at this temperature [degC]
NACELLE_SPLIT_C = 20.0


def _starts(producing: np.ndarray, stretch: np.ndarray) -> np.ndarray:
    """Rows within START_ROWS of a start (producing after a row that did not, in the same stretch)."""
    start = producing & np.concatenate([[False], ~producing[:-1] & (stretch[1:] == stretch[:-1])])
    out = np.zeros(producing.size, dtype=bool)
    for i in np.flatnonzero(start):
        out[i : i + START_ROWS] = True
    return out & producing


def regimes(record: ScadaRecord, thermostat_c: tuple[float, float] | None = None, sump: str | None = None) -> dict:
    """{regime name: row mask} of ``record``. ``thermostat_c``: (opens, fully open) [degC] of the description's
    cooler bypass, read on the measured ``sump`` channel (none: no thermostat regimes)."""
    p = np.asarray(record.values.get("power_kw", np.full(record.n, np.nan)), dtype=float)
    out = {f"P <= {PRODUCING_KW:.0f} kW (standstill, idling)": ~(p > PRODUCING_KW) & np.isfinite(p)}
    edges = (*POWER_BINS_KW[1:], np.inf)
    for lo, hi in zip(POWER_BINS_KW, edges):
        lo_kw = max(lo, PRODUCING_KW)
        label = f"P {lo_kw:.0f}-{hi:.0f} kW" if np.isfinite(hi) else f"P > {lo_kw:.0f} kW"
        out[label] = (p > lo_kw) & (p <= hi)
    out[f"first {START_ROWS * 10} min after a start"] = _starts(p > PRODUCING_KW, np.asarray(record.stretch))
    air = np.asarray(record.values.get("ambient_temp_c", np.full(record.n, np.nan)), dtype=float)
    # the air's name: the map's (engie: "nacelle"), else words no gearbox is wrong about (a reducer's map said
    # "nacelle >= 20 degC" of a workshop: a trial)
    ch = record.cmap.channels.get("ambient_temp_c")
    name = (ch.what if ch is not None and ch.what else "") or "air around the gearbox"
    out[f"{name} < {NACELLE_SPLIT_C:.0f} degC"] = air < NACELLE_SPLIT_C
    out[f"{name} >= {NACELLE_SPLIT_C:.0f} degC"] = air >= NACELLE_SPLIT_C
    if thermostat_c is not None and sump is not None and sump in record.values:
        oil = np.asarray(record.values[sump], dtype=float)
        lo_c, hi_c = thermostat_c
        out[f"thermostat closed (sump < {lo_c:.0f} degC)"] = oil < lo_c
        out[f"thermostat opening ({lo_c:.0f}-{hi_c:.0f} degC)"] = (oil >= lo_c) & (oil < hi_c)
        out[f"thermostat open (sump >= {hi_c:.0f} degC)"] = oil >= hi_c
    return out


def where(residual: dict[str, np.ndarray], masks: dict[str, np.ndarray]) -> list[dict]:
    """Per channel and regime: rows, mean and RMS residual [K] and the share of the squared residual of every
    channel together; sorted by share (largest first). ``residual``: {channel: measured - model} (NaN where either
    is missing)."""
    out = []
    total = sum(float(np.sum(r[np.isfinite(r)] ** 2)) for r in residual.values())
    if total <= 0.0:
        return out
    for ch, r in residual.items():
        ok = np.isfinite(r)
        for name, m in masks.items():
            sel = ok & m
            if not sel.any():
                continue
            out.append(
                {
                    "channel": ch,
                    "regime": name,
                    "rows": int(sel.sum()),
                    "mean_c": float(np.mean(r[sel])),
                    "rms_c": float(np.sqrt(np.mean(r[sel] ** 2))),
                    "share": float(np.sum(r[sel] ** 2) / total),
                }
            )
    return sorted(out, key=lambda w: -w["share"])
