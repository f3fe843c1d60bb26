from pathlib import Path

import numpy as np
import pytest
from parallel_groups import starts_a_controller


@pytest.hookimpl(tryfirst=True)  # before xdist reads the groups
def pytest_collection_modifyitems(config, items):
    seen: dict[Path, bool] = {}
    for item in items:
        path = Path(item.fspath)
        if path not in seen:
            seen[path] = starts_a_controller(path)
        if seen[path]:
            item.add_marker(pytest.mark.xdist_group("controller"))


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
