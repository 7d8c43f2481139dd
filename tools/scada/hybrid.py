"""The physics-informed normal-behaviour model: the linear NBM of :mod:`tools.scada.nbm` with the physics model's
estimate of the same channel among its features (docs/real-data.md, "The physics model inside the NBM").

The physics predictor (:class:`tools.scada.physics.PhysicsModel`: the onboard sensor, the task's effects fitted) is
fitted on the training records first; then, per target channel, a least-squares line over the NBM's features (the
power and its lags, the rotor speed, the outdoor and nacelle temperatures, the measured oil for the bearings) and
that channel's physics estimate. The physics carries what a linear function of the load cannot (the thermostat's
band, the cooling down at standstill, the heat paths' time constants); the regression carries what the physics
gets wrong in a way the load and the weather predict (a regime's bias). Its coefficient on the physics estimate
says how much of the prediction the physics makes. Rows without a physics estimate get no prediction.

``PhysicsInformedBoostedNBM`` is the same with the boosted NBM's trees in place of the line (the ``boosted``
extra): it can follow a physics estimate that is off in a way no line in the load describes, and has no single
weight on it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from tools.scada.nbm import BoostedNBM, LinearNBM, Task
from tools.scada.reader import ScadaRecord


class PhysicsInformedNBM(LinearNBM):
    """The linear NBM with the physics estimate as one more feature (the module's docstring); a predictor.
    ``physics``: a physics predictor of the same task; ``fit`` fits it first (a PhysicsModel with ``fit_effects``
    False keeps its values)."""

    name = "physics-informed NBM"

    def __init__(self, task: Task | str, physics):
        super().__init__(task)
        self.physics = physics
        self._estimates: dict[int, tuple] = {}  # id -> (record, estimates), within one fit or one predict

    def _extra(self, record: ScadaRecord, target: str) -> list[np.ndarray]:
        if id(record) not in self._estimates:
            self._estimates[id(record)] = (record, self.physics.predict(record))
        return [self._estimates[id(record)][1].get(target, np.full(record.n, np.nan))]

    def _extra_names(self) -> list[str]:
        return ["physics estimate"]

    def fit(self, records: Sequence[ScadaRecord]) -> PhysicsInformedNBM:
        self.physics.fit(records)
        self._estimates = {}
        try:
            return super().fit(records)
        finally:
            self._estimates = {}

    def predict(self, record: ScadaRecord) -> dict[str, np.ndarray]:
        self._estimates = {}
        try:
            return super().predict(record)
        finally:
            self._estimates = {}

    def physics_weight(self) -> dict[str, float]:
        """Per target, the coefficient on the physics estimate (1: the physics' own scale; 0: not used)."""
        return {t: float(c[-1]) for t, (c, _) in self.coef.items()}


class PhysicsInformedBoostedNBM(PhysicsInformedNBM, BoostedNBM):
    """The boosted NBM with the physics estimate as one more feature (the module's docstring); a predictor."""

    name = "physics-informed boosted NBM"

    def physics_weight(self) -> dict[str, float]:
        """None: trees have no single coefficient on the physics estimate."""
        return {}
