"""The onboard network: derived from the full one (aggregation, laws, loss maps), explicit step, stability proof."""

import dataclasses
import math

import numpy as np
import pytest

from firmware_model.components import PUBLISHED
from firmware_model.effects import CATALOG, EFFECT_IDS, FIELD_OF_EFFECT, EffectScales, effect_scales
from firmware_model.errors import ParameterError, StabilityError
from firmware_model.network import BOUNDARIES, ConductanceEvaluator, build_network
from firmware_model.onboard import evaluate as E
from firmware_model.onboard import reduce as R
from firmware_model.onboard import stability as S
from firmware_model.parameters import load_parameters
from firmware_model.physics.conductance_matrix import boundary_heat_w, conductance_matrix, node_conductance_w_per_k
from firmware_model.physics.gearbox_losses import GearboxLosses
from firmware_model.physics.kinematics import GEAR_MIN
from firmware_model.units import RAD_S_PER_RPM


@pytest.fixture(scope="module")
def params():
    return load_parameters("GRS905")


@pytest.fixture(scope="module")
def rp(params):
    return R.build_reduced(params)


@pytest.fixture(scope="module")
def full(params):
    net = build_network(params)
    return net, ConductanceEvaluator(net, params), GearboxLosses(params, net.geometry)


def _link_matrix(net, agg):
    M = np.zeros((len(agg.link_a), len(net.link_a)))
    for k, r in enumerate(agg.link_of_full):
        if r >= 0:
            M[r, k] = 1.0
    return M


# ---- the explicit step on a single RC node (hand calculation)


@pytest.mark.parametrize("scatter", ["index", "incidence"])
def test_single_rc_node_follows_its_exponential(scatter):
    """C dT/dt = G (T_b - T) + q: forward Euler at dt = 0.1 s against T_inf + (T0 - T_inf) exp(-t G / C)."""
    C, G, Tb, q, T0, dt = 2000.0, 40.0, 20.0, 800.0, 80.0, 0.1  # tau = 50 s, T_inf = 40 degC
    tau, T_inf = C / G, Tb + q / G
    kw = {}
    if scatter == "incidence":
        kw = dict(B_int=np.zeros((0, 1)), B_ext=np.array([[-1.0]]))
    T = np.array([T0])
    worst = 0.0
    for k in range(1, 5001):  # 10 time constants
        T = E.explicit_step(
            T,
            np.array([q]),
            np.zeros(0),
            np.array([G]),
            np.array([Tb]),
            np.zeros(0, int),
            np.zeros(0, int),
            np.array([0]),
            np.array([0]),
            np.array([dt / C]),
            **kw,
        )
        exact = T_inf + (T0 - T_inf) * math.exp(-k * dt / tau)
        worst = max(worst, abs(T[0] - exact))
    # Euler's global error for a decaying exponential is below dt / (2 tau) x e^-1 x |T0 - T_inf|
    assert worst <= dt / (2 * tau) * math.exp(-1) * abs(T0 - T_inf) * 1.01
    # the equilibrium is exact: a node at T_inf stays there
    T = E.explicit_step(
        np.array([T_inf]),
        np.array([q]),
        np.zeros(0),
        np.array([G]),
        np.array([Tb]),
        np.zeros(0, int),
        np.zeros(0, int),
        np.array([0]),
        np.array([0]),
        np.array([dt / C]),
        **kw,
    )
    assert T[0] == pytest.approx(T_inf, abs=1e-12)


def test_two_node_exchange_conserves_heat():
    T = np.array([[100.0, 20.0]])
    C = np.array([500.0, 1500.0])
    for _ in range(20000):
        T = E.explicit_step(
            T,
            np.zeros((1, 2)),
            np.array([[5.0]]),
            np.zeros((1, 0)),
            np.zeros((1, 1)),
            np.array([0]),
            np.array([1]),
            np.zeros(0, int),
            np.zeros(0, int),
            0.1 / C,
        )
    assert float(C @ T[0]) == pytest.approx(500 * 100 + 1500 * 20, rel=1e-12)
    assert T[0, 0] == pytest.approx(40.0, abs=1e-3) and T[0, 1] == pytest.approx(40.0, abs=1e-3)


# ---- stability


def test_stability_is_proven_for_the_default_parameters(rp):
    st = rp.stability
    assert rp.dt_s == 0.1 and st["margin"] == S.STABILITY_MARGIN
    assert np.all(st["dt_max_s"] >= rp.dt_s)
    assert st["limiting_node"] in rp.nodes and st["tau_min_s"] > 0


def test_stability_check_refuses_a_too_light_node(params):
    light = params.with_overrides({"wheel_bearing.mass_needle": 0.002})  # a 2 g needle bearing: C ~ 1 J/K
    with pytest.raises(StabilityError) as exc:
        R.build_reduced(light)
    msg = str(exc.value)
    assert "node LB" in msg or "node 2B" in msg or "node 1B" in msg
    assert "J/K" in msg and "W/K" in msg and "margin 0.8" in msg and "dt = 0.1 s" in msg


def test_stability_margin_and_dt_are_checked(params):
    with pytest.raises(StabilityError):
        R.build_reduced(params, dt_s=1.0)  # the CL wheel cannot take 1 s
    with pytest.raises(ParameterError):
        R.build_reduced(params, margin=1.5)


def test_stability_bound_covers_the_operating_range(rp):
    """The proven bound is above every node's actual sum of conductances at random operating points."""
    h = rp.helpers
    G_max = S.max_conductances(rp)["G"]
    rng = np.random.default_rng(7)
    bc = np.array(rp.bc_default_c)
    for _ in range(400):
        row = int(rng.integers(0, 17))
        w = rng.uniform(0, rp.max_speed_rpm) * RAD_S_PER_RPM
        T = rng.uniform(*S.OIL_RANGE_C)
        x, prop, phi = E.oil_row(rp, T, h)
        G, _ = E.conductances(rp, row, w, x, prop, phi, np.full(rp.n, T), bc, None, h)
        assert np.all(G <= G_max * (1 + 1e-9) + 1e-12), rp.link_name[int(np.argmax(G - G_max))]


# ---- derived from the full network


def test_fine_partition_keeps_every_node_and_the_total_heat_capacity(rp, full):
    net = full[0]
    assert rp.nodes == net.nodes and rp.partition == "fine"
    assert float(np.sum(rp.C_j_per_k)) == pytest.approx(float(np.sum(net.C_j_per_k)), rel=1e-12)
    assert [rp.nodes[i] for i in rp.published_index] == list(PUBLISHED)


def test_compact_partition_is_an_aggregation(params, full):
    net = full[0]
    agg = R.aggregate(net, R.PARTITIONS["compact"](net.geometry.description))
    assert len(agg.nodes) <= 41 and all(c in agg.nodes for c in PUBLISHED)
    assert float(agg.C.sum()) == pytest.approx(float(net.C_j_per_k.sum()), rel=1e-12)
    assert agg.C[agg.nodes.index("MS")] == pytest.approx(
        sum(net.C_j_per_k[net.index(s)] for s in net.nodes if s.startswith("MS@")), rel=1e-12
    )
    # links inside a group vanish; a link between groups is the sum of its members
    for k, r in enumerate(agg.link_of_full):
        a = agg.node_of_full[net.link_a[k]]
        b = net.link_b[k]
        if b < net.n and agg.node_of_full[b] == a:
            assert r == -1
    rpc = R.build_reduced(params, partition="compact")
    ev = full[1]
    kin = params.kinematics
    M = _link_matrix(net, agg)
    for g, rpm, T in ((9, 1300, 90.0), (3, 2000, 60.0), (14, 900, 110.0)):
        row = g - GEAR_MIN
        sp = np.abs(kin.speed[row] * rpm * RAD_S_PER_RPM)
        Gf = ev.evaluate(
            T, sp, row, kin.mesh_torque[row], bool(kin.low_range[row]), np.full(net.n, T), rpc.bc_default_c
        )
        x, prop, phi = E.oil_row(rpc, T)
        G, _ = E.conductances(rpc, row, rpm * RAD_S_PER_RPM, x, prop, phi, np.full(rpc.n, T), rpc.bc_default_c)
        ref = M @ Gf
        big = ref > 0.5
        assert np.max(np.abs(G[big] - ref[big]) / ref[big]) < 0.05


def test_conductance_laws_match_the_full_evaluator(rp, full):
    net, ev, _ = full
    kin = load_parameters("GRS905").kinematics
    M = _link_matrix(net, R.aggregate(net, {}))
    rng = np.random.default_rng(11)
    h = rp.helpers
    errs = []
    for _ in range(600):
        g = int(rng.integers(-2, 15))
        row = g - GEAR_MIN
        rpm = rng.uniform(0, 4000)
        T = rng.uniform(-40, 150)
        sp = np.abs(kin.speed[row] * rpm * RAD_S_PER_RPM)
        Tn = np.full(net.n, T + 3.0)
        Gf = M @ ev.evaluate(T, sp, row, kin.mesh_torque[row], bool(kin.low_range[row]), Tn, rp.bc_default_c)
        x, prop, phi = E.oil_row(rp, T, h)
        G, _ = E.conductances(
            rp, row, rpm * RAD_S_PER_RPM, x, prop, phi, np.full(rp.n, T + 3.0), rp.bc_default_c, None, h
        )
        big = Gf > 0.5  # below 0.5 W/K: links of a shaft at (nearly) standstill
        errs.append(np.abs(G[big] - Gf[big]) / Gf[big])
    e = np.concatenate(errs)
    assert np.percentile(e, 99) < 0.01
    assert e.max() < 0.06  # the ring's splash/housing kink inside one table cell


def test_power_laws_are_exact_where_the_physics_is_separable(rp):
    # splash (Eq 59) exponent 0.6, Harris and immersed bearings (Eq 52, 63) 0.5, constants 0
    assert set(np.round(rp.pw_exp, 6)) <= {0.0, 0.5, 0.6}
    assert {rp.link_name[i] for i in rp.cyl_link} == {f"{w}-oil" for w in ("LL", "3L", "2L", "1L", "CL", "RL", "RI")}


@pytest.mark.parametrize("T_range", [(20.0, 40.0), (40.0, 150.0)])
def test_loss_maps_match_gearbox_losses(rp, full, T_range):
    _, _, gl = full
    rng = np.random.default_rng(5)
    h = rp.helpers
    tol_mesh = 0.003 if T_range[0] < 40 else 0.001
    for _ in range(300):
        g = int(rng.integers(-2, 15))
        rpm = rng.uniform(300, 4000)
        tq = rng.uniform(-1000, 4200)
        T = rng.uniform(*T_range)
        ref = gl.heat(gl.evaluate(rpm * RAD_S_PER_RPM, tq, g, T))
        x, prop, phi = E.oil_row(rp, T, h)
        Q = E.heat_sources(rp, g - GEAR_MIN, rpm * RAD_S_PER_RPM, abs(tq), prop, x, h=h)
        meshes = [float(ref[f"mesh:{m}"][0]) for m in ("L", "3", "2", "1", "C", "R", "RI")]
        assert np.allclose(Q[:7], meshes, rtol=tol_mesh, atol=0.05)
        assert Q[7] + Q[8] == pytest.approx(float(ref["planetary"][0]), rel=tol_mesh, abs=0.05)
        bearings = [float(ref[f"bearing:{b}"][0]) for b in ("BIF", "BLF", "BLR", "BIM", "BMR", "BO")]
        assert np.allclose(Q[9:15], bearings, rtol=0.003, atol=0.05)
        oil = sum(float(ref[k][0]) for k in ("churning", "wheel_bearings", "synchronizers", "pump"))
        assert Q[R.I_SRC_OIL] == pytest.approx(oil, rel=0.07, abs=1.0)  # churning regime jumps (Eq 28-32)


def test_footprint_fits_an_ecu(rp):
    fp = rp.footprint(np.float32)
    assert fp["bytes"] <= 64 * 1024


def test_effects_record_validates_and_broadcasts():
    e = R.make_effects({"gear_friction_scale": [1.0, 1.3], "retarder_heat": 0.05})
    assert e.src_scale.shape == (2, R.N_SRC) and e.src_scale[1, 0] == 1.3 and e.retarder_frac == 0.05
    with pytest.raises(ParameterError):
        R.make_effects({"gear_friction_scale": 9.0})
    with pytest.raises(ParameterError):
        R.make_effects({"oil_sensor_lag": 10.0})


def test_one_effect_record_for_plant_and_onboard_model():
    """Every catalogued effect has its field in the one record; neutral values change nothing; the onboard model's
    record is the same type, with its per-source scales."""
    assert set(FIELD_OF_EFFECT) == set(EFFECT_IDS)  # the channel effects act on a rig's readings only
    assert set(FIELD_OF_EFFECT.values()) <= {f.name for f in dataclasses.fields(EffectScales)}
    neutral = effect_scales(None)
    assert all(getattr(neutral, f) == CATALOG[eid].neutral for eid, f in FIELD_OF_EFFECT.items())
    assert effect_scales({"churning_scale": 1.4}).churn_scale == 1.4
    e = R.make_effects({"bearing_loss_scale": [1.0, 2.0]})
    assert isinstance(e, EffectScales) and R.Effects is EffectScales
    np.testing.assert_array_equal(e.needle_scale, [1.0, 2.0])
    np.testing.assert_array_equal(e.src_scale[:, R.I_SRC_BEARING], [1.0, 2.0])


def test_conductance_matrix_is_the_network_laplacian(rp):
    """K of physics.conductance_matrix: symmetric, K 1 = the boundary links at each node, its diagonal the total
    conductance at each node (what the stability bound sums), and the plant's implicit matrix adds a0 C / h."""
    h = rp.helpers
    G = np.random.default_rng(2).uniform(0.1, 10.0, len(rp.link_a))
    K, Ge = conductance_matrix(G, h.topology)
    np.testing.assert_allclose(K, K.T, rtol=0, atol=0)
    np.testing.assert_allclose(K @ np.ones(rp.n), np.bincount(h.ea, Ge, minlength=rp.n), atol=1e-12)
    np.testing.assert_allclose(np.diag(K), node_conductance_w_per_k(G, h.topology), rtol=1e-14)
    extra = np.full(rp.n, 5.0)
    np.testing.assert_allclose(conductance_matrix(G, h.topology, extra).K_w_per_k, K + np.diag(extra), rtol=1e-14)
    T = np.random.default_rng(3).uniform(20, 100, rp.n)
    T_bc = np.asarray(rp.bc_default_c, dtype=float)
    rate = (
        E.explicit_step(T, np.zeros(rp.n), G[h.int_idx], G[h.ext_idx], T_bc, h.ia, h.ib, h.ea, h.eb, np.ones(rp.n)) - T
    )
    np.testing.assert_allclose(rate, -K @ T + boundary_heat_w(Ge, h.topology, T_bc), atol=1e-9)


def test_radiation_and_boundaries_are_those_of_the_plant(rp):
    assert len(rp.bc_default_c) == len(BOUNDARIES)
    h = rp.helpers
    g = E.radiation_conductances(rp, np.full(rp.n, 80.0), np.asarray(rp.bc_default_c), h)
    assert np.all(g > 0) and len(g) == 6


@pytest.mark.parametrize("low_range", [False, True])
def test_batched_evaluate_is_one_call_per_point_bit_for_bit(params, low_range):
    """ConductanceEvaluator.evaluate on a batch of speeds (the onboard build's law grid) returns exactly what one
    call per operating point returns: the same numpy loops on the same numbers, the oil properties scalars."""
    net = build_network(params)
    ev = ConductanceEvaluator(net, params, EffectScales(teeth_oil_h=1.3, planet_oil_h=0.7, housing_air_h=1.2))
    kin = params.kinematics
    rng = np.random.default_rng(5)
    row = int(np.flatnonzero(kin.low_range == low_range)[0])
    sp = np.abs(kin.speed[row]) * rng.uniform(0.0, 300.0, (40, 1))
    sp[:3] = 0.0  # standstill (speed floors, no oil flow)
    sp[3] = rng.uniform(0.0, 300.0, sp.shape[1])  # shafts at unrelated speeds
    Tn, Tbc = np.full(net.n, 70.0), np.full(len(BOUNDARIES), 35.0)
    for T in (-40.0, 23.7, 95.0, 180.0):
        batch = ev.evaluate(T, sp, row, kin.mesh_torque[row], low_range, Tn, Tbc)
        assert batch.shape == (len(sp), len(net.link_a))
        for k in range(len(sp)):
            one = ev.evaluate(T, sp[k], row, kin.mesh_torque[row], low_range, Tn, Tbc)
            assert np.array_equal(batch[k], one), (T, k)


def test_law_grid_batched_equals_one_evaluation_per_point(params):
    """The build tabulates its laws in batches; the tables are those of one evaluator call per grid point, bit for
    bit (so the ReducedParams, the kernel tables and the golden outputs do not move)."""
    net = build_network(params)
    fast, ref = R.law_grid(net, params), R.law_grid(net, params, batched=False)
    assert sorted(fast.tables) == sorted(ref.tables)
    for s in ref.tables:
        assert np.array_equal(fast.tables[s], ref.tables[s]), s
    assert np.array_equal(fast.G_ring_low, ref.G_ring_low)


@pytest.mark.parametrize("tq", [1e-30, 0.05, 0.2, 1.0, 3.0, 8.0, 30.0])
def test_loss_maps_match_gearbox_losses_at_tiny_torques(rp, full, tq):
    """The rolling loss's ramp below its least film torque (losses.ROLL_TORQUE_MIN_NM per contact: applied to the
    sun's total torque over 5 planets instead of per planet, as the plant does, the reduction gives PSP 70 W against
    57 W) and the slip table's low end, plant against reduction, every mesh."""
    _, _, gl = full
    h = rp.helpers
    for g in (-1, 1, 5, 8, 12, 14):
        for rpm in (600.0, 1400.0, 2200.0):
            ref = gl.heat(gl.evaluate(rpm * RAD_S_PER_RPM, tq, g, 80.0))
            x, prop, phi = E.oil_row(rp, 80.0, h)
            Q = E.heat_sources(rp, g - GEAR_MIN, rpm * RAD_S_PER_RPM, tq, prop, x, h=h)
            meshes = [float(ref[f"mesh:{m}"][0]) for m in ("L", "3", "2", "1", "C", "R", "RI")]
            assert np.allclose(Q[:7], meshes, rtol=0.003, atol=0.05), (g, rpm)
            assert Q[7] + Q[8] == pytest.approx(float(ref["planetary"][0]), rel=0.003, abs=0.05), (g, rpm)


# ---- the run-time tables' helpers and the retarder's heat


def test_helpers_live_and_die_with_their_tables(rp):
    """The derived helpers are cached on the tables themselves: a second call gives the same object, a copy of the
    tables gets its own, and tables no longer used are freed (no module-level cache keeps them alive)."""
    import gc
    import pickle
    import weakref

    assert rp.helpers is rp.helpers
    copy = dataclasses.replace(rp)
    h = copy.helpers
    assert h is not rp.helpers and copy.helpers is h
    ref = weakref.ref(copy)
    del copy, h
    gc.collect()
    assert ref() is None
    # a pickle carries the tables, not the derived helpers; the unpickled tables build equal ones
    back = pickle.loads(pickle.dumps(rp))
    assert "helpers" not in vars(back)
    np.testing.assert_array_equal(back.helpers.B_int, rp.helpers.B_int)


def test_retarder_heat_is_its_torque_times_the_output_speed(params):
    """The retarder's loss source: retarder_heat x |retarder torque| x output-shaft speed (its sign is the
    retarder's, not the heat's), the same in the step and in the time-to-limit point it leaves."""
    from firmware_model.onboard.records import SensorInputs
    from firmware_model.onboard.sensor import VirtualSensor
    from firmware_model.physics.kinematics import SPEED_NAMES

    frac, gear, rpm = 0.05, 9, 1500.0
    vs = VirtualSensor(params, effects={"retarder_heat": frac}, core="numpy")
    omega_out = abs(vs.reduced.speed_coef[gear - GEAR_MIN, SPEED_NAMES.index("OS")]) * rpm * RAD_S_PER_RPM
    for torque in (1200.0, -1200.0, 0.0):
        st = vs.initial_state(60.0)
        _, _, job = vs.step_deferred(st, SensorInputs(rpm, 800.0, gear, float("nan"), 20.0, 85.0, 60.0, torque))
        src = job.points[0].src_w
        assert src[R.I_SRC_RET] == pytest.approx(frac * abs(torque) * omega_out, rel=1e-12, abs=0.0)
        assert (src[R.I_SRC_RET] > 100.0) == (torque != 0.0)
