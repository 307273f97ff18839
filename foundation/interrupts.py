"""Clean stops on Ctrl-C and ``SIGTERM``: finish the step, save a checkpoint, say how to resume.

A long job wraps its loop in :func:`stop_requests`. While it is active, the
first ``SIGINT`` (Ctrl-C) or ``SIGTERM`` (what ``kill``, Slurm and Kubernetes
send) only sets :attr:`StopFlag.signal`; the loop checks :attr:`StopFlag.requested`
at its next safe point, writes a checkpoint and raises :class:`TrainingStopped`.
A second signal stops at once, as Python normally would (the last checkpoint
is still there). The command line turns :class:`TrainingStopped` into its message
and exit status ``128 + signal number`` (130 for Ctrl-C, 143 for ``SIGTERM``).
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from types import FrameType

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupted(KeyboardInterrupt):
    """Ctrl-C or ``SIGTERM`` outside a clean stop (see :func:`interrupt_on_sigterm`).

    Attributes:
        exit_status: ``128 + signal number``, the shell's convention.
    """

    def __init__(self, message: str, signal_number: int) -> None:
        super().__init__(message)
        self.exit_status = 128 + signal_number


@contextlib.contextmanager
def interrupt_on_sigterm() -> Iterator[None]:
    """While active, ``SIGTERM`` raises :class:`Interrupted` like Ctrl-C, so ``finally`` blocks and cleanups run.

    Python's default for ``SIGTERM`` ends the process on the spot. Outside the main
    thread nothing changes.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handle(number: int, frame: FrameType | None) -> None:
        raise Interrupted("SIGTERM", number)

    previous = signal.signal(signal.SIGTERM, handle)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


class TrainingStopped(Interrupted):
    """A job stopped cleanly on request, after saving what it had.

    A ``KeyboardInterrupt`` so code that does not know about it still unwinds.
    """


@dataclass
class StopFlag:
    """Which stop signal arrived (None: none yet)."""

    signal: int | None = None

    @property
    def requested(self) -> bool:
        """Whether the job should stop at its next safe point."""
        return self.signal is not None

    def stop(self, what: str, resume: str) -> TrainingStopped:
        """The exception to raise once the checkpoint is saved.

        Args:
            what: Where the job stopped, e.g. ``"distill: stopped at step 300 of 600"``.
            resume: How to go on, e.g. ``"run the same command again"``.
        """
        assert self.signal is not None, "no stop was requested"
        name = signal.Signals(self.signal).name
        return TrainingStopped(f"{what} on {name}; checkpoint saved; to resume, {resume}", self.signal)


@contextlib.contextmanager
def stop_requests() -> Iterator[StopFlag]:
    """Defers the first Ctrl-C or ``SIGTERM`` to the caller's next safe point (see the module docstring).

    Outside the main thread (where Python cannot install handlers) the flag is
    never set and signals behave as usual; an ignored signal stays ignored.
    """
    flag = StopFlag()
    if threading.current_thread() is not threading.main_thread():
        yield flag
        return

    def handle(number: int, frame: FrameType | None) -> None:
        if flag.requested:  # the second signal: stop now
            raise KeyboardInterrupt
        flag.signal = number

    # A process that ignores a signal (a worker whose parent handles Ctrl-C) keeps ignoring it.
    wanted = [number for number in STOP_SIGNALS if signal.getsignal(number) is not signal.SIG_IGN]
    previous = {number: signal.signal(number, handle) for number in wanted}
    try:
        yield flag
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def ignore_interrupts_in_worker() -> None:
    """In a worker process, ignores Ctrl-C: its parent hears it, stops cleanly and closes the worker.

    Call it where a worker builds its environment. Ctrl-C in a terminal reaches every
    process of the group; a worker that died of it would take the parent's clean
    stop down with it. Does nothing in the main process.
    """
    import multiprocessing

    if multiprocessing.parent_process() is not None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
