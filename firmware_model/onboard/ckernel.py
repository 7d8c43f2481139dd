"""The compiled onboard step: loading the C99 kernel (firmware_model/onboard/c/) and its plain structs in Python.

Binding: ctypes (standard library). The kernel's interface is a handful of plain C structs and three functions, so a
ctypes mirror is short, needs no compiler at import time and no build-time dependency (cffi would be one more
package on every ECU-side tool chain; an extension module would tie the kernel to the CPython ABI, and the same
kernel is meant for ECUs and FMUs that have no Python). ctypes costs ~1 us per call: offline paths step a whole
table in one call (:func:`firmware_model.onboard.compiled.run_table`), a batch of vehicles in one call per step.

Where the library comes from, first found wins (:func:`load`):

1. ``GVS_KERNEL_LIB``: a path to a built library (e.g. a float build for tests);
2. the library ``pip install`` built next to this module (setup.py: an optional extension; without a compiler the
   install still succeeds and the numpy step runs);
3. a build of the current sources in the user's cache directory, compiled on first use when a C compiler (``cc``,
   ``gcc`` or ``clang``) is on the PATH.

A library built from other sources than the ones shipped (a stale build) is never loaded: every build carries the
SHA-256 of its sources (``gvs_source_id``). Set ``GVS_CORE=numpy`` to never load it.
"""
from __future__ import annotations

import ctypes as C
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from functools import lru_cache
from pathlib import Path

import numpy as np

SOURCE_DIR = Path(__file__).resolve().parent / "c"
SOURCES = ("gvs_kernel.c", "gvs_kernel.h")
#: flags of every build: strict C99, warnings as errors, no fast-math (parity with numpy needs IEEE arithmetic)
CFLAGS = ("-std=c99", "-O3", "-fPIC", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-fno-fast-math")
#: capacities of the C structs (gvs_kernel.h)
MAX_NODES, MAX_LINKS, MAX_SRC, MAX_BC, MAX_STREAMS = 96, 192, 32, 8, 32
N_PUB, N_INPUTS, N_REJECT = 28, 8, 13
#: return codes of gvs_step
OK, SKIPPED, NEED_JUMP, BAD_TABLES = 0, 1, 2, -1


class CoreUnavailable(RuntimeError):
    """The compiled core cannot be used here (the message says why)."""


def source_id() -> str:
    """SHA-256 (first 16 hex digits) of the kernel's sources: a build records it, a loader checks it."""
    h = hashlib.sha256()
    for name in SOURCES:
        h.update((SOURCE_DIR / name).read_bytes())
    return h.hexdigest()[:16]


# --- the structs (the same fields, in the same order, as gvs_kernel.h) --------------------------------------

_I32, _I64, _I8, _F64 = C.c_int32, C.c_int64, C.c_int8, C.c_double
_PI = C.POINTER(C.c_int32)
#: gvs_tables, field by field: "i" int32, "r" real, "pr" pointer to real, "pi" pointer to int32
TABLE_FIELDS = (
    [(k, "i") for k in ("n", "nl", "nb", "ns", "npw", "n2", "nc", "ne", "nrad", "nst", "nsrc_nz", "nT", "ncol", "n_u",
                        "nT2", "n_u_churn", "nx", "n_mesh", "n_bear", "n_speed", "n_gears", "i_oil", "i_ambient",
                        "i_coolant", "cooler_code", "gear_min", "oil_mode_measured", "ttl_every")]
    + [("dt_over_C", "pr"), ("link_a", "pi"), ("link_b", "pi"), ("G_const", "pr"), ("published_index", "pi"),
       ("pw_link", "pi"), ("pw_col", "pi"), ("pw_effect", "pi"), ("pw_exp", "pr"), ("pw_gear_coef", "pr"),
       ("pw_phi", "pr"), ("t2_link", "pi"), ("t2_speed_coef", "pr"), ("t2_w_max", "pr"), ("t2_table", "pr"),
       ("t2_stride", "i"), ("cyl_link", "pi"), ("cyl_speed_coef", "pr"), ("cyl_c", "pr"), ("cyl_ln_rp2", "pr"),
       ("ef_link", "pi"), ("ef_effect", "pi"), ("ef_mcp", "pr"), ("ef_alpha", "pr"), ("ef_beta", "pr"),
       ("rad_link", "pi"), ("rad_node", "pi"), ("rad_bc", "pi"), ("rad_area_eps", "pr"), ("t2_stream_term", "pi"),
       ("stream_node", "pi"), ("prop", "pr"), ("T_grid0_c", "r"), ("T_grid_step_k", "r"), ("speed_coef", "pr"),
       ("mesh_torque", "pr"), ("mesh_omega2", "pr"), ("mesh_x0", "pr"), ("mesh_phi", "pr"), ("mesh_roll_k", "pr"),
       ("mesh_heat_sf", "pr"), ("mesh_roll_lt_min", "pr"), ("bear_speed", "pr"), ("bear_c", "pr"), ("bear_load", "pr"), ("needle_rel", "pr"),
       ("needle_c", "pr"), ("sync_coef", "pr"), ("pump_coef", "pr"), ("churn_table", "pr")]
    + [(k, "r") for k in ("churn_w_max", "churn_heat_sf", "x_step", "ln10")]
    + [("src_nz_src", "pi"), ("src_nz_node", "pi"), ("src_nz_w", "pr"), ("lag_gain", "r"), ("lag_tau_over_dt", "r")]
    + [(k, "r") for k in ("flow_m3_per_rad", "liquid_hA_ref", "liquid_Qmax_cool", "liquid_Qmax_heat", "air_hA_ref",
                          "air_Qmax_cool", "thermostat_open_c", "thermostat_full_c", "ref_ls_speed",
                          "ref_engine_speed", "exp_inner", "exp_outer", "air_flow_min_frac", "air_ref_speed_kmh",
                          "air_flow_max_rel", "inlet_drop_max_k", "default_vkmh")]
    + [("recirc_v_kmh", "pr"), ("recirc_dT_k", "pr"), ("n_recirc", "i")]
    + [(k, "r") for k in ("sigma", "kelvin", "rpm_per_rad_s", "rad_s_per_rpm", "palmgren_min", "min_speed", "ln_04",
                          "ln_0238", "ln_re_lam", "ln_re_bridge", "ln_1e6", "rad_T_lo_c", "rad_T_hi_c",
                          "speed_bin_min", "ln_speed_bin", "oil_bin_c", "dt_s")]
    + [(k, "pr") for k in ("input_lo", "input_hi", "clamp_lo", "clamp_hi", "aux_default")]
    + [(k, "r") for k in ("hold_s", "drive_frozen_s", "oil_frozen_s", "oil_frozen_drift_c", "oil_step_c",
                                          "clock_reset_s")]
    + [(k, "pr") for k in ("warning_c", "critical_c", "hysteresis_k", "warning_rest_c")]
    + [("debounce_s", "r"), ("lead_s", "r")]
    + [("C_j_per_k", "pr")] + [(k, "pi") for k in ("ldl_perm", "ldl_pos", "ldl_col_ptr", "ldl_row", "ldl_link_slot",
                                                   "ldl_upd_ptr", "ldl_upd_target", "ldl_upd_a", "ldl_upd_b",
                                                   "ttl_relin")]
    + [(k, "i") for k in ("ldl_nnz", "ldl_nupd", "ttl_sump_model", "ttl_relinearise")])


def structs(real) -> dict:
    """The ctypes mirrors of the kernel's structs and the numpy dtypes of its records, for a real type (c_double or
    c_float)."""
    R = real
    kinds = {"i": _I32, "r": R, "pr": C.POINTER(R), "pi": _PI}

    class Tables(C.Structure):
        _fields_ = [(name, kinds[k]) for name, k in TABLE_FIELDS]

    class Vehicle(C.Structure):
        _fields_ = [("src_scale", R * MAX_SRC)] + [(k, R) for k in (
            "teeth_oil_h", "planet_oil_h", "housing_air_h", "cooler_scale", "thermostat_offset_c", "retarder_frac",
            "churn_scale", "needle_scale")] + [("T_bc_default_c", R * MAX_BC)]

    class State(C.Structure):
        _fields_ = [("T_c", (R * MAX_NODES) * 2), ("lag_w", R * MAX_SRC), ("hold", R * N_INPUTS),
                    ("age_s", R * N_INPUTS), ("same_s", R * N_INPUTS), ("raw_prev", R * N_INPUTS), ("oil_ref_c", R),
                    ("pending_s", R * N_PUB), ("ttl_s", R * N_PUB), ("t_last_s", _F64), ("k", _I64),
                    ("rejects", _I64 * N_REJECT), ("memo_G", R * MAX_LINKS), ("memo_Gs", R * MAX_STREAMS),
                    ("memo_omega_q", R), ("memo_T_q", R), ("memo_row", _I32), ("memo_valid", _I32),
                    ("level", _I8 * N_PUB)]

    class Inputs(C.Structure):
        _fields_ = [("raw", _F64 * N_INPUTS), ("t_s", _F64)]

    class Outputs(C.Structure):
        _fields_ = [("T_c", R * N_PUB), ("ttl_s", R * N_PUB), ("model_oil_temp_c", R), ("oil_innovation_c", R),
                    ("rejects", _I64 * N_REJECT), ("valid_flags", _I32), ("frozen_flags", _I32), ("level", _I8 * N_PUB)] + [
            (k, _I8) for k in ("degraded_mode", "speed_valid", "torque_valid", "gear_valid", "oil_valid",
                               "oil_source")]

    class TtlPoint(C.Structure):
        _fields_ = [("T_main_c", R * MAX_NODES), ("src_w", R * MAX_SRC), ("G_w_per_k", R * MAX_LINKS),
                    ("G_streams_w_per_k", R * MAX_STREAMS), ("T_bc_c", R * MAX_BC), ("used", R * N_INPUTS)] + [
            (k, R) for k in ("dT_in_k", "Q_cool_w", "omega_in_rad_s", "T_oil_c", "rho_cp_j_per_m3k")] + [
            (k, _I32) for k in ("due", "measured", "row")]

    out = dict(Tables=Tables, Vehicle=Vehicle, State=State, Inputs=Inputs, Outputs=Outputs, TtlPoint=TtlPoint)
    out.update({f"{k}_dtype": np.dtype(v) for k, v in out.items() if k != "Tables"})
    out["real"] = np.dtype(R)
    return out


# --- finding and loading the library ---------------------------------------------------------------------------

def _cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "gearbox-vsensor"


def compiler() -> str | None:
    """The C compiler on the PATH (CC, cc, gcc, clang), or None."""
    for cc in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if cc and shutil.which(cc):
            return cc
    return None


def build(out: Path, real: str = "double", extra_flags: tuple = (), cc: str | None = None) -> Path:
    """Compile the kernel into the shared library ``out`` (real "double" or "float"); raises CoreUnavailable with
    the compiler's message when that fails."""
    cc = cc or compiler()
    if cc is None:
        raise CoreUnavailable("no C compiler (cc, gcc or clang) on the PATH")
    defs = [f'-DGVS_SOURCE_ID="{source_id()}"'] + (["-DGVS_REAL_FLOAT"] if real == "float" else [])
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=out.parent) as tmp:
        tmp_lib = Path(tmp) / out.name
        cmd = [cc, *CFLAGS, *extra_flags, "-shared", *defs, str(SOURCE_DIR / "gvs_kernel.c"), "-o", str(tmp_lib),
               "-lm"]
        res = subprocess.run(cmd, capture_output=True, text=True)
        if res.returncode != 0:
            raise CoreUnavailable(f"the C kernel did not compile ({' '.join(cmd[:2])} ...): "
                                  f"{(res.stderr or res.stdout).strip()[:400]}")
        os.replace(tmp_lib, out)              # atomic: a concurrent loader never sees half a library
    return out


def _open(path: Path, real: str):
    lib = C.CDLL(str(path))
    try:
        built_from = C.c_char_p.in_dll(lib, "gvs_source_id_str").value.decode()
    except (ValueError, AttributeError):
        built_from = "?"
    if built_from != source_id():
        raise CoreUnavailable(f"{path.name} was built from other sources (stale build)")
    S = structs(C.c_float if real == "float" else C.c_double)
    lib.gvs_sizeof.restype = C.c_int64
    lib.gvs_sizeof.argtypes = [C.c_int]
    sizes = {k: lib.gvs_sizeof(i) for i, k in enumerate(("Tables", "Vehicle", "State", "Inputs", "Outputs",
                                                             "TtlPoint"))}
    for k, size in sizes.items():
        if C.sizeof(S[k]) != size:
            raise CoreUnavailable(f"{path.name}: struct {k} is {size} bytes in C, {C.sizeof(S[k])} in the binding")
    if lib.gvs_sizeof(6) != S["real"].itemsize:
        raise CoreUnavailable(f"{path.name} is not a {real} build")
    P = C.POINTER
    lib.gvs_step.argtypes = [P(S["Tables"]), P(S["Vehicle"]), C.c_void_p, C.c_void_p, C.c_int, C.c_void_p,
                             C.c_void_p]
    lib.gvs_step.restype = C.c_int
    lib.gvs_run.argtypes = [P(S["Tables"]), P(S["Vehicle"]), C.c_void_p, C.c_void_p, C.c_int64, C.c_int,
                            C.c_void_p, C.c_void_p, P(C.c_int)]
    lib.gvs_run.restype = C.c_int64
    lib.gvs_step_batch.argtypes = [P(S["Tables"]), C.c_void_p, C.c_int64, C.c_int64, C.c_void_p, C.c_void_p,
                                   C.c_void_p, C.c_void_p, C.c_void_p, C.c_void_p]
    lib.gvs_step_batch.restype = C.c_int
    lib.gvs_ttl_refresh.argtypes = [P(S["Tables"]), C.c_void_p, C.c_void_p, C.c_void_p]
    lib.gvs_ttl_refresh.restype = C.c_int
    return lib, S


def _installed_library() -> Path | None:
    """The library pip built next to this module (setup.py), if any."""
    here = Path(__file__).resolve().parent
    for cand in sorted(here.glob("_gvs_kernel*")):
        if cand.suffix in (".so", ".pyd", ".dylib"):
            return cand
    return None


@lru_cache(maxsize=4)
def load(real: str = "double"):
    """``(lib, structs)`` of the compiled kernel, or raises CoreUnavailable saying why (see the module doc)."""
    if os.environ.get("GVS_CORE", "").lower() == "numpy":
        raise CoreUnavailable("GVS_CORE=numpy")
    reasons = []
    env = os.environ.get("GVS_KERNEL_LIB")
    candidates = [Path(env)] if env else []
    if real == "double":
        inst = _installed_library()
        if inst is not None:
            candidates.append(inst)
    suffix = ".dll" if sys.platform == "win32" else ".so"
    cached = _cache_dir() / f"gvs_kernel_{real}_{source_id()}{suffix}"
    candidates.append(cached)
    for path in candidates:
        if not path.exists():
            continue
        try:
            return _open(path, real)
        except (OSError, CoreUnavailable) as exc:
            reasons.append(str(exc))
    try:
        return _open(build(cached, real), real)
    except (OSError, CoreUnavailable) as exc:
        reasons.append(str(exc))
    raise CoreUnavailable("; ".join(reasons))


def availability(real: str = "double") -> tuple[bool, str]:
    """(usable, one line saying which library or why not)."""
    try:
        lib, _ = load(real)
    except CoreUnavailable as exc:
        return False, f"numpy step (the compiled core is unavailable: {exc})"
    return True, f"C kernel ({real}, {Path(lib._name).name})"


if __name__ == "__main__":     # python -m firmware_model.onboard.ckernel: build (if needed) and say which core
    print(availability()[1])
