"""Every README command that needs no robot runs as written.

The commands are read from the README's ```bash blocks. Skipped, each covered elsewhere: the set-up
line (CI runs it), `pytest` itself, `urident demo` (tests/test_demo.py), `urident excite` (minutes
of optimisation each; tests/test_excitation.py runs the command), URSim's `docker run`, and
commands that talk to a controller (`--host`, a server started with `&` and its `kill`:
tests/test_readme_dry_run.py runs that block); so is any command that reads what a skipped command would have written.
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
OUTPUT_FLAGS = ("--out", "--json-out", "--save", "--urdf", "--png", "--report")
NOT_HERE = (re.compile(r"^(pip|pytest|docker)\b"), re.compile(r"^urident (demo|excite)\b"),
            re.compile(r"--host\b"), re.compile(r"&$"), re.compile(r"^kill\b"))


def readme_commands() -> list[tuple[dict, str]]:
    return [c for block in bash_blocks() for c in block_commands(block)]


def outputs(command: str) -> list[str]:
    words = shlex.split(command)
    return [words[k + 1] for k, w in enumerate(words[:-1]) if w in OUTPUT_FLAGS]


def runnable(commands: list[tuple[dict, str]]) -> tuple[list[tuple[dict, str]], list[str]]:
    """The commands to run here, and the ones skipped (with what they would have written)."""
    keep, skipped, unavailable = [], [], set()
    for env, command in commands:
        needs_skipped = any(name in command for name in unavailable)
        if needs_skipped or any(p.search(command) for p in NOT_HERE):
            skipped.append(command)
            unavailable.update(outputs(command))
        else:
            keep.append((env, command))
    return keep, skipped


def test_readme_command_selection_is_what_the_docstring_says():
    commands = readme_commands()
    keep, skipped = runnable(commands)
    assert any(c.startswith("urident gap --robot ur10e") for _, c in keep)
    assert any(c.startswith("urident identify logs/sample_ident.csv") for _, c in keep)
    assert all("--host" not in c for _, c in keep)
    # the post-run commands of the operator workflow read the live robot's logs
    assert any(c.startswith("urident identify logs/ident.csv") for c in skipped)
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
    keep, _ = runnable(readme_commands())
    assert len(keep) >= 10
    for variables, command in keep:
        line = command.replace("/tmp/", f"{scratch}/")
        result = subprocess.run(["bash", "-c", line], cwd=work, env={**env, **variables},
                                capture_output=True, text=True, timeout=600)
        assert result.returncode == 0, f"README command failed: {command}\n{result.stderr[-2000:]}"
        assert "Traceback" not in result.stderr, command
