"""SensorService: time from frame timestamps, staleness, catch-up and time jumps, outputs, counters, robustness,
and the real truck captures (tests/data_paths.py) through the whole service."""

from __future__ import annotations

import logging
import math

import can
import numpy as np
import pytest

from can_dbc.adapter import REJECT_REASONS, STATUS_KEYS, can_id_of, decode_outputs, pgn_of
from firmware_model.components import PUBLISHED, STEP_S
from firmware_model.errors import ParameterError
from firmware_model.service import SensorService, ServiceOptions, can_filters, wanted_pgns
from tests.data_paths import SKIP_REASON, real_capture_dir

from .sensor_standin import VirtualSensor as StandIn
from .sensor_standin import make_sensor

DATA = real_capture_dir()
CAPTURES = ("normal", "tsc1", "fuzz_1ms_ID_and_Data", "utulsa_logger2_drive")


def frame(t, pgn, sa, data, prio=6, **kw):
    return can.Message(
        timestamp=t, arbitration_id=can_id_of(pgn, sa, prio), is_extended_id=True, data=bytes(data), **kw
    )


def eec1(t, rpm=1200.0, pct=50):
    raw = round(rpm / 0.125)
    return frame(t, 61444, 0x00, [0xF0, pct + 125, pct + 125, raw & 0xFF, raw >> 8, 0, 0xFF, 0xFF], prio=3)


def etc2(t, gear=4):
    return frame(t, 61445, 0x03, [gear + 125, 0xFF, 0xFF, gear + 125, 0xFF, 0xFF, 0xFF, 0xFF])


def trf1(t, oil=80.0):
    raw = round((oil + 273) / 0.03125)
    return frame(t, 65272, 0x03, [0xFF] * 4 + [raw & 0xFF, raw >> 8, 0xFF, 0xFF])


def traffic(t0, t1, rpm=1200.0, oil=80.0, gear=4):
    """EEC1 every 10 ms (phase 5 ms), ETC2 every 100 ms, TRF1 every 1 s, starting with an EEC1 at t0."""
    out = []
    for k in range(int(round((t1 - t0) / 0.01))):
        t = t0 + 0.01 * k + (0.0 if k == 0 else 0.005)
        out.append(eec1(t, rpm))
        if k % 10 == 3:
            out.append(etc2(t + 0.001, gear))
        if k % 100 == 4:
            out.append(trf1(t + 0.002, oil))
    return out


def service(**kw):
    opts = {k: kw.pop(k) for k in list(kw) if k in ServiceOptions.__dataclass_fields__}
    opts.setdefault("configured_ref_torque_nm", 2000.0)
    return SensorService(StandIn(), ServiceOptions(**opts), **{"record": True, **kw})


# --------------------------------------------------------------------------------------------------- time model


def test_steps_on_frame_time_boundaries_and_frames_stamped_with_step_time():
    svc = service()
    out = svc.feed_all(traffic(1000.0, 1003.0))
    rec = svc.recorded()
    # last frame at 1002.995: boundaries 1000.1 .. 1002.9
    assert svc.counters["steps"] == 29
    assert np.allclose(rec["can_time_s"], 1000.0 + STEP_S * np.arange(1, 30))
    assert np.allclose(rec["time_s"], STEP_S * np.arange(1, 30))
    stamps = sorted({m.timestamp for m in out})
    assert np.allclose(stamps, rec["can_time_s"])
    per_step = {}
    for m in out:
        per_step.setdefault(m.timestamp, []).append(m)
    assert all(len(v) in (16, 17) for v in per_step.values())
    dm1 = [m for m in out if pgn_of(m.arbitration_id) == 0xFECA]
    assert 3 <= len(dm1) <= 4  # every second (and the first step)


def test_step_uses_the_values_before_its_boundary():
    svc = service()
    frames = traffic(10.0, 10.2, rpm=1000.0)
    frames = [m for m in frames if m.timestamp < 10.1] + [eec1(10.1, 2000.0), eec1(10.15, 2000.0), eec1(10.2, 2000.0)]
    svc.feed_all(frames)
    rec = svc.recorded()
    assert list(rec["engine_speed_rpm"]) == [1000.0, 2000.0]


def test_same_traffic_same_outputs_and_unwanted_frames_never_move_time():
    base = traffic(5.0, 7.0)
    noisy = []
    for m in base:
        # foreign frames between, 11-bit, unknown PGNs, our own outputs: counted, never timing
        noisy.append(
            can.Message(timestamp=m.timestamp - 0.0004, arbitration_id=0x123, is_extended_id=False, data=b"\x01")
        )
        noisy.append(frame(m.timestamp - 0.0002, 0xFECA, 0x31, [0] * 8))
        noisy.append(m)
    noisy.insert(0, frame(4.9437, 0xFF40, 0xE5, [0] * 8))  # before the first wanted frame: must not anchor
    a, b = service(), service()
    out_a = a.feed_all(base)
    out_b = b.feed_all(noisy)
    assert [(m.timestamp, m.arbitration_id, bytes(m.data)) for m in out_a] == [
        (m.timestamp, m.arbitration_id, bytes(m.data)) for m in out_b
    ]
    assert b.counters["frames_not_timing"] == 2 * len(base) + 1
    d = b.decoder.counters
    assert d["frames_seen"] == d["frames_used"] + sum(d["rejected"].values()) == len(noisy)


def test_a_signal_that_stops_is_stale_after_3_periods_and_recovers():
    frames = [m for m in traffic(0.0, 4.0) if not (pgn_of(m.arbitration_id) == 61444 and 1.0 < m.timestamp < 2.0)]
    svc = service()
    svc.feed_all(frames)
    rec = svc.recorded()
    t, rpm = rec["can_time_s"], rec["engine_speed_rpm"]
    # last EEC1 before the gap at 0.995: fresh at 1.0 (5 ms), stale from 1.1 (105 ms > 60 ms) to 2.0 (EEC1 at 2.005)
    assert np.isnan(rpm[(t > 1.05) & (t < 2.0)]).all()
    assert np.isfinite(rpm[(t < 1.05) & (t > 0.35)]).all() and np.isfinite(rpm[t > 2.05]).all()
    assert (rec["speed_valid"][(t > 1.05) & (t < 2.0)] == 0).all()
    assert svc.counters["stale_steps"]["engine_speed_rpm"] == 10
    # the stale factor is configurable: with 10x the 20 ms period, 0.2 s without EEC1 is still fresh
    frames = [m for m in traffic(0.0, 2.0) if not (pgn_of(m.arbitration_id) == 61444 and 1.0 < m.timestamp < 1.15)]
    svc = service(stale_factor=10.0)
    svc.feed_all(frames)
    assert np.isfinite(svc.recorded()["engine_speed_rpm"][3:]).all()


def test_silent_bus_is_caught_up_step_by_step_and_only_the_last_step_is_sent():
    frames = traffic(0.0, 1.0) + traffic(3.0, 3.5)
    svc = service()
    out = svc.feed_all(frames)
    assert svc.counters["time_jumps"] == 0
    assert svc.counters["catchup_steps"] == 20  # 1.0 .. 2.9 stepped when the frame at 3.0 arrives; 3.0 sent
    stamps = sorted({round(m.timestamp, 6) for m in out})
    assert 2.9 not in stamps and 3.0 in stamps
    rec = svc.recorded()
    assert np.allclose(np.diff(rec["time_s"]), STEP_S)
    assert np.isnan(rec["engine_speed_rpm"][(rec["time_s"] > 1.1) & (rec["time_s"] < 2.95)]).all()


def test_time_jumps_restart_the_grid_and_are_counted(caplog):
    svc = service()
    with caplog.at_level(logging.WARNING, logger="gearbox_vsensor.can_service"):
        svc.feed_all(traffic(0.0, 1.0) + traffic(100.0, 101.0) + traffic(50.0, 51.0))
    assert svc.counters["time_jumps"] == 2
    assert sum("jumped forward" in r.message for r in caplog.records) == 1
    assert sum("jumped backward" in r.message for r in caplog.records) == 1
    rec = svc.recorded()
    assert (np.diff(rec["time_s"]) > 0).all()  # run-table time keeps increasing across a backward restart
    assert svc.counters["steps"] == 3 * 9
    # ... by one step: the sensor sees no gap where the clock went back (not 0.2 s, nor a forward time jump
    # there), and counts the one forward jump
    d = np.diff(rec["time_s"])
    assert np.count_nonzero(d > 1.5 * STEP_S) == 1 and np.allclose(d[d <= 1.5 * STEP_S], STEP_S)


class _WithoutPrepare:
    """A VirtualSensor seen without prepare_jump: the service then propagates a gap inside the step."""

    def __init__(self, sensor):
        self._sensor = sensor

    def __getattr__(self, name):
        if name == "prepare_jump":
            raise AttributeError(name)
        return getattr(self._sensor, name)


@pytest.mark.parametrize("core", ["numpy", "c"])
@pytest.mark.parametrize("change", ["T_c", "hold", "age_s", "gap"])
def test_a_propagation_prepared_for_another_state_or_gap_is_not_taken(core, change):
    """The prepared jump is keyed on all it reads: a state or gap that differs from the prepared one is computed
    afresh (the same bits as without preparing), and the entry is dropped."""
    from firmware_model.onboard.records import SensorInputs
    from firmware_model.onboard.sensor import VirtualSensor
    from firmware_model.parameters import load_parameters

    params = load_parameters()
    runs = []
    for prepare in (True, False):
        sensor = VirtualSensor(params, core=core)
        if core == "c" and sensor.compiled is None:
            pytest.skip("the compiled kernel is not built here")
        st = sensor.initial_state(T_oil_c=70.0)
        for k in range(1, 50):
            st, _ = sensor.step(st, SensorInputs(1500.0, 1800.0, 10, 70.0, 20.0, 85.0, 60.0, 0.0, t_s=0.1 * k))
        t_s = 4.9 + 12.0
        if prepare:
            assert sensor.prepare_jump(st, t_s)
        if change == "gap":
            t_s += 0.1
        else:
            a = np.array(getattr(st, change), dtype=float, copy=True)
            a.reshape(-1)[0] += 0.5
            st = st._replace(**{change: a.astype(np.asarray(getattr(st, change)).dtype)})
        st, out = sensor.step(st, SensorInputs(1500.0, 1800.0, 10, 70.0, 20.0, 85.0, 60.0, 0.0, t_s=t_s))
        runs.append((np.array(out.T_c), np.array(st.T_c), sensor.cache.ahead.hits, sensor.cache.ahead.key))
    (T_out, T_st, hits, key), (ref_out, ref_st, _, _) = runs
    assert hits == 0 and key is None
    assert not sensor.prepare_jump(st, float("inf")) and not sensor.prepare_jump(st, float("nan"))  # no jump the
    assert sensor.cache.ahead.key is None  # step would see: nothing done
    assert np.array_equal(T_out, ref_out) and np.array_equal(T_st, ref_st)


@pytest.mark.parametrize("core", ["numpy", "c"])
def test_a_forward_gap_is_propagated_at_its_first_frame_and_the_outputs_are_the_same_bits(core):
    """The live service propagates the state over a forward gap when the first frame after it arrives
    (VirtualSensor.prepare_jump), so the first output after an outage waits one step period, not a period plus the
    propagation; the step then takes the prepared result. Outputs and state bit for bit as without it."""
    from firmware_model.onboard.sensor import VirtualSensor
    from firmware_model.parameters import load_parameters

    params = load_parameters()
    frames = traffic(0.0, 30.0, rpm=1500.0) + traffic(42.0, 50.0, rpm=1500.0) + traffic(400.0, 403.0)
    runs = {}
    for prepared in (True, False):
        sensor = VirtualSensor(params, core=core)
        if core == "c" and sensor.compiled is None:
            pytest.skip("the compiled kernel is not built here")
        svc = SensorService(
            sensor if prepared else _WithoutPrepare(sensor),
            ServiceOptions(configured_ref_torque_nm=2000.0),
            record=True,
        )
        sent = svc.feed_all(frames)
        svc.finish_pending()
        runs[prepared] = (svc, sent, sensor.cache.ahead.hits)
    (svc, sent, hits), (plain, plain_sent, plain_hits) = runs[True], runs[False]
    assert svc.counters["time_jumps"] == plain.counters["time_jumps"] == 2
    assert (hits, plain_hits) == (2, 0)
    assert [(m.timestamp, m.arbitration_id, bytes(m.data)) for m in sent] == [
        (m.timestamp, m.arbitration_id, bytes(m.data)) for m in plain_sent
    ]
    rec, ref = svc.recorded(), plain.recorded()
    assert rec.keys() == ref.keys()
    for name in rec:
        assert np.array_equal(rec[name], ref[name], equal_nan=rec[name].dtype.kind == "f"), name
    for a, b in zip(svc.state, plain.state):
        assert np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)


def test_not_initialised_until_oil_temperature_or_timeout():
    svc = service()
    out = svc.feed_all(traffic(0.0, 0.3))  # TRF1 at 0.046
    assert svc.recorded()["degraded_mode"][0] != 3
    no_oil = [m for m in traffic(0.0, 5.0) if pgn_of(m.arbitration_id) != 65272]
    svc = service()
    out = svc.feed_all(no_oil)
    rec = svc.recorded()
    waiting = rec["time_s"] < 3.0 - 1e-9
    assert (rec["degraded_mode"][waiting] == 3).all() and (rec["degraded_mode"][~waiting] != 3).all()
    first = decode_outputs([m for m in out if abs(m.timestamp - 0.1) < 1e-9])
    assert first["status"]["degraded_mode"] == 3 and set(first["temps_c"].values()) == {None}
    assert set(first["levels"].values()) == {3}


def test_an_implausible_first_oil_reading_is_waited_past():
    """A TRF1 of 240 degC at key-on (the decoder passes up to 250 degC; the oil model ends at 200) put every node at
    240 degC and raised every warning; then, started at once from the default, it under-warned. The service waits
    for a plausible reading (up to init_wait_s) and starts from it."""
    hot = [m for m in traffic(0.0, 1.0, oil=240.0)]
    svc = service()
    svc.feed_all(hot + traffic(1.0, 3.0, oil=85.0))
    rec = svc.recorded()
    started = np.flatnonzero(rec["degraded_mode"] != 3)[0]
    assert rec["time_s"][started] > 1.0 and abs(rec["model_oil_temp_c"][started] - 85.0) < 0.5


def test_no_ec1_and_no_configured_reference_torque_means_torque_not_available(caplog):
    svc = service(configured_ref_torque_nm=None, no_ref_torque_warning_s=2.0)
    with caplog.at_level(logging.WARNING, logger="gearbox_vsensor.can_service"):
        svc.feed_all(traffic(0.0, 3.0))
    rec = svc.recorded()
    assert np.isnan(rec["engine_torque_nm"]).all() and (rec["torque_valid"] == 0).all()
    assert (rec["ref_torque_valid"] == 0).all()
    assert np.isfinite(rec["engine_torque_pct"][1:]).all()
    assert any("no EC1" in r.message and "degraded" in r.message for r in caplog.records)
    svc = service(configured_ref_torque_nm=2000.0)
    svc.feed_all(traffic(0.0, 1.0))
    assert np.allclose(svc.recorded()["engine_torque_nm"], 0.5 * 2000.0)


def test_gear_map_and_gears_outside_the_model_are_not_available():
    svc = service(gear_map={1: 5, 2: 6})
    frames = traffic(0.0, 0.5, gear=2) + traffic(0.5, 1.0, gear=3)
    svc.feed_all(frames)
    g = svc.recorded()["gear"]
    assert set(g[:3]) == {6.0} and np.isnan(g[-2:]).all()
    svc = service()
    svc.feed_all(traffic(0.0, 0.5, gear=20))
    assert np.isnan(svc.recorded()["gear"]).all()
    opts = ServiceOptions.from_config(type("C", (), {"can": {"gear_map": {"1": 3, "-1": -1}}})())
    assert opts.gear_map == {1: 3, -1: -1}
    with pytest.raises(ParameterError, match="gear_map"):
        ServiceOptions.from_config(type("C", (), {"can": {"gear_map": {"x": 3}}})())


def test_options_are_validated_with_named_errors():
    for key, value in (
        ("sensor_source_address", 300),
        ("engine_source_address", True),  # named by their [can]
        ("engine_reference_torque_nm", -5),
        ("retarder_reference_torque_nm", "x"),
    ):  # key, not field
        with pytest.raises(ParameterError, match=rf"can\.{key} = "):
            ServiceOptions.from_config(type("C", (), {"can": {key: value}})())
    with pytest.raises(ParameterError, match="stale_factor"):
        ServiceOptions(stale_factor=0.5)
    with pytest.raises(ParameterError, match="output_period_s"):
        ServiceOptions(output_period_s=0.15)
    # refused with a sentence: inf and NaN periods (else a traceback), an infinite stale factor (an input gone for
    # 5 minutes would stay valid), a NAME field too wide (cut to its low bits on the bus)
    for key, value in (
        ("output_period_s", math.inf),
        ("output_period_s", math.nan),
        ("stale_factor", math.inf),
        ("stale_factor", 1e300),
        ("counter_log_period_s", math.inf),
        ("name_identity_number", 2097157),
        ("name_industry_group", 9),
    ):
        with pytest.raises(ParameterError, match=rf"can\.{key} = "):
            ServiceOptions.from_config(type("C", (), {"can": {key: value}})())
    opts = ServiceOptions.from_config(
        type(
            "C",
            (),
            {
                "can": {
                    "engine_source_address": 0x01,
                    "transmission_source_address": 0x05,
                    "sensor_source_address": 0x80,
                    "retarder_reference_torque_nm": 3000,
                }
            },
        )()
    )
    assert opts.expected_sa["EEC1"] == 1 and opts.expected_sa["TRF1"] == 5 and opts.sensor_source_address == 0x80
    svc = SensorService(StandIn(), opts)
    assert svc.decoder.expected_sa["ETC2"] == 5 and svc.decoder.retarder_ref_torque_nm == 3000


def test_output_period_and_source_address():
    svc = service(output_period_s=0.5, sensor_source_address=0x80)
    out = svc.feed_all(traffic(0.0, 2.0))
    periodic = [m for m in out if pgn_of(m.arbitration_id) != 0xFECA]
    assert sorted({round(m.timestamp, 6) for m in periodic}) == [0.5, 1.0, 1.5]
    assert {m.arbitration_id & 0xFF for m in out} == {0x80}


class _Levels(StandIn):
    """A sensor whose warning levels the test sets."""

    def __init__(self):
        super().__init__()
        self.levels = np.zeros(len(PUBLISHED), dtype=int)

    def step(self, state, inputs):
        state, out = super().step(state, inputs)
        return state, out._replace(level=self.levels.copy())


def test_dm1_every_second_and_at_once_on_change():
    sensor = _Levels()
    svc = SensorService(sensor, ServiceOptions(configured_ref_torque_nm=2000.0))
    dm1 = []
    for m in traffic(0.0, 3.0):
        if abs(m.timestamp - 1.45) < 0.006:
            sensor.levels[PUBLISHED.index("PS")] = 1
        dm1 += [x for x in svc.feed(m) if pgn_of(x.arbitration_id) == 0xFECA]
    times = [round(x.timestamp, 6) for x in dm1]
    assert times == [0.1, 1.1, 1.5, 2.5]
    last = decode_outputs(dm1[2:3])["dm1"]
    assert last["amber_warning_lamp"] == 1 and last["dtc"]["component"] == "PS" and last["dtc"]["fmi"] == 16


def test_counters_are_logged_every_period_of_frame_time(caplog):
    svc = service(counter_log_period_s=1.0)
    with caplog.at_level(logging.INFO, logger="gearbox_vsensor.can_service"):
        svc.feed_all(traffic(0.0, 4.0))
    lines = [r.message for r in caplog.records if r.message.startswith("frames seen")]
    assert len(lines) == 3 and "rejected:" in lines[0] and "steps" in lines[0]


def test_filters_mask_priority_and_source_address():
    assert len(can_filters(network=False)) == len(wanted_pgns())
    filters = can_filters()
    assert len(filters) == len(wanted_pgns()) + 2  # + J1939 Request and Address Claimed

    def passes(can_id):
        return any((can_id & f["can_mask"]) == (f["can_id"] & f["can_mask"]) for f in filters)

    for pgn in wanted_pgns().values():
        for prio in (0, 3, 7):
            for sa in (0x00, 0x03, 0x31, 0xFE):
                dest = 0xFF if (pgn >> 8) & 0xFF < 240 else 0xFF
                assert passes(can_id_of(pgn, sa, prio, dest))
    assert passes(can_id_of(0xEC00, 0x00, 7, destination=0x21))  # TP.CM to a node: received, counted as rejected
    for pgn in (0xFECA, 0xFF40, 0xFEF2, 0xF003):
        assert not passes(can_id_of(pgn, 0x00, 6))
    assert len(can_filters(rig=True, network=False)) == len(wanted_pgns()) + 7


# --------------------------------------------------------------------------------------------------- robustness


def random_frames(n, seed=1):
    """Wrong lengths, remote and error frames, random and 11-bit IDs, random and out-of-range data, FD, time
    going backwards a little, valid frames between."""
    rng = np.random.default_rng(seed)
    wanted = list(wanted_pgns().values())
    t = 0.0
    for _i in range(n):
        t += float(rng.exponential(0.0005))
        if rng.random() < 0.001:
            t -= float(rng.uniform(0, 0.5))
        kind = rng.integers(0, 10)
        dlc = int(rng.integers(0, 9)) if rng.random() < 0.2 else 8
        data = bytes(rng.integers(0, 256, dlc, dtype=np.uint8))
        if kind == 0:
            yield can.Message(timestamp=t, arbitration_id=int(rng.integers(0, 0x800)), is_extended_id=False, data=data)
        elif kind == 1:
            yield can.Message(timestamp=t, is_error_frame=True)
        elif kind == 2:
            yield can.Message(
                timestamp=t,
                arbitration_id=can_id_of(wanted[rng.integers(len(wanted))] & 0x3FF00 if wanted[0] else 0, 0),
                is_extended_id=True,
                is_remote_frame=True,
                dlc=8,
                check=False,
            )
        elif kind == 3:
            yield can.Message(timestamp=t, arbitration_id=int(rng.integers(0, 1 << 29)), is_extended_id=True, data=data)
        elif kind == 4:
            yield can.Message(
                timestamp=t,
                arbitration_id=can_id_of(wanted[0], 0),
                is_extended_id=True,
                is_fd=True,
                data=bytes(rng.integers(0, 256, 12, dtype=np.uint8)),
                check=False,
            )
        elif kind == 5:  # TP.CM / TP.DT with random content and destinations
            pgn = (0xEC00, 0xEB00)[int(rng.integers(0, 2))]
            yield can.Message(
                timestamp=t,
                arbitration_id=can_id_of(pgn, int(rng.integers(0, 4)), 7, int(rng.choice([0xFF, 0x21]))),
                is_extended_id=True,
                data=data,
            )
        else:  # a wanted PGN from a plausible source with random (often out-of-range / n.a.) data
            pgn = wanted[int(rng.integers(len(wanted)))]
            sa = int(rng.choice([0x00, 0x03, 0x10, 0x31]))
            yield can.Message(
                timestamp=t, arbitration_id=can_id_of(pgn, sa, int(rng.integers(0, 8))), is_extended_id=True, data=data
            )


def test_100k_hostile_frames_through_the_service_no_exception_every_rejection_explained():
    svc = SensorService(make_sensor(), ServiceOptions(configured_ref_torque_nm=2500.0), record=True)
    n = 100_000
    out = svc.feed_all(random_frames(n))
    d = svc.decoder.counters
    assert d["frames_seen"] == n
    assert d["frames_seen"] == d["frames_used"] + sum(d["rejected"].values())
    assert set(d["rejected"]) <= set(REJECT_REASONS)
    for reason in (
        "error_frame",
        "remote_frame",
        "not_extended_id",
        "fd_frame",
        "unknown_pgn",
        "wrong_dlc",
        "wrong_source_address",
        "tp_not_broadcast",
    ):
        assert d["rejected"].get(reason, 0) > 0, reason
    assert svc.counters["steps"] > 100
    for m in out:
        assert m.is_extended_id and len(m.data) == 8 and m.arbitration_id & 0xFF == 0xE5
    decode_outputs(out[-17:])  # the frames are well-formed for cantools


# --------------------------------------------------------------------------------------------------- real captures

needs_captures = pytest.mark.skipif(DATA is None, reason=SKIP_REASON)

# README "What a correct decoder finds", at 10 Hz sampling: the sampled range lies inside the README's (half a unit
# of its last digit of slack) and covers most of it
EXPECTED = {
    "normal": {
        "engine_speed_rpm": (1147, 1786, 0.5),
        "gear": (2, 4, 0.5),
        "oil_temp_c": (77.3, 78.2, 0.05),
        "ambient_temp_c": (33.1, 33.1, 0.05),
        "vehicle_speed_kmh": (23.2, 54.9, 0.05),
        "coolant_temp_c": (92, 93, 0.5),
        "engine_torque_pct": (3, 45, 0.5),
    },
    "tsc1": {
        "engine_speed_rpm": (711, 1700, 0.5),
        "gear": (1, 4, 0.5),
        "oil_temp_c": (76.7, 77.6, 0.05),
        "ambient_temp_c": (35.4, 35.6, 0.05),
        "vehicle_speed_kmh": (14.1, 47.5, 0.05),
        "coolant_temp_c": (89, 93, 0.5),
        "engine_torque_pct": (0, 85, 0.5),
    },
    "fuzz_1ms_ID_and_Data": {
        "engine_speed_rpm": (719, 730, 0.5),
        "gear": (0, 0, 0.5),
        "oil_temp_c": (76.3, 77.3, 0.05),
        "ambient_temp_c": (34.5, 34.6, 0.05),
        "vehicle_speed_kmh": (0, 0, 0.5),
        "coolant_temp_c": (90, 90, 0.5),
        "engine_torque_pct": (5, 7, 0.5),
    },
    "utulsa_logger2_drive": {
        "engine_speed_rpm": (409, 1859, 0.5),
        "gear": None,
        "oil_temp_c": None,
        "ambient_temp_c": (21.4, 22.5, 0.05),
        "vehicle_speed_kmh": (0, 52.3, 0.05),
        "coolant_temp_c": (73, 79, 0.5),
        "engine_torque_pct": (0, 73, 0.5),
    },
}
EC1_NM = {"normal": 1109.0, "tsc1": 1109.0, "fuzz_1ms_ID_and_Data": 1109.0, "utulsa_logger2_drive": 2457.0}

_replayed: dict = {}


def replayed(name):
    if name not in _replayed:
        svc = SensorService(make_sensor(), ServiceOptions(), record=True)
        records = []
        handler = logging.Handler()
        handler.emit = records.append
        logger = logging.getLogger("gearbox_vsensor")
        logger.addHandler(handler)
        try:
            out = svc.feed_all(can.LogReader(DATA / f"{name}.candump.log"))
        finally:
            logger.removeHandler(handler)
        _replayed[name] = (svc, svc.recorded(), out, records)
    return _replayed[name]


@needs_captures
@pytest.mark.parametrize("name", CAPTURES)
def test_real_capture_inputs_as_the_readme_says(name):
    svc, rec, out, _ = replayed(name)
    ok = rec["can_time_s"] - rec["can_time_s"][0] > 6.0  # after the first EC1 and the first TRF1
    for col, expected in EXPECTED[name].items():
        values = rec[col][ok]
        if expected is None:
            assert np.isnan(values).all(), col
            continue
        lo, hi, tol = expected
        v = values[np.isfinite(values)]
        assert v.size > 0.9 * values.size, col
        assert lo - tol <= v.min() and v.max() <= hi + tol, (col, v.min(), v.max())
        assert v.max() - v.min() >= 0.5 * (hi - lo) - 2 * tol, (col, v.min(), v.max())
    # EC1 by TP.BAM: the reference torque and the torque in Nm computed from it
    ref = rec["engine_ref_torque_nm"]
    assert set(ref[np.isfinite(ref)]) == {EC1_NM[name]}
    tq = rec["engine_torque_nm"][ok]
    pct = rec["engine_torque_pct"][ok]
    both = np.isfinite(tq) & np.isfinite(pct)
    assert both.mean() > 0.9 and np.allclose(tq[both], pct[both] / 100.0 * EC1_NM[name])
    d = svc.decoder.counters
    assert d["frames_seen"] == d["frames_used"] + sum(d["rejected"].values())


@needs_captures
def test_real_capture_the_cab_node_with_every_byte_ff_is_ignored():
    svc, rec, _, _ = replayed("normal")
    assert np.nanmax(rec["oil_temp_c"]) < 100 and np.nanmax(rec["vehicle_speed_kmh"]) < 60
    assert svc.decoder.counters["rejected"]["wrong_source_address"] > 0


@needs_captures
def test_real_capture_utulsa_runs_degraded_without_gear_and_oil():
    svc, rec, out, _ = replayed("utulsa_logger2_drive")
    assert (rec["gear_valid"] == 0).all() and (rec["oil_valid"] == 0).all()
    assert (rec["degraded_mode"][rec["time_s"] > 3.05] != 0).all()
    status = decode_outputs(out[-40:])["status"]
    assert status["gear_valid"] is False and status["oil_valid"] is False and status["degraded_mode"] != 0
    assert status["speed_valid"] is True and status["ref_torque_valid"] is True


@needs_captures
@pytest.mark.parametrize("name", ["fuzz_1ms_ID_and_Data", "tsc1"])
def test_real_capture_fuzz_and_tsc1_no_crash_no_warning(name):
    svc, rec, out, records = replayed(name)
    assert svc.counters["steps"] >= 295 and svc.counters["time_jumps"] == 0
    assert not [r for r in records if r.levelno >= logging.WARNING], [r.getMessage() for r in records]
    levels = np.column_stack([rec[f"W_{c}"] for c in PUBLISHED])
    assert ((levels == 0) | (levels == 3)).all()
    dm1 = [m for m in out if pgn_of(m.arbitration_id) == 0xFECA]
    assert all(decode_outputs([m])["dm1"]["dtc"] is None for m in dm1)


def test_status_comes_from_the_sensors_status_record():
    import math

    from firmware_model.onboard.sensor import SensorInputs
    from firmware_model.onboard.sensor import VirtualSensor as Real
    from firmware_model.parameters import load_parameters

    sensor = Real(load_parameters("GRS905"))
    svc = SensorService(sensor, ServiceOptions())
    st = sensor.initial_state(T_oil_c=70.0)
    for inp in (
        SensorInputs(1200.0, math.nan, 9.0, 70.0, 20.0, 85.0, 50.0, 0.0),
        SensorInputs(1200.0, 900.0, 9.0, math.nan, 20.0, 85.0, 50.0, 0.0),
    ):
        st, out = sensor.step(st, inp)
        for ref in (None, 2400.0):
            status = svc._status(out.status, ref)
            assert status.torque_valid == bool(out.status.torque_valid)
            assert status.oil_valid == bool(out.status.oil_valid)
            assert status.degraded_mode == int(out.status.degraded_mode)
            assert status.ref_torque_valid == (ref is not None)
            innovation = float(out.status.oil_innovation_c)
            assert status.oil_innovation_c == (innovation if math.isfinite(innovation) else None)
    assert set(status._asdict()) <= set(STATUS_KEYS)  # what the encoder takes


def test_a_sensor_without_the_service_api_is_refused():
    class Wrong(StandIn):
        input_fields = ("speed_rpm", "torque_nm")

    with pytest.raises(ParameterError, match="input_fields"):
        SensorService(Wrong())

    class Slow(StandIn):
        dt_s = 0.2

    with pytest.raises(ParameterError, match="every 0.2 s"):
        SensorService(Slow())


def test_bad_can_settings_are_parameter_errors():
    with pytest.raises(ParameterError, match="source address"):
        SensorService(StandIn(), ServiceOptions(sensor_source_address=300))
    with pytest.raises(ParameterError, match="expected_sa"):
        SensorService(StandIn(), ServiceOptions(expected_sa={"XYZ": 1}))


def test_a_can_fd_frame_moves_no_time():
    """An FD copy of EEC1 first in a log set the step grid's start (can_time_s 0.102 against 0.111) though the
    decoder rejects it (a new user's review): FD frames, like error and remote frames, move no time."""
    first = traffic(1000.0, 1003.0)[0]
    fd = can.Message(
        timestamp=first.timestamp - 0.009,
        arbitration_id=first.arbitration_id,
        is_extended_id=True,
        is_fd=True,
        data=bytes(first.data) + b"\xff" * 4,
        check=False,
    )
    a, b = service(), service()
    a.feed_all(traffic(1000.0, 1003.0))
    b.feed_all([fd, *traffic(1000.0, 1003.0)])
    np.testing.assert_array_equal(b.recorded()["can_time_s"], a.recorded()["can_time_s"])
    assert b.decoder.counters["rejected"]["fd_frame"] == 1
