"""Plausibility of a whole record, not only of each value (docs/can.md "Trust findings"): unit and sign mistakes
that pass every per-value check of the sensor (docs/sensor.md "Bad input") yet give wrong numbers, and repairs on
too many steps. Shared by `replay` (run tables and CAN logs), `fleet`, the diagnosis's input preparation and the
live service (after its first minute).

Each finding is a :class:`PlausibilityFinding` (``kind`` "plausibility", :attr:`Severity.UNTRUSTED`, one
``.sentence`` naming the column, the likely unit or sign and the fix); :class:`RepairFinding` says that the sensor
clamped or repaired an input on more than REPAIR_UNTRUSTED_SHARE of its steps. The rules (oil in degF or
kelvin, torque of the wrong sign, torque in percent where N m is expected, speed in rad/s), their thresholds and why
they are set where they are: docs/can.md, "Trust findings", whole-record plausibility.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from firmware_model.components import MODE_NORMAL, STEP_S
from firmware_model.service.degraded import Severity, pct

#: the plausible range of a gearbox sump read in degC [degC]
OIL_ENVELOPE_C = (-40.0, 150.0)
#: a gearbox with limits of its own: the envelope's top is its sump's warning limit plus this [K] (the GRS905's,
#: OIL_WARNING_DEFAULT_C, gives the 150 above; the MM82's 75 gives 105, so a turbine's 40-60 degC sump logged in
#: degF is found)
OIL_ABOVE_WARNING_K, OIL_WARNING_DEFAULT_C = 30.0, 120.0
#: degC does not fit when at least this share of the readings is above the envelope ...
OIL_HOT_SHARE = 0.5
#: ... and another unit fits when this share of its converted readings lies in the envelope ...
OIL_FIT_SHARE = 0.95
#: ... and it rises no faster than this over the window [K/min, s] (twice the fastest honest rise of the named
#: cycles, 8.1 K/min over 5 min at steady full load)
OIL_MAX_RATE_C_PER_MIN, OIL_RATE_WINDOW_S = 16.0, 300.0
#: the time column's unit, judged by the oil: a gearbox sump's oil (with the housing it heats) changes at most
#: OIL_FAST_K_S over OIL_FAST_WINDOW_S (or 3 rows, if further apart) [K/s, s]; the fastest honest change of the
#: shipped gearboxes' plants is 0.45 K/s (the GRSO905 at 272 kW from a 20 degC sump; the fixed-ratio ones below
#: 0.03 K/s), while a truck's drive one row a minute read as seconds rises 2.2-2.8 K/s. Found when the oil is that
#: fast over at least OIL_FAST_WINDOWS windows' worth of the record (a shorter record, of at least one window:
#: over all of it, as a 12-minute drive stored in minutes is) and gradually (no one row carries more than
#: OIL_FAST_STEP_SHARE of a window's change: a sensor reconnecting steps once)
OIL_FAST_K_S, OIL_FAST_WINDOW_S, OIL_FAST_WINDOWS, OIL_FAST_STEP_SHARE = 1.0, 10.0, 2, 0.5
#: ... each window judged on a grid of this many bins (a row's step is looked for within the bins)
OIL_FAST_BINS = 10
#: a record needs this much oil reading (or driving) before a whole-record rule judges it [s]
OIL_MIN_S = 60.0
#: the other units an oil column is tried in: name, words, conversion to degC, the fix
OIL_UNITS = (
    ("degF", "degF", lambda x: (x - 32.0) / 1.8, "(degF - 32) / 1.8"),
    ("K", "kelvin", lambda x: x - 273.15, "K - 273.15"),
)
#: the oil against the sensor's own modelled sump (model_oil_temp_c, the twin): degC does not fit when the readings
#: lie at least OIL_MODEL_OFF_K from it on median over at least OIL_MODEL_MIN_S of readings, and another unit fits
#: when its converted readings lie within OIL_MODEL_FIT_SHARE of that, and OIL_MODEL_FIT_K, on median [K, s, -, K]
#: (the range rule above misses a sump read in degF while it warms: 68-136 degF read as degC is a hot gearbox, not
#: an impossible one; the twin says 43-69 degC beside it)
OIL_MODEL_OFF_K, OIL_MODEL_MIN_S, OIL_MODEL_FIT_SHARE, OIL_MODEL_FIT_K = 20.0, 1800.0, 0.25, 15.0
#: ... judged only when the sensor ran degraded (holding or modelling an input) on at most this share of the steps
OIL_MODEL_DEGRADED_SHARE = 0.2
#: the oil in degC but at least OIL_MODEL_GAP_K from the sensor's own modelled sump on median (over OIL_MODEL_MIN_S,
#: degraded as above): a warning that the model's cooler or boundaries are not this gearbox's [K]. A coolant left to
#: its default (80 degC, the uphill drive's ran at 93) put the GRS905's modelled sump 12.6 K under the measured one
#: and its sun wheel 29 K under the truth, exit 0: the cooler sets the oil the jets spray on the parts
OIL_MODEL_GAP_K = 8.0
#: a driving row: the engine at least this fast [rpm] with a gear engaged
DRIVE_MIN_RPM = 500.0
#: torque sign: below this torque [Nm] on more than SIGN_SHARE of at least SIGN_MIN_DRIVE_S [s] of driving, and
#: below the engine's min_torque on SIGN_BEYOND_SHARE of it or negative on SIGN_ALL_SHARE of it
SIGN_NEG_NM, SIGN_SHARE, SIGN_MIN_DRIVE_S, SIGN_BEYOND_SHARE, SIGN_ALL_SHARE = -50.0, 0.5, 300.0, 0.05, 0.9
#: torque in percent: never above PERCENT_MAX on at least PERCENT_MIN_DRIVE_S [s] of driving, reaching
#: PERCENT_MIN_PEAK
PERCENT_MAX, PERCENT_MIN_PEAK, PERCENT_MIN_DRIVE_S = 125.0, 40.0, 300.0
#: ... whose 10-90 % range is at least this (a drive's load varies; a rig's held point does not)
PERCENT_MIN_SPREAD = 30.0
#: ... or, on a vehicle that moves (at least PERCENT_MOVING_KMH on PERCENT_MOVING_SHARE of its driving steps) for at
#: least PERCENT_MOVING_MIN_S of driving, under load throughout (its 10th percentile above 0: no engine braking) and
#: not held (a 10-90 % range of at least PERCENT_MOVING_SPREAD): no road drive of a quarter of an hour pulls at most
#: 125 N m. A steady 30-minute climb in percent (p10 39, p90 67) escaped the spread rule with exit 0 (a newcomer's
#: trial); a rig, whose table moves no vehicle, keeps the spread rule
PERCENT_MOVING_KMH, PERCENT_MOVING_SHARE, PERCENT_MOVING_MIN_S, PERCENT_MOVING_SPREAD = 5.0, 0.5, 900.0, 10.0
#: ... and a fixed-ratio drive's torque only when the drive takes at least this [N m] (four times PERCENT_MAX: an
#: input never above a quarter of it; a small motor's reducer, the R1's 600 N m, runs honestly on 20 %)
PERCENT_FIXED_MIN_NM = 4.0 * PERCENT_MAX
#: a clamp or repair of an input on more than this share of the steps is untrusted
REPAIR_UNTRUSTED_SHARE = 0.05
#: the reject counters that clamp or repair a value the sensor then uses (a missing input is the degraded
#: finding's; drive_frozen is flagged but used as it is), with their words
REPAIR_REASONS = {
    "speed_clamped": "engine speed clamped to the engine's range",
    "torque_clamped": "engine torque clamped to the engine's range",
    "gear_unknown": "gear not an integer in -2..14 or no gear of the gearbox (last good gear held)",
    "oil_implausible": "oil reading out of range or jumping (modelled instead)",
}
#: the same of a fixed-ratio drive (its input shaft, clamped to the description's drive ranges): it has no engine
DRIVE_REPAIR_REASONS = {
    "speed_clamped": "input speed clamped to the drive's range",
    "torque_clamped": "input torque clamped to the drive's range",
}
#: where a column comes from: a run table's column, or a CAN log's decoded signal (the DBC fixes its unit)
SOURCES = {
    "table": {"oil_temp_c": "column oil_temp_c", "engine_torque_nm": "column engine_torque_nm"},
    "can": {
        "oil_temp_c": "the oil temperature (TRF1 SPN 177, degC by the DBC)",
        "engine_torque_nm": "the engine torque (EEC1 SPN 513 x the reference torque)",
    },
}


#: the J1939 SPN a live service's DM1 names for a finding on an input (FMI 2, docs/can.md "DM1: decision")
FINDING_SPNS = {"engine_speed_rpm": 190, "engine_torque_nm": 513, "gear": 523, "oil_temp_c": 177}
#: the input of each repair reason
REPAIR_INPUTS = {
    "speed_clamped": "engine_speed_rpm",
    "torque_clamped": "engine_torque_nm",
    "gear_unknown": "gear",
    "oil_implausible": "oil_temp_c",
}


def min_torque_nm(sensor) -> float | None:
    """The engine's braking limit the sensor clamps the torque to [Nm] (the torque-sign rule's; None: a sensor
    without SensorParams)."""
    from firmware_model.onboard.records import I_TORQUE

    sp = getattr(sensor, "sp", None)
    return float(sp.clamp_lo[I_TORQUE]) if sp is not None else None


@dataclass(frozen=True)
class PlausibilityFinding:
    """A whole record whose ``column`` looks like ``likely`` (a unit: "degF", "K", "degF or K", "percent"; or
    "negative"); ``what`` is its sentence."""

    kind: ClassVar[str] = "plausibility"
    column: str
    likely: str
    what: str

    @property
    def severity(self) -> Severity:
        return Severity.UNTRUSTED

    @property
    def sentence(self) -> str:
        return self.what

    @property
    def spn_key(self) -> str:
        return self.column


#: the gear-numbering rule: steps in gear while driving (over GEAR_MIN_KMH and GEAR_MIN_RPM) and steady give each
#: gear's engine speed per km/h, which over the gear's ratio is the axle and wheel's constant, the same in every
#: gear; gears whose constants differ by more than GEAR_RATIO_TOL (each with GEAR_MIN_S of steady driving) are not
#: this gearbox's (another transmission, or another numbering: [can] gear_map); docs/can.md gives the margins.
GEAR_MIN_KMH, GEAR_MIN_RPM, GEAR_MIN_S, GEAR_RATIO_TOL = 5.0, 500.0, 3.0, 0.10
#: ... steady: the clutch locked, its engine speed per km/h within GEAR_STEADY_TOL of every step GEAR_STEADY_S
#: before and after it that drives in the same gear (at least one does). A launch's slipping clutch holds the engine
#: while the truck gathers speed (20-30 % a second at 10 km/h) and reads the launch gear's constant 10 % high; a
#: locked gear's stays put but for noise (the real captures: 3 % a step) and a vehicle speed sent once a second
GEAR_STEADY_S, GEAR_STEADY_TOL = 1.0, 0.08
#: ... and that constant is a road vehicle's: its axle ratio on a tyre of WHEEL_RADIUS_M within AXLE_RANGE (assumed:
#: trucks' final drives 2.5-6.5, hub reductions to ~7; dynamic radii 0.47-0.53 m; a shift within a geometric
#: ladder, as the GRS905's upper gears, keeps the constants equal and only this range can catch it)
WHEEL_RADIUS_M, AXLE_RANGE = 0.5, (2.0, 7.0)


def _span(lo: float, hi: float) -> str:
    """``lo-hi`` to two figures, or the one value where they round alike ("11", not "11-11")."""
    a, b = f"{lo:.2g}", f"{hi:.2g}"
    return a if a == b else f"{a}-{b}"


#: the axle ratio on a WHEEL_RADIUS_M tyre per rpm per km/h per unit of gearbox ratio (2 pi r 3.6 / 60)
AXLE_PER_RPM_PER_KMH = 2.0 * math.pi * WHEEL_RADIUS_M * 3.6 / 60.0


class RecordWarning:
    """A whole-record finding that is a warning: the outputs are written and the exit status stays 0."""

    kind: ClassVar[str] = "plausibility"

    @property
    def severity(self) -> Severity:
        return Severity.WARNING


@dataclass(frozen=True)
class GearRatioFinding(RecordWarning):
    """The gears ``gears`` drove at ``rpm_per_kmh`` (median engine speed per km/h each), whose ratios in this
    gearbox are ``ratios``: from one gear to the next they step otherwise than the gearbox's ratios (by more than
    GEAR_RATIO_TOL), or they need an axle ratio outside AXLE_RANGE. A warning: the outputs are written and the exit
    status stays 0, but the losses are those of other gears."""

    gears: tuple
    rpm_per_kmh: tuple
    ratios: tuple
    gearbox: str
    source: str = "table"

    @property
    def spn_key(self) -> str:
        return "gear"

    @property
    def axles(self) -> list[float]:
        """The axle ratio each gear implies on a WHEEL_RADIUS_M tyre."""
        return [x / r * AXLE_PER_RPM_PER_KMH for x, r in zip(self.rpm_per_kmh, self.ratios)]

    @property
    def sentence(self) -> str:
        col = "the gear (ETC2 SPN 523)" if self.source == "can" else "column gear"
        steps = lambda xs: " : ".join(f"{a / b:.2f}" for a, b in zip(xs, xs[1:]))  # noqa: E731
        fix = "set [can] gear_map" if self.source == "can" else "renumber the gears"
        lo, hi = AXLE_RANGE
        axles = self.axles
        why = []
        if max(axles) > (1.0 + GEAR_RATIO_TOL) * min(axles):
            why.append(f"steps {steps(self.rpm_per_kmh)}, where the {self.gearbox}'s ratios step {steps(self.ratios)}")
        if min(axles) < lo or max(axles) > hi:
            why.append(
                f"over the {self.gearbox}'s ratios an axle ratio of {_span(min(axles), max(axles))} on "
                f"{WHEEL_RADIUS_M:g} m tyres, where road vehicles have {lo:g}-{hi:g}"
            )
        why = "; ".join(why)
        x = self.rpm_per_kmh
        up = [g for g, a, b in zip(self.gears[1:], x, x[1:]) if b > (1.0 + GEAR_RATIO_TOL) * a]
        if up:  # a higher gear turning the engine faster per km/h: no numbering does that
            speeds = (
                "the engine and vehicle speeds" if self.source == "can" else "engine_speed_rpm and vehicle_speed_kmh"
            )
            gears, turns = ", ".join(map(str, self.gears)), ", ".join(f"{v:.1f}" for v in x)
            return (
                f"{col} does not follow the {self.gearbox}'s ratios: driving in gears {gears}, the engine turns "
                f"{turns} rpm per km/h, more in gear {', '.join(map(str, up))} than in the gear below: no gearbox's "
                f"numbering does that; check that {speeds} are those quantities in rpm and km/h (a swapped or "
                "mislabelled column)"
            )
        if len(self.gears) > 1 and max(axles) <= (1.0 + GEAR_RATIO_TOL) * min(axles):
            # every gear steps as this gearbox's, only the overall scale is off: a speed's unit, or a numbering
            # shifted along a geometric ladder (the two look alike; a unit was blamed on the gears alone)
            speeds = "the engine or vehicle speed" if self.source == "can" else "engine_speed_rpm or vehicle_speed_kmh"
            return (
                f"{col} does not follow the {self.gearbox}'s ratios: driving in gears "
                f"{', '.join(map(str, self.gears))}, the engine turns {', '.join(f'{v:.1f}' for v in x)} rpm per "
                f"km/h, which steps as the {self.gearbox}'s ratios do but means {why}: either {speeds} is in another "
                "unit or scale (m/s for km/h is 3.6 x, rad/s for rpm 9.5 x: give rpm and km/h), or the gear numbers "
                f"are shifted along its ladder ({fix} to this gearbox's numbers)"
            )
        return (
            f"{col} does not follow the {self.gearbox}'s ratios: driving in gears "
            f"{', '.join(map(str, self.gears))}, the engine turns {', '.join(f'{v:.1f}' for v in x)} "
            f"rpm per km/h ({why}): these gear numbers are another gearbox's, and the losses those of other gears; "
            f"{fix} to this gearbox's numbers, or replay with its own description (--gearbox)"
        )


def gear_ratio_finding(
    speed_rpm, vehicle_kmh, gear, ratios, gearbox: str, dt_s: float = STEP_S, source: str = "table"
) -> GearRatioFinding | None:
    """The gear-numbering rules (GEAR_RATIO_TOL, AXLE_RANGE) on a record's engine speed, vehicle speed and gear;
    ``ratios``: gear number -> this gearbox's ratio (input over output speed)."""
    s, v, g = (_finite(x) for x in (speed_rpm, vehicle_kmh, gear))
    driving = np.isfinite(s) & np.isfinite(v) & np.isfinite(g) & (v > GEAR_MIN_KMH) & (s > GEAR_MIN_RPM)
    driving = _steady(s, v, g, driving, dt_s)
    per = {}
    for n in np.unique(g[driving]).astype(int):
        r = abs(float(ratios.get(int(n), math.nan)))
        rows = driving & (g == n)
        if math.isfinite(r) and r > 0 and rows.sum() * dt_s >= GEAR_MIN_S:
            per[int(n)] = (float(np.median(s[rows] / v[rows])), r)
    if not per:
        return None
    gears = sorted(per)
    found = GearRatioFinding(
        tuple(gears), tuple(per[n][0] for n in gears), tuple(per[n][1] for n in gears), gearbox, source
    )
    axles = found.axles
    lo, hi = AXLE_RANGE
    spread = len(per) >= 2 and max(axles) > (1.0 + GEAR_RATIO_TOL) * min(axles)
    return found if spread or min(axles) < lo or max(axles) > hi else None


def _steady(speed_rpm, vehicle_kmh, gear, driving, dt_s: float) -> np.ndarray:
    """The driving steps whose engine speed per km/h is steady (GEAR_STEADY_S, GEAR_STEADY_TOL): a step compares
    with the steps GEAR_STEADY_S before and after it (the neighbouring rows of a table further apart) that drive in
    the same gear; it needs one such step and none off by more than GEAR_STEADY_TOL."""
    k = max(1, int(round(GEAR_STEADY_S / dt_s)))
    if driving.size <= k:
        return np.zeros(driving.size, dtype=bool)
    q = np.where(driving, speed_rpm / np.where(driving, vehicle_kmh, 1.0), 1.0)
    pair = driving[k:] & driving[:-k] & (gear[k:] == gear[:-k])  # step i and step i + k, same gear
    off = pair & (np.abs(np.log(q[k:] / q[:-k])) > math.log1p(GEAR_STEADY_TOL))
    compared, unsteady = np.zeros(driving.size, dtype=bool), np.zeros(driving.size, dtype=bool)
    for flags, out in ((pair, compared), (off, unsteady)):
        out[k:] |= flags
        out[:-k] |= flags
    return driving & compared & ~unsteady


@dataclass(frozen=True)
class RepairFinding:
    """The sensor clamped or repaired inputs on ``repaired`` (reason -> steps) of ``steps`` steps; untrusted above
    REPAIR_UNTRUSTED_SHARE for any reason."""

    kind: ClassVar[str] = "repair"
    steps: int
    repaired: dict
    engine: bool = True  # a vehicle's engine drives it (else a fixed-ratio drive's input shaft: DRIVE_REPAIR_REASONS)
    step_word: str = "steps"  # what ``steps`` and the counts count: "rows" for a held table's (its input rows)

    @property
    def severity(self) -> Severity:
        return Severity.UNTRUSTED

    @property
    def spn_key(self) -> str:
        """The input repaired on the most steps."""
        return REPAIR_INPUTS[max(self.repaired, key=self.repaired.get)]

    @property
    def sentence(self) -> str:
        worst = sorted(
            ((n, r) for r, n in self.repaired.items() if n > REPAIR_UNTRUSTED_SHARE * self.steps), reverse=True
        )
        words = REPAIR_REASONS if self.engine else {**REPAIR_REASONS, **DRIVE_REPAIR_REASONS}
        said = "; ".join(f"{words[r]} on {pct(n, self.steps)}" for n, r in worst)
        return (
            f"the sensor clamped or repaired an input on more than {100 * REPAIR_UNTRUSTED_SHARE:.0f} % of its "
            f"{self.steps} {self.step_word} ({said}): its temperatures rest on values it had to change, not on the "
            f"record; check the column's unit and sign (or the sender's scaling)"
        )


def span_words(minutes: float) -> str:
    """A span in the unit a reader takes in: minutes under two hours, hours under two days, else days."""
    if minutes < 120.0:
        return f"{minutes:.1f} min"
    return f"{minutes / 60.0:.1f} h" if minutes < 2880.0 else f"{minutes / 1440.0:.1f} days"


def _finite(values) -> np.ndarray:
    return np.asarray(values, dtype=float).ravel()


def _max_rate_c_per_min(oil_c: np.ndarray, dt_s: float) -> float:
    """The fastest rise of the readings over OIL_RATE_WINDOW_S (NaN rows skipped) [K/min]."""
    lag = max(1, int(round(OIL_RATE_WINDOW_S / dt_s)))
    if oil_c.size <= lag:
        return 0.0
    rise = oil_c[lag:] - oil_c[:-lag]
    rise = rise[np.isfinite(rise)]
    return float(rise.max()) / (lag * dt_s / 60.0) if rise.size else 0.0


def oil_unit_finding(
    oil, dt_s: float = STEP_S, source: str = "table", warning_c: float | None = None
) -> PlausibilityFinding | None:
    """The oil rule (module doc) over the readings of a record, one every ``dt_s``; None when degC fits.
    ``warning_c``: the gearbox's own sump warning limit (the envelope's top then lies OIL_ABOVE_WARNING_K above it,
    at most OIL_ENVELOPE_C's); None: OIL_WARNING_DEFAULT_C, the GRS905's."""
    raw = _finite(oil)
    x = raw[np.isfinite(raw)]
    warning_c = OIL_WARNING_DEFAULT_C if warning_c is None else float(warning_c)
    lo, hi = OIL_ENVELOPE_C[0], min(OIL_ENVELOPE_C[1], warning_c + OIL_ABOVE_WARNING_K)
    if x.size * dt_s < OIL_MIN_S or np.mean(x > hi) < OIL_HOT_SHARE:
        return None
    fits = []
    for name, words, to_c, fix in OIL_UNITS:
        c = to_c(x)
        if (
            np.mean((c >= lo) & (c <= hi)) >= OIL_FIT_SHARE
            and _max_rate_c_per_min(to_c(raw), dt_s) <= OIL_MAX_RATE_C_PER_MIN
        ):
            fits.append((name, words, to_c, fix))
    if not fits:
        return None
    col = SOURCES[source]["oil_temp_c"]
    as_units = " or ".join(
        f"as {w} it is {to_c(np.percentile(x, 1)):.0f}-{to_c(np.percentile(x, 99)):.0f} degC" for _, w, to_c, _ in fits
    )
    fix = (
        ("give degC: " + " or ".join(f for *_, f in fits))
        if source == "table"
        else "the DBC fixes the unit, so check the node that sends it (or a gateway that re-encodes it)"
    )
    span_min = x.size * dt_s / 60.0
    return PlausibilityFinding(
        "oil_temp_c",
        " or ".join(n for n, *_ in fits),
        f"{col} reads {np.percentile(x, 1):.0f}-{np.percentile(x, 99):.0f} (median {np.median(x):.0f}) over "
        f"{span_words(span_min)}, above {hi:.0f} degC on {pct(int(np.sum(x > hi)), x.size)} of the readings, where a "
        f"gearbox sump in degC does not stay (its warning limit is {warning_c:.0f} degC); {as_units}, a plausible "
        f"drive: the oil looks like {' or '.join(w for _, w, *_ in fits)}, not degC; {fix} (if the sump really ran "
        f"above {hi:.0f} degC: stop and check the gearbox)",
    )


def oil_model_unit_finding(oil, model_oil, dt_s: float = STEP_S, source: str = "table") -> PlausibilityFinding | None:
    """The oil against the sensor's modelled sump (OIL_MODEL_OFF_K ...): a finding when degC lies far off the model
    and another unit lies near it; None otherwise."""
    x, m = _finite(oil), _finite(model_oil)
    ok = np.isfinite(x) & np.isfinite(m)
    if ok.sum() * dt_s < OIL_MODEL_MIN_S:
        return None
    off = float(np.median(x[ok] - m[ok]))
    if abs(off) < OIL_MODEL_OFF_K:
        return None
    near = [(float(np.median(np.abs(to_c(x[ok]) - m[ok]))), name, words, fix) for name, words, to_c, fix in OIL_UNITS]
    best = min(near)
    if not best[0] <= min(OIL_MODEL_FIT_SHARE * abs(off), OIL_MODEL_FIT_K):
        return None
    col = "oil_temp_c" if source == "table" else "the oil temperature"
    fix = f"give degC: {best[3]}" if source == "table" else "check the node that sends it"
    return PlausibilityFinding(
        "oil_temp_c",
        best[1],
        f"{col} reads {abs(off):.0f} K {'above' if off > 0 else 'below'} the sensor's own modelled sump on median "
        f"over {span_words(ok.sum() * dt_s / 60.0)}, where as {best[2]} it would lie {best[0]:.0f} K from it: the oil "
        f"looks like {best[2]}, not degC; {fix} (if it is degC, the gearbox or its cooler is not the one modelled: "
        "check --gearbox and the configuration's [cooler])",
    )


@dataclass(frozen=True)
class OilModelGapFinding(RecordWarning):
    """The measured oil ``off_k`` [K] from the sensor's own modelled sump on median over ``span_min`` minutes, no
    unit explaining it (:data:`OIL_MODEL_GAP_K`); ``defaulted``: the auxiliary inputs the record never gave. A
    warning: the outputs are written and the exit status stays 0."""

    off_k: float
    span_min: float
    defaulted: tuple = ()
    source: str = "table"

    @property
    def spn_key(self) -> str:
        return "oil_temp_c"

    @property
    def sentence(self) -> str:
        col = "oil_temp_c" if self.source == "table" else "the oil temperature"
        why = (
            f"; {' and '.join(self.defaulted)} never given: the sensor takes its configured default in its place, and "
            "the cooler it sets decides the oil the jets spray on the parts, so their estimates rest on it: give "
            f"{'them' if len(self.defaulted) > 1 else 'it'}"
            if self.defaulted
            else ""
        )
        return (
            f"{col} runs {abs(self.off_k):.0f} K {'above' if self.off_k > 0 else 'below'} the sensor's own modelled "
            f"sump on median over {span_words(self.span_min)}: the model's cooler or boundaries are not this "
            "gearbox's as it ran; the part estimates take the measured sump, but the oil the cooler leaves for the "
            f"jets and the boundaries are the model's, so they may be off by as much or more{why} (else check "
            "--gearbox and the configuration's [cooler])"
        )


def oil_model_gap_finding(oil, model_oil, defaulted=(), dt_s: float = STEP_S, source: str = "table"):
    """:class:`OilModelGapFinding` when the oil lies at least OIL_MODEL_GAP_K from the modelled sump on median over
    at least OIL_MODEL_MIN_S; None otherwise."""
    x, m = _finite(oil), _finite(model_oil)
    ok = np.isfinite(x) & np.isfinite(m)
    if ok.sum() * dt_s < OIL_MODEL_MIN_S:
        return None
    off = float(np.median(x[ok] - m[ok]))
    if abs(off) < OIL_MODEL_GAP_K:
        return None
    return OilModelGapFinding(off, ok.sum() * dt_s / 60.0, tuple(defaulted), source)


def _fast_windows(t: np.ndarray, x: np.ndarray, window_s: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The windows of ``window_s`` (on a grid of OIL_FAST_BINS bins a window) over readings ``x`` at times ``t``:
    (first and last row of each window, 2 x windows; which change faster than OIL_FAST_K_S and gradually; the
    time [s] the fast windows cover)."""
    bin_s = window_s / OIL_FAST_BINS
    edges = t[0] + bin_s * np.arange(int((t[-1] - t[0]) / bin_s) + 1)
    rows = np.searchsorted(t, edges, side="right") - 1  # the last row at or before each edge
    if rows.size <= OIL_FAST_BINS:
        return np.zeros((2, 0), dtype=int), np.zeros(0, dtype=bool), 0.0
    step = np.abs(np.diff(x))[: rows[-1]]
    bin_max = np.zeros(rows.size - 1)
    full = rows[1:] > rows[:-1]  # bins holding a row's step; the rest hold none
    if full.any():
        bin_max[full] = np.maximum.reduceat(step, rows[:-1][full])
    largest = np.lib.stride_tricks.sliding_window_view(bin_max, OIL_FAST_BINS).max(axis=1)
    ends = np.stack([rows[:-OIL_FAST_BINS], rows[OIL_FAST_BINS:]])
    rise, dt_s = x[ends[1]] - x[ends[0]], t[ends[1]] - t[ends[0]]
    fast = (dt_s > 0) & (np.abs(rise) > OIL_FAST_K_S * dt_s) & (largest <= OIL_FAST_STEP_SHARE * np.abs(rise))
    covered = np.convolve(fast.astype(float), np.ones(OIL_FAST_BINS))[: bin_max.size] > 0
    return ends, fast, float(covered.sum()) * bin_s


def oil_rate_finding(time_s, oil, source: str = "table") -> PlausibilityFinding | None:
    """The time-unit rule (OIL_FAST_K_S): the oil readings, over the record's own time column, change faster than a
    gearbox sump can (a table's time_s in minutes, or an oil sensor ramping wrong); None when they do not."""
    t, x = _finite(time_s), _finite(oil)
    ok = np.isfinite(t) & np.isfinite(x)
    t, x = t[ok], x[ok]
    if t.size < 4 or not np.all(np.diff(t) > 0):  # (a window holds at least 3 rows' steps)
        return None
    window_s = max(OIL_FAST_WINDOW_S, 3.0 * float(np.median(np.diff(t))))
    ends, fast, covered_s = _fast_windows(t, x, window_s)
    # two windows' worth, or all of a record shorter than that (on the windows' grid)
    bin_s = window_s / OIL_FAST_BINS
    if not fast.any() or covered_s < min(OIL_FAST_WINDOWS * window_s, bin_s * int((t[-1] - t[0]) / bin_s)):
        return None
    i0, i1 = ends[:, fast][:, np.argmax(np.abs(x[ends[1]] - x[ends[0]])[fast] / (t[ends[1]] - t[ends[0]])[fast])]
    rate = abs(x[i1] - x[i0]) / (t[i1] - t[i0])
    col, when = (("column oil_temp_c", "time_s"), ("the oil temperature (TRF1 SPN 177)", "frame time"))[
        source != "table"
    ]
    fix = (
        "if time_s is in minutes, give seconds (time_s x 60)"
        if source == "table"
        else "is the log's time base right (a log played faster than real time and stamped on arrival)?"
    )
    return PlausibilityFinding(
        "time_s",
        "minutes",
        f"{col} changes up to {rate:.1f} K/s over {window_s:g} s of {when} (from {x[i0]:.0f} to {x[i1]:.0f} degC at "
        f"{t[i0]:g}-{t[i1]:g} s) and faster than {OIL_FAST_K_S:g} K/s over {covered_s:.0f} s of the record, where a "
        f"gearbox sump with its housing changes at most about 0.5 K/s (at full load); {fix}; if the oil really "
        "changed that fast, check its sensor",
    )


def _driving(speed_rpm, gear, n: int) -> np.ndarray:
    speed = _finite(speed_rpm) if speed_rpm is not None else np.full(n, np.nan)
    if gear is None:
        return np.isfinite(speed) & (speed >= DRIVE_MIN_RPM)
    g = _finite(gear)
    return np.isfinite(speed) & (speed >= DRIVE_MIN_RPM) & np.isfinite(g) & (g != 0)


def torque_sign_finding(
    speed_rpm,
    torque_nm,
    gear=None,
    dt_s: float = STEP_S,
    min_torque_nm: float | None = None,
    source: str = "table",
    engine: bool = True,
) -> PlausibilityFinding | None:
    """The torque-sign rule (module doc); ``min_torque_nm``: the engine's braking limit (None: only the
    SIGN_ALL_SHARE branch); ``engine``: a vehicle's engine (False: a fixed-ratio drive's input, said in its words)."""
    torque = _finite(torque_nm)
    drive = _driving(speed_rpm, gear, torque.size) & np.isfinite(torque)
    n = int(drive.sum())
    if n * dt_s < SIGN_MIN_DRIVE_S:
        return None
    t = torque[drive]
    neg = float(np.mean(t < SIGN_NEG_NM))
    beyond = float(np.mean(t < min_torque_nm)) if min_torque_nm is not None else 0.0
    if neg <= SIGN_SHARE or (beyond < SIGN_BEYOND_SHARE and neg < SIGN_ALL_SHARE):
        return None
    col = SOURCES[source]["engine_torque_nm"]
    brake = (
        f", below the {'engine' if engine else 'drive'}'s braking limit {min_torque_nm:.0f} Nm on "
        f"{pct(int(np.sum(t < min_torque_nm)), n)}"
        if beyond >= SIGN_BEYOND_SHARE
        else ""
    )
    if not engine and source == "table":
        return PlausibilityFinding(
            "engine_torque_nm",
            "negative",
            f"column input_torque_nm is below {SIGN_NEG_NM:.0f} Nm on {pct(int(np.sum(t < SIGN_NEG_NM)), n)} of "
            f"the {n} steps the input turns at {DRIVE_MIN_RPM:.0f} rpm or more (median {np.median(t):.0f} Nm"
            f"{brake}): no drive brakes its gearbox for a whole run, so the sign convention looks mixed up; negate "
            "the column (the input torque is positive when it drives the gearbox)",
        )
    fix = (
        "negate the column (the engine's output torque is positive when it drives)"
        if source == "table"
        else "check the node that sends EEC1 (or a gateway that re-encodes it)"
    )
    return PlausibilityFinding(
        "engine_torque_nm",
        "negative",
        f"{col} is below {SIGN_NEG_NM:.0f} Nm on {pct(int(np.sum(t < SIGN_NEG_NM)), n)} of the {n} driving steps "
        f"(engine at {DRIVE_MIN_RPM:.0f} rpm or more in gear; median {np.median(t):.0f} Nm{brake}): engine braking "
        f"does not last a whole drive, so the sign convention looks mixed up; {fix}",
    )


def _driven_torque(speed_rpm, torque_nm, gear, dt_s: float) -> np.ndarray | None:
    """The torque of the driving steps, or None when they last under PERCENT_MIN_DRIVE_S (too short to judge)."""
    torque = _finite(torque_nm)
    drive = _driving(speed_rpm, gear, torque.size) & np.isfinite(torque)
    return torque[drive] if int(drive.sum()) * dt_s >= PERCENT_MIN_DRIVE_S else None


def _on_the_road(speed_rpm, torque_nm, gear, vehicle_kmh, dt_s: float) -> bool:
    """Whether the driving steps are a vehicle's on the road (PERCENT_MOVING_*): it moves on most of them, for at
    least PERCENT_MOVING_MIN_S; False without a vehicle speed (a rig's table)."""
    if vehicle_kmh is None:
        return False
    torque = _finite(torque_nm)
    drive = _driving(speed_rpm, gear, torque.size) & np.isfinite(torque)
    v = _finite(vehicle_kmh)[drive]
    return v.size * dt_s >= PERCENT_MOVING_MIN_S and float(np.mean(v >= PERCENT_MOVING_KMH)) >= PERCENT_MOVING_SHARE


def torque_percent_finding(
    speed_rpm,
    torque_nm,
    gear=None,
    dt_s: float = STEP_S,
    source: str = "table",
    vehicle_kmh=None,
    drive_max_nm: float | None = None,
) -> PlausibilityFinding | None:
    """The percent-torque rule (module doc); ``vehicle_kmh``: the vehicle's speed (None: a rig's table), for the
    rule of a vehicle on the road (PERCENT_MOVING_*); ``drive_max_nm``: a fixed-ratio drive's largest torque (None:
    a vehicle's engine), judged only when at least PERCENT_FIXED_MIN_NM (a small motor's reducer honestly runs
    on at most 125 N m) and said in its words."""
    t = _driven_torque(speed_rpm, torque_nm, gear, dt_s)
    if t is None or (drive_max_nm is not None and not drive_max_nm >= PERCENT_FIXED_MIN_NM):
        return None
    n = t.size
    peak = float(t.max())
    # (J1939's percent torque spans -125..125 %: a torque below -125 is N m, engine braking on a descent)
    if not (PERCENT_MIN_PEAK <= peak <= PERCENT_MAX) or float(t.min()) < -PERCENT_MAX:
        return None
    p10, p90 = (float(v) for v in np.percentile(t, [10, 90]))
    road = p10 > 0.0 and p90 - p10 >= PERCENT_MOVING_SPREAD
    if p90 - p10 < PERCENT_MIN_SPREAD and not (road and _on_the_road(speed_rpm, torque_nm, gear, vehicle_kmh, dt_s)):
        return None
    if drive_max_nm is not None:
        return PlausibilityFinding(
            "engine_torque_nm",
            "percent",
            f"column input_torque_nm never exceeds {PERCENT_MAX:.0f} over {span_words(n * dt_s / 60.0)} with the "
            f"input at {DRIVE_MIN_RPM:.0f} rpm or more (peak {peak:.0f}, median {np.median(t):.0f}) while the drive "
            f"takes up to {drive_max_nm:.4g} N m, so the torque looks like percent of it, not N m; give N m, unless "
            "it is an honest light load",
        )
    col = SOURCES[source]["engine_torque_nm"]
    fix = (
        "give N m (percent / 100 x the engine's reference torque, EC1 SPN 544)"
        if source == "table"
        else "check the reference torque ([can] engine_reference_torque_nm, else EC1 SPN 544 from the engine)"
    )
    return PlausibilityFinding(
        "engine_torque_nm",
        "percent",
        f"{col} never exceeds {PERCENT_MAX:.0f} over {span_words(n * dt_s / 60.0)} of driving (peak {peak:.0f}, median "
        f"{np.median(t):.0f}): a truck engine gives 1000-3500 N m and moves no truck for minutes on at most "
        f"{PERCENT_MAX:.0f} N m, so the torque looks like percent of the reference torque, not N m; {fix}",
    )


#: the kN m rule: a drive of at least PERCENT_MIN_DRIVE_S whose torque peaks above KNM_MIN_PEAK (it is there) and at
#: most KNM_MAX (no engine moves a truck for minutes on 10 N m; 2.6 kN m written in kN m is 2.6)
KNM_MAX, KNM_MIN_PEAK = 10.0, 0.5


def torque_knm_finding(
    speed_rpm, torque_nm, gear=None, dt_s: float = STEP_S, source: str = "table"
) -> PlausibilityFinding | None:
    """The kN m rule (KNM_MAX): a vehicle's engine torque that looks like kN m."""
    t = _driven_torque(speed_rpm, torque_nm, gear, dt_s)
    if t is None:
        return None
    n = t.size
    peak = float(np.max(np.abs(t)))
    if not KNM_MIN_PEAK < peak <= KNM_MAX:
        return None
    col = SOURCES[source]["engine_torque_nm"]
    return PlausibilityFinding(
        "engine_torque_nm",
        "kN m",
        f"{col} never exceeds {KNM_MAX:.0f} over {span_words(n * dt_s / 60.0)} of driving (peak {peak:.3g}): a truck "
        f"engine gives 1000-3500 N m, so the torque looks like kN m; give N m (x 1000)",
    )


#: the kN m rule of a fixed-ratio drive: where the input shaft turns at FIXED_FAST_SHARE of the drive's max speed or
#: more for at least FIXED_KNM_MIN_S, a torque whose 99th percentile is at most FIXED_KNM_SHARE of the drive's max
#: torque (every value fits it as kN m) and above 0 looks like kN m. In N m no honest record is that low there: a
#: wind turbine's rotor at 12 rpm and more delivers at least 166 kN m (median 310-340 kN m on the three shared MM82
#: turbines' 2013-2020 SCADA; the rule's bound is 2.5 kN m), and a motor's reducer must at least overcome its own
#: drag (the reference plant at 1485 rpm and 0 N m: the HR225 loses 0.61 kW, 3.9 N m against its bound of 1.8; the
#: R1 0.17 kW at 1450 rpm, 1.1 N m against 0.6)
FIXED_FAST_SHARE, FIXED_KNM_SHARE, FIXED_KNM_MIN_S = 0.6, 1e-3, 3600.0


#: a fixed-ratio drive's input turning above this multiple of its description's largest speed on more than half of
#: its running rows (at least FIXED_KNM_MIN_S) is another gearbox's record, or a speed in another unit
FIXED_OVERSPEED = 2.0


def fixed_speed_finding(speed_rpm, drive_limits, dt_s: float = STEP_S, source: str = "table"):
    """FIXED_OVERSPEED's rule: a record of a much faster input than the gearbox described (a 1480 rpm reducer's run
    replayed on the MM82, whose rotor turns 17 rpm, read as a torque in kN m before)."""
    max_rpm = float(drive_limits[0])
    speed = _finite(speed_rpm)
    running = np.isfinite(speed) & (speed > 0.0)
    n = int(running.sum())
    if n * dt_s < FIXED_KNM_MIN_S or not max_rpm > 0 or np.mean(speed[running] > FIXED_OVERSPEED * max_rpm) <= 0.5:
        return None
    median = float(np.median(speed[running]))
    col = "column input_speed_rpm" if source == "table" else SOURCES[source]["engine_speed_rpm"]
    return PlausibilityFinding(
        "engine_speed_rpm",
        "another gearbox",
        f"{col} turns at a median {median:.4g} rpm, {median / max_rpm:.3g} times the {max_rpm:.4g} rpm this gearbox's "
        "input turns at most: the record is another gearbox's (replay it with --gearbox of the one it comes from), "
        "or its speed is in another unit",
    )


def fixed_torque_knm_finding(
    speed_rpm, torque_nm, drive_limits, dt_s: float = STEP_S, source: str = "table"
) -> PlausibilityFinding | None:
    """The kN m rule of a fixed-ratio drive (FIXED_KNM_SHARE); ``drive_limits``: its (max speed [rpm], max torque
    [N m]) from the gearbox description."""
    max_rpm, max_nm = (float(v) for v in drive_limits)
    speed, torque = _finite(speed_rpm), _finite(torque_nm)
    fast = np.isfinite(speed) & np.isfinite(torque) & (speed >= FIXED_FAST_SHARE * max_rpm)
    n = int(fast.sum())
    if n < 3 or n * dt_s < FIXED_KNM_MIN_S or not (max_rpm > 0 and max_nm > 0):
        return None
    p99, median = (float(v) for v in np.percentile(torque[fast], [99, 50]))
    if not (median > 0 and p99 <= FIXED_KNM_SHARE * max_nm):
        return None
    # x 1000 that would still leave the torque inside the rule is no fix: MN m (a power 10^6 times too small)
    unit, times, power = (
        ("MN m", "1e6", "10^6 times too small: in MW read as W")
        if 1e3 * p99 <= FIXED_KNM_SHARE * max_nm
        else ("kN m", "1000", "1000 times too small: in MW read as kW, in kW read as W")
    )
    col = "column input_torque_nm" if source == "table" else SOURCES[source]["engine_torque_nm"]
    return PlausibilityFinding(
        "engine_torque_nm",
        unit,
        f"{col} stays at or below {p99:.4g} N m (99th percentile; median {median:.4g}) over the "
        f"{n * dt_s / 3600.0:.1f} h the input shaft turns at {FIXED_FAST_SHARE * max_rpm:.3g} rpm or more, within "
        f"{FIXED_KNM_SHARE * 100:g} % of the drive's {max_nm:.3g} N m: no gearbox turns that fast on so little "
        f"(its own drag is more), so the torque looks like {unit} (or derived from a power {power}); give N m "
        f"(x {times})",
    )


#: the ambient and coolant temperatures the sensor takes (firmware_model.onboard.records.SensorOptions.aux_range_c);
#: outside, it uses its default. A column outside on more than AUX_OUT_SHARE of its finite rows is a unit mistake.
AUX_COLUMNS_C, AUX_RANGE_C, AUX_OUT_SHARE = ("ambient_temp_c", "coolant_temp_c"), (-60.0, 150.0), 0.5


def aux_unit_finding(name: str, values_c) -> PlausibilityFinding | None:
    """The ambient or coolant column ``name`` mostly outside AUX_RANGE_C: the sensor replaced it by its default
    (e.g. a coolant in kelvin: the warning its heat would give is gone)."""
    x = _finite(values_c)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return None
    lo, hi = AUX_RANGE_C
    out = (x < lo) | (x > hi)
    if out.mean() <= AUX_OUT_SHARE:
        return None
    med = float(np.median(x))
    likely = "kelvin" if lo + 273.15 <= med <= hi + 273.15 else "another unit"
    return PlausibilityFinding(
        name,
        "K" if likely == "kelvin" else "unit",
        f"column {name} lies outside {lo:g}..{hi:g} degC on {pct(int(out.sum()), out.size)} of its rows (median "
        f"{med:.1f}): it looks like {likely}, and the sensor used its default in its place; give degC",
    )


def record_findings(
    columns,
    dt_s: float = STEP_S,
    min_torque_nm: float | None = None,
    source: str = "table",
    engine: bool = True,
    drive_limits: tuple | None = None,
    oil_warning_c: float | None = None,
    twin: bool = True,
    aux_expected: tuple = AUX_COLUMNS_C,
) -> list[PlausibilityFinding]:
    """The unit and sign findings of a whole record: ``columns`` maps run-table names (``oil_temp_c``,
    ``engine_speed_rpm``, ``engine_torque_nm``, ``gear``) to one value per ``dt_s`` (a RunTable or a dict;
    an absent column is not judged); ``source``: "table" or "can" (the sentence's words and fix); ``engine``: the
    drive is a vehicle's engine (a fixed-ratio drive's input, an idling reducer's few N m, is no kN m mistake by the
    engine's rule); ``drive_limits``: a fixed-ratio drive's (max speed [rpm], max torque [N m]), for its kN m rule;
    ``oil_warning_c``: the gearbox's sump warning limit, for the oil's unit rule (None: the GRS905's); ``twin``: the
    sensor's own modelled sump is judged beside the oil (False: a rig conditions the sump); ``aux_expected``: the
    auxiliary columns the gearbox reads (a missing one is named when the oil lies far from the model)."""

    def col(name):
        has = columns.has(name) if hasattr(columns, "has") else name in columns
        return columns[name] if has else None

    out = []
    oil, speed, torque, gear = (col(c) for c in ("oil_temp_c", "engine_speed_rpm", "engine_torque_nm", "gear"))
    if oil is not None:
        out.append(oil_unit_finding(oil, dt_s, source, oil_warning_c))
        modes = col("degraded_mode")
        # a replay's output: its twin beside the oil, a reference while the drive's inputs were the sensor's own
        # (degraded on more than OIL_MODEL_DEGRADED_SHARE, its modelled sump rests on held inputs: another gearbox's
        # record read as this one's, whose sump the twin misses by tens of kelvin in degC)
        if (
            out[-1] is None
            and twin
            and col("model_oil_temp_c") is not None
            and (modes is None or np.mean(np.asarray(modes, dtype=float) != MODE_NORMAL) <= OIL_MODEL_DEGRADED_SHARE)
        ):
            out.append(oil_model_unit_finding(oil, col("model_oil_temp_c"), dt_s, source))
            if out[-1] is None:  # degC, and still far from the model: its cooler's inputs or the gearbox
                never = tuple(c for c in aux_expected if col(c) is None or not np.isfinite(_finite(col(c))).any())
                out.append(oil_model_gap_finding(oil, col("model_oil_temp_c"), never, dt_s, source))
        if col("time_s") is not None:  # (a live check's samples carry none: its clock is the bus's)
            out.append(oil_rate_finding(col("time_s"), oil, source))
    if speed is not None and torque is not None:
        out.append(torque_sign_finding(speed, torque, gear, dt_s, min_torque_nm, source, engine))
        fixed_max_nm = None if engine or drive_limits is None else float(drive_limits[1])
        if engine or fixed_max_nm is not None:  # (a fixed-ratio drive without its limits: not judged)
            kmh = col("vehicle_speed_kmh")
            out.append(torque_percent_finding(speed, torque, gear, dt_s, source, kmh, fixed_max_nm))
        if engine:
            out.append(torque_knm_finding(speed, torque, gear, dt_s, source))
        elif drive_limits is not None:  # (a far faster input than described: its torque is no unit's mistake)
            over = fixed_speed_finding(speed, drive_limits, dt_s, source)
            out.append(over or fixed_torque_knm_finding(speed, torque, drive_limits, dt_s, source))
    if source == "table":  # (a CAN source decodes them in degC, its range checked by the decoder)
        out.extend(aux_unit_finding(c, col(c)) for c in AUX_COLUMNS_C if col(c) is not None)
    return [f for f in out if f is not None]


def _oil_warning_c(limits) -> float | None:
    """The sump's warning limit of a gearbox's limits (firmware_model.limits.Limits), None without one."""
    if limits is None or "oil" not in getattr(limits, "components", ()):
        return None
    return limits.of("oil")[0]


def repair_finding(
    rejects: Mapping[str, int], steps: int, engine: bool = True, rows: int | None = None
) -> RepairFinding | None:
    """The clamp/repair finding from the sensor's cumulative reject counters over ``steps`` steps, or None;
    ``engine``: a vehicle's engine drives the gearbox (False: a fixed-ratio drive's input shaft, said so); ``rows``:
    a held table's input rows, which the finding then counts in (its counters count 0.1 s steps, 6000 to a
    10-minute row: a sentence in those read as another run's)."""
    repaired = {r: int(rejects.get(r, 0)) for r in REPAIR_REASONS if int(rejects.get(r, 0))}
    if not steps or not any(n > REPAIR_UNTRUSTED_SHARE * steps for n in repaired.values()):
        return None
    if rows is not None:
        per_row = rows / steps
        return RepairFinding(int(rows), {r: int(round(n * per_row)) for r, n in repaired.items()}, engine, "rows")
    return RepairFinding(int(steps), repaired, engine)


def is_held(meta) -> bool:
    """Whether a replay's output table is held (tools.replay.table.replay_held: one row per input row, its reject
    counters in 0.1 s steps): its meta records the steps taken and their length."""
    return meta.get("steps") is not None and meta.get("step_s") is not None


def table_record_findings(out, min_torque_nm: float | None = None, source: str = "table") -> list:
    """The plausibility findings of a sensor output run table (a replay's: the inputs it read, one row per step,
    and the cumulative ``rejects_<reason>`` columns)."""
    if not out.n:
        return []
    meta = getattr(out, "meta", None) or {}
    held = is_held(meta)
    # a held table (tools.replay.table.replay_held: one row per input row, minutes apart): its rows' period, and
    # the 0.1 s steps its reject counters count
    dt_s = float(meta.get("row_period_s") or STEP_S) if held else STEP_S
    steps = int(round(meta["steps"] * meta["step_s"] / STEP_S)) if held else out.n
    found: list = record_findings(
        out,
        dt_s,
        min_torque_nm,
        source,
        bool(meta.get("engine_drive", True)),
        meta.get("drive_limits"),
        _oil_warning_c(meta.get("limits")),
        bool(meta.get("twin_judged", True)),
        tuple(meta.get("aux_expected", AUX_COLUMNS_C)),
    )
    if meta.get("gear_ratios") and all(out.has(c) for c in ("engine_speed_rpm", "vehicle_speed_kmh", "gear")):
        gears = gear_ratio_finding(
            out["engine_speed_rpm"],
            out["vehicle_speed_kmh"],
            out["gear"],
            meta["gear_ratios"],
            meta["gearbox"],
            dt_s,
            source,
        )
        found += [gears] if gears is not None else []
    rejects = {
        k[len("rejects_") :]: int(out[k][-1])
        for k in out.columns
        if k.startswith("rejects_") and np.isfinite(out[k][-1])
    }
    repair = repair_finding(rejects, steps, bool(meta.get("engine_drive", True)), out.n if held else None)
    return found + ([repair] if repair is not None else [])


#: the kinds of the whole-record findings (an offline replay takes them from its table, not from the service)
RECORD_KINDS = ("plausibility", "repair")


def with_record_findings(findings, out, min_torque_nm: float | None = None, source: str = "can") -> list:
    """A replay's findings: ``findings`` (the service's, ``firmware_model.service.trust``) with the whole-record
    ones taken from the output table ``out`` (all its steps, whichever path stepped them); most severe first."""
    kept = [f for f in findings if f.kind not in RECORD_KINDS]
    return sorted(kept + table_record_findings(out, min_torque_nm, source), key=lambda f: -f.severity)


#: the live check: one sample of the inputs every LIVE_SAMPLE_STEPS steps (1 s), the last LIVE_KEEP samples (2 h),
#: judged from LIVE_FIRST_S of steps on (the first minute) and again every LIVE_PERIOD_S
LIVE_SAMPLE_STEPS, LIVE_KEEP, LIVE_FIRST_S, LIVE_PERIOD_S = 10, 7200, 60.0, 60.0


class RecordCheck:
    """The whole-record rules for a running service: :meth:`add` every step (the inputs the step used, None when
    missing, and the sensor's cumulative reject counters); :meth:`update` returns the findings when a judgement is
    due (after the first minute, then every minute), else None; :attr:`findings` holds the latest judgement."""

    def __init__(self, min_torque_nm: float | None = None, reject_reasons=(), dt_s: float = STEP_S) -> None:
        self.min_torque_nm, self.dt_s = min_torque_nm, dt_s
        self.reasons = tuple(reject_reasons)
        self._samples = np.full((LIVE_KEEP, 4), np.nan)  # oil, speed, torque, gear
        self._n = 0  # samples taken (the ring's write position mod KEEP)
        self.steps = 0
        self._first_rejects = None
        self._rejects = None
        self._next_s = LIVE_FIRST_S
        self.findings: list = []

    def add(self, oil_c, speed_rpm, torque_nm, gear, rejects=None) -> None:
        if rejects is not None:
            if self._first_rejects is None:
                self._first_rejects = np.asarray(rejects, dtype=float).copy()
            self._rejects = rejects
        if self.steps % LIVE_SAMPLE_STEPS == 0:
            self._samples[self._n % LIVE_KEEP] = [
                np.nan if v is None else float(v) for v in (oil_c, speed_rpm, torque_nm, gear)
            ]
            self._n += 1
        self.steps += 1

    def update(self) -> list | None:
        """The findings when a judgement is due (None otherwise)."""
        if self.steps * self.dt_s < self._next_s:
            return None
        self._next_s += LIVE_PERIOD_S
        n = min(self._n, LIVE_KEEP)
        rows = np.roll(self._samples, -(self._n % LIVE_KEEP), axis=0)[-n:] if self._n > LIVE_KEEP else self._samples[:n]
        cols = dict(zip(("oil_temp_c", "engine_speed_rpm", "engine_torque_nm", "gear"), rows.T))
        found: list = record_findings(cols, self.dt_s * LIVE_SAMPLE_STEPS, self.min_torque_nm, "can")
        if self._rejects is not None and self.reasons:
            counts = np.asarray(self._rejects, dtype=float) - self._first_rejects
            repair = repair_finding(dict(zip(self.reasons, counts.astype(int).tolist())), self.steps)
            found += [repair] if repair is not None else []
        self.findings = found
        return found
