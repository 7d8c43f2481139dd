"""The commands say when their outputs cannot be trusted, and refuse implausible temperatures:

- `replay LOG` with a wrong engine source address: the foreign frames and the degraded share on stderr, exit 3
  (--allow-untrusted: 0), the outputs written; a run-table replay degraded most of the time likewise;
- a bus replayed faster than real time with frames stamped on arrival (python-can's virtual bus without preserved
  timestamps, as socketcan and udp_multicast do): the live service flags the time base (log line, GBX_STATUS
  TimeBaseSuspect, finding); `plant --speed X` warns on such buses and keeps the timestamps on the virtual bus;
- temperature options outside the oil model's range are one-sentence errors with nothing written.
"""

from __future__ import annotations

import logging
import threading
import time
import uuid

import can
import numpy as np
import pytest

from can_dbc.adapter import decode_outputs, pgn_of
from firmware_model.service import SensorService, ServiceOptions, can_filters, serve
from firmware_model.service.trust import TimeBaseFinding
from tools.cli import main
from tools.runtable import RunTable, read_run_table, write_run_table

from ..firmware_model.sensor_standin import VirtualSensor as StandIn

STEADY = "steady:gear=4L,rpm=1300,nm=2000,s=30"


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    d = tmp_path_factory.mktemp("trust")
    assert (
        main(["simulate", "--cycle", STEADY, "--out", str(d / "run.csv"), "--can-log", str(d / "run.log"), "--quiet"])
        == 0
    )
    (d / "wrong_sa.toml").write_text("[can]\nengine_source_address = 0x01\n")
    return d


def test_replay_with_a_wrong_engine_source_address_says_so_and_exits_3(sim, capsys):
    out = sim / "est.csv"
    rc = main(["replay", str(sim / "run.log"), "--config", str(sim / "wrong_sa.toml"), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 3
    assert "warning: EEC1 (PGN 61444) arrived " in err
    assert " times from SA 0x00 but [can] expects SA 0x01 (engine_source_address): check the source addresses" in err
    assert "warning: the sensor ran degraded on 100 % of" in err and "engine speed 100 %" in err
    assert "--allow-untrusted" in err
    est = read_run_table(out, required=("time_s",))  # the outputs are written all the same
    assert est.n > 250 and (est["degraded_mode"][30:] == 2).all()


def test_allow_untrusted_exits_0_with_the_same_warnings(sim, capsys):
    rc = main(
        [
            "replay",
            str(sim / "run.log"),
            "--config",
            str(sim / "wrong_sa.toml"),
            "--out",
            str(sim / "est_allowed.csv"),
            "--quiet",
            "--allow-untrusted",
        ]
    )
    err = capsys.readouterr().err
    assert rc == 0 and "warning: EEC1 (PGN 61444)" in err and "warning: the sensor ran degraded" in err


def test_replay_with_the_right_addresses_is_quiet(sim, capsys):
    assert main(["replay", str(sim / "run.log"), "--out", str(sim / "est_ok.csv")]) == 0
    assert "warning" not in capsys.readouterr().err


def test_table_replay_degraded_most_of_the_run_says_so_and_exits_3(tmp_path, capsys):
    t = np.arange(0.0, 60.0, 0.1)
    gear = np.full(t.size, 9.0)
    gear[100:] = np.nan  # the gear stops after 10 s
    table = RunTable(
        {
            "time_s": t,
            "engine_speed_rpm": np.full(t.size, 1300.0),
            "engine_torque_nm": np.full(t.size, 2000.0),
            "gear": gear,
            "oil_temp_c": np.full(t.size, 80.0),
        }
    )
    src = write_run_table(table, tmp_path / "run.csv")
    rc = main(["replay", str(src), "--out", str(tmp_path / "est.csv"), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 3 and "warning: the sensor ran degraded on 83 % of 599 steps" in err and "gear 83 %" in err
    assert (tmp_path / "est.csv").is_file()


# ------------------------------------------------------------------------------------------------ the time base


@pytest.fixture(scope="module")
def hil_frames():
    from tools.can.hil import prepare

    frames, _ = prepare("uphill", duration_s=120.0)
    return frames


def live_on_virtual_bus(frames, *, speed, preserve):
    """Stream the plant's frames ``speed`` x faster onto a virtual bus while the service (time-base windows of 2 s,
    two in a row) runs on it; ``preserve`` False: the bus stamps frames on arrival, like socketcan."""
    from tools.can.hil import stream

    channel = f"trust-{uuid.uuid4()}"
    svc_bus = can.Bus(interface="virtual", channel=channel, can_filters=can_filters())
    player = can.Bus(interface="virtual", channel=channel, preserve_timestamps=preserve)
    monitor = can.Bus(interface="virtual", channel=channel)
    service = SensorService(
        StandIn(), ServiceOptions(configured_ref_torque_nm=3000.0, time_base_window_s=2.0, time_base_windows=2)
    )
    stop = threading.Event()
    worker = threading.Thread(target=lambda: serve(svc_bus, service, stop=stop), daemon=True)
    worker.start()
    try:
        stream(frames, player, speedup=speed)
        time.sleep(0.3)
    finally:
        stop.set()
        worker.join(10.0)
        for bus in (svc_bus, player):
            bus.shutdown()
    statuses = []
    while (m := monitor.recv(0)) is not None:
        if pgn_of(m.arbitration_id) == 0xFF4F:
            statuses.append(decode_outputs([m])["status"]["time_base_suspect"])
    monitor.shutdown()
    return service, statuses


def test_a_bus_replayed_20x_faster_with_arrival_stamps_is_flagged(hil_frames, caplog):
    with caplog.at_level(logging.WARNING, logger="gearbox_vsensor.can_service"):
        service, statuses = live_on_virtual_bus(hil_frames, speed=20.0, preserve=False)
    found = [f for f in service.findings() if isinstance(f, TimeBaseFinding)]
    assert len(found) == 1 and found[0].direction == "faster" and 15.0 < found[0].ratio < 25.0
    assert sum("time base suspect" in r.getMessage() for r in caplog.records) == 1
    assert statuses[0] is None and statuses[-1] is True  # GBX_STATUS TimeBaseSuspect: no finding, then suspect
    # the health file's time_base (status warns with it) carries the logged sentence
    from firmware_model.service.persist import time_base_health

    tb = time_base_health(service.counters["time_base"])
    assert tb["suspect"] and tb["sentence"] == found[0].sentence


def test_the_same_stream_with_the_plants_timestamps_is_not_flagged(hil_frames):
    service, statuses = live_on_virtual_bus(hil_frames, speed=20.0, preserve=True)
    assert service.counters["time_base"]["windows_checked"] >= 20
    assert not [f for f in service.findings() if f.kind == "time_base"] and set(statuses) == {None}


def test_plant_warns_about_speed_on_a_bus_that_stamps_on_arrival(capsys, monkeypatch):
    import tools.can.bus as bus_mod

    channel = f"plant-{uuid.uuid4()}"
    monkeypatch.setattr(bus_mod, "open_player", lambda *a, **k: can.Bus(interface="virtual", channel=channel))
    assert (
        main(
            [
                "plant",
                "--interface",
                "socketcan",
                "--channel",
                "vcan0",
                "--cycle",
                STEADY,
                "--speed",
                "10",
                "--duration",
                "1",
                "--quiet",
            ]
        )
        == 0
    )
    err = capsys.readouterr().err
    assert err.count("plant: warning:") == 1 and "--speed 10 on socketcan" in err and "stamp frames on arrival" in err
    assert "use --speed 1" in err and "gearbox-vsensor replay RUN.log" in err
    assert (
        main(
            ["plant", "--interface", "socketcan", "--channel", "vcan0", "--cycle", STEADY, "--duration", "1", "--quiet"]
        )
        == 0
    )
    assert "warning" not in capsys.readouterr().err


def test_plant_on_the_virtual_bus_keeps_its_timestamps_and_does_not_warn(capsys):
    channel = f"plant-{uuid.uuid4()}"
    monitor = can.Bus(interface="virtual", channel=channel)
    assert (
        main(
            [
                "plant",
                "--interface",
                "virtual",
                "--channel",
                channel,
                "--cycle",
                STEADY,
                "--speed",
                "100",
                "--duration",
                "5",
                "--quiet",
            ]
        )
        == 0
    )
    stamps = []
    while (m := monitor.recv(0)) is not None:
        stamps.append(m.timestamp)
    monitor.shutdown()
    assert "warning" not in capsys.readouterr().err
    assert 0.0 <= min(stamps) and max(stamps) <= 5.1  # the plant's frame time, not the wall clock


# ----------------------------------------------------------------------------------------- temperature options


@pytest.mark.parametrize(
    "argv, option",
    [
        (["simulate", "--cycle", STEADY, "--initial-temp", "-300"], "--initial-temp -300.0 degC"),
        (["simulate", "--cycle", STEADY, "--initial-temp", "500"], "--initial-temp 500.0 degC"),
        (["simulate", "--cycle", STEADY, "--hold-oil", "900"], "--hold-oil 900.0 degC"),
        (["simulate", "--cycle", STEADY, "--hold-oil", "nan"], "--hold-oil nan degC"),
        (["simulate", "--cycle", STEADY + ",oil=250"], "oil 250.0 degC"),
        (["simulate", "--cycle", STEADY + ",init=-41"], "init -41.0 degC"),
    ],
)
def test_implausible_temperatures_are_refused_in_one_sentence(tmp_path, capsys, argv, option):
    out = tmp_path / "out.csv"
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and option in err and "-40..200 degC" in err
    assert not out.exists()


def test_replay_refuses_an_implausible_initial_temperature(sim, tmp_path, capsys):
    for src in (sim / "run.csv", sim / "run.log"):
        out = tmp_path / "est.csv"
        assert main(["replay", str(src), "--initial-temp", "-300", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "--initial-temp -300.0 degC" in err and not out.exists()


def test_the_limits_of_the_range_are_accepted(tmp_path):
    for value in ("-40", "200"):
        assert (
            main(
                [
                    "simulate",
                    "--cycle",
                    "steady:gear=4L,rpm=1300,nm=2000,s=10",
                    "--initial-temp",
                    value,
                    "--out",
                    str(tmp_path / "ok.csv"),
                    "--quiet",
                ]
            )
            == 0
        )


@pytest.mark.parametrize(
    "argv, words",
    [
        (["simulate", "--cycle", STEADY, "--noise", "--seed", "-5", "--out", "x.csv"], "--seed -5"),
        (["simulate", "--cycle", STEADY, "--out-dt", "nan", "--out", "x.csv"], "--out-dt nan"),
        (["plant", "--interface", "virtual", "--channel", "x", "--cycle", STEADY, "--seed", "-1"], "--seed -1"),
        (["bench-diagnosis", "--train-s", "-5"], "--train-s -5.0"),
        (["demo", "--print-every", "0"], "--print-every 0.0"),
    ],
)
def test_other_options_out_of_range_are_one_sentence_errors(tmp_path, monkeypatch, capsys, argv, words):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err


def test_the_diagnosis_refuses_a_log_recorded_on_a_wrong_clock(tmp_path):
    """A log recorded from a bus replayed 10x faster with arrival stamps: 400 s of drive in 40 s of frame time."""
    from firmware_model.errors import InputError
    from tools.can.logsynth import write_can_log
    from tools.cycles.named import get_cycle
    from tools.diagnosis.prepare import load_table

    from .can_fixtures import plant_output

    cycle = get_cycle("steady:gear=4L,rpm=1300,nm=2000,s=400", rate_hz=10.0)
    real = tmp_path / "real.log"
    write_can_log(cycle, plant_output(cycle), real)
    fast = tmp_path / "fast.log"
    with can.Logger(fast) as out:
        for m in can.LogReader(real):
            m.timestamp /= 10.0
            out.on_message_received(m)
    assert load_table(real).n > 3000
    with pytest.raises(InputError, match="time base suspect: the input messages arrive about 10.0x faster"):
        load_table(fast)
