"""The onboard sensor built from a description other than the GRS905's (issue 45): the docs' reducer R1 and the MM82
wind-turbine gearbox (a motor-driven pump, an air cooler behind a thermostat).

R1.toml states the network's physics but not yet every loss constant the gear losses read (physics.gearbox_losses:
the steel's elasticity, Palmgren's coefficients, the Eq 34 tooth height, the pump); the fixture adds the GRS905's
values for the keys the shipped file lacks, and, while the loader has no Palmgren keys for a cylindrical bearing,
takes R1's cylindrical bearing as a tapered one. Keys the shipped file states are never replaced."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from firmware_model.components import MODE_HOLDING
from firmware_model.description import description_of
from firmware_model.errors import ParameterError
from firmware_model.network import K_STREAM, build_network
from firmware_model.onboard import evaluate as E
from firmware_model.onboard import reduce as R
from firmware_model.onboard.records import (
    I_AMB,
    I_COOL,
    I_GEAR,
    I_OIL,
    I_RET,
    I_SPEED,
    I_TORQUE,
    I_VKMH,
    N_INPUTS,
    REJECT_INDEX,
)
from firmware_model.onboard.sensor import VirtualSensor
from firmware_model.parameters import PARAM_DIR, load_parameters
from firmware_model.physics.drivetrain import speed_names

#: section -> (key, TOML value) the gear losses read, the GRS905's values, added where R1.toml lacks them
_LOSS_STANDINS = {
    "material.steel": [("E", '2.1e11, u = "Pa"'), ("poisson", '0.3, u = "-"')],
    "oil": [("h_t0", '0.008, u = "m"')],
    "bearing": [
        ("P0", '0, u = "N"'),
        ("f2", '0, u = "-"'),
        ("f0_tapered", '3.0, u = "-"'),
        ("f1_tapered", '0.0003, u = "-"'),
        ("e_tapered", '0.55, u = "-"'),
        ("X1_tapered", '1, u = "-"'),
        ("Y1_tapered", '0, u = "-"'),
        ("X2_tapered", '1.2, u = "-"'),
        ("Y2_tapered", '1, u = "-"'),
    ],
    "wheel_bearing": [("f0_needle", '4.0, u = "-"')],
    "pump": [("k", '0.001, u = "Nm/rpm"')],
}


def _with_loss_standins(text: str) -> str:
    for section, keys in _LOSS_STANDINS.items():
        head = f"[{section}]\n"
        body = re.search(rf"^\[{re.escape(section)}\]\n(.*?)(?=^\[|\Z)", text, re.S | re.M)
        lines = "".join(
            f'{k} = {{ v = {v}, src = "assumed", note = "test stand-in: the GRS905\'s" }}\n'
            for k, v in keys
            if body is None or not re.search(rf"^{k} = ", body.group(1), re.M)
        )
        if body is None:
            text += f"\n{head}{lines}"
        elif lines:
            text = text.replace(head, head + lines, 1)
    if "f0_cylindrical" not in text:
        text = text.replace('kind = { v = "cylindrical"', 'kind = { v = "tapered"')
    return text


@pytest.fixture(scope="module")
def r1(tmp_path_factory):
    path = Path(tmp_path_factory.mktemp("r1")) / "R1.toml"
    path.write_text(_with_loss_standins((PARAM_DIR / "R1.toml").read_text()))
    return load_parameters(path)


def _drive(n: int, speed_rpm: float, torque_nm: float, oil_c: float, gear: int) -> np.ndarray:
    """A run table for the sensor: input speed and torque, the description's single gear, ambient 25 degC, the
    measured oil ramping up 10 K."""
    t = np.arange(n) * 0.1
    raw = np.full((n, N_INPUTS), np.nan)
    raw[:, I_SPEED] = speed_rpm * (0.6 + 0.4 * np.sin(t / 20.0) ** 2)
    raw[:, I_TORQUE] = torque_nm
    raw[:, I_GEAR] = gear
    raw[:, I_OIL] = oil_c + 10.0 * t / t[-1]
    raw[:, I_AMB] = 25.0
    return raw


def test_the_grs905_sources_are_its_description_s():
    d = description_of(load_parameters("GRS905"))
    assert R.source_names(d) == R.SRC_NAMES
    assert R.planetary_meshes(d) == ("PSP", "PPR")
    assert R.churn_column(d) == speed_names(d).index("LS")
    # Palmgren alone (Eq 35-40): no bearing.R1_<kind>, so no SKF rolling term on either core
    assert not np.any(R.build_reduced(load_parameters("GRS905")).bear_rr)


def test_r1_builds_from_its_description(r1):
    d = description_of(r1)
    rp = R.build_reduced(r1)
    assert rp.src_names == ("mesh:PW", "bearing:B1", "bearing:B2", "bearing:B3", "bearing:B4", "oil_lumped", "retarder")
    assert rp.src_planetary == ()
    assert rp.src_matrix.shape == (len(rp.src_names), rp.n)
    # every source's heat lands somewhere: the retarder's too (R1 has none, its column is 0 at run time)
    assert np.allclose(rp.src_matrix.sum(axis=1), 1.0)
    assert rp.published == tuple(c.id for c in d.published)
    # splash lubrication: no pump, no dipping wheel; the output shaft is OUT
    assert (rp.pump_speed_col, rp.churn_speed_col) == (-1, -1)
    assert rp.output_speed_col == speed_names(d).index("OUT")
    assert rp.flow_m3_per_rad == 0.0 and rp.cooler_code == 0
    assert rp.max_speed_rpm == pytest.approx(1800.0) and rp.max_torque_nm == pytest.approx(600.0)
    assert rp.bc_default_c[rp.i_ambient] == pytest.approx(25.0)


def test_a_pump_without_a_pump_shaft_is_driven_by_a_motor(r1):
    d = description_of(r1)
    forced = replace(d, oil=replace(d.oil, pump_flow=1e-4))
    assert R.speed_columns(forced)["pump_speed_col"] == -1
    assert R._pump_code(forced) == E.PUMP_CODES["motor"] and R._pump_code(d) == E.PUMP_CODES["none"]
    assert R._motor_pump_flow_m3_s(forced) == 1e-4 and R._pump_flow_m3_per_rad(forced) == 0.0


@pytest.mark.parametrize("oil_mode", ["measured", "model"])
def test_r1_steps_and_the_c_kernel_agrees(r1, oil_mode):
    gear = description_of(r1).gears[0].number
    raw = _drive(900, 1500.0, 400.0, 40.0, gear)
    out = {}
    for core in ("numpy", "c"):
        s = VirtualSensor(r1, core=core, oil_mode=oil_mode)
        st = s.initial_state(T_oil_c=40.0)
        _, o = s.step_table(st, raw)
        out[core] = o.T_c
    T = out["numpy"]
    assert T.shape == (len(raw), len(description_of(r1).published))
    assert np.isfinite(T).all()
    i_p, i_oil = s.published.index("P"), s.published.index("oil")
    # the loaded pinion heats above where it started
    assert T[-1, i_p] > T[0, i_p] + 1.0
    if oil_mode == "measured":
        assert np.allclose(T[:, i_oil], raw[:, I_OIL])
    else:
        assert not np.allclose(T[:, i_oil], raw[:, I_OIL], atol=1.0)
    assert np.max(np.abs(out["c"] - T)) <= 1e-9


def test_a_dipping_wheel_off_the_churning_shaft_s_ratio_is_one_sentence():
    from types import SimpleNamespace as NS

    speed = np.zeros((17, 3))
    speed[:, 0] = 1.0  # the churning column
    speed[:, 1] = 0.5  # a fixed ratio to it (the GRS905's idler)
    speed[:, 2] = np.linspace(0.2, 2.0, 17)  # a ratio that changes with the gear
    kin = NS(speed=speed, speed_names=("A", "B", "C"))
    d = NS(wheels=[NS(id="a"), NS(id="b")], oil=NS(dipping=("a", "b")), origin="X.toml")
    fixed = NS(ch_col=np.array([0, 1]), d=d)
    np.testing.assert_array_equal(R.churn_ratios(fixed, kin, 0), [1.0, 0.5])
    with pytest.raises(ParameterError, match=r"^X\.toml: topology\.oil\.dipping names b, whose speed over A's"):
        R.churn_ratios(NS(ch_col=np.array([0, 2]), d=d), kin, 0)


def _plant_or_skip(params):
    from tools.plant.reference import ReferencePlant

    try:
        return ReferencePlant(params)
    except (KeyError, ParameterError) as exc:  # the plant runs the GRS905's sources only until issue 45's plant lands
        pytest.skip(f"the reference plant does not run {params.variant} yet: {exc}")


def _load_steps(d, n_s: int, seed: int):
    """(time [s], input speed [rpm], input torque [N m]) every second: load steps of 5-15 minutes at 30-95 % of the
    drive's top speed and 10-90 % of its torque, a 10-minute standstill from 1200 s."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_s + 1, dtype=float)
    seg = np.searchsorted(np.cumsum(rng.integers(300, 900, 16)), t)
    speed_rpm = (0.3 + 0.65 * rng.random(seg.max() + 1))[seg] * d.drive.max_speed_rad_s * 60.0 / (2.0 * np.pi)
    torque_nm = (0.1 + 0.8 * rng.random(seg.max() + 1))[seg] * d.drive.max_torque_nm
    speed_rpm[1200:1800] = torque_nm[1200:1800] = 0.0
    return t, speed_rpm, torque_nm


@pytest.mark.parametrize("oil_mode", ["measured", "model"])
def test_r1_follows_the_reference_plant(r1, oil_mode):
    """Issue 45: within 1.5 K of the reference plant on a drive of load steps (30-95 % of the drive's top speed,
    10-90 % of its torque, two standstills) the sensor was built without, with measured and with modelled oil."""
    from tools.runtable import RunTable

    plant = _plant_or_skip(r1)
    d = description_of(r1)
    gear, n_s = d.gears[0].number, 3600
    t, speed_rpm, torque_nm = _load_steps(d, n_s, 45)
    table = RunTable(
        {
            "time_s": t,
            "engine_speed_rpm": speed_rpm,
            "engine_torque_nm": torque_nm,
            "gear": np.full(t.size, gear),
            "ambient_temp_c": np.full(t.size, 25.0),
        }
    )
    out = plant.run(table, initial_temp_c=25.0, progress=False).table
    published = [c.id for c in d.published]
    T_plant = np.column_stack([np.asarray(out[f"T_{c}_c"]) for c in published])
    t_out = np.asarray(out["time_s"])
    t_s = np.arange(0.0, n_s, 0.1)
    held = np.minimum(t_s.astype(int), n_s)
    raw = np.full((t_s.size, N_INPUTS), np.nan)
    raw[:, I_SPEED], raw[:, I_TORQUE], raw[:, I_GEAR], raw[:, I_AMB] = speed_rpm[held], torque_nm[held], gear, 25.0
    raw[:, I_OIL] = np.interp(t_s, t_out, np.asarray(out["T_oil_c"]))
    s = VirtualSensor(r1, oil_mode=oil_mode)
    _, o = s.step_table(s.initial_state(T_oil_c=25.0), raw)
    row = np.clip(np.round(t_out / 0.1).astype(int) - 1, 0, t_s.size - 1)
    assert T_plant.max() > 40.0  # the drive heats the reducer
    assert np.max(np.abs(o.T_c[row] - T_plant)) <= 1.5


# --------------------------------------------------------------------------------------------------------------
# MM82: a motor-driven pump, an air cooler behind a thermostatic bypass, a rotor at <= 20 rpm and 2.5 MN m


#: the MM82's thermostat band (calibrated on the shared turbines' sump, MM82.toml) [degC]
THERMOSTAT_C = (57.1, 60.0)


@pytest.fixture(scope="module")
def mm82():
    return load_parameters("MM82")


def test_mm82_builds_with_its_motor_pump_and_air_cooler(mm82):
    from firmware_model.physics.cooler import AIR_RECIRC_V_KMH

    d = description_of(mm82)
    rp = R.build_reduced(mm82)
    assert (rp.pump_code, rp.pump_speed_col, rp.flow_m3_per_rad) == (E.PUMP_CODES["motor"], -1, 0.0)
    assert rp.pump_flow_m3_s == pytest.approx(140e-3 / 60.0)  # 140 L/min
    assert rp.cooler_code == E.COOLER_CODES["air"]
    assert (
        (rp.cooler["thermostat_open"], rp.cooler["thermostat_full"])
        == THERMOSTAT_C
        == (
            mm82.values["cooler.thermostat_open"],
            mm82.values["cooler.thermostat_full"],
        )
    )
    # every oil stream is one: the cooler's inlet drop applies to all of them, as in the plant
    assert len(rp.ef_link) + int(np.sum(rp.t2_stream)) == len(build_network(mm82).links_of_kind(K_STREAM))
    # the oil inlet is derived, not a node: the sensor publishes the others in their order
    assert rp.published == tuple(c.id for c in d.published if c.id not in d.derived) and "oil.inlet" in d.derived
    # no vehicle speed: the plant's cooler air has no recirculation excess
    assert rp.default_v_kmh == AIR_RECIRC_V_KMH[-1]
    # the rotor turns below the GRS905's standstill speed of the conductances: its own is 1 % of its top speed
    assert rp.speed_bin_min_rad_s == pytest.approx(0.01 * d.drive.max_speed_rad_s)
    # SKF's rolling term (bearing.R1_cylindrical) on cylindrical bearings only (R1_tapered is not given), among them
    # the high-speed shaft's BHR (SCADA Gb2t); the replays below check it on both cores and against the plant
    names = [s.split(":")[1] for s in rp.src_names if s.startswith("bearing:")]
    kind = {b.id: b.kind for b in d.bearings}
    with_rr = {b for b, on in zip(names, np.any(rp.bear_rr > 0.0, axis=0)) if on}
    assert "BHR" in with_rr and {kind[b] for b in with_rr} == {"cylindrical"}


@pytest.fixture(scope="module")
def mm82_drive(mm82):
    """An hour of load steps from warm (oil at the thermostat's opening, ambient 30 degC): the thermostat opens. The
    plant's output and the sensor's raw inputs (the plant's sump as the measured oil)."""
    from tools.runtable import RunTable

    plant = _plant_or_skip(mm82)
    d = description_of(mm82)
    gear, n_s, amb_c, start_c = d.gears[0].number, 3600, 30.0, THERMOSTAT_C[0]
    t, speed_rpm, torque_nm = _load_steps(d, n_s, 82)
    table = RunTable(
        {
            "time_s": t,
            "engine_speed_rpm": speed_rpm,
            "engine_torque_nm": torque_nm,
            "gear": np.full(t.size, gear),
            "ambient_temp_c": np.full(t.size, amb_c),
        }
    )
    out = plant.run(table, initial_temp_c=start_c, progress=False).table
    t_s = np.arange(0.0, n_s, 0.1)
    held = np.minimum(t_s.astype(int), n_s)
    raw = np.full((t_s.size, N_INPUTS), np.nan)
    raw[:, I_SPEED], raw[:, I_TORQUE], raw[:, I_GEAR], raw[:, I_AMB] = speed_rpm[held], torque_nm[held], gear, amb_c
    raw[:, I_OIL] = np.interp(t_s, np.asarray(out["time_s"]), np.asarray(out["T_oil_c"]))
    return out, raw, start_c


@pytest.fixture(scope="module")
def mm82_replays(mm82, mm82_drive):
    """get(oil_mode, core) -> (sensor, step_table output over mm82_drive), each computed once per module: two tests
    read each (an hour of 0.1 s numpy steps is most of their time). They read temperatures only, none of which
    depends on the time to limit: it is refreshed once (tools.scada.replay.ESTIMATES_TTL_PERIOD_S), not every 1 s."""
    from tools.scada.replay import ESTIMATES_ONLY

    done = {}

    def get(oil_mode: str, core: str):
        if (oil_mode, core) not in done:
            _, raw, start_c = mm82_drive
            s = VirtualSensor(mm82, core=core, oil_mode=oil_mode, **ESTIMATES_ONLY)
            done[(oil_mode, core)] = (s, s.step_table(s.initial_state(T_oil_c=start_c), raw)[1])
        return done[(oil_mode, core)]

    return get


@pytest.mark.parametrize("oil_mode", ["measured", "model"])
def test_mm82_follows_the_reference_plant_and_the_c_kernel_agrees(mm82_replays, mm82_drive, oil_mode):
    """Issue 45: within 1.5 K of the reference plant on a drive the sensor was built without, every published
    component, with measured and with modelled oil; the C kernel equal to the numpy step within 1e-9 K."""
    out, raw, start_c = mm82_drive
    T = {}
    for core in ("numpy", "c"):
        s, o = mm82_replays(oil_mode, core)
        T[core] = o.T_c
    assert s.compiled is not None
    assert np.max(np.abs(T["c"] - T["numpy"])) <= 1e-9
    T_plant = np.column_stack([np.asarray(out[f"T_{c}_c"]) for c in s.published])
    t_out = np.asarray(out["time_s"])
    row = np.clip(np.round(t_out / 0.1).astype(int) - 1, 0, len(raw) - 1)
    oil = np.asarray(out["T_oil_c"])
    assert oil.max() > sum(THERMOSTAT_C) / 2.0  # the thermostat opens: the air cooler takes part
    assert T_plant.max() > start_c + 20.0  # the drive heats the high-speed stage
    assert np.max(np.abs(T["numpy"][row] - T_plant)) <= 1.5


@pytest.mark.parametrize("oil_mode", ["measured", "model"])
def test_mm82_oil_inlet_follows_the_reference_plant_and_the_c_kernel_agrees(mm82_replays, mm82_drive, oil_mode):
    """A forced oil system's inlet (the description's derived oil.inlet: the sump minus the cooler's drop Q / (mdot
    cp)) is a status output: the C kernel equal to the numpy step within 1e-9 K, below the sensor's sump by the drop
    once the thermostat opens, and the plant's inlet (T_oil.inlet_c) within a few mK with the oil measured and
    modelled, whatever vehicle speed the input holds: the MM82's drive has none, so its cooler sees the air of a
    stationary machine (no ram air, no recirculation), as the plant's does."""
    out, raw, start_c = mm82_drive
    res = {}
    for core in ("numpy", "c"):
        s, res[core] = mm82_replays(oil_mode, core)
    assert s.oil_inlet and s.compiled is not None
    inlet = res["numpy"].oil_inlet_temp_c
    assert np.isfinite(inlet).all() and np.isfinite(res["c"].oil_inlet_temp_c).all()
    assert np.max(np.abs(res["c"].oil_inlet_temp_c - inlet)) <= 1e-9
    # the inlet lies below the sump the step took by the cooler's drop: modelled, zero with the thermostat shut;
    # measured, the MM82's cooler takes what the sump's balance leaves (measured_cooler = "balance"), the valve's
    # band no guide, at most the fully open valve's hA (T_oil - T_air) / mdot cp
    i_oil = s.published.index("oil")
    sump_c = raw[:, I_OIL] if oil_mode == "measured" else np.concatenate([[start_c], res["numpy"].T_c[:-1, i_oil]])
    drop_k = sump_c - inlet
    assert drop_k.min() >= 0.0 and drop_k.max() > 3.0
    if oil_mode == "model":
        assert np.all(drop_k[sump_c < THERMOSTAT_C[0] - 1e-9] < 1e-12)
    else:
        assert np.any(drop_k[sump_c < THERMOSTAT_C[0] - 1e-9] > 0.5)
    t_out = np.asarray(out["time_s"])
    row = np.clip(np.round(t_out / 0.1).astype(int) - 1, 0, len(raw) - 1)
    plant_c = np.asarray(out["T_oil.inlet_c"])
    assert np.max(np.asarray(out["T_oil_c"]) - plant_c) > 3.0  # the plant's thermostat open too
    # the plant's inlet within a few mK with the oil measured (0.5 mK); modelled, within the sump's own residual
    # times the thermostat ramp's gain: 7 mK before the 10-minute standstill, 41 mK after it (since the MM82's pump
    # stops with the rotor, 2026-12-05: without jets the modelled sump drifts 17-21 mK from the plant's, and at the
    # restart the valve's ramp, dQ/dT ~ 12 kW/K over mdot cp ~ 3.9 kW/K, triples that in the inlet); a vehicle speed
    # read as a truck's would warm the cooler's air by 2-12 K and miss it by ~0.6 K
    assert np.isnan(raw[:, I_VKMH]).all()
    if oil_mode == "model":
        assert np.max(np.abs(inlet[row] - plant_c)) <= 0.05
    else:
        # the balance leaves out the sump's own storage (300 L: 0.54 MJ/K): on this drive's load steps the sump
        # moves up to 53 K/h and the drop misses the plant's law by up to 3.8 K (C_oil dS/dt over the share the
        # sump keeps of mdot cp, ~250 s x dS/dt); 0.54 K RMS over the hour, 0.21 K while it moves under 0.36 K/h
        dS = np.gradient(np.asarray(out["T_oil_c"]), t_out)
        err = inlet[row] - plant_c
        assert np.sqrt(np.mean(err**2)) <= 0.6
        assert np.max(np.abs(err[np.abs(dS) < 1e-4])) <= 0.25
    for v_kmh in (0.0, 50.0, s.sp.reduced.default_v_kmh):  # a fed vehicle speed changes nothing (C core here)
        raw_v = raw.copy()
        raw_v[:, I_VKMH] = v_kmh
        _, o = s.step_table(s.initial_state(T_oil_c=start_c), raw_v)
        assert np.max(np.abs(o.oil_inlet_temp_c - inlet)) <= 1e-9


@pytest.mark.parametrize("torque_frac", [0.2, 0.35])
def test_mm82_measured_cooler_balance_is_the_thermostat_s_heat_at_rest(mm82, torque_frac):
    """measured_cooler = "balance": with the sump measured the cooler takes what the sump's balance leaves. Where the
    modelled network is at rest (12 h of one load, the sump settled inside the thermostat's band, the valve part
    open) that is the heat the thermostat's law gives: the same network's state stepped on with its own sump as the
    measured oil gives the modelled run's inlet within 0.1 mK."""
    from tools.scada.replay import ESTIMATES_ONLY

    d = description_of(mm82)
    n = 12 * 36000
    raw = np.full((n, N_INPUTS), np.nan)
    raw[:, I_SPEED] = 0.8 * d.drive.max_speed_rad_s * 30.0 / np.pi
    raw[:, I_TORQUE] = torque_frac * d.drive.max_torque_nm
    raw[:, I_GEAR], raw[:, I_AMB] = d.gears[0].number, 20.0
    model = VirtualSensor(mm82, oil_mode="model", **ESTIMATES_ONLY)
    st, o = model.step_table(model.initial_state(T_oil_c=50.0), raw)
    sump_c = float(o.T_c[-1, model.published.index("oil")])
    assert THERMOSTAT_C[0] < sump_c < THERMOSTAT_C[1]  # the valve part open: the law's heat inside its bounds
    assert abs(sump_c - o.T_c[-36000, model.published.index("oil")]) < 1e-3  # settled
    ten = raw[-10:].copy()
    ten[:, I_OIL] = sump_c
    measured = VirtualSensor(mm82, oil_mode="measured", **ESTIMATES_ONLY)
    _, o_meas = measured.step_table(st, ten)
    assert sump_c - o.oil_inlet_temp_c[-1] > 3.0
    assert np.max(np.abs(o_meas.oil_inlet_temp_c - o.oil_inlet_temp_c[-1])) < 1e-4


def test_a_splash_gearbox_has_no_oil_inlet(r1):
    """A splash-lubricated gearbox (R1; the GRS905's is pinned by the goldens) outputs NaN as its oil inlet, in C and
    in numpy."""
    gear = description_of(r1).gears[0].number
    raw = _drive(50, 1500.0, 400.0, 40.0, gear)
    for core in ("numpy", "c"):
        s = VirtualSensor(r1, core=core)
        _, o = s.step_table(s.initial_state(T_oil_c=40.0), raw)
        assert not s.oil_inlet and np.isnan(o.oil_inlet_temp_c).all()
        _, one = s.step(s.initial_state(T_oil_c=40.0), s.Inputs(*raw[0]))
        assert np.isnan(one.status.oil_inlet_temp_c)


def test_a_gear_the_description_lacks_is_unknown_on_both_cores(r1):
    """R1 has gear 1 only: a 2 (in -2..14, but no gear of R1) was used as neutral's row, gear_valid 1 and no reject
    counted. Now it is rejected as any unknown gear: counted in gear_unknown, the last good gear held, mode 2, on
    the numpy step and the C kernel alike, bit for bit."""
    rp = R.build_reduced(r1)
    assert rp.gear_defined.tolist() == [n == 1 for n in range(-2, 15)]
    raw = _drive(300, 1500.0, 400.0, 40.0, 1)
    raw[100:200, I_GEAR] = 2.0  # no gear of R1
    runs = {}
    for core in ("numpy", "c"):
        s = VirtualSensor(r1, core=core)
        st = s.initial_state(T_oil_c=40.0)
        st, o = s.step_table(st, raw)
        held = raw.copy()
        held[:, I_GEAR] = 1.0  # what the sensor must have used: the last good gear
        _, o_held = s.step_table(s.initial_state(T_oil_c=40.0), held)
        runs[core] = o
        unknown = o.rejects[:, REJECT_INDEX["gear_unknown"]]
        assert int(st.rejects[REJECT_INDEX["gear_unknown"]]) == 100 and unknown[99] == 0 and unknown[199] == 100
        gear_valid = o.valid[:, 2]
        assert not gear_valid[100:200].any() and gear_valid[:100].all() and gear_valid[200:].all()
        assert (o.degraded_mode[100:200] == MODE_HOLDING).all()
        np.testing.assert_array_equal(o.T_c, o_held.T_c)
    np.testing.assert_allclose(runs["c"].T_c, runs["numpy"].T_c, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(runs["c"].rejects, runs["numpy"].rejects)
    np.testing.assert_array_equal(runs["c"].valid, runs["numpy"].valid)


def test_every_grs905_gear_is_defined():
    """The GRS905 numbers every gear of -2..14 (seed Table 1): the new flag changes nothing there."""
    assert R.build_reduced(load_parameters("GRS905")).gear_defined.all()


def _aux_missing_runs(params, raw: np.ndarray, oil_c: float) -> dict:
    """core -> (final state, step_table output) of both cores over ``raw`` from the oil at ``oil_c``."""
    out = {}
    for core in ("numpy", "c"):
        s = VirtualSensor(params, core=core)
        out[core] = s.step_table(s.initial_state(T_oil_c=oil_c), raw)
    np.testing.assert_array_equal(out["c"][1].rejects, out["numpy"][1].rejects)
    np.testing.assert_allclose(out["c"][1].T_c, out["numpy"][1].T_c, rtol=0, atol=1e-9)
    return out


@pytest.mark.parametrize("name", ["MM82", "HR225"])
def test_an_input_the_drive_has_not_is_not_counted_missing_on_both_cores(name):
    """A fixed-ratio drive (the MM82's air cooler, the HR225's none; no coolant boundary) has no coolant, vehicle
    speed or retarder: their absence was counted in aux_missing at every step, as if an auxiliary input failed. Not
    applicable now: not counted, and the coolant is never read (the temperatures are those with one given); a
    missing ambient, which every drive has, still counts, on the numpy step and the C kernel alike."""
    from firmware_model.units import RPM_PER_RAD_S
    from tools.drive_table import fixed_ratio_gear

    params = load_parameters(name)
    d = description_of(params)
    speed_rpm = 0.7 * d.drive.max_speed_rad_s * RPM_PER_RAD_S
    raw = _drive(300, speed_rpm, 0.5 * d.drive.max_torque_nm, 50.0, fixed_ratio_gear(d))
    raw[100:140, I_AMB] = np.nan  # the ambient sensor fails for 40 steps
    with_coolant = raw.copy()
    with_coolant[:, I_COOL] = 90.0
    runs = _aux_missing_runs(params, raw, 50.0)
    given = _aux_missing_runs(params, with_coolant, 50.0)
    for core in ("numpy", "c"):
        st, o = runs[core]
        assert int(st.rejects[REJECT_INDEX["aux_missing"]]) == 40, core
        assert o.rejects[99, REJECT_INDEX["aux_missing"]] == 0 and o.rejects[139, REJECT_INDEX["aux_missing"]] == 40
        np.testing.assert_array_equal(o.T_c, given[core][1].T_c)


def test_a_missing_coolant_the_drive_has_is_still_counted_on_both_cores():
    """The GRS905 (a vehicle, a liquid cooler on the engine's coolant) expects its coolant: missing, it is counted
    at every step it is missing on both cores, as are a missing vehicle speed and retarder torque."""
    params = load_parameters("GRS905")
    raw = _drive(200, 1400.0, 1500.0, 70.0, 12)
    raw[:, I_COOL], raw[:, I_VKMH], raw[:, I_RET] = 85.0, 80.0, 0.0
    raw[50:80, I_COOL] = np.nan  # 30 steps without a coolant
    raw[120:130, I_VKMH] = raw[120:130, I_RET] = np.nan  # 10 steps without vehicle speed and retarder: 2 each
    runs = _aux_missing_runs(params, raw, 70.0)
    for core in ("numpy", "c"):
        assert int(runs[core][0].rejects[REJECT_INDEX["aux_missing"]]) == 30 + 2 * 10, core
