"""Saying that numba is compiling: one notice, for the API and the command line alike.

A first call of a kernel compiles it (seconds to minutes on a busy machine) and later calls
load it from the cache (:mod:`engine._jit`). So that a first call does not look like a hang,
a compile that lasts longer than :data:`COMPILE_DELAY` is announced on stderr, with the time
it has taken so far, and when it ends, how long it took::

    conesurvey: compiling kernels (first run only, cached)  0:01
    conesurvey: compiled kernels in 0:42 (cached for later runs)

In a Python session this comes from numba's own compile events (a listener registered at
import: any kernel any API call compiles is announced, once, when it is compiled; a kernel
loaded from the cache or compiled already says nothing). ``conesurvey run`` announces the
first block of a run the same way, through :func:`announcing` (its progress reporter's stream
and label; a slow load from the cache is announced there too), and the listener keeps quiet
meanwhile. :func:`set_compile_notices` (``engine.set_compile_notices(False)``) or the
environment variable ``CONESURVEY_COMPILE_NOTICES=0`` silences the API's notices.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import sys
import threading
import time
from collections.abc import Iterator
from typing import TextIO

from numba.core import event

__all__ = [
    "COMPILE_DELAY",
    "COMPILE_MESSAGE",
    "LOAD_MESSAGE",
    "Notice",
    "announcing",
    "format_duration",
    "quiet",
    "set_compile_notices",
    "settle",
]

#: Seconds a compile may take before it is announced (a load from numba's cache takes less).
COMPILE_DELAY = 1.0
#: Seconds between two compiles that make them one notice (an API call compiles several).
GRACE = 1.0
COMPILE_MESSAGE = "compiling kernels (first run only, cached)"
LOAD_MESSAGE = "loading the compiled kernels from the cache"
#: The compile message where the cache is off.
UNCACHED_MESSAGE = "compiling kernels (not cached: CONESURVEY_NO_CACHE is set)"
LABEL = "conesurvey"
#: Whether compiled kernels are kept in the cache (:func:`listen`).
KEPT = True


def format_duration(seconds: float) -> str:
    """``h:mm:ss`` or ``m:ss`` for a duration [s]; ``?`` if unknown (NaN, inf, negative)."""
    if not (seconds >= 0.0 and seconds < float("inf")):
        return "?"
    s = int(round(seconds))
    h, rest = divmod(s, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class Notice:
    """One announced wait: once it has lasted ``delay`` s, a line saying so with the elapsed
    time (on a terminal, ``tty``, redrawn every second; elsewhere one line), and at
    :meth:`stop` how long it took. ``cached``: the wait is a load from the cache."""

    def __init__(
        self,
        stream: TextIO | None = None,
        *,
        label: str = LABEL,
        tty: bool | None = None,
        cached: bool = False,
        delay: float | None = None,
    ) -> None:
        self.stream = sys.stderr if stream is None else stream
        if tty is None:
            isatty = getattr(self.stream, "isatty", None)
            tty = bool(isatty()) if isatty is not None else False
        self.tty, self.label, self.cached = tty, label, cached
        self.delay = COMPILE_DELAY if delay is None else delay
        self.kept = KEPT
        self.message = LOAD_MESSAGE if cached else COMPILE_MESSAGE if KEPT else UNCACHED_MESSAGE
        self._stop = threading.Event()
        self._shown = threading.Event()
        self._held = threading.Event()  # between two compiles: nothing to show meanwhile
        self._thread: threading.Thread | None = None
        self.began = time.monotonic()

    def line(self) -> str:
        return f"{self.label}: {self.message}  {format_duration(time.monotonic() - self.began)}"

    def hold(self) -> None:
        """Nothing is being waited for now (a compile ended; another may follow)."""
        self._held.set()

    def go(self) -> None:
        """The wait goes on (another compile started)."""
        self._held.clear()

    def _tick(self) -> None:
        wait = self.delay
        while not self._stop.wait(wait):
            if self._held.is_set():
                wait = 0.1
                continue
            if self.tty:
                self._say("\r" + self.line())
            elif not self._shown.is_set():
                self._say(self.line() + "\n")
            self._shown.set()
            wait = 1.0

    def start(self) -> None:
        self.began = time.monotonic()
        self._thread = threading.Thread(target=self._tick, name="conesurvey-compiling", daemon=True)
        self._thread.start()

    def stop(self, until: float | None = None) -> float:
        """End the wait (it ended at ``until``, a ``time.monotonic()``; default now); say how
        long it took if it was announced. Returns its seconds."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        took = (time.monotonic() if until is None else until) - self.began
        if self._shown.is_set():
            span = format_duration(took)
            done = (
                f"{self.label}: loaded the kernels in {span}"
                if self.cached
                else f"{self.label}: compiled kernels in {span}"
                + (" (cached for later runs)" if self.kept else "")
            )
            self._say(("\r" + done.ljust(len(self.line())) if self.tty else done) + "\n")
        return took

    def _say(self, text: str) -> None:
        """Write to the stream, unless it is closed by now (a test runner's captured stream,
        a pipe whose reader left): a notice is never worth an error."""
        try:
            self.stream.write(text)
            self.stream.flush()
        except (ValueError, OSError):  # "I/O operation on closed file", EPIPE
            pass


class _Compiles(event.Listener):
    """numba's compile events, announced as one :class:`Notice` on stderr: from the start of
    an outermost compile (a kernel's callees compile inside it) to the end of the last of the
    compiles that follow each other within :data:`GRACE` s (one API call compiles several
    entry points in a row: one notice, with their time together)."""

    def __init__(self) -> None:
        self.enabled = os.environ.get("CONESURVEY_COMPILE_NOTICES", "1") not in ("0", "false")
        self.quiet = 0  # regions that announce themselves (:func:`announcing`) or are quiet
        self._lock = threading.Lock()
        self._depth = threading.local()
        self._active = 0
        self._notice: Notice | None = None
        self._ended = 0.0  # when the last outermost compile ended
        self._generation = 0  # a compile that starts cancels the close pending before it

    def on_start(self, ev: event.Event) -> None:
        depth = getattr(self._depth, "n", 0)
        self._depth.n = depth + 1
        if depth:
            return
        with self._lock:
            self._active += 1
            self._generation += 1
            if self._notice is not None:
                self._notice.go()
            elif self.enabled and not self.quiet:
                self._notice = Notice()
                self._notice.start()

    def on_end(self, ev: event.Event) -> None:
        depth = getattr(self._depth, "n", 0)
        if depth == 0:
            return  # it started before the listener was registered
        self._depth.n = depth - 1
        if depth > 1:
            return
        with self._lock:
            self._active -= 1
            if self._active or self._notice is None:
                return
            self._ended = time.monotonic()
            self._notice.hold()
            closer = threading.Timer(GRACE, self._close, args=(self._generation,))
            closer.daemon = True  # at exit, :meth:`flush` says it instead
            closer.start()

    def _close(self, generation: int | None = None) -> None:
        """End the notice if no compile started since the one that ended (``generation``;
        None: in any case, the interpreter is exiting)."""
        with self._lock:
            if self._notice is None or self._active and generation is not None:
                return
            if generation is not None and generation != self._generation:
                return
            notice, self._notice = self._notice, None
        notice.stop(until=self._ended or None)

    def flush(self) -> None:
        """At exit: say how long the last compile took, without waiting for the grace (unless
        the stream is closed by then, as a test runner's captured stream is)."""
        try:
            self._close(None)
        except (ValueError, OSError):  # "I/O operation on closed file"
            pass

    def settle(self) -> None:
        """If no compile is running, end the notice now (not after the grace)."""
        with self._lock:
            if self._active:
                return
            generation = self._generation
        self._close(generation)


_LISTENER = _Compiles()
_LISTENING = False
atexit.register(_LISTENER.flush)


def listen(kept: bool) -> None:
    """Announce numba's compiles from now on (once per process: :mod:`engine._jit` calls it);
    ``kept``: whether compiled kernels are cached (else the notices say they are not)."""
    global KEPT, _LISTENING
    KEPT = kept
    if not _LISTENING:
        event.register("numba:compile", _LISTENER)
        _LISTENING = True


def settle() -> None:
    """Say now how long the compiles that just ended took, if they were announced (before a
    line that should follow it: a progress reporter's)."""
    _LISTENER.settle()


def set_compile_notices(enabled: bool) -> bool:
    """Whether the API says on stderr that it is compiling (module docstring); returns the
    setting it replaces. ``engine.set_compile_notices(False)`` silences it."""
    if not isinstance(enabled, bool):
        raise ValueError(f"enabled must be True or False; got {enabled!r}")
    before, _LISTENER.enabled = _LISTENER.enabled, enabled
    return before


@contextlib.contextmanager
def quiet() -> Iterator[None]:
    """No compile notice inside (a caller that shows no progress: ``conesurvey run -q``)."""
    _LISTENER.quiet += 1
    try:
        yield
    finally:
        _LISTENER.quiet -= 1


@contextlib.contextmanager
def announcing(notice: Notice) -> Iterator[Notice]:
    """Around a wait that may compile (a run's first block): ``notice`` announces it, whether
    it compiles or loads from the cache; numba's compile events inside are not announced
    twice."""
    with quiet():
        notice.start()
        try:
            yield notice
        finally:
            notice.stop()
