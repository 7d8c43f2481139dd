"""The time-base warnings of an offline log replay, held until the whole log is judged.

While a log is replayed the service logs each time jump ("frame time jumped forward by ...") and each time-stamp
glitch as it meets them (firmware_model.service.trust.TIME_EVENT marks these records). Only the whole log says
whether they are real logger pauses or the time stamps' unit: a log in milliseconds read as seconds has a "jump"
between almost every two frames, and its one milliseconds finding explains them all. So `replay` holds the
service's records (:class:`HeldLog`) and passes them on after the findings: the time-base ones left out when the
milliseconds finding explains them (the counters and the finding still count them), else the first JUMPS_LOGGED
jumps one by one and one line for the rest, on the frame path as on the whole-log path.
"""

from __future__ import annotations

import logging

from firmware_model.service.columnar import JUMPS_LOGGED, JUMPS_MORE
from firmware_model.service.trust import TIME_EVENT


class HeldLog(logging.Handler):
    """Holds the records a service logs to :attr:`logger` (give it to the service) for ``target`` (the logger they
    are meant for); :meth:`pass_on` passes them on."""

    def __init__(self, target: logging.Logger) -> None:
        super().__init__()
        self.target = target
        self.records: list[logging.LogRecord] = []
        # a logger of its own, outside the hierarchy: nothing it logs reaches a handler before pass_on
        self.logger = logging.Logger(target.name, target.getEffectiveLevel())
        self.logger.addHandler(self)

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)

    def pass_on(self, time_explained: bool, time_jumps: int) -> None:
        """Pass the held records on to the target, in order: without the time-base ones when ``time_explained``
        (a finding explains them all), else with the jumps past the first JUMPS_LOGGED in one line (``time_jumps``:
        the run's count)."""
        jumps = 0
        for record in self.records:
            event = getattr(record, TIME_EVENT, None)
            if event is not None and time_explained:
                continue
            if event == "jump":
                jumps += 1
                if jumps > JUMPS_LOGGED:
                    if jumps == JUMPS_LOGGED + 1:  # the frame path logged them all: the whole-log path's line
                        self.target.warning(JUMPS_MORE, time_jumps - JUMPS_LOGGED, extra={TIME_EVENT: "jumps_more"})
                    continue
            if self.target.isEnabledFor(record.levelno):
                self.target.handle(record)
        self.records.clear()
