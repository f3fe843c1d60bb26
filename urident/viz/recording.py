"""Opening a Rerun recording: save to an ``.rrd`` file, spawn a viewer, or connect to one.

Every urident command that shows something in Rerun goes through :func:`open_recording`, so the
sink logic (and the headless checks) live in one place. All data goes on one timeline,
:data:`TIMELINE` ("time", a duration in seconds: the log's own timestamps).
"""

from __future__ import annotations

import os
import shutil
import socket
import sys
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

import rerun as rr

from urident.errors import UridentError
from urident.fileio import check_output, commit_temp, temp_beside

TIMELINE = "time"
DEFAULT_PORT = 9876
DEFAULT_URL = f"rerun+http://127.0.0.1:{DEFAULT_PORT}/proxy"
_PENDING: dict[int, tuple[str, Path, bool]] = {}  # recording -> (temporary .rrd, target, overwrite)


class ViewerUnavailable(UridentError):
    """No Rerun viewer can be spawned or reached (headless machine, no ``rerun`` executable,
    nothing listening at the connect address)."""


def viewer_unavailable_reason() -> str | None:
    """Why a native viewer cannot be spawned here, or None when it probably can."""
    if sys.platform.startswith("linux") and not any(
            os.environ.get(k) for k in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET")):
        return "no display (DISPLAY and WAYLAND_DISPLAY are unset)"
    if shutil.which("rerun") is None:
        return "the 'rerun' viewer executable is not on PATH"
    return None


def unreachable_reason(url: str) -> str | None:
    parsed = urlparse(url.replace("rerun+http", "http", 1).replace("rerun+https", "https", 1))
    host, port = parsed.hostname or "127.0.0.1", parsed.port or DEFAULT_PORT
    try:
        with socket.create_connection((host, port), timeout=0.5):
            return None
    except OSError as exc:
        return f"nothing answers at {host}:{port} ({exc.strerror or exc})"


def check_sink(save: str | Path | None = None, spawn: bool = False,
               connect: str | None = None, overwrite: bool = True) -> None:
    """Check a sink choice before doing any work: a writable ``.rrd`` path, a display for
    ``spawn``, a listening viewer for ``connect``. Raises a one-line :class:`UridentError`
    (:class:`ViewerUnavailable` for the viewer cases, suggesting ``--save``)."""
    if save is None and not spawn and connect is None:
        raise ValueError("open_recording needs one sink: save=PATH, spawn=True or connect=URL")
    if save is not None:
        path = Path(save)
        if path.suffix != ".rrd":
            raise UridentError(f"{path}: a Rerun recording file must end in .rrd")
        check_output(path, overwrite=overwrite)
    elif spawn:
        reason = viewer_unavailable_reason()
        if reason is not None:
            raise ViewerUnavailable(f"cannot spawn a Rerun viewer: {reason}; "
                                    "use --save OUT.rrd to write a recording file instead")
    else:
        url = connect or DEFAULT_URL
        reason = unreachable_reason(url)
        if reason is not None:
            raise ViewerUnavailable(f"cannot connect to a Rerun viewer at {url}: {reason}; "
                                    "use --save OUT.rrd to write a recording file instead")


def open_recording(
    app_id: str,
    save: str | Path | None = None,
    spawn: bool = False,
    connect: str | None = None,
    *,
    blueprint: Any = None,
    recording_id: str | None = None,
    overwrite: bool = True,
) -> rr.RecordingStream:
    """A new :class:`rerun.RecordingStream` with exactly one sink.

    ``save``: write an ``.rrd`` file (works headless); else ``spawn``: start a native viewer (or
    reuse one on port 9876); else ``connect``: a viewer's gRPC URL (``""`` for the default
    ``rerun+http://127.0.0.1:9876/proxy``). ``blueprint`` (a
    ``rerun.blueprint.Blueprint``) becomes the default layout. The ``.rrd`` file is written
    beside ``save`` under a temporary name and takes its name in :func:`close_recording`, so a
    symbolic link at ``save`` is never followed (``overwrite=False``: ``save`` must not exist).

    Raises :class:`ViewerUnavailable` (one line, naming the reason and suggesting ``--save``)
    when a viewer is asked for but cannot be spawned or reached.
    """
    check_sink(save, spawn, connect, overwrite)
    rec = rr.RecordingStream(app_id, recording_id=recording_id)
    if save is not None:
        fd, tmp = temp_beside(Path(save))
        os.close(fd)
        _PENDING[id(rec)] = (tmp, Path(save), overwrite)
        rec.save(Path(tmp), default_blueprint=blueprint)
    elif spawn:
        try:
            rec.spawn(default_blueprint=blueprint)
        except Exception as exc:  # noqa: BLE001 - any spawn failure is one user-facing line
            raise ViewerUnavailable(f"cannot spawn a Rerun viewer: {exc}; "
                                    "use --save OUT.rrd to write a recording file instead") from None
    else:
        rec.connect_grpc(connect or DEFAULT_URL, default_blueprint=blueprint)
    rec.log("robot", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    return rec


def close_recording(rec: rr.RecordingStream, timeout_s: float = 10.0) -> None:
    """Flush everything to the sink and disconnect (an ``.rrd`` file is complete afterwards)."""
    rec.flush(timeout_sec=timeout_s)
    rec.disconnect()
    pending = _PENDING.pop(id(rec), None)
    if pending is not None:
        commit_temp(*pending)


def set_time(rec: rr.RecordingStream, t: float) -> None:
    """Set the recording's :data:`TIMELINE` for subsequent ``rec.log`` calls (seconds)."""
    rec.set_time(TIMELINE, duration=float(t))


def time_column(t) -> rr.TimeColumn:
    """A :data:`TIMELINE` column of times ``t`` (N,) in seconds, for ``send_columns``."""
    return rr.TimeColumn(TIMELINE, duration=t)
