from pathlib import Path

import numpy as np
import pytest
from parallel_groups import starts_a_controller


def pytest_itemcollected(item):
    # during collection, so the group is set before pytest-xdist reads it, whatever the plugin order
    if starts_a_controller(Path(item.fspath)):
        item.add_marker(pytest.mark.xdist_group("controller"))


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
