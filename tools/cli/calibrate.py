"""`gearbox-vsensor calibrate`: fit the model's assumed parameters to measured runs, checked on held-out runs."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from firmware_model.config import load_config
from firmware_model.errors import InputError
from tools.cli.gearbox_option import add_gearbox_option, require_vehicle_drive, resolve_gearbox
from tools.cli.paths import check_paths
from tools.cli.scada_notes import say_conflicting_rows, say_damaged_lines, say_stuck_channels
from tools.cli.settings import add_hidden, setting

#: --report's help
REPORT_HELP = (
    "also write a Markdown report and its plot (run tables and CAN logs; not with --columns: the SCADA calibration "
    "prints its table)"
)


def add_subparser(sub):
    p = sub.add_parser(
        "calibrate",
        help="fit assumed parameters of the parameter file to measured runs (held-out check)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            "Calibrate the model to a gearbox: fit chosen parameters of the parameter file (each must declare "
            "plausible bounds lo/hi there) to the TRAINING files with the reference plant (SCADA records with "
            "--columns: with the onboard sensor, held over their rows), and check the result on "
            "the TEST files it never saw (see docs/diagnosis.md, 'Calibration').\n\n"
            "1. identifiability: each parameter's signature on every measured channel over half its plausible range, "
            "and which parameters the channels cannot separate;\n"
            "2. fit: bounded least squares of measured - model on every channel; one-sigma uncertainty;\n"
            "3. held-out RMS before and after;\n"
            '4. OUT.toml: the whole parameter file with the fitted values, provenance "fitted" and the data they '
            'came from; use it with --config (params = "OUT.toml") for replay, simulate or diagnose.\n\n'
            "An unknown key, a key without bounds or a key the data cannot identify is refused (one sentence, exit "
            "2, nothing written); --auto fits every bounded key the data can identify and lists the others. A fit "
            "that makes the held-out RMS worse, pooled or on most channels (on SCADA records also one that leaves it "
            "unchanged, or held-out "
            "records with fewer than 36 readings of any channel: they cannot test it) writes no OUT.toml (exit 3; "
            "the report, if asked for, shows why). A fit "
            "whose training residual holds too few effective samples to decide (docs/diagnosis.md, 'Thin evidence') "
            "is said in a warning, the report and the file's header, with the advice: more or longer files.\n\n"
            "How the runs start ([calibration] start): 'rest' (every part at the oil's first reading: a run from "
            "cold or after a long stop), 'running' (cut from a longer drive, a warm restart: each run scored after "
            "its first 600 s, a thermocouple after 900 s, with its housings' start fitted per run), 'auto' "
            "(default: at rest, with a warning for a run that begins with the truck driving and the gearbox warm)."
        ),
        epilog="examples:\n"
        "  gearbox-vsensor calibrate --train rig1.csv rig2.csv --test rig3.csv --auto --out my_gearbox.toml "
        "--report cal/report.md\n"
        "  gearbox-vsensor calibrate --train a.csv --test b.csv --params oil_system.flow_m3_per_rad,"
        "housing.hot_frac --out my_gearbox.toml",
    )
    p.add_argument("--train", nargs="+", required=True, metavar="FILE", help="training runs (the kinds --test takes)")
    p.add_argument(
        "--test",
        nargs="+",
        required=True,
        metavar="FILE",
        help="held-out runs, never used by the fit (a file that repeats rows of a training file is refused): run "
        "tables (.csv), CAN logs, or SCADA files (.csv, .csv.gz) with --columns",
    )
    keys = p.add_mutually_exclusive_group(required=True)
    keys.add_argument(
        "--params", metavar="KEY,KEY,...", help="dotted keys of the parameter file to fit (each with lo/hi bounds)"
    )
    keys.add_argument("--auto", action="store_true", help="fit every key with bounds that the data can identify")
    p.add_argument(
        "--out", required=True, metavar="OUT.toml", help="the calibrated parameter file (written atomically)"
    )
    p.add_argument("--report", metavar="OUT.md", help=REPORT_HELP)
    p.add_argument(
        "--config",
        metavar="TOML",
        help="project configuration: [gearbox] variant or params = a parameter file (one calibrate wrote, too), "
        "cooler kind, and [calibration]: plant_dt_s (the plant's step, 2 s: slow thermal fits lose nothing), "
        "workers (processes: 2 or the number of cores), start (how the runs start: auto, rest or running; above) "
        "(docs/interfaces.md section 8)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress or summary")
    p.add_argument(
        "--columns",
        metavar="NAME|FILE",
        help="the training and test files are SCADA records read through this column map (NAME: one shipped, "
        "engie; FILE: your own; docs/real-data.md): the onboard model of --gearbox is fitted (the sump from the "
        "model alone, every other channel from the measured sump) and a linear normal-behaviour model fitted on "
        "the same training records is scored beside it, without and with the calibrated model's estimate among "
        "its features (the physics-informed NBM)",
    )
    # moved to the configuration, still accepted (hidden) and overriding it: [cooler] kind and [calibration]
    p.add_argument("--cooler", choices=("none", "liquid", "air", "hold", "measured"), help=argparse.SUPPRESS)
    for key in CALIBRATION_KEYS:
        add_hidden(p, key)
    add_gearbox_option(p)
    p.set_defaults(func=run)
    return p


#: the [calibration] settings of the configuration (firmware_model.config.SETTINGS)
CALIBRATION_KEYS = ("calibration.plant_dt_s", "calibration.workers", "calibration.start")


#: a fit that leaves the training files this far off (pooled RMS) explains nothing a sensor could be off by: a unit,
#: a column, a variant or a start that is not at rest [degC]
TRAIN_RMS_REFUSE_C = 5.0
#: a fit that takes no channel's held-out RMS down by this share was not tested by those records (a held-out turbine
#: standing still on 1337 of its 1346 rows: pooled 7.580 -> 7.577 K while f0_tapered moved 4.64 -> 2.05); the
#: shipped MM82 calibrations took their channel down by 5 % (f0_cylindrical, Gb2t 2.62 -> 2.49 K, the pooled RMS
#: by 0.1 %) and 27 % (f0_tapered, Gb1t 5.14 -> 3.77 K)
SCADA_TEST_MIN_SHRINK = 0.01
#: a held-out channel the fit made worse by more than this share (and 0.05 K) is named in a warning
WORSE_SHARE = 0.10
#: a channel's held-out residual after the fit that is this constant (|mean| >= this share of its RMS) and at least
#: OFFSET_LEFT_C large is the signature of a sensor offset or placement, which calibrate does not fit
OFFSET_SHARE = 0.8
OFFSET_LEFT_C = 0.5


def _refusal(cal) -> str:
    """Why the fit is no calibration ('' when it is one): the held-out error grew, pooled or on most channels (a
    trial's PS thermocouple 1.5 K high: the fit took PS 1.15 -> 0.74 K and made the oil, LI teeth and BLR worse,
    and wrote the file), or the training files are still far off after it."""
    bound = [k for k in cal.keys if cal.at_bound[k]]
    at = f" (at a bound: {', '.join(bound)})" if bound else ""
    (before_c, after_c), (_, train_c) = cal.test_rms_c, cal.train_rms_c
    if not after_c < before_c:
        if after_c - before_c <= max(0.05, 0.1 * before_c):  # a change in the noise: the file already fits
            return (
                f"the fit did not reduce the held-out error (RMS {before_c:.4g} -> {after_c:.4g} degC, a change "
                f"within 0.05 K or 10 %): the file's values already match the held-out files; nothing to calibrate"
                f"{at}"
            )
        return (
            f"the fit made the held-out error worse (RMS {before_c:.4g} -> {after_c:.4g} degC); check the training "
            f"files' units and channels{at}"
        )
    by = getattr(cal, "test_by_channel", None) or {}
    worse = [ch for ch, (b, a) in by.items() if a > b * (1.0 + WORSE_SHARE) and a - b > 0.05]
    if len(worse) * 2 > len(by):  # the pooled RMS fell through a minority: one channel traded for the others
        rest = [ch for ch in by if ch not in worse]
        said = ", ".join(f"{ch} {by[ch][0]:.3f} -> {by[ch][1]:.3f}" for ch in worse)
        return (
            f"the fit made {len(worse)} of the {len(by)} held-out channels worse ({said} degC): the pooled RMS fell "
            f"only through {', '.join(rest) or 'none'}, which these values bend the model to; a sensor offset or an "
            f"effect on {'it' if len(rest) == 1 else 'them'} is likelier than the gearbox's values "
            f"(gearbox-vsensor diagnose tells them apart){at}"
        )
    if not train_c <= TRAIN_RMS_REFUSE_C:
        return (
            f"the fitted model is still {train_c:.3g} K (RMS) off the training files, far more than a sensor is "
            f"off: check their units (degF?), columns and variant, and that each run starts at rest (else "
            f'[calibration] start = "running"){at}'
        )
    return ""


def _cautions(cal, params) -> list[str]:
    """What a written calibration should be read with: held-out channels made worse, parameters the runs do not pin
    down (one standard deviation wider than a quarter of the plausible range) or left at a bound."""
    out = []
    for ch, (b, a) in cal.test_by_channel.items():
        if a > b * (1.0 + WORSE_SHARE) and a - b > 0.05:
            out.append(f"the fit made {ch} worse on the held-out files (RMS {b:.3f} -> {a:.3f} degC)")
    out += _offsets_left(cal)
    for k in cal.keys:
        lo, hi = params.bounds.get(k, (math.nan, math.nan))
        if cal.sigma[k] > 0.25 * (hi - lo):
            out.append(
                f"{k} = {cal.fitted[k]:.6g} +- {cal.sigma[k]:.2g} is not pinned down by these runs (its "
                f"plausible range is {lo:.6g}..{hi:.6g}): keep the file's value or add runs that excite it"
            )
        if cal.at_bound[k]:  # both can hold: a loose parameter that also ran into a bound
            out.append(
                f"{k} ended at a bound of its plausible range ({cal.fitted[k]:.6g}): the runs may want a "
                f"value outside it, or another parameter's effect"
            )
    return out


def _offsets_left(cal) -> list[str]:
    """Channels whose held-out residual after the fit is a near-constant offset: an oil sensor reading 2 K high
    biases the fitted file (hot_frac 0.54 for 0.35) and leaves 1.4 K that the user must be told about."""
    import numpy as np

    pooled: dict = {}
    for _, cid, _, _, after in cal.plot.get("test", []):
        pooled.setdefault(cid, []).append(np.asarray(after, dtype=float))
    out = []
    for cid, parts in pooled.items():
        r = np.concatenate(parts)
        r = r[np.isfinite(r)]
        if r.size == 0:
            continue
        mean, rms = float(r.mean()), float(np.sqrt(np.mean(r * r)))
        if abs(mean) >= OFFSET_LEFT_C and abs(mean) >= OFFSET_SHARE * rms:
            check = (
                "check it with `gearbox-vsensor diagnose` (it fits oil_sensor_offset)"
                if cid == "oil"
                else "check that sensor's calibration and placement"
            )
            out.append(
                f"{cid} reads {abs(mean):.2f} K {'above' if mean > 0 else 'below'} the calibrated model on the "
                f"held-out files, nearly constant (RMS {rms:.2f} K): the signature of a sensor offset or "
                f"placement, which calibrate does not fit and which biases the fitted values; {check} before "
                f"using this file"
            )
    return out


def run(args) -> int:
    import datetime as dt

    from firmware_model.parameters import parameter_path
    from tools.diagnosis.calibrate import calibrated_toml

    cfg = resolve_gearbox(args, load_config(args.config))
    params = cfg.load_params()
    if Path(args.out).suffix.lower() != ".toml":
        raise InputError(f"--out {args.out} must be a .toml file")
    if args.columns:
        return _run_scada(args, cfg, params)
    require_vehicle_drive(params, "calibrate")
    check_paths(
        [
            *(("a training file", f) for f in args.train),
            *(("a test file", f) for f in args.test),
            ("the --config", args.config),
        ],
        {"--out": args.out, "--report": args.report},
        makes_dirs=("--out", "--report"),
    )
    cal = _fit(args, cfg, params)
    for st in cal.starts:
        if st.hint:
            print(f"warning: {st.name}: {_calibrate_hint(st.hint)}", file=sys.stderr)
    if args.report:
        _write_report(args.report, cal, params)
    if cal.thin_evidence():  # too few effective samples: said, with the advice, written or not
        print(f"warning: {cal.thin_evidence()}", file=sys.stderr)
    refusal = _refusal(cal)
    if refusal:
        # no calibration (wrong units or channels in the training files, an effect the keys cannot stand for):
        # said, and no parameter file that would look fitted
        print(f"calibrate: {refusal}, so no parameter file was written", file=sys.stderr)
        return 3
    for line in _cautions(cal, params):
        print(f"warning: {line}", file=sys.stderr)
    _write_atomic(
        args.out,
        calibrated_toml(parameter_path(cfg.params_path or cfg.variant), params, cal, dt.date.today().isoformat()),
    )
    if not args.quiet:
        _print_summary(args, cal)
    return 0


def _run_scada(args, cfg, params) -> int:
    """`calibrate --columns MAP --train SCADA... --test SCADA... (--params KEYS | --auto) --out OUT.toml`."""
    import datetime as dt

    import numpy as np

    from firmware_model.parameters import parameter_path
    from tools.diagnosis.calibrate import calibrated_toml, check_keys
    from tools.scada.calibrate import calibrate_records, nbm_beside
    from tools.scada.diagnose import setup_of
    from tools.scada.reader import TEST_MIN_READINGS, held_readings, read_held_out

    check_paths(
        [*(("a training file", f) for f in args.train), *(("a test file", f) for f in args.test)],
        {"--out": args.out},
        makes_dirs=("--out",),
    )
    if args.report:
        raise InputError("--report is for run tables; on SCADA records calibrate prints its tables")
    keys = None if args.auto else check_keys(params, [k.strip() for k in args.params.split(",") if k.strip()])
    train, test = read_held_out(args.train, args.test, args.columns)
    setup, notes = setup_of(cfg, train[0].cmap)
    say_damaged_lines([*train, *test], "read", args.quiet)
    say_stuck_channels([*train, *test])
    say_conflicting_rows([*train, *test])
    for note in [] if args.quiet else notes:  # what the fit leaves out by design: a note, not a warning
        print(f"note: {note}", file=sys.stderr)
    cal = calibrate_records(setup, train, test, keys)
    for note in cal.notes:
        print(f"note: {note}", file=sys.stderr)
    nbm = nbm_beside(setup, train, test, params.with_overrides(cal.fitted))
    if not args.quiet:
        _print_scada(cal, nbm, params.bounds)
    (b, a) = cal.test_rms_c
    same = fit_returns_the_file(cal, params)
    held = max(held_readings(test).values(), default=0)
    why = (
        f"the held-out records hold at most {held} readings of a channel, too few to test it (at least "
        f"{TEST_MIN_READINGS})"
        if held < TEST_MIN_READINGS
        else f"the fit made the held-out records worse (RMS {b:.2f} -> {a:.2f} K)"
        if (a > b or not np.isfinite(a)) and not same
        else f"the fit changed no channel's held-out error by {100 * SCADA_TEST_MIN_SHRINK:g} % or more (RMS {b:.3f} "
        f"-> {a:.3f} K): "
        + (
            "every fitted value lies within two standard deviations of the file's, whose values are this fit's already"
            if same
            else "those records do not test it (a unit standing still, or channels the keys do not move)"
        )
        if not (a < b and any(y < x * (1.0 - SCADA_TEST_MIN_SHRINK) for x, y in cal.test_by_channel.values()))
        else ""
    )
    bound = [k for k in cal.keys if cal.at_bound[k]]
    if why:
        at = f" (at a bound: {', '.join(bound)})" if bound else ""
        print(f"calibrate: {why}{at}, so no parameter file was written", file=sys.stderr)
        return 3
    for line in [*_cautions(cal, params), *cal.rivals]:  # as for run tables: a value at a bound, one not pinned down
        print(f"warning: {line}", file=sys.stderr)
    _write_atomic(
        args.out,
        calibrated_toml(parameter_path(cfg.params_path or cfg.variant), params, cal, dt.date.today().isoformat()),
    )
    if not args.quiet:  # where the file went, on the last line as the run tables' summary and replay say it
        print(f"held-out RMS {b:.2f} -> {a:.2f} K ({100 * (1 - a / b):.0f} % down) -> {args.out}")
    return 0


def fit_returns_the_file(cal, params) -> bool:
    """Whether every fitted value lies within two standard deviations of the file's: the file's values are this
    fit's already. A key the fit could not pin down (an infinite or undefined deviation) never counts as returned."""
    return all(math.isfinite(cal.sigma[k]) and abs(cal.fitted[k] - params[k]) <= 2.0 * cal.sigma[k] for k in cal.fitted)


def _print_scada(cal, nbm: dict, bounds: dict) -> None:
    """Identifiability, the fitted values (and which ended at a bound of their plausible range) and the held-out
    table: physics before and after beside the NBM and the NBM with the calibrated physics among its features."""
    for x in cal.ident:
        sig = ", ".join(f"{ch} {v:.2f}" for ch, v in x.signature_c.items())
        print(f"{x.key}: signature [K over half its range] {sig}" + ("" if x.identifiable else f"; {x.reason}"))
    for k in cal.keys:
        lo, hi = bounds[k]
        at = f"; at a bound of its plausible range {lo:.6g}..{hi:.6g}" if cal.at_bound[k] else ""
        print(f"fitted {k} = {cal.fitted[k]:.6g} +- {cal.sigma[k]:.2g} (was {cal.start[k]:.6g}){at}")
    print(
        "| channel | held-out RMS, physics as shipped [K] | physics calibrated [K] | linear NBM [K] "
        "| physics-informed NBM [K] |"
    )
    print("|---|---:|---:|---:|---:|")
    for ch, (b, a) in cal.test_by_channel.items():
        n, h = nbm.get(ch, (float("nan"), float("nan")))
        print(f"| {ch} | {b:.2f} | {a:.2f} | {n:.2f} | {h:.2f} |")


def _calibrate_hint(hint: str) -> str:
    """A start hint of the diagnosis (tools/diagnosis/start.py), worded for calibrate."""
    return hint.replace("diagnose with", "calibrate with").replace("[diagnosis] start", "[calibration] start")


def _fit(args, cfg, params):
    """The calibration of ``params`` to the training files (tools.diagnosis.calibrate), with a count of the
    evaluations on a terminal."""
    from tools.diagnosis.calibrate import calibrate
    from tools.diagnosis.options import Options

    plant_dt_s, workers, start = (setting(args, cfg, key) for key in CALIBRATION_KEYS)
    cooler = args.cooler or cfg.cooler or params.strings.get("cooler.kind", "liquid")
    keys = [k.strip() for k in (args.params or "").split(",") if k.strip()]
    n = [0]

    def tick():
        n[0] += 1
        if not args.quiet and sys.stderr.isatty():
            print(f"\rcalibrate: fit, {n[0]} evaluations", end="", file=sys.stderr, flush=True)

    cal = calibrate(
        args.train,
        args.test,
        params,
        keys,
        auto=args.auto,
        cooler=cooler,
        opts=Options(workers=workers, start=start),
        progress=tick,
        config_path=cfg,
        dt_s=plant_dt_s,
    )
    if not args.quiet and sys.stderr.isatty():
        print(file=sys.stderr)
    return cal


def _write_atomic(path, text: str) -> None:
    from tools.runtable import atomic_text_file

    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with atomic_text_file(path) as fh:
        fh.write(text)


def _write_report(report, cal, params) -> None:
    """The Markdown report and its held-out plot next to it."""
    from tools.diagnosis.calibrate import plot_held_out, report_markdown

    rep = Path(report)
    rep.parent.mkdir(parents=True, exist_ok=True)
    fig = rep.with_suffix(".png")
    has_fig = plot_held_out(cal, fig)
    _write_atomic(rep, report_markdown(cal, params, fig.name if has_fig else None))


def _print_summary(args, cal) -> None:
    """The keys not fitted and why, each fitted value with its uncertainty, the held-out RMS before and after."""
    for x in cal.ident:
        if not x.identifiable:
            print(f"not fitted: {x.key}: {x.reason}")
    for k in cal.keys:
        print(
            f"{k}: {cal.start[k]:.6g} -> {cal.fitted[k]:.6g} +- {cal.sigma[k]:.2g} (SI)"
            + (" at a bound" if cal.at_bound[k] else "")
        )
    print(
        f"held-out RMS {cal.test_rms_c[0]:.3f} -> {cal.test_rms_c[1]:.3f} degC "
        f"({100 * (1 - cal.test_rms_c[1] / max(cal.test_rms_c[0], 1e-12)):.0f} % down) -> {args.out}"
    )
