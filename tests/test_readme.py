"""Every README command that needs no robot runs as written.

The README is the front page: its ```bash blocks are the set-up line and the operator workflow on
a live arm; the other commands live on the documentation pages, which tests/test_docs_site.py runs
by the same rules (tests/readme_helpers.py). Skipped, each covered elsewhere: the set-up line (CI
runs it), `pytest` itself, `urident demo` (tests/test_demo.py), `urident excite` (minutes of
optimisation each; tests/test_excitation.py runs the command), URSim's `docker run`, ROS 2's own
`ros2` commands, and commands that talk to a controller (`--host`, a server started with `&` and
its `kill`: tests/test_readme_dry_run.py runs that block of docs/getting-started.md), commands that
read a recording of the operator's own robot (a `logs/*.csv` the checkout does not ship); so is any
command that reads what a skipped command would have written.
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
    assert commands[:2] == [({}, 'pip install -e ".[dev]" && urident demo'), ({}, "pytest")]
    assert all("--host" not in c for _, c in keep)
    assert any("--host" in c for c in skipped)
    # the post-run commands of the operator workflow read the live robot's logs
    assert any(c.startswith("urident identify logs/ident.csv") for c in skipped)
    assert any(c.startswith("urident excite") for c in skipped)
    assert any(c.startswith("urident model --robot ur5") for _, c in keep)
    # every other command the README showed before it became a front page is on a docs page
    assert len(commands) < 15


@pytest.mark.skipif(not (SHARED / "data").is_dir(), reason="needs ../shared/data")
def test_readme_commands_run_as_written(tmp_path):
    keep, _ = selected()
    assert keep
    run_as_written(keep, tmp_path, SHARED)
