"""A synthetic SCADA table of a fixed-ratio drive: 10-minute rows of input speed and torque under a varying load and
the ambient's daily swing (issue 45's month of rows for the benchmarks and the held paths' tests; not a named cycle:
no vehicle drives it). SYNTHETIC: the load is a slow swing over about three days with a random walk on it, the machine
stops below a tenth of its load range, the ambient swings 8 K about 12 degC with its maximum at 18:00.
"""

from __future__ import annotations

import math

import numpy as np

from firmware_model.units import RAD_S_PER_RPM

#: a SCADA system's row period [s]
SCADA_PERIOD_S = 600.0
#: the load below which the machine stands still (a wind turbine below cut-in) [-] (assumed)
STANDSTILL_LOAD = 0.08


def scada_rows(description, days: float, seed: int = 0, period_s: float = SCADA_PERIOD_S):
    """``days`` of rows ``period_s`` apart for the fixed-ratio ``description``, mapped onto the code's inputs
    (tools.drive_table.map_fixed_ratio): speed 48-80 % of the drive's maximum while running, torque up to 48 % of its
    maximum (load^1.5), the ambient 4-20 degC over each day."""
    from tools.drive_table import map_fixed_ratio
    from tools.runtable import RunTable

    n = max(2, int(round(days * 86400.0 / period_s)))
    t_s = period_s * np.arange(n)
    rng = np.random.default_rng(seed)
    walk = np.tanh(np.cumsum(rng.normal(0.0, 0.08, n)) / 3.0)
    load = np.clip(0.5 + 0.45 * np.sin(2.0 * math.pi * t_s / (3.1 * 86400.0)) + 0.2 * walk, 0.0, 1.0)
    running = load > STANDSTILL_LOAD
    v_max_rpm = description.drive.max_speed_rad_s / RAD_S_PER_RPM
    cols = {
        "time_s": t_s,
        "input_speed_rpm": np.where(running, 0.8 * v_max_rpm * (0.6 + 0.4 * load), 0.0),
        "input_torque_nm": np.where(running, 0.48 * description.drive.max_torque_nm * load**1.5, 0.0),
        "ambient_temp_c": 12.0 + 8.0 * np.sin(2.0 * math.pi * (t_s / 86400.0 - 0.5)),
    }
    return map_fixed_ratio(RunTable(cols, source=f"synthetic SCADA rows of {description.name}"), description)
