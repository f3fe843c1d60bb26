"""Where the shared real-robot recordings are: ``$URIDENT_SHARED_DATA``, else ``shared/data`` beside
the repository (as CI checks it out), else the development machine's ``/work/shared/data``."""

import os
from pathlib import Path

_REPO = Path(__file__).resolve().parent.parent


def shared_data_dir() -> Path:
    candidates = [os.environ.get("URIDENT_SHARED_DATA"), _REPO.parent / "shared" / "data", "/work/shared/data"]
    for candidate in candidates:
        if candidate and Path(candidate).is_dir():
            return Path(candidate)
    return _REPO.parent / "shared" / "data"


UR10E_DATA = shared_data_dir() / "ur10e-dynamic-calibration"
