"""The QEMU vcan harness (tools/vcan_vm/harness.py) against a real Linux vcan0.

One VM boot (module fixture) runs every check and leaves its results in the shared directory;
the tests below read them on the host.  Skipped, naming what is missing, when QEMU, the Debian
kernel, busybox-static or can-utils are absent: get them with `python -m tools.vcan_vm install`
(or set VCAN_VM_INSTALL=1 to let this test install them).
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from tests.tools.vcan_helpers import VM_HIDDEN
from tools.vcan_vm import harness as vcan_vm

pytestmark = pytest.mark.vcan

N_GEN = 20
EXT_ID = 0x1ABCDE01
VM_TIMEOUT_S = 150  # hard limit; a run takes ~15-25 s

ROUNDTRIP_PY = r"""
import json, os, time
import can

share = os.environ["VM_SHARE"]
result = {"ok": False}
try:
    tx = can.Bus(interface="socketcan", channel="vcan0")
    rx = can.Bus(interface="socketcan", channel="vcan0")
    sent = can.Message(arbitration_id=0x1ABCDE01, is_extended_id=True, data=bytes([1, 2, 3, 4, 5, 6, 7, 8]))
    tx.send(sent)
    got = rx.recv(timeout=5.0)
    result["received"] = None if got is None else {
        "id": got.arbitration_id, "ext": got.is_extended_id, "data": list(got.data), "channel": got.channel}
    n = 200
    rtts = []
    for i in range(n):
        t = time.perf_counter()
        tx.send(can.Message(arbitration_id=0x18FF0000 | i, is_extended_id=True, data=i.to_bytes(2, "big")))
        m = rx.recv(timeout=2.0)
        rtts.append(time.perf_counter() - t)
        assert m is not None and m.arbitration_id == 0x18FF0000 | i, m
    rtts.sort()
    result.update(n=n, mean_ms=1e3 * sum(rtts) / n, median_ms=1e3 * rtts[n // 2], max_ms=1e3 * rtts[-1])
    tx.shutdown()
    rx.shutdown()
    result["ok"] = True
except Exception as exc:  # reported to the host, which fails the test with it
    result["error"] = repr(exc)
with open(os.path.join(share, "roundtrip.json"), "w") as fh:
    json.dump(result, fh)
"""

VM_SCRIPT = r"""
set -u
ip -details link show vcan0 > ip.txt 2>&1
echo "ip: $?" >> status.txt

# the repo is importable from any working directory
(cd / && "$VM_PYTHON" -c 'import json, firmware_model; print(json.dumps({"file": firmware_model.__file__}))') \
    > import.json 2> import.err
echo "import: $?" >> status.txt

"$VM_PYTHON" roundtrip.py > roundtrip.out 2>&1
echo "roundtrip: $?" >> status.txt

# can-utils with a background candump; & / wait / kill in the script
timeout 30 candump -L -n @N@ vcan0 > "$VM_SHARE/candump.log" 2> candump.err &
dump=$!
# cangen only once candump's socket is bound (its filter listed in /proc/net/can/rcvlist_all, which shows an empty
# list as "(vcan0: no entry)"; a fixed 0.5 s lost the first frames under a loaded emulation), at most 10 s
for i in $(seq 100); do
    grep -v 'no entry' /proc/net/can/rcvlist_all 2>/dev/null | grep -q vcan0 && break
    sleep 0.1
done
sleep 0.2
cangen vcan0 -e -n @N@ -g 2 -I i -L 8 -D i
echo "cangen: $?" >> status.txt
wait $dump
echo "candump: $?" >> status.txt

sleep 60 &
bg=$!
kill $bg
wait $bg
echo "killed-bg: $?" >> status.txt
echo done
""".replace("@N@", str(N_GEN))


@pytest.fixture(scope="module")
def vm_run(tmp_path_factory):
    missing = vcan_vm.vm_prerequisites()
    if missing and os.environ.get("VCAN_VM_INSTALL") == "1":
        vcan_vm.ensure_vm_assets(install=True)
        missing = vcan_vm.vm_prerequisites()
    if missing:
        pytest.skip(
            "vcan VM prerequisites missing: "
            + "; ".join(missing)
            + " -- get them with `python -m tools.vcan_vm install`"
        )
    share = tmp_path_factory.mktemp("vcan_vm_share")
    (share / "roundtrip.py").write_text(ROUNDTRIP_PY)
    result = vcan_vm.run_in_vm(VM_SCRIPT, timeout_s=VM_TIMEOUT_S, share_dir=share, hide_modules=VM_HIDDEN)
    print(f"vcan VM: boot {result.boot_s:.2f} s ({result.boot_attempts} boot(s)), whole run {result.total_s:.2f} s")
    yield result
    shutil.rmtree(share, ignore_errors=True)


def _status(result) -> dict[str, int]:
    text = (result.share_dir / "status.txt").read_text()
    return {k: int(v) for k, v in (line.split(": ") for line in text.splitlines())}


def _why(result) -> str:
    return "VM script output:\n" + result.script_output[-3000:]


def test_script_ran_to_completion(vm_run):
    assert vm_run.returncode == 0, _why(vm_run)
    assert vm_run.script_output.rstrip().endswith("done"), _why(vm_run)
    assert Path(vm_run.share_dir) == Path(os.path.realpath(vm_run.share_dir))


def test_vcan0_exists_and_is_up(vm_run):
    text = (vm_run.share_dir / "ip.txt").read_text()
    assert _status(vm_run)["ip"] == 0, text
    assert "vcan0" in text and "link/can" in text, text
    assert "\n    vcan " in text, text  # -details names the link kind
    assert "UP" in text.split("\n", 1)[0], text


def test_repo_importable_inside_vm_from_any_cwd(vm_run):
    err = (vm_run.share_dir / "import.err").read_text()
    assert _status(vm_run)["import"] == 0, err
    got = Path(json.loads((vm_run.share_dir / "import.json").read_text())["file"])
    assert got == vcan_vm.REPO_ROOT / "firmware_model" / "__init__.py"


def test_python_can_socketcan_29bit_roundtrip(vm_run):
    path = vm_run.share_dir / "roundtrip.json"
    assert path.is_file(), (
        (vm_run.share_dir / "roundtrip.out").read_text()
        if (vm_run.share_dir / "roundtrip.out").is_file()
        else _why(vm_run)
    )
    res = json.loads(path.read_text())
    assert res["ok"], res.get("error")
    assert res["received"] == {"id": EXT_ID, "ext": True, "data": [1, 2, 3, 4, 5, 6, 7, 8], "channel": "vcan0"}
    assert res["n"] == 200
    print(
        f"python-can round trip in the VM: mean {res['mean_ms']:.3f} ms, median {res['median_ms']:.3f} ms, "
        f"max {res['max_ms']:.3f} ms"
    )
    assert res["median_ms"] < 50  # ~0.3 ms under TCG; generous for a loaded CI machine


def test_cangen_candump_log_parsed_with_python_can(vm_run):
    can = pytest.importorskip("can")
    status = _status(vm_run)
    assert status["cangen"] == 0 and status["candump"] == 0, (vm_run.share_dir / "candump.err").read_text()
    msgs = list(can.LogReader(vm_run.share_dir / "candump.log"))
    assert len(msgs) == N_GEN
    assert all(m.is_extended_id for m in msgs)
    assert all(m.channel == "vcan0" for m in msgs)
    assert all(m.dlc == 8 for m in msgs)
    ids = [m.arbitration_id for m in msgs]
    assert ids == list(range(ids[0], ids[0] + N_GEN))  # -I i: consecutive identifiers
    assert [m.data[0] for m in msgs] == [i % 256 for i in range(msgs[0].data[0], msgs[0].data[0] + N_GEN)]
    stamps = [m.timestamp for m in msgs]
    assert stamps == sorted(stamps)


def test_background_job_killed_and_waited(vm_run):
    assert _status(vm_run)["killed-bg"] == 128 + 15  # SIGTERM
