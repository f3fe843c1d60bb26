"""Which test modules may start a simulated controller: they bind fixed loopback addresses and
ports (one binds 0.0.0.0) and run in real time, so under pytest-xdist they share one worker (the
"controller" group, tests/conftest.py) and the rest of the suite spreads beside them."""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

STARTS_A_CONTROLLER = re.compile(r'SimControllerProcess|run_session\(|run_trajectory\(|\[\s*"(run|demo|sim-controller)"'
                                 r'|urident (run|demo|sim-controller)\b|127\.0\.0\.|0\.0\.0\.0|localhost')


@functools.lru_cache(maxsize=None)
def starts_a_controller(path: Path) -> bool:
    """True when ``path``'s code (docstrings and comments aside) names a way to start a controller;
    a conservative reading: a mention in a string counts."""
    source = path.read_text(encoding="utf-8")
    docstrings = [ast.get_source_segment(source, node.body[0]) or "" for node in ast.walk(ast.parse(source))
                  if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                  and node.body and isinstance(node.body[0], ast.Expr)
                  and isinstance(node.body[0].value, ast.Constant) and isinstance(node.body[0].value.value, str)]
    text = source
    for doc in docstrings:
        text = text.replace(doc, "", 1)
    code = "\n".join(line.split("#", 1)[0] if line.lstrip().startswith("#") or "  #" in line else line
                     for line in text.splitlines())
    return bool(STARTS_A_CONTROLLER.search(code))
