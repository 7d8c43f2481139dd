"""Unit and sign mistakes of a whole record, and clamps on more than 5 % of the steps, through `replay` (run tables
and CAN logs), `fleet`, `diagnose` and the live service: none of them exits 0 with the wrong numbers."""

import logging
import math

import numpy as np
import pytest

from can_dbc.adapter import can_id_of, decode_outputs, pgn_of
from firmware_model.onboard.sensor import VirtualSensor
from firmware_model.parameters import load_parameters
from firmware_model.service import SensorService, ServiceOptions
from tools.can.logsynth import synth_frames, write_frames
from tools.cli import main
from tools.runtable import RunTable, write_run_table


def drive(minutes=12.0, oil=None, torque_scale=1.0, **cols):
    """A loaded drive, one row a second: the oil warming from 68 to about 92 degC, 1100-1500 rpm, 300-2700 Nm."""
    t = np.arange(0.0, minutes * 60.0, 1.0)
    rng = np.random.default_rng(0)
    base = {
        "time_s": t,
        "engine_speed_rpm": 1100.0 + 400.0 * rng.random(t.size),
        "engine_torque_nm": torque_scale * (1500.0 + 1200.0 * np.sin(t / 90.0)),
        "gear": np.full(t.size, 12.0),
        "vehicle_speed_kmh": np.full(t.size, 60.0),
        "oil_temp_c": 92.0 - 24.0 * np.exp(-t / 900.0) if oil is None else oil(t),
    }
    base.update(cols)
    return RunTable(base)


def degf(t):
    return (92.0 - 24.0 * np.exp(-t / 900.0)) * 1.8 + 32.0


def replay(tmp_path, capsys, table, *extra, name="run.csv"):
    src = write_run_table(table, tmp_path / name)
    out = tmp_path / f"est_{name}"
    rc = main(["replay", str(src), "--out", str(out), "--quiet", *extra])
    return rc, capsys.readouterr().err, out


@pytest.mark.parametrize(
    "minutes, table, words",
    [
        (12.0, dict(oil=degf), "the oil looks like degF, not degC; give degC: (degF - 32) / 1.8"),
        (30.0, dict(oil=degf), "the oil looks like degF"),
        (12.0, dict(oil=lambda t: 92.0 - 24.0 * np.exp(-t / 900.0) + 273.15), "the oil looks like kelvin"),
        (12.0, dict(torque_scale=-1.0), "column engine_torque_nm is below -50 Nm on"),
        (12.0, dict(torque_scale=100.0 / 3000.0), "the torque looks like percent of the reference torque, not N m"),
    ],
)
def test_a_whole_record_in_the_wrong_unit_or_sign_is_untrusted(tmp_path, capsys, minutes, table, words):
    rc, err, out = replay(tmp_path, capsys, drive(minutes, **table))
    assert rc == 3 and words in err and "should not be trusted" in err
    assert out.is_file()
    rc, err, _ = replay(tmp_path, capsys, drive(minutes, **table), "--allow-untrusted", name="again.csv")
    assert rc == 0 and words in err


def test_negative_torque_is_also_a_clamp_on_most_steps(tmp_path, capsys):
    rc, err, _ = replay(tmp_path, capsys, drive(torque_scale=-1.0))
    assert rc == 3 and "the sensor clamped or repaired an input on more than 5 % of its" in err
    assert "engine torque clamped to the engine's range on" in err


def test_a_clamp_on_more_than_5_percent_of_the_steps_is_untrusted(tmp_path, capsys):
    t = np.arange(0.0, 720.0, 1.0)
    high = drive(engine_torque_nm=np.where(t % 10 == 0, 5000.0, 1500.0))  # above 4200 Nm on 10 % of the rows
    rc, err, _ = replay(tmp_path, capsys, high)
    assert rc == 3 and "engine torque clamped to the engine's range on 10 %" in err
    few = drive(engine_torque_nm=np.where(t % 50 == 0, 5000.0, 1500.0))  # 2 %: a line in the summary only
    rc, err, _ = replay(tmp_path, capsys, few, name="few.csv")
    assert rc == 0 and "clamped or repaired" not in err


@pytest.mark.parametrize(
    "oil",
    [
        lambda t: 20.0 + 110.0 * (1.0 - np.exp(-t / 600.0)),  # a hot drive from 20 to 130 degC
        lambda t: -30.0 + 100.0 * (1.0 - np.exp(-t / 1200.0)),  # a cold start at -30 degC
        lambda t: 140.0 + 8.0 * np.sin(t / 300.0),  # hot, 132-148 degC
    ],
)
def test_honest_drives_are_not_flagged(tmp_path, capsys, oil):
    rc, err, _ = replay(tmp_path, capsys, drive(30.0, oil=oil))
    assert rc == 0 and "looks like" not in err and "clamped or repaired" not in err, err


def _log(tmp_path, table, name):
    return write_frames(synth_frames(table, None, rig=False).frames, tmp_path / name)


def test_a_can_log_whose_oil_reads_degf_is_untrusted(tmp_path, capsys):
    log = _log(tmp_path, drive(oil=degf), "degf.log")
    assert main(["replay", str(log), "--out", str(tmp_path / "e.csv"), "--quiet"]) == 3
    err = capsys.readouterr().err
    assert "the oil temperature (TRF1 SPN 177, degC by the DBC) reads" in err and "looks like degF" in err
    honest = _log(tmp_path, drive(), "honest.log")
    assert main(["replay", str(honest), "--out", str(tmp_path / "h.csv"), "--quiet"]) == 0
    assert "looks like" not in capsys.readouterr().err


def test_the_fleet_says_it_per_log(tmp_path):
    pytest.importorskip("pyarrow")
    pytest.importorskip("dask")
    from tools.fleet.manifest import LogEntry
    from tools.fleet.run import process_log

    log = _log(tmp_path, drive(oil=degf), "degf.log")
    kind, row = process_log(LogEntry(log, "truck1", None, None, "2026-01-01", "k1"))
    assert kind == "ok" and not row["trusted"] and "looks like degF" in row["trust_warnings"]


def test_the_diagnosis_refuses_a_file_whose_oil_reads_degf(tmp_path, capsys):
    bad = write_run_table(drive(oil=degf), tmp_path / "degf.csv")
    good = write_run_table(drive(), tmp_path / "good.csv")
    assert main(["diagnose", "--train", str(bad), "--test", str(good), "--json", str(tmp_path / "g.json")]) == 2
    err = capsys.readouterr().err
    assert "degf.csv: column oil_temp_c reads" in err and "looks like degF" in err


# -- the live service ---------------------------------------------------------------------------------------------


def _frame(t, pgn, sa, data, prio=6):
    import can

    return can.Message(timestamp=t, arbitration_id=can_id_of(pgn, sa, prio), is_extended_id=True, data=bytes(data))


def traffic(seconds, oil_c, pct):
    """EEC1 every 10 ms (speed 1300 rpm, torque ``pct`` % of the configured 2000 Nm), ETC2 (gear 12) every 100 ms,
    TRF1 (oil ``oil_c``) every 1 s."""
    raw_rpm, raw_oil = round(1300 / 0.125), round((oil_c + 273) / 0.03125)
    for k in range(int(seconds * 100)):
        t = 0.01 * k + 0.005
        yield _frame(t, 61444, 0x00, [0xF0, pct + 125, pct + 125, raw_rpm & 0xFF, raw_rpm >> 8, 0, 0xFF, 0xFF], 3)
        if k % 10 == 3:
            yield _frame(t + 0.001, 61445, 0x03, [137, 0xFF, 0xFF, 137, 0xFF, 0xFF, 0xFF, 0xFF])
        if k % 100 == 4:
            yield _frame(t + 0.002, 65272, 0x03, [0xFF] * 4 + [raw_oil & 0xFF, raw_oil >> 8, 0xFF, 0xFF])


@pytest.fixture(scope="module")
def sensor():
    return VirtualSensor(load_parameters("GRS905"))


def _run(sensor, seconds, oil_c, pct, caplog=None):
    svc = SensorService(sensor, ServiceOptions(configured_ref_torque_nm=2000.0))
    sent = []
    for m in traffic(seconds, oil_c, pct):
        sent += svc.feed(m)
    return svc, [f for f in sent if pgn_of(f.arbitration_id) == 0xFECA]


def test_the_live_service_finds_degf_oil_after_its_first_minute(sensor, caplog, tmp_path):
    from firmware_model.service.persist import HealthFile, read_health
    from tools.cli.status import status_lines

    svc, _ = _run(sensor, 50.0, 180.0, 40)
    assert "record_findings" not in svc.counters and not [f for f in svc.findings() if f.kind == "plausibility"]
    with caplog.at_level(logging.WARNING, logger="gearbox_vsensor.can_service"):
        svc, _ = _run(sensor, 65.0, 180.0, 40)
    found = [f for f in svc.findings() if f.kind == "plausibility"]
    assert len(found) == 1 and found[0].likely == "degF"
    logged = [r.getMessage() for r in caplog.records if "looks like degF" in r.getMessage()]
    assert len(logged) == 1  # logged once
    health = tmp_path / "health.json"
    HealthFile(health).maybe_write(svc)
    doc = read_health(health)
    assert doc["findings"][0]["kind"] == "plausibility" and doc["findings"][0]["severity"] == "untrusted"
    assert any(
        line.startswith("finding (untrusted): the oil temperature (TRF1 SPN 177") for line in status_lines(doc, 0.0)
    )


def test_the_live_service_names_the_input_in_dm1(sensor):
    """Torque at -60 % of 2000 Nm: clamped to the engine's -1000 Nm on every step; after the first minute DM1
    carries SPN 513 (actual engine percent torque) with FMI 2 (data incorrect) and the amber lamp."""
    svc, dm1 = _run(sensor, 70.0, 80.0, -60)
    assert [f.kind for f in svc.findings() if f.kind == "repair"] == ["repair"]
    before = decode_outputs([m for m in dm1 if m.timestamp < 59.0][-1:])["dm1"]
    after = decode_outputs(dm1[-1:])["dm1"]
    assert before["dtc"] is None or before["dtc"]["fmi"] != 2
    assert after["dtc"]["spn"] == 513 and after["dtc"]["fmi"] == 2 and after["amber_warning_lamp"] == 1
    assert math.isfinite(svc.counters["steps"])


def test_simulate_refuses_a_cycle_in_the_wrong_unit(tmp_path, capsys):
    """simulate ran a torque column in percent as a coasting truck, and degF oil with --cooler measured as a sump
    at 180 degC, without a word."""
    pct = write_run_table(drive(torque_scale=100.0 / 3000.0), tmp_path / "pct.csv")
    assert main(["simulate", "--cycle", str(pct), "--out", str(tmp_path / "p.csv"), "--quiet"]) == 2
    assert "looks like percent" in capsys.readouterr().err
    oil = write_run_table(drive(oil=degf), tmp_path / "degf.csv")
    assert (
        main(["simulate", "--cycle", str(oil), "--cooler", "measured", "--out", str(tmp_path / "o.csv"), "--quiet"])
        == 2
    )
    assert "looks like degF" in capsys.readouterr().err


def test_a_fixed_ratio_gearbox_s_oil_in_degf_while_it_warms_is_untrusted(tmp_path, capsys):
    """The HR225 warming from 20 degC at rated load, its sump written in degF (68-136): within the range rule's degC
    (a hot gearbox), it passed with exit 0 and false warnings; beside the sensor's own sump it is exit 3."""
    import numpy as np

    from tools.runtable import RunTable, read_run_table, write_run_table

    t = np.arange(0.0, 4 * 3600.0 + 1.0, 10.0)
    cyc = tmp_path / "rig.csv"
    write_run_table(
        RunTable(
            {
                "time_s": t,
                "input_speed_rpm": np.full(t.size, 1480.0),
                "input_torque_nm": np.full(t.size, 700.0),
                "ambient_temp_c": np.full(t.size, 25.0),
            }
        ),
        cyc,
    )
    run = tmp_path / "run.csv"
    assert main(["simulate", "--gearbox", "HR225", "--cycle", str(cyc), "--out", str(run), "--quiet"]) == 0
    tb = read_run_table(run, required=("time_s",))
    rows = {
        "time_s": tb["time_s"],
        "input_speed_rpm": tb["input_speed_rpm"],
        "input_torque_nm": tb["input_torque_nm"],
        "ambient_temp_c": tb["ambient_temp_c"],
    }
    good, bad = tmp_path / "good.csv", tmp_path / "degf.csv"
    write_run_table(RunTable({**rows, "oil_temp_c": tb["T_oil_c"]}), good)
    write_run_table(RunTable({**rows, "oil_temp_c": tb["T_oil_c"] * 1.8 + 32.0}), bad)
    capsys.readouterr()
    assert main(["replay", str(good), "--gearbox", "HR225", "--out", str(tmp_path / "g.csv")]) == 0
    assert "looks like degF" not in capsys.readouterr().err
    assert main(["replay", str(bad), "--gearbox", "HR225", "--out", str(tmp_path / "b.csv")]) == 3
    err = capsys.readouterr().err
    assert "above the sensor's own modelled sump on median" in err and "the oil looks like degF, not degC" in err


def test_a_rigs_held_sump_is_not_judged_against_the_model_in_a_log_or_a_table(tmp_path, capsys):
    """A rig holding its sump at 100 degC (`[cooler] kind = "hold"`), its run written as a CAN log and a run table,
    replayed with the rig's configuration: the model's own sump (no cooler) means nothing there, and the log's
    replay said "the oil temperature runs 26 K below the sensor's own modelled sump" (the run table's did not)."""
    cfg = tmp_path / "rig.toml"
    cfg.write_text('[cooler]\nkind = "hold"\n[simulate]\nhold_oil_c = 100\n')
    log, csv = tmp_path / "rig.log", tmp_path / "rig.csv"
    cycle = "steady:gear=10,rpm=1300,nm=2000,s=1900,oil=100"
    sim = ["simulate", "--cycle", cycle, "--config", str(cfg), "--out", str(csv), "--can-log", str(log), "--quiet"]
    assert main(sim) == 0
    capsys.readouterr()
    for source in (log, csv):
        assert main(["replay", str(source), "--config", str(cfg), "--out", str(tmp_path / "e.csv")]) == 0
        err = capsys.readouterr().err
        assert "modelled sump" not in err, (source.name, err)
