"""What the vcan VM tests share: skip (naming what is missing) without the VM, and a steady drive as a candump log."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tools.vcan_vm import harness as vcan_vm

REPO = Path(__file__).resolve().parents[2]
#: what the VM's Python need not import: python-can imports asammdf (pandas, sympy) at `import can` when the mf4
#: extra is installed, ~8 s of each service start-up under TCG on a quiet host; no VM test reads an MF4 log
VM_HIDDEN = ("asammdf",)


def skip_without_vm(extra_missing: list[str] | None = None) -> None:
    """Skip the calling test, naming what is missing and how to get it, unless the VM can run here."""
    missing = vcan_vm.vm_prerequisites() + list(extra_missing or [])
    if missing:
        pytest.skip("vcan VM prerequisites missing: " + "; ".join(missing) + f" ({vcan_vm.INSTALL_HINT})")


def steady_drive_log(share: Path, seconds: float) -> Path:
    """`gearbox-vsensor simulate` of a steady drive (gear 9, 1400 rpm, 1800 Nm) for ``seconds``: its J1939 traffic
    as share/drive.log (candump -L), the plant's table as share/plant.csv."""
    env = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    p = subprocess.run(
        [
            sys.executable,
            "-m",
            "tools.cli",
            "simulate",
            "--cycle",
            f"steady:gear=9,rpm=1400,nm=1800,s={seconds:.0f}",
            "--out",
            str(share / "plant.csv"),
            "--can-log",
            str(share / "drive.log"),
            "--quiet",
        ],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, p.stderr
    return share / "drive.log"
