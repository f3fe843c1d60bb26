"""Outputs: nothing is overwritten without --overwrite, nothing is written through a symbolic
link, and a directory or impossible target is exit 2 with one line before any work or motion."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from urident.cli.main import main
from urident.errors import OutputError
from urident.fileio import atomic_output, check_output, create_exclusive, write_text_atomic
from urident.logs import LOG_FIELDS, LogWriter

ROOT = Path(__file__).resolve().parent.parent
TRAJECTORY = ROOT / "experiments" / "ur5_ident.yaml"
SAMPLE_IDENT = ROOT / "logs" / "sample_ident.csv"
SAMPLE_VALID = ROOT / "logs" / "sample_valid.csv"


@pytest.fixture
def targets(tmp_path):
    """An existing file, a symbolic link to a victim file, a directory, a path in a missing
    directory."""
    existing = tmp_path / "existing.yaml"
    existing.write_text("keep me\n")
    victim = tmp_path / "victim.txt"
    victim.write_text("victim\n")
    link = tmp_path / "link.yaml"
    link.symlink_to(victim)
    directory = tmp_path / "dir.yaml"
    directory.mkdir()
    return {"existing": existing, "link": link, "victim": victim, "directory": directory,
            "nowhere": tmp_path / "missing" / "out.yaml"}


MESSAGES = {"existing": "exists; pass --overwrite to replace it",
            "link": "is a symbolic link; refusing to write through it",
            "directory": "is a directory", "nowhere": "does not exist"}


def _argvs(kind: str, target: Path, tmp: Path):
    """(argv, flag) of every command writing a file, with ``target`` as that file. The inputs
    (logs, trajectories) do not exist: the output check must come first."""
    t = str(target)
    rrd = target.with_suffix(".rrd")
    out = [
        (["identify", "missing.csv", "--robot", "ur5", "--out", t], "--out"),
        (["identify", "missing.csv", "--robot", "ur5", "--out", str(tmp / "p.yaml"), "--report", t], "--report"),
        (["identify", "missing.csv", "--robot", "ur5", "--out", str(tmp / "p.yaml"), "--method", "all",
          "--urdf", t], "--urdf"),
        (["validate", "missing.csv", "--params", "missing.yaml", "--json-out", t], "--json-out"),
        (["gap", "--robot", "ur5", "--ident", "a.csv", "--valid", "b.csv", "--json-out", t], "--json-out"),
        (["excite", "--robot", "ur5", "--out", t], "--out"),
        (["view", "missing.csv", "--save", str(rrd)], "--save"),
        (["identify", "missing.csv", "--robot", "ur5", "--out", str(tmp / "p.yaml"), "--save", str(rrd)], "--save"),
    ]
    if kind != "existing":  # a log's CSV; for "existing" see test_run_and_simulate_refuse_an_existing_log
        csv = target.with_suffix(".csv") if kind != "directory" else target
        out += [(["simulate", "--trajectory", "missing.yaml", "--out", str(csv)], "--out"),
                (["run", "--robot", "ur5", "--host", "127.0.0.1", "--trajectory", "missing.yaml",
                  "--out", str(csv)], "--out")]
    return out


@pytest.mark.parametrize("kind", ["existing", "link", "directory", "nowhere"])
def test_every_output_flag_is_checked_first(targets, tmp_path, capsys, kind):
    target = targets[kind]
    if kind in ("link", "existing"):  # the same kind of target with each command's suffix
        for suffix in (".rrd", ".csv"):
            alt = target.with_suffix(suffix)
            if kind == "link":
                alt.symlink_to(targets["victim"])
            else:
                alt.write_text("keep me\n")
    if kind == "directory":
        target.with_suffix(".rrd").mkdir()
    for argv, flag in _argvs(kind, target, tmp_path):
        code = main(argv)
        err = capsys.readouterr().err
        assert code == 2, (argv, err)
        assert err.count("\n") == 1 and err.startswith(f"urident: error: {flag} "), (argv, err)
        assert MESSAGES[kind] in err, (argv, err)
    assert targets["victim"].read_text() == "victim\n"
    assert targets["existing"].read_text() == "keep me\n"


def _log(path: Path) -> Path:
    with LogWriter(path, fields=LOG_FIELDS[:4], metadata={"robot": "ur5"}) as log:
        log.append([0.0] + [0.0] * 18)
    return path


def test_run_and_simulate_refuse_an_existing_log(tmp_path, capsys):
    log = _log(tmp_path / "done.csv")
    before = (log.read_bytes(), log.with_suffix(".yaml").read_bytes())
    for stem in ("done", "done.csv"):  # with or without the .csv suffix
        for argv in (["run", "--robot", "ur5", "--host", "127.0.0.1", "--trajectory", str(TRAJECTORY),
                      "--out", str(tmp_path / stem), "--yes"],
                     ["simulate", "--trajectory", str(TRAJECTORY), "--out", str(tmp_path / stem)]):
            assert main(argv) == 2  # before connecting: no controller is needed to refuse
            err = capsys.readouterr().err
            assert err.count("\n") == 1 and "done.csv: exists; pass --overwrite" in err
    log.unlink()  # a sidecar alone is enough to refuse: it would be replaced
    assert main(["run", "--robot", "ur5", "--host", "127.0.0.1", "--trajectory", str(TRAJECTORY),
                 "--out", str(log), "--yes"]) == 2
    assert "done.yaml: exists" in capsys.readouterr().err
    assert log.with_suffix(".yaml").read_bytes() == before[1]


def test_identify_overwrites_only_when_asked(tmp_path, capsys):
    out = tmp_path / "p.yaml"
    report = tmp_path / "report.txt"
    argv = ["identify", str(SAMPLE_IDENT), "--robot", "ur5", "--out", str(out), "--report", str(report)]
    assert main(argv) == 0
    capsys.readouterr()
    first = out.read_text()
    out.write_text("edited\n")
    assert main(argv) == 2 and "--out" in capsys.readouterr().err
    assert out.read_text() == "edited\n"
    assert main([*argv, "--overwrite"]) == 0
    assert out.read_text() == first
    victim = tmp_path / "victim.txt"
    victim.write_text("victim\n")
    report.unlink()
    report.symlink_to(victim)
    assert main([*argv, "--overwrite"]) == 2  # --overwrite never writes through a link
    assert "--report" in capsys.readouterr().err and victim.read_text() == "victim\n"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary files left


def test_view_save_is_written_under_a_temporary_name_then_renamed(tmp_path, capsys):
    rrd = tmp_path / "v.rrd"
    assert main(["view", str(SAMPLE_VALID), "--save", str(rrd)]) == 0
    assert rrd.stat().st_size > 0
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    assert main(["view", str(SAMPLE_VALID), "--save", str(rrd)]) == 2
    assert "--save" in capsys.readouterr().err
    assert main(["view", str(SAMPLE_VALID), "--save", str(rrd), "--overwrite"]) == 0


# -- the helpers --------------------------------------------------------------------------------

def test_write_text_atomic_never_follows_a_link(targets):
    link, victim = targets["link"], targets["victim"]
    for overwrite in (False, True):
        with pytest.raises(OutputError, match="symbolic link"):
            write_text_atomic(link, "evil\n", overwrite=overwrite)
    assert victim.read_text() == "victim\n" and link.is_symlink()
    with pytest.raises(OutputError, match="exists"):
        write_text_atomic(targets["existing"], "new\n", overwrite=False)
    write_text_atomic(targets["existing"], "new\n", overwrite=True)
    assert targets["existing"].read_text() == "new\n"
    new = targets["existing"].with_name("new.yaml")
    write_text_atomic(new, "x\n", overwrite=False)
    assert new.read_text() == "x\n" and oct(new.stat().st_mode & 0o777) != oct(0o600)


def test_atomic_output_and_exclusive_creation(targets, tmp_path):
    target = tmp_path / "plot.png"
    with pytest.raises(RuntimeError):
        with atomic_output(target) as tmp:
            assert tmp.suffix == ".png" and tmp.parent == tmp_path
            tmp.write_text("half")
            raise RuntimeError("the writer failed")
    assert not target.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".plot")]
    with atomic_output(target) as tmp:
        tmp.write_text("done")
    assert target.read_text() == "done"
    for kind in ("link", "existing", "directory"):
        with pytest.raises(OutputError):
            os.close(create_exclusive(targets[kind], overwrite=False))
    with pytest.raises(OutputError, match="symbolic link"):  # --overwrite removes files, never links
        create_exclusive(targets["link"], overwrite=True)
    os.close(create_exclusive(targets["existing"], overwrite=True))
    assert targets["existing"].read_text() == "" and targets["victim"].read_text() == "victim\n"
    with pytest.raises(OutputError, match="directory .* does not exist"):
        check_output(targets["nowhere"])


def test_log_writer_never_follows_a_link(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("victim\n")
    csv = tmp_path / "run.csv"
    csv.symlink_to(victim)
    for overwrite in (False, True):  # the recorder writes with overwrite=True
        with pytest.raises(OutputError, match="run.csv: is a symbolic link"):
            LogWriter(csv, fields=LOG_FIELDS[:4], overwrite=overwrite)
    csv.unlink()
    csv.with_suffix(".yaml").symlink_to(victim)
    with pytest.raises(OutputError, match="run.yaml: is a symbolic link"):
        LogWriter(csv, fields=LOG_FIELDS[:4])
    assert victim.read_text() == "victim\n"
