"""`gearbox-vsensor`: one console command, one module per subcommand (cantools style)."""

from __future__ import annotations

import argparse
import sys

from firmware_model.errors import VSensorError

SUBCOMMANDS = (
    "simulate",
    "replay",
    "play",
    "run",
    "plant",
    "diagnose",
    "calibrate",
    "bench_diagnosis",
    "demo",
    "export_c",
    "export_fmu",
    "export_dbc",
    "status",
    "service_unit",
    "fleet",
    "describe",
)


class CommandParser(argparse.ArgumentParser):
    """The top-level parser. What a subcommand does not know is rejected by that subcommand's parser, with its own
    usage and a suggestion (``unrecognized arguments: --outt (did you mean --out?)``), not with the top-level usage.
    An option a subcommand no longer has is refused with the sentence in its parser's ``removed_options`` (option ->
    what replaced it). ``subcommands``: name -> parser, filled by :func:`build_parser`."""

    subcommands: dict = {}

    def parse_known_args(self, args=None, namespace=None):
        self.given = list(sys.argv[1:] if args is None else args)  # for error(): the options it did not know
        namespace, extras = super().parse_known_args(args, namespace)
        sub = self.subcommands.get(getattr(namespace, "subcommand", None))
        if extras and sub is not None:
            removed = getattr(sub, "removed_options", {})
            for arg in extras:
                if arg.split("=", 1)[0] in removed:
                    sub.error(removed[arg.split("=", 1)[0]])
            sub.error("unrecognized arguments: " + " ".join(with_suggestion(sub, a) for a in extras))
        return namespace, extras

    def error(self, message):
        """A missing required option is often a mistyped one (``--outt``): say that first, with the suggestion."""
        if message.startswith("the following arguments are required"):
            removed = getattr(self, "removed_options", {})
            for arg in getattr(self, "given", ()):
                if arg.split("=", 1)[0] in removed:
                    super().error(removed[arg.split("=", 1)[0]])
            unknown = [a for a in getattr(self, "given", ()) if a.startswith("--") and not self.knows(a)]
            if unknown:
                message = f"unrecognized arguments: {' '.join(with_suggestion(self, a) for a in unknown)}; {message}"
        super().error(message)

    def knows(self, arg: str) -> bool:
        """Whether ``arg`` (``--name`` or ``--name=value``) is one of this parser's options or a prefix of one."""
        name = arg.split("=", 1)[0]
        return any(o == name or (self.allow_abbrev and o.startswith(name)) for o in self._option_string_actions)


def with_suggestion(parser: argparse.ArgumentParser, arg: str) -> str:
    """``arg``, followed by the closest option of ``parser`` when it looks like a mistyped option."""
    import difflib

    if not arg.startswith("--"):
        return arg
    options = [
        o
        for action in parser._actions
        if action.help != argparse.SUPPRESS
        for o in action.option_strings
        if o.startswith("--")
    ]
    close = difflib.get_close_matches(arg.split("=", 1)[0], options, n=1, cutoff=0.6)
    return f"{arg} (did you mean {close[0]}?)" if close else arg


class VersionAction(argparse.Action):
    """``--version``: the package version and the active onboard core (loading the kernel only when asked)."""

    def __call__(self, parser, namespace, values, option_string=None):
        from importlib.metadata import PackageNotFoundError, version

        from tools.cli.core_option import active_core

        try:
            v = version("gearbox-vsensor")
        except PackageNotFoundError:
            v = "(not installed)"
        print(f"gearbox-vsensor {v}\nonboard core: {active_core()}")
        parser.exit()


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The command line's parser; ``only`` (a module of SUBCOMMANDS): that subcommand's parser alone, so that a
    command imports its own module and not the fifteen others (the service's start-up on a small gateway)."""
    parser = CommandParser(
        prog="gearbox-vsensor",
        description="Virtual temperature sensor for gearboxes, each from one description file (--gearbox: the "
        "Scania GRS905 range-splitter by default, others shipped or your own; describe checks one): the reference "
        "thermal plant (simulate), the onboard sensor (replay, run), the HIL plant on CAN (plant), the sim-to-real "
        "gap diagnosis (diagnose, calibrate, bench-diagnosis) and the fleet (fleet).",
    )
    parser.add_argument(
        "--version",
        action=VersionAction,
        nargs=0,
        help="print the version and the onboard core this machine runs (the compiled C kernel or numpy), then exit",
    )
    sub = parser.add_subparsers(title="subcommands", dest="subcommand", metavar="SUBCOMMAND")
    import importlib

    for name in (only,) if only in SUBCOMMANDS else SUBCOMMANDS:
        try:
            mod = importlib.import_module(f"tools.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"tools.cli.{name}":
                continue
            raise
        mod.add_subparser(sub)
    from tools.cli.settings import DefaultsHelpFormatter

    for p in sub.choices.values():  # every option's default in its help
        p.formatter_class = DefaultsHelpFormatter
    parser.subcommands = dict(sub.choices)
    return parser


def requested_subcommand(argv) -> str | None:
    """The module of the subcommand that ``argv`` names first, or None (top-level options, no or an unknown name:
    every parser is built, for the full help or the list of choices)."""
    if not argv or argv[0].startswith("-"):
        return None
    name = argv[0].replace("-", "_")
    return name if name in SUBCOMMANDS and argv[0] == name.replace("_", "-") else None


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(requested_subcommand(argv))
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
        print(
            f"gearbox-vsensor {args.subcommand}: error: {exc.strerror or exc}: {exc.filename or ''}".rstrip(": "),
            file=sys.stderr,
        )
        return 2
    return int(rc or 0)


if __name__ == "__main__":
    sys.exit(main())
