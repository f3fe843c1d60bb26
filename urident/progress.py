"""One progress line for long work (loading, identification, diagnosis) on a terminal.

    with Progress("identify: regressor", total=n_samples) as p:
        for chunk in chunks:
            ...
            p.advance(len(chunk))

The line goes to stderr, is rewritten in place (carriage return) at most every 0.2 s and only once
the work has lasted ``delay`` seconds; it is cleared at the end. When the stream is not a terminal
(pipes, CI, tests) nothing is written at all.
"""

from __future__ import annotations

import sys
import time
from typing import Iterable, Iterator, TextIO, TypeVar

T = TypeVar("T")


class Progress:
    def __init__(self, what: str, total: int | None = None, stream: TextIO | None = None,
                 delay: float = 2.0, interval: float = 0.2) -> None:
        self.what = what
        self.total = total
        self.done = 0
        self._stream = sys.stderr if stream is None else stream
        isatty = getattr(self._stream, "isatty", None)
        self.enabled = bool(isatty and isatty())
        self._start = time.monotonic()
        self._delay = delay
        self._interval = interval
        self._last = 0.0
        self._width = 0

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def advance(self, n: int = 1, detail: str = "") -> None:
        self.done += n
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self._start < self._delay or now - self._last < self._interval:
            return
        self._last = now
        self._write(self.text(now - self._start, detail))

    def text(self, elapsed: float, detail: str = "") -> str:
        if self.total:
            frac = min(self.done / self.total, 1.0)
            line = f"{self.what}: {self.done}/{self.total} ({100 * frac:.0f} %)"
            if 0 < frac < 1:
                line += f", {elapsed / frac - elapsed:.0f} s left"
        else:
            line = f"{self.what}: {self.done}"
        return line + (f" {detail}" if detail else "") + f" [{elapsed:.0f} s]"

    def _write(self, line: str) -> None:
        pad = max(self._width - len(line), 0)
        self._stream.write("\r" + line + " " * pad)
        self._stream.flush()
        self._width = len(line)

    def close(self) -> None:
        if self.enabled and self._width:
            self._stream.write("\r" + " " * self._width + "\r")
            self._stream.flush()
            self._width = 0


def progress_iter(items: Iterable[T], what: str, total: int | None = None,
                  stream: TextIO | None = None, **kw) -> Iterator[T]:
    """``items`` with a :class:`Progress` advanced by one per item (``total``: len(items) if known)."""
    if total is None and hasattr(items, "__len__"):
        total = len(items)  # type: ignore[arg-type]
    with Progress(what, total, stream, **kw) as p:
        for item in items:
            yield item
            p.advance()


class Working:
    """A progress line without steps: ``what: 12 s`` refreshed every second while the block runs
    (work whose steps live elsewhere, e.g. the gap diagnosis); silent off a terminal."""

    def __init__(self, what: str, stream: TextIO | None = None, delay: float = 2.0,
                 interval: float = 1.0) -> None:
        import threading

        self._progress = Progress(what, None, stream, delay, 0.0)
        self._interval = interval
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True) if self._progress.enabled else None

    def _run(self) -> None:
        p = self._progress
        while not self._stop.wait(self._interval):
            elapsed = time.monotonic() - p._start
            if elapsed >= p._delay:
                p._write(f"{p.what}: {elapsed:.0f} s")

    def __enter__(self) -> "Working":
        if self._thread is not None:
            self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        self._progress.close()
