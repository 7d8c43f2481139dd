"""Held-out errors of the linear normal-behaviour model on measured gearbox temperatures (docs/real-data.md).

ENGIE's La Haute Borne SCADA (three Senvion MM82 turbines, 10-minute rows; not shipped with the repository) is read
through the `engie` column map, then the NBM (tools/scada/nbm.py) is fitted and scored on held-out data for both
tasks (bearings from the measured oil and the load; the oil sump and inlet without any oil reading):

- across turbines: fitted on two, tested on the third, each way round;
- in time: fitted on a turbine's first year (365 days from its first row) and tested on its later rows, and fitted
  on its 2013-2016 rows and tested on its 2017-2018 rows.

It prints the RMS and the 99th percentile of the absolute error [K] per split, task and channel, with empty columns
for the physics model (any predictor with fit(records) and predict(record) -> {channel: prediction}: pass its
factory to `run(..., other=...)`; `--vs-mean` fills them with each channel's training mean, the trivial
predictor), and the run time; then the oil task's error across turbines on producing rows and on the others.

`--physics` fills them with the physics model (tools/scada/physics.py: the MM82's onboard sensor with the task's
effects fitted on the training records; `--fit-rows N` caps the rows per training record, default half a year),
and prints each fit's effects.

`--period YYYY[-MM]` keeps only that calendar year or month (UTC) of every turbine before splitting; `--only TEXT`
(repeatable) keeps the splits whose label contains TEXT (e.g. `--only "-> R80721" --only "R80736: first year"`),
so that one split per kind can be run with the physics model.

`--boosted` fills them with the boosted NBM (tools/scada/nbm.py: the same features with gradient-boosted trees in
place of the least squares, scikit-learn's defaults; the `boosted` extra), the nonlinear data-driven reference.

`--informed` fills them with the physics-informed NBM (tools/scada/hybrid.py: the NBM with the physics model's
estimate as one more feature, both fitted on the training records) and prints each fit's weight on the physics;
`--informed --boosted` with the physics-informed boosted NBM (the boosted NBM's trees over the same features).

`--long-lag` fills them with the long-lag linear NBM (tools/scada/nbm.py: the power's lags to 24 h, the nacelle
air's and whether the turbine produces; a reviewer's stronger linear baseline), its ratio to the linear NBM.

`--compare` prints one table of all five on the same splits: the linear NBM's RMS and, with their ratios to it, the
boosted NBM's, the physics model's and both physics-informed NBMs' (the physics fitted once per split and task);
`--plot PNG` draws them as bars, a fraction of the linear NBM's RMS, with the goals.

    python benchmarks/bench_scada.py [--vs-mean | --long-lag | --boosted | --physics | --informed [--boosted]
        | --compare [--plot PNG]] [--fit-rows N] [--period P] [--only T]... DIR
"""

from __future__ import annotations

import datetime as dt
import os
import re
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from firmware_model.errors import InputError  # noqa: E402
from tools.scada.holdout import (  # noqa: E402
    TrainingMean,
    cross_unit_splits,
    errors,
    evaluate,
    ratio_table,
    table,
    time_splits,
)
from tools.scada.nbm import TASKS, BoostedNBM, LinearNBM, LongLagNBM  # noqa: E402
from tools.scada.reader import read_units  # noqa: E402

#: a row counts as producing above this power [kW]
PRODUCING_KW = 100.0


def by_state(records) -> str:
    """The NBM's oil task across turbines, its error split into producing rows and the others (standstill, idling)."""
    lines = [
        "| split | channel | producing rows | RMS [K] | p99 [K] | measured 5-95 % [degC] | other rows | RMS [K] "
        "| p99 [K] |",
        "|---|---|---:|---:|---:|---|---:|---:|---:|",
    ]
    for label, train, (test,) in cross_unit_splits(records):
        pred = LinearNBM(TASKS["oil"]).fit(train).predict(test)
        prod = test.values["power_kw"] > PRODUCING_KW
        for ch in TASKS["oil"].targets:
            meas = test.values[ch]
            n1, rms1, p1 = errors(meas[prod], pred[ch][prod])
            n2, rms2, p2 = errors(meas[~prod], pred[ch][~prod])
            lo, hi = np.nanpercentile(meas[prod], [5, 95])
            lines.append(
                f"| {label} | {ch} | {n1} | {rms1:.2f} | {p1:.2f} | {lo:.1f}-{hi:.1f} | {n2} | {rms2:.2f} | {p2:.2f} |"
            )
    return "\n".join(lines)


def period_of(records: dict, period: str) -> dict:
    """Each unit's rows in the calendar year (YYYY) or month (YYYY-MM) ``period``, UTC; units without any left out."""
    parts = [int(x) for x in period.split("-")]
    if len(parts) == 1:
        a, b = dt.datetime(parts[0], 1, 1), dt.datetime(parts[0] + 1, 1, 1)
    else:
        y, m = parts
        a, b = dt.datetime(y, m, 1), dt.datetime(y + m // 12, m % 12 + 1, 1)
    a_s, b_s = (x.replace(tzinfo=dt.timezone.utc).timestamp() for x in (a, b))
    out = {}
    for unit, rec in records.items():
        mask = (rec.time_s >= a_s) & (rec.time_s < b_s)
        if mask.any():
            out[unit] = rec.select(mask)
    return out


def period_arg(text: str) -> str:
    """argparse type of --period: a calendar year YYYY or month YYYY-MM (else argparse's one-line error)."""
    import argparse

    if not re.fullmatch(r"\d{4}(-(0[1-9]|1[0-2]))?", text):
        raise argparse.ArgumentTypeError(f"{text!r} is no calendar year YYYY or month YYYY-MM")
    return text


def add_data_dir(ap) -> None:
    """The SCADA folder argument of the benchmarks that take argparse options (GVS_REAL_SCADA by default)."""
    ap.add_argument("data_dir", nargs="?", default=os.environ.get("GVS_REAL_SCADA"), help="the ENGIE SCADA files")


def data_dir_of(args, usage: str) -> Path | None:
    """The parsed SCADA folder, or None after printing ``usage`` (no folder given, or not a folder)."""
    if not args.data_dir or not Path(args.data_dir).is_dir():
        print(f"usage: {usage} (or set GVS_REAL_SCADA)")
        return None
    if not any(Path(args.data_dir).glob("turbine_*.csv*")):
        print(f"{args.data_dir}: no turbine_<ID>_<period>_<k>.csv.gz files there (ENGIE's La Haute Borne SCADA)")
        return None
    return Path(args.data_dir)


def records_and_splits(data_dir: Path, period: str | None, only: list[str] | None):
    """The folder's records (of ``period``, when given) and the held-out splits whose label holds one of ``only``."""
    records = read_units(sorted(data_dir.glob("*.csv*")), "engie")
    if period:
        records = period_of(records, period)
    splits = cross_unit_splits(records) + time_splits(records) + time_splits(records, cut="2017-01-01")
    if only:
        splits = [s for s in splits if any(o in s[0] for o in only)]
    if not splits:
        raise InputError(
            "no held-out split to score"
            + (f": none of the split labels holds {' or '.join(map(repr, only))}" if only else "")
            + f" ({len(records)} turbines{f' in {period}' if period else ''})"
        )
    return records, splits


def headline(records: dict, splits: list, period: str | None, t_read: float, total: float) -> str:
    """The first line of a run: the records, the splits and the time taken."""
    rows = sum(r.n for r in records.values())
    return (
        (f"period {period}: " if period else "")
        + f"{len(records)} turbines, {rows} rows of 10 min ({', '.join(f'{u}: {r.n}' for u, r in records.items())}); "
        f"read in {t_read:.1f} s, {len(splits)} splits x {len(TASKS)} tasks fitted and scored in "
        f"{total - t_read:.1f} s (total {total:.1f} s)"
    )


def run(
    data_dir: Path, other=None, other_name: str = "physics", period: str | None = None, only: list[str] | None = None
) -> str:
    """The held-out table of the NBM (and of ``other``, a predictor factory task -> predictor, when given)."""
    t0 = time.perf_counter()
    records, splits = records_and_splits(data_dir, period, only)
    t_read = time.perf_counter() - t0
    nbm, phys = [], []
    for split in splits:
        for task in TASKS.values():
            nbm.extend(evaluate(LinearNBM, task, split))
            if other is not None:
                t1 = time.perf_counter()
                phys.extend(evaluate(other, task, split))
                print(
                    f"{split[0]} {task.name}: {other_name} fitted and scored in {time.perf_counter() - t1:.0f} s",
                    flush=True,
                )
    return (
        headline(records, splits, period, t_read, time.perf_counter() - t0)
        + "\n\n"
        + table(nbm, phys, other_name)
        + f"\n\nThe NBM's oil task across turbines, producing (P > {PRODUCING_KW:.0f} kW) and other rows:\n\n"
        + by_state(records)
    )


def physics_factory(fit_rows: int | None, fits: list):
    """A factory task -> PhysicsModel of the MM82 description (its fitted models kept in ``fits``)."""
    from firmware_model.config import load_config
    from tools.cli.gearbox_option import with_gearbox
    from tools.scada.physics import PhysicsModel

    cfg = with_gearbox(load_config(None), "MM82")

    def make(task):
        m = PhysicsModel(task, cfg) if fit_rows is None else PhysicsModel(task, cfg, max_fit_rows=fit_rows)
        fits.append(m)
        return m

    return make


def informed_factory(fit_rows: int | None, fits: list, boosted: bool = False):
    """A factory task -> PhysicsInformedNBM (PhysicsInformedBoostedNBM with ``boosted``) over the MM82's physics
    predictor (fitted models kept in ``fits``)."""
    from tools.scada.hybrid import PhysicsInformedBoostedNBM, PhysicsInformedNBM

    physics = physics_factory(fit_rows, [])
    kind = PhysicsInformedBoostedNBM if boosted else PhysicsInformedNBM

    def make(task):
        m = kind(task, physics(task))
        fits.append(m)
        return m

    return make


class FittedOnce:
    """A predictor fitted once per set of training records, however many predictors fit it (the physics model shared
    by the physics-informed NBMs of one split and task in ``--compare``)."""

    def __init__(self, model):
        self.model, self.name, self._on = model, getattr(model, "name", "physics"), None

    def fit(self, records):
        if self._on != tuple(map(id, records)):
            self.model.fit(records)
            self._on = tuple(map(id, records))
        return self

    def predict(self, record):
        return self.model.predict(record)


def compare(data_dir: Path, fit_rows: int | None, period: str | None = None, only: list[str] | None = None):
    """The held-out RMS of the linear NBM and, beside it with their ratios to it, of the boosted NBM, the physics
    model and both physics-informed NBMs, on the same splits (the physics fitted once per split and task): (the
    table, the scores per predictor)."""
    from tools.scada.hybrid import PhysicsInformedBoostedNBM, PhysicsInformedNBM

    t0 = time.perf_counter()
    records, splits = records_and_splits(data_dir, period, only)
    t_read = time.perf_counter() - t0
    physics = physics_factory(fit_rows, [])
    names = ("linear NBM", "boosted NBM", "physics", "physics-informed NBM", "physics-informed boosted NBM")
    scores: dict[str, list] = {n: [] for n in names}
    for split in splits:
        for task in TASKS.values():
            t1 = time.perf_counter()
            shared = FittedOnce(physics(task))
            makes = (
                LinearNBM,
                BoostedNBM,
                lambda t, shared=shared: shared,
                lambda t, shared=shared: PhysicsInformedNBM(t, shared),
                lambda t, shared=shared: PhysicsInformedBoostedNBM(t, shared),
            )
            for name, make in zip(names, makes):
                scores[name].extend(evaluate(make, task, split))
            print(f"{split[0]} {task.name}: five predictors fitted and scored in {time.perf_counter() - t1:.0f} s")
    text = headline(records, splits, period, t_read, time.perf_counter() - t0)
    return text + "\n\n" + ratio_table(scores, "linear NBM"), scores


#: the issue's goals as a fraction of the linear NBM's RMS, per channel (drawn on the figure)
GOALS = {"Gb1t_avg": 0.8, "Gb2t_avg": 0.8, "Gost_avg": 0.6}


def plot_compare(scores: dict, path: Path, title: str) -> None:
    """Each predictor's held-out RMS as a fraction of the linear NBM's, one panel per channel, one group of bars per
    split, the goals drawn as lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ref = {(s.split, s.channel): s.rms_k for s in scores["linear NBM"]}
    names = [n for n in scores if n != "linear NBM"]
    channels = list(dict.fromkeys(s.channel for s in scores["linear NBM"]))
    splits = list(dict.fromkeys(s.split for s in scores["linear NBM"]))
    fig, axes = plt.subplots(len(channels), 1, figsize=(10, 2.2 * len(channels) + 1), sharex=True, squeeze=False)
    axes = axes[:, 0]
    width = 0.8 / len(names)
    for ax, ch in zip(axes, channels):
        for k, name in enumerate(names):
            got = {s.split: s.rms_k for s in scores[name] if s.channel == ch}
            ratios = [got.get(sp, np.nan) / ref[(sp, ch)] for sp in splits]
            ax.bar(np.arange(len(splits)) + (k - (len(names) - 1) / 2) * width, ratios, width, label=name)
        ax.axhline(1.0, color="k", lw=0.8)
        if ch in GOALS:
            ax.axhline(GOALS[ch], color="k", ls="--", lw=0.8)
        ax.set_ylabel(f"{ch}\nRMS / linear NBM")
        ax.set_ylim(0, min(2.2, max(1.2, ax.get_ylim()[1])))
    axes[-1].set_xticks(
        range(len(splits)), [sp.replace(": ", ":\n").replace(" -> ", "\n-> ") for sp in splits], fontsize=8
    )
    axes[0].legend(fontsize=8, ncol=2, loc="upper right")
    axes[0].set_title(title + " (dashed: the goal; 1: the linear NBM)")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def main(argv: list[str]) -> int:
    flags = {a for a in argv if a in ("--vs-mean", "--boosted", "--physics", "--informed", "--compare", "--long-lag")}
    args = [a for a in argv if a not in flags]
    fit_rows, period, only, plot = None, None, [], None
    while any(a in args for a in ("--fit-rows", "--period", "--only", "--plot")):
        i = next(i for i, a in enumerate(args) if a in ("--fit-rows", "--period", "--only", "--plot"))
        flag, value = args[i], args[i + 1]
        del args[i : i + 2]
        if flag == "--fit-rows":
            fit_rows = int(value)
        elif flag == "--period":
            period = value
        elif flag == "--plot":
            plot = value
        else:
            only.append(value)
    where = args[0] if args else os.environ.get("GVS_REAL_SCADA")
    if not where or not Path(where).is_dir():
        print(
            "usage: bench_scada.py [--vs-mean | --long-lag | --boosted | --physics | --informed [--boosted] "
            "| --compare [--plot PNG]] [--fit-rows N] [--period YYYY[-MM]] [--only TEXT]... DATA_DIR "
            "(or set GVS_REAL_SCADA)"
        )
        return 2
    if plot and not Path(plot).resolve().parent.is_dir():
        print(f"error: the folder of --plot {plot} does not exist")
        return 2
    try:
        report(flags, Path(where), fit_rows, period, only, plot)
    except InputError as exc:
        print(f"error: {exc}")
        return 2
    return 0


def report(flags: set, where: Path, fit_rows: int | None, period: str | None, only: list, plot: str | None) -> None:
    """Runs and prints what the flags ask for (main's usage)."""
    if "--compare" in flags:
        text, scores = compare(where, fit_rows, period, only)
        print(text)
        if plot:
            plot_compare(scores, Path(plot), f"Held-out RMS{f', {period}' if period else ''}")
            print(f"\nfigure: {plot}")
    elif "--vs-mean" in flags:
        print(run(where, TrainingMean, "training mean", period, only))
    elif "--long-lag" in flags:
        print(run(where, LongLagNBM, "long-lag NBM", period, only))
    elif "--boosted" in flags and "--informed" not in flags:
        print(run(where, BoostedNBM, "boosted NBM", period, only))
    elif "--physics" in flags:
        fits: list = []
        print(run(where, physics_factory(fit_rows, fits), "physics", period, only))
        print("\nThe physics fits (in split order, bearings then oil):\n")
        for m in fits:
            print(f"- {m.task.name}: {m.report}")
    elif "--informed" in flags:
        fits = []
        boosted = "--boosted" in flags
        name = "physics-informed boosted NBM" if boosted else "physics-informed NBM"
        print(run(where, informed_factory(fit_rows, fits, boosted), name, period, only))
        print("\nEach fit's coefficient on the physics estimate (in split order, bearings then oil):\n")
        for m in fits:
            weights = ", ".join(f"{t} {w:.2f}" for t, w in m.physics_weight().items()) or "none (trees)"
            print(f"- {m.task.name}: {weights}; physics effects {m.physics.effects}")
    else:
        print(run(where, period=period, only=only))


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
