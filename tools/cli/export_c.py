"""`gearbox-vsensor export-c`: the onboard sensor as C sources for an ECU or gateway build (tools.export)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tools.cli.gearbox_option import add_gearbox_option, resolve_gearbox
from tools.cli.settings import add_hidden, setting


def add_subparser(sub):
    p = sub.add_parser(
        "export-c",
        help="write the onboard sensor as C sources for an ECU build (kernel, tables, test vectors)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Write the compiled onboard step as C99 sources an integrator drops into an ECU or gateway build: "
        "the generic kernel, the generated tables of one gearbox variant and configuration (const "
        "arrays), an API header, test vectors from the Python reference, a Makefile (`make test` builds "
        "a host program that checks them) and an integrator's README.\n\nThe exported sensor is the full "
        "onboard step, the time-to-limit refresh (every 1 s) and the early warning included; "
        "[export] time_to_limit = false in the --config leaves the refresh out (less flash and stack; time to "
        "limit not available, no early warning).",
        epilog="example:\n"
        "  gearbox-vsensor export-c --gearbox GRS905 --real float --out vsensor_c && make -C vsensor_c test",
    )
    add_gearbox_option(p)
    p.add_argument(
        "--config",
        metavar="TOML",
        help="project configuration: variant, cooler, [sensor] limits, [export] time_to_limit (docs/interfaces.md "
        "section 8)",
    )
    p.add_argument(
        "--real",
        choices=("float", "double"),
        default="float",
        help="the real type of the build: float (an ECU's single-precision FPU) or double "
        "(parity with the Python reference) (default: float)",
    )
    p.add_argument("--out", required=True, metavar="DIR", help="directory to write (created)")
    # moved: --no-ttl to [export] time_to_limit = false, still accepted (hidden) and overriding it; --quiet (its two
    # lines: redirect them) still accepted
    add_hidden(p, "export.time_to_limit")
    p.add_argument("--quiet", action="store_true", help=argparse.SUPPRESS)
    p.set_defaults(func=run)


def run(args) -> int:
    from firmware_model.config import load_config
    from tools.export.c_bundle import BUNDLE_FILES, export_c

    cfg = resolve_gearbox(args, load_config(args.config))
    ttl = setting(args, cfg, "export.time_to_limit")
    had = _existing_files(Path(args.out))
    out = export_c(args.out, config_path=cfg, real=args.real, ttl=ttl)
    replaced = sorted(had & set(BUNDLE_FILES))
    if replaced:  # an earlier export (a hand-edited source) overwritten, and a build's products left: said
        others = sorted(had - set(BUNDLE_FILES))
        shown = ", ".join(others[:5]) + (" ..." if len(others) > 5 else "")
        left = f"; {len(others)} other files left as they were ({shown}: `make -C {out} clean` removes a build's)"
        left = left if others else ""
        print(f"note: {out} held an export: {len(replaced)} of its files replaced{left}", file=sys.stderr)
    if not args.quiet:
        files = sorted(BUNDLE_FILES)  # what was written, not what else the directory holds
        print(f"wrote {len(files)} files to {out}: {', '.join(files)}\nnext: make -C {out} test")
    return 0


def _existing_files(out: Path) -> set:
    """The files under ``out`` before the export, as paths relative to it (the bundle's names)."""
    if not out.is_dir():
        return set()
    return {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()}
