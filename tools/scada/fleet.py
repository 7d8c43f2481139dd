"""The fleet on SCADA: per unit and period (a calendar month by default), the effects that show a turbine's gearbox
ageing, fitted with their standard errors, and the units that drift from their siblings (`fleet --columns`;
docs/real-data.md, "The fleet on SCADA").

Per unit and period (:func:`fit_period`): the onboard model replayed over the unit's whole record at the neutral
effects and once per effect of :data:`EFFECTS` stepped (tools.scada.diagnose.estimates: the sump channel from the
model alone, the other channels from the measured sump); one linear least-squares solve of all the effects together
on every channel's residual gives the values. Their standard errors allow for the residual's autocorrelation: the
larger of the AR(1) effective-sample-size error and a block (cluster-robust sandwich) error over blocks of a day,
which also covers the slower, weather-long correlation of a model's error that an AR(1) misses; a period needs
MIN_BLOCKS blocks with rows.

Per period, each effect's median over the units that identify it is the fleet's (seasons, the farm's weather move
every unit alike); only with MIN_UNITS units or more, where one drifting unit cannot move it. With an even number
of units each unit is set against the median of the others (an odd number): the mean of the two middle values
moves with a drifting unit that is one of them. A unit's *deviation*
is its value minus that median (its error: the unit's and the median unit's errors together), its *baseline* the
precision-weighted mean of its first BASELINE_PERIODS deviations no poorer than POOR_SE_FACTOR times its median
standard error (a unit may always differ a little; a partial first period or one standing still is left out of
it), and it is
flagged when its deviation leaves the baseline by more than DRIFT_MIN and 3 standard errors (the deviation's and the
baseline's together) for CONSECUTIVE of its periods in a row, and it does so against more than half of its siblings
one by one (:func:`against_most_siblings`): the first of them is the date in the flag. Flags are
taken in time order, and a flagged unit leaves the fleet from its flag's period on: a failing unit is no sibling's
reference (:func:`flag_units`).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from firmware_model.effects import CATALOG
from tools.fleet.health import Flag  # the truck fleet's flag row: one flags.parquet schema
from tools.scada.diagnose import Setup, effective_n, estimates
from tools.scada.reader import ScadaRecord

#: the effects fitted per unit and period: extra bearing heat (a bearing wearing), a cooler losing effectiveness
EFFECTS = ("bearing_loss_scale", "cooler_effectiveness_scale")
#: the finite-difference step of each effect (a scale: relative). The cooler's is a secant over the range a failing
#: cooler spans: behind a thermostat that reads the sump a cooler losing a fifth moves nothing (the valve opens
#: further), and a local slope would not see one at 0.3 (docs/real-data.md, "Planted effects")
STEP = {"bearing_loss_scale": 0.2, "cooler_effectiveness_scale": -0.5}
#: periods of baseline, periods in a row that make a flag, smallest drift that counts (per effect); the baseline
#: periods are a unit's first BASELINE_PERIODS usable ones that are no poorer than POOR_SE_FACTOR times its median
#: standard error (a record that begins with a partial week and a week standing still took those two: a baseline
#: of +- 0.21 that hid a drift of +0.3..+0.65 for nine weeks)
BASELINE_PERIODS = 2
POOR_SE_FACTOR = 2.0
CONSECUTIVE = 2
DRIFT_MIN = {"bearing_loss_scale": 0.15, "cooler_effectiveness_scale": 0.15}
#: what a drift of each effect means, up and down, in a reliability engineer's words (a flag's reason led with the
#: effect's id and a signed number alone: a review)
DRIFT_WORDS = {
    "bearing_loss_scale": (
        "its bearings run hotter for their load than its siblings' (more bearing heat: wear, preload; or a bearing "
        "sensor reads high: diagnose)",
        "its bearings run cooler for their load than its siblings' (or a bearing sensor reads low: diagnose)",
    ),
    "cooler_effectiveness_scale": (
        "its oil runs cooler under load than its siblings' (a cooler taking more heat)",
        "its oil runs hotter under load than its siblings' (a cooler losing effectiveness: fouled, blocked, a fan)",
    ),
}
#: a period needs this many rows with every channel of its unit measured (a channel without a single reading in the
#: unit's record left out: unit_channels)
MIN_ROWS = 36
#: the block of the cluster-robust error: a day, or a sixth of a period shorter than six days [s] (assumed: the
#: weather and the daily cycle set how long a model's error stays alike); a period needs MIN_BLOCKS blocks with rows
BLOCK_S = 86400.0
MIN_BLOCKS = 5
#: a period's fleet median needs this many units (with two, one drifting unit moves the median by half its drift
#: and the other seems to drift the other way)
MIN_UNITS = 3
#: an effect whose step moves no estimate by this much in a period is not fitted there [K]
IDENTIFIABLE_K = 0.01


class PeriodFit(NamedTuple):
    unit: str
    period: int
    start: str  # ISO date (UTC) of the period's first day (a month's 1st; as for trucks, not its first row's)
    rows: int
    values: dict  # effect -> fitted value
    se: dict  # effect -> standard error (inf: not identifiable in this period)
    rms_c: float  # the residual's RMS after the fit [K]
    blocks: int = 0  # blocks (BLOCK_S) with rows


def periods_of(record: ScadaRecord, days: float | None = None) -> list[tuple[int, str, np.ndarray]]:
    """(period number, start date, row mask) of ``record``: calendar months (UTC) when ``days`` is None, else spans
    of ``days`` from the Unix epoch. The number orders the periods across units alike, and the start date is the
    period's own first day (every unit's period k starts on the same date, whenever its rows begin)."""
    t = np.asarray(record.time_s, dtype=float)
    if days is None:
        stamps = [dt.datetime.fromtimestamp(x, tz=dt.timezone.utc) for x in t]
        key = np.array([s.year * 12 + s.month - 1 for s in stamps])
    else:
        key = np.floor(t / (86400.0 * days)).astype(int)
    out = []
    for k in np.unique(key):
        m = key == k
        if days is None:
            start = dt.date(int(k) // 12, int(k) % 12 + 1, 1)
        else:
            start = dt.datetime.fromtimestamp(int(k) * 86400.0 * days, tz=dt.timezone.utc).date()
        out.append((int(k), start.isoformat(), m))
    return out


def block_s(days: float | None) -> float:
    """The cluster block of periods of ``days`` (None: calendar months) [s]."""
    return BLOCK_S if days is None else min(BLOCK_S, 86400.0 * days / 6.0)


def fit_period(
    setup: Setup,
    r0: dict,
    r_step: dict,
    unit: str,
    period: int,
    start: str,
    block: np.ndarray | None = None,
    channels: Sequence[str] | None = None,
) -> PeriodFit | None:
    """The effects of one unit's period from the residual at the neutral effects ``r0`` and with each effect stepped
    (``r_step``: effect -> residual), all {channel: rows of the period}; ``block``: each row's block number (None:
    every row its own); ``channels``: the channels fitted (None: the setup's; a unit's channel without any reading is
    left out of its fits: :func:`unit_channels`). None with too few rows with every one of them measured, or
    blocks."""
    channels = setup.channels if channels is None else tuple(channels)
    if not channels:
        return None
    ok = np.all([np.isfinite(r0[ch]) for ch in channels], axis=0)
    n = int(ok.sum())
    blk = np.arange(ok.size) if block is None else np.asarray(block)
    blocks = np.unique(blk[ok])
    if n < MIN_ROWS or blocks.size < MIN_BLOCKS:
        return None
    y = np.concatenate([r0[ch][ok] for ch in channels])
    cols = [np.concatenate([(r0[ch][ok] - r_step[e][ch][ok]) / STEP[e] for ch in channels]) for e in EFFECTS]
    # an effect that moves nothing here (no cooler, a cooler bypassed all period) stays neutral, unknown
    moves = np.array([float(np.max(np.abs(c))) * abs(STEP[e]) >= IDENTIFIABLE_K for c, e in zip(cols, EFFECTS)])
    delta, se = np.zeros(len(EFFECTS)), np.full(len(EFFECTS), np.inf)
    res = y
    if moves.any():
        a = np.stack(cols, axis=1)[:, moves]
        d, *_ = np.linalg.lstsq(a, y, rcond=None)
        res = y - a @ d
        bread = np.linalg.pinv(a.T @ a)
        # AR(1): the residual's variance over an effective sample size
        n_eff = effective_n({ch: res[i * n : (i + 1) * n] for i, ch in enumerate(channels)})
        s2 = float(res @ res) / max(y.size - int(moves.sum()), 1)
        cov_ar1 = bread * s2 * y.size / n_eff
        # blocks: the sandwich with each block's score summed over its rows and channels (small-sample G / (G - 1))
        g = np.tile(blk[ok], len(channels))
        _, inv = np.unique(g, return_inverse=True)
        scores = np.zeros((blocks.size, a.shape[1]))
        np.add.at(scores, inv, a * res[:, None])
        cov_blk = bread @ (scores.T @ scores) @ bread * blocks.size / (blocks.size - 1)
        var = np.maximum(np.diag(cov_ar1), np.diag(cov_blk))
        delta[moves], se[moves] = d, np.sqrt(np.maximum(var, 0.0))
    return PeriodFit(
        unit,
        period,
        start,
        n,
        {e: float(CATALOG[e].neutral + d) for e, d in zip(EFFECTS, delta)},
        {e: float(s) for e, s in zip(EFFECTS, se)},
        float(np.sqrt(np.mean(res * res))),
        int(blocks.size),
    )


def _residual(setup: Setup, record: ScadaRecord, effects: dict) -> dict:
    est = estimates(setup, record, effects)
    return {ch: record.values[ch] - est[ch] for ch in setup.channels}


def residuals(setup: Setup, record: ScadaRecord) -> tuple[dict, dict]:
    """The unit's residual at the neutral effects and with each effect stepped (effect -> residual), each a
    {channel: measured - model} over its whole record."""
    r0 = _residual(setup, record, {})
    return r0, stepped_residuals(setup, record)


def stepped_residuals(setup: Setup, record: ScadaRecord) -> dict:
    """effect -> the unit's residual with that effect stepped from neutral."""
    return {e: _residual(setup, record, {e: CATALOG[e].neutral + STEP[e]}) for e in EFFECTS}


def unit_channels(setup: Setup, record: ScadaRecord) -> tuple[tuple[str, ...], list[str]]:
    """(the channels a unit's periods are fitted on, the channels left out for it): a channel other than the sump
    without a single reading in the unit's record (its column absent from its files, or empty, or every value
    rejected) is left out, so a unit with one dead column is still fitted on the rest (it lacked a row with every
    channel read: no period fitted, the unit dropped from the fleet). The sump is never left out: the other
    channels' estimates start from its reading, and the fleet's sump is fitted from the model alone."""
    dead = [
        ch
        for ch in setup.others
        if ch not in record.values or not np.isfinite(np.asarray(record.values[ch], dtype=float)).any()
    ]
    return tuple(ch for ch in setup.channels if ch not in dead), dead


def fit_unit(
    setup: Setup,
    record: ScadaRecord,
    days: float | None = None,
    resid=None,
    unit: str | None = None,
    channels: Sequence[str] | None = None,
) -> list[PeriodFit]:
    """One unit's PeriodFits in time order; ``resid``: its :func:`residuals` when already computed; ``unit``: its
    name (default: the record's); ``channels``: the channels fitted (None: :func:`unit_channels`)."""
    r0, r_step = residuals(setup, record) if resid is None else resid
    channels = unit_channels(setup, record)[0] if channels is None else channels
    block = np.floor(np.asarray(record.time_s, dtype=float) / block_s(days)).astype(np.int64)
    fits = []
    for period, start, m in periods_of(record, days):
        f = fit_period(
            setup,
            {ch: v[m] for ch, v in r0.items()},
            {e: {ch: v[m] for ch, v in r.items()} for e, r in r_step.items()},
            record.unit if unit is None else unit,
            period,
            start,
            block[m],
            channels,
        )
        if f is not None:
            fits.append(f)
    return fits


def fit_fleet(
    setup: Setup, records: dict[str, ScadaRecord], days: float | None = None, progress=None, rejected=None
) -> list:
    """Every unit's PeriodFit (units in name order, periods in time order). Each unit's whole record is replayed
    once at the neutral effects and once per effect stepped (a period keeps the state the ones before left: no
    start-up transient at each period's first rows), then each period is fitted on its rows. A unit whose units
    look wrong (tools.scada.replay.screen_untrusted: what makes replay exit 3) is left out, its fits would move the
    fleet's median; a single channel far off beside sound ones is left out of the unit instead: (unit, sentence)
    appended to ``rejected`` either way."""
    from firmware_model.errors import InputError
    from tools.scada.replay import screen_untrusted

    fits = []
    for unit, rec in sorted(records.items()):
        _, dead = unit_channels(setup, rec)
        files = ", ".join(Path(f).name for f in rec.files[:3]) + (" ..." if len(rec.files) > 3 else "")
        dead_notes = [
            f"the fleet record of {unit} ({files}): {ch} left out: no reading of it in the unit's files (its column "
            "absent, empty or every value rejected); its periods are fitted on its other channels, so its values "
            "are not comparable with its siblings' (its flags judge its drift from its own baseline, which is)"
            for ch in dead
        ]
        r0 = _residual(setup, rec, {})
        try:
            (rec,), (r0,), notes = screen_untrusted([rec], [r0], setup.params, "fleet", setup.sump)
        except InputError as exc:
            if rejected is not None:
                rejected.append((unit, str(exc)))
        else:
            if rejected is not None:  # a channel left out, the unit kept (a unit left out: its reason alone)
                rejected += [(unit, note) for note in (*dead_notes, *notes)]
            resid = r0, stepped_residuals(setup, rec)
            fits += fit_unit(setup, rec, days, resid=resid, unit=unit)  # (a channel screened out is NaN: left out)
        if progress is not None:
            progress()
    return fits


def _median_se(values: list[float], ses: list[float]) -> tuple[float, float]:
    """The median of ``values`` and its standard error: the median unit's (odd count), half the two middle ones'
    together (even)."""
    order = np.argsort(values)
    v, s = np.asarray(values)[order], np.asarray(ses)[order]
    k = v.size // 2
    if v.size % 2:
        return float(v[k]), float(s[k])
    return float(0.5 * (v[k - 1] + v[k])), float(0.5 * np.hypot(s[k - 1], s[k]))


def identified(f: PeriodFit, eid: str) -> bool:
    """Whether a period identifies its fitted ``eid``: a finite standard error no wider than the effect's plausible
    range (firmware_model.effects.CATALOG); an error wider than the whole range says nothing of where in it the
    value lies (a unit without its Gb2t reading: bearing losses 2.30 +- 23.80)."""
    e = CATALOG[eid]
    return bool(f.se[eid] <= e.high - e.low)  # (NaN and inf: not identified)


def in_range(f: PeriodFit, eid: str) -> bool:
    """Whether a period's fitted ``eid`` is identified (:func:`identified`) and within the effect's plausible range.
    Outside it a value is a short period's noise (a cooler at -4 x its effectiveness, +-2.8) or a failure beyond the
    range (a dead cooler near 0): the fleet's medians and drifts keep it, with its standard error, and
    effects.parquet and the report mark it."""
    e = CATALOG[eid]
    return identified(f, eid) and bool(e.low <= f.values[eid] <= e.high)


def deviations(
    fits: Sequence[PeriodFit], eid: str, flagged: dict | None = None
) -> dict[str, list[tuple[PeriodFit, float, float]]]:
    """unit -> [(its period fit, deviation from the fleet median, its standard error)] in time order, over the
    periods where MIN_UNITS units or more identify ``eid``; ``flagged`` (unit -> period): a unit already flagged
    is left out of the fleet from that period on (not the siblings' reference, not judged again)."""
    flagged = flagged or {}
    by_period: dict = {}
    for f in fits:
        if f.unit in flagged and f.period >= flagged[f.unit]:
            continue
        if identified(f, eid):
            by_period.setdefault(f.period, []).append(f)
    out: dict = {}
    for period in sorted(by_period):
        group = by_period[period]
        if len(group) < MIN_UNITS:
            continue
        values, ses = [f.values[eid] for f in group], [f.se[eid] for f in group]
        med, se_med = _median_se(values, ses)
        for i, f in enumerate(group):
            if len(group) % 2 == 0:  # even: the median of the others, an odd count (module doc)
                med, se_med = _median_se(values[:i] + values[i + 1 :], ses[:i] + ses[i + 1 :])
            out.setdefault(f.unit, []).append((f, f.values[eid] - med, float(np.hypot(f.se[eid], se_med))))
    return out


def coverage(fits: Sequence[PeriodFit], units, baseline_periods: int = BASELINE_PERIODS) -> dict[str, str]:
    """unit -> why it was not judged against its siblings ('' when it was, for some effect): no period fitted (each
    needs MIN_ROWS rows with every channel of the unit read over MIN_BLOCKS blocks), or too few periods shared with
    MIN_UNITS units for a baseline and a drift after it."""
    fitted: dict = {}
    for f in fits:
        fitted[f.unit] = fitted.get(f.unit, 0) + 1
    judged = {u for eid in EFFECTS for u in drifts(fits, eid, baseline_periods)}
    shared: dict = {}  # unit -> its most periods beside MIN_UNITS - 1 siblings, over the effects
    for eid in EFFECTS:
        for u, rows in deviations(fits, eid).items():
            shared[u] = max(shared.get(u, 0), len(rows))
    out = {}
    for u in units:
        if u in judged:
            out[u] = ""
        elif not fitted.get(u):
            out[u] = (
                f"no period could be fitted (each needs {MIN_ROWS} rows with the sump and every other channel the "
                f"unit has a reading of read, over {MIN_BLOCKS} days or more): not judged"
            )
        else:
            out[u] = (
                f"{fitted[u]} period(s) fitted, {shared.get(u, 0)} of them beside {MIN_UNITS - 1} or more siblings "
                f"fitted in the same period; a drift needs more than {baseline_periods} such periods: not judged"
            )
    return out


def alone_periods(fits: Sequence[PeriodFit]) -> dict[str, list[str]]:
    """unit -> the start dates of its fitted periods where fewer than MIN_UNITS units (it included) were fitted, for
    every effect: no fleet median there, so nothing of it is judged (a sibling's records ending left a fouling
    cooler's worst two months untested, and the run said '3 judged')."""
    with_units: dict = {}
    for f in fits:
        with_units.setdefault(f.period, set()).add(f.unit)
    return {
        u: sorted({f.start for f in fits if f.unit == u and len(with_units[f.period]) < MIN_UNITS})
        for u in sorted({f.unit for f in fits})
        if any(f.unit == u and len(with_units[f.period]) < MIN_UNITS for f in fits)
    }


def drifts(
    fits: Sequence[PeriodFit], eid: str, baseline_periods: int = BASELINE_PERIODS, flagged: dict | None = None
) -> dict[str, tuple[float, float, list[tuple[PeriodFit, float, float]]]]:
    """unit -> (baseline, its standard error, [(period fit, drift from the baseline, the drift's standard error)]
    over the periods after the baseline), for the units with more than ``baseline_periods`` usable periods
    (``flagged``: as :func:`deviations`)."""
    out = {}
    for unit, rows in sorted(deviations(fits, eid, flagged).items()):
        if len(rows) > baseline_periods:
            out[unit] = _from_baseline(rows, baseline_periods)
    return out


def _from_baseline(rows: list, baseline_periods: int) -> tuple[float, float, list]:
    """(baseline, its standard error, [(fit, drift, its standard error)] after it) of [(fit, deviation, standard
    error)] in time order: the baseline the precision-weighted mean of the first ``baseline_periods`` rows no poorer
    than POOR_SE_FACTOR times the median standard error (the first rows when too few are)."""
    typical = float(np.median([se for _, _, se in rows]))
    fine = [i for i, (_, _, se) in enumerate(rows[:-1]) if se <= POOR_SE_FACTOR * typical]
    chosen = fine[:baseline_periods] if len(fine) >= baseline_periods else list(range(baseline_periods))
    w = np.array([1.0 / rows[i][2] ** 2 for i in chosen])
    baseline = float(np.sum(w * [rows[i][1] for i in chosen]) / np.sum(w))
    se_base = float(1.0 / np.sqrt(np.sum(w)))
    return baseline, se_base, [(f, d - baseline, float(np.hypot(se, se_base))) for f, d, se in rows[chosen[-1] + 1 :]]


def _drifting(drift: float, se: float, eid: str) -> bool:
    return abs(drift) > DRIFT_MIN[eid] and abs(drift) > 3.0 * se


def against_most_siblings(
    fits: Sequence[PeriodFit], unit: str, eid: str, run: list, sign: float, baseline_periods: int, flagged: dict
) -> bool:
    """Whether ``unit`` drifts by ``sign`` over the periods ``run`` against most of its siblings one by one: each
    sibling's difference from it over their shared periods, from its own baseline as :func:`drifts` takes one, past
    the same bar in every period of the run, for more than half of the siblings with such a series (True when none
    has one). A drifting unit drifts against every sibling; a sound one whose median a drifting sibling moved drifts
    against that one alone (four turbines: the median of the other three is the drifting one's once it sits between
    them)."""
    mine = {f.period: f for f in fits if f.unit == unit and identified(f, eid)}
    agree = votes = 0
    for sib in sorted({f.unit for f in fits} - {unit}):
        theirs = {
            f.period: f
            for f in fits
            if f.unit == sib and identified(f, eid) and not (sib in flagged and f.period >= flagged[sib])
        }
        rows = [
            (mine[k], mine[k].values[eid] - theirs[k].values[eid], float(np.hypot(mine[k].se[eid], theirs[k].se[eid])))
            for k in sorted(set(mine) & set(theirs))
        ]
        if len(rows) <= baseline_periods:
            continue
        after = {f.period: (d, se) for f, d, se in _from_baseline(rows, baseline_periods)[2]}
        if not all(k in after for k in run):
            continue
        votes += 1
        agree += all(_drifting(after[k][0], after[k][1], eid) and after[k][0] * sign > 0 for k in run)
    return votes == 0 or 2 * agree > votes


def flag_units(
    fits: Sequence[PeriodFit], baseline_periods: int = BASELINE_PERIODS, consecutive: int = CONSECUTIVE
) -> list[Flag]:
    """The units that drift from their siblings (the module doc says how). Flags are taken in time order: the
    earliest flagged unit leaves the fleet from its flag's period on and the others are judged again without it, so
    a failing unit cannot move the siblings' median (a cooler failing on one of three turbines moved its bearing
    effect too, the median passed to a sibling, and that sibling seemed to drift)."""
    flagged: dict = {}
    taken: list[Flag] = []
    while True:
        new = [fk for fk in _drift_flags(fits, baseline_periods, consecutive, flagged) if fk[0].vehicle not in flagged]
        if not new:
            return sorted(taken, key=lambda f: (f.vehicle, f.effect))
        # the earliest flag, of two in one period the stronger (its drift over its threshold): all its unit's flags
        first, _ = min(new, key=lambda fk: (fk[0].period, -fk[1]))
        taken += [f for f, _ in new if f.vehicle == first.vehicle]
        flagged[first.vehicle] = first.period


def _drift_flags(fits, baseline_periods: int, consecutive: int, flagged: dict) -> list[tuple[Flag, float]]:
    """Every unit's first drifting run per effect that drifts against most of its siblings one by one
    (:func:`against_most_siblings`; a run that does not is passed over, and the scan goes on), the units in
    ``flagged`` left out from their periods on: (flag, its drift over its threshold, the larger of DRIFT_MIN and 3
    standard errors, at the run's last period)."""
    flags = []
    for eid in EFFECTS:
        for unit, (baseline, se_base, rows) in drifts(fits, eid, baseline_periods, flagged).items():
            run = 0
            for i, (f, drift, se) in enumerate(rows):
                run = run + 1 if _drifting(drift, se, eid) else 0
                if run >= consecutive and all(
                    np.sign(d) == np.sign(drift) for _, d, _ in rows[i - consecutive + 1 : i + 1]
                ):
                    periods = [r[0].period for r in rows[i - consecutive + 1 : i + 1]]
                    sign = 1.0 if drift > 0 else -1.0
                    if not against_most_siblings(fits, unit, eid, periods, sign, baseline_periods, flagged):
                        continue
                    first = rows[i - consecutive + 1][0]
                    strength = abs(drift) / max(DRIFT_MIN[eid], 3.0 * se)
                    flags.append(
                        (
                            Flag(
                                unit,
                                eid,
                                first.period,
                                first.start,
                                f.values[eid],
                                baseline,
                                f"{DRIFT_WORDS[eid][0 if drift > 0 else 1]}: drift from its siblings by "
                                f"{drift:+.2f} (its own baseline {baseline:+.2f} +- {se_base:.2f}) for "
                                f"{consecutive} periods",
                                "flag",
                            ),
                            strength,
                        )
                    )
                    break
    return flags
