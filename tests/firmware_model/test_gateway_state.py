"""The gateway keeps the sensor state across ignition cycles and shows its health (issue: in-vehicle gateway).

State saves are atomic and rate-bounded; a restart restores the state cooled for the time off and reconciled with
the first oil reading; a missing, corrupt, truncated or foreign file means a cold start, logged and counted; the
health file feeds `gearbox-vsensor status`; systemd gets READY=1 / WATCHDOG=1 over its notify socket."""

from __future__ import annotations

import base64
import json
import shutil
import socket
import subprocess

import numpy as np
import pytest

from can_dbc.adapter import decode_outputs, pgn_of
from firmware_model.onboard.sensor import VirtualSensor
from firmware_model.parameters import load_parameters
from firmware_model.service import SensorService, ServiceOptions
from firmware_model.service.persist import HealthFile, StateStore, read_health, sd_notify
from tests.firmware_model.test_can_service import traffic


class Clock:
    def __init__(self, t=1.0e9):
        self.t = t

    def __call__(self):
        return self.t


@pytest.fixture(scope="module")
def params():
    return load_parameters("GRS905")


def _service(params):
    return SensorService(VirtualSensor(params), ServiceOptions(configured_ref_torque_nm=2000.0))


def _drive(svc, t0, t1, oil=80.0):
    svc.feed_all(traffic(t0, t1, rpm=1500.0, oil=oil, gear=9))
    svc.finish_pending()


def test_saved_state_is_restored_cooled_and_reconciled(params, tmp_path):
    clock = Clock()
    first = _service(params)
    _drive(first, 0.0, 120.0)  # two minutes of driving: components above the oil
    store = StateStore(tmp_path / "state.json", period_s=60.0, clock=clock)
    assert store.save(first, final=True) and store.counters["saves"] == 1  # SIGTERM at the ignition off
    saved_T = np.array(first.state.T_c)
    # the gateway restarts 10 minutes later
    clock.t += 600.0
    second = _service(params)
    restore = StateStore(tmp_path / "state.json", clock=clock).load(second.sensor)
    assert restore is not None and restore[1] == pytest.approx(600.0)
    second.restore = restore
    _drive(second, 5000.0, 5001.0, oil=79.0)
    assert second.counters.get("state_restored") is True
    cooled = second.sensor.cool_down(saved_T[0], 600.0, 25.0)
    spread_saved = np.ptp(saved_T[0])
    assert spread_saved > 2.0  # the drive left gradients to keep
    # after the restart the main copy starts from the cooled state (the oil replaced by the reading), not flat
    assert np.ptp(np.array(second.state.T_c)[0]) > 0.2 * np.ptp(cooled)


@pytest.mark.parametrize(
    "content, reason",
    [
        (None, "no saved state"),
        (b'{"schema": "vsensor-state/1", "snap', "unreadable or truncated"),
        (b"\x00\xff garbage", "unreadable or truncated"),
        (json.dumps({"schema": "vsensor-state/1", "variant": "GRSO905", "nodes": ["a"]}).encode(), "another gearbox"),
        (json.dumps({"schema": "something/else"}).encode(), "schema"),
    ],
)
def test_unusable_state_means_a_counted_cold_start(params, tmp_path, content, reason, caplog):
    path = tmp_path / "state.json"
    if content is not None:
        path.write_bytes(content)
    store = StateStore(path)
    svc = _service(params)
    assert store.load(svc.sensor) is None
    assert store.counters["cold_starts"] == 1 and reason in store.counters["reason"]
    assert "cold start" in caplog.text
    _drive(svc, 0.0, 2.0)  # and the sensor starts from the oil as always
    assert svc.state is not None and np.allclose(np.array(svc.state.T_c)[0, :3], 80.0, atol=1.0)


def test_saves_are_atomic_and_rate_bounded(params, tmp_path):
    clock = Clock()
    svc = _service(params)
    store = StateStore(tmp_path / "state.json", period_s=60.0, clock=clock, timer=clock)
    assert not store.maybe_save(svc)  # not initialised yet: nothing to save
    _drive(svc, 0.0, 3.0)
    assert store.maybe_save(svc)
    for k in range(100):  # the loop ticks often: at most one write a period
        clock.t += 0.5
        _drive(svc, 3.0 + 0.5 * k, 3.5 + 0.5 * k)
        store.maybe_save(svc)
    assert store.counters["saves"] == 1  # 50 s of ticks: still the first save only
    clock.t += 20.0
    assert store.maybe_save(svc) and store.counters["saves"] == 2
    clock.t += 120.0  # the bus fell silent: nothing new to write
    assert not store.maybe_save(svc) and store.counters["saves"] == 2
    assert [p.name for p in tmp_path.iterdir()] == ["state.json"]  # no temporary file left behind
    json.loads((tmp_path / "state.json").read_bytes())


def test_a_save_says_whether_it_was_made_at_a_clean_stop(params, tmp_path):
    """A periodic save is made while stepping: restored from it, the service died while the truck drove (inputs
    held first); the shutdown save is a clean stop (cooled); a file from before the field counts as clean."""
    clock = Clock()
    svc = _service(params)
    _drive(svc, 0.0, 3.0)
    path = tmp_path / "state.json"
    store = StateStore(path, clock=clock)
    assert store.save(svc) and StateStore(path, clock=clock).load(svc.sensor).clean_stop is False
    assert store.save(svc, final=True) and StateStore(path, clock=clock).load(svc.sensor).clean_stop is True
    doc = json.loads(path.read_text())
    del doc["clean_stop"]
    path.write_text(json.dumps(doc))
    assert StateStore(path, clock=clock).load(svc.sensor).clean_stop is True


def test_a_slow_save_does_not_hold_up_the_loop(params, tmp_path, monkeypatch):
    """A periodic save in the frame loop would hold the outputs back for as long as an fsync takes (a second on an
    SD card). The gateway's store (background=True) writes in a thread; a save still
    being written is not doubled, and the shutdown save waits for it and then writes the state of that moment."""
    import threading

    from firmware_model.service import persist

    release, writes = threading.Event(), []
    real = persist.atomic_write

    def slow_write(path, data, durable=True):
        release.wait(10.0)  # the fsync of a slow card, until the test lets it go
        real(path, data, durable)
        writes.append(json.loads(data)["saved_wall_s"])

    monkeypatch.setattr(persist, "atomic_write", slow_write)
    clock = Clock()
    svc = _service(params)
    store = StateStore(tmp_path / "state.json", period_s=60.0, clock=clock, timer=clock, background=True)
    _drive(svc, 0.0, 3.0)
    assert store.maybe_save(svc)  # returned while the write is still blocked
    assert store.writing and not writes and store.counters["saves"] == 0
    clock.t += 61.0
    _drive(svc, 3.0, 4.0)
    assert not store.maybe_save(svc)  # the first is still writing: not a second one behind it
    release.set()
    assert store.wait(10.0) and store.counters["saves"] == 1 and len(writes) == 1
    clock.t += 5.0
    _drive(svc, 4.0, 5.0)
    assert store.save(svc, final=True)  # at shutdown: now, in this thread
    assert writes == [1.0e9, 1.0e9 + 66.0] and store.counters["saves"] == 2
    assert json.loads((tmp_path / "state.json").read_text())["saved_wall_s"] == 1.0e9 + 66.0


@pytest.mark.parametrize(
    "doc, reason",
    [
        ({"snapshot": None}, "no snapshot"),
        ({"saved_wall_s": None}, "no time of saving"),
        ({"saved_wall_s": "yesterday"}, "no time of saving"),
        ({"saved_wall_s": 1.0e9 + 86400.0}, "in the future"),
    ],
)
def test_a_state_file_with_bad_fields_is_a_cold_start_not_a_crash_loop(params, tmp_path, doc, reason):
    """A file of the right schema and network whose time of saving is null or text, or without its snapshot, is a
    cold start, not a traceback that systemd restarts into the same crash for ever; so is a state saved a day ahead
    of the clock (set back, or not yet set at boot), which restored would not cool."""
    first = _service(params)
    _drive(first, 0.0, 10.0)
    clock = Clock()
    StateStore(tmp_path / "state.json", clock=clock).save(first, final=True)
    saved = json.loads((tmp_path / "state.json").read_bytes())
    saved.update(doc)
    if doc.get("snapshot", 0) is None:
        del saved["snapshot"]
    (tmp_path / "state.json").write_text(json.dumps(saved))
    store = StateStore(tmp_path / "state.json", clock=clock)
    assert store.load(_service(params).sensor) is None
    assert store.counters["cold_starts"] == 1 and reason in store.counters["reason"]


def _damage_level(snap):
    a = np.frombuffer(base64.b64decode(snap["level"]["data"]), dtype=np.int8).copy()
    a[5] = 16  # no warning level: the first step's DM1 failed
    snap["level"]["data"] = base64.b64encode(a.tobytes()).decode()
    snap.pop("crc32", None)  # (a file from before the checksum)


def _flip_bit(snap):
    a = np.frombuffer(base64.b64decode(snap["T_c"]["data"]), dtype=np.float64).copy()
    a.view(np.uint64)[7] ^= np.uint64(1 << 53)  # one exponent bit: a node 100 K hotter or so
    snap["T_c"]["data"] = base64.b64encode(a.tobytes()).decode()


def _short_hold(snap):
    snap["hold"]["shape"] = [4]
    snap["hold"]["data"] = base64.b64encode(np.zeros(4).tobytes()).decode()
    snap.pop("crc32", None)


@pytest.mark.parametrize(
    "damage, reason",
    [(_damage_level, "'level' holds values"), (_flip_bit, "checksum"), (_short_hold, "'hold' has shape")],
)
def test_a_damaged_snapshot_is_a_cold_start_at_the_first_step(params, tmp_path, damage, reason):
    """One changed character of the saved warning levels, or an exponent bit flipped in a temperature (a 420 degC
    gear teeth node and a false warning), is a counted cold start through the snapshot's checksum and its shape, type
    and range checks: restored, the first would stop the service at its first step after saving the same state again
    (a crash loop under systemd)."""
    first = _service(params)
    _drive(first, 0.0, 30.0)
    clock = Clock()
    StateStore(tmp_path / "state.json", clock=clock).save(first, final=True)
    saved = json.loads((tmp_path / "state.json").read_bytes())
    damage(saved["snapshot"])
    (tmp_path / "state.json").write_text(json.dumps(saved))
    second = _service(params)
    second.restore = StateStore(tmp_path / "state.json", clock=clock).load(second.sensor)
    assert second.restore is not None  # the file itself parses: the sensor's check decides
    _drive(second, 5000.0, 5002.0, oil=80.0)
    assert second.counters.get("state_restored") is not True
    assert reason in second.counters["state_cold_start"]
    assert np.all(np.abs(np.array(second.state.T_c) - 80.0) < 5.0)  # started from the oil reading


def test_the_saved_time_is_the_last_steps_and_the_wall_clock_does_not_drive_the_period(params, tmp_path):
    """The state's time is that of the last step, so a save while the bus is silent does not make a gateway left
    powered overnight restore a hot gearbox 'cooled for 4 s'; the period runs on a monotonic timer, so a wall clock
    set back an hour does not stop the saves for an hour."""
    wall, mono = Clock(), Clock(100.0)
    svc = _service(params)
    store = StateStore(tmp_path / "state.json", period_s=60.0, clock=wall, timer=mono)
    _drive(svc, 0.0, 3.0)
    assert store.maybe_save(svc)
    stepped = wall.t
    for _ in range(10):  # ten minutes without a frame: no new save, and the saved time stays
        wall.t += 60.0
        mono.t += 60.0
        store.maybe_save(svc)
    store.save(svc, final=True)
    assert json.loads((tmp_path / "state.json").read_bytes())["saved_wall_s"] == stepped
    restore = StateStore(tmp_path / "state.json", clock=wall).load(svc.sensor)
    assert restore is not None and restore[1] == pytest.approx(600.0)
    wall.t -= 3600.0  # the wall clock set back an hour: the saves go on
    for k in range(3):
        mono.t += 61.0
        _drive(svc, 3.0 + k, 4.0 + k)
        assert store.maybe_save(svc)


def test_a_failing_save_is_tried_again_a_period_later_not_at_every_tick(params, tmp_path, caplog):
    """After a failed save (a full or read-only disk) the store tries again once a period, not at every tick
    (1961 attempts in 24 s, catch-up steps, a 176 ms p99); the shutdown's failure is logged."""
    mono = Clock(0.0)
    svc = _service(params)
    _drive(svc, 0.0, 3.0)
    (tmp_path / "state.json").mkdir()
    store = StateStore(tmp_path / "state.json", period_s=60.0, timer=mono)
    for k in range(200):  # 100 s of ticks
        mono.t += 0.5
        _drive(svc, 3.0 + 0.5 * k, 3.5 + 0.5 * k)
        store.maybe_save(svc)
    assert store.counters["save_errors"] == 2
    assert not store.save(svc, final=True)
    assert caplog.text.count("cannot save the state") == 2 and "at shutdown" in caplog.text


def test_a_failing_save_is_counted_not_fatal(params, tmp_path, caplog):
    svc = _service(params)
    _drive(svc, 0.0, 3.0)
    (tmp_path / "state.json").mkdir()  # the path is a directory: the rename fails
    store = StateStore(tmp_path / "state.json")
    assert not store.save(svc) and not store.save(svc)
    assert store.counters["save_errors"] == 2
    assert caplog.text.count("cannot save the state") == 1


def test_health_file_and_status_command(params, tmp_path, capsys):
    from tools.cli import main

    svc = _service(params)
    _drive(svc, 0.0, 5.0)
    store = StateStore(tmp_path / "state.json")
    store.save(svc)
    health = HealthFile(tmp_path / "health.json")
    assert health.maybe_write(svc, store)
    doc = read_health(tmp_path / "health.json")
    assert doc["steps"] == svc.counters["steps"] and doc["initialised"] and doc["state"]["saves"] == 1
    assert main(["status", "--health-file", str(tmp_path / "health.json")]) == 0
    out = capsys.readouterr().out
    assert "service: running" in out and "sensor: initialised" in out and "1 saves" in out
    doc["written_wall_s"] -= 60.0
    doc["written_boottime_s"] -= 60.0
    (tmp_path / "health.json").write_text(json.dumps(doc))
    assert main(["status", "--health-file", str(tmp_path / "health.json")]) == 1
    assert "NOT RUNNING" in capsys.readouterr().out
    assert main(["status", "--health-file", str(tmp_path / "missing.json")]) == 2
    for field, bad in (("uptime_s", "long"), ("written_wall_s", None), ("decoder", "x")):  # damaged by hand
        (tmp_path / "bad.json").write_text(json.dumps({**doc, field: bad}))
        assert main(["status", "--health-file", str(tmp_path / "bad.json")]) == 2, field
        assert "not a gearbox-vsensor health file" in capsys.readouterr().err


def test_status_says_when_a_running_service_has_stopped_stepping(params, tmp_path, capsys, monkeypatch):
    """With the sensor's input frames gone (other nodes still sending), `status` does not say "running ... mode
    now 0 (normal)" with exit 0 while no step runs and nothing is sent."""
    import tools.cli.status as status_cli
    from tools.cli import main

    svc = _service(params)
    _drive(svc, 0.0, 5.0)
    timer = Clock(100.0)
    health = HealthFile(tmp_path / "health.json", period_s=0.0, timer=timer)
    monkeypatch.setattr(status_cli, "health_age_s", lambda doc: 0.5)  # the file itself is fresh
    assert health.maybe_write(svc)
    assert main(["status", "--health-file", str(tmp_path / "health.json")]) == 0
    assert "(0 s ago)" in capsys.readouterr().out
    timer.t += 20.0  # 20 s without a step: the file is still rewritten
    assert health.maybe_write(svc)
    assert main(["status", "--health-file", str(tmp_path / "health.json")]) == 3
    assert "NO STEP for 20 s" in capsys.readouterr().out
    _drive(svc, 5.0, 6.0)
    assert health.maybe_write(svc)
    assert main(["status", "--health-file", str(tmp_path / "health.json")]) == 0
    doc = read_health(tmp_path / "health.json")  # damaged by hand: one sentence, exit 2
    (tmp_path / "health.json").write_text(json.dumps({**doc, "last_step_age_s": "long"}))
    assert main(["status", "--health-file", str(tmp_path / "health.json")]) == 2
    assert "not a gearbox-vsensor health file" in capsys.readouterr().err


def test_status_says_when_a_service_has_never_stepped_after_its_grace(params, tmp_path, capsys, monkeypatch):
    """a service up for 8 s without a single step (no input frame on its
    channel) printed "waiting for inputs, 0 steps" with exit 0, where --help and docs/gateway.md promise exit 3
    when it has not stepped for 5 s. Within its first 5 s it is still only waiting."""
    import tools.cli.status as status_cli
    from tools.cli import main

    path = tmp_path / "health.json"
    timer = Clock(100.0)
    health = HealthFile(path, period_s=0.0, timer=timer, interface="socketcan", channel="can0")
    monkeypatch.setattr(status_cli, "health_age_s", lambda doc: 0.5)  # the file itself is fresh
    svc = _service(params)  # no frame fed: it never steps
    timer.t += 3.0
    assert health.maybe_write(svc)
    assert main(["status", "--health-file", str(path)]) == 0
    out = capsys.readouterr().out
    assert "service: running," in out and "waiting for inputs, 0 steps" in out and "NEVER" not in out
    timer.t += 5.0  # started 8 s ago, still no step
    assert health.maybe_write(svc)
    doc = read_health(path)
    assert doc["steps"] == 0 and doc["uptime_s"] == pytest.approx(8.0) and doc["last_step_age_s"] is None
    assert main(["status", "--health-file", str(path)]) == 3
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("service: running, but NEVER STEPPED in 8 s")
    assert lines[1].startswith("no step: the service has run 8 s without a single step")
    assert "0 frames received" in lines[1] and "socketcan can0" in lines[1] and "candump can0" in lines[1]
    _drive(svc, 0.0, 1.0)  # frames come: it steps, exit 0
    assert health.maybe_write(svc)
    assert main(["status", "--health-file", str(path)]) == 0
    assert "NEVER" not in capsys.readouterr().out
    path.write_text(json.dumps({**doc, "uptime_s": 8.0, "channel": None}))  # an older file: no channel named
    assert main(["status", "--health-file", str(path)]) == 3
    assert "its CAN channel (`run --channel`)" in capsys.readouterr().out
    doc["stopped"] = True  # stopped cleanly: not running (1), not "no step"
    path.write_text(json.dumps(doc))
    assert main(["status", "--health-file", str(path)]) == 1
    assert "NEVER" not in capsys.readouterr().out


def test_sd_notify_reaches_a_notify_socket(tmp_path, monkeypatch):
    addr = str(tmp_path / "notify")
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as srv:
        srv.bind(addr)
        monkeypatch.setenv("NOTIFY_SOCKET", addr)
        assert sd_notify("READY=1") and sd_notify("WATCHDOG=1")
        assert srv.recv(64) == b"READY=1" and srv.recv(64) == b"WATCHDOG=1"
    monkeypatch.delenv("NOTIFY_SOCKET")
    assert not sd_notify("READY=1")


def test_service_unit_passes_systemd_analyze_verify(tmp_path):
    if shutil.which("systemd-analyze") is None:
        pytest.skip("systemd-analyze is not installed (apt install systemd)")
    from tools.can.systemd import unit_text

    unit = tmp_path / "gearbox-vsensor.service"
    # a "-" in the channel and a "%" in the config path too (unescaped, they are a fatal error in verify)
    unit.write_text(unit_text("socketcan", "can-gw", config="/etc/gvs/truck%Z.toml"))
    res = subprocess.run(["systemd-analyze", "verify", str(unit)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    unit.write_text(unit_text("socketcan", "can0"))
    res = subprocess.run(["systemd-analyze", "verify", str(unit)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    text = unit.read_text()
    for key in ("Type=notify", "WatchdogSec=", "Restart=always", "DynamicUser=yes", "CapabilityBoundingSet="):
        assert key in text


def test_service_unit_fits_the_interface_and_refuses_what_cannot_stand_in_it(capsys):
    """The unit fits its interface: a pcan unit is not bound to a network device (it never exists), udp_multicast
    is not blocked by the address families; a line break in --channel (lines added to the unit) and a relative
    --config (not found by the service) are refused."""
    from tools.can.systemd import unit_text
    from tools.cli import main

    pcan = unit_text("pcan", "PCAN_USBBUS1")
    assert "BindsTo" not in pcan and "sys-subsystem-net-devices" not in pcan and "RestrictAddressFamilies" not in pcan
    assert "RestrictAddressFamilies=AF_INET AF_INET6" in unit_text("udp_multicast", "239.0.0.1")
    assert "BindsTo=sys-subsystem-net-devices-can0.device" in unit_text("socketcan", "can0")
    # systemd escapes "-" in a device unit's name (unescaped, "can-gw" names a unit that never appears), and a "%"
    # in the config path is doubled, else it is taken for a specifier
    assert "BindsTo=sys-subsystem-net-devices-can\\x2dgw.device" in unit_text("socketcan", "can-gw")
    assert "--config /etc/gvs/truck%%Z.toml" in unit_text("socketcan", "can0", config="/etc/gvs/truck%Z.toml")
    for args, words in (
        (["--channel", "can0\nExecStartPre=/bin/true"], "line breaks"),
        (["--config", "project.toml"], "absolute path"),
    ):
        assert main(["service-unit", *args]) == 2
        captured = capsys.readouterr()
        assert words in captured.err and "[Unit]" not in captured.out


def test_a_health_file_that_cannot_be_written_is_said_once(params, tmp_path, caplog):
    """A health file that cannot be written (a read-only file system) is said once, not skipped without a word
    (`status` would then report a service that is not running)."""
    svc = _service(params)
    _drive(svc, 0.0, 2.0)
    health = HealthFile(tmp_path / "no_such_dir" / "health.json", period_s=0.0)
    with caplog.at_level("WARNING", logger="gearbox_vsensor.state"):
        assert not health.maybe_write(svc) and not health.maybe_write(svc)
    assert health.errors == 2
    assert sum("cannot write the health file" in r.getMessage() for r in caplog.records) == 1


def test_failed_health_writes_are_shown_by_status_once_a_write_succeeds(params, tmp_path, capsys):
    """Writes that failed (a full or read-only disk for a while) are counted in the next health document, and a
    stale file says the service may be running but unable to rewrite it."""
    from tools.cli import main

    svc = _service(params)
    _drive(svc, 0.0, 2.0)
    target = tmp_path / "d" / "health.json"
    health = HealthFile(target, period_s=0.0)
    assert not health.maybe_write(svc) and not health.maybe_write(svc)
    target.parent.mkdir()
    assert health.maybe_write(svc)
    assert read_health(target)["health_write_errors"] == 2
    assert main(["status", "--health-file", str(target)]) == 0
    assert "health file: 2 writes failed" in capsys.readouterr().out
    doc = read_health(target)
    doc["written_wall_s"] -= 60.0
    doc["written_boottime_s"] -= 60.0
    target.write_text(json.dumps(doc))
    assert main(["status", "--health-file", str(target)]) == 1
    assert "unable to rewrite this file" in capsys.readouterr().out


def test_service_unit_warns_of_every_place_the_sandbox_hides(tmp_path):
    """Every path the sandbox hides is warned of: the resolved python (a venv in /tmp whose python links to /root),
    not only /home and /root, and the code of an editable install."""
    from tools.can.systemd import check_unit_args

    assert check_unit_args("socketcan", "can0", None, "/opt/gvs/bin/python") == []
    tmp_python = check_unit_args("socketcan", "can0", None, "/tmp/venv/bin/python")
    assert len(tmp_python) == 1 and "PrivateTmp=yes" in tmp_python[0]
    link = tmp_path / "python"
    link.symlink_to("/root/.pyenv/bin/python3")  # need not exist: the link is resolved as text
    linked = check_unit_args("socketcan", "can0", None, str(link))
    assert any("ProtectHome=yes" in w and "through its links" in w for w in linked)
    # the configuration too (it was never checked): under /tmp or /root the service cannot read it
    for where, setting in (("/tmp/cfg.toml", "PrivateTmp=yes"), ("/root/truck.toml", "ProtectHome=yes")):
        (w,) = check_unit_args("socketcan", "can0", where, "/opt/gvs/bin/python")
        assert f"the --config {where}" in w and setting in w and "/etc/gearbox-vsensor" in w and "venv" not in w
    assert check_unit_args("socketcan", "can0", "/etc/gearbox-vsensor/truck.toml", "/opt/gvs/bin/python") == []


def test_service_unit_warns_of_an_unknown_interface_and_a_config_that_does_not_load(tmp_path):
    """A unit that would fail at every start (Restart=always: a crash loop) was written without a word; what this
    machine can tell is a warning (the unit may be for another host)."""
    from tools.can.systemd import check_unit_args

    (w,) = check_unit_args("nosuch", "can0", None, "/opt/gvs/bin/python")
    assert "--interface nosuch: python-can here knows no such interface" in w
    bad = tmp_path / "gvs.toml"
    bad.write_text("[can]\nbitrat = 250000\n")
    found = check_unit_args("socketcan", "can0", str(bad), "/opt/gvs/bin/python")
    assert any(f"--config {bad} does not load here" in x and "bitrat" in x for x in found), found


def test_status_says_not_running_at_once_when_the_service_s_process_is_gone(params, tmp_path, capsys):
    """A service killed with SIGKILL left a fresh health file: status said 'running' for up to 5 s. Its pid is no
    live process on this boot: NOT RUNNING at once, exit 1."""
    import subprocess
    import sys

    from tools.cli import main

    svc = _service(params)
    _drive(svc, 0.0, 2.0)
    health = HealthFile(tmp_path / "health.json")
    assert health.maybe_write(svc, None)
    doc = read_health(tmp_path / "health.json")
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (tmp_path / "health.json").write_text(json.dumps({**doc, "pid": dead.pid}))
    assert main(["status", "--health-file", str(tmp_path / "health.json")]) == 1
    assert f"NOT RUNNING (its process {dead.pid} is gone: killed or crashed" in capsys.readouterr().out


def test_status_says_restored_stopped_and_the_mode_now(params, tmp_path, capsys):
    """`status` says whether the saved state was restored, says 'stopped' (not 'running') right after a clean
    stop, and shows the degraded mode now, not only lifetime totals."""
    from tools.cli import main

    clock = Clock()
    first = _service(params)
    _drive(first, 0.0, 60.0)
    StateStore(tmp_path / "state.json", clock=clock).save(first, final=True)
    second = _service(params)
    store = StateStore(tmp_path / "state.json", clock=clock)
    second.restore = store.load(second.sensor)
    _drive(second, 100.0, 102.0)
    health = HealthFile(tmp_path / "health.json")
    assert health.maybe_write(second, store)
    assert main(["status", "--health-file", str(tmp_path / "health.json")]) == 0
    out = capsys.readouterr().out
    assert "restored at start" in out and "mode now 0 (normal)" in out and "service: running" in out
    assert health.maybe_write(second, store, stopped=True)
    assert main(["status", "--health-file", str(tmp_path / "health.json")]) == 1
    assert "stopped cleanly" in capsys.readouterr().out


def test_status_of_a_service_long_stopped_gives_ages_counted_to_now(params, tmp_path, capsys):
    """A health file left 2 h ago (the service killed, or stopped cleanly) printed "last step ... (0 s ago)" and
    "last 0 s ago" for the state save: the ages as the service wrote them, not counted to now. Now the stale lines
    say since when the figures are and every age includes the file's own age."""
    from tools.cli import main

    svc = _service(params)
    _drive(svc, 0.0, 5.0)
    store = StateStore(tmp_path / "state.json")
    store.save(svc)
    path = tmp_path / "health.json"
    for stopped in (False, True):
        assert HealthFile(path).maybe_write(svc, store, stopped=stopped)
        doc = read_health(path)
        assert doc["last_step_age_s"] < 1.0 and doc["state"]["last_save_age_s"] < 1.0
        doc["written_wall_s"] -= 7200.0
        doc["written_boottime_s"] -= 7200.0
        path.write_text(json.dumps(doc))
        assert main(["status", "--health-file", str(path)]) == 1
        lines = capsys.readouterr().out.splitlines()
        assert lines[0].startswith("service: stopped cleanly" if stopped else "service: NOT RUNNING"), lines[0]
        assert lines[1].startswith("stale: the lines below are the service's last health, written ") and (
            "(7200 s ago)" in lines[1]
        ), lines[1]
        (sensor,) = [x for x in lines if x.startswith("sensor:")]
        (state,) = [x for x in lines if x.startswith("state:")]
        assert "(7200 s ago)" in sensor and "last 7200 s ago" in state, (sensor, state)
        assert "(0 s ago)" not in "\n".join(lines) and "uptime" not in lines[0]


def test_status_json_says_whether_live_and_counts_ages_to_now(params, tmp_path, capsys):
    """`status --json` printed the raw health file: a service stopped 2 h ago showed "last_step_age_s": 0.0 and
    nothing said the figures were stale. The document is kept as written and a "status" object adds the text's
    judgement: live or not, the state in one word, the exit status and the ages counted to now."""
    from tools.cli import main

    svc = _service(params)
    _drive(svc, 0.0, 5.0)
    store = StateStore(tmp_path / "state.json")
    store.save(svc)
    path = tmp_path / "health.json"
    assert HealthFile(path).maybe_write(svc, store)
    assert main(["status", "--health-file", str(path), "--json"]) == 0
    fresh = json.loads(capsys.readouterr().out)
    assert fresh["status"]["live"] is True and fresh["status"]["service"] == "running"
    assert fresh["status"]["exit_status"] == 0 and fresh["status"]["health_age_s"] < 5.0
    for stopped, word in ((False, "stale"), (True, "stopped")):
        assert HealthFile(path).maybe_write(svc, store, stopped=stopped)
        doc = read_health(path)
        doc["written_wall_s"] -= 7200.0
        doc["written_boottime_s"] -= 7200.0
        path.write_text(json.dumps(doc))
        assert main(["status", "--health-file", str(path), "--json"]) == 1
        out = json.loads(capsys.readouterr().out)
        judged = out.pop("status")
        assert out == doc  # every key of the document as the service wrote it (extended, not changed)
        assert judged["live"] is False and judged["service"] == word and judged["exit_status"] == 1
        assert judged["health_age_s"] == pytest.approx(7200.0, abs=60.0)
        assert judged["last_step_age_s"] == pytest.approx(doc["last_step_age_s"] + judged["health_age_s"])
        assert judged["last_save_age_s"] == pytest.approx(doc["state"]["last_save_age_s"] + judged["health_age_s"])
    path.write_text(json.dumps({**doc, "state": {**doc["state"], "last_save_age_s": "long"}}))  # damaged by hand
    assert main(["status", "--health-file", str(path), "--json"]) == 2
    assert "not a gearbox-vsensor health file" in capsys.readouterr().err


def test_status_of_a_file_written_on_an_earlier_boot_is_not_running(params, tmp_path, capsys):
    """A health file kept on disk across a reboot, read on a gateway whose wall clock is behind it (no RTC): its
    wall-clock age was negative and status said 'running' with exit 0. A file of another boot was written by a
    process that is not running: exit 1, and the age the wall clock cannot give is said to be unknown."""
    from firmware_model.service.persist import boot_id
    from tools.cli import main

    if boot_id() is None:
        pytest.skip("no boot id on this system (Linux /proc/sys/kernel/random/boot_id)")
    svc = _service(params)
    _drive(svc, 0.0, 5.0)
    path = tmp_path / "health.json"
    assert HealthFile(path).maybe_write(svc)
    doc = read_health(path)
    doc["boot_id"] = "an-earlier-boot"
    doc["written_wall_s"] += 3600.0  # this boot's wall clock is an hour behind the file's
    path.write_text(json.dumps(doc))
    assert main(["status", "--health-file", str(path)]) == 1
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("service: NOT RUNNING (written on an earlier boot of this machine"), lines[0]
    assert "age unknown" in lines[1] and "(0 s ago)" not in "\n".join(lines), lines
    doc["written_wall_s"] -= 3600.0 + 600.0  # a wall clock that is right: the age it gives is shown
    path.write_text(json.dumps(doc))
    assert main(["status", "--health-file", str(path)]) == 1
    out = capsys.readouterr().out
    assert "NOT RUNNING (written on an earlier boot" in out and "(600 s ago)" in out


def test_a_restored_state_is_cooled_until_the_first_frame(params, tmp_path):
    """The time off runs until the first frame, not until the service starts: a gateway restarted while the truck
    sleeps would otherwise restore a state too hot by the whole wait."""
    from tools.can.live import GatewayHooks, LiveSettings

    clock = Clock()
    first = _service(params)
    _drive(first, 0.0, 60.0)
    StateStore(tmp_path / "state.json", clock=clock).save(first, final=True)
    second = _service(params)
    hooks = GatewayHooks(LiveSettings("virtual", "t", state_file=str(tmp_path / "state.json")), second)
    hooks.store.clock = clock
    clock.t += 7200.0  # two hours until the truck sends its first frame
    hooks.tick()
    assert second.restore is not None and second.restore[1] == pytest.approx(7200.0)


def test_dm1_names_a_missing_engine_speed_instead_of_clearing(params):
    """With the engine speed gone (EEC1 stopped, ETC2 and TRF1 still there) the levels become not available after
    the hold time; DM1 then names SPN 190 with FMI 9 (abnormal update rate) and the amber lamp, not "no active DTC"
    with lamps off (a service tool would read a gearbox at critical as "fault cleared"), and clears again once the
    speed is back."""
    svc = SensorService(VirtualSensor(params), ServiceOptions(configured_ref_torque_nm=2000.0))

    def dm1s(frames):
        return [decode_outputs([m])["dm1"] for m in frames if pgn_of(m.arbitration_id) == 0xFECA]

    before = dm1s(svc.feed_all(traffic(0.0, 20.0, rpm=1500.0, gear=9)))
    assert before and all(d["dtc"] is None and d["amber_warning_lamp"] == 0 for d in before)
    no_speed = [m for m in traffic(20.0, 40.0, rpm=1500.0, gear=9) if pgn_of(m.arbitration_id) != 0xF004]
    during = dm1s(svc.feed_all(no_speed))
    assert during[0]["dtc"] is None  # holding: the levels are still evaluated
    last = during[-1]
    assert last["dtc"] is not None and last["dtc"]["spn"] == 190 and last["dtc"]["fmi"] == 9
    assert last["amber_warning_lamp"] == 1 and last["red_stop_lamp"] == 0
    after = dm1s(svc.feed_all(traffic(40.0, 45.0, rpm=1500.0, gear=9)))
    assert after[-1]["dtc"] is None and after[-1]["amber_warning_lamp"] == 0


def test_status_warns_of_a_suspect_time_base(params, tmp_path, capsys, monkeypatch):
    """A log played 10 x faster onto a bus that stamps frames on arrival: the service logged "time base suspect" and
    sent TimeBaseSuspect, but `status` said "mode now 0 (normal)" and nothing else, and the health file had no
    trace of it. The health file now carries the live check (suspect, windows, its sentence) and status warns."""
    import tools.cli.status as status_cli
    from tools.cli import main

    svc = _service(params)
    _drive(svc, 0.0, 5.0)
    health = HealthFile(tmp_path / "health.json", period_s=0.0, timer=Clock(100.0))
    monkeypatch.setattr(status_cli, "health_age_s", lambda doc: 0.5)
    assert health.maybe_write(svc)
    assert read_health(tmp_path / "health.json")["time_base"] == {
        "suspect": False,
        "windows_checked": 0,
        "windows_suspect": 0,
        "sentence": None,
    }
    assert main(["status", "--health-file", str(tmp_path / "health.json")]) == 0
    assert "time base" not in capsys.readouterr().out
    sentence = "time base suspect: the input messages arrive about 10.0x faster than their J1939 periods"
    svc.counters["time_base"].update(suspect=True, windows_checked=4, windows_suspect=2, sentence=sentence)
    assert health.maybe_write(svc)
    assert read_health(tmp_path / "health.json")["time_base"]["suspect"] is True
    main(["status", "--health-file", str(tmp_path / "health.json")])
    assert f"WARNING time base suspect now: {sentence}" in capsys.readouterr().out
