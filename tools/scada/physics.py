"""The physics model as a predictor of measured temperatures: the onboard sensor of a gearbox description with a few
of its effects (firmware_model.onboard.reduce.EFFECT_HOOKS) fitted on training records, scored like the NBM
(:mod:`tools.scada.holdout`; docs/real-data.md, "The physics model beside the NBM").

Each task fits the effects that move what it predicts, each with bounds that keep it physical:

- ``bearings`` (each bearing from the measured oil and the load): the bearings' own losses and the housing's
  convection to the nacelle air (how far the bearings sit above the oil, and how much the air pulls them down), and
  each bearing channel's reading offset (the catalog's thermocouple_offset, added to the estimate after the replay:
  the NBM's intercept);
- ``oil`` (the sump without any oil reading): the mesh friction, the cooler's effectiveness, the housing's
  convection and the thermostat's opening temperature.

The fit is a bounded Gauss-Newton least squares (tools/scada/gauss_newton.py: the sensitivities once, then two
confirmed steps) of estimate - measured over the training rows of every target, the sensor replayed over each
training record (one output row per SCADA row) for every evaluation; ``max_fit_rows`` caps the rows per
training record (its last rows: the most recent state of the turbine) to bound the time.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from firmware_model.effects import CATALOG
from tools.scada import gauss_newton
from tools.scada.nbm import Task
from tools.scada.reader import ScadaRecord


@dataclass(frozen=True)
class FitParam:
    """One fitted effect: its id, start (the catalog's neutral value), bounds (the catalog's plausible range) and
    the step of the finite differences (in its own unit)."""

    effect: str
    step: float

    @property
    def entry(self):
        """The catalog's entry (a channel's reading offset, ``thermocouple_offset:<channel>``: its base id's)."""
        return CATALOG[self.effect.split(":", 1)[0]]

    @property
    def start(self) -> float:
        return float(self.entry.neutral)

    @property
    def lo(self) -> float:
        return float(self.entry.low)

    @property
    def hi(self) -> float:
        return float(self.entry.high)


#: the reading offset of a measured channel (the catalog's thermocouple_offset, one per channel): added to the
#: estimate after the replay, as the diagnosis does (tools/scada/diagnose.py), not an effect of the sensor's
OFFSET = "thermocouple_offset"

#: the effects each task fits (ids of the effect catalog; scales are relative, offsets in K); the bearings' task also
#: fits each bearing channel's reading offset (the NBM's intercept, in the catalog's words: a thermocouple reading
#: a constant off)
FIT = {
    "bearings": (FitParam("bearing_loss_scale", 0.05), FitParam("housing_air_h_scale", 0.05)),
    "oil": (
        FitParam("gear_friction_scale", 0.05),
        FitParam("cooler_effectiveness_scale", 0.05),
        FitParam("housing_air_h_scale", 0.05),
        FitParam("thermostat_offset", 0.5),
    ),
}


#: an effect whose step moves no estimate of the training rows by this much is not identifiable there [K]
IDENTIFIABLE_K = 0.01


@dataclass
class PhysicsModel:
    """A predictor: ``fit(records)`` then ``predict(record)`` -> {channel: estimate} (NaN where it has none)."""

    task: Task
    config: object  # firmware_model.config.Config: the gearbox (the MM82 description), the sensor's settings
    max_fit_rows: int = 26_280  # half a year of 10-minute rows per training record
    effects: dict = field(default_factory=dict)
    report: dict = field(default_factory=dict)
    name: str = "physics"
    params: object = field(default=None, repr=False)
    fit_effects: bool = True  # False: fit() keeps ``effects`` (the sensor with its values, e.g. calibrated ones)

    @property
    def oil_mode(self) -> str:
        return "measured" if self.task.oil_input else "model"

    def _config(self):
        return self.config

    def _params(self):
        """The gearbox's parameters, read once (a read parses and checks its TOML files: ~1.5 s per replay else)."""
        if self.params is None:
            self.params = self._config().load_params()
        return self.params

    def _fit_params(self) -> tuple:
        """The task's effects (FIT), then a reading offset of each target channel the task measures with a
        thermocouple (the bearings' task: every target; the oil's: none, its sump's offset is the oil sensor's)."""
        offsets = tuple(FitParam(f"{OFFSET}:{ch}", 0.5) for ch in self.task.targets) if self.task.oil_input else ()
        return FIT[self.task.name] + offsets

    def _estimates(self, record: ScadaRecord, effects: dict) -> dict[str, np.ndarray]:
        from tools.scada.replay import ESTIMATES_ONLY, replay_record

        options = {**ESTIMATES_ONLY, "oil_mode": self.oil_mode}
        hooks = {k: v for k, v in effects.items() if not k.startswith(OFFSET + ":")}
        res = replay_record(record, self._config(), options, effects=hooks, params=self._params())
        return {
            ch: res.table[f"est_{ch}"] + effects.get(f"{OFFSET}:{ch}", 0.0)
            for ch in self.task.targets
            if res.table.has(f"est_{ch}")
        }

    def fit(self, records: Sequence[ScadaRecord]) -> PhysicsModel:
        """Fit the task's effects on ``records``: first which of them move the estimates at all (identifiability:
        one step of each from the neutral value; one that moves no estimate by IDENTIFIABLE_K stays neutral and is
        reported), then least squares over the others."""
        if not self.fit_effects:
            self.report = {"effects": dict(self.effects), "fitted": False}
            return self
        train = [r.select(np.arange(r.n) >= r.n - self.max_fit_rows) for r in records]
        all_params = self._fit_params()

        def residuals(eff: dict) -> np.ndarray:
            out = []
            for r in train:
                est = self._estimates(r, eff)
                for ch in self.task.targets:
                    if ch in est:
                        e = est[ch] - r.values[ch]
                        out.append(np.where(np.isfinite(e), e, 0.0))
            return np.concatenate(out)

        r0 = residuals({})
        moves, cols = {}, {}
        for p in all_params:
            step = p.step if p.start + p.step <= p.hi else -p.step
            r1 = residuals({p.effect: p.start + step})
            moves[p.effect] = float(np.max(np.abs(r1 - r0)))
            cols[p.effect] = (r1 - r0) / step
        params = [p for p in all_params if moves[p.effect] >= IDENTIFIABLE_K]
        self.effects, nfev, r_end = {}, len(all_params) + 1, r0
        if params:
            out = gauss_newton.fit(
                lambda x: residuals({p.effect: float(v) for p, v in zip(params, x)}),
                np.array([p.start for p in params]),
                np.array([p.lo for p in params]),
                np.array([p.hi for p in params]),
                np.array([p.step for p in params]),
                r0=r0,
                jac=np.stack([cols[p.effect] for p in params], axis=1),
            )
            self.effects = {p.effect: float(v) for p, v in zip(params, out["x"])}
            nfev, r_end = nfev + out["evaluations"], out["r"]
        cost = 0.5 * float(r_end @ r_end)
        self.report = {
            "effects": dict(self.effects),
            "not_identifiable": [e for e, m in moves.items() if m < IDENTIFIABLE_K],
            "largest_move_k": moves,
            "evaluations": nfev,
            "rows": sum(r.n for r in train),
            "rms_k": float(np.sqrt(2.0 * cost / max(r0.size, 1))),
        }
        return self

    def predict(self, record: ScadaRecord) -> dict[str, np.ndarray]:
        est = self._estimates(record, self.effects)
        return {ch: est.get(ch, np.full(record.n, np.nan)) for ch in self.task.targets}
