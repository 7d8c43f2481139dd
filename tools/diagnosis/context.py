"""What every stage of one diagnosis shares: the model under diagnosis and its re-simulations (counted and timed),
the parameters, the options, the cooler kind and the candidate effects."""

from __future__ import annotations

import time
from dataclasses import dataclass

from tools.diagnosis.options import Options


class Simulator:
    """The model's re-simulations of the measured files, counted (simulations = runs x files) and timed."""

    def __init__(self, model):
        self.model = model
        self.n_sims = 0
        self.simulate_s = 0.0

    def run(self, datasets: list, runs: list) -> list:
        """Per run, per dataset: the model outputs with the columns the datasets' channels need."""
        cols = sorted({ch.model_column for ds in datasets for ch in ds.channels.values()})
        t0 = time.perf_counter()
        out = self.model.simulate(datasets, runs, cols)
        self.n_sims += len(runs) * len(datasets)
        self.simulate_s += time.perf_counter() - t0
        return out

    def count(self, n: int) -> None:
        """Count `n` simulations made outside :meth:`run` (the fallback model's)."""
        self.n_sims += n


@dataclass(frozen=True)
class Context:
    model: object  # the model under diagnosis (tools.diagnosis.models)
    params: object  # the gearbox parameters
    opts: Options
    cooler: str
    candidates: tuple  # effect ids to fit
    sim: Simulator

    @property
    def is_plant(self) -> bool:
        return self.model.name == "plant"

    def backend_of(self, eid: str) -> str:
        """Which model fitted effect `eid` (the onboard model delegates what it cannot represent to the plant)."""
        delegated = getattr(self.model, "delegated", [])
        if self.model.name == "onboard" and eid in delegated:
            return "plant (fallback)"
        return self.model.name
