"""Hot restart against the reference plant (issue: in-vehicle gateway): a climb, the ignition off for 10 minutes
(the service's state saved, the plant computing on with the engine stopped and the engine-side boundaries cooling),
then the service restarts. The first temperatures it publishes, restored from the saved state, must be within 2 K of
the plant's on every component, and far better than a cold start from the oil reading. benchmarks/bench_restart.py
prints the same comparison (longer drives and stops)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_restart.py"


def _bench():
    spec = importlib.util.spec_from_file_location("bench_restart", BENCH)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_restored_state_is_within_2_k_of_the_plant_after_a_10_minute_stop():
    r = _bench().run_restart(drive_s=600.0, off_s=600.0)
    restored = np.abs(r.restored_err_k)
    cold = np.abs(r.cold_err_k)
    print(
        f"\nhot restart after 600 s off: worst restored {restored.max():.2f} K "
        f"({r.components[int(restored.argmax())]}), worst cold start {cold.max():.2f} K "
        f"({r.components[int(cold.argmax())]})"
    )
    assert any("restored" in line for line in r.restored_log.splitlines())
    assert np.all(np.isfinite(r.restored_c)) and np.all(np.isfinite(r.cold_c))
    assert restored.max() <= 2.0
    assert cold.max() > 5.0 * restored.max()  # the climb left gradients that a cold start cannot know


def test_a_crash_mid_climb_is_restored_with_the_inputs_held_not_cooled():
    """A service that dies while the truck climbs (systemd restarts it 5 s later, its last periodic save 30 s old)
    is not restored as if the ignition had been off (cooled for 35 s with the engine stopped, several K low on the
    hot components): a state saved while stepping (not at a clean stop) has its inputs held over the time off (at
    most the time-jump hold, 60 s), then cools: as a forward time jump does."""
    r = _bench().run_crash(drive_s=600.0)
    held, cooled, never = (np.abs(e) for e in (r.held_err_k, r.cooled_err_k, r.uninterrupted_err_k))
    print(
        f"\ncrash restart at 600 s: worst held {held.max():.2f} K, cooled {cooled.max():.2f} K, never died "
        f"{never.max():.2f} K"
    )
    assert "saved while stepping" in r.restored_log
    assert held.max() <= 1.5 and cooled.max() > 3.0 * held.max()
