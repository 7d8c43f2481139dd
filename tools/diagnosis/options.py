"""Settings and constants of the gap diagnosis, shared by its stages, and how it writes a number into its JSON."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from firmware_model.effects import IdFamilies

SCHEMA = "gap-diagnosis/1"
#: J1939 temperature resolution (TRF1 SPN 177, rig thermocouples): the noise floor of a measured channel
J1939_RES_C = 0.03125
#: channel id of the vehicle's oil sensor (oil_temp_c)
OIL = "oil"
#: channel id of a rig thermocouple in the sump (meas_T_oil_c): not the vehicle's oil sensor
OIL_RIG = "oil@rig"
INPUT_COLUMNS = (
    "time_s",
    "engine_speed_rpm",
    "engine_torque_nm",
    "gear",
    "ambient_temp_c",
    "coolant_temp_c",
    "vehicle_speed_kmh",
    "retarder_torque_nm",
)
#: effects whose prediction is exact from the baseline (no simulation needed before the check): the oil sensor's
#: lag (a filter of the model's sump), offset and gain, and a rig thermocouple's offset (thermocouple_offset:ID)
#: the housings' start in the sensitivity run of a file that starts running [K] (tools/diagnosis/start.py): below the
#: oil and of the size met (2-11 K), since the response is linear only near it (a +2 K run scaled to -20 K is
#: 0.15-0.23 degC off the re-simulation on the oil)
HOUSING_PERTURB_C = -6.0
ANALYTIC = IdFamilies(("oil_sensor_lag", "oil_sensor_offset", "oil_sensor_gain", "thermocouple_offset"))
LOG_SUFFIXES = (".log", ".asc", ".blf", ".mf4", ".trc")
#: the stages of one diagnosis, in order (what the progress callback is told)
STAGES = ("baseline and candidate grid", "where", "fit", "test", "verdict")


@dataclass
class ReadingOptions:
    """Reading and preparing the files: the analysis grid and the gaps a file may have."""

    grid_dt_s: float = 2.0  # analysis grid
    max_time_gap_s: float = 60.0
    max_channel_gap_frac: float = 0.25


#: a file whose first reading lies this far above the ambient begins warm (start.driving_at_start); less than this
#: above it, a file starts at rest whatever its residual (start.judge: a gearbox that had been running is warmer)
WARM_ABOVE_AMBIENT_K = 15.0


@dataclass
class StartOptions:
    """How each file starts (tools/diagnosis/start.py): at rest, or running with its first minutes not scored."""

    start: str = "auto"  # each file's start: auto, rest or running
    burn_in_s: float = 600.0  # a running start: the oil's first seconds not scored (the components' start
    burn_in_tc_s: float = 900.0  # unknown), and a rig thermocouple's
    start_early_s: float = 300.0  # ... judged from a real gap in the oil's first seconds
    start_min_span_s: float = 300.0  # ... and at least this much left after them, else it is scored at rest
    start_min_cells: int = 30  # a running file's channel keeps at least this many cells, else it is dropped
    housing_offset_lo_c: float = -25.0  # a running start: the housings' start within these of the sump
    housing_offset_hi_c: float = 5.0


@dataclass
class SimulationOptions:
    """The model's runs: the plant's step, the output interval, the processes, the surrogate's grid."""

    plant_dt_s: float = 1.0  # re-simulation step of the plant
    out_dt_s: float = 1.0  # model output interval (before the nuisance lag and the grid)
    workers: int | None = None
    coarse_grid: bool = True  # surrogate grid at the plant's coarse step (2 s), differences only
    dense: int = 161  # dense parameter grid of the surrogate
    refine: int = 2  # refinement re-simulations per candidate


@dataclass
class FitOptions:
    """Fitting the candidates: the nuisances and the forward selection of several effects."""

    sensor_lag_max_s: float = 10.0  # normal sensor dynamics: a nuisance, never an effect
    model_floor_c: float = 0.05  # model error floor added to the noise in the weights
    initial_offset_max_c: float = 0.25  # the initial temperature nuisance: within this of the first reading
    max_effects: int = 3  # forward selection: at most this many effects found together (1: off)
    set_starts: int = 3  # forward selection: from the best candidate and up to 2 confusable with it
    set_start_test_tol: float = 0.1  # a set from another start must leave the held-out RMS at most this much above
    # the best candidate's own result (the held-out guard against an overfit)
    combine_check: int = 2  # forward selection: candidates re-simulated per step
    add_share_min: float = 0.02  # forward selection: a new effect's least share of all the set explains (unless it
    # closes a clear gap)
    add_explain_min: float = 0.2  # forward selection: share of the set's unexplained excess a new effect must explain
    clear_gap_factor: float = 2.0  # a clear gap: a systematic residual at least this many times its threshold
    clear_gap_cut: float = 2.5  # ... or cut by more than this factor, leaving no clear gap (set between the cases
    # seen: a true second effect cut 3.9 -> 1.2, a stand-in third 2.8 -> 1.4)


@dataclass
class VerdictOptions:
    """The verdict and the exclusion of the other effects: the thresholds of a gap, of evidence and of a shrink."""

    none_k: float = 0.3  # "none" at once: systematic residual <= none_k x noise (per sample) ...
    none_floor_c: float = 0.03  # ... or this, on every channel
    gap_k: float = 1.0  # a real gap: systematic residual > gap_k x noise ...
    gap_floor_c: float = 0.1  # ... and this, on some channel
    ident_k: float = 0.5  # identifiable: the effect can move a channel by ident_k x noise (RMS)
    min_frac: float = 0.1  # a verdict's effect must sit >= 10 % of the way from neutral to its bound
    evidence_min: float = 10.0  # score (-dBIC) for strong evidence
    explain_min: float = 0.5  # share of the excess squared residual the verdict must explain
    confusable_corr: float = 0.95
    confusable_share: float = 0.1  # explained shares within this of the best
    shrink_min: float = 0.3  # a verdict's effect must shrink a real held-out gap by this much
    not_excluded: bool = True  # say which other effects the data cannot rule out beside the verdict
    not_excluded_min_frac: float = 0.3  # list an effect not excluded beside the verdict when its interval
    # (exclude.py) reaches this far towards a bound


@dataclass
class ReportOptions:
    """What the report shows: the regime split of the residual ("where")."""

    cold_c: float = 60.0  # oil below this: the "cold" regime


#: the settings of the diagnosis by stage: Options' attribute -> its class
STAGE_OPTIONS = {
    "reading": ReadingOptions,
    "starts": StartOptions,
    "simulation": SimulationOptions,
    "fit": FitOptions,
    "verdict": VerdictOptions,
    "report": ReportOptions,
}
#: every setting's stage (each name belongs to one)
SETTING_STAGE = {f.name: stage for stage, cls in STAGE_OPTIONS.items() for f in fields(cls)}


class Options:
    """The settings of the gap diagnosis, grouped by stage (``opts.reading``, ``opts.starts``, ``opts.simulation``,
    ``opts.fit``, ``opts.verdict``, ``opts.report``). Each setting is also read and written by its own name
    (``opts.grid_dt_s``) and given so (``Options(grid_dt_s=1.0, start="rest")``), as when the settings were one flat
    list; a stage may be given whole (``Options(verdict=VerdictOptions(evidence_min=6))``)."""

    def __init__(self, **given):
        for stage, cls in STAGE_OPTIONS.items():
            value = given.pop(stage, None)
            if value is not None and not isinstance(value, cls):
                raise TypeError(f"Options({stage}=...) must be a {cls.__name__}")
            object.__setattr__(self, stage, value if value is not None else cls())
        for name, value in given.items():
            if name not in SETTING_STAGE:
                raise TypeError(f"Options() got an unexpected keyword argument {name!r}")
            setattr(getattr(self, SETTING_STAGE[name]), name, value)

    def __setattr__(self, name, value):
        if name in STAGE_OPTIONS:
            object.__setattr__(self, name, value)
        elif name in SETTING_STAGE:
            setattr(getattr(self, SETTING_STAGE[name]), name, value)
        else:
            raise AttributeError(f"Options has no setting {name!r}")

    def __eq__(self, other):
        return isinstance(other, Options) and all(getattr(self, s) == getattr(other, s) for s in STAGE_OPTIONS)

    def __repr__(self):
        return "Options(" + ", ".join(f"{s}={getattr(self, s)!r}" for s in STAGE_OPTIONS) + ")"


def _flat(name: str, stage: str) -> property:
    """A setting read and written by its own name on Options (``opts.grid_dt_s`` is ``opts.reading.grid_dt_s``)."""
    return property(
        lambda self: getattr(getattr(self, stage), name),
        lambda self, value: setattr(getattr(self, stage), name, value),
        doc=f"``{stage}.{name}``",
    )


for _name, _stage in SETTING_STAGE.items():
    setattr(Options, _name, _flat(_name, _stage))


def n_eff_needed(opts: Options, k: int = 1) -> int:
    """The least effective sample size at which the BIC decision can be made (docs/diagnosis.md, "Thin evidence"):
    the smallest n at which `k` parameters that explain ``explain_min`` of the excess squared residual reach strong
    evidence, n ln(1 / (1 - explain_min)) - k ln n >= evidence_min (19 for one parameter with the defaults). Below it
    a score says how closely a fit follows a few independent pieces of residual, not how many support it."""
    gain = -math.log(max(1.0 - opts.explain_min, 1e-9))
    n = 2
    while n * gain - k * math.log(n) < opts.evidence_min and n < 1_000_000:
        n += 1
    return n


def json_number(x, nd=4):
    """A JSON number: rounded to `nd` decimals; None for None, NaN and infinities."""
    if x is None:
        return None
    x = float(x)
    if x != x or x in (float("inf"), float("-inf")):
        return None
    return round(x, nd)


def how_much_more(needed: float, n_eff: float, train_s: float) -> str:
    """How much training time the decision needs at this autocorrelation, in words ("1 times" read as enough)."""
    if not train_s > 0.0:  # (a real truck's capture of a few minutes: its time all before scoring starts)
        return "far more than these files give: none of their time was scored"
    if not n_eff >= 1.0:  # (under one effective sample no ratio means anything)
        return f"at this autocorrelation far more than the {_span(train_s)} scored"
    more = needed / n_eff
    return f"at this autocorrelation about {more:.1f} times the {_span(train_s)} scored in all, {_span(more * train_s)}"


def _span(seconds: float) -> str:
    """A duration in the unit a reader takes in: seconds under 2 min, minutes under an hour, else hours."""
    if seconds < 120.0:
        return f"{seconds:.0f} s"
    return f"{seconds / 60.0:.0f} min" if seconds < 3600.0 else f"{seconds / 3600.0:.1f} h"
