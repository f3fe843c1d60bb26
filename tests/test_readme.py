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

import pytest
from readme_helpers import file_blocks, run_as_written, selected
from shared_data import shared_data_dir

SHARED = shared_data_dir().parent  # the README reads ../shared/data


def readme_commands() -> list[tuple[dict, str]]:
    return [c for block in file_blocks() for c in block]


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
    keep, _ = selected()
    assert len(keep) >= 10
    run_as_written(keep, tmp_path, SHARED)
