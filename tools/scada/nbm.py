"""The linear normal-behaviour model (NBM) of wind-turbine condition monitoring: the baseline the physics is held
against on measured temperatures (docs/real-data.md, "The data-driven baseline").

A temperature is a least-squares linear function of: the power, its exponential lags with time constants of 10 min,
30 min, 1 h and 2 h (first order, computed along each gap-free stretch and reset to the power at the stretch's first
row, a missing power held), the rotor speed, the outdoor and the nacelle temperatures, a constant, and for the
bearings also the measured oil. Two tasks: ``bearings`` (each bearing from the measured oil and the load) and
``oil`` (the sump and the inlet without any oil reading). Rows where a feature or the target is NaN are left out
of the fit and get a NaN prediction.

``BoostedNBM`` is the same model with gradient-boosted regression trees in place of the least squares (scikit-learn's
HistGradientBoostingRegressor, its default settings, not tuned here): the nonlinear kind of NBM the field also uses,
on the same features and rows. It needs the ``boosted`` extra (``pip install -e ".[boosted]"``).

``LongLagNBM`` is the linear NBM with slower memories: the power's lags of 6, 12 and 24 h, the nacelle air's of 2
and 12 h, and lags of 30 min, 3 h and 12 h of whether the turbine produces; a sump that cools for hours at
standstill is what the 2 h lags miss (a reviewer's stronger baseline: the unmeasured sump across turbines 3.3-3.6 K
against the linear NBM's 5.0-5.4 K; docs/real-data.md, "A stronger linear baseline").

Any model compared on these tasks is a *predictor*: ``fit(records)`` on training records, then
``predict(record)`` -> {channel: prediction}, NaN where it has none (:mod:`tools.scada.holdout` scores them).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from firmware_model.errors import InputError
from tools.scada.reader import ScadaRecord
from tools.scada.regimes import PRODUCING_KW

#: the time constants of the power's lags [s]
LAG_TAUS_S = (600.0, 1800.0, 3600.0, 7200.0)
#: the long-lag NBM's further lags [s]: of the power, of the nacelle air, of whether the turbine produces (its
#: power above tools.scada.regimes.PRODUCING_KW, the standstill bound)
LONG_POWER_TAUS_S, LONG_AIR_TAUS_S, LONG_PRODUCING_TAUS_S = (
    (21600.0, 43200.0, 86400.0),
    (7200.0, 43200.0),
    (
        1800.0,
        10800.0,
        43200.0,
    ),
)


@dataclass(frozen=True)
class Task:
    """What is predicted (``targets``, measured channels) and which measured channel is an input (``oil_input``)."""

    name: str
    targets: tuple[str, ...]
    oil_input: str | None = None
    #: the run-table inputs used as features (besides the power's lags)
    inputs: tuple[str, ...] = ("power_kw", "input_speed_rpm", "outdoor_temp_c", "ambient_temp_c")
    #: the input whose lags are features
    lagged: str = "power_kw"


#: the two tasks on the ENGIE map's channels
TASKS = {
    "bearings": Task("bearings", ("Gb1t_avg", "Gb2t_avg"), oil_input="Gost_avg"),
    "oil": Task("oil", ("Gost_avg", "Git_avg")),
}


def exp_lag(x: np.ndarray, time_s: np.ndarray, stretch: np.ndarray, tau_s: float) -> np.ndarray:
    """First-order lag of ``x`` with time constant ``tau_s``, y_k = a y_{k-1} + (1 - a) x_k, a = exp(-dt / tau),
    along each stretch: y = x at the stretch's first row (reset at every gap); a NaN ``x`` is held at its last
    value (NaN until the stretch's first valid one). ``dt`` is the stretch's median step."""
    y = np.full(x.shape, np.nan)
    starts = np.flatnonzero(np.diff(stretch, prepend=-1) != 0)
    for a0, b0 in zip(starts, np.append(starts[1:], x.size)):
        seg = x[a0:b0]
        ok = np.flatnonzero(~np.isnan(seg))
        if ok.size == 0:
            continue
        first = ok[0]
        held = seg[first:].copy()
        idx = np.where(~np.isnan(held), np.arange(held.size), 0)
        held = held[np.maximum.accumulate(idx)]  # forward fill
        dt = float(np.median(np.diff(time_s[a0:b0]))) if b0 - a0 > 1 else tau_s
        a = np.exp(-dt / tau_s)
        y[a0 + first : b0] = lfilter([1.0 - a], [1.0, -a], held, zi=[a * held[0]])[0]
    return y


def channel(record: ScadaRecord, name: str) -> np.ndarray | None:
    """``record``'s channel ``name``, the power [kW] from the input speed and torque where a map gives no
    ``power_kw`` (a rig's reducer: speed and torque, no electrical power), or None."""
    if name in record.values:
        return record.values[name]
    if name == "power_kw" and {"input_speed_rpm", "input_torque_nm"} <= record.values.keys():
        v = record.values
        return (
            np.asarray(v["input_speed_rpm"], dtype=float)
            * np.asarray(v["input_torque_nm"], dtype=float)
            * (np.pi / 30.0 / 1000.0)
        )
    return None


def task_for(records: Sequence[ScadaRecord], name: str, targets: tuple, oil_input: str | None = None) -> Task:
    """The task ``name`` on ``records`` with the default inputs every one of them has (a rig without outdoor air
    or a nacelle leaves those out): the ENGIE records have them all, the task as :data:`TASKS`'s."""
    inputs = tuple(c for c in Task.inputs if all(channel(r, c) is not None for r in records))
    return Task(name, tuple(targets), oil_input=oil_input, inputs=inputs)


def features(record: ScadaRecord, task: Task) -> tuple[np.ndarray, list[str]]:
    """(rows x features matrix without the constant, the features' names) of ``record`` for ``task``."""
    missing = [c for c in (*task.inputs, task.lagged, task.oil_input) if c and channel(record, c) is None]
    if missing:
        need = "the power (power_kw, or input_speed_rpm and input_torque_nm)" if missing[0] == "power_kw" else ""
        raise InputError(
            f"the record of {record.unit} has no channel {missing[0]} the {task.name} task's NBM needs"
            + (f": it takes {need}" if need else "")
        )
    cols = [channel(record, c) for c in task.inputs]
    names = list(task.inputs)
    for tau in LAG_TAUS_S:
        cols.append(exp_lag(channel(record, task.lagged), record.time_s, record.stretch, tau))
        names.append(f"{task.lagged}_lag{tau / 60:.0f}min")
    if task.oil_input:
        cols.append(record.values[task.oil_input])
        names.append(task.oil_input)
    return np.column_stack(cols), names


def least_squares(
    x: np.ndarray, y: np.ndarray, names: Sequence[str] = (), target: str = "the target"
) -> tuple[np.ndarray, float]:
    """(coefficients, intercept) of y ~ x (rows with a NaN left out), solved on standardised columns; ``names`` (x's
    columns) and ``target`` (y's) name the emptiest column when too few rows are complete."""
    ok = np.all(np.isfinite(x), axis=1) & np.isfinite(y)
    if ok.sum() <= x.shape[1] + 1:
        given = np.column_stack([np.isfinite(x), np.isfinite(y)]).sum(axis=0)
        labels = (
            [*names, target] if len(names) == x.shape[1] else [f"feature {i}" for i in range(x.shape[1])] + [target]
        )
        worst = int(np.argmin(given))
        raise InputError(
            f"{int(ok.sum())} complete rows cannot fit {x.shape[1] + 1} coefficients: {labels[worst]} has a value "
            f"on {int(given[worst])} of {len(y)} rows (an empty or rejected column?)"
        )
    xs, ys = x[ok], y[ok]
    mu, sd = xs.mean(axis=0), xs.std(axis=0)
    sd = np.where(sd > 0, sd, 1.0)
    a = np.column_stack([(xs - mu) / sd, np.ones(len(xs))])
    sol = np.linalg.lstsq(a, ys, rcond=None)[0]
    coef = sol[:-1] / sd
    return coef, float(sol[-1] - coef @ mu)


class LinearNBM:
    """The linear NBM of one task (the module's docstring); a predictor. A subclass adds feature columns per target
    through ``_extra`` (and their names through ``_extra_names``), or fits another regression through ``_solve``
    and ``_apply``."""

    name = "linear NBM"

    def __init__(self, task: Task | str):
        if isinstance(task, str) and task not in TASKS:
            raise InputError(f"no NBM task {task!r}: the tasks are {', '.join(TASKS)}")
        self.task = TASKS[task] if isinstance(task, str) else task
        #: per target, the fitted regression (here (coefficients, intercept))
        self.coef: dict[str, object] = {}
        self.feature_names: list[str] = []

    def _extra(self, record: ScadaRecord, target: str) -> list[np.ndarray]:
        """More feature columns of ``record`` for ``target`` (none here)."""
        return []

    def _extra_names(self) -> list[str]:
        return []

    def _solve(self, x: np.ndarray, y: np.ndarray, target: str):
        """The regression of y on x's columns (rows with a NaN left out)."""
        return least_squares(x, y, self.feature_names, target)

    def _apply(self, fitted, x: np.ndarray) -> np.ndarray:
        """The fitted regression's prediction on x's rows (NaN where a feature is)."""
        c, b = fitted
        return x @ c + b

    def fit(self, records: Sequence[ScadaRecord]) -> LinearNBM:
        mats = [features(r, self.task) for r in records]
        self.feature_names = mats[0][1] + self._extra_names()
        for target in self.task.targets:
            x = np.vstack([np.column_stack([m[0], *self._extra(r, target)]) for m, r in zip(mats, records)])
            y = np.concatenate([r.values[target] for r in records])
            self.coef[target] = self._solve(x, y, target)
        return self

    def predict(self, record: ScadaRecord) -> dict[str, np.ndarray]:
        if not self.coef:
            raise InputError(f"the {self.name} predicts only after fit()")
        x = features(record, self.task)[0]
        return {t: self._apply(f, np.column_stack([x, *self._extra(record, t)])) for t, f in self.coef.items()}


class BoostedNBM(LinearNBM):
    """The NBM of one task with gradient-boosted trees (the module's docstring): scikit-learn's
    HistGradientBoostingRegressor at its defaults, seeded; like the linear NBM it is fitted on the rows where every
    feature and the target exist and predicts NaN where a feature is missing, so both score the same rows."""

    name = "boosted NBM"

    def _solve(self, x: np.ndarray, y: np.ndarray, target: str):
        try:
            from sklearn.ensemble import HistGradientBoostingRegressor
        except ImportError as exc:
            raise InputError(
                'the boosted NBM needs scikit-learn: pip install -e ".[boosted]" (or pip install scikit-learn)'
            ) from exc
        ok = np.all(np.isfinite(x), axis=1) & np.isfinite(y)
        if ok.sum() <= x.shape[1] + 1:
            least_squares(x, y, self.feature_names, target)  # its sentence names the emptiest column
        return HistGradientBoostingRegressor(random_state=0).fit(x[ok], y[ok])

    def _apply(self, fitted, x: np.ndarray) -> np.ndarray:
        ok = np.all(np.isfinite(x), axis=1)
        pred = np.full(len(x), np.nan)
        if ok.any():
            pred[ok] = fitted.predict(x[ok])
        return pred


class LongLagNBM(LinearNBM):
    """The linear NBM with the slower lags (the module's docstring), least squares on the same rows."""

    name = "long-lag linear NBM"
    _has_air = True  # (set by fit: every training record has the nacelle air)

    def _extra(self, record: ScadaRecord, target: str) -> list[np.ndarray]:
        power = channel(record, "power_kw")
        air = channel(record, "ambient_temp_c")
        producing = np.where(np.isfinite(power), (power > PRODUCING_KW).astype(float), np.nan)
        t, stretch = record.time_s, record.stretch
        cols = [exp_lag(power, t, stretch, tau) for tau in LONG_POWER_TAUS_S]
        if self._has_air:  # (a record without the air the fit had: NaN, no prediction)
            air = np.full(record.n, np.nan) if air is None else np.asarray(air, dtype=float)
            cols += [exp_lag(air, t, stretch, tau) for tau in LONG_AIR_TAUS_S]
        return cols + [exp_lag(producing, t, stretch, tau) for tau in LONG_PRODUCING_TAUS_S]

    def _extra_names(self) -> list[str]:
        air = [f"ambient_temp_c_lag{tau / 3600:.0f}h" for tau in LONG_AIR_TAUS_S] if self._has_air else []
        return [
            *(f"power_kw_lag{tau / 3600:.0f}h" for tau in LONG_POWER_TAUS_S),
            *air,
            *(f"producing_lag{tau / 3600:g}h" for tau in LONG_PRODUCING_TAUS_S),
        ]

    def fit(self, records: Sequence[ScadaRecord]) -> LongLagNBM:
        self._has_air = all(channel(r, "ambient_temp_c") is not None for r in records)
        return super().fit(records)
