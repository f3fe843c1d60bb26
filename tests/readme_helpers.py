"""The shell examples of the README and of the documentation pages, as tests read and run them.

Which commands run here (``runnable``) and how (``run_as_written``) is written once, for
tests/test_readme.py and tests/test_docs_site.py alike."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
OUTPUT_FLAGS = ("--out", "--json-out", "--save", "--urdf", "--png", "--report", "--mjcf", "--write-sim", "--bag")
NOT_HERE = (re.compile(r"^(pip|pytest|docker|ros2)\b"), re.compile(r"^urident (demo|excite)\b"),
            re.compile(r"--host\b"), re.compile(r"&$"), re.compile(r"^kill\b"))


def bash_blocks(text: str | None = None, after: str | None = None, path: Path | None = None) -> list[str]:
    """The ```bash blocks of the README (or of the markdown file ``path``, or of ``text``), those
    after the phrase ``after`` only."""
    if text is None:
        text = (path or README).read_text()
    if after is not None:
        text = text[text.index(after):]
    return re.findall(r"```bash\n(.*?)```", text, re.S)


def block_commands(block: str) -> list[tuple[dict[str, str], str]]:
    """(variables set before it in the block, command) for every command line of ``block``:
    backslash continuations joined, comments and blank lines dropped."""
    out, env = [], {}
    for line in block.replace("\\\n", " ").splitlines():
        line = re.sub(r"\s+#.*$", "", line).strip()
        if not line or line.startswith("#"):
            continue
        assignment = re.fullmatch(r"([A-Z_][A-Z0-9_]*)=(\S+)", line)
        if assignment:
            env[assignment.group(1)] = assignment.group(2)
            continue
        out.append((dict(env), re.sub(r"\s+", " ", line)))
    return out


def file_blocks(path: Path | None = None) -> list[list[tuple[dict, str]]]:
    """The commands of every ```bash block of a markdown file (default: the README), block by block."""
    return [block_commands(block) for block in bash_blocks(path=path)]


def outputs(command: str) -> list[str]:
    words = shlex.split(command)
    return [words[k + 1] for k, w in enumerate(words[:-1]) if w in OUTPUT_FLAGS]


def runnable(commands: list[tuple[dict, str]]) -> tuple[list[tuple[dict, str]], list[str]]:
    """The commands of one block to run here, and the ones skipped: the set-up line, `pytest`,
    `urident demo` and `urident excite` (covered by their own tests), docker and ros2, commands
    that talk to a controller (`--host`, a server started with `&` and its `kill`), commands that
    read a recording of the operator's own robot (a `logs/*.csv` the checkout does not ship), and
    any command that reads what a skipped command would have written."""
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


def selected(path: Path | None = None) -> tuple[list[tuple[dict, str]], list[str]]:
    """``runnable`` over every block of a markdown file (default: the README)."""
    keep, skipped = [], []
    for block in file_blocks(path):
        k, s = runnable(block)
        keep += k
        skipped += s
    return keep, skipped


def run_as_written(commands: list[tuple[dict, str]], tmp_path: Path, shared: Path, source: str = "README") -> None:
    """Run ``commands`` in order as a user at a shell would, in a scratch copy of logs/ and
    experiments/ beside a link to ``shared`` (the directory holding data/), with `/tmp/` pointing
    into ``tmp_path``, so the checkout is never written; each must exit 0 without a traceback."""
    work = tmp_path / "repo"
    work.mkdir()
    for name in ("logs", "experiments"):
        shutil.copytree(ROOT / name, work / name)
    (work / "urident").symlink_to(ROOT / "urident")
    (tmp_path / "shared").symlink_to(shared)
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    for variables, command in commands:
        line = command.replace("/tmp/", f"{scratch}/")
        result = subprocess.run(["bash", "-c", line], cwd=work, env={**env, **variables},
                                capture_output=True, text=True, timeout=600)
        assert result.returncode == 0, f"{source} command failed: {command}\n{result.stderr[-2000:]}"
        assert "Traceback" not in result.stderr, command
