"""The gap diagnosis on SCADA records: where the onboard model of a gearbox description misses measured temperatures,
which catalog effect explains it, and how far it shrinks on held-out records (docs/real-data.md, "The gap on real
data"; the result is a gap-diagnosis/1 JSON as for run tables, docs/diagnosis.md).

The model is the onboard sensor replayed over each record (one output row per SCADA row): the sump channel from
the model alone (the oil not read), every other channel from the measured sump (the bearings' task). Each candidate
effect of :data:`EFFECTS` is fitted alone on the training records: one finite-difference replay gives its
sensitivity, one linear least-squares step its value (within the catalog's range), a replay at that value its
exact residual. The measurement effects need no replay: ``oil_sensor_offset`` on the sump channel,
``thermocouple_offset:<channel>`` on each other channel (a reading offset by a constant). An effect that moves no
estimate by IDENTIFIABLE_K is not a candidate (the gearbox has no such part, or these records cannot show it).

Score: the drop of the Bayesian information criterion with an effective sample size (residuals of 10-minute rows
are autocorrelated: n_eff = n (1 - rho) / (1 + rho), rho the lag-1 autocorrelation of the residual before the fit).
Verdict: ``none`` when the model is within NOISE_K RMS of the readings; else the best candidate whose score passes
SCORE_MIN and whose fit makes the held-out records no worse; else ``unexplained``, naming the regime that carries
the largest share of the gap. Never a claim that makes held-out data worse.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from firmware_model.effects import CATALOG
from firmware_model.errors import InputError
from tools.diagnosis.options import Options, n_eff_needed
from tools.scada.reader import ScadaRecord
from tools.scada.regimes import regimes, where
from tools.scada.runtable import oil_channel

#: the model effects tried (ids of the effect catalog the onboard model represents; the truck's retarder is not)
EFFECTS = (
    "gear_friction_scale",
    "planetary_loss_scale",
    "bearing_loss_scale",
    "churning_scale",
    "teeth_oil_h_scale",
    "planet_oil_h_scale",
    "housing_air_h_scale",
    "cooler_effectiveness_scale",
    "thermostat_offset",
)
#: the finite-difference step of each effect's sensitivity, in its parameter's unit (scales: relative)
STEP = {"thermostat_offset": 1.0}
DEFAULT_STEP = 0.1
#: an effect that moves no estimate by this much is not a candidate [K]
IDENTIFIABLE_K = 0.01
#: the model agrees "within the measurement noise" below this pooled RMS [K] (10-minute averages of PT100s)
NOISE_K = 0.5
#: the least score (BIC drop) of a claimed effect: "very strong" evidence on Kass and Raftery's scale
SCORE_MIN = 10.0
#: candidates refined and re-scored on the held-out records (the best by training score)
TESTED = 3
#: a claim may leave no channel's held-out RMS worse by more than this fraction and this many kelvin (the pooled
#: figure alone can hide one channel made much worse while another improves)
WORSE_REL = 0.05
WORSE_MIN_K = 0.05
#: a claim must shrink the pooled held-out RMS by at least this fraction: the per-channel guard lets a channel be
#: WORSE_REL worse as no change, so a smaller shrink is no change either
CLAIM_MIN_SHRINK = WORSE_REL
#: a fitted value within this fraction of its range from a bound sits at the bound (as calibrate's)
BOUND_FRACTION = 0.01
#: secant replays that refine a nonlinear effect's value
SECANT_STEPS = 3
#: the two oil modes' replays of an evaluation on two threads (the same results; False: one after the other)
PARALLEL_MODES = True
#: what a reading offset's verdict cannot tell (a reviewer: +2.01 K on R80721's bearing 1 is its training rows' mean
#: residual, "a sensor fault" by its name): a reading off by a constant and a model off by one on that part alike
OFFSET_CAVEAT = (
    "; a constant gap between this reading and its estimate: a thermocouple reading off by it, or the model off by "
    "as much on this part on every row, which these records do not tell apart (a second reading of the part, or "
    "the sensor checked against a reference, does)"
)
#: a reading offset's held-out residual is the one before it, shifted (no replay; False: replayed, the same figures
#: to rounding: benchmarks/bench_scada_speed.py's reference)
OFFSETS_WITHOUT_REPLAY = True


@dataclass
class Setup:
    """What the diagnosis replays: the configuration (its gearbox), the sump channel and the other channels."""

    config: object
    sump: str | None
    others: tuple[str, ...]
    #: the gearbox's parameters, read from its file once (each read parses and checks the TOML files: ~1.5 s, which
    #: made up half of a diagnosis of a turbine-year when every replay read them again)
    _params: object = field(default=None, repr=False, compare=False)

    @property
    def channels(self) -> tuple[str, ...]:
        return ((self.sump,) if self.sump else ()) + self.others

    @property
    def params(self):
        """The configuration's gearbox parameters (read once; replays read them, never change them)."""
        if self._params is None:
            self._params = self.config.load_params()
        return self._params


def setup_of(config, cmap) -> tuple[Setup, list[str]]:
    """The Setup of ``config``'s gearbox for the channels of column map ``cmap`` tied to parts the sensor publishes
    (the sump: the channel tied to ``oil``), and a note per channel left out (tied to a part it does not publish)."""
    from firmware_model.onboard.sensor import VirtualSensor

    published = set(VirtualSensor(config.load_params(), config=config).published)
    tied = {ch: node for ch, node in cmap.nodes.items() if node in published}
    sump = next((ch for ch, node in tied.items() if node == "oil"), None)
    notes = [f"{ch} is left out of the fit: {_why_left_out(n)}" for ch, n in cmap.nodes.items() if ch not in tied]
    return Setup(config, sump, tuple(ch for ch in tied if ch != sump)), notes


def _why_left_out(node: str) -> str:
    """Why a channel tied to ``node`` is not scored: a derived temperature (the forced oil system's inlet, which replay
    writes as a status column beside the published nodes) or a part the sensor does not publish."""
    from tools.scada.replay import DERIVED_COLUMNS

    if node in DERIVED_COLUMNS:
        column = DERIVED_COLUMNS[node]
        return f"{node!r} is a derived temperature, not a node of the model (replay writes it as {column})"
    return f"{node!r} is not a component the sensor publishes"


def thermostat_of(params) -> tuple[float, float] | None:
    """(opens, fully open) [degC] of the description's thermostatic cooler bypass, None without one."""
    keys = ("cooler.thermostat_open", "cooler.thermostat_full")
    return tuple(float(params.values[k]) for k in keys) if all(k in params.values for k in keys) else None


def estimates(setup: Setup, record: ScadaRecord, effects: dict, params=None) -> dict[str, np.ndarray]:
    """{channel: the model's estimate} over ``record`` with ``effects`` (the sump's from the model alone, the others
    from the measured sump); ``params``: the gearbox's parameters in place of the configuration's."""
    from tools.scada.replay import ESTIMATES_ONLY, after_long_gaps, replay_record

    model_effects = {k: v for k, v in effects.items() if k in EFFECTS}
    params = setup.params if params is None else params
    modes = (("model",) if setup.sump else ()) + (("measured",) if setup.others else ())

    def replay(mode: str):
        return replay_record(record, setup.config, {**ESTIMATES_ONLY, "oil_mode": mode}, model_effects, params).table

    if len(modes) == 2 and PARALLEL_MODES:
        # the two replays are independent and the kernel releases the GIL: side by side on two threads
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(2, thread_name_prefix="gvs-diagnose") as pool:
            tables = dict(zip(modes, pool.map(replay, modes)))
    else:
        tables = {mode: replay(mode) for mode in modes}
    out = {}
    if setup.sump:
        # the modelled sump's rows just after a day's gap rest on an assumed standstill: no evidence, neither fitted
        # nor scored
        est = np.asarray(tables["model"][f"est_{setup.sump}"], dtype=float) + effects.get("oil_sensor_offset", 0.0)
        out[setup.sump] = np.where(after_long_gaps(record), np.nan, est)
    for ch in setup.others:
        out[ch] = tables["measured"][f"est_{ch}"] + effects.get(f"thermocouple_offset:{ch}", 0.0)
    return out


def record_residuals(
    setup: Setup, records: Sequence[ScadaRecord], effects: dict, params=None
) -> list[dict[str, np.ndarray]]:
    """Per record, {channel: measured - model} (NaN where either is missing); ``params`` as :func:`estimates`."""
    est = [estimates(setup, r, effects, params) for r in records]
    return [{ch: r.values[ch] - e[ch] for ch in setup.channels} for r, e in zip(records, est)]


def join_records(per_record: Sequence[dict], channels: Sequence[str]) -> dict[str, np.ndarray]:
    """The records' residuals joined per channel."""
    return {ch: np.concatenate([r[ch] for r in per_record]) for ch in channels}


def _residuals(setup: Setup, records: Sequence[ScadaRecord], effects: dict) -> dict[str, np.ndarray]:
    """{channel: measured - model} over ``records`` joined (NaN where either is missing)."""
    return join_records(record_residuals(setup, records, effects), setup.channels)


def neutral_residuals(
    setup: Setup, records: Sequence[ScadaRecord], role: str, params=None, require: bool = True
) -> tuple[list[ScadaRecord], dict[str, np.ndarray], list[str]]:
    """(the records screened, their residuals at the neutral effects joined, a note per channel left out): a record
    whose units look wrong is refused (tools.scada.replay.screen_untrusted: what makes replay exit 3 would be fitted
    as a gearbox effect), a measured channel alone far off its estimate left out of its record; with ``require``,
    records without a reading beside an estimate are refused. ``params``: the gearbox's in place of the setup's."""
    from tools.scada.replay import screen_untrusted

    params = setup.params if params is None else params
    per = record_residuals(setup, records, {}, params)
    records, per, notes = screen_untrusted(records, per, params, role, setup.sump)
    out = join_records(per, setup.channels)
    if require:
        require_readings(out, role)
    return records, out, notes


def require_readings(res: dict[str, np.ndarray], which: str) -> None:
    """An InputError when ``res`` (measured - model per channel) holds no row with both a reading and an estimate."""
    if not any(np.isfinite(r).any() for r in res.values()):
        raise InputError(
            f"the {which} records hold no reading of {', '.join(res) or 'any measured channel'} beside an estimate: "
            "nothing to compare the model with"
        )


def _pooled(res: dict[str, np.ndarray]) -> np.ndarray:
    v = np.concatenate(list(res.values()))
    return v[np.isfinite(v)]


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x))) if x.size else float("nan")


def effective_n(res: dict[str, np.ndarray]) -> float:
    """The effective sample size of autocorrelated residuals: sum over channels of n (1 - rho) / (1 + rho)."""
    total = 0.0
    for r in res.values():
        r = r[np.isfinite(r)]
        if r.size < 3:
            continue
        d = r - r.mean()
        rho = float(np.clip(np.sum(d[1:] * d[:-1]) / max(np.sum(d * d), 1e-300), 0.0, 0.999))
        total += r.size * (1.0 - rho) / (1.0 + rho)
    return max(total, 1.0)


def _score(sse0: float, sse1: float, n: int, n_eff: float) -> float:
    """BIC drop of one fitted parameter with ``n_eff`` effective samples (positive: the effect is supported)."""
    if sse1 <= 0.0 or sse0 <= 0.0:
        return float("inf") if sse1 <= 0.0 < sse0 else 0.0
    return float(n_eff * np.log(sse0 / sse1) - np.log(n_eff))


def _fit_value(effect: str, r0: dict, jac: dict) -> float:
    """The linear least-squares value of one effect: residual r0 - J (theta - neutral), within its range."""
    e = CATALOG[effect]
    num = den = 0.0
    for ch, j in jac.items():
        ok = np.isfinite(r0[ch]) & np.isfinite(j)
        num += float(np.sum(j[ok] * r0[ch][ok]))
        den += float(np.sum(j[ok] * j[ok]))
    theta = e.neutral + (num / den if den > 0 else 0.0)
    return float(np.clip(theta, e.low, e.high))


def _measurement_candidates(setup: Setup, r0: dict) -> dict:
    """{effect id: value} of the reading offsets: each channel's mean residual, within the catalog's range."""
    out = {}
    for ch in setup.channels:
        eid = "oil_sensor_offset" if ch == setup.sump else f"thermocouple_offset:{ch}"
        r = r0[ch][np.isfinite(r0[ch])]
        if r.size:
            e = CATALOG[eid]
            out[eid] = float(np.clip(r.mean(), e.low, e.high))
    return out


def _sse(res: dict) -> float:
    p = _pooled(res)
    return float(p @ p)


def _channel_stats(train: dict, test: dict) -> dict:
    out = {}
    for ch in train:
        a, b = train[ch][np.isfinite(train[ch])], test[ch][np.isfinite(test[ch])]
        out[ch] = {
            "train_rms_c": _rms(a),
            "train_max_c": float(np.max(np.abs(a))) if a.size else float("nan"),
            "test_rms_c": _rms(b),
            "test_max_c": float(np.max(np.abs(b))) if b.size else float("nan"),
        }
    return out


def _model_candidates(setup: Setup, train: Sequence[ScadaRecord], r0: dict) -> list[dict]:
    """Every identifiable model effect fitted alone on ``train``: value, training residual after, sensitivity."""
    out = []
    for eid in EFFECTS:
        e = CATALOG[eid]
        step = STEP.get(eid, DEFAULT_STEP)
        step = step if e.neutral + step <= e.high else -step
        r_step = _residuals(setup, train, {eid: e.neutral + step})
        jac = {ch: (r0[ch] - r_step[ch]) / step for ch in r0}  # d(model)/d(theta)
        move = max(float(np.nanmax(np.abs(j * step))) if np.isfinite(j).any() else 0.0 for j in jac.values())
        if move < IDENTIFIABLE_K:
            continue
        theta = _fit_value(eid, r0, jac)
        after = _residuals(setup, train, {eid: theta})
        out.append({"effect": eid, "value": theta, "after": after, "jac": _pooled_jac(jac), "r0": r0})
    return out


def _refine(setup: Setup, train: Sequence[ScadaRecord], c: dict) -> None:
    """Secant steps from the linear value while the effect is nonlinear (the slope between the neutral value and
    the last one replaces the first sensitivity), at most SECANT_STEPS replays; keeps the best residual."""
    e = CATALOG[c["effect"]]
    r0 = c.pop("r0")
    for _ in range(SECANT_STEPS):
        d = c["value"] - e.neutral
        if d == 0.0:
            return
        slope = {ch: (r0[ch] - c["after"][ch]) / d for ch in r0}
        theta = _fit_value(c["effect"], r0, slope)
        if abs(theta - c["value"]) < 0.002 * (e.high - e.low):
            return
        after = _residuals(setup, train, {c["effect"]: theta})
        if _sse(after) >= _sse(c["after"]):
            return
        c["value"], c["after"] = theta, after


def worse_channels(before: dict[str, np.ndarray], after: dict[str, np.ndarray]) -> list[str]:
    """The channels whose held-out RMS ``after`` ({channel: residual}) is worse than ``before`` by more than
    WORSE_REL and WORSE_MIN_K, or that had an estimate before and have none after."""
    out = []
    for ch, r in after.items():
        b = _rms(before[ch][np.isfinite(before[ch])])
        a = _rms(r[np.isfinite(r)])
        lost = np.isfinite(b) and not np.isfinite(a)
        if lost or (np.isfinite(a) and np.isfinite(b) and a > b * (1.0 + WORSE_REL) and a - b > WORSE_MIN_K):
            out.append(ch)
    return out


def _pooled_jac(jac: dict) -> np.ndarray:
    v = np.concatenate(list(jac.values()))
    return np.where(np.isfinite(v), v, 0.0)


#: a channel whose held-out gap (the 90th percentile of |measured - model| at the neutral effects: the RMS is led
#: by the hours after a long data gap, 44 K off in a reviewer's training files) is this many times the training
#: records' and at least CHANGED_MIN_K more is said: something changed between the two (a cooler fouling from a date
#: in the held-out files turned a verdict of a reading offset into bearing losses, unsaid: a review)
CHANGED_FACTOR, CHANGED_MIN_K = 2.0, 1.0


def changed_channels(train: dict, test: dict) -> list[str]:
    """A warning per channel whose held-out gap (``test``: channel -> residual) is far larger than its training gap
    (``train``), by the 90th percentile of |residual| (CHANGED_FACTOR, CHANGED_MIN_K)."""
    out = []
    for ch in train:
        a, b = (np.abs(r[np.isfinite(r)]) for r in (train[ch], test.get(ch, np.zeros(0))))
        if a.size < 2 or b.size < 2:
            continue
        pa, pb = float(np.percentile(a, 90)), float(np.percentile(b, 90))
        if pb >= CHANGED_FACTOR * pa and pb - pa >= CHANGED_MIN_K:
            out.append(
                f"{ch}'s gap on the held-out records (90 % of its rows within {pb:.2f} K, RMS {_rms(b):.2f} K) is "
                f"{pb / pa:.1f} x the training records' ({pa:.2f} K, RMS {_rms(a):.2f} K): the gearbox, its sensors "
                "or its surroundings changed between them, or the held-out records hold conditions the training ones "
                "do not; the verdict explains the training records' gap, not that change (diagnose the later records "
                "with part of them as training)"
            )
    return out


def diagnose_records(
    setup: Setup,
    train: Sequence[ScadaRecord],
    test: Sequence[ScadaRecord],
    thermostat_c: tuple[float, float] | None = None,
) -> dict:
    """The gap-diagnosis/1 result of ``setup``'s model on the SCADA records (``train`` fits, ``test`` scores)."""
    t0 = time.perf_counter()
    train, r0, notes = neutral_residuals(setup, train, "training")
    test, t_before, test_notes = neutral_residuals(setup, test, "test")
    notes += test_notes
    sse0, n = _sse(r0), int(_pooled(r0).size)
    n_eff = effective_n(r0)
    masks = [regimes(r, thermostat_c, setup.sump or oil_channel(r)) for r in train]
    joined = {k: np.concatenate([m[k] for m in masks]) for k in masks[0]} if masks else {}
    # within the noise there is nothing to explain: no candidate is fitted
    gap = _rms(_pooled(r0)) >= NOISE_K
    cands = _model_candidates(setup, train, r0) if gap else []
    for eid, value in (_measurement_candidates(setup, r0) if gap else {}).items():
        cands.append({"effect": eid, "value": value, "after": _residuals_offset(r0, eid, value, setup), "jac": None})
    cands.sort(key=lambda c: _sse(c["after"]))
    for c in cands[:TESTED]:  # the best by the linear step: their value refined where the effect is nonlinear
        if "r0" in c:
            _refine(setup, train, c)
    for c in cands:
        c.pop("r0", None)
        c["score"] = _score(sse0, _sse(c["after"]), n, n_eff)
    cands.sort(key=lambda c: -c["score"])
    out_cands, test_after = [], {}
    for i, c in enumerate(cands):
        eid = c["effect"]
        entry = {
            "effect": eid,
            "parameters": {CATALOG[eid].param: c["value"]},
            "at_bound": at_bound(eid, c["value"]),
            "train_rms_before_c": _rms(_pooled(r0)),
            "train_rms_after_c": _rms(_pooled(c["after"])),
            "score": c["score"],
            "confusable_with": _confusable(c, cands),
        }
        if i < TESTED:
            # a reading offset moves no estimate: the held-out residual before it, shifted (no replay)
            after = (
                _residuals(setup, test, {eid: c["value"]})
                if c["jac"] is not None or not OFFSETS_WITHOUT_REPLAY
                else _residuals_offset(t_before, eid, c["value"], setup)
            )
            entry["test_rms_before_c"] = _rms(_pooled(t_before))
            entry["test_rms_after_c"] = _rms(_pooled(after))
            entry["worse_channels"] = worse_channels(t_before, after)
            test_after[eid] = after
        out_cands.append(entry)
    verdict = _verdict(r0, t_before, out_cands, where(r0, joined))
    # as for run tables: the effective samples of the training residual after the best fit (before it, a large
    # smooth gap would count as few samples however well an effect explains it)
    n_eff_fit = effective_n(cands[0]["after"]) if cands else n_eff
    if verdict["effect"] != "none" and n_eff_fit < n_eff_needed(Options()):
        verdict = _thin_verdict(verdict, out_cands, n, n_eff_fit)
    channels = _channel_stats(r0, t_before)
    notes += changed_channels(r0, t_before)
    # the verdict's held-out residual per channel (as for run tables: channels.*.test_rms_after_c); none and
    # unexplained leave the model as it is
    for ch, r in test_after.get(verdict["effect"], t_before).items():
        channels[ch]["test_rms_after_c"] = _rms(r[np.isfinite(r)])
    return {
        "schema": "gap-diagnosis/1",
        "train": [str(f) for r in train for f in r.files],
        "test": [str(f) for r in test for f in r.files],
        "units": {"train": [r.unit for r in train], "test": [r.unit for r in test]},
        "channels": channels,
        "where": where(r0, joined)[:12],
        "candidates": out_cands,
        "verdict": verdict,
        "model": {"kind": "onboard", "rows_train": n, "effective_samples": n_eff},
        "timing": {"total_s": time.perf_counter() - t0},
    } | ({"warnings": notes} if notes else {})


def _thin_verdict(verdict: dict, cands: list[dict], n: int, n_eff: float) -> dict:
    """Too few effective samples to decide (as for run tables, tools.diagnosis.decide): no effect claimed and no
    regime named as where the gap lies; the best candidate and what it would do held out, as no claim."""
    needed = n_eff_needed(Options())
    best = next((c for c in cands if "test_rms_after_c" in c), None)
    cut = (
        f"; the best candidate {best['effect']} ({_fmt_params(best['parameters'])}) would "
        f"{'cut' if best['test_rms_after_c'] < best['test_rms_before_c'] else 'not cut'} the held-out RMS "
        f"{best['test_rms_before_c']:.2f} -> {best['test_rms_after_c']:.2f} K, but that is no claim"
        if best
        else ""
    )
    return {
        "test_rms_before_c": verdict["test_rms_before_c"],
        "effect": "unexplained",
        "test_rms_after_c": verdict["test_rms_before_c"],
        "shrink": 0.0,
        "evidence": "thin",
        "reason": f"thin evidence, too little to decide: the training residual after the best fit holds n_eff = "
        f"{n_eff:.0f} effective "
        f"samples of {n} readings and the decision needs at least {needed}{cut}; add more training files, or "
        "longer ones, and diagnose again",
    }


def at_bound(effect: str, value: float) -> bool:
    """Whether ``value`` of ``effect`` sits at a bound of the catalog's plausible range (within BOUND_FRACTION)."""
    e = CATALOG[effect]
    margin = BOUND_FRACTION * (e.high - e.low)
    return bool(value <= e.low + margin or value >= e.high - margin)


def _residuals_offset(r0: dict, eid: str, value: float, setup: Setup) -> dict:
    ch = setup.sump if eid == "oil_sensor_offset" else eid.split(":", 1)[1]
    return {k: (v - value if k == ch else v) for k, v in r0.items()}


def _confusable(c: dict, cands: list) -> list[str]:
    """The other model effects whose sensitivity is nearly parallel to this one's (|correlation| > 0.9)."""
    if c["jac"] is None:
        return []
    out = []
    for o in cands:
        if o is c or o["jac"] is None:
            continue
        a, b = c["jac"], o["jac"]
        den = float(np.linalg.norm(a) * np.linalg.norm(b))
        if den > 0 and abs(float(a @ b)) / den > 0.9:
            out.append(o["effect"])
    return out


def _verdict(r0: dict, t_before: dict, cands: list[dict], where_rows: list[dict]) -> dict:
    before = _rms(_pooled(t_before))
    base = {"test_rms_before_c": before}
    if _rms(_pooled(r0)) < NOISE_K:
        return {
            **base,
            "effect": "none",
            "test_rms_after_c": before,
            "shrink": 0.0,
            "reason": f"the model is within {NOISE_K} K RMS of the readings",
        }
    bound, worse, weak = None, None, None
    for c in cands:
        if "test_rms_after_c" not in c or c["score"] < SCORE_MIN or c["test_rms_after_c"] > before:
            continue
        if c.get("worse_channels"):  # better pooled, but a channel worse held out: no claim
            worse = worse or c
            continue
        # the best that holds sits at a bound of its range with a gap left (above the noise): the data want more
        # of it than the range allows, a model form rather than this effect (as the run tables' verdict); the
        # weaker candidates below it are no claim either
        if c["at_bound"] and c["train_rms_after_c"] >= NOISE_K:
            bound = c
            break
        if not before > 0 or c["test_rms_after_c"] > before * (1.0 - CLAIM_MIN_SHRINK):  # too little: the next
            weak = weak or c
            continue
        return {
            **base,
            "effect": c["effect"],
            "parameters": c["parameters"],
            "test_rms_after_c": c["test_rms_after_c"],
            "shrink": 1.0 - c["test_rms_after_c"] / before if before > 0 else 0.0,
            "reason": f"score {c['score']:.0f} (BIC drop) on the training records, and the held-out RMS falls"
            + (OFFSET_CAVEAT if c["effect"].startswith(("thermocouple_offset", "oil_sensor_offset")) else ""),
        }
    top = where_rows[0] if where_rows else None
    at = f"; the largest share of the gap: {top['channel']} in '{top['regime']}'" if top else ""
    at += f"; {_at_bound_text(bound)}" if bound else ""
    if weak:
        shrink = 1.0 - weak["test_rms_after_c"] / before if before > 0 else 0.0
        at += (
            f"; the best that holds, {weak['effect']} ({_fmt_params(weak['parameters'])}), shrinks the held-out RMS "
            f"by {100 * shrink:.1f} % only ({before:.2f} -> {weak['test_rms_after_c']:.2f} K; a claim needs "
            f"{100 * CLAIM_MIN_SHRINK:g} %)"
        )
    if worse:
        at += (
            f"; {worse['effect']} ({_fmt_params(worse['parameters'])}) lowers the pooled held-out RMS but makes "
            f"{', '.join(worse['worse_channels'])} worse"
        )
    return {
        **base,
        "effect": "unexplained",
        "test_rms_after_c": before,
        "shrink": 0.0,
        "reason": f"no candidate both scores {SCORE_MIN:.0f} on the training records within its range and holds "
        f"on the held-out ones{at}",
    }


def _fmt_params(params: dict) -> str:
    return ", ".join(f"{k} = {v:g}" for k, v in params.items())


def _at_bound_text(c: dict) -> str:
    """Why candidate ``c`` (it holds on the held-out records) is not the verdict: it sits at a bound."""
    return (
        f"the best candidate that holds on the held-out records, {c['effect']} (score {c['score']:.0f}, held-out "
        f"RMS {c['test_rms_after_c']:.2f} K), sits at the bound of its range ({_fmt_params(c['parameters'])}) with "
        "a gap left"
    )
