"""`gearbox-vsensor`: one console command, one module per subcommand (cantools style)."""
from __future__ import annotations

import argparse
import sys

from firmware_model.errors import VSensorError

SUBCOMMANDS = ("simulate", "replay", "run", "plant", "diagnose", "bench_diagnosis", "demo")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="gearbox-vsensor",
        description="Virtual temperature sensor for Scania GRS905-type range-splitter gearboxes: the reference "
                    "thermal plant (simulate), the onboard sensor (replay, run), the HIL plant on CAN (plant) and "
                    "the sim-to-real gap diagnosis (diagnose, bench-diagnosis).")
    sub = parser.add_subparsers(title="subcommands", dest="subcommand", metavar="SUBCOMMAND")
    import importlib
    for name in SUBCOMMANDS:
        try:
            mod = importlib.import_module(f"tools.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"tools.cli.{name}":
                continue
            raise
        mod.add_subparser(sub)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        rc = args.func(args)
    except VSensorError as exc:
        print(f"gearbox-vsensor {args.subcommand}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"gearbox-vsensor {args.subcommand}: interrupted", file=sys.stderr)
        return 130
    except OSError as exc:
        print(f"gearbox-vsensor {args.subcommand}: error: {exc.strerror or exc}: {exc.filename or ''}".rstrip(": "),
              file=sys.stderr)
        return 2
    return int(rc or 0)


if __name__ == "__main__":
    sys.exit(main())
