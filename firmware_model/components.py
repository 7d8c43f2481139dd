"""Component ids (docs/interfaces.md section 5; every code spelled out in docs/glossary.md) and the list the onboard sensor publishes.

The order of PUBLISHED is the order of every per-component CAN signal, run-table column block and array
in the onboard model. Extend at the end only: CAN layouts depend on it.
"""
from __future__ import annotations

#: wheels on the input shaft (LI) and main shaft (3M, 2M, 1M, CM, RM); split into teeth and bulk
IDLE_WHEELS = ("LI", "3M", "2M", "1M", "CM", "RM")
#: wheels fixed to the layshaft, in the same pair order as IDLE_WHEELS
LAYSHAFT_WHEELS = ("LL", "3L", "2L", "1L", "CL", "RL")
#: reverse intermediate wheel
REVERSE_IDLER = "RI"
#: planetary: sun, planets, ring
PLANETARY = ("PS", "PP", "PR")
#: shaft bearings (tapered except BO, a ball bearing)
SHAFT_BEARINGS = ("BIF", "BLF", "BLR", "BIM", "BMR", "BO")
#: needle bearings under the idle wheels, same order as IDLE_WHEELS
WHEEL_BEARINGS = ("LB", "3B", "2B", "1B", "CB", "RB")
HOUSINGS = ("H1", "H2", "H3")
OIL = "oil"

#: pair name -> (idle wheel, layshaft wheel)
PAIRS = {"L": ("LI", "LL"), "3": ("3M", "3L"), "2": ("2M", "2L"), "1": ("1M", "1L"),
         "C": ("CM", "CL"), "R": ("RM", "RL")}

#: what the onboard sensor publishes (28 components)
PUBLISHED = (
    tuple(f"{w}.teeth" for w in IDLE_WHEELS)
    + LAYSHAFT_WHEELS
    + SHAFT_BEARINGS
    + WHEEL_BEARINGS
    + PLANETARY
    + (OIL,)
)

#: component group of each published id, for plots and default warning limits
GROUP = {}
for _c in PUBLISHED:
    if _c.endswith(".teeth") or _c in LAYSHAFT_WHEELS:
        GROUP[_c] = "gear"
    elif _c in SHAFT_BEARINGS or _c in WHEEL_BEARINGS:
        GROUP[_c] = "bearing"
    elif _c == "PS":
        GROUP[_c] = "sun"
    elif _c in ("PP", "PR"):
        GROUP[_c] = "planetary"
    else:
        GROUP[_c] = "oil"
del _c

#: the onboard sensor's fixed step (10 Hz): one owner, used by the onboard build, the service and the cycles
STEP_S = 0.1

#: warning level of a published component (the W_<id> columns and GBX_Warn signals)
LEVEL_NORMAL, LEVEL_WARNING, LEVEL_CRITICAL, LEVEL_NA = 0, 1, 2, 3
LEVEL_NAMES = {LEVEL_NORMAL: "normal", LEVEL_WARNING: "warning", LEVEL_CRITICAL: "critical", LEVEL_NA: "n/a"}

#: degraded mode of the sensor (status frame, degraded_mode column)
MODE_NORMAL, MODE_OIL_MODEL, MODE_HOLDING, MODE_NOT_INITIALISED = 0, 1, 2, 3
MODE_NAMES = {MODE_NORMAL: "normal", MODE_OIL_MODEL: "oil modelled", MODE_HOLDING: "holding inputs",
              MODE_NOT_INITIALISED: "not initialised"}
