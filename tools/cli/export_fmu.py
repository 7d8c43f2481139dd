"""`gearbox-vsensor export-fmu`: the onboard sensor as an FMI 2.0 or 3.0 co-simulation FMU (tools.export.fmu)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tools.cli.gearbox_option import add_gearbox_option, resolve_gearbox


def add_subparser(sub):
    p = sub.add_parser(
        "export-fmu",
        help="write the onboard sensor as an FMI 2.0 or 3.0 co-simulation FMU for HIL/SIL rigs",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Build an FMI 2.0 (default) or FMI 3.0 co-simulation FMU of the onboard sensor from the "
        "compiled C kernel and the "
        "variant's generated tables: the binary for this platform plus its sources. Communication step "
        "0.1 s (or a multiple). Variables are named as the run-table columns (docs/interfaces.md "
        "section 3): inputs engine_speed_rpm ... retarder_torque_nm (a fixed-ratio gearbox: input_speed_rpm, "
        "input_torque_nm, oil_temp_c, ambient_temp_c), outputs T_<id>_c, W_<id>, "
        "ttl_<id>_s, degraded_mode, valid_flags, frozen_flags, model_oil_temp_c, oil_innovation_c, "
        "rejects_<reason>; parameters variant, initial_temp_c and the limits limit_warning_<id>_c, "
        "limit_critical_<id>_c.\n\nThe time to limit is refreshed every 1 s inside the FMU (the kernel's "
        "march) and the early warning is on. Needs a C compiler and FMPy (pip install fmpy) for the "
        "FMI headers.",
        epilog="examples:\n  gearbox-vsensor export-fmu --out vsensor.fmu && python -m fmpy info vsensor.fmu\n"
        "  gearbox-vsensor export-fmu --fmi 3 --out vsensor3.fmu && python -m fmpy validate vsensor3.fmu",
    )
    p.add_argument(
        "--config",
        metavar="TOML",
        help="project configuration: [gearbox] (default GRS905), cooler, [sensor] limits",
    )
    p.add_argument(
        "--fmi",
        choices=("2", "3"),
        default="2",
        help="FMI version: 2 (most rigs import it) or 3 (Float64/Int32 variables) (default: 2)",
    )
    p.add_argument("--out", required=True, metavar="FILE.fmu", help="the FMU to write")
    add_gearbox_option(p)
    # moved: --quiet (its one line: redirect it) still accepted
    p.add_argument("--quiet", action="store_true", help=argparse.SUPPRESS)
    p.set_defaults(func=run)


def run(args) -> int:
    from tools.cli.paths import check_paths
    from tools.export.fmu import export_fmu

    # before the build: --out a directory, in a missing directory, or also the --config
    check_paths([("the --config", args.config)], {"--out": args.out})
    cfg = resolve_gearbox(args)
    if cfg.setting("export.time_to_limit") is False:  # export-c's setting: said, not ignored in silence
        print(
            "warning: [export] time_to_limit = false applies to export-c (an ECU's flash); the FMU computes the time "
            "to limit as the onboard sensor does (its ttl_<id>_s outputs)",
            file=sys.stderr,
        )
    existed = Path(args.out).is_file()
    out = export_fmu(args.out, config_path=cfg, fmi_version=int(args.fmi))
    if existed:  # (a rig's FMU replaced in silence: a trial)
        print(f"note: {out} existed and was replaced", file=sys.stderr)
    if not args.quiet:
        print(f"wrote {out} ({out.stat().st_size // 1024} KiB, FMI {args.fmi}.0 co-simulation, step 0.1 s)")
    return 0
