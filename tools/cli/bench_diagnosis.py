"""`gearbox-vsensor bench-diagnosis`: the withheld-effect benchmark of the gap diagnosis (tools/diagnosis/bench.py)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from firmware_model.errors import InputError


def add_subparser(sub):
    p = sub.add_parser(
        "bench-diagnosis",
        help="withheld-effect benchmark of the gap diagnosis (synthetic scenarios)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            "Generate scenarios with the reference plant: one catalog effect (or none) at a random magnitude, at "
            "least 30 % of the way from neutral to a bound, on SYNTHETIC training cycles and different test "
            "cycles; measure them like real sensors (lag 0.5-5 s, noise 0.1-0.2 degC, J1939 quantisation "
            "0.03125 degC, 0.5 % dropped samples, noisy torque and speed) with the channels of a truck (oil only) "
            "or a rig (oil plus meas_T_PS_c, meas_T_LI.teeth_c, meas_T_BLR_c); diagnose them with the effect "
            "withheld and print the score table: top-1 identification, false alarms on null scenarios, test-set "
            "RMS shrink, seconds per scenario."
        ),
        epilog="examples:\n  gearbox-vsensor bench-diagnosis --scenarios 40 --seed 1 --out bench/\n"
        "  gearbox-vsensor bench-diagnosis --effect planetary_loss_scale:factor=1.3 --setup rig "
        "--write-scenarios --out ex/",
    )
    p.add_argument("--scenarios", type=int, metavar="N", help="number of scenarios (default 40: 8 null)")
    p.add_argument("--seed", type=int, default=1, metavar="S", help="random seed (default 1)")
    p.add_argument("--out", metavar="DIR", help="write bench.md, bench.csv and one JSON per scenario here")
    p.add_argument(
        "--model",
        choices=("plant", "onboard"),
        default="plant",
        help="model under diagnosis (default plant: the scenarios' truth is the plant at a finer step)",
    )
    p.add_argument(
        "--train-s",
        type=float,
        default=1500.0,
        metavar="S",
        help="length of each of the two training cycles (default 1500 s)",
    )
    p.add_argument(
        "--test-s", type=float, default=1500.0, metavar="S", help="length of the test cycle (default 1500 s)"
    )
    p.add_argument("--only", metavar="I,J,...", help="run only these scenario indices of the plan")
    p.add_argument(
        "--family",
        choices=("single", "sensor", "pair", "model-form"),
        help="the plan's scenario family: single (default: one physical catalog effect, or none), "
        "sensor (the oil sensor's offset or gain, or none), pair (two effects at once, a physical "
        "one and a physical or sensor one, each at least half-way to a bound; or none) or model-form "
        "(four assumed values of the parameter file moved within their bounds: the diagnosis, then "
        "calibrate --auto, on the same files)",
    )
    p.add_argument(
        "--effect", metavar="ID:PARAM=VALUE|none", help="one custom scenario with this effect instead of the plan"
    )
    p.add_argument("--setup", choices=("truck", "rig"), help="set-up of the custom scenario (--effect; default rig)")
    p.add_argument(
        "--cooler", choices=("liquid", "air"), help="cooler of the custom scenario (--effect; default liquid)"
    )
    p.add_argument(
        "--start",
        choices=("auto", "rest", "running"),
        default="auto",
        help="how each file of a scenario starts, as diagnose's --start (default auto: at rest unless a "
        "file's residual shows it began running; the table counts the files taken running)",
    )
    p.add_argument(
        "--write-scenarios",
        action="store_true",
        help="also write each scenario's measured run tables (train1.csv, train2.csv, test1.csv) under "
        "DIR/scenario_NN/, to run `diagnose` on them by hand",
    )
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    import warnings

    from firmware_model.effects import parse_effect
    from tools.diagnosis import bench as B
    from tools.diagnosis.options import Options

    warnings.filterwarnings("ignore", category=RuntimeWarning)
    plan_only = [
        o
        for o, v in (("--scenarios", args.scenarios), ("--only", args.only), ("--family", args.family))
        if v is not None
    ]
    custom_only = [o for o, v in (("--setup", args.setup), ("--cooler", args.cooler)) if v is not None]
    if args.effect and plan_only:
        raise InputError(
            f"{', '.join(plan_only)} {'selects' if len(plan_only) == 1 else 'select'} scenarios of the "
            f"plan, which --effect replaces by one custom scenario"
        )
    if not args.effect and custom_only:
        raise InputError(
            f"{', '.join(custom_only)} {'applies' if len(custom_only) == 1 else 'apply'} only to the "
            f"custom scenario of --effect"
        )
    args.scenarios = 40 if args.scenarios is None else args.scenarios
    args.setup, args.cooler = args.setup or "rig", args.cooler or "liquid"
    if args.scenarios < 1:
        raise InputError(f"--scenarios {args.scenarios} must be at least 1")
    if args.seed < 0:
        raise InputError(f"--seed {args.seed} must be a non-negative integer")
    for opt, value_s in (("--train-s", args.train_s), ("--test-s", args.test_s)):
        if not 60.0 <= value_s <= 86400.0:
            raise InputError(f"{opt} {value_s} must be within 60..86400 s")
    if args.family == "model-form" and args.start != "auto":
        raise InputError(
            "--start applies to the diagnosis of the single, sensor and pair families; the model-form "
            "family's files start at rest"
        )
    if args.write_scenarios and not args.out:
        raise InputError("--write-scenarios needs --out DIR")
    only = None
    if args.only:
        try:
            only = {int(x) for x in args.only.split(",") if x.strip()}
        except ValueError:
            raise InputError(f"--only {args.only!r} must be comma-separated scenario numbers") from None
        outside = sorted(i for i in only if not 0 <= i < args.scenarios)
        if outside:
            raise InputError(
                f"--only {args.only}: no scenario {', '.join(map(str, outside))} in a plan of "
                f"{args.scenarios} (numbered 0..{args.scenarios - 1}; --scenarios sets the plan)"
            )
    custom = None
    if args.effect:
        if args.effect.strip().lower() == "none":
            custom = (args.setup, None, None, args.cooler)
        else:
            eid, val = parse_effect(args.effect)
            custom = (args.setup, eid, val, args.cooler)
    from tqdm import tqdm

    if args.family == "model-form":
        return _model_form(args, only)
    # one result line per scenario on stderr, above the progress bar (shown on a terminal)
    rows, summary = B.run_bench(
        args.scenarios,
        args.seed,
        args.out,
        model=args.model,
        train_s=args.train_s,
        test_s=args.test_s,
        only=only,
        custom=custom,
        write_scenarios=args.write_scenarios,
        progress=lambda line: tqdm.write(line, file=sys.stderr),
        family=args.family or "single",
        opts=Options(start=args.start),
    )
    print(B.format_table(rows, summary))
    if args.out:
        print(f"\n-> {Path(args.out) / 'bench.md'}", file=sys.stderr)
    return 0


def _model_form(args, only) -> int:
    """The model-form family: its own rows (diagnosis and calibration on the same files)."""
    from firmware_model.parameters import load_parameters
    from tools.diagnosis.bench_model_form import format_rows, run_model_form_bench

    rows = run_model_form_bench(
        args.scenarios,
        args.seed,
        load_parameters("GRS905"),
        model=args.model,
        train_s=args.train_s,
        only=only,
        progress=lambda line: print(line, file=sys.stderr),
    )
    table = format_rows(rows)
    print(table)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "bench.md").write_text(table)
        print(f"\n-> {out / 'bench.md'}", file=sys.stderr)
    return 0
