"""The model-form family of ``bench-diagnosis``: the truth differs from the parameter file in assumed values that
are not catalog effects.

Per scenario, the reference plant that makes the truth has ``n_keys`` of the parameter file's bounded keys (those that
``calibrate`` may fit) moved to random values 30-100 % of the way from the file's value to a bound. Then, on the same
measured files: the diagnosis (it must not claim an effect whose held-out shrink is small: a claim with < 30 % is
counted), and ``calibrate --auto`` (the held-out RMS before and after).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np


@dataclass
class FormRow:
    index: int
    setup: str
    cooler: str
    perturbed: dict  # key -> (file value, truth value) [SI]
    verdict: str
    shrink: float
    claim_ok: bool  # no effect claimed with a small held-out shrink
    fitted: dict  # key -> fitted value [SI]
    cal_before_c: float
    cal_after_c: float
    diag_s: float
    cal_s: float

    @property
    def reduction(self) -> float:
        return 1.0 - self.cal_after_c / max(self.cal_before_c, 1e-12)


def perturbation(params, rng: np.random.Generator, n_keys: int) -> dict:
    """n_keys bounded keys moved 30-100 % of the way from the file's value to a bound (the side at random)."""
    keys = sorted(params.bounds)
    pick = rng.choice(len(keys), size=min(n_keys, len(keys)), replace=False)
    out = {}
    for i in sorted(pick):
        k = keys[i]
        lo, hi = params.bounds[k]
        v = params[k]
        bound = hi if rng.random() < 0.5 else lo
        out[k] = float(v + rng.uniform(0.3, 1.0) * (bound - v))
    return out


def run_case(
    i: int, seed: int, setup: str, params, model: str, train_s: float, n_keys: int, shrink_min: float
) -> FormRow:
    from tools.diagnosis.bench import make_scenario
    from tools.diagnosis.calibrate import calibrate
    from tools.diagnosis.core import diagnose

    rng = np.random.default_rng([int(seed), int(i), 0xF0A])
    pert = perturbation(params, rng, n_keys)
    truth = params.with_overrides(pert)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = make_scenario(i, seed, setup, None, None, truth, train_s=train_s, test_s=train_s)
        t0 = time.perf_counter()
        res = diagnose(sc.train, sc.test, params, model=model)
        t1 = time.perf_counter()
        cal = calibrate(sc.train, sc.test, params, None, auto=True)
        t2 = time.perf_counter()
    v = res["verdict"]
    claimed = v["effect"] not in ("none", "unexplained")
    shrink = float(v["shrink"] or 0.0)
    return FormRow(
        i,
        setup,
        sc.cooler,
        {k: (params[k], x) for k, x in pert.items()},
        v["effect"],
        shrink,
        not (claimed and shrink < shrink_min),
        dict(cal.fitted),
        cal.test_rms_c[0],
        cal.test_rms_c[1],
        t1 - t0,
        t2 - t1,
    )


def format_rows(rows: list) -> str:
    head = (
        "| # | set-up | truth: assumed values moved (file -> truth) | verdict (held-out shrink) | calibrated "
        "(fitted) | held-out RMS before -> after calibrate [degC] | down | s (diagnose / calibrate) |\n"
        "|---|---|---|---|---|---|---|---|\n"
    )
    lines = []
    for r in rows:
        moved = "; ".join(f"{k} {a:.4g} -> {b:.4g}" for k, (a, b) in r.perturbed.items())
        fit = "; ".join(f"{k} {x:.4g}" for k, x in r.fitted.items())
        verdict = f"{r.verdict} ({100 * r.shrink:.0f} %)" + ("" if r.claim_ok else " CLAIM < 30 %")
        lines.append(
            f"| {r.index} | {r.setup} | {moved} | {verdict} | {fit} | {r.cal_before_c:.3f} -> "
            f"{r.cal_after_c:.3f} | {100 * r.reduction:.0f} % | {r.diag_s:.0f} / {r.cal_s:.0f} |"
        )
    red = [r.reduction for r in rows]
    times = [r.diag_s for r in rows] + [r.cal_s for r in rows]
    foot = (
        f"\n\n| figure | measured | target |\n|---|---|---|\n"
        f"| scenarios (truck / rig) | {len(rows)} ({sum(r.setup == 'truck' for r in rows)} / "
        f"{sum(r.setup == 'rig' for r in rows)}) | >= 10 |\n"
        f"| median held-out RMS down after calibrate | {100 * float(np.median(red)):.0f} % | >= 60 % |\n"
        f"| verdicts claiming an effect with < 30 % held-out shrink | {sum(not r.claim_ok for r in rows)} | 0 |\n"
        f"| median time per case, diagnose / calibrate (max of both) | {np.median([r.diag_s for r in rows]):.0f} s"
        f" / {np.median([r.cal_s for r in rows]):.0f} s ({max(times):.0f} s) | <= 60 s |\n"
    )
    return head + "\n".join(lines) + foot


def run_model_form_bench(
    n: int, seed: int, params, model: str = "plant", train_s: float = 1500.0, n_keys: int = 4, progress=print, only=None
) -> list:
    from tools.diagnosis.options import Options

    rows = []
    for i in range(n):
        if only is not None and i not in only:
            continue
        setup = "rig" if i % 2 == 0 else "truck"
        r = run_case(i, seed, setup, params, model, train_s, n_keys, Options().shrink_min)
        rows.append(r)
        progress(
            f"[{i + 1}/{n}] {setup:5s} {len(r.perturbed)} assumed values moved -> verdict {r.verdict} "
            f"(shrink {100 * r.shrink:.0f} %); calibrate {r.cal_before_c:.3f} -> {r.cal_after_c:.3f} degC "
            f"({100 * r.reduction:.0f} % down)  {r.diag_s:.0f} s + {r.cal_s:.0f} s"
        )
    return rows
