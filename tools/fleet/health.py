"""Fleet health: per vehicle and period, the effects the oil channel alone identifies, fitted with their uncertainty,
and the vehicles that drift or sit outside the fleet's spread (``gearbox-vsensor fleet --diagnose``).

Per log (:func:`fit_log`, on the worker): the onboard model (tools/diagnosis/models.py) re-runs the log's decoded
inputs open loop on a grid of ``cooler_effectiveness_scale`` and ``oil_level_low`` and keeps the sum of squared
differences to the measured oil (DIR/fits). Per vehicle and period (:func:`fleet_health`): the grids add up, the
minimum is the estimate and the curvature its standard error (one independent point per :data:`DECORRELATION_S`); a
vehicle is flagged when :data:`CONSECUTIVE` periods in a row sit below its first :data:`BASELINE_PERIODS` by more than
:data:`DRIFT_MIN` and 3 standard errors. A truck that sends its measured oil level (SPN 124, tools/fleet/level.py,
:func:`period_level`, :func:`_level_flag`) is judged on that level; without it an oil-volume drift is a *watch*, not
a flag. docs/fleet.md, "Fleet health", has the rules, why the fleet's spread alone never flags and why the oil volume
from the temperature is only a watch.
"""

from __future__ import annotations

import datetime as dt
import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from firmware_model.effects import CATALOG
from firmware_model.errors import InputError

#: the grid of the per-log fit: cooler effectiveness scale [-] and oil volume [L] (catalog ranges)
COOLER_GRID = (0.2, 0.35, 0.5, 0.65, 0.8, 1.0, 1.2)
VOLUME_GRID_L = (8.0, 9.0, 10.0, 11.5, 13.5)
#: the fit compares the oil every this many seconds; one independent residual per DECORRELATION_S
FIT_DT_S = 5.0
DECORRELATION_S = 120.0
#: drift: periods of baseline, periods in a row, smallest drop that counts (per effect)
BASELINE_PERIODS = 2
CONSECUTIVE = 2
DRIFT_MIN = {"cooler_effectiveness_scale": 0.15, "oil_level_low": 1.0}
#: the measured level (SPN 124): its baseline is taken as the nominal volume, and a drop counts from the same 1 L
#: as the estimate's, as a share of the baseline (7.4 % of it: 6.7 points at 90 %), and never less than three bits;
#: a period's level needs readings from at least LEVEL_MIN_LOGS logs; its standard error never goes below one bit
#: over sqrt(logs); a baseline below LEVEL_PLAUSIBLE_MIN_PCT is not a fill level (a sender's placeholder, a sensor
#: fault): such a vehicle's level is not read
NOMINAL_VOLUME_L = float(CATALOG["oil_level_low"].neutral)  # the nominal oil volume [L]
LEVEL_BIT_PCT = 0.4
LEVEL_DRIFT_MIN_SHARE = DRIFT_MIN["oil_level_low"] / NOMINAL_VOLUME_L
LEVEL_DRIFT_MIN_PCT = 3 * LEVEL_BIT_PCT
LEVEL_PLAUSIBLE_MIN_PCT = 30.0
LEVEL_MIN_LOGS = 2
#: a log contributes to the fit only with at least this share of measured oil (readings the sensor used: a reading
#: it rejected as frozen or implausible is no measurement)
MIN_OIL_SHARE = 0.8
_MODELS: dict = {}


def health_model(variant: str | None = None, config: str | None = None):
    """The diagnosis's onboard backend for a (variant, config), built once per worker process."""
    key = (variant, config)
    if key not in _MODELS:
        from tools.diagnosis.models import OnboardModel
        from tools.fleet.manifest import vehicle_config

        cfg = vehicle_config(variant, config)
        _MODELS[key] = OnboardModel(cfg.load_params(), config=cfg, out_dt_s=FIT_DT_S, workers=1)
    return _MODELS[key]


class LogData(NamedTuple):
    """One log as the model simulates it: its decoded inputs (a RunTable) and the first measured oil [degC]."""

    inputs: object
    initial_temp_c: float


def fit_log(table, variant: str | None = None, config: str | None = None) -> dict | None:
    """The SSE grid of one replayed log (rows: VOLUME_GRID_L, columns: COOLER_GRID) against its measured oil, the
    number of compared points and the log's span; None when the log has too little measured oil."""
    from tools.diagnosis.models import Run
    from tools.runtable import RunTable

    oil = np.asarray(table["oil_temp_c"], dtype=float)
    if table.has("oil_valid"):  # the sensor's verdict on each reading (frozen, implausible: not used)
        oil = np.where(np.asarray(table["oil_valid"], dtype=float) == 1, oil, np.nan)
    if table.n < 2 * int(DECORRELATION_S / 0.1) or np.mean(np.isfinite(oil)) < MIN_OIL_SHARE:
        return None
    t = np.asarray(table["time_s"], dtype=float)
    cols = {"time_s": t - t[0]}
    for c in (
        "engine_speed_rpm",
        "engine_torque_nm",
        "gear",
        "ambient_temp_c",
        "coolant_temp_c",
        "vehicle_speed_kmh",
        "retarder_torque_nm",
    ):
        cols[c] = np.asarray(table[c], dtype=float)
    first = int(np.flatnonzero(np.isfinite(oil))[0])
    runs = [Run.of({"cooler_effectiveness_scale": c, "oil_level_low": v}) for v in VOLUME_GRID_L for c in COOLER_GRID]
    outs = health_model(variant, config).simulate([LogData(RunTable(cols), float(oil[first]))], runs, ["oil_temp_c"])
    t_fit = outs[0][0]["time_s"]
    meas = np.interp(t_fit, cols["time_s"], np.where(np.isfinite(oil), oil, np.nan))
    ok = np.isfinite(meas)
    sse = np.array([float(np.sum((o[0]["oil_temp_c"][ok] - meas[ok]) ** 2)) for o in outs])
    return {
        "sse": sse.reshape(len(VOLUME_GRID_L), len(COOLER_GRID)).ravel().tolist(),
        "points": int(ok.sum()),
        "span_s": float(cols["time_s"][-1]),
        "cooler_grid": list(COOLER_GRID),
        "volume_grid_l": list(VOLUME_GRID_L),
    }


def _parabola(x: np.ndarray, y: np.ndarray, i: int) -> tuple[float, float]:
    """Vertex and curvature (d2y/dx2) of the parabola through the minimum ``i`` and its neighbours. At an edge of
    the grid, or where the three points bend the wrong way, the minimum stays on its grid point and the curvature
    is the one-sided bound 2 x (the rise to the next point) / spacing^2 (the evidence that it beats its neighbour)."""
    j = min(max(i, 1), x.size - 2)
    a, b, _ = np.polyfit(x[j - 1 : j + 2], y[j - 1 : j + 2], 2)
    vertex = -b / (2 * a) if a > 0 else math.nan
    if a > 0 and x[0] <= vertex <= x[-1] and 0 < i < x.size - 1:
        return float(vertex), float(2 * a)
    k = i + 1 if i < x.size - 1 else i - 1
    rise = max(float(y[k] - y[i]), 0.0)
    return float(x[i]), 2 * rise / float(x[k] - x[i]) ** 2


class PeriodFit(NamedTuple):
    vehicle: str
    period: int
    start: str
    logs: int
    cooler_scale: float
    cooler_se: float
    oil_volume_l: float
    oil_volume_se: float
    rms_c: float
    oil_level_pct: float = math.nan  # the measured level (SPN 124): median over the period's logs
    oil_level_se: float = math.nan
    level_logs: int = 0  # the period's logs with a measured level (fewer than LEVEL_MIN_LOGS: no period level)


def fit_period(vehicle: str, period: int, start: str, fits: list[dict]) -> PeriodFit:
    """The estimate of one vehicle-period from its logs' SSE grids."""
    cooler = np.asarray(fits[0].get("cooler_grid") or COOLER_GRID, dtype=float)
    volume = np.asarray(fits[0].get("volume_grid_l") or VOLUME_GRID_L, dtype=float)
    sse = np.sum([np.asarray(f["sse"]) for f in fits], axis=0).reshape(volume.size, cooler.size)
    points = sum(f["points"] for f in fits)
    n_eff = max(sum(f["span_s"] for f in fits) / DECORRELATION_S, 3.0)
    iv, ic = np.unravel_index(int(np.argmin(sse)), sse.shape)
    s2 = float(sse[iv, ic]) / max(points - 2, 1)
    # a point's squared residual counts points / n_eff times: the curvature is divided by that inflation
    infl = points / n_eff
    c_hat, c_curv = _parabola(cooler, sse[iv, :], ic)
    v_hat, v_curv = _parabola(volume, sse[:, ic], iv)

    def se(curv):
        return math.sqrt(2 * s2 * infl / curv) if curv > 0 else math.inf

    return PeriodFit(
        vehicle,
        period,
        start,
        len(fits),
        c_hat,
        se(c_curv),
        v_hat,
        se(v_curv),
        math.sqrt(s2),
        *period_level(fits),
        int(np.isfinite(np.array([f.get("level_pct", math.nan) for f in fits], dtype=float)).sum()),
    )


def period_level(fits: list[dict]) -> tuple[float, float]:
    """The period's measured oil level [%] and its standard error: the median of its logs' levels (each the median
    of that log's SPN 124 readings), the error from their scatter (1.2533 x std / sqrt(n)); NaN without readings in
    at least :data:`LEVEL_MIN_LOGS` logs."""
    x = np.array([f.get("level_pct", math.nan) for f in fits], dtype=float)
    x = x[np.isfinite(x)]
    if x.size < LEVEL_MIN_LOGS:
        return math.nan, math.nan
    se = 1.2533 * float(np.std(x, ddof=1)) / math.sqrt(x.size)
    return float(np.median(x)), max(se, LEVEL_BIT_PCT / math.sqrt(x.size))


class Flag(NamedTuple):
    vehicle: str
    effect: str
    period: int
    start: str
    value: float
    baseline: float
    reason: str
    #: "flag", or "watch": an oil-level drift estimated from the oil temperature of a truck without SPN 124 (not
    #: identifiable: on the synthetic fleets such drifts were right 2 times in 7; a dipstick check, not a flag)
    kind: str = "flag"


class Health(NamedTuple):
    periods: int
    fits: list
    flags: list
    watch: tuple | list = ()  # Flag(kind="watch"): oil-level drifts from the temperature alone
    why_none: str = ""  # why no vehicle-period was fitted (nothing is written then)
    vehicles: int = 0  # vehicles with a fitted period
    judged: int = 0  # of them, those with the periods a judgement needs (JUDGED_PERIODS)
    undated: int = 0  # fitted logs left out: no date (frame times not Unix time, none in the manifest)
    far: int = 0  # fitted logs left out: dated far before or after the rest of the fleet
    #: (vehicle, periods) whose measured level (SPN 124) was read in too few of a period's logs to count
    level_short: tuple | list = ()


def level_short(periods) -> list[tuple[str, int]]:
    """(vehicle, how many of its periods) for the vehicles that send the measured level (SPN 124) in some period
    with fewer than :data:`LEVEL_MIN_LOGS` logs reading it: those periods have no level (the median of one log is
    no period's level), which would otherwise go unsaid. ``periods``: PeriodFit rows (or dicts of their fields)."""
    short: dict = {}
    for r in periods:
        r = r if isinstance(r, dict) else r._asdict()
        if 0 < (r.get("level_logs") or 0) < LEVEL_MIN_LOGS:
            short[r["vehicle"]] = short.get(r["vehicle"], 0) + 1
    return sorted(short.items())


def level_short_sentence(short: list) -> str:
    """One sentence on :func:`level_short`'s vehicles ('' when none)."""
    if not short:
        return ""
    names = ", ".join(f"{v} ({n} period{'s' if n != 1 else ''})" for v, n in short[:10])
    more = f" and {len(short) - 10} more vehicles" if len(short) > 10 else ""
    return (
        f"the measured oil level (SPN 124) is left out of periods in which only one log has it: {names}{more}; a "
        f"period's level needs it from at least {LEVEL_MIN_LOGS} logs (more logs per period, or a longer [fleet] "
        "period_days, would use it)"
    )


def _level_rows(rows: list) -> list:
    """The vehicle's periods with a measured level (SPN 124), when it has enough of them to be judged on it: a
    plausible baseline (the first :data:`BASELINE_PERIODS` with a level, each at least :data:`LEVEL_PLAUSIBLE_MIN_PCT`)
    and at least :data:`CONSECUTIVE` periods after it; else [] (the level is then not read for this vehicle)."""
    measured = [r for r in rows if math.isfinite(r.oil_level_pct)]
    if len(measured) < BASELINE_PERIODS + CONSECUTIVE:
        return []
    if any(r.oil_level_pct < LEVEL_PLAUSIBLE_MIN_PCT for r in measured[:BASELINE_PERIODS]):
        return []
    return measured


def _level_flag(vehicle: str, measured: list) -> Flag | None:
    """The oil-level flag from the measured level (SPN 124): :data:`CONSECUTIVE` consecutive periods below the
    baseline (its first :data:`BASELINE_PERIODS` periods with a level, taken as the nominal fill) by more than
    :data:`LEVEL_DRIFT_MIN_SHARE` of it (at least :data:`LEVEL_DRIFT_MIN_PCT`) and 3 standard errors (the period's and
    the baseline's combined); a period without a level breaks the run. Value and baseline in litres on that scale."""
    base_rows = measured[:BASELINE_PERIODS]
    baseline = float(np.median([r.oil_level_pct for r in base_rows]))
    base_se = max(r.oil_level_se for r in base_rows)
    min_drop = max(LEVEL_DRIFT_MIN_SHARE * baseline, LEVEL_DRIFT_MIN_PCT)
    run, prev = 0, base_rows[-1].period
    for r in measured[BASELINE_PERIODS:]:
        drop = baseline - r.oil_level_pct
        big = drop > min_drop and drop > 3 * math.hypot(r.oil_level_se, base_se)
        run = (run + 1 if r.period == prev + 1 else 1) if big else 0
        prev = r.period
        if run >= CONSECUTIVE:
            return Flag(
                vehicle,
                "oil_level_low",
                r.period,
                r.start,
                r.oil_level_pct / baseline * NOMINAL_VOLUME_L,
                NOMINAL_VOLUME_L,
                "the measured oil level (SPN 124) fell from its own baseline",
            )
    return None


def _drift_flags(per_vehicle: dict, fleet_median: dict, fleet_mad: dict) -> list[Flag]:
    flags = []
    for vehicle, rows in per_vehicle.items():
        rows = sorted(rows, key=lambda r: r.period)
        level_rows = _level_rows(rows)
        measured = bool(level_rows)
        if measured and (flag := _level_flag(vehicle, level_rows)) is not None:
            flags.append(flag)
        for effect, attr, se_attr in (
            ("cooler_effectiveness_scale", "cooler_scale", "cooler_se"),
            ("oil_level_low", "oil_volume_l", "oil_volume_se"),
        ):
            if measured and effect == "oil_level_low":
                continue  # read from the level sensor: the estimate from the oil temperature is not used
            base_rows = rows[:BASELINE_PERIODS]
            if len(rows) <= BASELINE_PERIODS:
                continue
            baseline = float(np.median([getattr(r, attr) for r in base_rows]))
            run = 0
            for r in rows[BASELINE_PERIODS:]:
                value, se = getattr(r, attr), getattr(r, se_attr)
                drop = baseline - value
                drifting = drop > DRIFT_MIN[effect] and drop > 3 * se
                outside = value < fleet_median[(effect, r.period)] - SPREAD_OUTSIDE * fleet_mad[(effect, r.period)]
                run = run + 1 if drifting else 0
                if run >= CONSECUTIVE:
                    weak = effect == "oil_level_low"  # from the temperature alone (no SPN 124): a watch
                    flags.append(
                        Flag(
                            vehicle,
                            effect,
                            r.period,
                            r.start,
                            value,
                            baseline,
                            (
                                "the oil volume estimated from the oil temperature (not identifiable: check "
                                "the level) drifted"
                                if weak
                                else "drift"
                            )
                            + " from its own baseline"
                            + (", outside the fleet's spread" if outside else ""),
                            "watch" if weak else "flag",
                        )
                    )
                    break
    return flags


def flag_vehicles(period_fits: list[PeriodFit]) -> list[Flag]:
    """The drifting vehicles of a fleet's vehicle-period fits (the module doc says how): flags, and watches
    (``kind == "watch"``: an oil-level drift from the oil temperature of a truck not judged on SPN 124)."""
    per_vehicle: dict = {}
    stats_med, stats_mad = {}, {}
    for f in period_fits:
        per_vehicle.setdefault(f.vehicle, []).append(f)
    for effect, attr in (("cooler_effectiveness_scale", "cooler_scale"), ("oil_level_low", "oil_volume_l")):
        for p in {f.period for f in period_fits}:
            values = [getattr(f, attr) for f in period_fits if f.period == p]
            med, spread = fleet_spread([x for x in values if not at_grid_edge(attr, x)])
            stats_med[(effect, p)] = med
            stats_mad[(effect, p)] = spread
    return _drift_flags(per_vehicle, stats_med, stats_mad)


#: a vehicle-period's value this many spreads below the fleet's median is "outside the fleet's spread"
SPREAD_OUTSIDE = 4.0


#: the grid of each fitted value (PeriodFit's attribute): a value on its first or last point is a bound, not an estimate
GRIDS = {"cooler_scale": COOLER_GRID, "oil_volume_l": VOLUME_GRID_L}


def at_grid_edge(attr: str, value: float) -> bool:
    """Whether a vehicle-period's fitted ``attr`` sits on its grid's first or last point: the fit ran to the end of
    what it tries (another gearbox's log replayed as this one's fitted a cooler of 1.2, the grid's top), so it is a
    bound, kept out of the fleet's median and spread (that one widened the spread and hid a fouled cooler)."""
    grid = GRIDS.get(attr)
    return grid is not None and math.isfinite(value) and (value <= grid[0] or value >= grid[-1])


def fleet_spread(values) -> tuple[float, float]:
    """The fleet's median of a period's values and its spread, 1.4826 x their median absolute deviation (the
    standard deviation of normal scatter, robust to the outlier it is meant to show); the finite values only, NaN
    for none; the spread at least 1e-6."""
    a = np.asarray(values, dtype=float)
    a = a[np.isfinite(a)]
    if not a.size:
        return math.nan, math.nan
    med = float(np.median(a))
    return med, max(1.4826 * float(np.median(np.abs(a - med))), 1e-6)


def _grid(row: dict) -> tuple[tuple, tuple]:
    return tuple(row.get("cooler_grid") or COOLER_GRID), tuple(row.get("volume_grid_l") or VOLUME_GRID_L)


def _check_grids(out: str | Path, rows: list[dict]) -> None:
    """Every stored log fit must be an SSE grid of this version's shape (a vehicle-period adds its logs' grids)."""
    here = (COOLER_GRID, VOLUME_GRID_L)
    n = len(COOLER_GRID) * len(VOLUME_GRID_L)
    bad = [r for r in rows if _grid(r) != here or len(r.get("sse") or ()) != n]
    if bad:
        raise InputError(
            f"{Path(out) / 'fits'}: {len(bad)} of {len(rows)} log fits are not on this version's grid "
            f"({len(VOLUME_GRID_L)} oil volumes x {len(COOLER_GRID)} cooler scales; the first has "
            f"{len(bad[0].get('sse') or ())} points): they come from another version of "
            "gearbox-vsensor; run `gearbox-vsensor fleet --diagnose` into a new --out folder"
        )


#: why no vehicle-period was fitted when no log was (fit_log's conditions)
NO_FIT = (
    f"no log was long enough to fit: each needs at least {2 * DECORRELATION_S / 60:.0f} min of replay with the "
    f"oil temperature measured (and used by the sensor) on {MIN_OIL_SHARE:.0%} of its steps or more"
)
#: why, when the folder's logs were summarised but none has a fit
NO_FIT_HERE = (
    "no log in this folder has a health fit: either none was long enough ("
    + NO_FIT.split(": ", 1)[1]
    + "), or its logs were summarised (or replayed again, their settings changed) by a run without --diagnose, "
    "which a re-run skips: run --diagnose into a new --out folder"
)


def _why_no_fit(summary) -> str:
    """Why no log has a fit: every summarised log shorter than a fit needs (said with the longest), else either
    reason (:data:`NO_FIT_HERE`: the folder's logs may have been summarised by a run without --diagnose)."""
    if summary is None or not summary.num_rows:
        return NO_FIT
    column = summary.column("duration_s").to_pylist() if "duration_s" in summary.column_names else []
    spans = [s for s in column if s is not None]
    if spans and max(spans) < 2 * DECORRELATION_S:
        return f"{NO_FIT} (the longest log here: {max(spans) / 60:.1f} min)"
    return NO_FIT_HERE


#: the periods a vehicle needs before a drift can be flagged: a baseline, then a run of drifting periods
JUDGED_PERIODS = BASELINE_PERIODS + CONSECUTIVE


#: fitted logs dated more than this before or after the rest of the fleet (and few) are left out of the periods [d]
FAR_DATE_GAP_DAYS = 60
#: ... when they are at most this share of the fitted logs
FAR_DATE_SHARE = 0.05


def _drop_far_dates(rows: list, dates: dict) -> tuple[list, int]:
    """(the rows, how many were left out): the fitted logs dated more than FAR_DATE_GAP_DAYS before (or after) all
    the others, when they are at most FAR_DATE_SHARE of them (a truck's clock set a year back: one such log would
    move every vehicle's periods and give each a one-log first period). Never all of them."""
    days = sorted(dt.date.fromisoformat(dates[r["log_key"]]).toordinal() for r in rows)
    lo, hi = 0, len(days)
    cap = int(FAR_DATE_SHARE * len(days))
    for i in range(min(cap, len(days) - 1)):
        if days[i + 1] - days[i] > FAR_DATE_GAP_DAYS:
            lo = i + 1
    for i in range(len(days) - 1, max(len(days) - 1 - cap, lo), -1):
        if days[i] - days[i - 1] > FAR_DATE_GAP_DAYS:
            hi = i
    first, last = days[lo], days[hi - 1]
    keep = [r for r in rows if first <= dt.date.fromisoformat(dates[r["log_key"]]).toordinal() <= last]
    return keep, len(rows) - len(keep)


def _current_fits(summary, fits) -> dict:
    """{log key: its fit} for the fits made with the log's current summary row (the same replay time), under that
    row's vehicle: a log replayed again without --diagnose (its file or settings changed, its vehicle renamed) keeps
    no fit of its old replay. One per log (a log fitted twice: a run killed between files)."""
    from tools.fleet.store import REPLAYED

    keys = summary.column("log_key").to_pylist()
    vehicles = dict(zip(keys, summary.column("vehicle").to_pylist()))
    at = dict(zip(keys, summary.column(REPLAYED).to_pylist())) if REPLAYED in summary.column_names else {}
    unique = {}
    for r in fits.to_pylist():
        made, fitted = at.get(r["log_key"]), r.get(REPLAYED)
        if r["log_key"] in vehicles and (made is None or fitted is None or made == fitted):
            unique[r["log_key"]] = {**r, "vehicle": vehicles[r["log_key"]]}
    return unique


def fleet_health(out: str | Path, period_days: float = 7.0) -> Health:
    """Fit every vehicle-period from DIR/fits, flag drifting vehicles; writes DIR/health/periods.parquet,
    DIR/health/flags.parquet and DIR/health/watch.parquet. Returns the fits, the flags and the watches."""
    import pyarrow as pa

    from tools.fleet.store import HEALTH, read_table, write_atomic

    fits = read_table(out, "fits")
    summary = read_table(out)
    if fits is None or summary is None or not fits.num_rows:
        return Health(0, [], [], why_none=_why_no_fit(summary))
    dates = dict(zip(summary.column("log_key").to_pylist(), summary.column("date").to_pylist()))
    unique = _current_fits(summary, fits)
    if not unique:
        return Health(0, [], [], why_none=NO_FIT_HERE)
    _check_grids(out, list(unique.values()))
    rows = [r for r in unique.values() if dates.get(r["log_key"], "unknown") != "unknown"]
    undated = len(unique) - len(rows)
    if not rows:
        return Health(
            0,
            [],
            [],
            why_none="no fitted log has a date (its frame times are not Unix time and the "
            "manifest gives none), so none falls into a period",
            undated=undated,
        )
    rows, far = _drop_far_dates(rows, dates)
    day0 = min(dt.date.fromisoformat(dates[r["log_key"]]) for r in rows)
    groups: dict = {}
    for r in rows:
        d = dt.date.fromisoformat(dates[r["log_key"]])
        p = int((d - day0).days // period_days)
        groups.setdefault((r["vehicle"], p), []).append(r)
    period_fits = [
        fit_period(v, p, (day0 + dt.timedelta(days=p * period_days)).isoformat(), g)
        for (v, p), g in sorted(groups.items())
    ]
    found = flag_vehicles(period_fits)
    flags = [f for f in found if f.kind == "flag"]
    watch = [f for f in found if f.kind == "watch"]
    root = Path(out) / HEALTH
    write_atomic(pa.Table.from_pylist([f._asdict() for f in period_fits]), root / "periods.parquet")
    schema = pa.schema(
        [
            ("vehicle", pa.string()),
            ("effect", pa.string()),
            ("period", pa.int64()),
            ("start", pa.string()),
            ("value", pa.float64()),
            ("baseline", pa.float64()),
            ("reason", pa.string()),
            ("kind", pa.string()),
        ]
    )
    write_atomic(pa.Table.from_pylist([f._asdict() for f in flags], schema=schema), root / "flags.parquet")
    write_atomic(pa.Table.from_pylist([f._asdict() for f in watch], schema=schema), root / "watch.parquet")
    per_vehicle: dict = {}
    for f in period_fits:
        per_vehicle[f.vehicle] = per_vehicle.get(f.vehicle, 0) + 1
    judged = sum(n >= JUDGED_PERIODS for n in per_vehicle.values())
    return Health(
        len(period_fits),
        period_fits,
        flags,
        watch,
        vehicles=len(per_vehicle),
        judged=judged,
        undated=undated,
        far=far,
        level_short=level_short(period_fits),
    )


__all__ = [
    "COOLER_GRID",
    "JUDGED_PERIODS",
    "SPREAD_OUTSIDE",
    "VOLUME_GRID_L",
    "Flag",
    "Health",
    "LogData",
    "PeriodFit",
    "fit_log",
    "fit_period",
    "fleet_spread",
    "at_grid_edge",
    "flag_vehicles",
    "fleet_health",
    "health_model",
    "level_short",
    "level_short_sentence",
    "period_level",
]
