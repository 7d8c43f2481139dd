"""The oil cooler (seed section 3.4, Eq 82-83): the Eq 82/83 kernel against hand calculations, and the one cooler
model the plant and the onboard sensor share."""

import dataclasses

import numpy as np
import pytest

from firmware_model.errors import ParameterError
from firmware_model.onboard import evaluate as E
from firmware_model.onboard import reduce as R
from firmware_model.parameters import load_parameters
from firmware_model.physics import cooler as CO
from firmware_model.physics import oil as oilprops
from tools.plant.reference import ReferencePlant


def test_thermostat_and_eq82():
    np.testing.assert_allclose(
        CO.thermostat_fraction(np.array([60.0, 80.0, 90.0, 100.0, 120.0]), 80.0, 100.0), [0.0, 0.0, 0.5, 1.0, 1.0]
    )
    assert CO.thermostat_temperature_c(95.0, 4000.0, 0.5, 2000.0) == pytest.approx(91.0)
    assert CO.thermostat_temperature_c(95.0, 4000.0, 0.0, 2000.0) == pytest.approx(95.0)
    with pytest.raises(ParameterError):
        CO.thermostat_fraction(90.0, 100.0, 80.0)


ARGS = dict(mdot_kg_s=0.4, cp_j_per_kgk=2200.0, Q_max_cool_w=15e3, Q_max_heat_w=12e3, T_open_c=80.0, T_full_c=95.0)


def test_cooler_none_and_liquid():
    assert CO.cooler_heat_w("none", 400.0, 100.0, 20.0, **ARGS) == 0.0
    assert CO.cooler_heat_w("liquid", 400.0, 100.0, 80.0, **ARGS) == pytest.approx(8000.0)
    assert CO.cooler_heat_w("liquid", 400.0, 100.0, 20.0, **ARGS) == pytest.approx(15e3)  # cooling saturates
    assert CO.cooler_heat_w("liquid", 400.0, 50.0, 80.0, **ARGS) == pytest.approx(-12e3)  # heats, saturates
    assert CO.cooler_heat_w("liquid", 400.0, 70.0, 80.0, **ARGS) == pytest.approx(-4000.0)
    with pytest.raises(ParameterError):
        CO.cooler_heat_w("water", 400.0, 100.0, 20.0, **ARGS)


def test_cooler_air_cannot_heat_and_thermostat_closed():
    assert CO.cooler_heat_w("air", 400.0, 20.0, 30.0, **ARGS) == 0.0  # oil colder than air
    assert CO.cooler_heat_w("air", 400.0, 75.0, 20.0, **ARGS) == 0.0  # below T_open
    assert CO.cooler_heat_w("air", 400.0, 80.0, 20.0, **ARGS) == 0.0  # at T_open
    assert CO.cooler_heat_w("air", 1e4, 130.0, 20.0, **ARGS) == pytest.approx(15e3)  # saturated
    with pytest.raises(ParameterError):
        CO.cooler_heat_w("air", 400.0, 100.0, 20.0, **{**ARGS, "T_full_c": 80.0})


def test_cooler_air_hand_case():
    # T_oil 90, air 20, hA 100 -> a = 7000 W; C = 0.4 * 2200 = 880 W/K; ramp 80..95 (D = 15 K)
    # Q = a (90 - 80 - Q/C) / 15 -> Q = 7000 * 10 / (15 + 7000/880)
    Q = CO.cooler_heat_w("air", 100.0, 90.0, 20.0, **ARGS)
    assert Q == pytest.approx(70000.0 / (15.0 + 7000.0 / 880.0))
    s = (90.0 - Q / 880.0 - 80.0) / 15.0
    assert Q == pytest.approx(7000.0 * s)


def test_cooler_air_satisfies_eq82_eq83():
    rng = np.random.default_rng(3)
    n = 2000
    hA = rng.uniform(10.0, 3000.0, n)
    T_oil = rng.uniform(40.0, 140.0, n)
    T_air = rng.uniform(-20.0, 45.0, n)
    mdot = rng.uniform(0.01, 1.0, n)
    cp = 2200.0
    args = {**ARGS, "mdot_kg_s": mdot}
    Q = CO.cooler_heat_w("air", hA, T_oil, T_air, **args)
    assert Q.shape == (n,)
    assert np.all(Q >= 0.0) and np.all(Q <= ARGS["Q_max_cool_w"] + 1e-9)
    T_th = CO.thermostat_temperature_c(T_oil, Q, mdot, cp)
    rhs = hA * (T_oil - T_air) * CO.thermostat_fraction(T_th, ARGS["T_open_c"], ARGS["T_full_c"])
    sat = Q >= ARGS["Q_max_cool_w"] - 1e-9
    np.testing.assert_allclose(Q[~sat], np.maximum(rhs[~sat], 0.0), rtol=1e-9, atol=1e-6)
    assert np.all(rhs[sat] >= ARGS["Q_max_cool_w"] - 1e-6)
    assert sat.any() and (~sat & (Q > 0)).any() and (Q == 0).any()


def test_a_thermostat_at_the_sump_reads_the_oil_before_the_cooler():
    # hand case of test_cooler_air_hand_case, the thermostat at the sump: Q = a (90 - 80) / 15, no Q / C coupling
    Q = CO.cooler_heat_w("air", 100.0, 90.0, 20.0, **ARGS, thermostat_sump=1.0)
    assert Q == pytest.approx(7000.0 * 10.0 / 15.0)
    assert Q > CO.cooler_heat_w("air", 100.0, 90.0, 20.0, **ARGS)  # the return lies below the sump: less opening
    # the same bounds: closed at T_open, the whole hA dT above T_full, the rating above that
    assert CO.cooler_heat_w("air", 100.0, 80.0, 20.0, **ARGS, thermostat_sump=1.0) == 0.0
    assert CO.cooler_heat_w("air", 100.0, 96.0, 20.0, **ARGS, thermostat_sump=1.0) == pytest.approx(7600.0)
    assert CO.cooler_heat_w("air", 1e4, 96.0, 20.0, **ARGS, thermostat_sump=1.0) == pytest.approx(15e3)


def test_the_stability_bound_takes_the_cooler_as_a_conductance_at_either_thermostat():
    """The proof's cooler bound: Q = hA x (T_oil - T_air) with the opening 0 <= x <= 1, a conductance of at most hA
    between the sump and the air, wherever the thermostat reads the oil (the opening is a coefficient, as the oil-
    dependent conductances are: docs/sensor.md, "Stability proof"); over oil and air, Q / (T_oil - T_air) stays
    under it, and reaches hA with the valve open below the cooler's rating."""
    c = CO.CoolerParams(0, 0, 0, 1400.0, 6e4, 55.0, 60.0, 1.0, 1.0, 0.5, 0.3, 1.0, 1.0)
    bound = CO.cooler_hA_bound_w_per_k(c, "air", 1.0, 1.0, 1.0, motor_pump=True)
    assert bound == CO.cooler_hA_bound_w_per_k(c._replace(thermostat_sump=0.0), "air", 1.0, 1.0, 1.0, motor_pump=True)
    T = np.linspace(40.0, 150.0, 2201)
    for sump in (1.0, 0.0):
        for T_air in (-40.0, 0.0, 30.0):
            Q = CO.cooler_heat_w("air", 1400.0, T, T_air, 1.0, 2000.0, 6e4, 0.0, 55.0, 60.0, thermostat_sump=sump)
            G = Q / (T - T_air)
            assert np.all(G <= bound * (1 + 1e-12))
            if sump and T_air == 30.0:  # open below the rating: the whole hA
                assert np.max(G) == pytest.approx(1400.0)


def test_a_measured_sump_s_balance_gives_the_cooler_what_the_sump_does_not_keep():
    """measured_cooler = "balance" (physics.cooler.measured_balance_heat_w): the sump gains H and gets back the jets'
    share s of the cooler's net heat Q, so Q = H / (1 - s); the cooler itself between a shut bypass and its fully
    open valve hA (T_oil - T_air) (at most Q_max_cool); the heater's heat added before those bounds, taken off after;
    a share near 1 divided as BALANCE_KEEP_MIN, never by 0."""
    c = CO.CoolerParams(0, 0, 0, 1400.0, 6e4, 55.0, 60.0, 1.0, 1.0, 0.5, 0.3, 1.0, 1.0, 3000.0, 20.0, 5.0, 1.0)
    Q = CO.measured_balance_heat_w(c, np.array([1e4, -5e3, 1e5]), 0.5, 1400.0, 58.0, 20.0)
    np.testing.assert_allclose(Q, [2e4, 0.0, 1400.0 * 38.0])
    assert CO.measured_balance_heat_w(c, 1e4, 0.5, 1400.0, 15.0, 20.0) == pytest.approx(-3000.0)  # heater on, no Q
    assert CO.measured_balance_heat_w(c, 1e4, 0.5, 1400.0, 15.0, 10.0) == pytest.approx(1400.0 * 5.0 - 3000.0)
    assert CO.measured_balance_heat_w(c, 1e4, 0.5, 5000.0, 58.0, 20.0) == pytest.approx(2e4)
    assert CO.measured_balance_heat_w(c, 1e4, 0.5, 1e4, 58.0, 20.0) == pytest.approx(2e4)
    assert CO.measured_balance_heat_w(c, 1e4, 0.5, 1e5, 100.0, 20.0) == pytest.approx(2e4)
    assert CO.measured_balance_heat_w(c, 1e5, 0.5, 1e5, 100.0, 20.0) == pytest.approx(6e4)  # at Q_max_cool
    assert CO.measured_balance_heat_w(c, 100.0, 1.2, 1e5, 58.0, 20.0) == pytest.approx(100.0 / CO.BALANCE_KEEP_MIN)


@pytest.fixture(scope="module")
def models():
    """(parameters, onboard model) of the default gearbox."""
    p = load_parameters("GRS905")
    return p, R.build_reduced(p)


@pytest.mark.parametrize("kind", ["liquid", "air"])
def test_plant_and_onboard_use_the_same_cooler(models, kind):
    """The plant (mass flows, exact oil properties) and the onboard model (layshaft speed, the same rho cp) give the
    same heat at the same operating point, up to the last bits of the flow ratio."""
    params, rp = models
    plant = ReferencePlant(params, cooler=kind)
    rpk = dataclasses.replace(rp, cooler_code=E.COOLER_CODES[kind])
    rng = np.random.default_rng(4)
    for _ in range(200):
        T, w_ls, w_eng = rng.uniform(40, 140), rng.uniform(1, 200), rng.uniform(0, 250)
        T_cool, T_amb, v = rng.uniform(60, 95), rng.uniform(-10, 40), rng.uniform(0, 130)
        op = oilprops.oil_properties(T)
        q_plant, _ = plant.cooler_heat(T, w_ls, w_eng, T_cool, T_amb, v)
        q_onboard, _, _ = E.cooler_heat(rpk, T, w_ls, w_eng, T_cool, T_amb, v, op.rho_kg_m3 * op.cp_j_per_kgk)
        assert float(q_onboard) == pytest.approx(q_plant, rel=1e-12, abs=1e-9)


def test_air_cooler_sees_recirculated_air():
    assert CO.air_temperature_c(25.0, 15.0) == pytest.approx(34.0)  # +9 K at 15 km/h (seed 3.4)
    assert CO.air_temperature_c(25.0, 50.0) == pytest.approx(27.0)
    assert CO.air_temperature_c(25.0, -5.0) == pytest.approx(37.0)  # standstill: the table's first row
    assert CO.air_temperature_c(25.0, 300.0) == pytest.approx(25.0)


def test_no_oil_flow_no_heat_and_the_inlet_drop_is_clipped(models):
    c = CO.cooler_params(CO.cooler_values(models[0]))
    for kind in CO.COOLER_KINDS:
        q = CO.oil_cooler_heat(c, kind, 110.0, 0.0, 150.0, 80.0, 25.0, 50.0, 0.0)
        assert float(q.Q_w) == 0.0
    assert float(CO.inlet_drop_k(3000.0, 100.0)) == 30.0 == CO.INLET_DROP_MAX_K
    assert float(CO.inlet_drop_k(-3000.0, 100.0)) == -30.0
    assert float(CO.inlet_drop_k(500.0, 100.0)) == 5.0
    assert float(CO.inlet_drop_k(500.0, 0.0)) == 0.0


def test_liquid_cooler_hA_follows_its_flows(models):
    c = CO.cooler_params(CO.cooler_values(models[0]))
    ref = CO.cooler_hA_w_per_k(c, "liquid", 1.0, c.ref_engine_speed_rad_s, 50.0)
    assert ref == pytest.approx(c.liquid_hA_ref_w_per_k)
    assert CO.cooler_hA_w_per_k(c, "liquid", 4.0, c.ref_engine_speed_rad_s, 50.0) == pytest.approx(
        ref * 4.0**c.exp_inner
    )
    assert CO.cooler_hA_bound_w_per_k(c, "air", 2 * c.ref_ls_speed_rad_s, 0.0, 1.2) >= CO.cooler_hA_w_per_k(
        c, "air", 2.0, 0.0, 1e3, 1.2
    )
