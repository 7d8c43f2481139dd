"""One progress bar for every long offline run (plant, replay, diagnosis, benchmarks), from tqdm.

``progress(total, desc, enabled)`` returns a tqdm bar on stderr. ``enabled=None`` (the default) shows it only when
stderr is a terminal, so logs, pipes and CI stay clean; ``True`` forces it, ``False`` silences it. Use it as a context
manager and call ``update(n)``; ``set_postfix_str`` for a short status.
"""

from __future__ import annotations

import sys

from tqdm import tqdm


class _Bar(tqdm):
    # no monitor thread: tqdm starts one for every bar and a disabled bar never stops it; a stray thread makes
    # forking unsafe (worker processes started by fork)
    monitor_interval = 0


def progress(total: int | None, desc: str, enabled: bool | None = None, unit: str = "it", **kw) -> tqdm:
    """A tqdm bar on stderr, shown when ``enabled`` or (None) when stderr is a terminal."""
    show = sys.stderr.isatty() if enabled is None else bool(enabled)
    return _Bar(
        total=total,
        desc=desc,
        unit=unit,
        disable=not show,
        file=sys.stderr,
        leave=False,
        dynamic_ncols=True,
        mininterval=0.2,
        **kw,
    )
