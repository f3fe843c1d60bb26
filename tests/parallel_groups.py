"""Which test modules may start a simulated controller: they bind fixed loopback addresses and
ports (one binds 0.0.0.0) and run in real time, so under pytest-xdist they share one worker (the
"controller" group, tests/conftest.py) and the rest of the suite spreads beside them."""

from __future__ import annotations

import re
from pathlib import Path

STARTS_A_CONTROLLER = re.compile(r'SimControllerProcess|run_session\(|run_trajectory\(|\[\s*"(run|demo|sim-controller)"'
                                 r'|urident (run|demo|sim-controller)\b|127\.0\.0\.|0\.0\.0\.0|localhost')


def starts_a_controller(path: Path) -> bool:
    """True when ``path``'s text names a way to start a controller (a conservative reading)."""
    return bool(STARTS_A_CONTROLLER.search(path.read_text(encoding="utf-8")))
