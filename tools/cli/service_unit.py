"""`gearbox-vsensor service-unit`: print the systemd unit that runs the sensor as a gateway service."""

from __future__ import annotations

import argparse


def add_subparser(sub):
    p = sub.add_parser(
        "service-unit",
        help="print a systemd unit that runs `gearbox-vsensor run` as a service on a gateway",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Print a systemd unit for the live sensor: Type=notify with a 10 s watchdog, restart on "
        "failure, an unprivileged dynamic user without capabilities, the saved state in "
        "/var/lib/gearbox-vsensor, the health file in /run/gearbox-vsensor (what `gearbox-vsensor "
        "status` reads), logs in the journal (journalctl -t gearbox-vsensor).",
        epilog="install (docs/gateway.md):\n"
        "  gearbox-vsensor service-unit --interface socketcan --channel can0 \\\n"
        "      | sudo tee /etc/systemd/system/gearbox-vsensor.service\n"
        "  sudo systemctl daemon-reload && sudo systemctl enable --now gearbox-vsensor\n"
        "  gearbox-vsensor status",
    )
    p.add_argument("--interface", default="socketcan", help="python-can interface (default socketcan)")
    p.add_argument("--channel", default="can0", help="CAN channel (default can0)")
    p.add_argument("--config", metavar="TOML", help="absolute path of the project configuration on the gateway")
    p.add_argument("--python", metavar="PATH", help="the Python that runs it (default: this one)")
    p.set_defaults(func=run)


def run(args) -> int:
    import sys

    from tools.can.systemd import check_unit_args, unit_text

    for warning in check_unit_args(args.interface, args.channel, args.config, args.python):
        print(f"warning: {warning}", file=sys.stderr)
    print(unit_text(args.interface, args.channel, args.config, args.python), end="")
    return 0
