"""The QEMU VM run shared by test_vcan_e2e.py and test_vcan_faults.py: one boot and one service for both (the
service's start-up under TCG emulation is 30-60 s of each VM test; tests/conftest.py keeps the VM files on one
worker, so the session fixture runs once)."""

from __future__ import annotations

import time

import pytest


@pytest.fixture(scope="session")
def vcan_service_run(tmp_path_factory):
    """(share, VMResult, the offline replay of the drive): `gearbox-vsensor run` on vcan0 follows the uphill drive of
    test_vcan_e2e.py, then the steady drive with the bus faults of test_vcan_faults.py, then SIGTERM."""
    from tests.tools import test_vcan_e2e as e2e
    from tests.tools import test_vcan_faults as faults
    from tests.tools.vcan_helpers import VM_HIDDEN, skip_without_vm
    from tools.vcan_vm import harness as vcan_vm

    skip_without_vm()
    t0 = time.monotonic()
    share = tmp_path_factory.mktemp("vcan-e2e")
    offline, env = e2e.prepare_drive(share)
    env.update(faults.prepare_faults(share))
    host_s = time.monotonic() - t0
    script = e2e.VM_SCRIPT + faults.FAULTS_SCRIPT + e2e.SHUTDOWN_SCRIPT
    try:
        res = vcan_vm.run_in_vm(script, timeout_s=e2e.VM_TIMEOUT_S, share_dir=share, env=env, hide_modules=VM_HIDDEN)
    except vcan_vm.VMUnavailable as exc:
        pytest.skip(f"vcan VM unavailable: {exc.reason}")
    e2e.print_timings(res, host_s)
    assert res.returncode == 0, res.script_output[-3000:]
    return share, res, offline
