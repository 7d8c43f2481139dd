"""The systemd unit of the gateway service (`gearbox-vsensor service-unit`, docs/gateway.md).

Type=notify with a watchdog (the service sends READY=1 and WATCHDOG=1, firmware_model.service.persist.sd_notify),
restart always (a clean stop by a stray SIGHUP too), an unprivileged dynamic user without capabilities (CAN sockets
need none for plain reading and writing; ``unit_text(raw=True)``, which no command line offers, would grant
CAP_NET_RAW), a state directory for the saved state, journal
logging with a syslog identifier a journal can filter (``journalctl -t gearbox-vsensor``).
"""

from __future__ import annotations

import os
import re
import shlex
import sys
from pathlib import Path

from firmware_model.errors import InputError

UNIT = """[Unit]
Description=gearbox-vsensor virtual gearbox temperature sensor on {channel}
{device}

[Service]
Type=notify
NotifyAccess=main
ExecStart={exec_start}
Restart=always
RestartSec=2
WatchdogSec=10
TimeoutStopSec=10
DynamicUser=yes
StateDirectory=gearbox-vsensor
RuntimeDirectory=gearbox-vsensor
SyslogIdentifier=gearbox-vsensor
StandardOutput=journal
StandardError=journal
CapabilityBoundingSet={caps}
AmbientCapabilities={caps}
NoNewPrivileges=yes
ProtectSystem=strict
ProtectHome=yes
PrivateTmp=yes
{families}
{environment}
[Install]
WantedBy=multi-user.target
"""


#: the address families each interface's sockets need (socketcan: CAN sockets; udp_multicast: IP); other
#: interfaces (vendor libraries on character devices) get no restriction, since their needs are not known here
FAMILIES = {"socketcan": "AF_CAN AF_UNIX AF_NETLINK", "udp_multicast": "AF_INET AF_INET6 AF_UNIX AF_NETLINK"}
#: a channel name that can stand in a unit file and a device name (no spaces, no newlines)
CHANNEL_RE = re.compile(r"[A-Za-z0-9_.:@/-]+")


#: where the unit's sandboxing hides files from the service, and the setting that does it
HIDDEN = {
    "/home/": "ProtectHome=yes",
    "/root/": "ProtectHome=yes",
    "/run/user/": "ProtectHome=yes",
    "/tmp/": "PrivateTmp=yes",
    "/var/tmp/": "PrivateTmp=yes",
}


def _here_warnings(interface: str, config: str | None) -> list[str]:
    """What this machine can tell of a unit that would fail at every start (a unit may be made for another host,
    so these are warnings, and a --python that is not here is none): an interface this python-can does not know,
    a --config that is here and does not load."""
    import can

    out = []
    if interface not in can.interfaces.VALID_INTERFACES:
        out.append(
            f"--interface {interface}: python-can here knows no such interface ({', '.join(sorted(VALID_SHOWN))}, "
            "...): unless the gateway's python-can has it, the service fails at every start"
        )
    if config is not None and os.path.isfile(config):
        from firmware_model.config import load_config
        from firmware_model.errors import ParameterError

        try:
            load_config(config)
        except (InputError, ParameterError) as exc:
            out.append(f"--config {config} does not load here ({exc}): the service would fail at every start")
    return out


#: the interfaces a warning lists (python-can's common ones)
VALID_SHOWN = ("socketcan", "pcan", "kvaser", "vector", "slcan", "udp_multicast", "virtual")


def check_unit_args(interface: str, channel: str, config: str | None, python: str | None) -> list[str]:
    """InputError for a channel that cannot stand in a unit file or a relative --config; returns warnings (a
    Python, the code or the --config under /home, /root or /tmp, which the unit's sandbox hides from the service)."""
    for opt, v in (("--interface", interface), ("--channel", channel)):
        if not CHANNEL_RE.fullmatch(v or ""):
            raise InputError(
                f"{opt} {v!r} must be a name of letters, digits and _ . : @ / - (no spaces or line "
                f"breaks: it goes into the unit file)"
            )
    if config is not None and not os.path.isabs(config):
        raise InputError(f"--config {config} must be an absolute path: the service does not start in this directory")
    warnings = _here_warnings(interface, config)
    if interface == "virtual":
        warnings.append(
            "--interface virtual is python-can's bus inside one process: the service would receive no "
            "frame from any other program (a test bus, not a gateway's)"
        )
    exe = os.path.abspath(python or sys.executable)
    places = [("the Python", exe), ("the Python (through its links)", os.path.realpath(exe))]
    if config is not None:  # (that --python and --config exist is not checked: a unit may be made for another host)
        places.append(("the --config", os.path.realpath(config)))
    if python is None:  # this Python's own copy of gearbox-vsensor (an editable install: the source tree)
        places.append(("the gearbox-vsensor code", str(Path(__file__).resolve().parents[2])))
    found = []
    for what, path in places:
        hidden = next((h for h in HIDDEN if path.startswith(h)), None)
        if hidden and not any(path == p for _, p, _ in found):
            found.append((what, path, hidden))
    if not found:
        return warnings
    where = "; ".join(f"{what} {path} is under {hidden.rstrip('/')} ({HIDDEN[hidden]})" for what, path, hidden in found)
    fixes = []
    if any(what != "the --config" for what, _, _ in found):
        fixes.append(
            "install gearbox-vsensor (not editable) into a virtual environment outside /home, /root and /tmp (e.g. "
            "/opt/gearbox-vsensor) and pass its python with --python"
        )
    if any(what == "the --config" for what, _, _ in found):
        fixes.append("put the configuration outside them (e.g. /etc/gearbox-vsensor/config.toml)")
    fix = "; ".join(fixes)
    return warnings + [f"{where}: the unit's sandbox hides it from the service. {fix[:1].upper()}{fix[1:]}"]


def device_unit(channel: str) -> str:
    """The systemd device unit of a network device (``systemd-escape``: "/" becomes "-", every byte other than
    letters, digits, ":", "_" and "." (a leading "." too) becomes \\xNN: "can-gw" is
    sys-subsystem-net-devices-can\\x2dgw; the unescaped name is a device that never appears)."""
    out = []
    for i, b in enumerate(channel.encode("utf-8")):
        c = chr(b)
        if c == "/":
            out.append("-")
        elif (c.isascii() and c.isalnum()) or c in ":_" or (c == "." and i > 0):
            out.append(c)
        else:
            out.append(f"\\x{b:02x}")
    return f"sys-subsystem-net-devices-{''.join(out)}.device"


def unit_text(
    interface: str, channel: str, config: str | None = None, python: str | None = None, raw: bool = False
) -> str:
    """The unit file: `run` on ``interface`` ``channel``, the state in /var/lib/gearbox-vsensor, the health file in
    /run/gearbox-vsensor (what `gearbox-vsensor status` reads by default). A socketcan channel is a network device
    the service is bound to; other interfaces have no such device."""
    cmd = [
        python or sys.executable,
        "-m",
        "tools.cli",
        "run",
        "--interface",
        interface,
        "--channel",
        channel,
        "--state-file",
        "/var/lib/gearbox-vsensor/state.json",
        "--health-file",
        "/run/gearbox-vsensor/health.json",
    ]
    if config:
        cmd += ["--config", config]
    caps = "CAP_NET_RAW" if raw else ""
    device = (
        (f"After=network.target {device_unit(channel)}\nBindsTo={device_unit(channel)}")
        if interface == "socketcan"
        else "After=network.target"
    )
    families = f"RestrictAddressFamilies={FAMILIES[interface]}" if interface in FAMILIES else ""
    # "%" starts a systemd specifier: a literal one is "%%" (a --config path with "%" failed systemd-analyze verify)
    exec_start = " ".join(shlex.quote(c) for c in cmd).replace("%", "%%")
    return UNIT.format(
        channel=channel,
        device=device,
        exec_start=exec_start,
        caps=caps,
        families=families,
        environment="Environment=PYTHONUNBUFFERED=1\n",
    )
