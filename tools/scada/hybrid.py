"""The physics-informed normal-behaviour model: the linear NBM of :mod:`tools.scada.nbm` with the physics model's
estimate of the same channel among its features (docs/real-data.md, "The physics model inside the NBM").

The physics predictor (:class:`tools.scada.physics.PhysicsModel`: the onboard sensor, the task's effects fitted) is
fitted on the training records first; then, per target channel, a least-squares line over the NBM's features (the
power and its lags, the rotor speed, the outdoor and nacelle temperatures, the measured oil for the bearings) and
that channel's physics estimate. The physics carries what a linear function of the load cannot (the thermostat's
band, the cooling down at standstill, the heat paths' time constants); the regression carries what the physics
gets wrong in a way the load and the weather predict (a regime's bias). Its coefficient on the physics estimate
says how much of the prediction the physics makes. Rows without a physics estimate get no prediction.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from firmware_model.errors import InputError
from tools.scada.nbm import TASKS, Task, features, least_squares
from tools.scada.reader import ScadaRecord


class PhysicsInformedNBM:
    """The linear NBM with the physics estimate as one more feature (the module's docstring); a predictor.
    ``physics``: an unfitted physics predictor of the same task (``fit`` fits it)."""

    name = "physics-informed NBM"

    def __init__(self, task: Task | str, physics):
        self.task = TASKS[task] if isinstance(task, str) else task
        self.physics = physics
        self.coef: dict[str, tuple[np.ndarray, float]] = {}
        self.feature_names: list[str] = []

    def _matrix(self, record: ScadaRecord, estimates: dict, target: str) -> np.ndarray:
        x = features(record, self.task)[0]
        return np.column_stack([x, estimates.get(target, np.full(record.n, np.nan))])

    def fit(self, records: Sequence[ScadaRecord]) -> PhysicsInformedNBM:
        self.physics.fit(records)
        estimates = [self.physics.predict(r) for r in records]
        self.feature_names = features(records[0], self.task)[1] + ["physics estimate"]
        for target in self.task.targets:
            x = np.vstack([self._matrix(r, e, target) for r, e in zip(records, estimates)])
            y = np.concatenate([r.values[target] for r in records])
            self.coef[target] = least_squares(x, y)
        return self

    def predict(self, record: ScadaRecord) -> dict[str, np.ndarray]:
        if not self.coef:
            raise InputError("the physics-informed NBM predicts only after fit()")
        estimates = self.physics.predict(record)
        return {t: self._matrix(record, estimates, t) @ c + b for t, (c, b) in self.coef.items()}

    def physics_weight(self) -> dict[str, float]:
        """Per target, the coefficient on the physics estimate (1: the physics' own scale; 0: not used)."""
        return {t: float(c[-1]) for t, (c, _) in self.coef.items()}
