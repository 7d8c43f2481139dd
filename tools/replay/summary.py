"""What `gearbox-vsensor replay` prints after a replay, the same for a run table and a CAN log: the component
closest to its own warning limit (limits differ by component), the warnings raised and for how long, the degraded
share, and the rejected inputs in words (a table without the auxiliary columns is not an error: defaults are used)."""

from __future__ import annotations

import numpy as np

from firmware_model.components import LEVEL_CRITICAL, LEVEL_NA, LEVEL_WARNING, STEP_S
from firmware_model.service.plausibility import is_held
from tools.published import description, ids, label_of

#: the auxiliary input columns (their absence means defaults, docs/sensor.md "Bad input")
AUX_COLUMNS = ("ambient_temp_c", "coolant_temp_c", "vehicle_speed_kmh", "retarder_torque_nm")
#: the J1939 message of each auxiliary input (a log replay's decoder counts its arrivals)
AUX_MESSAGES = {
    "ambient_temp_c": "AMB",
    "coolant_temp_c": "ET1",
    "vehicle_speed_kmh": "CCVS1",
    "retarder_torque_nm": "ERC1",
}
#: reject counters in words
REJECT_WORDS = {
    "drive_frozen": (
        "speed and torque bit-identical for over 120 s while turning (flagged, still used: a synthetic "
        "cycle without --noise or a test bench holds them so; from a vehicle's or a machine's own sensors it is a "
        "frozen signal)"
    ),
    "oil_frozen": (
        "oil reading frozen while the model's sump moved (modelled instead; a rig or plant run that holds "
        "the sump at one temperature reads so too)"
    ),
    "oil_implausible": "oil reading out of range or jumping (modelled instead)",
    "oil_missing": "oil reading missing (modelled instead)",
    "speed_clamped": "engine speed outside the engine's range (clamped)",
    "torque_clamped": "engine torque outside the engine's range (clamped)",
    "gear_unknown": "gear not an integer in -2..14 or no gear of the gearbox (last good gear held)",
    "time_jump": "forward time jumps (state propagated over the gap)",
    "time_backward": "frames whose time went back (step skipped)",
}
#: the same of a fixed-ratio drive (a turbine's rotor, a motor's input shaft: the table's input_speed_rpm and
#: input_torque_nm, clamped to the description's drive ranges), which has no engine
DRIVE_REJECT_WORDS = {
    "speed_clamped": "input speed outside the drive's range (clamped)",
    "torque_clamped": "input torque outside the drive's range (clamped)",
}


def _row_durations_s(time_s) -> np.ndarray:
    """How long each output row stands [s]: until the next row (a table's rows may lie seconds apart, not one
    STEP_S), the last row as long as the median spacing (STEP_S for a single row); time going back counts 0."""
    t = np.asarray(time_s, dtype=float)
    if t.size < 2:
        return np.full(t.size, STEP_S)
    d = np.maximum(np.diff(t), 0.0)
    return np.append(d, float(np.median(d)))


def _minutes(seconds: float) -> str:
    return f"{seconds / 60.0:.1f} min"


def _closest_line(out, limits, published: tuple, desc) -> str:
    margins = {
        c: float(np.nanmin(limits.of(c)[0] - np.asarray(out[f"T_{c}_c"], dtype=float)))
        for c in published
        if out.has(f"T_{c}_c") and np.any(np.isfinite(out[f"T_{c}_c"]))
    }
    if not margins:
        return "closest to its limit: no temperature estimated"
    c = min(margins, key=margins.get)
    T = np.asarray(out[f"T_{c}_c"], dtype=float)
    k = int(np.nanargmax(T))
    t_min = (out["time_s"][k] - out["time_s"][0]) / 60.0
    m = margins[c]
    rel = f"{m:.1f} K below" if m > 0 else f"{-m:.1f} K over"
    return (
        f"closest to its limit: {label_of(c, desc)}, peak {T[k]:.1f} degC at {t_min:.1f} min, {rel} its warning "
        f"limit {limits.of(c)[0]:.0f} degC"
    )


def _warning_line(out, published: tuple) -> str:
    parts = []
    dur_s = _row_durations_s(out["time_s"]) if out.n else np.zeros(0)
    for c in published:
        if not out.has(f"W_{c}"):
            continue
        w = np.asarray(out[f"W_{c}"])
        n_warn, n_crit = float(np.sum(dur_s[w == LEVEL_WARNING])), float(np.sum(dur_s[w == LEVEL_CRITICAL]))
        if np.any(w == LEVEL_WARNING) or np.any(w == LEVEL_CRITICAL):
            first = int(np.argmax(np.isin(w, (LEVEL_WARNING, LEVEL_CRITICAL))))
            t0 = (out["time_s"][first] - out["time_s"][0]) / 60.0
            crit = f", critical for {_minutes(n_crit)}" if n_crit else ""
            parts.append(f"{c} in warning for {_minutes(n_warn)} in all{crit} (first at {t0:.1f} min)")
    line = "warnings: " + ("; ".join(parts) if parts else "none")
    na = _not_available_share(out, dur_s, published)
    if na > 0.0:
        # "none" alone would read as an all-clear where the sensor could not judge (a log without torque has level
        # n/a on 99 % of the cells)
        share = f"{100.0 * na:.1f} %" if na >= 0.001 else "under 0.1 %"
        line += (
            f" (warning levels not available, level {LEVEL_NA}, on {share} of the component-time: "
            f"no warning could be raised there; see degraded)"
        )
    return line


def _not_available_share(out, dur_s, published: tuple) -> float:
    """The share of component-time (the published components' rows weighted by how long each stands) at level
    n/a."""
    cols = [np.asarray(out[f"W_{c}"]) for c in published if out.has(f"W_{c}")]
    total = float(np.sum(dur_s)) * len(cols)
    if not cols or not total > 0.0:
        return 0.0
    return sum(float(np.sum(dur_s[w == LEVEL_NA])) for w in cols) / total


def _arrivals(out) -> dict:
    """The decoder's frames per input message of a log replay (its meta counters); empty for a run table."""
    counters = (getattr(out, "meta", None) or {}).get("counters", {})
    return counters.get("decoder", {}).get("arrivals", {}) if isinstance(counters, dict) else {}


def _unused_inputs(desc) -> tuple:
    """The auxiliary inputs the gearbox's drive has not (firmware_model.onboard.reduce.aux_inputs_expected: a
    fixed-ratio drive's vehicle speed and retarder, its coolant without a coolant boundary or liquid cooler), which
    the sensor does not count missing, so that their absence is no line of the summary either."""
    from firmware_model.onboard.reduce import aux_inputs_expected

    if desc is None:
        return ()
    return tuple(c for c, has in zip(AUX_COLUMNS, aux_inputs_expected(desc)) if not has)


def _usable_erc1(out, erc1: int) -> int:
    """The ERC1 frames from the retarder's address whose percent torque (SPN 520) was usable: those that arrived,
    less the short ones and those whose value the decoder rejected (not available, error, out of range)."""
    counters = (getattr(out, "meta", None) or {}).get("counters", {})
    decoder = counters.get("decoder", {}) if isinstance(counters, dict) else {}
    rejected = sum((decoder.get("signal_rejected", {}).get("retarder_torque_pct") or {}).values())
    return erc1 - rejected - int(decoder.get("short_frames", {}).get("ERC1", 0))


def _reject_line(out, unused: tuple = ()) -> str:
    n = out.n
    counts = {
        k[len("rejects_") :]: int(out[k][-1]) for k in out.columns if k.startswith("rejects_") and n and out[k][-1] > 0
    }
    words = []
    aux = counts.pop("aux_missing", 0)
    if aux:
        given = [c for c in AUX_COLUMNS if out.has(c) and np.any(np.isfinite(out[c]))]
        absent = [c for c in AUX_COLUMNS if c not in given and c not in unused]  # the counter counts no unused one
        erc1 = _arrivals(out).get("ERC1", 0)
        # no torque in Nm although ERC1 carried a usable percent: only then was the reference missing (docs/can.md:
        # Nm = percent / 100 x RC's, else the configured one); frames without one are "sent but never usable"
        unreferenced = "retarder_torque_nm" in absent and _usable_erc1(out, erc1) > 0
        if unreferenced:
            absent.remove("retarder_torque_nm")
            words.append(
                f"{erc1} retarder frames (ERC1) arrived, but without a retarder reference torque (no RC, SPN 556 "
                f"by TP.BAM, from the retarder's source address, no [can] retarder_reference_torque_nm) their "
                f"percent torque "
                f"is no torque: the retarder's heat is left out"
            )
        arrivals = _arrivals(out)
        rejected = [c for c in absent if arrivals.get(AUX_MESSAGES[c], 0) > 0]  # sent, but no value was usable
        absent = [c for c in absent if c not in rejected]
        if rejected:
            sent = ", ".join(f"{c} ({arrivals[AUX_MESSAGES[c]]} {AUX_MESSAGES[c]} frames)" for c in rejected)
            words.append(
                f"auxiliary inputs sent but never usable: {sent}, none with a usable value (short frames, "
                f"not available or out of range: the decoder's counters): defaults used"
            )
        if absent:
            words.append(f"auxiliary inputs not given ({', '.join(absent)}): defaults used, as documented")
        elif not unreferenced and not rejected:
            words.append(f"auxiliary inputs missing or out of range on {aux} steps: defaults used")
    meta = getattr(out, "meta", None) or {}
    held = is_held(meta)
    said = {**REJECT_WORDS, **(DRIVE_REJECT_WORDS if meta.get("engine_drive") is False else {})}
    for k, v in counts.items():
        # a held table's rows stand for many 0.1 s steps, which its counters count: said as time, not as steps
        amount = f"{v * STEP_S:g} s" if held else f"{v} steps"
        words.append(f"{said.get(k, k.replace('_', ' '))}: {amount}")
    return "rejected or repaired inputs: " + ("; ".join(words) if words else "none")


def summary_lines(out, limits=None, oil_model: bool = False, gearbox=None) -> list[str]:
    """The lines printed after a replay of ``out`` (the sensor output run table); ``oil_model``: the oil modelled by
    request (--oil-mode model), which is not degraded; ``gearbox``: the sensor, its parameter set or description
    (the published components and their words; None: the default gearbox); ``limits``: None for the sensor's that
    ran (the table's meta), else the gearbox's own (tools.published.limits), never the GRS905's for another one."""
    from firmware_model.components import MODE_NORMAL, MODE_OIL_MODEL
    from tools.published import limits as gearbox_limits

    limits = limits or (getattr(out, "meta", None) or {}).get("limits") or gearbox_limits(gearbox)
    line = "degraded: 0.0 % of steps"
    if out.n and out.has("degraded_mode"):
        mode = np.asarray(out["degraded_mode"])
        normal = (mode == MODE_NORMAL) | ((mode == MODE_OIL_MODEL) if oil_model else False)
        line = f"degraded: {100 * float(np.mean(~normal)):.1f} % of steps"
        if oil_model:
            line += f" (the oil modelled by request on {100 * float(np.mean(mode == MODE_OIL_MODEL)):.1f} %)"
    pub, desc = ids(gearbox), description(gearbox)
    return [
        _closest_line(out, limits, pub, desc),
        _warning_line(out, pub),
        line,
        _reject_line(out, _unused_inputs(desc)),
    ]
