"""OUT/report.md of `fleet --columns` (docs/real-data.md, "The fleet on SCADA"): what a reliability engineer reads
first, the flags with their reasons, then each unit's fitted values period by period, the units or periods not
judged and why, and what was left out (files, channels, stuck readings). The Parquet tables under OUT/health hold the
same and more; this is their summary in words (the trucks' fleet writes its own, tools.fleet.report)."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

from tools.scada.fleet import EFFECTS, PeriodFit, in_range

#: the effects in a reader's words (columns of the per-unit tables)
EFFECT_WORDS = {"bearing_loss_scale": "bearing losses [x nominal]", "cooler_effectiveness_scale": "cooler [x nominal]"}


def _cell(text) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _value(f: PeriodFit, eid: str) -> str:
    """A fitted value with its standard error, '-' where the period does not identify it, '(out of range)' marked."""
    v, se = f.values.get(eid, math.nan), f.se.get(eid, math.inf)
    if not (math.isfinite(v) and math.isfinite(se)):
        return "-"
    mark = "" if in_range(f, eid) else " (outside its plausible range)"
    return f"{v:.2f} +- {se:.2f}{mark}"


def report_lines(
    fits: Sequence[PeriodFit],
    flags: Sequence,
    not_judged: dict,
    left_out: Sequence[tuple[str, str]],
    kind: str,
    max_rows: int = 60,
) -> list[str]:
    """The report's lines: ``flags`` (tools.fleet.health.Flag), ``not_judged`` (unit -> why it or some of its periods
    were not judged, '' when judged throughout), ``left_out`` ((files, sentence) of files, units or channels not
    used in whole or in part), ``kind`` ("unit-months" or "unit-periods")."""
    units = sorted({f.unit for f in fits} | set(not_judged))
    lines = [
        "# Fleet report (SCADA)",
        "",
        f"{len({f.unit for f in fits})} units fitted, {len(fits)} {kind}; {len(flags)} flagged. Each unit's effects "
        "are fitted per period with the onboard model and judged against its siblings' median (docs/real-data.md, "
        '"The fleet on SCADA"): a unit is flagged when it drifts from its own baseline against them for two '
        "periods.",
        "",
        f"## Flags ({len(flags)})",
        "",
    ]
    if flags:
        lines += ["| unit | effect | from the period of | what it means, the figures |", "|---|---|---|---|"]
        lines += [f"| {_cell(f.vehicle)} | {f.effect} | {f.start} | {_cell(f.reason)} |" for f in flags]
    else:
        lines.append("None: no unit drifted from its siblings beyond its intervals for two periods.")
    lines.append("")
    said = {u: w for u, w in not_judged.items() if w}
    if said:
        lines += [f"## Not judged, in whole or in part ({len(said)})", ""]
        lines += [f"- {_cell(u)}: {_cell(w)}" for u, w in sorted(said.items())]
        lines.append("")
    if left_out:
        lines += [f"## Left out, in whole or in part ({len(left_out)})", "", "| files | why |", "|---|---|"]
        lines += [
            f"| {_cell(', '.join(os.path.basename(p) for p in str(files).split(', '))[:120])} | {_cell(why)} |"
            for files, why in left_out
        ]
        lines.append("")
    lines += ["## Fitted values per unit", ""]
    for u in units:
        mine = sorted((f for f in fits if f.unit == u), key=lambda f: f.period)
        lines += [f"### {u} ({len(mine)} periods fitted)", ""]
        if not mine:
            lines += ["No period fitted.", ""]
            continue
        lines += [
            "| period from | rows | " + " | ".join(EFFECT_WORDS.get(e, e) for e in EFFECTS) + " | residual RMS [K] |",
            "|---|---:|" + "---:|" * len(EFFECTS) + "---:|",
        ]
        lines += [
            f"| {f.start} | {f.rows} | " + " | ".join(_value(f, e) for e in EFFECTS) + f" | {f.rms_c:.2f} |"
            for f in mine[-max_rows:]
        ]
        if len(mine) > max_rows:
            lines.append(f"\n(the last {max_rows} of {len(mine)}; all in health/effects.parquet)")
        lines.append("")
    return lines


def write_report(path: str | os.PathLike, *args, **kwargs) -> Path:
    """Write :func:`report_lines` to ``path`` atomically (a temporary file, then renamed); returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text("\n".join(report_lines(*args, **kwargs)) + "\n")
    os.replace(tmp, path)
    return path
