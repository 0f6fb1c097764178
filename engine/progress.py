"""A small progress reporter for surveys: ``progress(done_points, total_points)``.

On a terminal it draws one line, redrawn in place (at most every 0.1 s)::

    conesurvey [##########..........]  50%    500,000/1,000,000 points   1.2M/s  0:01 left

Elsewhere (a log file, a pipe, CI) it prints plain lines, at most one every 2 s plus the final
one, so logs stay short::

    conesurvey: 500,000/1,000,000 points (50.0%), 1.2M points/s, 0:01 left

Before the first point, a run compiles its numba kernels (or loads them from the cache): inside
:meth:`Progress.compiling` a compile that lasts longer than a cache load is announced, with the
time it has taken so far, so that a first run does not look like a hang::

    conesurvey: compiling kernels (first run only, cached)  0:12

The notice is the API's own (:mod:`engine._compiling`, which also announces any compile of a
Python session), written on the reporter's stream.

A resumed run says so before it computes (:meth:`Progress.resumed`), and its rates and the time
left count only the points computed by this run, not the stored ones::

    conesurvey: resuming: 6 of 18 blocks verified and kept (720 of 2,160 points); 12 to compute
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import sys
import time
from collections.abc import Callable, Iterator
from types import TracebackType
from typing import TextIO

from ._compiling import (  # the one notice of a compile, the API's and the CLI's
    COMPILE_DELAY,
    COMPILE_MESSAGE,
    LOAD_MESSAGE,
    Notice,
    announcing,
    format_duration,
    settle,
)

__all__ = [
    "COMPILE_DELAY",
    "COMPILE_MESSAGE",
    "LOAD_MESSAGE",
    "Progress",
    "format_bytes",
    "format_duration",
    "format_rate",
]

#: Seconds between redraws of the terminal bar.
TTY_INTERVAL = 0.1
#: Seconds between plain log lines.
LOG_INTERVAL = 2.0
BAR_MIN, BAR_MAX = 8, 40


def format_bytes(n: float) -> str:
    """A size [bytes] with an SI prefix: ``950 B``, ``85.8 MB``, ``1.2 TB``."""
    for unit in ("B", "kB", "MB", "GB"):
        if n < 999.5:
            return f"{n:.3g} {unit}"
        n /= 1000
    return f"{n:.3g} TB"


def format_rate(points_per_second: float, unit: str = " points/s") -> str:
    """A rate [points/s] with an SI prefix: ``950``, ``12.3k``, ``1.2M`` points/s."""
    r = points_per_second
    if not r >= 0.0 or r == float("inf"):
        return f"?{unit}"
    for prefix, scale in (("G", 1e9), ("M", 1e6), ("k", 1e3)):
        if r >= scale:
            return f"{r / scale:.3g}{prefix}{unit}"
    return f"{r:.3g}{unit}"


class Progress:
    """Report survey progress on ``stream`` (default ``sys.stderr``); call it as ``(done, total)``.

    ``tty`` forces the terminal bar (True) or log lines (False); by default it follows
    ``stream.isatty()``. ``clock`` returns seconds (``time.monotonic``; injectable for tests).
    Use it as a context manager, or call :meth:`close` at the end to finish the line.
    """

    def __init__(
        self,
        stream: TextIO | None = None,
        *,
        label: str = "conesurvey",
        tty: bool | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.stream = sys.stderr if stream is None else stream
        if tty is None:
            isatty = getattr(self.stream, "isatty", None)
            tty = bool(isatty()) if isatty is not None else False
        self.tty = tty
        self.label = label
        self.clock = clock
        self.interval = TTY_INTERVAL if tty else LOG_INTERVAL
        self.start = clock()
        self._last_shown = -float("inf")
        self._state: tuple[int, int] | None = None
        self._shown_state: tuple[int, int] | None = None
        self._drawn = False  # a bar is on the terminal line
        self._closed = False
        #: Set when the kernels are known to be in numba's cache: the wait is then a load.
        self.kernels_cached = False
        #: Points an earlier run stored (:meth:`resumed`): not counted in the rates.
        self.kept = 0

    def __call__(self, done: int, total: int) -> None:
        """Record that ``done`` of ``total`` points are finished; show it if it is time."""
        if self._closed:
            return
        self._state = (int(done), int(total))
        now = self.clock()
        if done >= total or now - self._last_shown >= self.interval:
            self._show(now)

    def resumed(self, blocks: int, blocks_total: int, points: int, points_total: int) -> None:
        """Say that the run resumes: ``blocks`` of ``blocks_total`` stored blocks (``points``
        of ``points_total`` points) were verified against their checksums and are kept. The
        rates shown from now on count only the points this run computes."""
        self.kept = int(points)
        left = blocks_total - blocks
        self.stream.write(
            f"{self.label}: resuming: {blocks:,} of {blocks_total:,} blocks verified and kept "
            f"({points:,} of {points_total:,} points); {left:,} to compute\n"
        )
        self.stream.flush()

    @contextlib.contextmanager
    def compiling(self, delay: float = COMPILE_DELAY) -> Iterator[None]:
        """Around the kernels' compile: once it has lasted ``delay`` s, say so with the elapsed
        time (on a terminal redrawn every second; in a log one line), and at the end how long it
        took (the API's notice, :class:`engine._compiling.Notice`, on this reporter's stream).
        Rates and the time left count from the end of the compile."""
        notice = Notice(self.stream, label=self.label, tty=self.tty,
                        cached=self.kernels_cached, delay=delay)  # fmt: skip
        try:
            with announcing(notice):
                yield
        finally:
            self.start = self.clock()

    def close(self) -> None:
        """Show the last state if it was not shown, and end the terminal line."""
        if self._closed:
            return
        if self._state is not None and self._state != self._shown_state:
            self._show(self.clock())
        if self._drawn:
            self.stream.write("\n")
            self.stream.flush()
        self._closed = True

    def __enter__(self) -> Progress:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # -- formatting --

    def _numbers(self, now: float, unit: str = " points/s") -> tuple[int, int, float, str, str]:
        assert self._state is not None
        done, total = self._state
        elapsed = max(now - self.start, 0.0)
        fraction = done / total if total > 0 else 1.0
        computed = done - self.kept  # the points of this run (a resumed run kept the others)
        rate = computed / elapsed if elapsed > 0 else float("nan")
        if done >= total:
            when = f"done in {format_duration(elapsed)}"
        elif computed > 0 and elapsed > 0:
            when = f"{format_duration((total - done) / rate)} left"
        else:
            when = "? left"
        return done, total, fraction, format_rate(rate, unit), when

    def log_line(self, now: float) -> str:
        """The plain line for the current state at time ``now``."""
        done, total, fraction, rate, when = self._numbers(now)
        return f"{self.label}: {done:,}/{total:,} points ({100 * fraction:.1f}%), {rate}, {when}"

    def bar_line(self, now: float, columns: int) -> str:
        """The terminal line for the current state, at most ``columns - 1`` characters."""
        done, total, fraction, rate, when = self._numbers(now, unit="/s")
        n = len(f"{total:,}")  # fixed-width fields: the bar keeps its width while it fills
        tail = f" {100 * fraction:3.0f}%  {done:>{n},}/{total:,} points  {rate:>7}  {when:<12}"
        room = columns - 1 - len(self.label) - len(tail) - 3
        if room < BAR_MIN:
            return (self.label + tail)[: columns - 1]
        width = min(room, BAR_MAX)
        filled = int(width * min(max(fraction, 0.0), 1.0))
        return f"{self.label} [{'#' * filled}{'.' * (width - filled)}]{tail}"

    def _columns(self) -> int:
        """Width of the terminal behind the stream (stdout may be redirected), default 80."""
        try:
            columns = os.get_terminal_size(self.stream.fileno()).columns
        except (AttributeError, ValueError, OSError, io.UnsupportedOperation):
            columns = 0
        return columns if columns > 0 else shutil.get_terminal_size((80, 24)).columns or 80

    def _show(self, now: float) -> None:
        settle()  # a compile that ended says so before this line
        if self.tty:
            columns = self._columns()
            line = self.bar_line(now, columns)
            self.stream.write("\r" + line.ljust(columns - 1))
            self._drawn = True
        else:
            self.stream.write(self.log_line(now) + "\n")
        self.stream.flush()
        self._last_shown = now
        self._shown_state = self._state
