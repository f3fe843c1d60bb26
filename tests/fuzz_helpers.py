"""Helpers shared by the property-based fuzz tests of file formats."""

from __future__ import annotations


def key_paths(node, prefix=(), max_items: int | None = None):
    """Every key path of a parsed YAML document (tuples of keys and list indices), the root first;
    ``max_items`` limits how many entries of each list are walked."""
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from key_paths(v, prefix + (k,), max_items)
    elif isinstance(node, list):
        for i, v in enumerate(node if max_items is None else node[:max_items]):
            yield from key_paths(v, prefix + (i,), max_items)


def file_states(directory) -> dict:
    """path -> (size, mtime_ns, bytes' hash) of every file under ``directory``: compare before and
    after a command to see that it changed no existing file."""
    import hashlib
    from pathlib import Path

    out = {}
    for p in sorted(Path(directory).rglob("*")):
        if p.is_file():
            st = p.stat()
            out[p] = (st.st_size, st.st_mtime_ns, hashlib.sha256(p.read_bytes()).hexdigest())
    return out


THIRD_PARTY_MARKS = ("Traceback", "Warning:", "Error:   ", "** On entry to", "WARNING: ", "internal error")


def assert_promise(code: int, out: str, err: str, before: dict, after: dict) -> None:
    """The bad-input promise of a command run: exit 0, or exit 2 with one ``urident: error:`` line
    (the last of stderr); never 70; no third-party output (tracebacks, numpy warnings, urdfdom's or
    LAPACK's lines, MuJoCo's warnings); no file that existed before changed."""
    assert code in (0, 2), (code, err[-500:])
    errors = [line for line in err.splitlines() if line.startswith("urident: ")]
    if code == 2:
        assert len(errors) == 1 and err.rstrip("\n").splitlines()[-1] == errors[0], err[-500:]
        assert errors[0].startswith("urident: error: "), errors[0]
    else:  # notes and warnings may be said; no error
        assert not [e for e in errors if e.startswith("urident: error")], err[-500:]
    for mark in THIRD_PARTY_MARKS:
        assert mark not in out and mark not in err, (mark, out[-300:], err[-300:])
    changed = [str(p) for p, state in before.items() if after.get(p) != state]
    assert not changed, f"changed or removed: {changed}"
