"""Safe output files: checked before any work, created exclusively, never written through a
symbolic link, and replaced atomically (a crash leaves the old file or the new one).

    check_output(path, "--out", overwrite)          # early: one-line OutputError, exit 2
    write_text_atomic(path, text, overwrite=False)  # temp file, then link (new) or rename
    with atomic_output(path, overwrite) as tmp:     # for libraries that write a path themselves
        figure.savefig(tmp)
    fd = create_exclusive(path, overwrite)          # a file streamed in place (log CSV)
"""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from pathlib import Path
from typing import Iterator

from urident.errors import OutputError


def _name(path: Path, flag: str | None) -> str:
    return f"{flag} {path}" if flag else str(path)


def check_output(path: str | Path, flag: str | None = None, overwrite: bool = False) -> Path:
    """Raise :class:`OutputError` (naming ``flag`` and the path) unless ``path`` can be written:
    not a symbolic link, not a directory, absent unless ``overwrite``, in an existing writable
    directory."""
    path = Path(path)
    name = _name(path, flag)
    if path.is_symlink():
        raise OutputError(f"{name}: is a symbolic link; refusing to write through it")
    if path.is_dir():
        raise OutputError(f"{name}: is a directory")
    if path.exists() and not overwrite:
        raise OutputError(f"{name}: exists; pass --overwrite to replace it")
    if path.exists() and not path.is_file():
        raise OutputError(f"{name}: is not a regular file")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise OutputError(f"{name}: directory {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{name}: directory {parent} is not writable")
    return path


def check_distinct_outputs(outputs, inputs=()) -> None:
    """:class:`OutputError` when two of ``outputs`` ((flag, path) pairs; None paths skipped) name one
    file (the same path, or two names of one existing file), or one names an input (``inputs``,
    the same pairs): one would replace the other. Checked before any work, with or without
    ``--overwrite``."""
    def same(a: Path, b: Path) -> bool:
        if a.resolve() == b.resolve():
            return True
        return a.exists() and b.exists() and os.path.samefile(a, b)

    ins = [(flag, Path(p)) for flag, p in inputs if p is not None]
    seen: list[tuple[str, Path]] = []
    for flag, path in outputs:
        if path is None:
            continue
        path = Path(path)
        for other_flag, other in ins:
            if same(path, other):
                raise OutputError(f"{_name(path, flag)}: is also the input {_name(other, other_flag)}; "
                                  "refusing to replace an input")
        for other_flag, other in seen:
            if same(path, other):
                raise OutputError(f"{_name(path, flag)}: also the {other_flag} output; give each output its own path")
        seen.append((flag, path))


def check_output_dir(path: str | Path, flag: str | None = None) -> Path:
    """A directory to write files into (created if missing): not a symbolic link, not a file."""
    path = Path(path)
    name = _name(path, flag)
    if path.is_symlink():
        raise OutputError(f"{name}: is a symbolic link; refusing to write through it")
    if path.exists() and not path.is_dir():
        raise OutputError(f"{name}: exists and is not a directory")
    if not path.exists():
        check_output(path, flag, overwrite=False)  # its parent must exist and be writable
    elif not os.access(path, os.W_OK | os.X_OK):
        raise OutputError(f"{name}: directory is not writable")
    return path


def temp_beside(path: Path) -> tuple[int, str]:
    """A new private temporary file (fd, name) in ``path``'s directory, ending in its suffix."""
    directory = path.parent if str(path.parent) else Path(".")
    try:  # keep the suffix: some writers choose the format by it (.png, .rrd)
        return tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}", dir=directory)
    except OSError as exc:
        raise OutputError(f"{path}: cannot write in {directory}: {exc.strerror or exc}") from None


def commit_temp(tmp: str, path: Path, overwrite: bool) -> None:
    """Move the finished ``tmp`` to ``path``: a rename when replacing (it replaces a link itself,
    never what it points to), a hard link when the file must be new (fails if it exists)."""
    if path.is_symlink():
        raise OutputError(f"{path}: is a symbolic link; refusing to write through it")
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # the usual permissions, not mkstemp's private 0600
    if overwrite:
        if path.is_dir():
            raise OutputError(f"{path}: is a directory")
        os.replace(tmp, path)
        return
    try:
        os.link(tmp, path)
    except FileExistsError:
        raise OutputError(f"{path}: exists; pass --overwrite to replace it") from None
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.EOPNOTSUPP, errno.EXDEV, errno.EMLINK):
            raise
        os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o666))
        os.replace(tmp, path)  # no hard links here: claim the name exclusively, then rename
        return
    os.unlink(tmp)


_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)


def write_text_atomic(path: str | Path, text: str, fsync: bool = True,
                      overwrite: bool = True) -> None:
    """Write ``text`` to ``path`` through a temporary file, then a rename (``overwrite``) or an
    exclusive link (the file must not exist). Never writes through a symbolic link."""
    write_bytes_atomic(path, text.encode("utf-8"), fsync=fsync, overwrite=overwrite)


def write_bytes_atomic(path: str | Path, data: bytes, fsync: bool = True,
                       overwrite: bool = True) -> None:
    path = Path(path)
    fd, tmp = temp_beside(path)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            if fsync:
                fh.flush()
                os.fsync(fh.fileno())
        commit_temp(tmp, path, overwrite)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    if fsync:
        _fsync_dir(path.parent if str(path.parent) else Path("."))


@contextlib.contextmanager
def atomic_output(path: str | Path, overwrite: bool = False, flag: str | None = None) -> Iterator[Path]:
    """A temporary path beside ``path`` for a library to write; on success it becomes ``path``
    (as :func:`write_text_atomic`), on an exception it is removed."""
    path = check_output(path, flag, overwrite)
    fd, tmp = temp_beside(path)
    os.close(fd)
    try:
        yield Path(tmp)
        commit_temp(tmp, path, overwrite)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def create_exclusive(path: str | Path, overwrite: bool = False, flag: str | None = None) -> int:
    """A new file at ``path`` opened for writing (a file descriptor), for files written in
    place as they grow. ``O_EXCL`` never follows a link; with ``overwrite`` an existing regular
    file is removed first."""
    path = Path(path)
    if overwrite and path.is_file() and not path.is_symlink():
        path.unlink()
    try:
        return os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o666)
    except FileExistsError:
        check_output(path, flag, overwrite=False)  # says why: a link, a directory, or it exists
        raise
    except OSError as exc:
        raise OutputError(f"{_name(path, flag)}: cannot create: {exc.strerror or exc}") from None


def _fsync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
