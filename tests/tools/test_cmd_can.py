"""The CAN subcommands through the CLI: `simulate --can-log`, `replay LOG`, `play LOG`, `plant`, `run`."""

from __future__ import annotations

import sys
import uuid
from collections import Counter

import can
import numpy as np
import pytest

from can_dbc.adapter import decode_outputs, pgn_of
from tools.cli import build_parser, main
from tools.runtable import read_run_table

STEADY = "steady:gear=4L,rpm=1300,nm=2000,s=30"


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    d = tmp_path_factory.mktemp("cmd_can")
    rc = main(["simulate", "--cycle", STEADY, "--out", str(d / "run.csv"), "--can-log", str(d / "run.log"), "--quiet"])
    assert rc == 0
    return d


def drain(bus):
    out = []
    while (m := bus.recv(0)) is not None:
        out.append(m)
    return out


def test_simulate_can_log_then_replay_it(sim, capsys):
    out = sim / "est.csv"
    assert main(["replay", str(sim / "run.log"), "--out", str(out), "--frames-out", str(sim / "gbx.log")]) == 0
    assert "replayed" in capsys.readouterr().out
    est = read_run_table(out, required=("time_s",))
    plant = read_run_table(sim / "run.csv")
    assert 297 <= est.n <= 299 and np.allclose(np.diff(est["time_s"]), 0.1)
    assert np.nanmax(np.abs(est["engine_speed_rpm"][5:] - 1300.0)) <= 0.125
    assert np.nanmax(np.abs(est["engine_torque_nm"][5:] - 2000.0)) <= 30.0  # 1 % of the 3000 Nm reference
    for c in ("PS", "oil", "BO"):  # rig thermocouples = the plant's truth, within the 1/32 degC quantisation
        meas = est[f"meas_T_{c}_c"][-1]
        truth = np.interp(est["time_s"][-1] - 0.125, plant["time_s"], plant[f"T_{c}_c"])
        assert abs(meas - truth) < 0.05, c
    assert (est["degraded_mode"][20:] == 0).all()
    frames = list(can.LogReader(sim / "gbx.log"))
    assert len([m for m in frames if pgn_of(m.arbitration_id) == 0xFF4F]) == est.n
    last = decode_outputs(frames[-17:])
    assert abs(last["temps_c"]["PS"] - est["T_PS_c"][-1]) <= 1 / 64


@pytest.mark.parametrize("speed", ["0", "-1", "nan"])
def test_play_at_a_speed_that_is_no_positive_number_is_one_sentence(sim, capsys, speed):
    """--speed 0 on a bus that stamps on arrival was a ZeroDivisionError traceback (the warning divided by it)."""
    args = ["play", str(sim / "run.log"), "--interface", "socketcan", "--channel", "vcan0", "--speed", speed]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert f"--speed {speed} must be a positive number" in err and "Traceback" not in err and "warning" not in err


def test_play_skips_a_malformed_line_as_replay_does_and_says_so(sim, tmp_path, capsys):
    """A line of noise in the middle of a log stopped play half-way (exit 2, the frames before it already on the
    bus); replay skips and counts it. play now checks the log first, plays every frame around it and names the log
    and the line in its note."""
    lines = (sim / "run.log").read_text().splitlines()
    mid = len(lines) // 2
    (tmp_path / "noisy.log").write_text("\n".join(lines[:mid] + ["#### logger hiccup ####"] + lines[mid:]) + "\n")
    ch = f"rt-{uuid.uuid4()}"
    mon = can.Bus(interface="virtual", channel=ch)
    assert (
        main(["play", str(tmp_path / "noisy.log"), "--interface", "virtual", "--channel", ch, "--speed", "1000"]) == 0
    )
    got = drain(mon)
    mon.shutdown()
    assert len(got) == len(lines)
    # named with the log's file, as replay says it (the sentence alone did not say which log)
    assert f"note: noisy.log: 1 malformed line skipped (line {mid + 1})\n" in capsys.readouterr().err


def test_play_plays_the_log_onto_a_bus(sim, capsys):
    ch = f"rt-{uuid.uuid4()}"
    mon = can.Bus(interface="virtual", channel=ch)
    assert main(["play", str(sim / "run.log"), "--interface", "virtual", "--channel", ch, "--speed", "100"]) == 0
    got = drain(mon)
    mon.shutdown()
    want = list(can.LogReader(sim / "run.log"))
    assert [(m.arbitration_id, bytes(m.data)) for m in got] == [(m.arbitration_id, bytes(m.data)) for m in want]
    out = capsys.readouterr()
    assert f"played {len(want)} frames" in out.out
    # as run and plant say: a virtual bus reaches this process only (its --help example reached nobody)
    assert "note: --interface virtual joins only buses inside this one process" in out.err


def test_replay_errors_are_one_sentence(sim, capsys, monkeypatch):
    assert main(["replay", str(sim / "run.log")]) == 2
    assert "--out" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["play", str(sim / "run.log")])
    assert exc.value.code == 2 and "--interface, --channel" in capsys.readouterr().err
    (sim / "x.mf4").write_bytes(b"\0" * 16)
    monkeypatch.setitem(sys.modules, "asammdf", None)
    assert main(["replay", str(sim / "x.mf4"), "--out", str(sim / "o.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "asammdf" in err and "[mf4]" in err


def test_plant_streams_inputs_and_rig_frames(capsys):
    ch = f"hil-{uuid.uuid4()}"
    mon = can.Bus(interface="virtual", channel=ch)
    assert (
        main(
            [
                "plant",
                "--interface",
                "virtual",
                "--channel",
                ch,
                "--cycle",
                STEADY,
                "--speed",
                "100",
                "--duration",
                "10",
                "--quiet",
            ]
        )
        == 0
    )
    got = drain(mon)
    mon.shutdown()
    pgns = {}
    for m in got:
        pgns[pgn_of(m.arbitration_id)] = pgns.get(pgn_of(m.arbitration_id), 0) + 1
    assert 500 <= pgns[61444] <= 1000 and 95 <= pgns[61445] <= 101 and 9 <= pgns[65272] <= 11
    assert all(95 <= pgns[p] <= 101 for p in range(0xFF50, 0xFF57))
    bams = Counter(m.arbitration_id & 0xFF for m in got if pgn_of(m.arbitration_id) == 0xEC00)
    assert bams[0x00] == 2 and bams[0x10] == (2 if 61440 in pgns else 0)  # EC1 every 5 s; RC with ERC1
    # a sensor on the bus gets the same from it as from the log: decode one step of the rig
    from can_dbc.adapter import decode_rig

    rig = decode_rig([m for m in got if 0xFF50 <= pgn_of(m.arbitration_id) <= 0xFF56][-7:])
    assert len(rig) == 28 and all(20.0 < v < 200.0 for v in rig.values())


def test_run_and_plant_help_explain_every_option(capsys):
    parser = build_parser()
    for cmd, options in (
        # --bitrate, --log-level (run, plant), --quiet (play) and --strict (replay) moved to the configuration
        ("run", ["--interface", "--channel", "--config", "bitrate_bit_s", "--duration", "log_level"]),
        ("plant", ["--interface", "--channel", "--cycle", "--speed", "--config", "--effect", "bitrate_bit_s"]),
        ("play", ["--interface", "--channel", "--bitrate", "--speed"]),
        ("replay", ["--frames-out", "strict"]),
    ):
        with pytest.raises(SystemExit):
            parser.parse_args([cmd, "--help"])
        text = capsys.readouterr().out
        for opt in options:
            assert opt in text, (cmd, opt)


def test_a_simulated_log_carries_its_retarder_reference_so_replay_needs_no_config(tmp_path, capsys):
    """A cycle with retarder torque written as a log: RC (SPN 556) in the log gives the replay the reference torque
    the ERC1 percent refers to (the log once needed [can] retarder_reference_torque_nm in the replay's config)."""
    from tools.runtable import RunTable, write_run_table

    t = np.arange(0.0, 30.0, 1.0)
    cyc = RunTable(
        {
            "time_s": t,
            "engine_speed_rpm": np.full(t.size, 1200.0),
            "engine_torque_nm": np.zeros(t.size),
            "gear": np.full(t.size, 12.0),
            "retarder_torque_nm": np.full(t.size, 800.0),
        }
    )
    write_run_table(cyc, tmp_path / "down.csv")
    assert (
        main(
            [
                "simulate",
                "--cycle",
                str(tmp_path / "down.csv"),
                "--out",
                str(tmp_path / "r.csv"),
                "--can-log",
                str(tmp_path / "r.log"),
                "--quiet",
            ]
        )
        == 0
    )
    assert "retarder_reference_torque_nm" not in capsys.readouterr().err
    main(["replay", str(tmp_path / "r.log"), "--out", str(tmp_path / "e.csv"), "--quiet"])
    est = np.genfromtxt(tmp_path / "e.csv", delimiter=",", names=True)
    braking = est["retarder_torque_nm"][est["time_s"] > 6.0]
    assert np.all(np.abs(braking - 800.0) <= 0.5 * 3500.0 / 100.0), braking  # within half a percent step


def test_bus_problems_are_one_sentence_and_virtual_says_it_is_in_process(capsys, monkeypatch):
    """A vendor driver without its library (kvaser: NameError) is one sentence, not a traceback; plant refuses
    --bitrate 5; plant on --interface virtual says its frames reach no other process."""
    assert main(["plant", "--interface", "virtual", "--channel", "x", "--cycle", STEADY, "--bitrate", "5"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--bitrate 5 must be a CAN bit rate" in err

    def broken_driver(**kwargs):
        raise NameError("name 'canGetNumberOfChannels' is not defined")

    monkeypatch.setattr(can, "Bus", broken_driver)
    assert main(["plant", "--interface", "kvaser", "--channel", "0", "--cycle", STEADY]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "its driver failed (NameError" in err
    monkeypatch.undo()
    ch = f"hil-{uuid.uuid4()}"
    assert (
        main(
            [
                "plant",
                "--interface",
                "virtual",
                "--channel",
                ch,
                "--cycle",
                STEADY,
                "--speed",
                "100",
                "--duration",
                "1",
                "--quiet",
            ]
        )
        == 0
    )
    assert "joins only buses inside this one process" in capsys.readouterr().err


def test_sigterm_while_the_plant_computes_is_an_interrupt():
    """SIGTERM during the plant's precomputation is an interrupt as Ctrl-C is, not a death without a word or a bus
    shutdown, and the handler before it comes back."""
    import os
    import signal

    from tools.cli.plant import _term_interrupts

    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(KeyboardInterrupt):
        with _term_interrupts():
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(1000):  # the handler runs between bytecodes
                pass
    assert signal.getsignal(signal.SIGTERM) is before


def test_a_bus_that_fails_to_open_leaves_no_teardown_message(capsys, caplog):
    """A udp_multicast bus with a channel that is no address: one sentence, and none of python-can's "... was not
    properly shut down" for the half-built bus after it."""
    import logging

    pytest.importorskip("msgpack", reason="python-can's udp_multicast needs msgpack")
    with caplog.at_level(logging.WARNING):
        assert (
            main(["plant", "--interface", "udp_multicast", "--channel", "notanaddress", "--cycle", STEADY, "--quiet"])
            == 2
        )
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot open CAN channel 'notanaddress'" in err
    assert not [r for r in caplog.records if "not properly shut down" in r.getMessage()]


def test_a_kernel_without_socketcan_is_said_so(monkeypatch):
    """'[Errno 97] Address family not supported by protocol' for can0, vcan0 and '' alike did not say the kernel
    has no SocketCAN: the sentence now says so and what to do (python-can's error as a kernel without CAN gives it)."""
    import errno

    from firmware_model.errors import InputError
    from tools.can.bus import open_bus

    def no_af_can(**kwargs):
        raise OSError(errno.EAFNOSUPPORT, "Address family not supported by protocol")

    monkeypatch.setattr(can, "Bus", no_af_can)
    with pytest.raises(InputError, match=r"\[Errno 97\].*this kernel has no SocketCAN: load its modules"):
        open_bus("socketcan", "can0")


def test_plant_sends_another_gearboxs_rig_frames_in_its_own_dbc(tmp_path):
    """plant --gearbox HR225 sent the GRS905's seven RIG_TC messages (0xFF50-0xFF56), every value but the oil "not
    available": the true temperatures of P, W and B1-B4 never reached the bus. Now the HR225's own DBC's rig
    messages (as simulate --can-log and export-dbc lay them out), every published component decoded."""
    from can_dbc.dbc import for_components
    from firmware_model.description import description_of
    from firmware_model.onboard.reduce import published_ids
    from firmware_model.parameters import load_parameters

    cycle = tmp_path / "hr.csv"  # a fixed-ratio drive: the input shaft at 1100 rpm and 1000 N m for 10 s
    cycle.write_text(
        "time_s,input_speed_rpm,input_torque_nm,ambient_temp_c\n" + "".join(f"{t},1100,1000,25\n" for t in range(11))
    )
    ch = f"hil-{uuid.uuid4()}"
    mon = can.Bus(interface="virtual", channel=ch)
    argv = ["plant", "--gearbox", "HR225", "--interface", "virtual", "--channel", ch, "--speed", "100"]
    assert main([*argv, "--cycle", str(cycle), "--quiet"]) == 0
    got = drain(mon)
    mon.shutdown()
    ids = published_ids(description_of(load_parameters("HR225")))
    db = for_components(ids)
    rig_ids = {m.frame_id for m in db.database.messages if m.name.startswith("RIG_TC")}
    assert rig_ids and rig_ids.isdisjoint({0x18FF50F0 + (k << 8) for k in range(7)} - rig_ids)
    seen = {}
    for m in got:
        if m.arbitration_id in rig_ids:
            seen.update(db.database.decode_message(m.arbitration_id, m.data, decode_choices=False))
    temps = {k: v for k, v in seen.items() if k.startswith("TC_")}
    assert {f"TC_{c}" for c in ids} <= set(temps) and all(10.0 < v < 200.0 for v in temps.values()), temps


def test_plant_says_which_boundary_temperatures_the_bus_cannot_carry(capsys):
    """simulate --can-log says that a log carries no boundary temperatures where the cycle's differ from the
    gearbox's own (the sensor then takes its own: a gap in a diagnosis); plant streamed the same frames without a
    word. Both say it now, in one sentence each."""
    ch = f"hil-{uuid.uuid4()}"
    argv = ["plant", "--interface", "virtual", "--channel", ch, "--cycle", "uphill", "--duration", "5"]
    assert main([*argv, "--speed", "100", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "note: the bus carries no boundary temperatures" in err and "hot_surroundings 100 (its own 90)" in err
