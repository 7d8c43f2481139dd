"""The degraded-share finding of a run (how much of it the sensor ran on held, modelled or default inputs), its
severity scale and :func:`untrusted`: the part of the trust findings (firmware_model.service.trust) that a run-table
replay needs, without the CAN edge (python-can, cantools), which trust imports for the time-base and source-address
checks.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from firmware_model.components import MODE_NAMES, MODE_NORMAL, MODE_OIL_MODEL

#: degraded on at least this share of the steps: a loud warning; above the second share: untrusted (`replay`
#: exits 3). Not initialised counts as degraded (it lasts at most 3 s of a run: 10 % of a 30 s capture).
DEGRADED_WARN_SHARE = 0.2
DEGRADED_UNTRUSTED_SHARE = 0.5
#: the inputs whose absence degrades the sensor, by their ``stale_steps`` name (the decoder signal) or run-table
#: validity column, and their readable names (the others have defaults and are not listed as a cause)
INPUT_NAMES = {
    "engine_speed_rpm": "engine speed",
    "engine_torque_nm": "engine torque",
    "gear": "gear",
    "oil_temp_c": "oil temperature",
    "speed_valid": "engine speed",
    "torque_valid": "engine torque",
    "gear_valid": "gear",
    "oil_valid": "oil temperature",
}


class Severity(enum.IntEnum):
    """How loud a finding is: NOTE (worth a line), WARNING (loud: the outputs are less accurate than they look),
    UNTRUSTED (loud, and `replay` exits 3: the outputs should not be used)."""

    NOTE = 0
    WARNING = 1
    UNTRUSTED = 2


@dataclass(frozen=True)
class DegradedFinding:
    """The sensor ran degraded on ``degraded`` of ``steps`` steps; ``by_mode``: degraded mode -> steps;
    ``missing``: input -> steps it was missing (stale, not available or invalid)."""

    kind: ClassVar[str] = "degraded"
    steps: int
    degraded: int
    by_mode: dict = field(default_factory=dict)
    missing: dict = field(default_factory=dict)
    causes: tuple = ()  # why inputs were missing, as far as the CAN decoder's counters tell (trust)
    rejected: dict = field(default_factory=dict)  # the sensor's own input checks: reject reason -> steps
    oil_frozen_at_c: float | None = None  # the oil reading on the last step it was rejected as frozen
    engine: bool = True  # a vehicle's engine drives the gearbox (False: a fixed-ratio drive's input shaft)
    step_word: str = "steps"  # what ``steps`` counts: "rows" for a held table's (its input rows)

    @property
    def share(self) -> float:
        return self.degraded / self.steps if self.steps else 0.0

    @property
    def severity(self) -> Severity:
        if self.share > DEGRADED_UNTRUSTED_SHARE:
            return Severity.UNTRUSTED
        return Severity.WARNING if self.share >= DEGRADED_WARN_SHARE else Severity.NOTE

    @property
    def sentence(self) -> str:
        modes = ", ".join(
            f"{MODE_NAMES.get(m, f'mode {m}')} {pct(n, self.steps)}"
            for m, n in sorted(self.by_mode.items(), key=lambda kv: -kv[1])
            if m != MODE_NORMAL and n
        )

        def name(k):  # a fixed-ratio drive's input shaft is no engine
            return INPUT_NAMES[k] if self.engine else INPUT_NAMES[k].replace("engine ", "input ")

        worst = sorted(
            ((n, f"{name(k)} {pct(n, self.steps)}") for k, n in self.missing.items() if n and k in INPUT_NAMES),
            reverse=True,
        )
        # the sensor's own checks (a frozen or implausible reading) next to the missing inputs, the most steps
        # first: a frozen oil reading is what degraded such a run, not the few steps a torque came late
        frozen_at = "" if self.oil_frozen_at_c is None else f" at {self.oil_frozen_at_c:.1f} degC"
        worst = sorted(
            worst
            + [
                (n, REJECT_WORDS[r].format(at=frozen_at, share=pct(n, self.steps)))
                for r, n in self.rejected.items()
                if n and r in REJECT_WORDS
            ],
            key=lambda nw: -nw[0],
        )
        inputs = (
            (
                "; inputs not usable (missing, stale or rejected as implausible or frozen): "
                + ", ".join(words for _, words in worst)
            )
            if worst
            else ""
        )
        why = f" ({'; '.join(self.causes)})" if self.causes else ""
        no_oil = any(INPUT_NAMES.get(k) == "oil temperature" and n >= self.steps for k, n in self.missing.items())
        advice = (
            ' (no oil reading at all: [sensor] oil_mode = "model", or --oil-mode model, models the oil by request, '
            "not as a fault)"
            if no_oil and self.steps
            else ""
        )
        return (
            f"the sensor ran degraded on {pct(self.degraded, self.steps)} of {self.steps} {self.step_word} "
            f"({modes}){inputs}"
            f"{why}: its temperatures rest on held, modelled or default inputs{advice}"
        )


#: the sensor's input checks that leave an input unused (firmware_model.onboard.records.REJECT_REASONS), in words;
#: {share}: the share of the run's steps, {at}: " at <the frozen reading> degC". (A frozen drive is only flagged:
#: its inputs are still used, so it is no cause of a degraded run.)
REJECT_WORDS = {
    "oil_frozen": "oil temperature frozen{at} for {share} of the steps (bit-identical while the model's "
    "sump moved: the oil was modelled instead)",
    "oil_implausible": "oil temperature rejected as implausible (out of range, or a jump) on {share} of the steps",
}


def pct(n: int, total: int) -> str:
    share = 100.0 * n / total if total else 0.0
    return f"{share:.0f} %" if share >= 1.0 or share == 0.0 else f"{share:.1f} %"


def degraded_finding(
    mode_steps: Mapping[int, int],
    missing: Mapping[str, int] | None = None,
    oil_model: bool = False,
    rejected: Mapping[str, int] | None = None,
    oil_frozen_at_c: float | None = None,
    engine: bool = True,
    step_word: str = "steps",
) -> DegradedFinding:
    """The degraded share of a run from its steps per degraded mode (and the steps each input was missing; the
    steps the sensor's own checks rejected one, ``rejected``: reason -> steps, with the frozen oil reading).
    ``oil_model``: the sensor was asked to model the oil (oil_mode "model"): its oil-modelled steps are its normal
    ones, and an absent oil reading is no cause."""
    rejected = dict(rejected or {})
    if oil_model:
        mode_steps = dict(mode_steps)
        mode_steps[MODE_NORMAL] = mode_steps.get(MODE_NORMAL, 0) + mode_steps.pop(MODE_OIL_MODEL, 0)
        missing = {k: v for k, v in (missing or {}).items() if INPUT_NAMES.get(k) != "oil temperature"}
        rejected = {k: v for k, v in rejected.items() if not k.startswith("oil_")}
    steps = int(sum(mode_steps.values()))
    degraded = steps - int(mode_steps.get(MODE_NORMAL, 0))
    return DegradedFinding(
        steps,
        degraded,
        {int(m): int(n) for m, n in mode_steps.items()},
        dict(missing or {}),
        rejected=rejected,
        oil_frozen_at_c=oil_frozen_at_c,
        engine=engine,
        step_word=step_word,
    )


#: a table whose rows jump forward in time on more than this share of the steps has the wrong time unit
TIME_JUMP_UNTRUSTED_SHARE = 0.5
#: an engine that delivers at least this torque [Nm] cannot turn slower than this [rpm]: a speed column in rad/s
#: (1300 rpm = 136 rad/s) does; untrusted when it happens on this share of the steps with torque
STALL_TORQUE_NM, STALL_SPEED_RPM, STALL_UNTRUSTED_SHARE = 500.0, 300.0, 0.2


@dataclass(frozen=True)
class UnitFinding:
    """A run table whose columns look like another unit than their names say: ``what`` says which and why."""

    kind: ClassVar[str] = "units"
    what: str

    @property
    def severity(self) -> Severity:
        return Severity.UNTRUSTED

    @property
    def sentence(self) -> str:
        return self.what


def unit_findings(
    steps: int, time_jumps: int, step_times_s, speed_rpm, torque_nm, hold_s: float = 60.0, engine: bool = True
) -> list[UnitFinding]:
    """The unit mistakes a run table shows: time_s in milliseconds (a forward time jump on most steps, the steps
    further apart than the ``hold_s`` over which a jump holds the inputs: the sensor took the engine as off for most
    of the run), engine speed in rad/s (a turning engine delivering torque far below any idle speed; only when the
    input is a vehicle's ``engine``: a fixed-ratio drive's rotor, the MM82's, delivers 2 MN m at 15 rpm)."""
    import numpy as np

    out = []
    t = np.asarray(step_times_s, dtype=float)
    spacing_s = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    if steps >= 3 and time_jumps > TIME_JUMP_UNTRUSTED_SHARE * steps and spacing_s > hold_s:
        out.append(
            UnitFinding(
                f"time_s jumps forward on {time_jumps} of {steps} steps, {spacing_s:.0f} s apart (the "
                f"sensor held the inputs {hold_s:.0f} s over each gap, then took the engine as off): "
                f"if time_s is in milliseconds, give seconds; if the rows really lie "
                f"{spacing_s:.0f} s apart, the table is too sparse for the sensor (rows at most "
                f"{hold_s:.0f} s apart; resample it)"
            )
        )
    speed, torque = np.asarray(speed_rpm, dtype=float), np.asarray(torque_nm, dtype=float)
    loaded = np.isfinite(speed) & np.isfinite(torque) & (np.abs(torque) >= STALL_TORQUE_NM) & (speed > 1.0)
    slow = loaded & (speed < STALL_SPEED_RPM)
    if engine and loaded.sum() >= 3 and slow.sum() > STALL_UNTRUSTED_SHARE * loaded.sum():
        out.append(
            UnitFinding(
                f"the turning engine delivers {STALL_TORQUE_NM:g} Nm or more below "
                f"{STALL_SPEED_RPM:g} rpm on {pct(int(slow.sum()), int(loaded.sum()))} of its loaded "
                f"steps (median {float(np.median(speed[slow])):.0f} rpm): is engine_speed_rpm in "
                f"rad/s?"
            )
        )
    return out


def untrusted(findings) -> bool:
    """True when a finding says the outputs should not be used."""
    return any(f.severity >= Severity.UNTRUSTED for f in findings)


def recorded_reject_counters(rejects, reasons, oil_c, base=None) -> dict:
    """The service's counters of the sensor's input checks from recorded steps (the whole-log path, the copy that
    ran the sensor half; the step path counts them as it goes): ``input_rejects`` (reason -> steps of this run, the
    reasons with any) and ``oil_frozen_at_c`` (the oil reading on the last step rejected as frozen, else None).
    ``rejects``: the sensor's cumulative counters after each step (steps x reasons), ``oil_c`` the steps' oil
    readings, ``base`` the counters the run started from (a restored state's; default zeros)."""
    r = np.asarray(rejects, dtype=float).reshape(-1, len(reasons))
    b = np.zeros(len(reasons)) if base is None else np.asarray(base, dtype=float).reshape(-1)[: len(reasons)]
    total = r[-1] - b if r.shape[0] else np.zeros(len(reasons))
    out: dict = {"input_rejects": {k: int(n) for k, n in zip(reasons, total) if n > 0}, "oil_frozen_at_c": None}
    if "oil_frozen" in reasons and r.shape[0]:
        j = list(reasons).index("oil_frozen")
        rose = np.flatnonzero(np.diff(np.concatenate([[b[j]], r[:, j]])) > 0)
        if rose.size:
            out["oil_frozen_at_c"] = float(np.asarray(oil_c, dtype=float)[rose[-1]])
    return out


def recorded_mode_counters(modes) -> dict:
    """The service's mode counters from the degraded modes of recorded steps (the whole-log path and the copy that
    ran the sensor half): ``mode_steps`` (steps per mode) and ``mode_now`` (the last step's, when there is one)."""
    finite = np.asarray(modes, dtype=float)
    finite = finite[np.isfinite(finite)].astype(int)
    values, counts = np.unique(finite, return_counts=True)
    out = {"mode_steps": dict(zip(values.tolist(), counts.tolist()))}
    if finite.size:
        out["mode_now"] = int(finite[-1])
    return out
