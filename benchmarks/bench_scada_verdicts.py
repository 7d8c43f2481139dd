"""The gap diagnosis's verdict on each turbine of the ENGIE SCADA (docs/real-data.md, "The gap on real data": issue
46's "the diagnosis's verdict on each turbine, with the held-out shrink").

For each turbine T of R80721, R80736, R80790 (R80711 is held out: never read), the diagnosis of the MM82's onboard
model (tools/scada/diagnose.py, the path of `diagnose --gearbox MM82 --columns engie`):

- own history: trained on T's 2013-2016 files, held out on T's 2017-2020 files;
- across turbines (``--cross``): trained on the two others' 2017-2020 files, held out on T's 2017-2020 files.

It prints one table row per diagnosis: the verdict and its parameter, the held-out RMS before -> after pooled and
per channel (the sump in model mode, the bearings from the measured sump) with the shrink, the regime carrying the
largest share of the training gap (the JSON's "where"), every tested candidate's held-out RMS (marked at a bound
of its range), the verdict of the rule before one at a bound was refused, and the wall time; then every effect's
fitted value on every split, to compare the turbines. ``--out DIR`` also writes each
gap-diagnosis/1 JSON there.

``--return-thermostat 80`` diagnoses instead the copy of the MM82 whose thermostat reads the return, with that oil
flow [L/min] (benchmarks/bench_mm82_thermostat.py: the form of before 2026-12-05, the values calibrated since).

    python benchmarks/bench_scada_verdicts.py DATA_DIR [--cross] [--only R80721]... [--out DIR] [--return-thermostat F]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from firmware_model.config import load_config  # noqa: E402
from tools.cli.gearbox_option import with_gearbox  # noqa: E402
from tools.scada.diagnose import SCORE_MIN, diagnose_records, setup_of, thermostat_of  # noqa: E402
from tools.scada.reader import read_units  # noqa: E402

TURBINES = ("R80721", "R80736", "R80790")
#: the farm's fourth turbine, kept out as a held-out test (the data's README): never read here
HELD_OUT = "R80711"


def files_of(data_dir: Path, unit: str, period: str) -> list[Path]:
    """The files of ``unit``'s ``period`` (2013-2016 or 2017-2020) in ``data_dir``, in name order."""
    if unit == HELD_OUT:
        raise SystemExit(f"{HELD_OUT} is held out: not read")
    files = sorted(data_dir.glob(f"turbine_{unit}_{period}_*.csv*"))
    if not files:
        raise SystemExit(f"no file turbine_{unit}_{period}_*.csv[.gz] in the folder")
    return files


def splits(data_dir: Path, cross: bool, only: list[str]) -> list[tuple[str, str, list[Path], list[Path]]]:
    """(label, short name, training files, held-out files) of each diagnosis."""
    out = []
    for t in TURBINES:
        if only and t not in only:
            continue
        test = files_of(data_dir, t, "2017-2020")
        out.append((f"{t}: 2013-16 -> 2017-20", f"{t}_own", files_of(data_dir, t, "2013-2016"), test))
        if cross:
            others = [u for u in TURBINES if u != t]
            train = [f for u in others for f in files_of(data_dir, u, "2017-2020")]
            out.append((f"{'+'.join(others)} -> {t} (2017-20)", f"{t}_cross", train, test))
    return out


def diagnose_split(cfg, train_files, test_files) -> dict:
    """The gap-diagnosis/1 result of ``cfg``'s gearbox, as `diagnose --columns engie` computes it."""
    train, test = (list(read_units(f, "engie").values()) for f in (train_files, test_files))
    setup, _ = setup_of(cfg, train[0].cmap)
    return diagnose_records(setup, train, test, thermostat_of(cfg.load_params()))


def _value(c: dict) -> str:
    """An effect's one parameter: an offset signed, a factor plain (none for none and unexplained)."""
    return "".join(f" {x:+.2f}" if k == "offset_c" else f" {x:.2f}" for k, x in c.get("parameters", {}).items())


def _holds(c: dict, before: float) -> bool:
    """Whether candidate ``c`` was tested, scores, and makes the held-out records no worse."""
    return "test_rms_after_c" in c and c["score"] >= SCORE_MIN and c["test_rms_after_c"] <= before


def _verdict(res: dict) -> str:
    """The verdict; for 'unexplained', the candidate at a bound of its range that it did not claim."""
    v = res["verdict"]
    text = f"`{v['effect']}`{_value(v)}"
    if v["effect"] == "unexplained":
        b = next((c for c in res["candidates"] if _holds(c, v["test_rms_before_c"])), None)
        if b is not None and b.get("at_bound"):
            text += f" ({b['effect']}{_value(b)}: bound)"
    return text


def _without_bound_rule(res: dict) -> str:
    """The verdict of the rule before candidates at a bound were refused: the best that scores and holds."""
    before = res["verdict"]["test_rms_before_c"]
    c = next((c for c in res["candidates"] if _holds(c, before)), None)
    if res["verdict"]["effect"] == "none" or c is None:
        return f"`{res['verdict']['effect']}`"
    return f"`{c['effect']}`{_value(c)}, {before:.2f} -> {c['test_rms_after_c']:.2f}"


def _pct(x: float) -> str:
    """A shrink in whole percent (an int: no "-0 %")."""
    return f"{round(100 * x)} %"


def row(label: str, res: dict, wall_s: float) -> str:
    v = res["verdict"]
    chans = "; ".join(
        f"{ch.removesuffix('_avg')} {c['test_rms_c']:.2f} -> {c['test_rms_after_c']:.2f} "
        f"({_pct(1 - c['test_rms_after_c'] / c['test_rms_c'])})"
        for ch, c in res["channels"].items()
    )
    w = res["where"][0] if res["where"] else None
    top = f"{w['channel'].removesuffix('_avg')}, {w['regime']}: {100 * w['share']:.0f} %, mean {w['mean_c']:+.1f} K"
    others = ", ".join(
        f"{c['effect']}{_value(c)}{' (bound)' if c.get('at_bound') else ''}: {c['test_rms_after_c']:.2f}"
        for c in res["candidates"]
        if "test_rms_after_c" in c and c["effect"] != v["effect"]
    )
    pooled = f"{v['test_rms_before_c']:.2f} -> {v['test_rms_after_c']:.2f} ({_pct(v['shrink'])})"
    return (
        f"| {label} | {_verdict(res)} | {pooled} | {chans} | {top if w else '-'} | {others or '-'} | "
        f"{_without_bound_rule(res)} | {wall_s:.0f} |"
    )


def values_table(results: dict) -> str:
    """Every candidate's fitted value and training score per split (the same effect on every turbine, or not)."""
    labels = list(results)
    effects = sorted({c["effect"] for r in results.values() for c in r["candidates"]})
    lines = ["| effect | " + " | ".join(labels) + " |", "|---|" + "---:|" * len(labels)]
    for e in effects:
        cells = []
        for lab in labels:
            c = next((c for c in results[lab]["candidates"] if c["effect"] == e), None)
            cells.append(f"{next(iter(c['parameters'].values())):.2f} ({c['score']:.0f})" if c else "-")
        lines.append(f"| {e} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data_dir", type=Path)
    ap.add_argument("--cross", action="store_true", help="also train on the two other turbines' 2017-2020 files")
    ap.add_argument("--only", action="append", default=[], help="only this test turbine (repeatable)")
    ap.add_argument("--out", type=Path, help="write each gap-diagnosis/1 JSON into this folder")
    ap.add_argument(
        "--return-thermostat",
        type=float,
        metavar="L_PER_MIN",
        help="diagnose a copy of the MM82 whose thermostat reads the return (seed Eq 82, the form before "
        "2026-12-05), with this oil flow (80: the value of before), in place of the shipped one",
    )
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        gearbox = "MM82"
        if args.return_thermostat is not None:
            from bench_mm82_thermostat import return_thermostat_copy

            gearbox = str(return_thermostat_copy(args.return_thermostat, Path(tmp)))
            print(f"MM82 with its thermostat at the return, oil flow {args.return_thermostat:g} L/min\n")
        run(args, with_gearbox(load_config(None), gearbox))
    return 0


def run(args, cfg) -> None:
    """Every split's diagnosis with ``cfg``'s gearbox: the table, then the values side by side."""
    print(
        "| split | verdict | held-out RMS [K] before -> after (shrink) | per channel [K] | largest share of the "
        "training gap | tested candidates: held-out RMS [K] | with bounds allowed (rule before) | wall [s] |"
    )
    print("|---|---|---|---|---|---|---|---:|")
    results = {}
    for label, name, train, test in splits(args.data_dir, args.cross, args.only):
        t0 = time.perf_counter()
        res = diagnose_split(cfg, train, test)
        results[label] = res
        print(row(label, res, time.perf_counter() - t0), flush=True)
        if args.out:
            args.out.mkdir(parents=True, exist_ok=True)
            (args.out / f"{name}.json").write_text(json.dumps(res, indent=1))
    print("\nEvery candidate's fitted value (training score, BIC drop) per split:\n")
    print(values_table(results))


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
