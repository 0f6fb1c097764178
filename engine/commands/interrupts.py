"""A Ctrl-C while numba loads or compiles a kernel ends the command as any other Ctrl-C.

numba hands a compiled kernel to and from its disk cache through two callbacks that LLVM calls
from C (llvmlite's object cache hooks). Python runs a SIGINT's handler at the next line of Python
it executes, and after seconds spent in LLVM's C code that line is often inside one of these
callbacks; the KeyboardInterrupt raised there cannot pass through C: ctypes prints it and drops
it. The kernel then loads without the cached object (the Ctrl-C is lost and the run goes on) or
is compiled without it (numba's cache write fails with ``RuntimeError: no compiled object yet``,
exit 1). numba's cache write (index, then data, each through a temporary file it removes only on
an ``Exception``) would also leave a temporary file in the cache if interrupted. A destructor
(``__del__``, run by the garbage collector at any line, llvmlite's own among them) and a weakref
callback swallow a KeyboardInterrupt the same way: Python reports it as "Exception ignored" and
goes on.

:func:`interrupts_outside_compile_hooks` installs a SIGINT handler that, inside those
callbacks, the cache write or a destructor, postpones the interrupt by :data:`RETRY` seconds (and
again, until the main thread is out of them); elsewhere it raises KeyboardInterrupt as Python's
own handler does. A KeyboardInterrupt that some other code swallows anyway reaches
:func:`sys.unraisablehook`; within the block that hook postpones it the same way instead of
printing it. An interrupt still postponed when the block ends is raised there.
"""

from __future__ import annotations

import _thread
import contextlib
import signal
import sys
import threading
from collections.abc import Iterator
from types import FrameType

from llvmlite.binding.executionengine import ExecutionEngine
from numba.core.caching import IndexDataCacheFile

__all__ = ["RETRY", "interrupts_outside_compile_hooks"]

#: Seconds after which a postponed interrupt is delivered again.
RETRY = 0.01

#: Code that must not see a KeyboardInterrupt: LLVM's object cache callbacks and numba's cache
#: write.
_GUARDED = frozenset(
    (
        ExecutionEngine._raw_object_cache_notify.__code__,
        ExecutionEngine._raw_object_cache_getbuffer.__code__,
        IndexDataCacheFile.save.__code__,
    )
)


#: Code names whose exceptions Python swallows: a destructor run by the garbage collector.
_SWALLOWING = frozenset(("__del__",))


def _guarded(frame: FrameType | None) -> bool:
    while frame is not None:
        if frame.f_code in _GUARDED or frame.f_code.co_name in _SWALLOWING:
            return True
        frame = frame.f_back
    return False


class _Postponer:
    """The SIGINT handler of one :func:`interrupts_outside_compile_hooks` block."""

    def __init__(self) -> None:
        self.active = True
        self.pending = False
        self.previous_hook = sys.unraisablehook

    def handle(self, signum: int, frame: FrameType | None) -> None:
        if not _guarded(frame):
            self.pending = False
            raise KeyboardInterrupt
        self.postpone()

    def postpone(self) -> None:
        self.pending = True
        timer = threading.Timer(RETRY, self._again)
        timer.daemon = True
        timer.start()

    def unraisable(self, report: sys.UnraisableHookArgs) -> None:
        """Within the block: a KeyboardInterrupt that was swallowed comes again later."""
        if (
            self.active
            and report.exc_type is not None
            and issubclass(report.exc_type, KeyboardInterrupt)
        ):
            self.postpone()
            return
        self.previous_hook(report)

    def _again(self) -> None:
        if self.active and self.pending:
            _thread.interrupt_main()


@contextlib.contextmanager
def interrupts_outside_compile_hooks() -> Iterator[None]:
    """Within the block, a SIGINT raises KeyboardInterrupt outside numba's compile-cache hooks
    (module docstring). Does nothing outside the main thread or when SIGINT has a handler of
    its own (not Python's default)."""
    if (
        threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    ):
        yield
        return
    postponer = _Postponer()
    signal.signal(signal.SIGINT, postponer.handle)
    sys.unraisablehook = postponer.unraisable
    try:
        yield
    finally:
        postponer.active = False
        signal.signal(signal.SIGINT, signal.default_int_handler)
        sys.unraisablehook = postponer.previous_hook
    if postponer.pending:
        raise KeyboardInterrupt
