"""The README's shell examples, as tests read them."""

from __future__ import annotations

import re
from pathlib import Path

README = Path(__file__).resolve().parent.parent / "README.md"


def bash_blocks(text: str | None = None, after: str | None = None) -> list[str]:
    """The ```bash blocks of the README (or ``text``), those after the phrase ``after`` only."""
    text = README.read_text() if text is None else text
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
