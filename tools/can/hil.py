"""HIL: the reference plant as a simulator on a CAN bus, the library behind `gearbox-vsensor plant`.

The cycle is run through the reference plant *before* streaming starts (the plant is deterministic and its inputs
are known in advance, so precomputing costs one plant run, a few seconds per simulated hour, and removes every
real-time risk from the solver); then the truck's J1939 inputs (the same frames as ``simulate --can-log``,
tools/can/logsynth.py) and the plant's true temperatures (RIG_TC_1..7) are sent on a bus with their timing, in real
time or ``speedup`` times faster.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from firmware_model.errors import InputError
from tools.can.logsynth import SynthFrames, SynthResult

#: a progress line every this many seconds of cycle time
PROGRESS_PERIOD_S = 10.0
#: the plant's output sample period used for the rig frames [s]
PLANT_OUTPUT_DT_S = 1.0


def prepare(
    cycle: str,
    config_path=None,
    effects=(),
    *,
    duration_s: float | None = None,
    seed: int = 0,
    rig: bool = True,
    notes: list | None = None,
) -> SynthResult:
    """Run the plant over the cycle (a name, a ``steady:`` spec or a CSV; the first ``duration_s`` seconds only if
    given) with the unmodelled ``effects`` ("ID:PARAM=VALUE") switched on, and synthesize its frames. ``notes``:
    what the caller should say appended (the boundary temperatures the frames cannot carry)."""
    from firmware_model.config import load_config
    from firmware_model.effects import parse_effect
    from tools.can.logsynth import rig_dbc, synth_frames
    from tools.cycles.named import boundaries_a_log_cannot_carry, check_cycle_hold, get_cycle
    from tools.plant.reference import ReferencePlant
    from tools.runtable import RunTable

    cfg = load_config(config_path)
    params = cfg.load_params()
    from firmware_model.description import description_of

    table = get_cycle(cycle, description=description_of(params))
    check_cycle_hold(table.meta, None, cfg.cooler)  # a held sump against the configured cooler
    note = boundaries_a_log_cannot_carry(table, description_of(params))
    if note is not None and notes is not None:
        notes.append(f"the bus {note}")
    if duration_s is not None:
        t_s = table["time_s"]
        keep = t_s <= t_s[0] + duration_s
        if keep.sum() < 2:
            raise InputError(f"--duration {duration_s} s keeps fewer than two samples of the cycle")
        table = RunTable({c: table[c][keep] for c in table.columns}, meta=table.meta)
    plant = ReferencePlant(params, dict(parse_effect(e) for e in effects), cooler=cfg.cooler)
    res = plant.run(table, out_dt_s=PLANT_OUTPUT_DT_S, progress=False)
    # the rig frames of this gearbox's DBC (its published components), as simulate --can-log writes them
    return synth_frames(table, res.table, config=cfg, seed=seed, rig=rig, db=rig_dbc(params))


def stream(
    frames: SynthFrames,
    bus,
    *,
    speedup: float = 1.0,
    stop: threading.Event | None = None,
    progress: Callable[[float, int], None] | None = None,
) -> int:
    """Send the frames with their timing, ``speedup`` x faster than real time, until done or ``stop`` is set;
    ``progress(cycle_time_s, frames_sent)`` every PROGRESS_PERIOD_S of cycle time. Returns the number sent."""
    import can

    if not speedup > 0:
        raise InputError(f"--speed {speedup} must be positive")
    if not len(frames):
        return 0
    timestamps_s = frames.timestamp_s.tolist()
    ids = frames.can_id.tolist()
    data = frames.data
    t_first_s = timestamps_s[0]
    wall0_s = time.perf_counter()
    sent = 0
    next_report_s = PROGRESS_PERIOD_S
    for i, (t_s, can_id) in enumerate(zip(timestamps_s, ids)):
        if stop is not None and stop.is_set():
            break
        delay_s = wall0_s + (t_s - t_first_s) / speedup - time.perf_counter()
        if delay_s > 0:
            time.sleep(delay_s)
        bus.send(
            can.Message(timestamp=t_s, arbitration_id=can_id, is_extended_id=True, data=data[i].tobytes(), check=False)
        )
        sent += 1
        if progress is not None and t_s - t_first_s >= next_report_s:
            progress(t_s - t_first_s, sent)
            next_report_s += PROGRESS_PERIOD_S
    return sent
