"""Calibration of a gearbox description's assumed values to SCADA records (`calibrate --columns`; docs/real-data.md,
"Calibrating on real data"), with the linear NBM fitted on the same training records beside it.

The model is the onboard sensor replayed over each record (tools.scada.diagnose.estimates: the sump channel from
the model alone, every other channel from the measured sump), with trial values of parameter keys that declare
plausible bounds (lo, hi) in the description. As for run tables (tools.diagnosis.calibrate):

1. identifiability: each key stepped by SENS_STEP of its range; its signature per channel is the RMS change scaled
   to half the range; a key below IDENT_MIN_C on every channel, or whose sensitivity is nearly parallel to a
   stronger key's (|cos| >= COLLINEAR_COS), is not fitted;
2. fit: bounded Gauss-Newton least squares (tools/scada/gauss_newton.py: the identifiability's sensitivities, then
   two confirmed steps) of measured - model over every training row and channel, the keys scaled to their bounds;
3. one standard deviation from the Jacobian, inflated by N / N_eff (autocorrelated 10-minute residuals);
4. held-out: the test records with the file's and with the fitted values, per channel; and the NBM's (both tasks:
   the bearings from the measured sump, the sump without it), fitted on the same training records, with and without
   the calibrated sensor's estimate among its features (the physics-informed NBM, tools/scada/hybrid.py).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from firmware_model.errors import InputError
from tools.diagnosis.calibrate import COLLINEAR_COS, IDENT_MIN_C, SENS_STEP, Calibration, Identifiability
from tools.scada import gauss_newton
from tools.scada.diagnose import Setup, effective_n, estimates, neutral_residuals
from tools.scada.reader import ScadaRecord


def _residual(setup: Setup, records: Sequence[ScadaRecord], params) -> dict[str, np.ndarray]:
    est = [estimates(setup, r, {}, params) for r in records]
    return {ch: np.concatenate([r.values[ch] - e[ch] for r, e in zip(records, est)]) for ch in setup.channels}


def _vector(res: dict) -> np.ndarray:
    v = np.concatenate(list(res.values()))
    return np.where(np.isfinite(v), v, 0.0)


def _rms(res: dict) -> float:
    v = np.concatenate(list(res.values()))
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v * v))) if v.size else float("nan")


def _ch_rms(r: np.ndarray) -> float:
    r = r[np.isfinite(r)]
    return float(np.sqrt(np.mean(r * r))) if r.size else float("nan")


def identifiability(setup, train, params, keys, r0) -> tuple[list[Identifiability], dict]:
    """Each key's signature per channel and whether it can be fitted; the sensitivity columns (d residual / d u, u
    the key scaled to its bounds) of every key."""
    cols, out = {}, []
    for k in keys:
        lo, hi = params.bounds[k]
        v0 = params.values[k]
        step = SENS_STEP * (hi - lo) * (1.0 if v0 + SENS_STEP * (hi - lo) <= hi else -1.0)
        r1 = _residual(setup, train, params.with_overrides({k: v0 + step}))
        sig = {ch: 0.5 * _ch_rms(r1[ch] - r0[ch]) / SENS_STEP for ch in r0}
        cols[k] = (_vector(r1) - _vector(r0)) / (step / (hi - lo))
        ok = max(sig.values()) >= IDENT_MIN_C
        why = "" if ok else f"moves no channel by {IDENT_MIN_C} K over half its range"
        out.append(Identifiability(k, sig, ok, why))
    strength = {x.key: max(x.signature_c.values()) for x in out}
    for x in sorted(out, key=lambda x: -strength[x.key]):
        if not x.identifiable:
            continue
        for y in out:
            if y is x or not y.identifiable or strength[y.key] < strength[x.key]:
                continue
            a, b = cols[x.key], cols[y.key]
            cos = abs(float(a @ b)) / max(float(np.linalg.norm(a) * np.linalg.norm(b)), 1e-300)
            if cos > x.max_cos:
                x.max_cos, x.with_key = cos, y.key
            if cos >= COLLINEAR_COS:
                x.identifiable, x.reason = False, f"cannot be separated from {y.key} (|cos| {cos:.3f})"
                break
    return out, cols


def calibrate_records(
    setup: Setup, train: Sequence[ScadaRecord], test: Sequence[ScadaRecord], keys: Sequence[str] | None
) -> Calibration:
    """Fit ``keys`` (None: every key with bounds the records identify) of the setup's gearbox on ``train``; the
    held-out RMS on ``test`` before and after."""
    from firmware_model.parameters import with_fit_bounds

    params = setup.config.load_params()
    keys = sorted(params.bounds) if keys is None else list(keys)
    params = with_fit_bounds(params, keys)  # the thermostat's open below its full, whatever the trial
    train, r0, notes = neutral_residuals(setup, train, "training", params)
    test, t0, test_notes = neutral_residuals(setup, test, "test", params, require=False)  # (readings: the command's)
    notes += test_notes
    ident, cols = identifiability(setup, train, params, keys, r0)
    fit_keys = [x.key for x in ident if x.identifiable]
    if not keys:
        raise InputError(f"{params.origin} declares no parameter with plausible bounds (lo, hi): nothing to calibrate")
    if not fit_keys:
        raise InputError(
            "none of the parameters can be identified from these records: "
            + "; ".join(f"{x.key} {x.reason}" for x in ident)
        )
    lo = np.array([params.bounds[k][0] for k in fit_keys])
    span = np.array([params.bounds[k][1] for k in fit_keys]) - lo

    def over(u: np.ndarray):
        return params.with_overrides({k: float(lo[i] + span[i] * u[i]) for i, k in enumerate(fit_keys)})

    u0 = np.array([(params.values[k] - lo[i]) / span[i] for i, k in enumerate(fit_keys)])
    sol = gauss_newton.fit(
        lambda u: _vector(_residual(setup, train, over(u))),
        u0,
        np.zeros(len(fit_keys)),
        np.ones(len(fit_keys)),
        np.full(len(fit_keys), SENS_STEP),
        r0=_vector(r0),
        jac=np.stack([cols[k] for k in fit_keys], axis=1),
    )
    u = sol["x"]
    fitted = {k: float(lo[i] + span[i] * u[i]) for i, k in enumerate(fit_keys)}
    # the residual at the fit per channel (the vector's NaN rows were zeros: NaN again)
    edges = np.cumsum([0] + [v.size for v in r0.values()])
    r1 = {ch: np.where(np.isfinite(v), sol["r"][a:b], np.nan) for (ch, v), a, b in zip(r0.items(), edges, edges[1:])}
    n, n_eff = int(sum(np.isfinite(v).sum() for v in r1.values())), effective_n(r1)
    s2 = float(sol["r"] @ sol["r"]) / max(n - len(fit_keys), 1)
    try:
        cov = np.linalg.inv(sol["jac"].T @ sol["jac"]) * s2 * n / n_eff
        sigma = {k: float(math.sqrt(max(cov[i, i], 0.0)) * span[i]) for i, k in enumerate(fit_keys)}
    except np.linalg.LinAlgError:
        sigma = {k: math.inf for k in fit_keys}
    t1 = _residual(setup, test, params.with_overrides(fitted))
    return Calibration(
        keys=fit_keys,
        start={k: params.values[k] for k in fit_keys},
        fitted=fitted,
        sigma=sigma,
        at_bound={k: bool(min(u[i], 1.0 - u[i]) < 1e-3) for i, k in enumerate(fit_keys)},
        ident=ident,
        train_rms_c=(_rms(r0), _rms(r1)),
        test_rms_c=(_rms(t0), _rms(t1)),
        test_by_channel={ch: (_ch_rms(t0[ch]), _ch_rms(t1[ch])) for ch in t0},
        n_sims=int(sol["evaluations"]) + len(keys) + 3,
        train=[str(f) for r in train for f in r.files],
        test=[str(f) for r in test for f in r.files],
        n_eff=n_eff,
        n_cells=n,
        notes=notes,
        rivals=offset_rivals(r0, r1),
    )


#: a channel's training gap a constant reading offset of at least this explains ...
RIVAL_OFFSET_C = 0.5
#: ... leaving at most this share more than the fit leaves on it: the fit may have turned a sensor's offset into a
#: parameter (a bearing reading +3 K planted into a turbine's year fitted f0_tapered at 5.52 for 3.65, and moved
#: f0_cylindrical too, written with no word: a reviewer's trial; diagnose named the offset, +4.36 K)
RIVAL_SHARE = 1.05


def offset_rivals(r0: dict, r1: dict) -> list[str]:
    """A sentence per channel whose training gap before the fit (``r0``, measured - model at the file's values) a
    constant offset explains about as well as the fit did (``r1``, after it)."""
    out = []
    for ch, before in r0.items():
        ok = np.isfinite(before) & np.isfinite(r1[ch])
        if ok.sum() < 2:
            continue
        offset, left = float(np.mean(before[ok])), float(np.std(before[ok]))
        fit_left = float(np.sqrt(np.mean(r1[ch][ok] ** 2)))
        moved = fit_left < float(np.sqrt(np.mean(before[ok] ** 2)))
        if abs(offset) >= RIVAL_OFFSET_C and moved and left <= RIVAL_SHARE * fit_left:
            out.append(
                f"{ch}: a constant reading offset of {offset:+.2f} K explains its training gap as well as the fitted "
                f"values do ({left:.2f} against {fit_left:.2f} K RMS left): a sensor's offset is no parameter of "
                "the gearbox, and calibrate may have turned one into the fitted values; check it with `diagnose "
                "--columns` (thermocouple_offset) before using this file"
            )
    return out


def nbm_beside(setup: Setup, train: Sequence[ScadaRecord], test: Sequence[ScadaRecord], params=None) -> dict:
    """{channel: (held-out RMS of the linear NBM fitted on ``train``, of the physics-informed NBM)}: the sump without
    any oil reading, every other channel from the measured sump and the load. The physics-informed NBM
    (tools/scada/hybrid.py) takes the sensor with ``params`` (the calibrated values) as its physics; NaN without."""
    from tools.scada.holdout import errors
    from tools.scada.hybrid import PhysicsInformedNBM
    from tools.scada.nbm import LinearNBM, task_for
    from tools.scada.physics import PhysicsModel
    from tools.scada.replay import after_long_gaps

    both = [*train, *test]
    tasks = ([task_for(both, "oil", (setup.sump,))] if setup.sump else []) + (
        [task_for(both, "bearings", setup.others, oil_input=setup.sump)] if setup.others else []
    )
    out = {}
    for task in tasks:
        nbm = LinearNBM(task).fit(train)
        preds = [[nbm.predict(r) for r in test]]
        if params is not None:
            try:  # the sensor's estimates may leave too few complete rows: the column says nan, the rest stands
                sensor = PhysicsModel(task, setup.config, params=params, fit_effects=False)
                informed = PhysicsInformedNBM(task, sensor).fit(train)
                preds.append([informed.predict(r) for r in test])
            except InputError:
                pass
        for ch in task.targets:
            # on the rows the physics is scored on: the sump's after a day's gap are no evidence (after_long_gaps)
            meas = np.concatenate(
                [np.where(after_long_gaps(r), np.nan, r.values[ch]) if ch == setup.sump else r.values[ch] for r in test]
            )
            rms = [errors(meas, np.concatenate([p[ch] for p in pm]))[1] for pm in preds]
            out[ch] = (rms[0], rms[1] if len(rms) > 1 else float("nan"))
    return out
