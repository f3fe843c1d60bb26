"""The dry run with urident's simulated controller works exactly as written.

The commands are parsed out of docs/getting-started.md, where the README's documentation links
lead (the first ``bash`` block after "urident's own simulated controller"), and run as a user at a
shell would: a line ending in ``&`` starts a background job (the next line is typed once it printed
its ``listening on`` line), ``kill %N`` ends job N, any other line must exit 0. They run in a scratch directory holding a copy of ``experiments/``, so the
log lands there; ``urident`` is this tree's ``python -m urident.cli.main``.
"""

from __future__ import annotations

import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path

from readme_helpers import bash_blocks, block_commands

from urident.logs import load_log

ROOT = Path(__file__).resolve().parents[1]


def dry_run_commands() -> list[str]:
    blocks = bash_blocks(path=ROOT / "docs" / "getting-started.md", after="urident's own simulated controller")
    assert blocks, "no bash block after the simulated-controller paragraph"
    return [command for _, command in block_commands(blocks[0])]


def argv(words: list[str]) -> list[str]:
    assert words[0] == "urident", words
    return [sys.executable, "-m", "urident.cli.main", *words[1:]]


def test_readme_dry_run_as_written(tmp_path):
    shutil.copytree(ROOT / "experiments", tmp_path / "experiments")
    (tmp_path / "logs").mkdir()  # as in the checkout, where the page's commands run
    jobs: list[subprocess.Popen] = []
    ran = []
    try:
        for line in dry_run_commands():
            words = shlex.split(line, comments=True)
            if words[0] == "kill":
                job = jobs[int(words[1].lstrip("%")) - 1]
                job.terminate()
                assert job.wait(timeout=30) == 0
                ran.append("kill")
                continue
            background = words[-1] == "&"
            if background:
                job = subprocess.Popen(argv(words[:-1]), cwd=tmp_path, stdout=subprocess.PIPE,
                                       stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, text=True)
                jobs.append(job)
                deadline = time.monotonic() + 60
                out = ""
                while "listening on" not in out and time.monotonic() < deadline and job.poll() is None:
                    out = job.stdout.readline()
                assert "listening on" in out, f"{line!r} did not start: {out}"
                ran.append(words[1])
                continue
            r = subprocess.run(argv(words), cwd=tmp_path, capture_output=True, text=True,
                               timeout=300, stdin=subprocess.DEVNULL)
            assert r.returncode == 0, f"{line!r} exited {r.returncode}: {r.stderr}"
            ran.append(words[1])
    finally:
        for job in jobs:
            if job.poll() is None:
                job.kill()
                job.wait()
    assert ran == ["sim-controller", "run", "kill"]
    log = load_log(tmp_path / "logs" / "sim_ident.csv")
    assert log.status == "completed" and log.robot == "ur5e"
    assert log.duration > 20.0
