"""Progress and cancellation for long work (loading a scene) without any UI dependency.

The window hands a :class:`Progress` whose callback posts to the UI thread and whose cancel flag
the dialog's Cancel button sets; the CLI hands one that drives a terminal bar. Work calls
:meth:`Progress.report` at its natural steps (a mesh, a texture); a cancelled load stops there
with :class:`LoadCancelled`, so nothing half-built ever reaches the caller.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

ReportFn = Callable[[float, str], None]


class LoadCancelled(Exception):
    """The user cancelled the work; not an error, nothing to show."""


class Progress:
    """A fraction in [0, 1] and a short text for the person waiting, plus a cancel flag.

    :meth:`span` gives a child that maps its own 0..1 into a slice of the parent, so a stage
    (reading, building, finding where to stand) reports without knowing the whole plan.
    """

    def __init__(
        self,
        report: ReportFn | None = None,
        cancel: threading.Event | None = None,
        *,
        start: float = 0.0,
        end: float = 1.0,
    ) -> None:
        self._report = report
        self.cancel = cancel if cancel is not None else threading.Event()
        self._start = start
        self._end = end

    def report(self, fraction: float, text: str) -> None:
        """Tell how far the work is; raises :class:`LoadCancelled` once cancel is set."""
        self.check()
        if self._report is not None:
            f = min(max(float(fraction), 0.0), 1.0) if fraction == fraction else 0.0
            self._report(self._start + (self._end - self._start) * f, text)

    def check(self) -> None:
        if self.cancel.is_set():
            raise LoadCancelled("cancelled")

    def span(self, start: float, end: float) -> Progress:
        """A child covering [start, end] of this one's range (both fractions of this range)."""
        width = self._end - self._start
        return Progress(
            self._report,
            self.cancel,
            start=self._start + width * start,
            end=self._start + width * end,
        )
