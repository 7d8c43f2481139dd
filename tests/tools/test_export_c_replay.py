"""`gvs_replay`, the exported bundle's drive replay, checks its input file before it steps the sensor: a file that is
not whole float64 records (truncated, empty, float32, text) is refused with one sentence and no output, instead of a
replay of a partial record or of garbage (an ECU integrator's review). The sensor's own handling of bad values (NaN,
out of range: its degraded modes) is the kernel's and stays replayed."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from tools.cli import main

HAVE_CC = shutil.which("make") is not None and (shutil.which("cc") or shutil.which("gcc")) is not None
ARM_TOOLS = ("arm-none-eabi-gcc", "qemu-system-arm")
HAVE_ARM = all(shutil.which(t) for t in ARM_TOOLS)
pytestmark = pytest.mark.skipif(not HAVE_CC, reason="no make or C compiler on this machine")

RECORD = 8 * 8  # 8 float64 inputs per step


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    """A float bundle without the time to limit (the harness is the same in every bundle; this one steps fastest),
    its host replay program built."""
    d = tmp_path_factory.mktemp("export_replay")
    assert main(["export-c", "--real", "float", "--no-ttl", "--out", str(d), "--quiet"]) == 0
    build = subprocess.run(["make", "-s", "gvs_replay"], cwd=d, capture_output=True, text=True, timeout=300)
    assert build.returncode == 0, build.stdout + build.stderr
    return d


def drive(steps: int, seed: int = 0) -> np.ndarray:
    """A plausible drive in gvs_inputs.raw's order (speed rpm, torque N m, gear, oil, ambient, coolant degC,
    vehicle speed km/h, retarder N m): moving, with idle stretches of zero torque and the retarder mostly off."""
    rng = np.random.default_rng(seed)
    t = np.arange(steps) * 0.1
    speed = 1200.0 + 500.0 * np.sin(t / 7.0) + rng.normal(0.0, 5.0, steps)
    torque = np.where(np.sin(t / 3.0) > -0.3, 900.0 + rng.normal(0.0, 20.0, steps), 0.0)
    gear = np.clip(np.round(6 + 4 * np.sin(t / 11.0)), 1, 12)
    oil = 70.0 + 0.01 * t
    vkmh = np.clip(40.0 + 30.0 * np.sin(t / 13.0), 0.0, None)
    ret = np.where(np.sin(t / 5.0) > 0.8, 400.0, 0.0)
    return np.column_stack([speed, torque, gear, oil, np.full(steps, 20.0), np.full(steps, 85.0), vkmh, ret])


def replay(bundle, name: str, content: bytes | None = None, out: str = "out.bin"):
    """Run the host harness on bundle/name (written from content when given) into bundle/out."""
    if content is not None:
        (bundle / name).write_bytes(content)
    if out != name:
        (bundle / out).unlink(missing_ok=True)
    return subprocess.run(["./gvs_replay", name, out], cwd=bundle, capture_output=True, text=True, timeout=120)


def one_sentence(res) -> str:
    """The refusal: exit 2, nothing on stdout, one line on stderr naming the program."""
    assert res.returncode == 2, res.stdout + res.stderr
    err = res.stderr.strip()
    assert err.startswith("gvs_replay: ") and "\n" not in err and err.endswith("."), err
    assert "steps" not in res.stdout, res.stdout
    return err


def out_record_bytes(bundle) -> int:
    """OUT's record: float32 T_c and ttl_s, int8 level per published component, int8 degraded_mode."""
    header = (bundle / "gvs_kernel.h").read_text()
    n_pub = int(header.split("#define GVS_MAX_PUB ")[1].split()[0])
    return 4 * n_pub * 2 + n_pub + 1


def test_a_whole_float64_drive_replays_every_record(bundle):
    data = drive(300)
    res = replay(bundle, "good.bin", np.ascontiguousarray(data, "<f8").tobytes())
    assert res.returncode == 0, res.stdout + res.stderr
    assert "steps 300" in res.stdout
    assert (bundle / "out.bin").stat().st_size == 300 * out_record_bytes(bundle)
    # the bundle's README says how to write IN and how to read OUT, and both are what the harness does
    readme = (bundle / "README.md").read_text()
    assert "np.ascontiguousarray(inputs[:, :8], '<f8').tofile('drive.bin')" in readme
    out_dtype = eval(readme.split("(numpy: `")[1].split("`)")[0], {"np": np})
    rec = np.fromfile(bundle / "out.bin", dtype=out_dtype)
    assert len(rec) == 300 and np.isfinite(rec["T"]).all() and set(np.unique(rec["mode"])) <= {0, 1, 2}


@pytest.mark.parametrize("cut", [1, 20, RECORD - 1, RECORD + 8])
def test_a_truncated_file_is_refused_naming_the_record_size_and_the_bytes(bundle, cut):
    """It replayed the whole records and dropped the partial one silently (exit 0)."""
    raw = np.ascontiguousarray(drive(100), "<f8").tobytes()[:-cut]
    err = one_sentence(replay(bundle, "cut.bin", raw))
    assert "cut.bin" in err and f"{len(raw)} bytes" in err and f"{RECORD}-byte records" in err
    assert f"{len(raw) % RECORD} bytes left over" in err
    assert not (bundle / "out.bin").exists()  # no output that could be taken for a replay


def test_an_empty_file_is_refused(bundle):
    """It wrote an empty output and printed `steps 0` (exit 0)."""
    err = one_sentence(replay(bundle, "empty.bin", b""))
    assert "empty.bin" in err and "empty" in err.removeprefix("gvs_replay: empty.bin")
    assert not (bundle / "out.bin").exists()


@pytest.mark.parametrize("steps", [101, 300])
def test_float32_records_are_refused(bundle, steps):
    """An odd number of float32 records is not a whole number of float64 ones (the size says it); an even number is
    (half the steps of garbage: torques of ~1e12 N m, oil of 1e-310 degC), told by the values read both ways."""
    raw = np.ascontiguousarray(drive(steps), "<f4").tobytes()
    err = one_sentence(replay(bundle, "f32.bin", raw))
    assert "f32.bin" in err and "float32" in err and "'<f8'" in err  # the fix: how to write float64
    assert not (bundle / "out.bin").exists()


def test_a_text_file_is_refused(bundle):
    """A CSV of the inputs given as IN, padded to a whole number of records so that its size cannot tell."""
    text = "\n".join(",".join(f"{v:.3f}" for v in row) for row in drive(50)) + "\n"
    text += " " * (-len(text) % RECORD)
    assert len(text) % RECORD == 0
    err = one_sentence(replay(bundle, "drive.csv", text.encode()))
    assert "drive.csv" in err and "text" in err
    assert not (bundle / "out.bin").exists()


def test_bad_values_in_float64_records_are_the_sensors_to_handle_and_replay(bundle):
    """Every record with a hostile value (NaN, inf, +-1e308, out of range, tiny, a wind turbine's 2.5 MN m) is still
    a float64 record: replayed, not refused as float32; the kernel's counters say what it rejected."""
    data = drive(400, seed=1)
    rng = np.random.default_rng(2)
    hostile = np.array([np.nan, np.inf, -np.inf, 1e308, -1e308, -5.0, 7.5, 1e-12, 2.5e6, 1e8])
    data[np.arange(400), rng.integers(0, 8, 400)] = rng.choice(hostile, 400)
    for name, values in (("noisy.bin", data), ("round.bin", np.round(data))):
        res = replay(bundle, name, np.ascontiguousarray(values, "<f8").tobytes())
        assert res.returncode == 0, res.stdout + res.stderr
        assert "steps 400" in res.stdout
        counters = [int(x) for x in res.stdout.split("rejected or repaired inputs:")[1].split()]
        assert len(counters) == 13 and sum(counters) > 0  # the hostile values were seen, and counted


def test_the_same_file_as_in_and_out_is_refused_and_left_intact(bundle):
    """`wb` on OUT truncated IN before a byte was read: `steps 0`, exit 0, the drive lost."""
    raw = np.ascontiguousarray(drive(20), "<f8").tobytes()
    (bundle / "same.bin").write_bytes(raw)
    err = one_sentence(replay(bundle, "same.bin", out="same.bin"))
    assert "same.bin" in err and "OUT" in err
    assert (bundle / "same.bin").read_bytes() == raw


def test_in_and_out_one_file_under_two_names_is_not_a_silent_empty_replay(bundle):
    """OUT a hard link to IN: opening OUT empties the drive before it is read (the harness cannot tell two names of
    one file apart in C99), and it replayed the outputs it wrote as inputs, `steps 1000`, exit 0; it says so."""
    import os

    raw = np.ascontiguousarray(drive(1000), "<f8").tobytes()  # 64 kB: more than a stdio buffer
    (bundle / "linked.bin").unlink(missing_ok=True)
    (bundle / "drive2.bin").write_bytes(raw)
    os.link(bundle / "drive2.bin", bundle / "linked.bin")
    res = subprocess.run(["./gvs_replay", "drive2.bin", "linked.bin"], cwd=bundle, capture_output=True, text=True)
    err = one_sentence(res)
    assert "opening OUT linked.bin changed IN drive2.bin" in err


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full (a device whose writes fail)")
def test_an_output_that_cannot_be_written_is_refused_and_left_in_place(bundle):
    """A full disk: the writes (or the close that flushes them) fail; it said `steps N`, exit 0. OUT, here a device,
    is emptied on failure, never removed."""
    (bundle / "good.bin").write_bytes(np.ascontiguousarray(drive(300), "<f8").tobytes())
    res = subprocess.run(["./gvs_replay", "good.bin", "/dev/full"], cwd=bundle, capture_output=True, text=True)
    assert "cannot write OUT /dev/full" in one_sentence(res)
    assert Path("/dev/full").exists()


def test_a_directory_or_a_missing_file_is_refused(bundle):
    (bundle / "adir").mkdir(exist_ok=True)
    for name in ("adir", "missing.bin"):
        err = one_sentence(replay(bundle, name))
        assert name in err


def test_make_replay_stops_on_a_truncated_file(bundle):
    (bundle / "cut.bin").write_bytes(np.ascontiguousarray(drive(10), "<f8").tobytes()[:-3])
    (bundle / "host.out").unlink(missing_ok=True)
    res = subprocess.run(["make", "-s", "replay", "IN=cut.bin"], cwd=bundle, capture_output=True, text=True)
    assert res.returncode != 0 and "not a whole number of 64-byte records" in res.stderr, res.stderr
    assert not (bundle / "host.out").exists()


@pytest.mark.skipif(
    not HAVE_ARM,
    reason="needs " + ", ".join(ARM_TOOLS) + " (apt install gcc-arm-none-eabi libnewlib-arm-none-eabi "
    "qemu-system-arm; .ci/run installs them)",
)
def test_the_cortex_m4_build_checks_its_input_over_semihosting(bundle):
    """The same checks in the emulated Cortex-M4F build (the file's size read through semihosting)."""
    good = np.ascontiguousarray(drive(30), "<f8").tobytes()
    f32 = np.ascontiguousarray(drive(60), "<f4").tobytes()
    text = "1500.0,500.0,6,80.0,20.0,85.0,50.0,0.0\n" * 8
    cases = (("good.bin", good, 0), ("cut.bin", good[:-5], 2), ("empty.bin", b"", 2), ("f32.bin", f32, 2))
    for name, raw, rc in (*cases, ("drive.csv", text.encode(), 2)):
        (bundle / name).write_bytes(raw)
        (bundle / "m4.out").unlink(missing_ok=True)
        res = subprocess.run(
            ["make", "-s", "qemu-replay", f"IN={name}"], cwd=bundle, capture_output=True, text=True, timeout=600
        )
        if rc == 0:
            assert res.returncode == 0 and "steps 30" in res.stdout, res.stdout + res.stderr
            assert (bundle / "m4.out").stat().st_size == 30 * out_record_bytes(bundle)
        else:
            assert res.returncode != 0 and f"gvs_replay: {name}" in res.stdout + res.stderr, res.stdout + res.stderr
            assert not (bundle / "m4.out").exists()
