"""The C kernel's interface, described once: every struct field (name, C type, shape, unit, doc) and every constant
the kernel and the Python side share. The rest is generated from it:

* the header ``firmware_model/onboard/c/gvs_kernel.h`` (structs, #define and enum constants, prototypes), checked in
  so that an embedded build, export-c and the FMU need no Python: ``python -m firmware_model.onboard.kernel_interface
  --write`` regenerates it, ``--check`` says whether it is current (tests/firmware_model/test_kernel_interface.py
  regenerates and compares, and compiles a probe of every struct's sizeof and offsets against the ctypes classes);
* the ctypes classes of the binding (:func:`ctypes_fields`, built at import time by
  :mod:`firmware_model.onboard.ckernel`: no generated Python file to keep in step);
* the keys of the table builder (:func:`struct_values`, used by :mod:`firmware_model.onboard.kernel_tables`: a
  field it does not fill, or a key the struct does not have, is an error naming it).

The numpy reference imports the shared constants from here (the march, the effect codes, the speed columns, the
oil-property columns); the ones another module owns (published components, input fields, reject reasons, warning
levels, modes, cooler kinds, gears) are read from that module, so each number is written once.
"""

from __future__ import annotations

import argparse
import ctypes as C
import math
import sys
from pathlib import Path
from typing import NamedTuple

from firmware_model.components import (
    LEVEL_CRITICAL,
    LEVEL_NA,
    LEVEL_NORMAL,
    LEVEL_WARNING,
    MODE_HOLDING,
    MODE_NORMAL,
    MODE_OIL_MODEL,
)
from firmware_model.onboard.records import MAIN, N_INPUTS, N_REJECT, REJECT_REASONS, TWIN
from firmware_model.physics.cooler import COOLER_KINDS
from firmware_model.physics.losses import SKF_ISH_EXP, SKF_RR_LOAD_EXP, SKF_RR_NU_N_EXP

HEADER_PATH = Path(__file__).resolve().parent / "c" / "gvs_kernel.h"
REGENERATE = "python -m firmware_model.onboard.kernel_interface --write"

# --- constants shared by the kernel and the numpy reference ------------------------------------------------------

#: default capacities of the plain structs (the tables give the actual sizes; gvs_check_tables() refuses larger
#: ones); an ECU build sets them to the exported variant's sizes (-DGVS_MAX_NODES=61 ...) to save RAM
MAX_NODES, MAX_LINKS, MAX_SRC, MAX_BC, MAX_STREAMS, MAX_LNZ, MAX_TERMS = 96, 192, 32, 8, 32, 512, 64
#: ... and the most published components and gears (the description's published.order and gears; GRS905: 28, 17)
MAX_PUB, MAX_GEARS = 48, 32
#: return codes of gvs_step
OK, SKIPPED, NEED_JUMP, BAD_TABLES = 0, 1, 2, -1
#: columns of the oil property table (logarithms where the property spans decades: interpolated in the log)
PROP_COLUMNS = ("LOG10_MU", "LN_NU_CST", "LN_MU", "LN_ROLL", "RHO", "CP", "K", "LN_PR")
N_PROP = len(PROP_COLUMNS)
P_LOG10_MU, P_LN_NU_CST, P_LN_MU, P_LN_ROLL, P_RHO, P_CP, P_K, P_LN_PR = range(N_PROP)
#: which vehicle effect scales a conductance law (pw_effect, ef_effect): none or a gvs_vehicle field
#: oil pump kinds; the index is ReducedParams.pump_code and tables.pump_code (GVS_PUMP_*): none (splash
#: lubrication), a pump on a shaft (flow per radian of it: the GRS905's on the layshaft), a motor-driven pump (a fixed
#: volume flow, the MM82's)
PUMP_KINDS = ("none", "shaft", "motor")
EFFECT_NONE, EFFECT_TEETH_OIL_H, EFFECT_PLANET_OIL_H, EFFECT_HOUSING_AIR_H = range(4)
#: the time to limit's march (held_march): first step [s], each step this many times longer than the last
MARCH_H0_S = 1.0
MARCH_RATIO = 1.4
#: time to limit beyond this is reported as never (inf) [s]
TTL_HORIZON_S = 2.0e6
#: the result is the first multiple of this at or after the crossing [s]
TTL_QUANTUM_S = 2.0**-7
#: TR-BDF2 with gamma = 2 - sqrt(2): both stages solve with C + d A, d = MARCH_D_FRAC h (trapezoid to gamma h, then
#: BDF2 e1 = A1 e_gamma - A0 e0 + d C^-1 (-A e1))
MARCH_GAMMA = 2.0 - math.sqrt(2.0)
MARCH_D_FRAC = 1.0 - 1.0 / math.sqrt(2.0)
MARCH_A1 = 1.0 / (MARCH_GAMMA * (2.0 - MARCH_GAMMA))
MARCH_A0 = (1.0 - MARCH_GAMMA) ** 2 / (MARCH_GAMMA * (2.0 - MARCH_GAMMA))
#: samples of the Hermite interpolant that look for the first sign change, then bisections
HERMITE_SAMPLES = 16
HERMITE_BISECTIONS = 40
#: the coupled held system must keep 1 - e_sump^T K^-1 u above this (else a real mode grows: the inlet is frozen)
COUPLING_MARGIN = 1.0e-6
#: with the sump modelled: re-linearise the held-input system this many times at the sump temperature the last
#: solution predicts at the earliest crossing (the losses and oil-side conductances follow the sump; docs/sensor.md)
TTL_RELINEARISE_STEPS = 2
#: ... until the operating point's sump temperature moves less than this [K]
TTL_RELINEARISE_TOL_K = 0.5
#: the bounded time to limit (ttl_bound): a sump within this of its far value is settled (the step's own system
#: is marched) [K]
TTL_BOUND_TOL_K = 0.5
#: ... and where it predicts a crossing within this, today's method too, the earlier kept (the early warning's
#: lead is 30 s: a warning never comes later than today's) [s]
TTL_BOUND_GATE_S = 60.0
#: ... and its marches' grid: each step this many times longer than the last (today's: MARCH_RATIO); on the 240
#: held points of benchmarks/bench_ttl.py 1.8 or 1.4 put one crossing more of 211 within 20 % (docs/sensor.md)
TTL_BOUND_RATIO = 2.5
#: ... its far sump, where the held model's own steady sump is the sump it is evaluated at: at most this many
#: solves after the bracket's ends ...
TTL_FAR_ITERS = 12
#: ... until the bracket, or the steady sump's miss, is narrower than this [K]
TTL_FAR_TOL_K = 0.05
#: ... the sump's path to its far value cut into at most this many parts, each with its own lines under the
#: cooler's and the inlet drop's curves (one line lay kilowatts under a curve with a kink: 20-95 % early) ...
TTL_SEG_MAX = 3
#: ... the path sampled at this many sumps evenly between its ends (and each part at as many inside it) ...
TTL_SEG_SAMPLES = 16
#: ... and cut while a part's lines lie more than this under the curves [W]
TTL_SEG_GAP_W = 200.0
#: ... at the first cuts whose worst gap is within this of the best (clipped curves tie: rounding must not decide) [W]
TTL_SEG_TIE_W = 1.0
#: an early warning (Limits.lead_s) is judged only on a time to limit refreshed at most this long ago [s] (every live
#: and 0.1 s offline configuration refreshes at least this often; a held replay's coarse step refreshes once per row
#: and publishes the countdown in between, which neither raises nor holds an early warning: docs/sensor.md)
TTL_FRESH_S = 10.0
#: drive inputs back after an outage longer than the hold (hold_s): the warning levels stay "not available" for as
#: long as the outage went on past the hold, at most this long [s] (assumed: three time constants of the quickest
#: published parts, ~200 s; after a 5-min torque outage on the uphill cycle the sun wheel read 11 K high in mode 0
#: and warned, the true one 10 K under its limit, the error down to 4 K after 200 s: docs/sensor.md "Bad input")
RECOVER_MAX_S = 600.0
#: with the sump measured, an oil reading is judged against the last good reading and the main copy's sump (that
#: reading carried by the model since): a reading off both by more than oil_step_c plus this rate times the time
#: since that reading came (its age and oil_period_s, the period one reading stands for) is implausible [K/s]
#: (derived: the measured sump's distance from the model moved by at most 0.053 K/s from one 10-minute row to the
#: next on three MM82 turbines' five years, its 99.9th percentile 0.008-0.010 K/s; a reading that jumps and stays, a
#: sensor failed to a plausible value, is modelled over for about the gap / this rate: 30 min for 95 K)
OIL_DRIFT_K_PER_S = 0.05
#: the age of an oil reading never taken (a start without one) [s]: any first reading is good
OIL_AGE_NONE_S = 1.0e9
#: the C names of the input fields (records.INPUT_FIELDS, same order)
INPUT_C_NAMES = ("SPEED", "TORQUE", "GEAR", "OIL", "AMB", "COOL", "VKMH", "RET")
if len(INPUT_C_NAMES) != N_INPUTS:
    raise ImportError(
        f"kernel_interface.INPUT_C_NAMES names {len(INPUT_C_NAMES)} inputs, INPUT_FIELDS has "
        f"{N_INPUTS}: name the new input's C enum there"
    )


class Constant(NamedTuple):
    """One #define of the header: C name (without GVS_), value, doc."""

    name: str
    value: int | float
    doc: str = ""


class Enum(NamedTuple):
    """One enum of the header: doc, (C name without GVS_, value) pairs."""

    doc: str
    items: tuple


def _enum(doc: str, prefix: str, names, values=None) -> Enum:
    values = range(len(names)) if values is None else values
    return Enum(doc, tuple((prefix + n.upper(), int(v)) for n, v in zip(names, values)))


#: capacities: #ifndef-guarded so that a build can size the structs (the export pins them)
CAPACITIES = (
    Constant("MAX_NODES", MAX_NODES, "nodes of the network"),
    Constant("MAX_LINKS", MAX_LINKS, "links"),
    Constant("MAX_SRC", MAX_SRC, "heat sources"),
    Constant("MAX_BC", MAX_BC, "boundary temperatures"),
    Constant("MAX_STREAMS", MAX_STREAMS, "oil-system streams"),
    Constant("MAX_LNZ", MAX_LNZ, "entries of L below the diagonal in the time to limit's sparse LDL^T (GRS905: 178)"),
    Constant(
        "MAX_TERMS",
        MAX_TERMS,
        "the most terms of one kind of conductance law (tables, closed-form streams) and oil-factor columns",
    ),
    Constant("MAX_PUB", MAX_PUB, "published components (tables.n_pub; the description's published.order)"),
    Constant("MAX_GEARS", MAX_GEARS, "gear rows of the per-gear tables (tables.n_gears)"),
)
#: fixed sizes and numbers of the kernel and the numpy reference
DEFINES = (
    Constant("N_INPUTS", N_INPUTS, "input fields (records.INPUT_FIELDS)"),
    Constant("N_REJECT", N_REJECT, "reject counters (records.REJECT_REASONS)"),
    Constant("N_PROP", N_PROP, "columns of the oil property table"),
    Constant("SKF_RR_LOAD_EXP", SKF_RR_LOAD_EXP, "SKF's rolling moment: exponent of the load (tables.bear_rr)"),
    Constant("SKF_RR_NU_N_EXP", SKF_RR_NU_N_EXP, "... and of nu n [cSt rpm]"),
    Constant("SKF_ISH_EXP", SKF_ISH_EXP, "... its inlet shear factor: exponent of n^2 nu [rpm2 cSt]"),
    Constant("MARCH_H0_S", MARCH_H0_S, "time to limit: first march step [s]"),
    Constant("MARCH_RATIO", MARCH_RATIO, "each march step this many times longer than the last"),
    Constant("TTL_HORIZON_S", TTL_HORIZON_S, "time to limit beyond this is never (inf) [s]"),
    Constant("TTL_QUANTUM_S", TTL_QUANTUM_S, "result: the first multiple of this at or after the crossing [s]"),
    Constant("MARCH_D_FRAC", MARCH_D_FRAC, "TR-BDF2, gamma = 2 - sqrt(2): d = MARCH_D_FRAC h = 1 - 1/sqrt(2)"),
    Constant("MARCH_A1", MARCH_A1, "BDF2 stage: 1 / (gamma (2 - gamma))"),
    Constant("MARCH_A0", MARCH_A0, "BDF2 stage: (1 - gamma)^2 / (gamma (2 - gamma))"),
    Constant("HERMITE_SAMPLES", HERMITE_SAMPLES, "samples of the Hermite interpolant looking for a crossing"),
    Constant("HERMITE_BISECTIONS", HERMITE_BISECTIONS, "then bisections"),
    Constant("TTL_RELINEARISE_STEPS", TTL_RELINEARISE_STEPS, "re-linearisations at the predicted sump"),
    Constant("TTL_RELINEARISE_TOL_K", TTL_RELINEARISE_TOL_K, "... until the sump moves less than this [K]"),
    Constant("COUPLING_MARGIN", COUPLING_MARGIN, "the coupled held system needs 1 - e^T K^-1 u above this"),
    Constant(
        "TTL_BOUND_TOL_K", TTL_BOUND_TOL_K, "bounded time to limit: a sump this close to its far value is settled [K]"
    ),
    Constant("TTL_BOUND_GATE_S", TTL_BOUND_GATE_S, "a crossing within this: today's march too, the earlier [s]"),
    Constant("TTL_BOUND_RATIO", TTL_BOUND_RATIO, "... its marches: each step this many times longer than the last"),
    Constant("TTL_FAR_ITERS", TTL_FAR_ITERS, "... its far sump: at most this many solves in the bracket"),
    Constant("TTL_FAR_TOL_K", TTL_FAR_TOL_K, "... until the bracket is narrower than this [K]"),
    Constant("TTL_SEG_MAX", TTL_SEG_MAX, "... the sump's path to its far value in at most this many parts"),
    Constant("TTL_SEG_SAMPLES", TTL_SEG_SAMPLES, "... sampled at this many sumps between"),
    Constant("TTL_SEG_GAP_W", TTL_SEG_GAP_W, "... cut where its lines lie this far under the curves [W]"),
    Constant("TTL_SEG_TIE_W", TTL_SEG_TIE_W, "... at the first sample within this of the best [W]"),
    Constant("TTL_FRESH_S", TTL_FRESH_S, "an early warning judges a time to limit at most this old [s]"),
    Constant("RECOVER_MAX_S", RECOVER_MAX_S, "levels not available after an outage: at most this long [s]"),
    Constant("OIL_DRIFT_K_PER_S", OIL_DRIFT_K_PER_S, "oil off the last good one and its carry: step + this x age"),
    Constant("OIL_AGE_NONE_S", OIL_AGE_NONE_S, "the age of an oil reading never taken [s]"),
)
#: the structs gvs_sizeof() measures, in its argument's order ("real": sizeof(gvs_real))
SIZEOF_IDS = ("tables", "vehicle", "state", "inputs", "outputs", "ttl_point", "real")
ENUMS = (
    _enum("input fields (records.INPUT_FIELDS order)", "I_", INPUT_C_NAMES),
    Enum(
        "return codes of gvs_step",
        (("OK", OK), ("SKIPPED", SKIPPED), ("NEED_JUMP", NEED_JUMP), ("BAD_TABLES", BAD_TABLES)),
    ),
    _enum("reject counters (records.REJECT_REASONS order)", "RJ_", REJECT_REASONS),
    _enum(
        "warning levels (firmware_model.components)",
        "LEVEL_",
        ("normal", "warning", "critical", "na"),
        (LEVEL_NORMAL, LEVEL_WARNING, LEVEL_CRITICAL, LEVEL_NA),
    ),
    _enum(
        "degraded modes (firmware_model.components)",
        "MODE_",
        ("normal", "oil_model", "holding"),
        (MODE_NORMAL, MODE_OIL_MODEL, MODE_HOLDING),
    ),
    _enum("the two copies of the network in the state (records)", "", ("main", "twin"), (MAIN, TWIN)),
    _enum("columns of the oil property table (tables.prop)", "P_", PROP_COLUMNS),
    _enum(
        "the vehicle effect that scales a conductance law (pw_effect, ef_effect)",
        "EFFECT_",
        ("none", "teeth_oil_h", "planet_oil_h", "housing_air_h"),
        (EFFECT_NONE, EFFECT_TEETH_OIL_H, EFFECT_PLANET_OIL_H, EFFECT_HOUSING_AIR_H),
    ),
    _enum("cooler kinds (tables.cooler_code; firmware_model.physics.cooler.COOLER_KINDS)", "COOLER_", COOLER_KINDS),
    _enum("oil pump kinds (tables.pump_code; PUMP_KINDS)", "PUMP_", PUMP_KINDS),
    _enum("the argument of gvs_sizeof", "SIZEOF_", SIZEOF_IDS),
)


# --- the structs -------------------------------------------------------------------------------------------------


class Field(NamedTuple):
    """One struct field. ``ctype``: int32_t, int64_t, int8_t, double, gvs_real, or a read-only table
    ``const gvs_real *`` / ``const gvs_idx *``. ``shape``: of a plain array its C dimensions (numbers or capacity
    names), of a table the sizes its length is made of (tables fields, ``gears`` = n_gears)."""

    name: str
    ctype: str
    shape: tuple = ()
    unit: str = ""
    doc: str = ""


class Struct(NamedTuple):
    """One struct: its C name, the binding's class name, doc, and items (Field, or a str: a comment line)."""

    c_name: str
    py_name: str
    doc: str
    items: tuple

    @property
    def fields(self) -> tuple:
        return tuple(i for i in self.items if isinstance(i, Field))


I32, I64, I8, F64, REAL, PREAL, PIDX, PT2 = (
    "int32_t",
    "int64_t",
    "int8_t",
    "double",
    "gvs_real",
    "const gvs_real *",
    "const gvs_idx *",
    "const gvs_t2 *",
)


def _f(names: str, ctype: str, shape: tuple = (), unit: str = "", doc: str = "") -> list:
    """Fields of one C type, shape and unit (``names``: space separated)."""
    return [Field(n, ctype, shape, unit, doc) for n in names.split()]


_TABLES = (
    "sizes: nodes, links, boundaries, sources, power laws, tables, cylinders, closed-form streams, radiation links, "
    "streams, source non-zeros; then the tables' axes",
    *_f("n nl nb ns npw n2 nc ne nrad nst nsrc_nz", I32),
    *_f("nT ncol n_u nT2 n_u_churn nx n_mesh n_bear n_needle n_speed n_gears n_pub", I32),
    Field("i_oil", I32, doc="the sump node"),
    Field("i_ambient", I32, doc="the ambient boundary"),
    Field("i_coolant", I32, doc="the coolant boundary"),
    Field("cooler_code", I32, doc="GVS_COOLER_*"),
    Field("pump_code", I32, doc="GVS_PUMP_*: the oil flow follows pump_speed_col (shaft) or is pump_flow_m3_s (motor)"),
    Field("oil_inlet", I32, doc="1: a forced oil system, the step outputs its oil inlet (sump - inlet drop); 0: NaN"),
    Field("gear_min", I32, doc="gear of row 0"),
    Field("gear_defined", I32, doc="bit r: the description has gear gear_min + r (another gear input is unknown)"),
    Field("aux_expected", I32, doc="bit i: the drive has auxiliary input I_AMB + i (another one is not counted)"),
    Field("oil_mode_measured", I32, doc="1: a measured sump is used"),
    Field("ttl_every", I32, doc="steps between time-to-limit refreshes"),
    "network",
    Field("dt_over_C", PREAL, ("n",), "s K/J", "dt / C"),
    Field("link_a", PIDX, ("nl",)),
    Field("link_b", PIDX, ("nl",), doc="link_b >= n: boundary link_b - n"),
    Field("G_const", PREAL, ("nl",), "W/K"),
    Field("published_index", PIDX, ("n_pub",), doc="node of each published component"),
    "power laws: G = coef[row, t] w^exp[t] (phi(T)[col[t]] or 1) x effect",
    *_f("pw_link pw_col pw_effect", PIDX, ("npw",)),
    Field("pw_exp", PREAL, ("npw",)),
    Field("pw_gear_coef", PREAL, ("gears", "npw")),
    Field("pw_phi", PREAL, ("nT", "ncol")),
    "bilinear tables over (sqrt(w_t / w_max), T)",
    Field("t2_link", PIDX, ("n2",)),
    Field("t2_speed_coef", PREAL, ("gears", "n2")),
    Field("t2_omega_max_rad_s", PREAL, ("n2",), "rad/s"),
    Field("t2_table", PT2, ("n2", "n_u", "nT2"), "W/K", "times t2_scale"),
    Field("t2_scale", PREAL, ("n2",), doc="per table: 1, or the step of an export's int16 table (GVS_T2_Q16)"),
    Field("t2_stride", I32, doc="the tables use every t2_stride-th temperature of the grid"),
    "immersed wheels, Nusselt in closed form",
    Field("cyl_link", PIDX, ("nc",)),
    Field("cyl_speed_coef", PREAL, ("gears", "nc")),
    Field("cyl_c", PREAL, ("nc",), "m"),
    Field("cyl_ln_rp2", PREAL, ("nc",), doc="ln(R_p^2 [m2])"),
    "oil-system streams in closed form",
    *_f("ef_link ef_effect", PIDX, ("ne",)),
    *_f("ef_mcp ef_alpha ef_beta", PREAL, ("ne",)),
    "radiation",
    *_f("rad_link rad_node rad_bc", PIDX, ("nrad",)),
    Field("rad_area_eps", PREAL, ("nrad",), "m2"),
    "streams: G_streams = [G2[t2_stream_term], Ge]; stream s moves G dT_in from stream_node[s] to the sump",
    Field("t2_stream_term", PIDX, ("nst - ne",)),
    Field("stream_node", PIDX, ("nst",)),
    "oil properties on the temperature grid",
    Field("prop", PREAL, ("nT", "N_PROP"), doc="columns GVS_P_*"),
    Field("T_grid0_c", REAL, (), "degC"),
    Field("T_grid_step_k", REAL, (), "K"),
    "losses",
    Field("speed_coef", PREAL, ("gears", "n_speed"), doc="every speed per unit input speed"),
    Field("pump_speed_col", I32, doc="speed_coef column of the shaft that drives the oil pump (flow, cooler); -1 none"),
    Field("churn_speed_col", I32, doc="... of the shaft whose dipping wheels churn (the churning table); -1 none"),
    Field("output_speed_col", I32, doc="... of the output shaft (retarder); -1 none"),
    *_f("mesh_torque mesh_omega2", PREAL, ("gears", "n_mesh")),
    Field("mesh_x0", PREAL, ("n_mesh",)),
    Field("mesh_phi", PREAL, ("n_mesh", "nx")),
    *_f("mesh_roll_k mesh_heat_sf", PREAL, ("n_mesh",)),
    Field("mesh_roll_lt_min", PREAL, ("n_mesh",), doc="log10 T1 below which the rolling loss ramps to 0"),
    *_f("bear_speed bear_c bear_load", PREAL, ("gears", "n_bear")),
    Field("bear_rr", PREAL, ("gears", "n_bear"), doc="SKF rolling moment per |T|^0.31 (nu n)^0.6; all 0: none"),
    Field("bear_ish", PREAL, ("n_bear",), doc="... over 1 + bear_ish (n^2 nu)^0.64 (SKF's inlet shear)"),
    Field("needle_rel", PREAL, ("gears", "n_needle"), doc="needle bearings' relative speed per unit input speed"),
    Field("needle_c", PREAL, ("n_needle",)),
    *_f("sync_coef pump_coef", PREAL, ("gears",)),
    Field("churn_table", PREAL, ("n_u_churn", "nT"), "W"),
    *_f("churn_omega_max_rad_s", REAL, (), "rad/s"),
    *_f("churn_heat_sf x_step ln10", REAL),
    "source -> node heat, sparse: node heat[src_nz_node[k]] += delivered[src_nz_src[k]] * src_nz_w[k]",
    *_f("src_nz_src src_nz_node", PIDX, ("nsrc_nz",)),
    Field("src_nz_w", PREAL, ("nsrc_nz",)),
    Field("lag_gain", REAL),
    Field("lag_tau_over_dt", REAL),
    "cooler (seed 3.4, Eq 82-83)",
    Field("flow_m3_per_rad", REAL, (), "m3/rad"),
    Field("pump_flow_m3_s", REAL, (), "m3/s", doc="a motor-driven pump's fixed flow"),
    Field("pump_stop_rad_s", REAL, (), "rad/s", doc="... none while the input shaft turns at or below it (0: always)"),
    *_f("liquid_hA_ref", REAL, (), "W/K"),
    *_f("liquid_Qmax_cool liquid_Qmax_heat", REAL, (), "W"),
    Field("air_hA_ref", REAL, (), "W/K"),
    Field("air_Qmax_cool", REAL, (), "W"),
    *_f("thermostat_open_c thermostat_full_c", REAL, (), "degC"),
    Field("thermostat_sump", REAL, doc="1: the thermostat reads the sump (before the cooler); 0: the return, Eq 82"),
    Field("heater_w", REAL, (), "W", doc="the sump heater's power (0: none)"),
    Field("heater_set_c", REAL, (), "degC", doc="the heater is off above this sump temperature ..."),
    Field("heater_band_k", REAL, (), "K", doc="... and at full power below heater_set_c - heater_band_k"),
    Field("measured_balance", REAL, doc="1: a measured sump's cooler takes what the sump's balance leaves"),
    Field("balance_keep_min", REAL, doc="... dividing by at least this share kept (BALANCE_KEEP_MIN)"),
    *_f("ref_ls_speed ref_engine_speed", REAL, (), "rad/s"),
    *_f("exp_inner exp_outer air_flow_min_frac", REAL),
    Field("air_ref_speed_kmh", REAL, (), "km/h"),
    Field("air_flow_max_rel", REAL),
    Field("inlet_drop_max_k", REAL, (), "K"),
    Field("default_vkmh", REAL, (), "km/h"),
    Field("recirc_v_kmh", PREAL, ("n_recirc",), "km/h"),
    Field("recirc_dT_k", PREAL, ("n_recirc",), "K"),
    Field("n_recirc", I32),
    "constants of the laws",
    Field("sigma", REAL, (), "W/m2K4"),
    Field("kelvin", REAL, (), "K"),
    Field("rpm_per_rad_s", REAL),
    Field("rad_s_per_rpm", REAL),
    Field("palmgren_min", REAL),
    Field("min_speed", REAL, (), "rad/s"),
    *_f("ln_04 ln_0238 ln_re_lam ln_re_bridge ln_1e6", REAL),
    *_f("rad_T_lo_c rad_T_hi_c", REAL, (), "degC"),
    Field("speed_bin_min", REAL, (), "rad/s"),
    Field("ln_speed_bin", REAL),
    Field("oil_bin_c", REAL, (), "degC"),
    "sensor: inputs, options, limits",
    Field("dt_s", REAL, (), "s"),
    *_f("input_lo input_hi clamp_lo clamp_hi", PREAL, ("N_INPUTS",)),
    Field("aux_default", PREAL, ("N_INPUTS - I_AMB",), doc="ambient, coolant, vehicle speed, retarder"),
    *_f("hold_s drive_frozen_s oil_frozen_s oil_period_s", REAL, (), "s"),
    *_f("oil_frozen_drift_c oil_step_c", REAL, (), "K"),
    Field("clock_reset_s", REAL, (), "s", "t_s back by more than this: a reset clock (stepped, counted)"),
    *_f("warning_c critical_c", PREAL, ("n_pub",), "degC"),
    Field("hysteresis_k", PREAL, ("n_pub",), "K"),
    Field("warning_rest_c", PREAL, ("n_pub",), "degC"),
    *_f("debounce_s lead_s", REAL, (), "s"),
    "time to limit (gvs_ttl_refresh; firmware_model.onboard.held_march, time_to_limit): heat capacities, the sparse "
    "LDL^T pattern of C/h + K (firmware_model.onboard.sparse_ldl), the components whose crossing re-linearises, and "
    "the options: the sump heats with the held load (else a measured sump is held), and re-linearise at the "
    "predicted sump (every effect one value for all vehicles); ttl_bound: the bounded method (ttl_bound, "
    "gvs_kernel.c ttl_refresh_bound; 0: today's march, ttl_method 'march')",
    Field("C_j_per_k", PREAL, ("n",), "J/K"),
    *_f("ldl_perm ldl_pos", PIDX, ("n",)),
    Field("ldl_col_ptr", PIDX, ("n + 1",)),
    Field("ldl_row", PIDX, ("ldl_nnz",)),
    Field("ldl_link_slot", PIDX, ("nl",)),
    Field("ldl_upd_ptr", PIDX, ("n + 1",)),
    *_f("ldl_upd_target ldl_upd_a ldl_upd_b", PIDX, ("ldl_nupd",)),
    Field("ttl_relin", PIDX, ("n_pub",)),
    *_f("ldl_nnz ldl_nupd ttl_sump_model ttl_relinearise", I32),
    *_f("ttl_bound", I32),
)

_VEHICLE = (
    Field("src_scale", REAL, ("GVS_MAX_SRC",), doc="loss scale of each heat source"),
    *_f("teeth_oil_h planet_oil_h housing_air_h cooler_scale", REAL, doc="conductance and cooler scales"),
    Field("thermostat_offset_c", REAL, (), "K"),
    Field("retarder_frac", REAL, doc="share of the retarder's power that heats the oil"),
    *_f("churn_scale needle_scale", REAL),
    Field("T_bc_default_c", REAL, ("GVS_MAX_BC",), "degC", "hot-surroundings offset applied"),
)

_STATE = (
    Field("T_c", REAL, (2, "GVS_MAX_NODES"), "degC", "main copy, open-loop twin"),
    Field("lag_w", REAL, ("GVS_MAX_SRC",), "W"),
    *_f("hold", REAL, ("GVS_N_INPUTS",), doc="held inputs"),
    *_f("age_s same_s", REAL, ("GVS_N_INPUTS",), "s"),
    Field("raw_prev", REAL, ("GVS_N_INPUTS",)),
    Field("oil_ref_c", REAL, (), "degC"),
    *_f("pending_s ttl_s", REAL, ("GVS_MAX_PUB",), "s"),
    Field("t_last_s", F64, (), "s", "frame time of the last step (NaN unknown)"),
    Field("k", I64, doc="steps done"),
    Field("rejects", I64, ("GVS_N_REJECT",)),
    Field("recover_s", REAL, (), "s", "the drive inputs' outage past the hold still to recover from"),
    "memo of the last conductance bin (a pure function of its key: the outputs never depend on it; a state packed "
    "from elsewhere starts with memo_valid = 0)",
    Field("memo_G", REAL, ("GVS_MAX_LINKS",), "W/K"),
    Field("memo_Gs", REAL, ("GVS_MAX_STREAMS",), "W/K"),
    Field("memo_omega_q", REAL, (), "rad/s"),
    Field("memo_T_q", REAL, (), "degC"),
    *_f("memo_row memo_valid", I32),
    "memo of the last heat sources, in a build with GVS_STEP_MEMO only (the host's: a held replay steps the same "
    "inputs tens of times a row; an ECU's inputs change every frame, so its build leaves the code out): the sources "
    "at (gear row, speed, torque, sump, retarder); a state packed from elsewhere starts with memo_heat_valid = 0",
    Field("memo_src", REAL, ("GVS_MAX_SRC",), "W"),
    Field("memo_heat_key", REAL, (4,), doc="speed [rad/s], |torque| [N m], sump [degC], retarder heat [W]"),
    *_f("memo_heat_row memo_heat_valid", I32),
    Field("level", I8, ("GVS_MAX_PUB",), doc="GVS_LEVEL_*"),
)

_INPUTS = (
    Field("raw", F64, ("GVS_N_INPUTS",), doc="GVS_I_* order (NaN: not available)"),
    Field("t_s", F64, (), "s", "frame time (NaN: the caller keeps the grid)"),
)

_OUTPUTS = (
    Field("T_c", REAL, ("GVS_MAX_PUB",), "degC"),
    Field("ttl_s", REAL, ("GVS_MAX_PUB",), "s"),
    *_f("model_oil_temp_c", REAL, (), "degC"),
    Field("oil_innovation_c", REAL, (), "K"),
    Field("oil_inlet_temp_c", REAL, (), "degC", "a forced oil system's inlet: the sump the step took - the inlet drop"),
    Field("rejects", I64, ("GVS_N_REJECT",), doc="the cumulative reject counters after this step"),
    *_f("valid_flags frozen_flags", I32, doc="bit GVS_I_* per input"),
    Field("level", I8, ("GVS_MAX_PUB",), doc="GVS_LEVEL_*"),
    Field("degraded_mode", I8, doc="GVS_MODE_*"),
    *_f("speed_valid torque_valid gear_valid oil_valid oil_source", I8),
)

_TTL_POINT = (
    Field("T_main_c", REAL, ("GVS_MAX_NODES",), "degC"),
    Field("src_w", REAL, ("GVS_MAX_SRC",), "W"),
    Field("G_w_per_k", REAL, ("GVS_MAX_LINKS",), "W/K"),
    Field("G_streams_w_per_k", REAL, ("GVS_MAX_STREAMS",), "W/K"),
    Field("T_bc_c", REAL, ("GVS_MAX_BC",), "degC"),
    Field("used", REAL, ("GVS_N_INPUTS",), doc="inputs used"),
    Field("dT_in_k", REAL, (), "K"),
    Field("Q_cool_w", REAL, (), "W"),
    Field("omega_in_rad_s", REAL, (), "rad/s"),
    Field("T_oil_c", REAL, (), "degC"),
    Field("rho_cp_j_per_m3k", REAL, (), "J/m3K"),
    *_f("due measured row", I32),
)

STRUCTS = (
    Struct(
        "gvs_tables",
        "Tables",
        "The generated tables of one gearbox variant and sensor configuration (read only; "
        'firmware_model.onboard.kernel_tables). Table shapes in the comments; 2-D arrays are row-major; "gears" '
        "rows are gear - gear_min.",
        _TABLES,
    ),
    Struct(
        "gvs_vehicle",
        "Vehicle",
        "Effect values and boundary defaults of one vehicle (firmware_model.effects; neutral = 1 / 0).",
        _VEHICLE,
    ),
    Struct("gvs_state", "State", "Everything the sensor remembers (SensorState of the numpy reference).", _STATE),
    Struct("gvs_inputs", "Inputs", "One step's inputs.", _INPUTS),
    Struct(
        "gvs_outputs",
        "Outputs",
        "One step's outputs (SensorOutputs and SensorStatus of the numpy reference).",
        _OUTPUTS,
    ),
    Struct(
        "gvs_ttl_point",
        "TtlPoint",
        "The operating point of a due time-to-limit refresh (TtlPoint of the numpy reference).",
        _TTL_POINT,
    ),
)
STRUCT = {s.py_name: s for s in STRUCTS}
#: the per-vehicle effect fields of gvs_vehicle (its plain scalars, in order)
VEHICLE_EFFECTS = tuple(f.name for f in STRUCT["Vehicle"].fields if not f.shape)
if tuple(s.c_name.removeprefix("gvs_") for s in STRUCTS) != SIZEOF_IDS[:-1]:
    raise ImportError("kernel_interface.SIZEOF_IDS must list STRUCTS in order")


# --- the Python side ---------------------------------------------------------------------------------------------

#: the value of every name a plain array's dimension may use
DIMENSIONS = {"GVS_" + c.name: c.value for c in CAPACITIES + DEFINES}


def ctypes_fields(struct: Struct, real) -> list:
    """``_fields_`` of the ctypes class of ``struct`` for a real type (c_double or c_float); the binding's index
    tables are int32 (gvs_idx of a build without GVS_INDEX16)."""
    scalars = {
        I32: C.c_int32,
        I64: C.c_int64,
        I8: C.c_int8,
        F64: C.c_double,
        REAL: real,
        PREAL: C.POINTER(real),
        PIDX: C.POINTER(C.c_int32),
        PT2: C.POINTER(real),
    }
    out = []
    for f in struct.fields:
        t = scalars[f.ctype]
        if f.ctype not in (PREAL, PIDX, PT2):
            for dim in reversed(f.shape):
                t = t * (dim if isinstance(dim, int) else DIMENSIONS[dim])
        out.append((f.name, t))
    return out


def table_kind(f: Field) -> str:
    """gvs_tables fields as the table writers sort them: "i" int32, "r" real, "pr" real table, "pi" index table."""
    return {I32: "i", REAL: "r", PREAL: "pr", PIDX: "pi", PT2: "pr"}[f.ctype]


def struct_values(struct: Struct, values: dict) -> dict:
    """``values`` in the struct's field order; a field it lacks or a key the struct does not have raises."""
    names = [f.name for f in struct.fields]
    missing = [n for n in names if n not in values]
    extra = [k for k in values if k not in names]
    if missing or extra:
        raise KeyError(
            f"{struct.c_name}: the table builder "
            + (f"fills no {', '.join(missing)}" if missing else "")
            + ("; " if missing and extra else "")
            + (f"fills {', '.join(extra)}, which the struct does not have" if extra else "")
            + f" (kernel_interface.py describes the struct; {REGENERATE} after changing it)"
        )
    return {n: values[n] for n in names}


# --- the header ----------------------------------------------------------------------------------------------------

HEADER_TOP = """/* gearbox-vsensor onboard step: a generic C99 kernel.
 *
 * One call of gvs_step() is one 0.1 s step of the onboard virtual sensor, exactly as the numpy reference
 * (firmware_model/onboard/step.py, step_deferred) does it: input checks, holds and reject counters; loss maps
 * and conductance laws at the centre of the operating point's bin; the heat lag; the cooler and its inlet drop;
 * one explicit (forward Euler) step of the main network and of the open-loop twin; warning levels with hysteresis
 * and debounce (early warning from the time to limit); degraded modes and status.
 *
 * Everything gearbox-specific is data (struct gvs_tables), generated from the one description by
 * firmware_model.onboard.kernel_tables: handed over at run time from Python, or written as a C source of const
 * arrays for an embedded build. The kernel has no dynamic allocation, no I/O, no mutable globals, and uses
 * nothing from libc beyond <math.h>, <string.h> and <stdint.h>.
 *
 * The real type is chosen at compile time: double by default (parity with the numpy reference), float with
 * -DGVS_REAL_FLOAT (an ECU with a single-precision FPU). Time stamps stay double in both builds.
 *
 * The time to limit is refreshed every ttl_every steps from the operating point a step hands out in a
 * gvs_ttl_point: gvs_ttl_refresh() marches the held-input system (no eigen-decomposition: a sparse LDL^T and
 * TR-BDF2 on a geometric grid; docs/sensor.md), gvs_run() does it in place when asked, and a caller that wants the
 * step's frames out first calls it after the step. One part of the sensor is left to the host: the propagation of
 * the state over a forward time jump (the kernel returns GVS_NEED_JUMP before touching the state; the host
 * propagates state->T_c and calls again with jump_done = 1).
 */
#ifndef GVS_KERNEL_H
#define GVS_KERNEL_H

#include <stdint.h>

/* The kernel's and the API's NaN and range checks are comparisons with NaN: -ffast-math (-ffinite-math-only) lets
 * the compiler assume they never hold, so bad input reads as good and tables are indexed with garbage (a crash under
 * clang). Every file that includes this header stops; gvs_check_tables() also refuses to step a build whose NaN
 * comparisons do not work (clang's -fno-honor-nans defines no macro). */
#if defined(__FAST_MATH__) || defined(__FINITE_MATH_ONLY__) && __FINITE_MATH_ONLY__
#error "gearbox-vsensor's C must not be compiled with -ffast-math or -ffinite-math-only (its NaN checks would vanish)"
#endif

/* the sources' SHA-256 prefix this build was made from */
extern const char *const gvs_source_id_str;

#ifdef GVS_REAL_FLOAT
typedef float gvs_real;
#else
typedef double gvs_real;
#endif

/* the tables' index arrays: int32 (the Python binding's), or int16 in an exported build whose indices all fit
 * (GVS_INDEX16, set by the export's Makefile: half the flash of the index tables) */
#ifdef GVS_INDEX16
typedef int16_t gvs_idx;
#else
typedef int32_t gvs_idx;
#endif

/* the bilinear conductance tables (t2_table): gvs_real, or int16 steps of a per-table scale (t2_scale) in an
 * exported float build (GVS_T2_Q16, set by the export: 9 KB of flash; within 1.5e-5 of each table's largest value) */
#ifdef GVS_T2_Q16
typedef int16_t gvs_t2;
#else
typedef gvs_real gvs_t2;
#endif
"""

HEADER_FUNCTIONS = """/* 0 when the tables fit the structs, else GVS_BAD_TABLES. */
int gvs_check_tables(const gvs_tables *tb);     /* also GVS_BAD_TABLES when a build's NaN checks do not work */

/* One 0.1 s step of one vehicle, in place. jump_done: the host has propagated the state over the forward time
 * jump this step's t_s shows (count it and step); 0: return GVS_NEED_JUMP first. ttl: filled when a refresh of the
 * time to limit is due after this step (may be NULL). Returns GVS_OK, GVS_SKIPPED (time went backwards: nothing
 * integrated, outputs repeat the state), GVS_NEED_JUMP or GVS_BAD_TABLES. */
int gvs_step(const gvs_tables *tb, const gvs_vehicle *veh, gvs_state *st, const gvs_inputs *in, int jump_done,
             gvs_outputs *out, gvs_ttl_point *ttl);

/* The time to limit [s] of every published component (0: at or above its warning limit now; +inf: not within
 * GVS_TTL_HORIZON_S; NaN: the held system has no finite steady state, or tables without the time to limit's,
 * ldl_nnz 0) from a due refresh's operating point p, into ttl_s[tb->n_pub].
 * Returns GVS_OK, or GVS_BAD_TABLES. Cost: one sparse factorisation and solve, then march steps (from
 * GVS_MARCH_H0_S, each GVS_MARCH_RATIO times longer, to the horizon) of one factorisation and three solves each
 * until every component has crossed or provably cannot. */
int gvs_ttl_refresh(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real *ttl_s);

/* Steps over a table of inputs (n_steps rows) for one vehicle, writing one gvs_outputs per step, or with keep
 * (n_steps flags; NULL: every step) only for the steps whose flag is set, one after the other (a held replay keeps
 * one step a row: the others' outputs are never written). A step that leaves a due time-to-limit refresh: with
 * stop_on_ttl the run stops after it (the caller refreshes), else the refresh runs in place (gvs_ttl_refresh into
 * st->ttl_s) when ttl is given. Stops before a step that needs a jump propagated; returns the number of steps done
 * (the caller resumes from there). *status: the last gvs_step return code. */
int64_t gvs_run(const gvs_tables *tb, const gvs_vehicle *veh, gvs_state *st, const gvs_inputs *in, int64_t n_steps,
                int stop_on_ttl, const int8_t *keep, gvs_outputs *out, gvs_ttl_point *ttl, int *status);

/* One step of n_vehicles vehicles (arrays of states, inputs, outputs, time-to-limit points; jump_done and ttl may
 * be NULL), vehicle parameters veh[v * veh_stride] (stride 0: one set for all). codes[v]: each vehicle's return
 * code (may be NULL). Returns GVS_OK when every vehicle stepped, else the first other code (errors first). */
int gvs_step_batch(const gvs_tables *tb, const gvs_vehicle *veh, int64_t veh_stride, int64_t n_vehicles,
                   gvs_state *st, const gvs_inputs *in, const int8_t *jump_done, gvs_outputs *out,
                   gvs_ttl_point *ttl, int32_t *codes);

/* sizeof of the structs, which = GVS_SIZEOF_* (the binding checks its layouts against them) */
int64_t gvs_sizeof(int which);

#endif
"""

WIDTH = 120


def _comment(text: str, indent: str = "") -> list:
    """``text`` as a C comment wrapped to WIDTH."""
    words, lines, line = text.split(), [], indent + "/*"
    for w in words:
        if len(line) + 1 + len(w) > WIDTH - 3:
            lines.append(line)
            line = indent + " *"
        line += " " + w
    lines.append(line + " */")
    return lines


def _c_number(v) -> str:
    return str(v) if isinstance(v, int) else repr(float(v))


def _constants_text() -> list:
    out = [
        "/* capacities of the plain structs (the tables give the actual sizes; gvs_check_tables() refuses larger "
        "ones);",
        " * an ECU build sets them to the exported variant's sizes (-DGVS_MAX_NODES=61 ...) to save RAM */",
    ]
    for c in CAPACITIES:
        out += [f"#ifndef GVS_{c.name}"] + _comment(c.doc) + [f"#define GVS_{c.name} {c.value}", "#endif"]
    out.append("")
    for c in DEFINES:
        out.append(f"#define GVS_{c.name} {_c_number(c.value)}".ljust(48) + f"/* {c.doc} */")
    out.append("")
    for e in ENUMS:
        body = ", ".join(f"GVS_{n} = {v}" for n, v in e.items)
        out += [f"/* {e.doc} */"] + _wrap_enum(body)
    return out + [""]


def _wrap_enum(body: str) -> list:
    lines, line = [], "enum {"
    for item in body.split(", "):
        if len(line) + len(item) + 4 > WIDTH:
            lines.append(line + ",")
            line = "      "
            line += " " + item
        else:
            line += (" " if line.endswith(("{", "      ")) else ", ") + item
    return lines + [line + " };"]


def _decl(group: list) -> str:
    """One declaration of fields that share their type and shape: ``int32_t n, nl;``, ``const gvs_real *a, *b;``."""
    f = group[0]
    if f.ctype in (PREAL, PIDX, PT2):
        return f"    {f.ctype}" + ", *".join(g.name for g in group) + ";"
    dims = "".join(f"[{d}]" for d in f.shape)
    return f"    {f.ctype} " + ", ".join(g.name + dims for g in group) + ";"


def _group_text(group: list) -> list:
    f = group[0]
    shape = f"({' x '.join(str(d) for d in f.shape)}) " if f.shape and f.ctype in (PREAL, PIDX, PT2) else ""
    note = (shape + (f"[{f.unit}] " if f.unit else "") + f.doc).strip()
    decls, part = [], []
    for g in group:  # long groups: one declaration per line that fits
        if part and len(_decl(part + [g])) > WIDTH:
            decls.append(_decl(part))
            part = []
        part.append(g)
    decls.append(_decl(part))
    if not note:
        return decls
    line = decls[0].ljust(39) + f" /* {note} */"
    return [line] if len(decls) == 1 and len(line) <= WIDTH else _comment(note, "    ") + decls


def _struct_text(s: Struct) -> list:
    out, group = _comment(s.doc) + ["typedef struct {"], []
    for item in s.items + ("",):
        key = None if isinstance(item, str) else item[1:]
        if group and key != group[0][1:]:
            out += _group_text(group)
            group = []
        if isinstance(item, str):
            out += _comment(item, "    ") if item else []
        else:
            group.append(item)
    return out + [f"}} {s.c_name};", ""]


def header_text() -> str:
    """The whole of gvs_kernel.h, generated from this module."""
    banner = [
        "/* GENERATED from firmware_model/onboard/kernel_interface.py: do not edit. Regenerate with",
        f" * `{REGENERATE}`",
        " * (tests/firmware_model/test_kernel_interface.py compares). */",
    ]
    lines = banner + HEADER_TOP.splitlines() + [""] + _constants_text()
    for s in STRUCTS:
        lines += _struct_text(s)
    return "\n".join(lines) + "\n" + HEADER_FUNCTIONS


def first_difference(current: str, generated: str) -> str | None:
    """None when equal, else a sentence naming the first differing line of the header and how to regenerate."""
    if current == generated:
        return None
    a, b = current.splitlines(), generated.splitlines()
    for i, (x, y) in enumerate(zip(a, b)):
        if x != y:
            return (
                f"{HEADER_PATH.name} line {i + 1} differs from what kernel_interface.py generates: has {x!r}, "
                f"expected {y!r}; do not edit the header: change kernel_interface.py and run `{REGENERATE}`"
            )
    n = min(len(a), len(b))
    return (
        f"{HEADER_PATH.name} has {len(a)} lines, kernel_interface.py generates {len(b)} (first difference at line "
        f"{n + 1}); run `{REGENERATE}`"
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m firmware_model.onboard.kernel_interface",
        description="Generate the C kernel's header from its one description.",
    )
    ap.add_argument("--write", action="store_true", help="write firmware_model/onboard/c/gvs_kernel.h")
    ap.add_argument("--check", action="store_true", help="exit 1 when the header is not what would be generated")
    args = ap.parse_args(argv)
    text = header_text()
    if args.write:
        HEADER_PATH.write_text(text)
        print(f"wrote {HEADER_PATH.name} ({len(text.splitlines())} lines)")
        return 0
    if args.check:
        diff = first_difference(HEADER_PATH.read_text(), text)
        print(diff or f"{HEADER_PATH.name} is current")
        return 1 if diff else 0
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
