"""The fleet on SCADA: per unit and period (a calendar month by default), the effects that show a turbine's gearbox
ageing, fitted with their standard errors, and the units that drift from their siblings (`fleet --columns`;
docs/real-data.md, "The fleet on SCADA").

Per unit and period (:func:`fit_period`): the onboard model replayed over the unit's whole record at the neutral
effects and once per effect of :data:`EFFECTS` stepped (tools.scada.diagnose.estimates: the sump channel from the
model alone, the other channels from the measured sump); one linear least-squares solve of all the effects together
on every channel's residual gives the values, and the residual's variance with an effective sample size their
standard errors. Per period, each effect's median over all the units is the fleet's (seasons, the farm's weather
move every unit alike; with three units or more, one drifting unit does not move it); a unit's *deviation* is its
value minus that median, its *baseline* the median of its deviation over its first BASELINE_PERIODS periods (a
unit may always differ a little), and it is flagged when its deviation leaves the baseline by more than DRIFT_MIN
and 3 standard errors for CONSECUTIVE periods in a row: the first of them is the date in the flag.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from firmware_model.effects import CATALOG
from tools.fleet.health import Flag  # the truck fleet's flag row: one flags.parquet schema
from tools.scada.diagnose import Setup, effective_n, estimates
from tools.scada.reader import ScadaRecord

#: the effects fitted per unit and period: extra bearing heat (a bearing wearing), a cooler losing effectiveness
EFFECTS = ("bearing_loss_scale", "cooler_effectiveness_scale")
#: the finite-difference step of each effect (a scale: relative)
STEP = {"bearing_loss_scale": 0.2, "cooler_effectiveness_scale": -0.2}
#: periods of baseline, periods in a row that make a flag, smallest drift that counts (per effect)
BASELINE_PERIODS = 2
CONSECUTIVE = 2
DRIFT_MIN = {"bearing_loss_scale": 0.15, "cooler_effectiveness_scale": 0.15}
#: a period needs this many rows with every channel measured
MIN_ROWS = 36
#: an effect whose step moves no estimate by this much in a period is not fitted there [K]
IDENTIFIABLE_K = 0.01


class PeriodFit(NamedTuple):
    unit: str
    period: int
    start: str  # ISO date (UTC) of the period's first row
    rows: int
    values: dict  # effect -> fitted value
    se: dict  # effect -> standard error
    rms_c: float  # the residual's RMS after the fit [K]


def periods_of(record: ScadaRecord, days: float | None = None) -> list[tuple[int, str, np.ndarray]]:
    """(period number, start date, row mask) of ``record``: calendar months (UTC) when ``days`` is None, else spans
    of ``days`` from the Unix epoch. The number orders the periods across units alike."""
    t = np.asarray(record.time_s, dtype=float)
    if days is None:
        stamps = [dt.datetime.fromtimestamp(x, tz=dt.timezone.utc) for x in t]
        key = np.array([s.year * 12 + s.month - 1 for s in stamps])
    else:
        key = np.floor(t / (86400.0 * days)).astype(int)
    out = []
    for k in np.unique(key):
        m = key == k
        start = dt.datetime.fromtimestamp(t[m][0], tz=dt.timezone.utc).date().isoformat()
        out.append((int(k), start, m))
    return out


def fit_period(setup: Setup, r0: dict, r_step: dict, unit: str, period: int, start: str) -> PeriodFit | None:
    """The effects of one unit's period from the residual at the neutral effects ``r0`` and with each effect stepped
    (``r_step``: effect -> residual), all {channel: rows of the period}; None with too few measured rows."""
    ok = np.all([np.isfinite(r0[ch]) for ch in setup.channels], axis=0)
    if ok.sum() < MIN_ROWS:
        return None
    y = np.concatenate([r0[ch][ok] for ch in setup.channels])
    cols = [np.concatenate([(r0[ch][ok] - r_step[e][ch][ok]) / STEP[e] for ch in setup.channels]) for e in EFFECTS]
    # an effect that moves nothing here (no cooler, a cooler bypassed all period) stays neutral, unknown
    moves = np.array([float(np.max(np.abs(c))) * abs(STEP[e]) >= IDENTIFIABLE_K for c, e in zip(cols, EFFECTS)])
    delta, se = np.zeros(len(EFFECTS)), np.full(len(EFFECTS), np.inf)
    res = y
    if moves.any():
        a = np.stack(cols, axis=1)[:, moves]
        d, *_ = np.linalg.lstsq(a, y, rcond=None)
        res = y - a @ d
        n_eff = effective_n({ch: res[i * ok.sum() : (i + 1) * ok.sum()] for i, ch in enumerate(setup.channels)})
        s2 = float(res @ res) / max(y.size - int(moves.sum()), 1)
        cov = np.linalg.pinv(a.T @ a) * s2 * y.size / n_eff
        delta[moves], se[moves] = d, np.sqrt(np.maximum(np.diag(cov), 0.0))
    return PeriodFit(
        unit,
        period,
        start,
        int(ok.sum()),
        {e: float(CATALOG[e].neutral + d) for e, d in zip(EFFECTS, delta)},
        {e: float(s) for e, s in zip(EFFECTS, se)},
        float(np.sqrt(np.mean(res * res))),
    )


def _residual(setup: Setup, record: ScadaRecord, effects: dict) -> dict:
    est = estimates(setup, record, effects)
    return {ch: record.values[ch] - est[ch] for ch in setup.channels}


def fit_fleet(setup: Setup, records: dict[str, ScadaRecord], days: float | None = None, progress=None) -> list:
    """Every unit's PeriodFit (units in name order, periods in time order). Each unit's whole record is replayed
    once at the neutral effects and once per effect stepped (a period keeps the state the ones before left: no
    start-up transient at each period's first rows), then each period is fitted on its rows."""
    fits = []
    for unit, rec in sorted(records.items()):
        r0 = _residual(setup, rec, {})
        r_step = {e: _residual(setup, rec, {e: CATALOG[e].neutral + STEP[e]}) for e in EFFECTS}
        for period, start, m in periods_of(rec, days):
            f = fit_period(
                setup,
                {ch: v[m] for ch, v in r0.items()},
                {e: {ch: v[m] for ch, v in r.items()} for e, r in r_step.items()},
                unit,
                period,
                start,
            )
            if f is not None:
                fits.append(f)
        if progress is not None:
            progress()
    return fits


def flag_units(fits: Sequence[PeriodFit]) -> list[Flag]:
    """The units that drift from their siblings (the module doc says how)."""
    by_period: dict = {}
    for f in fits:
        by_period.setdefault(f.period, []).append(f)
    flags = []
    for unit in sorted({f.unit for f in fits}):
        rows = sorted((f for f in fits if f.unit == unit), key=lambda f: f.period)
        for eid in EFFECTS:
            dev = []
            for f in rows:
                fleet = [g.values[eid] for g in by_period[f.period]]
                dev.append(f.values[eid] - float(np.median(fleet)) if len(fleet) > 1 else np.nan)
            if len(rows) <= BASELINE_PERIODS or not np.all(np.isfinite(dev[:BASELINE_PERIODS])):
                continue
            baseline = float(np.median(dev[:BASELINE_PERIODS]))
            run = 0
            for i in range(BASELINE_PERIODS, len(rows)):
                drift = dev[i] - baseline
                run = run + 1 if abs(drift) > DRIFT_MIN[eid] and abs(drift) > 3.0 * rows[i].se[eid] else 0
                if run >= CONSECUTIVE:
                    first = rows[i - CONSECUTIVE + 1]
                    flags.append(
                        Flag(
                            unit,
                            eid,
                            first.period,
                            first.start,
                            rows[i].values[eid],
                            baseline,
                            f"drift from its siblings by {drift:+.2f} (its own baseline {baseline:+.2f}) for "
                            f"{CONSECUTIVE} periods",
                            "flag",
                        )
                    )
                    break
    return flags
