"""Test session set-up: one BLAS thread, as the onboard core runs (see firmware_model/__init__.py); the slowest modules
first."""

import os

import numpy as np
import pytest

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

#: modules whose tests take 15 s to 3 min each (`--durations=30`), marked `slow` here (`-m "not slow"` leaves them out)
SLOW_MODULES = (
    "tests/tools/test_diagnosis.py",
    "tests/firmware_model/test_kernel.py",
    "tests/tools/test_export_c.py",
    "tests/tools/test_export_descriptions.py",
    "tests/tools/test_diagnosis_thin.py",
    "tests/tools/test_diagnosis_start.py",
    "tests/tools/test_calibrate.py",
    "tests/golden/test_golden.py",
    "tests/firmware_model/test_overheat.py",
    "tests/tools/test_fleet.py",
    "tests/tools/test_can_live.py",
)


def _rank(item) -> int:
    """0: the VM modules (`vcan`), 1: the other slow ones, 2: the rest."""
    if item.get_closest_marker("vcan"):
        return 0
    return 1 if item.get_closest_marker("slow") else 2


def pytest_collection_modifyitems(config, items):
    """Mark the slow modules and run whole modules, the slowest first (module-scoped set-ups stay shared): with
    pytest-xdist's `--dist loadfile --no-loadscope-reorder` (pyproject.toml) both workers start on the longest files and
    the short ones fill the end."""
    for item in items:
        if item.nodeid.split("::", 1)[0] in SLOW_MODULES:
            item.add_marker(pytest.mark.slow)
    module_rank: dict[str, int] = {}
    for item in items:
        path = item.nodeid.split("::", 1)[0]
        module_rank[path] = min(module_rank.get(path, 2), _rank(item))
    items.sort(key=lambda item: module_rank[item.nodeid.split("::", 1)[0]])


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """With `--dist loadfile`: whole files per worker, and the QEMU VM files (tests/tools/test_vcan_*) as one unit on
    one worker, one VM at a time (two VMs of 2 vCPUs each on a 2-core host slow the services inside below real time)."""
    if config.getoption("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class VMFilesTogether(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]
            return "tests/tools/test_vcan_*" if path.startswith("tests/tools/test_vcan_") else path

    return VMFilesTogether(config, log)


@pytest.fixture(scope="session")
def uphill_plant():
    """The reference plant (GRS905) over the uphill cycle, 2 h at 1 s rows: computed once per session (about 20 s),
    read by the tests that need it (they must not modify it)."""
    from firmware_model.parameters import load_parameters
    from tools.cycles.named import get_cycle
    from tools.plant.reference import ReferencePlant

    return ReferencePlant(load_parameters("GRS905")).run(get_cycle("uphill"), progress=False).table


@pytest.fixture(scope="session")
def uphill_hour(uphill_plant):
    """The first hour of `uphill_plant`: it holds every warning and nearly every finite time to limit of the two
    hours (the second adds a steady climb, no warning, and half of the numpy reference replay's time)."""
    return uphill_plant.select(np.asarray(uphill_plant["time_s"]) < 3600.0)


@pytest.fixture(scope="session")
def uphill_numpy_replay(uphill_hour):
    """`uphill_hour` replayed by the numpy core (the reference of the compiled ones): computed once per session."""
    from firmware_model.onboard.sensor import VirtualSensor
    from firmware_model.parameters import load_parameters
    from tools.replay.table import replay_table

    return replay_table(uphill_hour, VirtualSensor(load_parameters("GRS905"), core="numpy"))
