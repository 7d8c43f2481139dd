"""The gateway service supervised by a real systemd (PID 1 in the QEMU VM, tools/vcan_vm/harness.py, init="systemd";
issue: in-vehicle gateway).

The unit is the one `gearbox-vsensor service-unit --interface socketcan --channel vcan0` prints, installed as an
integrator would (docs/gateway.md), started with `systemctl start` (Type=notify: it returns when the service has
sent READY=1). What must hold:

- a crash (SIGSEGV to the main process) is restarted by systemd (Restart=always): a new main process, active;
- a hang (SIGSTOP: no more WATCHDOG=1) is caught by the unit's 10 s watchdog and restarted;
- the twice-restarted service decodes a drive played onto vcan0 and publishes GBX_STATUS from its source address,
  and `gearbox-vsensor status` reads its health file as running.

Drop-ins adapt the machine, not the behaviour under test: the repo on PYTHONPATH; when the test's Python lives under
/root or /home (the unit's ProtectHome=yes hides those, and a dynamic user cannot read them), the service runs as
root with ProtectHome off (a venv's Python counts where its base interpreter lives); when the checkout or the
Python lives under /tmp (the unit's PrivateTmp=yes hides it), PrivateTmp off.
docs/gateway.md tells integrators to install into a system-wide venv.

Marked `vcan`; skipped, naming what is missing, without QEMU, the Debian kernel, busybox-static, can-utils or
systemd and udev on the host. About 3 minutes (the service's start-up under TCG emulation is ~25 s, three times).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from can_dbc.adapter import default_source, pgn_of
from tests.tools.vcan_helpers import VM_HIDDEN, skip_without_vm, steady_drive_log
from tools.vcan_vm import harness as vcan_vm

pytestmark = pytest.mark.vcan

SENSOR_SA = default_source("GBX_STATUS")
STATUS_PGN = 0xFF4F
DRIVE_S = 12

VM_SCRIPT = r"""
set -u
cd "$VM_SHARE"
UNIT=/run/systemd/system/gearbox-vsensor.service
svc() { systemctl show -p "$1" --value gearbox-vsensor; }
# wait (up to 240 s) until the service is active with a main process other than $1; print the seconds waited
wait_new_main() {
    t0=$(cut -d' ' -f1 /proc/uptime)
    for i in $(seq 480); do
        # one snapshot of both properties (separate reads raced with the watchdog's kill: state active, then pid 0)
        snap=$(systemctl show -p ActiveState -p MainPID gearbox-vsensor | sort | tr '\n' ' ')
        pid=$(echo "$snap" | sed -n 's/.*MainPID=\([0-9]*\).*/\1/p')
        if echo "$snap" | grep -q "ActiveState=active " && [ "$pid" != 0 ] && [ "$pid" != "$1" ]; then
            awk -v a="$t0" -v b="$(cut -d' ' -f1 /proc/uptime)" 'BEGIN { printf "%.1f\n", b - a }'; return 0
        fi
        sleep 0.5
    done
    echo "timeout"; return 1
}
"$VM_PYTHON" -m tools.cli service-unit --interface socketcan --channel vcan0 > $UNIT || exit 3
mkdir -p $UNIT.d
# the repo (and the stubs of the modules the VM hides) on PYTHONPATH, as for the script
printf '[Service]\nEnvironment=PYTHONPATH=%s\n' "$PYTHONPATH" > $UNIT.d/repo.conf
# the host's compiled kernel (the harness sets GVS_KERNEL_LIB): no compile under TCG at each of the three starts
[ -n "${GVS_KERNEL_LIB:-}" ] \
    && printf '[Service]\nEnvironment=GVS_KERNEL_LIB=%s\n' "$GVS_KERNEL_LIB" > $UNIT.d/kernel.conf
# the Python as the unit runs it (a venv's python is a symlink to its base interpreter)
case "$VM_PYTHON $(readlink -f "$VM_PYTHON")" in /root/*|/home/*|*" /root/"*|*" /home/"*)
    printf '[Service]\nProtectHome=no\nDynamicUser=no\n' > $UNIT.d/python-under-home.conf
    echo "python_under_home=1" >> result.txt;;
esac
case "$VM_REPO $VM_PYTHON" in /tmp/*|/var/tmp/*|*" /tmp/"*|*" /var/tmp/"*)
    printf '[Service]\nPrivateTmp=no\n' > $UNIT.d/repo-under-tmp.conf
    echo "repo_under_tmp=1" >> result.txt;;
esac
systemctl daemon-reload
systemctl start gearbox-vsensor || { journalctl -u gearbox-vsensor --no-pager > journal.txt; exit 4; }
pid1=$(svc MainPID)
echo "pid1=$pid1" >> result.txt
kill -SEGV "$pid1"
echo "segv_restart_s=$(wait_new_main "$pid1")" >> result.txt
pid2=$(svc MainPID)
echo "pid2=$pid2" >> result.txt
kill -STOP "$pid2"
echo "hang_restart_s=$(wait_new_main "$pid2")" >> result.txt
pid3=$(svc MainPID)
echo "pid3=$pid3" >> result.txt
echo "restarts=$(svc NRestarts)" >> result.txt
candump -L vcan0 > rec.log 2> candump.err &
dump=$!
sleep 1
canplayer -I drive.log vcan0=can0
sleep 2
kill $dump
sleep 2
"$VM_PYTHON" -m tools.cli status > status.txt 2>&1
echo "status_rc=$?" >> result.txt
journalctl -u gearbox-vsensor --no-pager > journal.txt
cat result.txt
"""


def _systemd_missing() -> list[str]:
    return [
        f"{p} (apt install systemd udev)"
        for p in ("/lib/systemd/systemd", "/lib/systemd/systemd-udevd")
        if not Path(p).is_file()
    ]


@pytest.fixture(scope="module")
def vm_run(tmp_path_factory):
    skip_without_vm(_systemd_missing())
    share = tmp_path_factory.mktemp("vcan-systemd")
    steady_drive_log(share, DRIVE_S)
    try:
        res = vcan_vm.run_in_vm(VM_SCRIPT, timeout_s=900, share_dir=share, init="systemd", hide_modules=VM_HIDDEN)
    except vcan_vm.VMUnavailable as exc:
        pytest.skip(f"vcan VM unavailable: {exc.reason}")
    journal = (share / "journal.txt").read_text() if (share / "journal.txt").is_file() else ""
    assert res.returncode == 0, res.script_output[-3000:] + journal[-3000:]
    result = dict(line.split("=", 1) for line in (share / "result.txt").read_text().split())
    print(res.script_output[-1500:])
    return share, result, journal


def test_a_crash_is_restarted_by_systemd(vm_run):
    _, result, journal = vm_run
    assert result["segv_restart_s"] != "timeout", journal[-2000:]
    assert result["pid2"] != result["pid1"] != "0"
    assert re.search(r"Main process exited, code=(killed|dumped), status=11/SEGV", journal), journal[-2000:]
    print(f"SIGSEGV -> active again in {result['segv_restart_s']} s")


def test_a_hang_is_caught_by_the_watchdog_and_restarted(vm_run):
    _, result, journal = vm_run
    assert result["hang_restart_s"] != "timeout", journal[-2000:]
    assert result["pid3"] not in (result["pid2"], "0")
    assert "Watchdog timeout" in journal, journal[-2000:]
    assert result["restarts"] == "2"
    # the watchdog fires after 10 s without WATCHDOG=1: the restart cannot come sooner
    assert float(result["hang_restart_s"]) > 10.0
    print(f"SIGSTOP -> active again in {result['hang_restart_s']} s")


def test_the_restarted_service_publishes_and_reports_running(vm_run):
    share, result, _ = vm_run
    status = (share / "status.txt").read_text()
    # 0: running and stepping; 3: running, but its input frames stopped (the scenario's traffic may end before
    # `status` runs: then the first line says so)
    assert result["status_rc"] == "0" or (result["status_rc"] == "3" and "NO STEP for" in status), status
    assert status.startswith("service: running"), status
    m = re.search(r"sensor: initialised, (\d+) steps", status)
    assert m and int(m.group(1)) > 0, status
    published = 0
    for line in (share / "rec.log").read_text().splitlines():
        can_id = int(line.split()[2].split("#")[0], 16)
        if can_id & 0xFF == SENSOR_SA and pgn_of(can_id) == STATUS_PGN:
            published += 1
    # 10 Hz status over most of the 12 s drive (the first steps wait for every input)
    assert published >= 50, published
