"""Third-party libraries' own output kept off the user's terminal: C/C++/Fortran code (urdfdom's
parser, LAPACK's xerbla) writes straight to file descriptors 1 and 2, where Python's
``sys.stdout``/``sys.stderr`` redirection cannot reach. urident says what went wrong in its own
one line; what the library wrote is kept for that line.

    with captured_fds() as out:
        model = pin.buildModelFromUrdf(path)
    out.text          # what was written to fd 1 and 2 meanwhile
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from typing import Iterator


class Captured:
    """What a :func:`captured_fds` block wrote to its file descriptors (filled on exit)."""

    text: str = ""

    def first_line(self, marker: str = "") -> str:
        """The first non-empty line (containing ``marker``, when given), stripped; "" if none."""
        for line in self.text.splitlines():
            if line.strip() and marker in line:
                return " ".join(line.split())
        return ""


@contextlib.contextmanager
def captured_fds(fds: tuple[int, ...] = (1, 2)) -> Iterator[Captured]:
    """Redirect the OS-level file descriptors ``fds`` to a temporary file for the block and restore
    them after (also on an exception); Python's own streams are flushed first so nothing of ours
    is caught or reordered."""
    out = Captured()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    saved = []
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        try:
            for fd in fds:
                try:
                    saved.append((fd, os.dup(fd)))
                except OSError:    # not open (a daemon's closed stdout): nothing to keep off it
                    continue
                os.dup2(tmp.fileno(), fd)
            yield out
        finally:
            for stream in (sys.stdout, sys.stderr):
                with contextlib.suppress(Exception):
                    stream.flush()
            for fd, copy in saved:
                os.dup2(copy, fd)
                os.close(copy)
            tmp.seek(0)
            out.text = tmp.read().decode("utf-8", errors="replace")
