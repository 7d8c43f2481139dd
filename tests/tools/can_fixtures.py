"""Shared by the CAN tool tests: a made-up plant output for a drive cycle (the sump and every published
component warming linearly), enough for the TRF1 and RIG_TC_* frames of a synthesized log."""

from __future__ import annotations

import numpy as np

from firmware_model.components import PUBLISHED
from tools.runtable import RunTable


def plant_output(
    inputs,
    *,
    start_s: float | None = None,
    step_s: float = 1.0,
    oil0_c: float = 70.0,
    oil_rate_k_s: float = 0.1,
    T0_c: float = 60.0,
    T_rate_k_s: float = 0.5,
) -> RunTable:
    """``oil_temp_c`` = oil0_c + oil_rate_k_s x t and ``T_<id>_c`` = T0_c + i + T_rate_k_s x t (i: the published
    index), every ``step_s`` from ``start_s`` (None: the cycle's first time) to past the cycle's end."""
    t0_s = inputs["time_s"][0] if start_s is None else start_s
    t_s = np.arange(t0_s, inputs["time_s"][-1] + step_s / 2, step_s)
    cols = {"time_s": t_s, "oil_temp_c": oil0_c + oil_rate_k_s * t_s}
    for i, c in enumerate(PUBLISHED):
        cols[f"T_{c}_c"] = T0_c + i + T_rate_k_s * t_s
    return RunTable(cols)
