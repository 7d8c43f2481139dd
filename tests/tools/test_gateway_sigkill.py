"""SIGKILL mid-run (issue: in-vehicle gateway): `gearbox-vsensor run --state-file` on a bus shared between processes
(python-can's udp_multicast on this host's loopback) is killed with SIGKILL while driving; restarted with the same
file, it restores the last periodic snapshot (logged with its age), not a cold start. Corrupt, truncated and foreign
files each give a clean cold start (tests/firmware_model/test_gateway_state.py)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.firmware_model.test_can_service import traffic

pytest.importorskip(
    "msgpack", reason="python-can's udp_multicast bus needs msgpack (pip install msgpack, in the 'test' extra)"
)

REPO = Path(__file__).resolve().parents[2]
#: a multicast group of its own (python-can's default IPv4 group is 239.74.163.2)
GROUP = "239.74.163.7"


def _bus():
    import can

    try:
        return can.Bus(interface="udp_multicast", channel=GROUP)
    except Exception as exc:  # no multicast route on this host
        pytest.skip(f"udp_multicast unavailable here: {exc}")


def _start(tmp_path: Path, tag: str):
    err = open(tmp_path / f"{tag}.err", "w")
    env = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    p = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "tools.cli",
            "run",
            "--interface",
            "udp_multicast",
            "--channel",
            GROUP,
            "--config",
            str(tmp_path / "gw.toml"),
            "--state-file",
            str(tmp_path / "state.json"),
            "--state-period",
            "1",
            "--health-file",
            str(tmp_path / "health.json"),
            "--log-level",
            "INFO",
        ],
        cwd=REPO,
        env=env,
        stderr=err,
        stdout=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 120
    while "listening" not in (tmp_path / f"{tag}.err").read_text():
        if p.poll() is not None or time.monotonic() > deadline:
            p.kill()
            pytest.fail("the service did not start: " + (tmp_path / f"{tag}.err").read_text()[-2000:])
        time.sleep(0.2)
    return p


def _drive(bus, t0_s: float, seconds: float, oil_c: float) -> None:
    """The test traffic in real time (udp_multicast stamps frames on arrival: frame time is wall time)."""
    start = time.monotonic()
    for msg in traffic(t0_s, t0_s + seconds, rpm=1500.0, oil=oil_c, gear=9):
        delay = (msg.timestamp - t0_s) - (time.monotonic() - start)
        if delay > 0:
            time.sleep(delay)
        bus.send(msg)


def test_sigkill_mid_run_restores_the_last_periodic_snapshot(tmp_path):
    (tmp_path / "gw.toml").write_text("[can]\nengine_reference_torque_nm = 2000.0\n")
    bus = _bus()
    try:
        first = _start(tmp_path, "first")
        _drive(bus, 0.0, 4.0, oil_c=80.0)
        deadline = time.monotonic() + 30
        while not (tmp_path / "state.json").exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert (tmp_path / "state.json").exists(), (tmp_path / "first.err").read_text()[-2000:]
        saved = json.loads((tmp_path / "state.json").read_text())
        first.send_signal(signal.SIGKILL)
        first.wait(30)
        assert first.returncode == -signal.SIGKILL
        # no shutdown save happened: the file is the last periodic one, complete
        assert json.loads((tmp_path / "state.json").read_text()) == saved
        second = _start(tmp_path, "second")
        _drive(bus, 0.0, 2.0, oil_c=81.0)
        second.send_signal(signal.SIGTERM)
        assert second.wait(60) == 0
    finally:
        bus.shutdown()
    log = (tmp_path / "second.err").read_text()
    assert "sensor state restored" in log, log[-2000:]
    assert "cold start" not in log
    health = json.loads((tmp_path / "health.json").read_text())
    print(f"\nSIGKILL: restored from the periodic snapshot; health after the restart: {json.dumps(health)[:300]}")
