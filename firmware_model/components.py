"""Component ids (docs/interfaces.md section 5), the list the onboard sensor publishes, and what each code means
(:func:`describe`, short names taken from docs/glossary.md).

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
PAIRS = {
    "L": ("LI", "LL"),
    "3": ("3M", "3L"),
    "2": ("2M", "2L"),
    "1": ("1M", "1L"),
    "C": ("CM", "CL"),
    "R": ("RM", "RL"),
}

#: what the onboard sensor publishes (28 components)
PUBLISHED = (
    tuple(f"{w}.teeth" for w in IDLE_WHEELS) + LAYSHAFT_WHEELS + SHAFT_BEARINGS + WHEEL_BEARINGS + PLANETARY + (OIL,)
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
MODE_NAMES = {
    MODE_NORMAL: "normal",
    MODE_OIL_MODEL: "oil modelled",
    MODE_HOLDING: "holding inputs",
    MODE_NOT_INITIALISED: "not initialised",
}


#: what each code stands for, in a few words (docs/glossary.md spells them out and shows where they sit)
NAMES = {
    "LI": "low-split wheel, input shaft",
    "LL": "low-split wheel, layshaft",
    "3M": "high-split/3rd wheel, main shaft",
    "3L": "high-split/3rd wheel, layshaft",
    "2M": "2nd gear wheel, main shaft",
    "2L": "2nd gear wheel, layshaft",
    "1M": "1st gear wheel, main shaft",
    "1L": "1st gear wheel, layshaft",
    "CM": "crawler wheel, main shaft",
    "CL": "crawler wheel, layshaft",
    "RM": "reverse wheel, main shaft",
    "RL": "reverse wheel, layshaft",
    "RI": "reverse idler wheel",
    "PS": "sun wheel",
    "PP": "planet wheels",
    "PR": "ring gear",
    "BIF": "input shaft front bearing",
    "BLF": "layshaft front bearing",
    "BLR": "layshaft rear bearing",
    "BIM": "input/main shaft pilot bearing",
    "BMR": "main shaft rear bearing",
    "BO": "output shaft bearing",
    "LB": "low-split wheel bearing",
    "3B": "high-split/3rd wheel bearing",
    "2B": "2nd gear wheel bearing",
    "1B": "1st gear wheel bearing",
    "CB": "crawler wheel bearing",
    "RB": "reverse wheel bearing",
    "H1": "front housing",
    "H2": "rear housing",
    "H3": "bearing housing",
    "oil": "oil sump",
    "IS": "input shaft",
    "LS": "layshaft",
    "MS": "main shaft",
    "OS": "output shaft",
}
#: the parts of an idle wheel (``LI.teeth``, ``LI.bulk``)
WHEEL_PARTS = {"teeth": "teeth", "bulk": "hub"}
#: shaft segments not named after what sits on them
SEGMENT_NAMES = {
    "IS@bulk": "input shaft, front part",
    "OS@carrier": "planet carrier",
    "OS@bulk": "output shaft between carrier and bearing",
    "OS@EY": "output shaft at the end yoke",
}


def meaning(component_id: str) -> str | None:
    """What a component code stands for in a few words (``"PS"`` -> ``"sun wheel"``); None for an unknown code."""
    if component_id in NAMES:
        return NAMES[component_id]
    if component_id in SEGMENT_NAMES:
        return SEGMENT_NAMES[component_id]
    wheel, _, part = component_id.partition(".")
    if part in WHEEL_PARTS and wheel in IDLE_WHEELS:
        return f"{WHEEL_PARTS[part]} of the {NAMES[wheel]}"
    shaft, _, under = component_id.partition("@")
    if shaft in ("IS", "LS", "MS", "OS") and under:
        return f"{NAMES[shaft]} under {under}"
    return None


def describe(component_id: str) -> str:
    """A code with its meaning, for legends and printed output: ``"PS"`` -> ``"PS (sun wheel)"``,
    ``"LI.teeth"`` -> ``"LI.teeth (teeth of the low-split wheel, input shaft)"``; an unknown code as it is."""
    words = meaning(component_id)
    return f"{component_id} ({words})" if words else component_id
