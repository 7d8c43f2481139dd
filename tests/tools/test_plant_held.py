"""The reference plant's held path (tools/plant/held.py): a fixed-ratio drive's 10-minute rows integrated in long
exact steps agree with the 0.5 s BDF2 steps, and the energy ledger closes (issue 45)."""

from __future__ import annotations

import numpy as np
import pytest

from firmware_model.description import description_of
from firmware_model.parameters import load_parameters
from tools.cycles.scada_rows import scada_rows
from tools.plant.reference import ReferencePlant

#: the held path's bound against the step path at the row times, every node [K]: measured over two days of 10-minute
#: rows (bench_held_month.py) 0.038 K on the HR225, 0.027 K on the R1, 0.058 K on the MM82 while its thermostat read
#: the return (a planet, 50 K above the sump: 0.1 % of its rise); the step path's own step error (0.5 s against
#: 0.1 s) is 0.011 K on the HR225. The MM82's thermostat reads the sump since 2026-12-05: the jets' oil, the sump minus
#: the cooler's drop, moves ~9 K for a kelvin of sump in the valve's band, and on this test's 6 hours the 0.5 s step
#: path itself errs by 0.080 K (P2, against 0.1 s), the held path by 0.068 K (PS): 0.087 K apart (P2); with the
#: seats HB and the bearing factors of 2026-12-06: 0.076 K apart (P2; the step path's own 0.078 K against 0.1 s)
HELD_BOUND_K = {"HR225": 0.06, "MM82": 0.09}
#: the ledger: generated = stored + rejected, and the held path's books against the step path's, share of generated
LEDGER_CLOSURE = 1e-9
LEDGER_VS_STEP = 1e-3


@pytest.fixture(scope="module", params=[("HR225", 0.5), ("MM82", 0.25)], ids=["HR225-12h", "MM82-6h"])
def both_paths(request):
    name, days = request.param
    params = load_parameters(name)
    table = scada_rows(description_of(params), days)
    held = ReferencePlant(params).run(table, out_dt_s=600.0, progress=False)
    step = ReferencePlant(params).run(table, out_dt_s=600.0, progress=False, held=False)
    return name, table, held, step


def test_a_table_of_slow_rows_takes_the_held_path_in_far_fewer_solves(both_paths):
    _, table, held, step = both_paths
    assert "held_sub_intervals" in held.table.meta and "held_sub_intervals" not in step.table.meta
    assert held.table.meta["held_sub_intervals"] < 10 * table.n  # a cold start halves; the step path: 1 200 a row
    np.testing.assert_array_equal(held.table["time_s"], step.table["time_s"])  # one output row per input row


def test_the_held_path_agrees_with_the_step_path_at_every_node(both_paths):
    name, _, held, step = both_paths
    nodes = [c for c in step.table.columns if c.startswith("T_") and c.endswith("_c")]
    err = {c: float(np.max(np.abs(held.table[c] - step.table[c]))) for c in nodes}
    assert max(err.values()) <= HELD_BOUND_K[name], f"{name}: {sorted(err.items(), key=lambda kv: -kv[1])[:4]}"
    oil = step.table["T_oil_c"]
    assert np.ptp(oil) > 20.0  # a warm-up: the sump moved, the losses with it
    if name == "MM82":  # into its thermostat's band (57.1-60 degC) inside row intervals, and held on the valve's ramp
        params = load_parameters(name)
        t_open, t_full = params.values["cooler.thermostat_open"], params.values["cooler.thermostat_full"]
        # the thermostat reads the sump: from under its opening into the band, held there over the last hour (the
        # sump 57.9-58.0 degC; its rise over the opening no margin, 0.95 K in the VG 320, 1.01 K in the seed's oil)
        assert oil.min() < t_open < np.min(oil[-6:]) and oil.max() < t_full


def test_the_ledger_closes_and_books_what_the_step_path_books(both_paths):
    _, _, held, step = both_paths
    eh, es = held.energy_balance(), step.energy_balance()
    assert eh["closure_rel"] <= LEDGER_CLOSURE
    for key in ("generated_j", "stored_j", "rejected_j", "mechanical_loss_j", "cooler_j", "housing_convection_j"):
        assert abs(eh[key] - es[key]) <= LEDGER_VS_STEP * es["generated_j"], key
    # the Q_ columns: per row, the heat generated is stored or leaves (interval averages)
    q = held.table
    out = sum(q[c] for c in q.columns if c.startswith("Q_out_"))
    np.testing.assert_allclose(
        (q["Q_heat_total_w"] - out - q["Q_stored_w"])[1:], 0.0, atol=1e-6 * q["Q_heat_total_w"].max()
    )


def test_a_10_hz_table_keeps_the_step_path():
    params = load_parameters("HR225")
    table = scada_rows(description_of(params), 0.01, period_s=0.1)
    res = ReferencePlant(params).run(table, progress=False)
    assert "held_sub_intervals" not in res.table.meta
