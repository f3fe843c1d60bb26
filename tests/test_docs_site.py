"""The documentation site builds strictly, its CLI reference covers every flag, and every command
in its pages that needs no robot runs as written.

`mkdocs build --strict` (mkdocs.yml at the root; its hook docs/hooks/cli_reference.py generates a
page per `urident` subcommand from the argparse parsers) runs into a temporary directory. The
pages' ```bash blocks are selected and run by the README test's rules (tests/readme_helpers.py);
a block whose every runnable command is also a runnable README command is left to
tests/test_readme.py, which runs it already.
"""

from __future__ import annotations

import argparse
import html
import os
import subprocess
import sys
from pathlib import Path

import pytest
from parallel_groups import STARTS_A_CONTROLLER
from readme_helpers import file_blocks, run_as_written, runnable, selected
from shared_data import shared_data_dir

from urident.cli.main import get_argument_parser

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
SHARED = shared_data_dir().parent  # the pages read ../shared/data, as the README does
API_OBJECTS = ("urident.logs.load_log", "urident.logs.Recording", "urident.ident.prepare",
               "urident.ident.identify.identify", "urident.ident.identify_all", "urident.ident.predict_recordings",
               "urident.ident.validate.validate", "urident.ident.load_params", "urident.ident.save_params",
               "urident.gap.diagnose.diagnose", "urident.gap.GapResult", "urident.excitation.check_trajectory",
               "urident.excitation.load_trajectory", "urident.model.load_robot", "urident.model.RobotSpec",
               "urident.api.design_excitation", "urident.excitation.design.ExcitationDesign",
               "urident.api.identify_payload", "urident.ident.payload_fit.PayloadIdentification",
               "urident.api.calibrate_drive_gains", "urident.ident.gains_fit.DriveGainCalibration",
               "urident.api.run_trajectory", "urident.api.diagnose_sim", "urident.api.export_model",
               "urident.model.payload.Payload")

pytest.importorskip("mkdocs", reason="the docs site needs the dev extra (mkdocs, mkdocs-material, mkdocstrings-python)")


def pages() -> list[Path]:
    return sorted(p for p in DOCS.rglob("*.md") if "hooks" not in p.relative_to(DOCS).parts)


def subcommands() -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in get_argument_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1",
           "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    result = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
                            cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, f"mkdocs build --strict failed:\n{result.stderr[-4000:]}"
    return out


def test_cli_reference_has_every_subcommand_and_flag(site):
    commands = subcommands()
    assert {"identify", "validate", "gap", "run"} <= set(commands)
    index = (site / "reference/cli/index.html").read_text()
    for name, parser in commands.items():
        page = site / "reference/cli" / name / "index.html"
        assert page.is_file(), f"no CLI reference page for 'urident {name}'"
        text = page.read_text()
        assert f'href="{name}/"' in index, name
        for action in parser._actions:
            if action.help == argparse.SUPPRESS or isinstance(action, argparse._HelpAction):
                continue
            for flag in action.option_strings or [action.metavar or action.dest]:
                assert html.escape(flag) in text, f"'urident {name}' page lacks {flag}"


def test_every_page_is_in_the_nav_and_the_api_reference_is_there(site):
    home = (site / "index.html").read_text()
    for page in pages():
        rel = page.relative_to(DOCS).with_suffix("")
        url = "." if rel.as_posix() == "index" else (rel.parent if rel.name == "index" else rel).as_posix() + "/"
        assert (site / url / "index.html").is_file(), page
        assert f'href="{url}"' in home or rel.as_posix() == "index", f"{page.name} is not in the nav"
    api = (site / "reference/api/index.html").read_text()
    for name in API_OBJECTS:
        assert f'id="{name}"' in api, f"API reference lacks {name}"


def docs_commands() -> tuple[list[tuple[dict, str]], list[str], int]:
    """(commands to run here, commands skipped, blocks left to the README test)."""
    readme_keep = {(tuple(sorted(e.items())), c) for e, c in selected()[0]}
    keep, skipped, covered = [], [], 0
    for page in pages():
        for block in file_blocks(page):
            k, s = runnable(block)
            skipped += s
            if k and all((tuple(sorted(e.items())), c) in readme_keep for e, c in k):
                covered += 1
                continue
            keep += [c for c in k if c not in keep]  # a command shown on two pages runs once
    return keep, skipped, covered


def test_docs_command_selection():
    keep, skipped, covered = docs_commands()
    assert keep or covered, "the docs show no runnable command"
    assert all("--host" not in c for _, c in keep)
    assert any("--host" in c for c in skipped)  # the live-arm guide is read, and skipped
    assert not any(c.startswith("urident excite") for _, c in keep)
    assert not any(STARTS_A_CONTROLLER.search(c) for _, c in keep)  # they run beside the controller tests
    # the commands that left the README when it became a front page run here
    assert any(c.startswith("urident gap --robot ur10e") for _, c in keep)
    assert any(c.startswith("urident identify logs/sample_ident.csv") for _, c in keep)
    assert any(c.startswith("urident payload $D/ur-20_01_31-load.csv") for _, c in keep)
    assert any(c.startswith("urident identify logs/ident.csv") for c in skipped)
    assert all("logs/tool.csv" not in c for _, c in keep)
    joined = [c for page in pages() for block in file_blocks(page) for _, c in block if "--valid-rows 700-4200" in c]
    assert joined and all("\\" not in c for c in joined)
    assert len({c for _, c in keep}) == len(keep)  # each command runs once


@pytest.mark.skipif(not (SHARED / "data").is_dir(), reason="needs ../shared/data")
def test_docs_commands_run_as_written(tmp_path):
    keep, _, _ = docs_commands()
    run_as_written(keep, tmp_path, SHARED, source="docs")
