"""The mistakes a new user makes with an honest drive, each replayed, and what the tool answers (docs/can.md, "Trust
findings").

Makes fresh copies of the bundled drive (the demo's synthetic uphill drive, 2 h), of its first 12 and 30 minutes,
of its CAN log and of a real truck capture (when found: ``--captures DIR`` or ``$GVS_REAL_J1939``), spoils each
copy in one way (degF or kelvin oil, negative torque, torque in percent, speed in rad/s, time_s in minutes, a
garbage line, a truncated last line), replays it with ``gearbox-vsensor replay`` and prints a Markdown table: the
exit status and the first sentence said about the mistake. None may exit 0 with wrong numbers.

    python benchmarks/new_user_mistakes.py [--captures DIR] [--keep DIR]
"""

from __future__ import annotations

import argparse
import csv
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: rad/s per rpm
RAD_S_PER_RPM = 2.0 * 3.141592653589793 / 60.0
#: the engine reference torque the percent mistake divides by [N m] (the configuration's default)
REF_TORQUE_NM = 2400.0


def cli(*args: str, timeout_s: float = 600.0) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "tools.cli", *args], cwd=REPO, capture_output=True, text=True, timeout=timeout_s
    )


def rewrite_table(src: Path, dst: Path, column: str, fn, rows: int | None = None) -> None:
    """Copy the run table ``src`` to ``dst`` (its first ``rows`` rows), ``column`` mapped through ``fn``."""
    with src.open() as f_in, dst.open("w", newline="") as f_out:
        reader = csv.DictReader(f_in)
        writer = csv.DictWriter(f_out, fieldnames=reader.fieldnames)
        writer.writeheader()
        for i, row in enumerate(reader):
            if rows is not None and i >= rows:
                break
            if column and row.get(column, "") != "":
                row[column] = repr(fn(float(row[column])))
            writer.writerow(row)


def spoil_log(src: Path, dst: Path, how: str) -> None:
    """A garbage line in the middle of the log, or its last line cut in half (a logger unplugged)."""
    lines = src.read_text().splitlines(keepends=True)
    if how == "garbage":
        lines.insert(len(lines) // 2, "this is not a frame 12#zz\n")
    elif how == "truncated":
        lines[-1] = lines[-1][: len(lines[-1]) // 2]
    dst.write_text("".join(lines))


def what_it_said(proc: subprocess.CompletedProcess, work: Path) -> str:
    """The first warning or error replay printed (its generic 'exit status 3' line last), else 'nothing'."""
    lines = [ln.strip().replace(str(work) + os.sep, "") for ln in (proc.stderr + proc.stdout).splitlines()]
    generic = "should not be trusted (warnings above)"
    for pattern in (r"^(warning|error)\b|: error:", r"untrusted|skipped|malformed|degF|kelvin|percent|rad/s"):
        for s in lines:
            if re.search(pattern, s, re.I) and generic not in s:
                return s[:400].replace("|", "/")
    return "nothing"


def table_cases(work: Path, drive: Path) -> list[tuple[str, str, Path]]:
    """(drive, mistake, run table) for the run-table mistakes."""
    cases = []
    for label, rows in (("12 min", 720), ("30 min", 1800), ("2 h (bundled)", None)):
        base = work / f"drive_{rows}.csv"
        rewrite_table(drive, base, "", None, rows)
        cases.append((label, "none (honest)", base))
        degf = work / f"degf_{rows}.csv"
        rewrite_table(drive, degf, "oil_temp_c", lambda c: c * 1.8 + 32.0, rows)
        cases.append((label, "oil in degF", degf))
    short = work / "drive_720.csv"
    for mistake, column, fn in (
        ("oil in kelvin", "oil_temp_c", lambda c: c + 273.15),
        ("torque sign flipped", "engine_torque_nm", lambda t: -t),
        ("torque in percent", "engine_torque_nm", lambda t: 100.0 * t / REF_TORQUE_NM),
        ("speed in rad/s", "engine_speed_rpm", lambda n: n * RAD_S_PER_RPM),
        ("time_s in minutes", "time_s", lambda t: t / 60.0),  # a logger's time column in minutes, 1 s rows kept
    ):
        for label, src in (("12 min", short), ("2 h (bundled)", drive)):
            dst = work / f"{column}_{len(cases)}.csv"
            rewrite_table(src, dst, column, fn)
            cases.append((label, mistake, dst))
    return cases


def log_cases(work: Path, logs: dict[str, Path]) -> list[tuple[str, str, Path]]:
    cases = []
    for label, log in logs.items():
        cases.append((label, "none (honest)", log))
        for how in ("garbage", "truncated"):
            dst = work / f"{how}_{log.name}"
            spoil_log(log, dst, how)
            cases.append((label, "a garbage line" if how == "garbage" else "truncated last line", dst))
    return cases


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--captures",
        type=Path,
        default=os.environ.get("GVS_REAL_J1939"),
        help="directory holding normal.candump.log (a real truck capture); default $GVS_REAL_J1939",
    )
    ap.add_argument("--keep", type=Path, help="keep the spoiled files in this directory")
    args = ap.parse_args()
    work = args.keep or Path(tempfile.mkdtemp(prefix="gvs_mistakes_"))
    work.mkdir(parents=True, exist_ok=True)
    drive, log = work / "uphill.csv", work / "uphill_1800.log"
    cli("simulate", "--cycle", "uphill", "--out", str(drive), "--quiet")
    short_csv = work / "uphill_1800.csv"
    rewrite_table(drive, short_csv, "", None, 1800)
    cli("simulate", "--cycle", str(short_csv), "--out", str(work / "sim_1800.csv"), "--can-log", str(log), "--quiet")
    logs = {"CAN log, 30 min (simulate --can-log)": log}
    if args.captures and (Path(args.captures) / "normal.candump.log").is_file():
        logs["real capture (normal)"] = Path(args.captures) / "normal.candump.log"
    print("| drive | mistake | exit | what replay says |")
    print("|---|---|---|---|")
    for label, mistake, path in table_cases(work, drive) + log_cases(work, logs):
        t0 = time.perf_counter()
        proc = cli("replay", str(path), "--out", str(work / "est.csv"))
        said = what_it_said(proc, work)
        print(f"| {label} | {mistake} | {proc.returncode} | {said} |", flush=True)
        print(f"  ({time.perf_counter() - t0:.1f} s)", file=sys.stderr)
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
