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

from firmware_model.onboard.kernel_interface import SIZEOF_IDS, STRUCT, STRUCTS, ctypes_fields, table_kind

SOURCE_DIR = Path(__file__).resolve().parent / "c"
SOURCES = ("gvs_kernel.c", "gvs_kernel.h")
#: flags of every build: strict C99, warnings as errors, no fast-math (parity with numpy needs IEEE arithmetic)
CFLAGS = ("-std=c99", "-O3", "-fPIC", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-fno-fast-math")
#: a host build memoises the last step's heat sources (gvs_kernel.c, GVS_STEP_MEMO; an ECU export leaves it out);
#: ``extra_flags=("-UGVS_STEP_MEMO",)`` builds without it
HOST_DEFINES = ("-DGVS_STEP_MEMO",)


class CoreUnavailable(RuntimeError):
    """The compiled core cannot be used here (the message says why)."""


def source_id() -> str:
    """SHA-256 (first 16 hex digits) of the kernel's sources: a build records it, a loader checks it."""
    h = hashlib.sha256()
    for name in SOURCES:
        h.update((SOURCE_DIR / name).read_bytes())
    return h.hexdigest()[:16]


# --- the structs: built from the one description (kernel_interface), as the header is -------------------------

#: gvs_tables, field by field: "i" int32, "r" real, "pr" pointer to real, "pi" pointer to int32
TABLE_FIELDS = tuple((f.name, table_kind(f)) for f in STRUCT["Tables"].fields)


def structs(real) -> dict:
    """The ctypes mirrors of the kernel's structs and the numpy dtypes of its records, for a real type (c_double or
    c_float)."""
    out = {s.py_name: type(s.py_name, (C.Structure,), {"_fields_": ctypes_fields(s, real)}) for s in STRUCTS}
    out.update({f"{k}_dtype": np.dtype(v) for k, v in list(out.items()) if k != "Tables"})
    out["real"] = np.dtype(real)
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
        cmd = [cc, *CFLAGS, *HOST_DEFINES, *extra_flags, "-shared", *defs, str(SOURCE_DIR / "gvs_kernel.c"), "-o"]
        cmd += [str(tmp_lib), "-lm"]
        res = subprocess.run(cmd, capture_output=True, text=True)
        if res.returncode != 0:
            raise CoreUnavailable(
                f"the C kernel did not compile ({' '.join(cmd[:2])} ...): {(res.stderr or res.stdout).strip()[:400]}"
            )
        os.replace(tmp_lib, out)  # atomic: a concurrent loader never sees half a library
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
    for i, s in enumerate(STRUCTS):
        size = lib.gvs_sizeof(i)
        if C.sizeof(S[s.py_name]) != size:
            raise CoreUnavailable(
                f"{path.name}: struct {s.c_name} is {size} bytes in C, {C.sizeof(S[s.py_name])} in the binding"
            )
    if lib.gvs_sizeof(SIZEOF_IDS.index("real")) != S["real"].itemsize:
        raise CoreUnavailable(f"{path.name} is not a {real} build")
    P = C.POINTER
    lib.gvs_step.argtypes = [P(S["Tables"]), P(S["Vehicle"]), C.c_void_p, C.c_void_p, C.c_int, C.c_void_p, C.c_void_p]
    lib.gvs_step.restype = C.c_int
    lib.gvs_run.argtypes = [
        P(S["Tables"]),
        P(S["Vehicle"]),
        C.c_void_p,
        C.c_void_p,
        C.c_int64,
        C.c_int,
        C.c_void_p,
        C.c_void_p,
        C.c_void_p,
        P(C.c_int),
    ]
    lib.gvs_run.restype = C.c_int64
    lib.gvs_step_batch.argtypes = [
        P(S["Tables"]),
        C.c_void_p,
        C.c_int64,
        C.c_int64,
        C.c_void_p,
        C.c_void_p,
        C.c_void_p,
        C.c_void_p,
        C.c_void_p,
        C.c_void_p,
    ]
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


if __name__ == "__main__":  # python -m firmware_model.onboard.ckernel: build (if needed) and say which core
    print(availability()[1])
