"""The systemd unit of the gateway service (`gearbox-vsensor service-unit`, docs/gateway.md).

Type=notify with a watchdog (the service sends READY=1 and WATCHDOG=1, firmware_model.service.persist.sd_notify),
restart on failure, an unprivileged dynamic user, no capabilities beyond CAP_NET_RAW (CAN sockets do not need it
for plain reading and writing; it is offered only with ``--raw``), a state directory for the saved state, journal
logging with a syslog identifier a journal can filter (``journalctl -t gearbox-vsensor``).
"""
from __future__ import annotations

import shlex
import sys

UNIT = """[Unit]
Description=gearbox-vsensor virtual gearbox temperature sensor on {channel}
After=network.target sys-subsystem-net-devices-{channel}.device
BindsTo=sys-subsystem-net-devices-{channel}.device

[Service]
Type=notify
NotifyAccess=main
ExecStart={exec_start}
Restart=on-failure
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
RestrictAddressFamilies=AF_CAN AF_UNIX AF_NETLINK
{environment}
[Install]
WantedBy=multi-user.target
"""


def unit_text(interface: str, channel: str, config: str | None = None, python: str | None = None,
              raw: bool = False) -> str:
    """The unit file: `run` on ``interface`` ``channel``, the state in /var/lib/gearbox-vsensor, the health file in
    /run/gearbox-vsensor (what `gearbox-vsensor status` reads by default)."""
    cmd = [python or sys.executable, "-m", "tools.cli", "run", "--interface", interface, "--channel", channel,
           "--state-file", "/var/lib/gearbox-vsensor/state.json",
           "--health-file", "/run/gearbox-vsensor/health.json"]
    if config:
        cmd += ["--config", config]
    caps = "CAP_NET_RAW" if raw else ""
    return UNIT.format(channel=channel, exec_start=" ".join(shlex.quote(c) for c in cmd), caps=caps,
                       environment="Environment=PYTHONUNBUFFERED=1\n")
