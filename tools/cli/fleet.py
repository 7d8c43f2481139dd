"""`gearbox-vsensor fleet`: the onboard sensor over a fleet's CAN logs on Dask; one summary row per log (Parquet)."""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
from pathlib import Path

from firmware_model.errors import InputError
from tools.cli.gearbox_option import add_gearbox_option, resolve_gearbox
from tools.cli.paths import check_paths
from tools.cli.scada_notes import say_conflicting_rows, say_damaged_lines, say_stuck_channels, stuck_sentences
from tools.cli.settings import add_hidden, given, setting


def add_subparser(sub):
    p = sub.add_parser(
        "fleet",
        help="run the sensor over many trucks' CAN logs on Dask (one summary row per log, Parquet)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=DESCRIPTION,
        epilog=EPILOG,
    )
    p.add_argument("logs", nargs="*", metavar="LOGS", help="CAN log files and folders (searched for log suffixes)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created; re-runs resume into it)")
    p.add_argument(
        "--manifest",
        metavar="CSV",
        help="CSV with columns log,vehicle and optional variant,config,date (paths relative to the manifest)",
    )
    p.add_argument(
        "--vehicle-from",
        metavar="REGEX",
        help="regular expression searched in each log's file name, else in its whole path (a pattern with a "
        "folder in it: '(?P<vehicle>[^/]+)/[^/]+$'): the vehicle is its group (?P<vehicle>...), else its first "
        "group, else what it matches (optional (?P<variant>...), (?P<date>...)); a file it does not match stops "
        "the run naming it. Default: the folder directly inside a folder given that holds the log (logs/V/*.log, "
        "logs/V/2026-01/*.log), else one "
        "vehicle per log (its file name without the suffix); the run says which in one line",
    )
    p.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler, tcp://HOST:PORT")
    p.add_argument("--workers", type=int, metavar="N", help="local worker processes (default: one per core)")
    p.add_argument(
        "--diagnose",
        action="store_true",
        help="fleet health: per vehicle and week, fit the cooler effectiveness and (weakly) the oil "
        "volume from the oil temperature, with their uncertainty, and read the measured oil level "
        "(J1939 SPN 124) where a truck sends it; flag drifting vehicles (on synthetic fleets cooler "
        "flags were reliable; trucks that send SPN 124 are flagged on their measured level; on the "
        "others a drift of the oil volume from the temperature is only a 'to watch' (a leak moves "
        "the oil less than the model's own error); docs/fleet.md)",
    )
    p.add_argument(
        "--prune",
        action="store_true",
        help="first remove from DIR the rows of logs that are no longer at their path (moved, renamed "
        "or deleted: a moved log is replayed again under its new path and would count twice)",
    )
    p.add_argument(
        "--config",
        metavar="TOML",
        help="project configuration of the logs whose manifest row names none (variant, [can], [sensor]), and "
        "[fleet]: estimates (write each log's 10 Hz outputs, false), period_days (the --diagnose period, 7; with "
        "--columns calendar months unless set; a drift is flagged after 4 periods at the earliest), report "
        "(report.md and its plots, true) (docs/interfaces.md section 8)",
    )
    # moved to the configuration, still accepted (hidden) and overriding it: [fleet] estimates, period_days,
    # report; --vehicle-pattern is --vehicle-from
    p.add_argument(
        "--columns",
        metavar="NAME|FILE",
        help="LOGS are SCADA files and folders (.csv, .csv.gz) read through this column map (NAME: one shipped, "
        "engie; FILE: your own): per unit and calendar month ([fleet] period_days = N in --config: spans of "
        "N days) the effects of a gearbox ageing fitted with the onboard model of "
        "--gearbox, and the units that drift from the fleet flagged (DIR/health/effects.parquet, flags.parquet; "
        "docs/real-data.md)",
    )
    p.add_argument("--vehicle-pattern", metavar="REGEX", help=argparse.SUPPRESS)
    for key in FLEET_KEYS:
        add_hidden(p, key)
    add_gearbox_option(
        p,
        "the gearbox of the logs whose manifest row names no variant: a description shipped in "
        "firmware_model/params/ (NAME: {names}) or the path of a parameter file with a [topology] (FILE) (default: "
        "their configuration's [gearbox], else GRS905)",
    )
    p.set_defaults(func=run)
    return p


#: the [fleet] settings of the configuration (firmware_model.config.SETTINGS)
FLEET_KEYS = ("fleet.estimates", "fleet.period_days", "fleet.report")
DESCRIPTION = (
    "Replay every CAN log (.log candump -L, .asc, .blf, .mf4, .trc) through the onboard sensor exactly as "
    "`gearbox-vsensor replay` does, and write per log one summary row: vehicle, log, start and end, "
    "duration, per component the peak and when, the time above the warning and the critical level, the "
    "warnings raised and the shortest time to limit, the degraded share, the rejected frames by reason, "
    "the oil innovation mean and RMS (columns: docs/fleet.md).\n\n"
    "Output in DIR: summary/vehicle=V/date=D/*.parquet (Hive partitions), errors/*.parquet (a log that "
    "cannot be read: its reason; the run goes on), estimates/ (with [fleet] estimates: the 10 Hz outputs), "
    "health/ (with --diagnose) and report.md with its plots. Every file is complete or absent; a re-run "
    "skips the logs already done and never writes a row twice.\n\n"
    "Runs on a Dask LocalCluster on this machine (no set-up; --workers N processes, default one per "
    "core) or on an existing cluster (--scheduler tcp://HOST:PORT; the workers need gearbox-vsensor "
    "installed).\n\n"
    "SCADA records (--gearbox MM82 --columns engie DIR...): each unit's files (the unit from the map's unit "
    "column) are replayed in this process and its effects fitted per calendar month ([fleet] period_days = N in "
    "--config: spans of N days); OUT/health/effects.parquet holds every unit-period's fitted values with their "
    "standard errors, flags.parquet the units that drift from their siblings, errors.parquet the files or units "
    "that could not be used. A unit read but never judged against two siblings in the same periods is said in a "
    "note; OUT/report.md says it in words (the flags, what was not judged or left out, each unit's values), and a "
    're-run writes the folder again (docs/real-data.md, "The fleet on SCADA").'
)
EPILOG = (
    "examples:\n"
    "  gearbox-vsensor fleet logs/ --out fleet_out    # logs/V/*.log: vehicle V; logs/*.log: one per log\n"
    "  gearbox-vsensor fleet logs/ --out o --vehicle-from '^(truck\\d+)_'  # truck7_2026-01-05.log\n"
    "  gearbox-vsensor fleet --manifest fleet.csv --out fleet_out --workers 2\n"
    "  gearbox-vsensor fleet --manifest fleet.csv --out fleet_out --scheduler tcp://10.0.0.5:8786\n"
    "  gearbox-vsensor fleet logs/ --out fleet_out --diagnose  # + cooler and oil-level health per week\n"
    "  gearbox-vsensor fleet logs/ --out o --vehicle-from '(?P<vehicle>truck\\d+)_(?P<date>[-\\d]+)'\n"
    "  gearbox-vsensor fleet scada/ --gearbox MM82 --columns engie --out turbines   # SCADA files, one folder"
)


def _entries(args):
    """(the logs, one sentence on how their vehicles were read: None for a manifest, which names them)."""
    from firmware_model.config import load_config
    from tools.cli.gearbox_option import check_gearbox, given_gearbox
    from tools.fleet.manifest import check_entries, entries_and_rule, read_manifest, vehicle_config

    if args.manifest and args.logs:
        raise InputError("give either --manifest or LOGS, not both")
    if args.manifest:
        for opt, value in (("--vehicle-pattern", args.vehicle_pattern), ("--vehicle-from", args.vehicle_from)):
            if value:
                raise InputError(f"{opt} reads vehicles from the logs' names; a manifest names them itself")
        entries, rule = read_manifest(args.manifest), None
    elif not args.logs:
        raise InputError("no logs: give LOGS (files or folders) or --manifest CSV")
    else:
        entries, rule = entries_and_rule(args.logs, args.vehicle_pattern, args.vehicle_from)
    if args.config:  # the configuration of the logs that name none
        config = str(Path(args.config).resolve())
        entries = check_entries([e if e.config else e._replace(config=config) for e in entries], "the logs given")
    gearbox = given_gearbox(args)
    if gearbox is not None:  # the gearbox of the logs that name none, checked as a command's --gearbox
        cfg = resolve_gearbox(args, load_config(None))
        gearbox = cfg.params_path or cfg.variant
        entries = check_entries([e if e.variant else e._replace(variant=gearbox) for e in entries], "the logs given")
    for variant, config in dict.fromkeys((e.variant, e.config) for e in entries):
        check_gearbox(vehicle_config(variant, config))
    return entries, rule


def _warn_duplicates(out) -> None:
    """A warning for logs that look like copies of each other (tools.fleet.report.duplicate_logs)."""
    from tools.fleet.report import copy_vehicles, duplicate_logs
    from tools.fleet.store import read_table

    summary = read_table(out)
    if summary is None:
        return
    c = {n: summary.column(n).to_pylist() for n in ("vehicle", "log", "start_s", "end_s", "frames")}
    dups = duplicate_logs(c)
    for g in dups[:5]:
        vehicles = copy_vehicles(c, g)
        whose = "of one vehicle" if len(vehicles) == 1 else f"under {len(vehicles)} vehicles ({', '.join(vehicles)})"
        print(
            f"warning: {len(g)} logs {whose} look like copies of each other (the same first and last frame "
            f"time and frame count), each summarised and counted: {', '.join(g)}",
            file=sys.stderr,
        )
    if len(dups) > 5:
        print(f"warning: ... {len(dups) - 5} more groups of copies (report.md lists the first 50)", file=sys.stderr)


def _warn_dates(out) -> None:
    """A warning for logs dated (by a manifest or --vehicle-from) otherwise than their Unix frame times say
    (tools.fleet.report.misdated_logs)."""
    from tools.fleet.report import misdated_logs
    from tools.fleet.store import read_table

    summary = read_table(out)
    if summary is None:
        return
    differ = misdated_logs({n: summary.column(n).to_pylist() for n in ("log", "date", "start_s")})
    for log, date, framed in differ[:5]:
        print(
            f"warning: {log} is dated {date} (the manifest or --vehicle-from), its frame times say {framed}: one of "
            "them is wrong, and the date decides the log's period in the health fit",
            file=sys.stderr,
        )
    if len(differ) > 5:
        print(f"warning: ... {len(differ) - 5} more logs whose date differs from their frame times", file=sys.stderr)


def _warn_overlaps(out) -> None:
    """A warning for logs of one vehicle that overlap in time (tools.fleet.report.overlapping_logs)."""
    from tools.fleet.report import overlapping_logs
    from tools.fleet.store import read_table

    summary = read_table(out)
    if summary is None:
        return
    found = overlapping_logs(
        {n: summary.column(n).to_pylist() for n in ("vehicle", "log", "start_s", "end_s", "frames")}
    )
    for vehicle, a, b, overlap_s in found[:5]:
        print(
            f"warning: vehicle {vehicle}: the logs {a} and {b} overlap in time by {overlap_s:.0f} s (one truck "
            "drives one log at a time: two trucks' logs under one vehicle, or one drive logged twice; its peaks "
            "and health fit mix them)",
            file=sys.stderr,
        )
    if len(found) > 5:
        print(f"warning: ... {len(found) - 5} more overlapping pairs (report.md lists the first 50)", file=sys.stderr)


def _warn_gone(out) -> None:
    """A warning for rows whose log is no longer at its path (``--prune`` removes them)."""
    from tools.fleet.store import read_table

    summary = read_table(out)
    if summary is None:
        return
    gone = sorted({p for p in summary.column("log").to_pylist() if not os.path.exists(p)})
    if gone:
        print(
            f"warning: {len(gone)} logs summarised in {out} are no longer at their path (moved, renamed or "
            f"deleted; a moved log is counted again under its new path): {', '.join(gone[:3])}"
            f"{' ...' if len(gone) > 3 else ''}; run again with --prune to remove their rows",
            file=sys.stderr,
        )


def _scada_files(paths) -> list[Path]:
    """The SCADA files among ``paths`` (files, and folders searched for .csv and .csv.gz)."""
    out = []
    for p in map(Path, paths):
        if p.is_dir():
            out += sorted(f for f in p.rglob("*") if f.name.endswith((".csv", ".csv.gz")))
        elif p.is_file():
            out.append(p)
        else:
            raise InputError(f"{p}: no such file or folder")
    if not out:
        raise InputError(f"no SCADA file (.csv, .csv.gz) in {', '.join(map(str, paths)) or 'the arguments'}")
    return out


def _check_scada_drive(cfg, records) -> None:
    """SCADA records are a fixed-ratio drive's run tables: a gearbox with a vehicle drive (no --gearbox: the GRS905)
    is refused before any work, not after notes on channels its description does not have."""
    from firmware_model.description import description_of
    from tools.drive_table import SCADA_SOURCE, check_drive
    from tools.scada.runtable import INPUTS

    unit = next(iter(records))
    check_drive(("time_s", *INPUTS), description_of(cfg.load_params()), f"{SCADA_SOURCE}{unit}")


def _run_scada(args) -> int:
    """`fleet --gearbox NAME --columns MAP DIR... --out OUT`: the fleet's health on SCADA records."""
    from firmware_model.config import load_config
    from tools.progress import progress
    from tools.scada.diagnose import setup_of
    from tools.scada.fleet import MIN_UNITS, fit_fleet, flag_units
    from tools.scada.reader import read_units

    _refuse_log_options(args)
    try:  # (after the options: a misplaced one is said whether or not pyarrow is installed)
        import pyarrow  # noqa: F401
    except ImportError:
        raise InputError("the fleet command writes Parquet: pip install 'gearbox-vsensor[fleet]' (pyarrow)") from None
    cfg = resolve_gearbox(args, load_config(args.config))
    # the CAN logs' [fleet] settings a shared configuration may hold: said, not silently dropped
    for key, default in (("fleet.estimates", False), ("fleet.report", True)):
        if cfg.setting(key) != default:
            print(f"note: [fleet] {key.split('.')[1]} is for CAN logs; the SCADA fleet ignores it", file=sys.stderr)
    if Path(args.out).exists() and not Path(args.out).is_dir():
        raise InputError(f"--out {args.out} is a file; the fleet writes a folder (health/*.parquet) there")
    skipped: list = []
    records = read_units(_scada_files(args.logs), args.columns, skipped)
    for path, why in skipped:
        print(f"skipped {path}: {why}", file=sys.stderr)
    _check_scada_drive(cfg, records)  # before the notes: a gearbox of another drive is the one sentence
    say_damaged_lines(records.values(), "read")
    say_stuck_channels(records.values())
    say_conflicting_rows(records.values())
    for rec in records.values():  # kept with the output, as a channel left out is (errors.parquet)
        skipped += [(", ".join(str(p) for p in rec.files), why) for why in stuck_sentences(rec)]
        if rec.conflict_sentence():  # the files whose rows disagreed, not every file of the unit
            skipped.append((", ".join(str(p) for p in sorted(rec.conflicts)), rec.conflict_sentence()))
    setup, notes = setup_of(cfg, next(iter(records.values())).cmap)
    for note in notes:
        print(f"note: {note}", file=sys.stderr)
    t0 = time.perf_counter()
    # calendar months unless --period-days or the file's [fleet] period_days is given (the setting's default, 7,
    # is the trucks'; a file's value was ignored in silence)
    chosen = given(args, ("fleet.period_days",)) or "fleet.period_days" in cfg.settings
    days = float(setting(args, cfg, "fleet.period_days")) if chosen else None
    rejected: list = []
    with progress(len(records), "fleet", unit="unit") as bar:
        fits = fit_fleet(setup, records, days, progress=lambda: bar.update(1), rejected=rejected)
    for unit, why in rejected:
        print(f"{'note' if ' left out: ' in why else 'left out ' + unit}: {why}", file=sys.stderr)
        skipped.append((", ".join(str(p) for p in records[unit].files), why))
    rejected = [r for r in rejected if " left out: " not in r[1]]  # (a channel left out: the unit is fitted)
    _say_rows_dropped(records)
    flags = flag_units(fits)
    root = Path(args.out) / "health"
    _write_health(root, fits, flags)
    kind = "unit-months" if days is None else "unit-periods"
    used = len(records) - len(rejected)
    judged, not_judged = _say_not_judged(fits, sorted(set(records) - {u for u, _ in rejected}))
    used = len({f.unit for f in fits})  # fitted: a unit read without a fitted period is in the notes above
    # the units read and those fitted: a unit left out (a sump in degF) is said on stdout too, not only on stderr
    left = f" ({len(rejected)} of {len(records)} read left out, above)" if rejected else ""
    print(
        f"fleet: {used} unit{'s' if used != 1 else ''} fitted{left}, {judged} judged against their siblings, "
        f"{len(fits)} {kind} in {time.perf_counter() - t0:.1f} s; {len(flags)} flagged -> {root}"
    )
    for f in flags:
        print(f"  {f.vehicle}: {f.effect} from {f.start}: {f.reason}")
    if used < MIN_UNITS:
        print(
            f"note: {used} unit{'s' if used != 1 else ''} fitted: a unit is flagged against its siblings' "
            f"median, which needs at least {MIN_UNITS}; none could be flagged",
            file=sys.stderr,
        )
    _write_left_out(root, skipped)
    from tools.scada.report import write_report as write_scada_report

    print(f"report: {write_scada_report(Path(args.out) / 'report.md', fits, flags, not_judged, skipped, kind)}")
    return 0


def _write_left_out(root: Path, skipped: list) -> None:
    """health/errors.parquet: the files, units or channels not used in whole or in part (none: an earlier run's
    table removed, it is not this run's)."""
    import pyarrow as pa

    from tools.fleet.store import write_atomic

    if not skipped:  # a run into the folder of an earlier one: its errors are not this run's
        (root / "errors.parquet").unlink(missing_ok=True)
    if skipped:
        write_atomic(
            pa.Table.from_pylist([{"file": str(p), "error": why} for p, why in skipped]), root / "errors.parquet"
        )
        print(
            f"note: {len(skipped)} file(s), unit(s) or channels could not be used, in whole or in part (above; "
            f"{root / 'errors.parquet'})",
            file=sys.stderr,
        )


def _refuse_log_options(args) -> None:
    """One sentence for the CAN logs' options given with --columns."""
    logs_only = ("scheduler", "workers", "diagnose", "manifest", "prune", "vehicle_from", "vehicle_pattern")
    named = [f"--{o.replace('_', '-')}" for o in logs_only if getattr(args, o)]
    named += given(args, ("fleet.estimates", "fleet.report"))
    if named:
        raise InputError(
            f"{', '.join(named)}: for CAN logs, not with --columns (a SCADA unit is its files' "
            "Wind_turbine_name column, or the map's unit_id)"
        )


def _say_not_judged(fits, units) -> tuple[int, dict]:
    """On stderr, a note per unit of ``units`` never judged against its siblings, and why (a unit read but never
    compared is not a sound one), or judged but for some periods; (the number judged, unit -> what was said)."""
    from tools.scada.fleet import MIN_UNITS, alone_periods, coverage

    why = coverage(fits, units)
    said = {u: w for u, w in why.items() if w}
    for unit, starts in alone_periods(fits).items():
        if not why.get(unit):  # (a unit never judged is said as such)
            which = ", ".join(starts[:3]) + (" ..." if len(starts) > 3 else "")
            said[unit] = (
                f"{len(starts)} of its periods ({which}) {'was' if len(starts) == 1 else 'were'} fitted beside fewer "
                f"than {MIN_UNITS - 1} siblings: no fleet median there, not judged"
            )
    for unit, sentence in said.items():
        print(f"note: {unit}: {sentence}", file=sys.stderr)
    return sum(not w for w in why.values()), said


def _say_rows_dropped(records) -> None:
    """On stderr, each unit's rows the reader dropped or sorted (duplicate, unreadable or unstamped rows, rows out of
    order), as replay says them: a file whose turbine column names another unit folds into that unit's record."""
    from tools.scada.clean import REASON_WORDS

    for unit, rec in sorted(records.items()):
        c = {
            k: rec.counts.get(k, 0)
            for k in ("bad_line", "bad_time", "duplicate_time", "conflicting_time", "out_of_order")
        }
        if any(c.values()):
            said = "; ".join(f"{v} {REASON_WORDS[k]}" for k, v in c.items() if v)
            print(f"note: {unit} ({rec.n} rows kept): {said}", file=sys.stderr)


def _write_health(root: Path, fits, flags) -> None:
    """health/effects.parquet (one row per unit, period and effect) and health/flags.parquet under ``root``."""
    import pyarrow as pa

    from tools.fleet.store import write_atomic
    from tools.scada.fleet import in_range

    root.mkdir(parents=True, exist_ok=True)
    rows = [
        {
            "unit": f.unit,
            "start": f.start,
            "rows": f.rows,
            "blocks": f.blocks,
            "effect": e,
            "value": f.values[e],
            "se": f.se[e],
            "rms_c": f.rms_c,
            "in_range": in_range(f, e),  # identified and within the effect's plausible range
        }
        for f in fits
        for e in f.values
    ]
    write_atomic(pa.Table.from_pylist(rows), root / "effects.parquet")
    flag_schema = pa.schema(
        [
            (k, pa.float64() if k in ("value", "baseline") else pa.int64() if k == "period" else pa.string())
            for k in ("vehicle", "effect", "period", "start", "value", "baseline", "reason", "kind")
        ]
    )
    write_atomic(pa.Table.from_pylist([f._asdict() for f in flags], schema=flag_schema), root / "flags.parquet")


def check_health_gearboxes(entries) -> None:
    """InputError before any work when --diagnose's health fit (the cooler's effectiveness and the sump's volume of
    the GRS905 family, tools/fleet/health.py) cannot act on a log's gearbox: every log failed it, one by one."""
    from firmware_model.config import load_config
    from firmware_model.effects import oil_level_refusal
    from tools.cli.gearbox_option import with_gearbox

    for variant in sorted({e.variant for e in entries if e.variant}):
        why = oil_level_refusal(with_gearbox(load_config(None), variant).load_params())
        if why:
            raise InputError(
                f"--diagnose fits the cooler's effectiveness and the oil volume of the GRS905 family's sump, which "
                f"the logs of gearbox {Path(variant).name} cannot have ({why}); without --diagnose the fleet "
                "summarises them"
            )


def run(args) -> int:
    from firmware_model.config import load_config
    from tools.fleet.run import run_fleet

    if args.config:
        check_paths([("the --config", args.config)], {})
    if args.columns:
        return _run_scada(args)
    estimates, period_days, report = (setting(args, load_config(args.config), key) for key in FLEET_KEYS)
    entries, rule = _entries(args)
    if args.diagnose:
        check_health_gearboxes(entries)
    if given(args, ("fleet.period_days",)) and not args.diagnose:
        raise InputError("--period-days sets the health fit's period, which only --diagnose runs")
    if args.scheduler and not re.fullmatch(
        r"(tcp|tls|inproc|ucx|ws|wss)://[^\s/]+(:\d+)?/?|[\w.-]+:\d+", args.scheduler
    ):
        raise InputError(f"--scheduler {args.scheduler!r} is not a scheduler address; give tcp://HOST:PORT")
    if args.prune:
        _prune(args.out)
    if rule:
        print(rule)
    t0 = time.perf_counter()
    res = run_fleet(
        entries, args.out, scheduler=args.scheduler, workers=args.workers, estimates=estimates, diagnose=args.diagnose
    )
    wall_s = time.perf_counter() - t0
    n_vehicles = len({e.vehicle for e in entries})
    print(
        f"fleet: {res.logs} logs of {n_vehicles} vehicle{'s' if n_vehicles != 1 else ''}; {res.skipped} done before, "
        f"{res.summarised} summarised, {res.failed} in the errors table; {res.tasks} tasks on {res.workers} "
        f"workers in {wall_s:.1f} s"
    )
    if res.resettled:
        print(
            f"fleet: {res.resettled} of the logs summarised before were replayed again: their settings changed since "
            "(the gearbox, the [can], [sensor], [cooler] or [boundary] configuration, the vehicle name or the "
            "manifest's date) or [fleet] estimates asked for estimates they did not have"
        )
    if res.unrecorded:
        print(
            f"note: {res.unrecorded} logs in {args.out} were summarised by an earlier version, whose rows do not "
            "record their configuration: kept, so a changed --config is not seen for them (use a new --out, or "
            "remove their rows, to replay them with it)",
            file=sys.stderr,
        )
    _print_errors(args.out)
    _warn_duplicates(args.out)
    _warn_overlaps(args.out)
    _warn_dates(args.out)
    _warn_gone(args.out)
    why_none = _health(args.out, period_days) if args.diagnose else ""
    if report:
        from tools.fleet.report import write_report

        print(f"report: {write_report(args.out, why_none)}")
    return 0


def _prune(out) -> None:
    """--prune: remove the rows of logs no longer at their path, and say which."""
    from tools.fleet.store import FleetStore

    gone = FleetStore(out).prune() if (Path(out) / "summary").is_dir() else []
    print(
        f"prune: {len(gone)} logs no longer at their path, their rows removed"
        + (": " + ", ".join(gone[:5]) + (f" ... and {len(gone) - 5} more" if len(gone) > 5 else "") if gone else "")
    )


def _print_errors(out) -> None:
    """The first five rows of the errors table on stderr."""
    from tools.fleet.store import ERRORS, read_table

    errors = read_table(out, ERRORS)
    if errors is not None and errors.num_rows:
        for r in errors.slice(0, 5).to_pylist():
            # the reason names its log when the reader raised it; a summary's sentence may not ("the log's first
            # frame time ..."): the log's name first then
            name = os.path.basename(str(r.get("log") or ""))
            why = r["reason"] if not name or name in r["reason"] else f"{name}: {r['reason']}"
            print(f"  error ({r['stage']}): {why}", file=sys.stderr)
        if errors.num_rows > 5:
            print(f"  ... {errors.num_rows - 5} more in {out}/errors", file=sys.stderr)


def _health(out, period_days: int) -> str:
    """--diagnose: the fleet health per vehicle and period, its summary lines; why nothing was written ('' when
    something was)."""
    from tools.fleet.health import JUDGED_PERIODS, fleet_health, level_short_sentence

    health = fleet_health(out, period_days=period_days)
    if health.periods:
        print(
            f"health: {health.judged} of {health.vehicles} vehicles have the {JUDGED_PERIODS} periods of "
            f"{period_days:g} days a drift needs before it can be flagged (a baseline, then a run)"
            + (
                f"; {health.undated} fitted logs left out: no date (give one in the manifest's date column)"
                if health.undated
                else ""
            )
            + (
                f"; {health.far} fitted logs left out: dated more than 60 days before or after the rest of "
                f"the fleet (a truck's clock set wrong? give the date in the manifest)"
                if health.far
                else ""
            )
        )
    print(
        f"health: {health.periods} vehicle-periods fitted; flagged: "
        + (", ".join(f"{f.vehicle} ({f.effect})" for f in health.flags) or "none")
        + "; to watch (oil level from the oil temperature, not identifiable: check it): "
        + (", ".join(f.vehicle for f in health.watch) or "none")
    )
    if health.level_short:
        print(f"health: {level_short_sentence(health.level_short)}")
    if health.why_none:
        print(f"health: nothing written to {out}/health: {health.why_none}")
    return health.why_none or ""
