"""The files a command reads and writes, checked before any work: an output that is also an input (it would be
destroyed before or after it is read), two outputs on one file (one silently lost), an output whose directory does
not exist or that is a directory, a plot in a format matplotlib cannot write, a CAN log in a format that is not
written. Each is one sentence (InputError), raised before anything is written."""

from __future__ import annotations

import os
from pathlib import Path

from firmware_model.errors import InputError

#: the figure formats the plots are written in (matplotlib's raster and vector backends)
PLOT_SUFFIXES = (
    ".png",
    ".pdf",
    ".svg",
    ".svgz",
    ".jpg",
    ".jpeg",
    ".eps",
    ".ps",
    ".pgf",
    ".tif",
    ".tiff",
    ".webp",
    ".raw",
    ".rgba",
)
#: the formats a run table is written in (tools.runtable)
TABLE_SUFFIXES = (".csv", ".parquet")
#: the formats a CAN log is written in (tools.can.logsynth, python-can's Logger)
CAN_LOG_SUFFIXES = (".log", ".asc", ".blf")


def check_paths(
    inputs, outputs: dict, plots: tuple = (), makes_dirs: tuple = (), tables: tuple = (), can_logs: tuple = ()
) -> None:
    """``inputs``: (role, path or None) pairs ("the input", "a training file", "the --config"); ``outputs``:
    {option: path or None (not given)}; ``plots``: the output options that are figures; ``makes_dirs``: the output
    options whose directory the command creates; ``tables``: the output options that are run tables (.csv or
    .parquet); ``can_logs``: those that are CAN logs (.log, .asc, .blf). Raises InputError naming the option and
    the file."""
    ins = [(role, p, Path(p).resolve()) for role, p in inputs if p]
    for role, p, full in ins:
        if full.is_dir():
            glob = os.path.join(os.fspath(p), "*")
            raise InputError(f"{role} {p} is a directory, not a file: give the files in it (e.g. {glob})")
    seen: dict = {}
    for opt, p in outputs.items():
        if not p:
            continue
        path = Path(p)
        full = path.resolve()
        for role, _, in_full in ins:
            if full == in_full:
                raise InputError(f"{opt} {p} is also {role}: writing it would destroy that input; choose another path")
        if full in seen:
            raise InputError(
                f"{opt} {p} is also {seen[full]}: one of the two outputs would be lost; choose another path"
            )
        seen[full] = opt
        if full.is_dir():
            raise InputError(f"{opt} {p} is a directory, not a file")
        if opt not in makes_dirs and not full.parent.is_dir():
            raise InputError(f"{opt} {p}: the directory {full.parent} does not exist")
        above = next(a for a in full.parents if a.exists())  # a directory the command would create under it
        if not above.is_dir():
            raise InputError(f"{opt} {p}: {above} is a file, so no directory can be made there")
        if opt in tables and path.suffix.lower() not in TABLE_SUFFIXES:
            raise InputError(
                f"{opt} {p}: a run table is written as .csv or .parquet, not "
                f"{path.suffix or 'a file without an extension'}"
            )
        if opt in can_logs and path.suffix.lower() not in CAN_LOG_SUFFIXES:
            raise InputError(
                f"{opt} {p}: a CAN log is written as .log (candump -L), .asc or .blf, not "
                f"{path.suffix or 'a file without an extension'}"
            )
        if opt in plots and path.suffix and path.suffix.lower() not in PLOT_SUFFIXES:  # none: matplotlib's png
            raise InputError(
                f"{opt} {p}: a figure is written as {', '.join(s[1:] for s in PLOT_SUFFIXES)}, not "
                f"{path.suffix or 'a file without an extension'}"
            )


def figure_path(plot):
    """The file matplotlib writes for a --plot path: the path, or with .png appended when it has no suffix (the
    default format); None for None."""
    return plot and (plot if Path(plot).suffix else f"{plot}.png")
