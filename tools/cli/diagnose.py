"""`gearbox-vsensor diagnose`: locate, identify and test the gap between measurements and the model."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from firmware_model.config import load_config
from firmware_model.errors import InputError
from tools.cli.core_option import add_core_option, apply_core
from tools.cli.gearbox_option import add_gearbox_option, require_vehicle_drive, resolve_gearbox
from tools.cli.paths import check_paths
from tools.cli.scada_notes import say_conflicting_rows, say_damaged_lines, say_stuck_channels
from tools.cli.settings import add_hidden, setting


def add_subparser(sub):
    from firmware_model.effects import CATALOG

    effects = "\n".join(f"  {e.id:28s} {e.param} {e.low:g}..{e.high:g} {e.unit}" for e in CATALOG.values())
    p = sub.add_parser(
        "diagnose",
        help="sim-to-real gap diagnosis: where the model misses, which unmodelled effect explains it",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=_description(),
        epilog="examples:\n"
        "  gearbox-vsensor diagnose --train run1.csv run2.csv --test run3.csv --json gap.json\n"
        "  gearbox-vsensor diagnose --train rig_a.csv --test rig_b.csv --model plant --json gap.json "
        "--report gap.md\n\neffects (docs/interfaces.md section 6):\n" + effects,
    )
    p.add_argument(
        "--train",
        nargs="+",
        required=True,
        metavar="FILE",
        help="training runs: run tables (.csv) or CAN logs (.log candump -L, .asc, .blf, .mf4, .trc; decoded "
        "with the sensor's CAN service: TRF1 oil temperature and rig thermocouple frames); SCADA files (.csv, "
        ".csv.gz) with --columns",
    )
    p.add_argument(
        "--test",
        nargs="+",
        required=True,
        metavar="FILE",
        help="test runs (run tables, CAN logs, or SCADA files with --columns), different runs from the training "
        "files (a file that repeats rows of one, e.g. a time window cut from it, is refused)",
    )
    p.add_argument(
        "--config",
        metavar="TOML",
        help="project configuration: gearbox variant, cooler kind (none, liquid, air, hold, measured), boundaries, "
        "and [diagnosis]: grid_dt_s (analysis grid, 2 s), plant_dt_s (the re-simulations' step, 1 s), workers "
        "(processes: 2 or the number of cores), start (how the files start: auto, rest or running; below) "
        "(docs/interfaces.md section 8)",
    )
    p.add_argument(
        "--model",
        choices=("onboard", "plant"),
        default="onboard",
        help="model under diagnosis: onboard, the reduced model that runs in the truck (the reference plant is "
        "used, and said so, while the onboard model is not available), or plant, the reference plant "
        "(default: onboard)",
    )
    p.add_argument("--json", required=True, metavar="OUT.json", help="the gap-diagnosis result (written atomically)")
    p.add_argument(
        "--report", metavar="OUT.md", help="also write a Markdown report with PNG plots next to it (run tables only)"
    )
    add_core_option(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary on stderr/stdout")
    p.add_argument(
        "--columns",
        metavar="NAME|FILE",
        help="the training and test files are SCADA records read through this column map (NAME: one shipped, "
        "engie; FILE: your own; docs/real-data.md): the onboard model of --gearbox replayed over them, the "
        "sump from the model alone, every other measured channel from the measured sump",
    )
    # moved to the configuration, still accepted (hidden) and overriding it: [cooler] kind and [diagnosis]
    p.add_argument("--cooler", choices=("none", "liquid", "air", "hold", "measured"), help=argparse.SUPPRESS)
    for key in DIAGNOSIS_KEYS:
        add_hidden(p, key)
    add_gearbox_option(p)
    p.set_defaults(func=run)
    return p


#: the [diagnosis] settings of the configuration (firmware_model.config.SETTINGS)
DIAGNOSIS_KEYS = ("diagnosis.grid_dt_s", "diagnosis.plant_dt_s", "diagnosis.workers", "diagnosis.start")


def _description() -> str:
    return (
        "Compare measured run tables with the model and diagnose the gap (JSON schema gap-diagnosis/1, see "
        "docs/diagnosis.md).\n\n"
        "Measured channels: oil_temp_c (the vehicle's oil sensor) and meas_T_<id>_c (rig thermocouples, "
        "component ids of docs/interfaces.md section 5, spelled out in docs/glossary.md). The model predicts "
        "the oil itself with its cooler model, and every component follows the model's oil (see "
        "docs/diagnosis.md for why); with cooler kind "
        "'measured' or 'hold' the oil is an input and only thermocouples are diagnosed.\n\n"
        "1. where: residual (measured - model) per channel, its share by regime and episode, and for the oil "
        "the unexplained heat flow it implies;\n"
        "2. which: every catalog effect fitted on the TRAINING files by re-simulation and ranked by "
        "score = -dBIC with an effective sample size (autocorrelated residuals); confusable candidates and "
        "the extra measurement that separates them; verdict 'none' when the model agrees within the "
        "measurement noise, 'unexplained' when no candidate explains the gap (qualified as thin evidence, with the "
        "best candidate and what it would cut, when the files hold too few effective samples to decide: add "
        "more or longer files); beside an effect verdict, the "
        "other effects the data cannot rule out (no strong evidence against them, the verdict refitted) and "
        "those they point to without a claim ('indicated');\n"
        "3. how far it shrinks: RMS and max residual before/after on the TEST files only.\n\n"
        "How the files start ([diagnosis] start): 'rest' (every part at the oil's first reading: a key-on after "
        "a night, a rig run from cold), 'running' (cut from a longer drive, a warm restart: each file scored "
        "after its first 600 s, a thermocouple's after 900 s, with its housings' start fitted), or 'auto' "
        "(default: at rest, then running for the files whose first minutes show a real gap and which the "
        "housings' start then fits far better, unless they begin less than 15 K above the ambient; diagnosed "
        "again; the JSON's 'starts' says which and why)."
    )


def strict_json(obj):
    """``obj`` with every NaN or infinite number as null: JSON has no NaN (Python's json writes one that strict
    parsers refuse, e.g. a held-out RMS over no row)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: strict_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [strict_json(v) for v in obj]
    return obj


def write_json_atomic(obj, path) -> Path:
    from tools.runtable import atomic_text_file

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_text_file(path) as fh:
        json.dump(strict_json(obj), fh, indent=1, allow_nan=False)
        fh.write("\n")
    return path


def run(args) -> int:
    from tools.diagnosis.core import Options, diagnose

    if args.columns:
        return _run_scada(args)

    core_line = apply_core(args)
    if not args.quiet:
        on_core = (
            f"; {core_line}"
            if args.model == "onboard"
            else " (the reference plant; the onboard step's core is not used)"
        )
        print(f"model: {args.model}{on_core}", file=sys.stderr)
    cfg = resolve_gearbox(args, load_config(args.config))
    params = cfg.load_params()
    require_vehicle_drive(params, "diagnose")
    cooler = args.cooler or cfg.cooler or params.strings.get("cooler.kind", "liquid")
    grid_dt_s, plant_dt_s, workers, start = (setting(args, cfg, key) for key in DIAGNOSIS_KEYS)
    check_paths(
        [
            *(("a training file", f) for f in args.train),
            *(("a test file", f) for f in args.test),
            ("the --config", args.config),
        ],
        {"--json": args.json, "--report": args.report},
        makes_dirs=("--json", "--report"),
    )
    opts = Options(grid_dt_s=grid_dt_s, plant_dt_s=plant_dt_s, workers=workers, start=start)
    res, d = _diagnose_with_progress(args, params, cooler, opts, diagnose)
    # render the report first (staged), then the JSON: both complete or nothing new
    if args.report:
        from tools.diagnosis.report import write_report

        write_report(res, d.plot_data, args.report)
    write_json_atomic(res, args.json)
    if not args.quiet:
        print_summary(args, res)
    for w in res.get("warnings", []):  # the data's warnings (a frozen sensor ...), even with --quiet
        print(f"warning: {w}", file=sys.stderr)
    return 0


def _run_scada(args) -> int:
    """`diagnose --columns MAP --train SCADA... --test SCADA...`: the gap of the onboard model on real records."""
    from tools.scada.diagnose import diagnose_records, setup_of, thermostat_of
    from tools.scada.reader import TEST_MIN_READINGS, held_readings, read_held_out

    check_paths(
        [*(("a training file", f) for f in args.train), *(("a test file", f) for f in args.test)],
        {"--json": args.json},
        makes_dirs=("--json",),
    )
    if args.report:
        raise InputError("--report is for run tables; on SCADA records the JSON holds the diagnosis")
    if args.model == "plant":
        raise InputError(
            "--model plant is for run tables; on SCADA records the onboard model of --gearbox is diagnosed (its "
            "replays are what a 10-minute record can drive)"
        )
    cfg = resolve_gearbox(args, load_config(args.config))
    train, test = read_held_out(args.train, args.test, args.columns)
    setup, notes = setup_of(cfg, train[0].cmap)
    say_damaged_lines([*train, *test], "read", args.quiet)
    say_stuck_channels([*train, *test])
    say_conflicting_rows([*train, *test])
    held = held_readings(test)
    if max(held.values(), default=0) < TEST_MIN_READINGS:  # as calibrate: a verdict those rows cannot test
        raise InputError(
            f"the held-out records hold at most {max(held.values(), default=0)} readings of a channel, too few to "
            f"test a diagnosis (at least {TEST_MIN_READINGS}, 6 h of 10-minute rows): give more test files"
        )
    res = diagnose_records(setup, train, test, thermostat_of(cfg.load_params()))
    unread = [ch for ch, n in held.items() if n == 0]
    data_warnings = res.get("warnings", []) + [
        f"the held-out records hold no reading of {ch}: its held-out error is not known (nan in the JSON)"
        for ch in unread
    ]
    res["warnings"] = data_warnings
    if notes:
        res["warnings"] = notes + data_warnings
    write_json_atomic(res, args.json)
    if not args.quiet:
        _print_summary_scada(args, res)
    for note in [] if args.quiet else notes:  # what the fit leaves out by design: a note, as calibrate says it
        print(f"note: {note}", file=sys.stderr)
    for w in data_warnings:
        print(f"warning: {w}", file=sys.stderr)
    return 0


def _print_summary_scada(args, res) -> None:
    v = res["verdict"]
    extra = "".join(f" ({k} = {x:g})" for k, x in v.get("parameters", {}).items())
    print(
        f"verdict: {v['effect']}{extra}; held-out RMS {v['test_rms_before_c']:.2f} -> {v['test_rms_after_c']:.2f} K "
        f"(shrink {100 * v['shrink']:.0f} %) -> {args.json}"
    )
    print(f"reason: {v['reason']}")
    per = ", ".join(
        f"{ch} {c['test_rms_c']:.2f} -> {c['test_rms_after_c']:.2f}"
        if c["test_rms_c"] is not None and math.isfinite(c["test_rms_c"])
        else f"{ch} not read in the held-out records"
        for ch, c in res["channels"].items()
    )
    print(f"held-out RMS per channel [K]: {per}")
    shown = res["where"][:3] if v.get("evidence") != "thin" else []  # (thin: too few rows to say where)
    for w in shown:
        print(f"  gap: {w['channel']} in '{w['regime']}': mean {w['mean_c']:+.2f} K, {100 * w['share']:.0f} % of it")
    if shown:  # a row lies in one regime of each kind (power, nacelle, thermostat...): the shares overlap
        print("  (% of it: of the channel's squared error on the training records; regimes of different kinds overlap)")
    print(f"time: {res['timing']['total_s']:.1f} s")


def _diagnose_with_progress(args, params, cooler, opts, diagnose):
    """The diagnosis with a progress bar by stage (the stages again for files that started running)."""
    from tools.diagnosis.options import STAGES
    from tools.progress import progress

    with progress(len(STAGES), "diagnose", enabled=False if args.quiet else None, unit="stage") as bar:
        again = []

        def stage(name):
            if STAGES.index(name) < bar.n:  # every stage again: some files started running
                again.append(name)
            bar.update(STAGES.index(name) - bar.n)
            bar.set_postfix_str(f"again (files that started running): {name}" if again else name)

        out = diagnose(
            args.train,
            args.test,
            params,
            model=args.model,
            cooler=cooler,
            opts=opts,
            progress=stage,
            keep=True,
            config_path=resolve_gearbox(args),
        )
        bar.update(len(STAGES) - bar.n)
    return out


def print_summary(args, res) -> None:
    """The verdict, its shrink on the test files, the reason, the files taken running and the time."""
    v = res["verdict"]
    extra = ""
    if v["effect"] not in ("none", "unexplained"):
        ((pn, pv),) = v["parameters"].items()
        extra = f" ({pn} = {pv:g})"
    if v.get("evidence") == "thin":
        extra = " (thin evidence)"
    print(
        f"verdict: {v['effect']}{extra}; test RMS {v['test_rms_before_c']:.3f} -> {v['test_rms_after_c']:.3f} "
        f"degC (shrink {100 * v['shrink']:.0f} %) -> {args.json}"
    )
    if v.get("evidence") == "thin":
        print(v["thin_evidence"]["text"])
    confusable = [c["effect"] if isinstance(c, dict) else str(c) for c in v.get("confusable_with") or []]
    if confusable:  # (the JSON and the report list them: the console named the verdict alone)
        print(f"confusable with: {', '.join(confusable)} (they fit these files about as well; the JSON says more)")
    print(f"reason: {v['reason']}")
    running = [n for n, st in res.get("starts", {}).items() if st["start"] == "running"]
    if running:
        print(f"started running (scored after their first minutes, the housings' start fitted): {', '.join(running)}")
    print(f"time: {res['timing']['total_s']:.1f} s (the diagnosis, files read)")
    if res["model"].get("note"):
        print(f"note: {res['model']['note']}", file=sys.stderr)
