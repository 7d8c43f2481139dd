"""`gearbox-vsensor replay`: run the onboard sensor offline over a run table (CSV) or a CAN log, at 10 Hz.

Run tables: tools/replay/table.py; CAN logs (``.log .asc .blf .mf4 .trc``) go through the live CAN service,
tools/replay/log.py, so a log replays bit-identically to a live run. An option of CAN logs on a run table
(``--frames-out``, the hidden ``--strict``) is an error, not silently ignored. Playing a log onto a bus is
`gearbox-vsensor play` (tools/cli/play.py).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from firmware_model.errors import InputError
from tools.can.bus import can_subcommand
from tools.cli.core_option import add_core_option, apply_core
from tools.cli.gearbox_option import add_gearbox_option, resolve_gearbox
from tools.cli.paths import check_paths, figure_path
from tools.cli.scada_notes import say_damaged_lines, say_stuck_channels
from tools.cli.settings import add_hidden, given, setting
from tools.outputs import naming, outputs

#: the two ways to call replay; every option is in one of them (tests/tools/test_cli_options.py)
USAGE = (
    "%(prog)s CSV --out EST.csv [--config TOML] [--gearbox NAME|FILE] [--plot PNG]\n"
    "           [--core {auto,c,numpy}] [--allow-untrusted] [--quiet]\n"
    "       %(prog)s LOG --out EST.csv [those options] [--frames-out OUT.log]\n"
    "       %(prog)s SCADA... --columns NAME|FILE --out EST.csv [those options]"
)
#: the options of CAN logs only, by argparse dest
LOG_OPTIONS = ("frames_out",)
#: the sentence for each option of replay's --realtime, now `gearbox-vsensor play`
_PLAY = (
    "replay --realtime is now its own command: gearbox-vsensor play LOG --interface NAME --channel NAME "
    "[--bitrate BIT_S] [--speed X] plays a log onto a bus; replay computes the outputs offline"
)
#: options replay no longer has: the sentence that says what replaced them (tools.cli.CommandParser)
REMOVED_OPTIONS = {
    "--processes": "--processes was removed: a CAN log without --frames-out is replayed as a whole log at once, the "
    "fast path (same outputs bit for bit as frame by frame); drop the option",
    **{option: _PLAY for option in ("--realtime", "--interface", "--channel", "--bitrate", "--speed")},
}


#: what a record's count counts, where it is not rows (tools.scada.clean.REASON_WORDS): `rows: missing 2034` on a
#: record of 2014 rows without a sump column counted its empty cells
COUNTED = {
    "bad_bytes": "lines",
    "bad_line": "lines",
    "gap": "gaps",
    "missing": "cells",
    "implausible": "values",
    "jump": "values",
    "stuck": "values",
}


def add_subparser(sub):
    p = can_subcommand(
        sub,
        "replay",
        summary="run the onboard sensor offline over a run table or a CAN log (10 Hz estimates)",
        description="Run the onboard virtual sensor (the same pure step as in the truck) over a recorded drive: "
        "a run table (CSV: time_s, engine_speed_rpm, engine_torque_nm, gear, optional oil_temp_c, ambient_temp_c, "
        "coolant_temp_c, vehicle_speed_kmh, retarder_torque_nm) or a CAN log (.log candump -L, .asc, .blf, .mf4, "
        ".trc) decoded like the live service, or a fixed-ratio gearbox's SCADA record (--columns MAP: one output "
        "row per row, est_<channel> beside each measured one; docs/real-data.md). Writes the sensor's output at "
        "10 Hz (a SCADA record's: one row per its rows): the inputs it read, T_<id>_c, W_<id> (0 normal, 1 "
        "warning, 2 critical, 3 not available), "
        "ttl_<id>_s (time to the warning limit with held inputs, empty when never, and where not available: "
        "W_<id> = 3, the first second; docs/interfaces.md) for the gearbox's published "
        "components (28 for the GRS905), and the status (degraded, degraded_mode, input validity, "
        "oil_innovation_c = measured - model oil, model_oil_temp_c, reject counters). Bad input values are not "
        "errors: the sensor holds, clamps or degrades and counts them. Run tables: docs/interfaces.md section 3; "
        "component codes: docs/glossary.md.",
        examples=[
            "gearbox-vsensor replay uphill.csv --out est.csv --plot est.png",
            "gearbox-vsensor replay truck.blf --config truck.toml --out est.csv",
            "gearbox-vsensor replay uphill.csv --config model_oil.toml --out est_model_oil.csv   "
            '# model_oil.toml: [sensor] oil_mode = "model"',
        ],
        notes="\nA CAN log's source addresses come from --config [can] (docs/can.md): the group keys\n"
        "(transmission_source_address sets ETC2 and TRF1 ...) and, per message, the table\n"
        "[can.source_address] (EEC1 EC1 ETC2 TRF1 ET1 AMB CCVS1 ERC1 RC): on a truck that sends the gear\n"
        "from 0x03 and the transmission oil from 0x21, write [can.source_address] TRF1 = 0x21.",
    )
    p.usage = USAGE
    p.removed_options = REMOVED_OPTIONS
    p.add_argument(
        "input",
        metavar="INPUT",
        nargs="+",
        help="run table (.csv), CAN log (.log .asc .blf .mf4 .trc), or with --columns one or more SCADA files "
        "(.csv, .csv.gz) of one unit",
    )
    p.add_argument(
        "--config",
        metavar="TOML",
        help="project configuration: gearbox variant (give the one the drive was made with: another variant's "
        "gear ratios and masses give other temperatures without any error), cooler, [sensor] oil_mode, [can], "
        "[replay] initial_temp_c and strict (docs/interfaces.md section 8)",
    )
    p.add_argument(
        "--out",
        metavar="EST.csv",
        help="sensor output run table (10 Hz; a SCADA record's: one row per its rows; .csv, or .parquet with pyarrow: "
        "several times faster to write); required",
    )
    add_gearbox_option(p)
    p.add_argument("--plot", metavar="PNG", help="plot of the estimates, warnings and oil innovation")
    add_core_option(p)
    p.add_argument(
        "--quiet",
        action="store_true",
        help="no summary (warnings that the outputs are not to be trusted are still printed)",
    )
    p.add_argument(
        "--allow-untrusted",
        action="store_true",
        help="exit 0 even when the outputs should not be trusted: the sensor degraded on more than half "
        "of the steps, a suspect time base, a needed message only from unexpected source "
        "addresses, a unit or sign mistake of the whole record (oil in degF or kelvin, torque "
        "negated or in percent, speed in rad/s, time_s in minutes: the oil changing faster than any gearbox "
        "sump; a fixed-ratio drive's rows over an hour apart: time_s in milliseconds; its speed in rad/s or "
        "time_s in minutes only show as the oil's gap to the model), an input clamped or repaired on more than 5 %% "
        "of the steps, or a log's malformed lines (over 1 %% of them, or one breaking a frame "
        "sequence the step needs) (default: warn on stderr and exit 3, outputs written)",
    )
    _add_log_options(p)
    _add_scada_options(p)
    # moved to the configuration, still accepted (hidden) and overriding it: [sensor] oil_mode, [replay]
    # initial_temp_c and strict
    p.add_argument("--oil-mode", choices=("measured", "model"), help=argparse.SUPPRESS)
    add_hidden(p, "replay.initial_temp_c")
    add_hidden(p, "replay.strict")
    p.set_defaults(func=run)
    return p


def _add_log_options(p: argparse.ArgumentParser) -> None:
    """Options of `replay` that only apply to CAN logs."""
    g = p.add_argument_group("CAN logs (.log candump -L, .asc, .blf, .mf4, .trc)")
    g.add_argument(
        "--frames-out", metavar="OUT.log", help="also write the frames the sensor would send (GBX_*, DM1) as a CAN log"
    )


def _add_scada_options(p: argparse.ArgumentParser) -> None:
    """Options of `replay` for SCADA records (docs/real-data.md)."""
    g = p.add_argument_group("SCADA records (.csv, .csv.gz; docs/real-data.md)")
    g.add_argument(
        "--columns",
        metavar="NAME|FILE",
        help="read the inputs as a SCADA record through this column map (NAME: one shipped, engie; FILE: your own): "
        "one output row per record row, each measured channel beside its estimate est_<channel>; "
        '[sensor] oil_mode = "model" (or --oil-mode model) leaves the sump unread',
    )


def _sensor_options(args) -> dict:
    """The sensor's options of the command line and [replay]: oil_mode (--oil-mode over [sensor] oil_mode, which
    the sensor reads itself), initial_temp_c."""
    from firmware_model.physics.oil import check_temperature_c

    opts = {}
    if args.oil_mode:
        opts["oil_mode"] = args.oil_mode
    initial_c = setting(args, _config(args), "replay.initial_temp_c")
    if initial_c is not None:
        opts["initial_temp_c"] = check_temperature_c("--initial-temp", initial_c)
    return opts


def _config(args):
    """The configuration the replay runs with: --config, its gearbox replaced by --gearbox."""
    return resolve_gearbox(args)


def _given(args, dests) -> list[str]:
    """The options among ``dests`` that the command line set, as written (``--speed``)."""
    return ["--" + d.replace("_", "-") for d in dests if getattr(args, d) not in (None, False)]


def _refuse(given: list[str], why: str) -> None:
    if given:
        raise InputError(f"{', '.join(given)} {'does' if len(given) == 1 else 'do'} nothing {why}")


def run(args) -> int:
    from tools.replay.formats import is_can_log

    if args.columns:
        _config(args)  # the gearbox checked before any work
        print_core = apply_core(args)
        if not args.quiet:
            print(print_core)
        return _run_scada(args)
    if len(args.input) > 1:
        raise InputError(
            f"replay reads one run table or CAN log, not {len(args.input)} files (several files are read as one "
            "record only with --columns, for SCADA)"
        )
    path = Path(args.input[0])
    check_paths(
        [("the input", str(path)), ("the --config", args.config)],
        {"--out": args.out, "--plot": args.plot, "--frames-out": args.frames_out},
        plots=("--plot",),
        tables=("--out",),
        can_logs=("--frames-out",),
    )
    _config(args)  # the gearbox checked before any work
    core_line = apply_core(args)
    if not args.quiet:
        print(core_line)
    if is_can_log(path):
        return _run_log(args, path)
    if path.suffix.lower() == ".gz":
        from tools.replay.formats import check_log

        check_log(path)  # says it is compressed and how to decompress it
    if path.suffix.lower() != ".csv":
        raise InputError(
            f"{path}: unknown input type {path.suffix!r}; replay reads run tables (.csv) and CAN logs "
            f"(.log, .asc, .blf, .mf4, .trc)"
        )
    _refuse(
        _given(args, LOG_OPTIONS) + given(args, ("replay.strict",)), f"on a run table ({path.name}), only on a CAN log"
    )
    if not args.out:
        raise InputError("--out EST.csv is required")
    from firmware_model.description import description_of
    from tools.replay.plot import plot_replay
    from tools.replay.table import held_step_line, replay_csv, summarize, table_findings, written_table
    from tools.runtable import write_run_table

    # the outputs to temporary files first: a failure leaves none of them (tools.outputs)
    with outputs(("--out", args.out), ("--plot", figure_path(args.plot))) as (out_tmp, plot_tmp):
        out, variant, oil_mode = replay_csv(path, _config(args), _sensor_options(args))
        gearbox = _config(args).load_params()
        with naming(out_tmp):
            write_run_table(written_table(out, description_of(gearbox)), out_tmp)  # the columns the drive has
        if plot_tmp:
            with naming(plot_tmp):
                plot_replay(out, plot_tmp, f"{variant} onboard sensor, replay of {path.name}", gearbox=gearbox)
    dest = Path(args.out)
    if not args.quiet:
        from tools.replay.summary import summary_lines

        s = summarize(out)
        print(f"replayed {s.span_s:.1f} s in {s.steps} steps -> {dest}")
        if held_step_line(out):
            print(held_step_line(out))
        for line in summary_lines(out, oil_model=oil_mode == "model", gearbox=gearbox):
            print(line)
    return _report_trust(args, table_findings(out, oil_model=oil_mode == "model"))


def _run_scada(args) -> int:
    """`gearbox-vsensor replay SCADA... --columns NAME|FILE --out EST.csv`: the sensor over one unit's SCADA."""
    from tools.replay.table import held_step_line
    from tools.runtable import write_run_table
    from tools.scada.reader import read_record
    from tools.scada.replay import error_lines, record_findings, replay_record
    from tools.scada.runtable import oil_channel

    check_paths(
        [*(("an input", p) for p in args.input), ("the --config", args.config)],
        {"--out": args.out, "--plot": args.plot},
        plots=("--plot",),
        tables=("--out",),
    )
    _refuse(_given(args, LOG_OPTIONS) + given(args, ("replay.strict",)), "on a SCADA record, only on a CAN log")
    if not args.out:
        raise InputError("--out EST.csv is required")
    config = _config(args)
    record = read_record(args.input, args.columns)
    with outputs(("--out", args.out), ("--plot", figure_path(args.plot))) as (out_tmp, plot_tmp):
        result = replay_record(record, config, _sensor_options(args))
        findings = record_findings(record, result)
        with naming(out_tmp):
            write_run_table(result.written(), out_tmp)  # the columns the drive has
        if plot_tmp:
            from tools.scada.plot import plot_estimates

            with naming(plot_tmp):
                plot_estimates(result, plot_tmp)
    if not args.quiet:
        print(
            f"replayed {record.unit}: {record.n} rows in {record.n_stretches} stretches "
            f"(oil {result.oil_mode}) -> {Path(args.out)}"
        )
        if held_step_line(result.table):
            print(held_step_line(result.table))
        dropped = {k: v for k, v in record.counts.items() if v}
        if dropped:  # each count in what it counts: rows, lines, cells (a record without a column: every row's cell)
            print(
                "  read: "
                + ", ".join(f"{k.replace('_', ' ')} {v} {COUNTED.get(k, 'rows')}" for k, v in dropped.items())
            )
        for line in error_lines(result, oil_channel(record)):
            print(line)
    say_damaged_lines([record], "replayed", args.quiet)
    say_stuck_channels([record])
    return _report_trust(args, findings)


def _report_trust(args, findings) -> int:
    """Print the trust findings (firmware_model.service.trust) on stderr, warnings even with --quiet; returns 3 when
    the outputs should not be trusted (unless --allow-untrusted), else 0."""
    from firmware_model.service.degraded import Severity, untrusted  # (not trust: that imports python-can)

    for f in findings:
        if f.severity >= Severity.WARNING or not args.quiet:
            print(f"{'warning' if f.severity >= Severity.WARNING else 'note'}: {f.sentence}", file=sys.stderr)
    if untrusted(findings) and not args.allow_untrusted:
        print(
            "gearbox-vsensor replay: the outputs are written but should not be trusted (warnings above): exit "
            "status 3 (--allow-untrusted exits 0)",
            file=sys.stderr,
        )
        return 3
    return 0


def _time_notes(result) -> list[str]:
    """The summary's notes on a log's time jumps and time-stamp glitches (counted by the service): where each is
    logged, or, when the time stamps look like milliseconds, one note that the finding explains them all (they are
    then not logged one by one: tools/replay/timelog.py)."""
    jumps = result.service_counters["time_jumps"]
    glitches = result.service_counters.get("frames_time_glitch", 0)
    counted = [
        f"{n} {what if n == 1 else plural}"
        for n, what, plural in (
            (jumps, "time jump", "time jumps"),
            (glitches, "frame time stamp glitch", "frame time stamp glitches"),
        )
        if n
    ]
    if counted and any(f.kind == "milliseconds" for f in result.findings):
        return [
            f"note: {' and '.join(counted)} in the log, all from its time stamps in milliseconds read as seconds "
            "(the warning below), so not listed one by one"
        ]
    notes = []
    if jumps:
        notes.append(f"note: {jumps} time jump{'s' if jumps > 1 else ''} in the log (the warnings above say where)")
    if glitches:
        notes.append(
            f"note: {glitches} frame time stamp{'s' if glitches > 1 else ''} far ahead of the frames around: "
            "taken for glitches, not time jumps (the warnings above say where)"
        )
    return notes


def _run_log(args, path: Path) -> int:
    """`gearbox-vsensor replay LOG --out EST.csv ...`: the sensor's outputs over a CAN log, offline."""
    from tools.replay.log import replay_log_file

    if not args.out:
        raise InputError("--out EST.csv is required to replay a log (to play it onto a bus: gearbox-vsensor play)")
    gearbox = _config(args).load_params()
    with outputs(("--out", args.out), ("--frames-out", args.frames_out), ("--plot", figure_path(args.plot))) as tmp:
        out_tmp, frames_tmp, plot_tmp = tmp
        result = replay_log_file(
            path,
            out_tmp,
            config_path=_config(args),
            sensor_options=_sensor_options(args),
            frames_out=frames_tmp,
            strict=setting(args, _config(args), "replay.strict"),
        )
        if plot_tmp:
            from tools.replay.plot import plot_replay

            with naming(plot_tmp):
                plot_replay(result.table, plot_tmp, f"onboard sensor, replay of {path.name}", gearbox=gearbox)
    table = result.table
    d = result.decoder_counters
    rejected = ", ".join(f"{k} {v}" for k, v in sorted(d["rejected"].items())) or "none"
    if not args.quiet:
        print(
            f"replayed {d['frames_seen']} frames ({d['frames_used']} used; rejected: {rejected}) -> "
            f"{table.n} steps of {table['time_s'][-1]:.1f} s -> {Path(args.out)}"
        )
        for line in _time_notes(result):
            print(line)
        if table.n:
            from tools.replay.summary import summary_lines

            oil_mode = args.oil_mode or _config(args).sensor.get("oil_mode", "measured")
            for line in summary_lines(table, oil_model=oil_mode == "model", gearbox=gearbox):
                print(line)
    return _report_trust(args, _with_log_name(result.findings, table.meta.get("malformed"), path.name))


def _with_log_name(findings, malformed, name: str) -> list:
    """The findings with the log's skipped lines named after its file: among them when they make the outputs
    untrusted (a warning), else added as a note (stderr, like the other notes)."""
    if malformed is None:
        return list(findings)
    named = dataclasses.replace(malformed, name=name)
    if any(f is malformed for f in findings):
        return [named if f is malformed else f for f in findings]
    return [*findings, named]
