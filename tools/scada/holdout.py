"""Held-out scores of predictors on measured temperatures (docs/real-data.md, "Held-out table").

A predictor is anything with ``fit(records)`` and ``predict(record)`` -> {channel: prediction} (the linear NBM of
:mod:`tools.scada.nbm`, later the physics model); ``make`` builds one for a task. :func:`evaluate` fits it on the
training records and scores it on the held-out ones: the RMS and the 99th percentile of the absolute error [K] over
the rows where both the measurement and the prediction exist. The splits: :func:`cross_unit_splits` (fit on all
units but one, test on that one, each way round) and :func:`time_splits` (fit on a unit's rows before a cut, test
on the rows after it).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from tools.scada.nbm import Task
from tools.scada.reader import ScadaRecord

#: one split: (its label, the training records, the held-out records)
Split = tuple[str, list[ScadaRecord], list[ScadaRecord]]
YEAR_S = 365.0 * 86400.0


@dataclass(frozen=True)
class Score:
    """One predictor's held-out error on one channel of one split."""

    predictor: str
    split: str
    task: str
    channel: str
    n: int
    rms_k: float
    p99_k: float


class TrainingMean:
    """The trivial predictor: each target's mean over the training records (what any model must beat)."""

    name = "training mean"

    def __init__(self, task: Task):
        self.task = task
        self.mean: dict[str, float] = {}

    def fit(self, records: Sequence[ScadaRecord]) -> TrainingMean:
        self.mean = {ch: float(np.nanmean(np.concatenate([r.values[ch] for r in records]))) for ch in self.task.targets}
        return self

    def predict(self, record: ScadaRecord) -> dict[str, np.ndarray]:
        return {ch: np.full(record.n, m) for ch, m in self.mean.items()}


def errors(measured: np.ndarray, predicted: np.ndarray) -> tuple[int, float, float]:
    """(rows scored, RMS, 99th percentile of the absolute error) over the rows where both are finite."""
    ok = np.isfinite(measured) & np.isfinite(predicted)
    if not ok.any():
        return 0, float("nan"), float("nan")
    e = predicted[ok] - measured[ok]
    return int(ok.sum()), float(np.sqrt(np.mean(e * e))), float(np.percentile(np.abs(e), 99.0))


def evaluate(make: Callable[[Task], object], task: Task, split: Split) -> list[Score]:
    """Fit ``make(task)`` on the split's training records; its scores per target on the held-out records."""
    label, train, test = split
    model = make(task).fit(train)
    preds = [model.predict(r) for r in test]
    out = []
    for ch in task.targets:
        meas = np.concatenate([r.values[ch] for r in test])
        pred = np.concatenate([p[ch] for p in preds])
        out.append(Score(getattr(model, "name", type(model).__name__), label, task.name, ch, *errors(meas, pred)))
    return out


def cross_unit_splits(records: dict[str, ScadaRecord]) -> list[Split]:
    """Fit on every unit but one, hold that one out; each unit in turn."""
    return [
        (f"{'+'.join(u for u in records if u != held)} -> {held}", [r for u, r in records.items() if u != held], [rec])
        for held, rec in records.items()
    ]


def time_splits(records: dict[str, ScadaRecord], cut: str | None = None) -> list[Split]:
    """Per unit: fit on its rows before ``cut`` (ISO date, UTC; None: a year after its first row), test after."""
    out = []
    for unit, rec in records.items():
        if cut is None:
            t_cut, what = rec.time_s[0] + YEAR_S, "first year"
        else:
            t_cut, what = float(np.datetime64(cut, "s").astype(np.int64)), f"before {cut}"
        early = rec.time_s < t_cut
        if early.any() and (~early).any():
            out.append((f"{unit}: {what} -> later", [rec.select(early)], [rec.select(~early)]))
    return out


def _cell(scores: dict, key) -> str:
    s = scores.get(key)
    return "- | -" if s is None else f"{s.rms_k:.2f} | {s.p99_k:.2f}"


def table(nbm: Sequence[Score], other: Sequence[Score] = (), other_name: str = "physics") -> str:
    """A Markdown table: per split, task and channel, the rows scored, the NBM's RMS and p99 [K], and the same of
    ``other`` (another predictor's scores on the same splits; '-' where it has none)."""
    others = {(s.split, s.task, s.channel): s for s in other}
    lines = [
        f"| split | task | channel | rows | NBM RMS [K] | NBM p99 [K] | {other_name} RMS [K] | {other_name} p99 [K] |",
        "|---|---|---|---:|---:|---:|---:|---:|",
    ]
    for s in nbm:
        key = (s.split, s.task, s.channel)
        lines.append(
            f"| {s.split} | {s.task} | {s.channel} | {s.n} | {s.rms_k:.2f} | {s.p99_k:.2f} | {_cell(others, key)} |"
        )
    return "\n".join(lines)


def ratio_table(scores: dict[str, Sequence[Score]], reference: str) -> str:
    """A Markdown table: per split, task and channel, the rows scored and each predictor's RMS [K] (``scores``:
    predictor name -> its scores on the same splits), every one but ``reference``'s with its ratio to the
    reference's in brackets; '-' where a predictor has no score."""
    ref = scores[reference]
    others = {name: {(s.split, s.task, s.channel): s for s in sc} for name, sc in scores.items() if name != reference}
    lines = [
        f"| split | task | channel | rows | {reference} RMS [K] | "
        + " | ".join(f"{name} RMS [K] (ratio)" for name in others)
        + " |",
        "|---|---|---|---:|---:|" + "---:|" * len(others),
    ]
    for s in ref:
        cells = []
        for by_key in others.values():
            o = by_key.get((s.split, s.task, s.channel))
            ratio = o.rms_k / s.rms_k if o is not None and s.rms_k > 0 else float("nan")
            cells.append("-" if o is None else f"{o.rms_k:.2f} ({ratio:.2f})")
        lines.append(f"| {s.split} | {s.task} | {s.channel} | {s.n} | {s.rms_k:.2f} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
