"""Build glue: the compiled onboard step (firmware_model/onboard/c/gvs_kernel.c) as an optional library.

Everything else is in pyproject.toml. The kernel is plain C99 loaded with ctypes (no Python API), built here by
``pip install`` when a C compiler is present; without one (or when the build fails) the install still succeeds and
the sensor runs its numpy step, saying so (``gearbox-vsensor --version``).
"""

import hashlib
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

HERE = Path(__file__).resolve().parent
C_DIR = HERE / "firmware_model" / "onboard" / "c"


def source_id() -> str:
    """The kernel's source id as firmware_model.onboard.ckernel.source_id computes it (the loader checks it)."""
    h = hashlib.sha256()
    for name in ("gvs_kernel.c", "gvs_kernel.h"):
        h.update((C_DIR / name).read_bytes())
    return h.hexdigest()[:16]


class OptionalBuildExt(build_ext):
    """A failed kernel build is a warning, not a failed install."""

    def build_extension(self, ext):
        try:
            super().build_extension(ext)
        except Exception as exc:  # noqa: BLE001 - any compiler failure
            print(f"warning: the C kernel was not built ({exc}); the sensor will use its numpy step")


kernel = Extension(
    "firmware_model.onboard._gvs_kernel",
    sources=["firmware_model/onboard/c/gvs_kernel.c"],
    include_dirs=["firmware_model/onboard/c"],
    # GVS_STEP_MEMO: the host's build memoises the last step's heat sources (gvs_kernel.c; an ECU export does not)
    define_macros=[("GVS_SOURCE_ID", f'"{source_id()}"'), ("GVS_STEP_MEMO", "1")],
    extra_compile_args=["-std=c99", "-O3", "-fno-fast-math"],
    optional=True,
)

setup(ext_modules=[kernel], cmdclass={"build_ext": OptionalBuildExt})
