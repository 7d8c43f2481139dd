"""`gearbox-vsensor status`: the health of a running sensor service, for a technician (docs/gateway.md)."""

from __future__ import annotations

import argparse
import os
import time

from firmware_model.errors import InputError

DEFAULT_HEALTH = "/run/gearbox-vsensor/health.json"
#: a health file older than this says the service is not running (it is rewritten every second) [s]
STALE_S = 5.0
#: a running service that has not stepped for this long has lost its inputs (it steps every 0.1 s of frame time) [s]
NO_STEP_S = 5.0


def add_subparser(sub):
    p = sub.add_parser(
        "status",
        help="show the health of a running `gearbox-vsensor run` (uptime, last step, degraded, counters)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Read the health file a running service rewrites every second (`run --health-file`) and print "
        "uptime, the last step's frame time, whether the sensor is initialised, the degraded modes, "
        "frame counters, time jumps, the state saves (count, errors, age of the last) and whether the "
        "saved state was restored at start. Exit status 0 when the service is running and stepping, 1 "
        "when the file is stale (not rewritten for 5 s: not running), 2 when it is missing or not a "
        "health file, 3 when the service runs but has not stepped for 5 s (its input frames stopped, or "
        "none came in its first 5 s: it publishes nothing; the first line says which and what to "
        "check). Within its first 5 s a service that has not stepped yet is `waiting for inputs`, "
        "exit 0. A file written on an earlier boot is not running either (exit 1). When the service is not "
        "running, a second line `stale: ...` gives when the file was written and every age shown is counted "
        "to now (the file's age on the time since boot, not the ages as the service wrote them).",
    )
    p.add_argument(
        "--health-file",
        default=DEFAULT_HEALTH,
        metavar="PATH",
        help=f"the service's health file (default {DEFAULT_HEALTH}, as the systemd unit writes it)",
    )
    p.add_argument(
        "--json",
        action="store_true",
        help="print the health document as JSON, as the service wrote it, plus a `status` object: live (false when "
        "not running: the figures are stale), service (running, not_stepping, never_stepped, stale, stopped, "
        "process_gone, earlier_boot), exit_status, and health_age_s, last_step_age_s, last_save_age_s counted to "
        "now (null when unknown)",
    )
    p.set_defaults(func=run)


def run(args) -> int:
    import json

    from firmware_model.service.persist import read_health

    try:
        doc = read_health(args.health_file)
    except FileNotFoundError:
        raise InputError(
            f"{args.health_file}: no health file; is `gearbox-vsensor run --health-file {args.health_file}` running?"
        ) from None
    except (OSError, ValueError) as exc:
        raise InputError(f"{args.health_file}: not a gearbox-vsensor health file ({exc})") from None
    try:  # a health file edited or damaged by hand: its fields of the wrong type are one sentence, exit 2
        age_s = health_age_s(doc)
        gone = process_gone(doc) or earlier_boot(doc)
        lines = status_lines(doc, age_s, gone)
        code = exit_status(doc, age_s, gone, not not_stepping(doc))
        judged = status_json(doc, age_s, gone, code)
    except (TypeError, ValueError, AttributeError) as exc:
        raise InputError(
            f"{args.health_file}: not a gearbox-vsensor health file (a field of the wrong type: {exc})"
        ) from None
    try:
        if args.json:  # the document as the service wrote it, and the judgement of it now under "status"
            print(json.dumps({**doc, "status": judged}, indent=2))
        else:
            for line in lines:
                print(line)
    except BrokenPipeError:  # `status | head -1`: the reader has what it wanted
        import os
        import sys

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return code


def exit_status(doc: dict, age_s: float, gone: bool, stepping: bool) -> int:
    """1 not running (stale, stopped, process gone, earlier boot), 3 running without steps, 0 running."""
    if age_s > STALE_S or doc.get("stopped") or gone:
        return 1
    return 0 if stepping else 3


def status_json(doc: dict, age_s: float, gone: bool, code: int) -> dict:
    """What `--json` adds to the health document: the text lines' judgement as fields. Whether the figures are live,
    the service's state in one word, the exit status, and the file's and the service's ages counted to now (the
    document's own ages are as at its writing; None when the file's age is unknown: a wall clock behind it)."""
    state = doc.get("state") or {}
    return {
        "live": is_live(doc, age_s, gone),
        "service": service_state(doc, age_s, gone),
        "exit_status": code,
        "health_age_s": age_now(0.0, age_s),
        "last_step_age_s": age_now(doc.get("last_step_age_s"), age_s),
        "last_save_age_s": age_now(state.get("last_save_age_s"), age_s),
    }


def is_live(doc: dict, age_s: float, gone: bool) -> bool:
    """Whether the document is the health of a service running now (else its last health: stale)."""
    return age_s <= STALE_S and not doc.get("stopped") and not gone


def not_stepping(doc: dict) -> bool:
    """A running service whose step count has not moved for NO_STEP_S, or that has not stepped once in the NO_STEP_S
    since its start (a health file of an older version: only the latter)."""
    age = doc.get("last_step_age_s")
    return (age is not None and float(age) > NO_STEP_S) or never_stepped(doc)


def never_stepped(doc: dict) -> bool:
    """A service up for more than its start-up grace (NO_STEP_S) without a single step: it steps on the frame time
    of its input messages (from any source address), so none of them has reached it."""
    return int(doc.get("steps") or 0) == 0 and float(doc.get("uptime_s") or 0.0) > NO_STEP_S


def never_stepped_sentence(doc: dict) -> str:
    """What a service that never stepped shows and what to check: the bus it listens on, the frames it saw."""
    channel = doc.get("channel")
    bus = f"{doc.get('interface')} {channel}" if channel else "its CAN channel (`run --channel`)"
    seen = int((doc.get("decoder") or {}).get("frames_seen", 0))
    name = channel or "CHANNEL"
    tools = (
        (f" (`ip -details link show {name}`)", f" (`candump {name}`)")
        if doc.get("interface") in (None, "socketcan")
        else ("", "")
    )
    return (
        f"no step: the service has run {float(doc['uptime_s']):.0f} s without a single step, as no frame of its "
        f"input messages (EEC1 engine speed, ETC2, TRF1, ...) has reached it ({seen} frames received), so it "
        f"publishes nothing; check that {bus} is the truck's powertrain CAN bus, that the interface is up at the "
        f"bus's bitrate{tools[0]} and that frames arrive on it{tools[1]}: none means wiring, termination or "
        f"bitrate"
    )


def health_age_s(doc: dict) -> float:
    """How long ago the file was written: by the time since boot when it was written on this boot (a wall clock set
    back or forward says nothing then), else by the wall clock."""
    from firmware_model.service.persist import boot_clock, boot_id

    wall_age_s = time.time() - float(doc.get("written_wall_s", 0.0))
    boot = doc.get("written_boottime_s")
    if boot is not None and doc.get("boot_id") and doc.get("boot_id") == boot_id():
        return boot_clock() - float(boot)
    return wall_age_s


def earlier_boot(doc: dict) -> bool:
    """Whether ``doc`` was written on another boot of this machine (a file kept on disk across a reboot): its writer
    is not running, whatever the wall clock says (a gateway without RTC may boot with its clock behind the file)."""
    from firmware_model.service.persist import boot_id

    here = boot_id()
    return bool(doc.get("boot_id")) and here is not None and doc.get("boot_id") != here


def process_gone(doc: dict) -> bool:
    """Whether the service that wrote ``doc`` on this boot has no process any more (killed, crashed): its pid is no
    live process here. Only for a file of this boot (a pid of another boot says nothing) and a service in this
    machine's process namespace (status runs on the gateway)."""
    from firmware_model.service.persist import boot_id

    pid = doc.get("pid")
    if doc.get("stopped") or not isinstance(pid, int) or pid <= 0 or doc.get("boot_id") != boot_id():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:  # (another user's process: alive)
        return False
    return False


def age_now(age_s: float | None, file_age_s: float) -> float | None:
    """An age the service wrote (at its last write) counted to now: plus the file's own age; None when either is
    unknown (the file's age negative: a wall clock behind the file's)."""
    return None if age_s is None or file_age_s < 0 else float(age_s) + file_age_s


def ago(age_s: float | None, file_age_s: float) -> str:
    """``age_now`` as text: "N s", or "unknown"."""
    now = age_now(age_s, file_age_s)
    return "unknown" if now is None else f"{now:.0f} s"


def service_state(doc: dict, age_s: float, gone: bool) -> str:
    """The service's state in one word, the first line's cases in its order."""
    if doc.get("stopped"):
        return "stopped"
    if gone:
        return "earlier_boot" if earlier_boot(doc) else "process_gone"
    if age_s > STALE_S:
        return "stale"
    if never_stepped(doc):
        return "never_stepped"
    return "not_stepping" if not_stepping(doc) else "running"


def service_line(doc: dict, age_s: float, gone: bool) -> str:
    """The first line: running (and stepping or not), or why not and since when; a service not running has no
    uptime now, only the time it had run."""
    old = f"health {ago(0.0, age_s)} old" if age_s >= 0 else "health of unknown age"
    word = service_state(doc, age_s, gone)
    if word == "stopped":
        state = f"stopped cleanly {ago(0.0, age_s)} ago" if age_s >= 0 else "stopped cleanly (when: unknown)"
    elif word == "earlier_boot":
        state = f"NOT RUNNING (written on an earlier boot of this machine; {old})"
    elif word == "process_gone":
        state = f"NOT RUNNING (its process {doc.get('pid')} is gone: killed or crashed; {old})"
    elif word == "stale":
        state = (
            f"NOT RUNNING ({old}; or running but unable to rewrite this file: its log says "
            f"'cannot write the health file')"
        )
    elif word == "never_stepped":
        state = f"running, but NEVER STEPPED in {float(doc['uptime_s']):.0f} s"
    elif word == "not_stepping":
        state = (
            f"running, but NO STEP for {ago(doc['last_step_age_s'], age_s)} (its input frames stopped: "
            f"engine speed or the bus; it publishes nothing)"
        )
    else:
        state = "running"
    run_for = "uptime" if state.startswith("running") else "had run"
    return f"service: {state}, pid {doc.get('pid')}, {run_for} {float(doc.get('uptime_s', 0.0)):.0f} s"


def stale_line(doc: dict, age_s: float) -> str:
    """For a service not running: the figures are its last health, from when (the wall clock of the writing), and
    every age below is counted to now."""
    when = time.strftime("%Y-%m-%d %H:%M:%S %z", time.localtime(float(doc.get("written_wall_s", 0.0))))
    age = f"({ago(0.0, age_s)} ago)" if age_s >= 0 else "(age unknown: this machine's wall clock is behind it)"
    return f"stale: the lines below are the service's last health, written {when} {age}; not live"


def status_lines(doc: dict, age_s: float, gone: bool = False) -> list[str]:
    from firmware_model.components import MODE_NAMES

    state = doc.get("state") or {}
    last = doc.get("last_step_frame_time_s")
    live = is_live(doc, age_s, gone)
    now = doc.get("degraded_mode_now")
    j = doc.get("j1939")
    step_age = doc.get("last_step_age_s")
    lines = [
        service_line(doc, age_s, gone),
        f"sensor: {'initialised' if doc.get('initialised') else 'waiting for inputs'}, {doc.get('steps', 0)} "
        f"steps, last step at frame time {'-' if last is None else f'{last:.1f} s'}"
        + ("" if step_age is None else f" ({ago(step_age, age_s)} ago)")
        + ("" if now is None else f"; mode {'now' if live else 'last'} {now} ({MODE_NAMES.get(int(now), '?')})"),
        f"degraded modes (steps since start): {doc.get('degraded_mode_steps') or 'none'}; time jumps "
        f"{doc.get('time_jumps', 0)}; clock steps {doc.get('clock_steps', 0)}; frames sent "
        f"{doc.get('frames_sent', 0)}"
        + (f" ({doc['frames_held_no_address']} held: no J1939 address)" if doc.get("frames_held_no_address") else ""),
        "frames: " + ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in (doc.get("decoder") or {}).items()),
    ]
    if not live:
        lines.insert(1, stale_line(doc, age_s))
    elif never_stepped(doc):
        lines.insert(1, never_stepped_sentence(doc))
    if j:
        a = j.get("address")
        lines.append(
            "J1939 address: "
            + (
                f"0x{int(a):02X}"
                if a is not None
                else "LOST (Cannot Claim sent: the sensor sends nothing; another node claimed "
                "its address with a higher-priority NAME)"
            )
            + f"; contentions won {j.get('contentions_won', 0)}, lost {j.get('contentions_lost', 0)}"
        )
    bus = doc.get("bus") or {}
    if bus.get("outages") or bus.get("read_errors") or doc.get("bus_off"):
        lines.append(
            f"bus: {bus.get('outages', 0)} receive outages, {bus.get('read_errors', 0)} receive errors, "
            f"{bus.get('reopens', 0)} reopens ({bus.get('reopen_failures', 0)} failed attempts), "
            f"{doc.get('bus_off', 0)} bus-off error frames"
        )
    tb = doc.get("time_base") or {}
    if tb.get("suspect"):  # every output rests on the frames' clock: a wrong one is a wrong sensor
        lines.append(f"WARNING time base suspect {'now' if live else 'at the last health'}: {tb.get('sentence')}")
    for f in doc.get("findings") or []:  # the whole-record findings of the run (after its first minute)
        lines.append(f"finding ({f.get('severity')}): {f.get('sentence')}")
    if doc.get("health_write_errors"):
        lines.append(
            f"health file: {doc['health_write_errors']} writes failed before this one (the service's log "
            f"names the first error)"
        )
    if state:
        age = state.get("last_save_age_s")
        restored = (
            ("restored at start" if state.get("restored") else "not restored")
            if "degraded_mode_now" in doc
            else "restored at start: unknown (a health file of an older version)"
        )
        lines.append(
            f"state: {state.get('path')}, {restored}"
            f", {state.get('saves', 0)} saves ({state.get('save_errors', 0)} "
            f"errors), last {'never' if age is None else f'{ago(age, age_s)} ago'}; cold starts "
            f"{state.get('cold_starts', 0)}{' (' + str(state.get('reason')) + ')' if state.get('reason') else ''}"
        )
    return lines
