"""Every README command that needs no robot runs as written.

The commands are read from the README's ```bash blocks. Skipped, each covered elsewhere: the set-up
line (CI runs it), `pytest` itself, `urident demo` (tests/test_demo.py), `urident excite` (minutes
of optimisation each; tests/test_excitation.py runs the command), URSim's `docker run`, ROS 2's own `ros2` commands, and
commands that talk to a controller (`--host`, a server started with `&` and its `kill`:
tests/test_readme_dry_run.py runs that block), commands that read a recording of the operator's own
robot (a `logs/*.csv` the checkout does not ship); so is any command that reads what a skipped command would have written.
They run in a scratch copy of logs/ and experiments/ beside a link to ../shared, with `/tmp/`
pointing into the test's own directory, so the checkout is never written.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from readme_helpers import bash_blocks, block_commands
from shared_data import shared_data_dir

ROOT = Path(__file__).resolve().parent.parent
SHARED = shared_data_dir().parent  # the README reads ../shared/data
OUTPUT_FLAGS = ("--out", "--json-out", "--save", "--urdf", "--png", "--report", "--mjcf", "--write-sim", "--bag")
NOT_HERE = (re.compile(r"^(pip|pytest|docker|ros2)\b"), re.compile(r"^urident (demo|excite)\b"),
            re.compile(r"--host\b"), re.compile(r"&$"), re.compile(r"^kill\b"))


def readme_blocks() -> list[list[tuple[dict, str]]]:
    return [block_commands(block) for block in bash_blocks()]


def readme_commands() -> list[tuple[dict, str]]:
    return [c for block in readme_blocks() for c in block]


def outputs(command: str) -> list[str]:
    words = shlex.split(command)
    return [words[k + 1] for k, w in enumerate(words[:-1]) if w in OUTPUT_FLAGS]


def runnable(commands: list[tuple[dict, str]]) -> tuple[list[tuple[dict, str]], list[str]]:
    """The commands of one block to run here, and the ones skipped."""
    keep, skipped, unavailable = [], [], set()
    for env, command in commands:
        words = shlex.split(command)
        needs_skipped = any(w in unavailable for w in words if w not in outputs(command))
        own_recording = any(not (ROOT / w).exists() and w not in outputs(command)
                            for w in words if re.fullmatch(r"logs/[\w.-]+\.csv", w))
        if needs_skipped or own_recording or any(p.search(command) for p in NOT_HERE):
            skipped.append(command)
            unavailable.update(outputs(command))
        else:
            keep.append((env, command))
            unavailable.difference_update(outputs(command))
    return keep, skipped


def selected() -> tuple[list[tuple[dict, str]], list[str]]:
    keep, skipped = [], []
    for block in readme_blocks():
        k, s = runnable(block)
        keep += k
        skipped += s
    return keep, skipped


def test_readme_command_selection_is_what_the_docstring_says():
    commands = readme_commands()
    keep, skipped = selected()
    assert any(c.startswith("urident gap --robot ur10e") for _, c in keep)
    assert any(c.startswith("urident identify logs/sample_ident.csv") for _, c in keep)
    assert all("--host" not in c for _, c in keep)
    # the post-run commands of the operator workflow read the live robot's logs
    assert any(c.startswith("urident identify logs/ident.csv") for c in skipped)
    assert any(c.startswith("urident payload $D/ur-20_01_31-load.csv") for _, c in keep)
    assert all("logs/tool.csv" not in c for _, c in keep)
    joined = [c for _, c in commands if "--valid-rows 700-4200" in c]
    assert joined and all("\\" not in c for c in joined)


@pytest.mark.skipif(not (SHARED / "data").is_dir(), reason="needs ../shared/data")
def test_readme_commands_run_as_written(tmp_path):
    work = tmp_path / "repo"
    work.mkdir()
    for name in ("logs", "experiments"):
        shutil.copytree(ROOT / name, work / name)
    (work / "urident").symlink_to(ROOT / "urident")
    (tmp_path / "shared").symlink_to(SHARED)
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    keep, _ = selected()
    assert len(keep) >= 10
    for variables, command in keep:
        line = command.replace("/tmp/", f"{scratch}/")
        result = subprocess.run(["bash", "-c", line], cwd=work, env={**env, **variables},
                                capture_output=True, text=True, timeout=600)
        assert result.returncode == 0, f"README command failed: {command}\n{result.stderr[-2000:]}"
        assert "Traceback" not in result.stderr, command
