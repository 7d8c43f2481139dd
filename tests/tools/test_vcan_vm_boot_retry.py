"""The vcan VM harness's boot watchdog, on the host, with a fake QEMU that hangs or boots.

A boot whose kernel does not start the init within ``boot_timeout_s`` is killed and retried, the last retry with one
CPU; after the last one the hang is raised as :class:`VMBootHang`.  No QEMU needed: ``run_in_vm`` gets assets whose
"QEMU" is a small Python script that reads ``-smp`` and either hangs after the BIOS line (a kernel stuck before its
init) or prints what a VM prints and exits.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

from tools.vcan_vm import harness

FAKE_QEMU = r"""#!@PYTHON@
import sys, time
args = sys.argv[1:]
cpus = int(args[args.index("-smp") + 1])
with open("@CALLS@", "a") as fh:
    fh.write(f"{cpus}\n")
print("SeaBIOS (version fake)\nBooting from ROM..", flush=True)
if cpus in (@HANG@):
    time.sleep(60)
# the init's line in two writes, then a script that outlasts the boot timeout
marker = "@INIT@"
print(marker[:9], end="", flush=True)
time.sleep(0.3)
print(marker[9:] + " at 2.0 s uptime", flush=True)
time.sleep(@SCRIPT_S@)
print("@BEGIN@\nhello\n@EXIT@0", flush=True)
"""


def _assets(tmp_path: Path, hang_with_cpus: tuple[int, ...], script_s: float = 0.0) -> tuple[harness.Assets, Path]:
    calls = tmp_path / "calls.txt"
    qemu = tmp_path / "fake-qemu"
    qemu.write_text(
        FAKE_QEMU.replace("@PYTHON@", sys.executable)
        .replace("@CALLS@", str(calls))
        .replace("@HANG@", "".join(f"{c}," for c in hang_with_cpus))
        .replace("@INIT@", harness.INIT_MARKER)
        .replace("@BEGIN@", harness.SENTINEL_BEGIN)
        .replace("@EXIT@", harness.SENTINEL_EXIT)
        .replace("@SCRIPT_S@", repr(script_s))
    )
    qemu.chmod(0o755)
    assets = harness.Assets(
        kernel=tmp_path / "vmlinuz", kernel_version="fake", initramfs=tmp_path / "initrd", qemu=qemu, modules=()
    )
    return assets, calls


def _cpus(calls: Path) -> list[int]:
    return [int(line) for line in calls.read_text().split()]


def test_a_boot_that_starts_the_init_is_not_retried(tmp_path, capsys):
    assets, calls = _assets(tmp_path, ())
    res = harness.run_in_vm("true", timeout_s=30, share_dir=tmp_path / "share", assets=assets, boot_timeout_s=10)
    assert res.returncode == 0 and res.boot_attempts == 1 and _cpus(calls) == [2]
    assert res.script_output == "hello\n"
    assert "hung" not in capsys.readouterr().err


def test_the_watchdog_stops_at_the_init_even_split_over_two_reads_and_a_script_may_outlast_it(tmp_path, capsys):
    """The init's line arrives in two pieces; the script then runs 3 s, three times the boot timeout: one boot."""
    assets, calls = _assets(tmp_path, (), script_s=3.0)
    res = harness.run_in_vm("true", timeout_s=30, share_dir=tmp_path / "share", assets=assets, boot_timeout_s=1.0)
    assert res.returncode == 0 and res.boot_attempts == 1 and res.smp == 2 and _cpus(calls) == [2]
    assert res.script_output == "hello\n" and res.total_s > 3.0
    assert "hung" not in capsys.readouterr().err


def test_a_hung_boot_is_killed_and_retried_last_with_one_cpu(tmp_path, capsys):
    assets, calls = _assets(tmp_path, (2,))
    t0 = time.monotonic()
    res = harness.run_in_vm("true", timeout_s=30, share_dir=tmp_path / "share", assets=assets, boot_timeout_s=1.0)
    assert time.monotonic() - t0 < 20  # the hangs were cut at the boot timeout, not at the run's 30 s
    assert res.returncode == 0 and res.boot_attempts == 3 and res.smp == 1 and _cpus(calls) == [2, 2, 1]
    assert res.script_output == "hello\n"
    err = capsys.readouterr().err
    assert "boot 1 of 3 hung before the init" in err and "Booting from ROM.." in err
    assert "boot 2 of 3 hung" in err and "with one CPU" in err


def test_every_boot_hung_raises_boot_hang_with_the_console(tmp_path):
    assets, calls = _assets(tmp_path, (1, 2))
    with pytest.raises(harness.VMBootHang, match=r"boot 2 of 2 \(1 CPU\): .*did not start the init within 1 s") as info:
        harness.run_in_vm(
            "true", timeout_s=30, share_dir=tmp_path / "share", assets=assets, boot_timeout_s=1.0, boot_attempts=2
        )
    assert _cpus(calls) == [2, 1]
    assert "Booting from ROM.." in info.value.output
    assert isinstance(info.value, harness.VMTimeout)  # callers catching the run's timeout still catch it
