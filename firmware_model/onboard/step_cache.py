"""What the onboard step memoises, in one explicit object the sensor owns and passes to the step.

Both memos are bounded and hold pure functions of their keys (the conductances of an operating-point bin, the modes
of a held-input system), so a step gives the same outputs with a fresh cache, a warm one or one shared by sensors
built from the same parameters.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from firmware_model.onboard.conductance_bins import BinCache
from firmware_model.onboard.held_modes import ModeCache


@dataclass
class StepCache:
    """The step's memos: conductances per operating-point bin (one vehicle) and held-input modes (time to limit,
    time jumps, cool-down)."""
    bins: BinCache = field(default_factory=BinCache)
    modes: ModeCache = field(default_factory=ModeCache)
