"""The reference plant runs any shipped description, not only the GRS905: R1 and HR225 (fixed-ratio reducers, splash,
no cooler) and MM82 (a wind turbine's planetary and two helical stages, a motor pump, an air cooler behind a
thermostat). A run table in the vehicle columns drives them: engine_speed_rpm is the input shaft's speed,
engine_torque_nm its torque, gear the description's one gear. Over hours of plausible load each gives finite
temperatures, its energy books close (losses = heat out + stored) and a constant load settles."""

from __future__ import annotations

import numpy as np
import pytest

from firmware_model.description import load_description
from firmware_model.parameters import load_parameters
from tools.plant.reference import ReferencePlant
from tools.runtable import RunTable

#: the books close to this share of the heat generated
LEDGER_REL = 1e-3
#: the plant's step for these hours-long runs: calibrate's default 2 s (the plant's own 0.5 s is for the vehicles' 10 Hz
#: loads; these loads move over minutes, and the books close by construction at any step)
PLANT_DT_S = 2.0


def _gear(name: str) -> int:
    (g,) = [g.number for g in load_description(name).gears if g.number != 0]
    return g


def _table(name: str, t_s, rpm, torque_nm, bc: dict) -> RunTable:
    cols = {
        "time_s": t_s,
        "engine_speed_rpm": rpm,
        "engine_torque_nm": torque_nm,
        "gear": np.full(t_s.size, _gear(name)),
    }
    cols.update({f"bc_{b}_c": np.broadcast_to(v, t_s.shape).astype(float) for b, v in bc.items()})
    return RunTable(cols)


def _varying(t_s, lo, hi, period_s, seed):
    """A load wandering between lo and hi: a slow sine with a random step every 10 minutes."""
    rng = np.random.default_rng(seed)
    block = (t_s // 600).astype(int)
    steps = rng.uniform(-0.25, 0.25, block[-1] + 1)[block]
    x = np.clip(0.5 + 0.4 * np.sin(2 * np.pi * t_s / period_s) + steps, 0.0, 1.0)
    return lo + (hi - lo) * x


def _node_temps(res) -> np.ndarray:
    return np.column_stack([np.asarray(res.table[f"T_{n}_c"]) for n in res.nodes])


def _check_books(res) -> None:
    T = _node_temps(res)
    assert np.all(np.isfinite(T)) and -40 < T.min() and T.max() < 200
    bal = res.energy_balance()
    assert bal["generated_j"] > 0 and bal["closure_rel"] < LEDGER_REL, bal


def _rate_k_per_h(res, last_s: float) -> float:
    """The largest rate of change of any node over the last ``last_s`` of the run [K/h]."""
    t = np.asarray(res.table["time_s"])
    T = _node_temps(res)
    i = np.searchsorted(t, t[-1] - last_s)
    return float(np.max(np.abs(T[-1] - T[i])) / (t[-1] - t[i]) * 3600.0)


#: (description, rpm range, torque range [N m], boundaries: {name: (lo, hi) degC}) of hours of plausible load
VARYING = {
    "R1": ((900.0, 1500.0), (100.0, 450.0), {"ambient": (15.0, 30.0)}),
    "HR225": ((1480.0, 1480.0), (300.0, 700.0), {"ambient": (15.0, 30.0)}),
    "MM82": ((5.0, 16.0), (0.2e6, 1.25e6), {"ambient": (5.0, 25.0)}),
}


@pytest.mark.parametrize("name", sorted(VARYING))
def test_hours_of_varying_load_give_finite_temperatures_and_closed_books(name):
    (r0, r1), (q0, q1), bcs = VARYING[name]
    t = np.arange(0.0, 6 * 3600.0 + 1, 10.0)
    x = _varying(t, 0.0, 1.0, 5400.0, 1)
    rpm, torque = r0 + (r1 - r0) * x, q0 + (q1 - q0) * x  # the torque follows the speed, as a wind turbine's
    bc = {b: lo + (hi - lo) * (0.5 + 0.5 * np.sin(2 * np.pi * t / 86400.0)) for b, (lo, hi) in bcs.items()}
    res = ReferencePlant(load_parameters(name), dt_s=PLANT_DT_S).run(_table(name, t, rpm, torque, bc), out_dt_s=60.0)
    _check_books(res)
    # a cold start under load warms: steadily over the first half hour, and by kelvins over the hour (the housings
    # face the run's air: the MM82's sump reaches its plateau for the load near the hour, where the load falls)
    T_oil = np.asarray(res.table["T_oil_c"])
    assert np.all(np.diff(T_oil[:30]) >= -1e-9) and T_oil[59] - T_oil[0] > 5.0


#: (description, rpm, torque [N m], boundaries [degC], hours) at a constant rated load
RATED = {
    "R1": (1450.0, 400.0, {"ambient": 25.0}, 14.0),
    "HR225": (1480.0, 700.0, {"ambient": 25.0}, 14.0),
    "MM82": (
        15.7,
        1.25e6,
        {b: 20.0 for b in ("hot_surroundings", "cold_surroundings", "ambient", "mainframe")},
        14.0,
    ),
}


@pytest.mark.parametrize("name", sorted(RATED))
def test_a_constant_load_settles_with_closed_books(name):
    rpm, torque, bc, hours = RATED[name]
    t = np.arange(0.0, hours * 3600.0 + 1, 60.0)
    tab = _table(name, t, np.full(t.size, rpm), np.full(t.size, torque), bc)
    res = ReferencePlant(load_parameters(name), dt_s=PLANT_DT_S).run(tab, out_dt_s=60.0)
    _check_books(res)
    assert _rate_k_per_h(res, 3600.0) < 0.5  # settled: no node moves half a kelvin in the last hour
    oil = np.asarray(res.table["T_oil_c"])[-1]
    assert max(bc.values()) + 5.0 < oil < 120.0  # the losses warm it, the housing (and cooler) hold it
