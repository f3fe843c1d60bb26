"""MkDocs hook: the CLI reference, one page per ``urident`` subcommand, generated from the argparse
parsers of ``urident.cli.main.get_argument_parser`` at every build (a new flag appears by itself),
and the nav made tolerant: every page under docs/ that the nav in mkdocs.yml does not list is
appended under "More", so a branch adding a page cannot break the strict build or hide the page.

Generated pages live at ``reference/cli/<command>.md``; the nav entry ``reference/cli/index.md`` in
mkdocs.yml is replaced by a "CLI reference" section holding the index and every command page.
"""

from __future__ import annotations

import argparse
import html
import re

from mkdocs.structure.files import File, Files

CLI_DIR = "reference/cli"
CLI_INDEX = f"{CLI_DIR}/index.md"
MARKDOWN_SPECIAL = re.compile(r"([\\`*_\[\]|<>#])")


def subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The subparsers of ``parser`` by name, in the order ``urident --help`` lists them."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def documented_actions(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """The actions a user can see in ``--help`` (suppressed ones and ``-h`` left out)."""
    return [a for a in parser._actions
            if a.help is not argparse.SUPPRESS and not isinstance(a, argparse._HelpAction)]


def escape(text: str) -> str:
    return MARKDOWN_SPECIAL.sub(lambda m: html.escape(m.group(1)) if m.group(1) in "<>" else "\\" + m.group(1),
                                " ".join(text.split()))


def help_text(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    if not action.help:
        return ""
    try:
        return parser._get_formatter()._expand_help(action)  # %(default)s etc., as --help prints them
    except (KeyError, TypeError, ValueError):
        return action.help


def invocation(action: argparse.Action) -> str:
    if not action.option_strings:
        return action.metavar or action.dest
    if action.nargs == 0:
        return ", ".join(action.option_strings)
    formatter = argparse.HelpFormatter("urident")
    return formatter._format_action_invocation(action)


def command_page(name: str, parser: argparse.ArgumentParser) -> str:
    lines = [f"# urident {name}", "",
             "<!-- generated from the argparse parser by docs/hooks/cli_reference.py: edit the parser, not this page -->",
             ""]
    if parser.description:
        lines += [escape(parser.description), ""]
    usage = parser.format_usage().strip()
    lines += ["```text", usage.removeprefix("usage: "), "```", ""]
    shown = {id(a) for a in documented_actions(parser)}
    for group in parser._action_groups:
        actions = [a for a in group._group_actions if id(a) in shown]
        if not actions:
            continue
        title = {"positional arguments": "Arguments", "options": "Options",
                 "optional arguments": "Options"}.get(group.title or "", group.title or "Options")
        lines += [f"## {title[:1].upper()}{title[1:]}", ""]
        if group.description:
            lines += [escape(group.description), ""]
        lines += ["| argument | description |", "| --- | --- |"]
        for action in actions:
            described = escape(help_text(parser, action))
            if action.choices and "{" not in invocation(action):
                described += f" (one of {', '.join('`' + str(c) + '`' for c in action.choices)})"
            if action.required and action.option_strings:
                described = "**Required.** " + described
            lines.append(f"| `{invocation(action)}` | {described} |")
        lines.append("")
    return "\n".join(lines)


def index_page(parser: argparse.ArgumentParser, commands: dict[str, argparse.ArgumentParser]) -> str:
    helps = {a.dest: a.help for a in subcommand_action(parser)._choices_actions}
    lines = ["# Command-line reference", "",
             "Generated at every build from the argparse parsers (`urident.cli.main.get_argument_parser`), "
             "so every flag of the installed version is here. `urident COMMAND --help` prints the same.",
             "", "| command | what it does |", "| --- | --- |"]
    for name, sub in commands.items():
        summary = helps.get(name) or (sub.description or "").split(". ")[0]
        lines.append(f"| [`urident {name}`]({name}.md) | {escape(summary or '')} |")
    lines += ["", "Exit codes (every command): 0 success, 2 bad input, 3 a safety check refused or no "
              "controller at the address (nothing moved), 4 run aborted after it started (robot stopped, "
              "log kept), 70 internal error, 130 interrupted before motion.", ""]
    return "\n".join(lines)


def subcommand_action(parser: argparse.ArgumentParser) -> argparse._SubParsersAction:
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))


def cli_pages() -> dict[str, str]:
    """``{src_uri: markdown}`` for the index and every subcommand."""
    from urident.cli.main import get_argument_parser

    parser = get_argument_parser()
    commands = subcommands(parser)
    pages = {CLI_INDEX: index_page(parser, commands)}
    for name, sub in commands.items():
        pages[f"{CLI_DIR}/{name}.md"] = command_page(name, sub)
    return pages


def listed(nav) -> set[str]:
    """Every page path a nav (as written in mkdocs.yml) lists."""
    found: set[str] = set()
    if isinstance(nav, str):
        found.add(nav)
    elif isinstance(nav, dict):
        for value in nav.values():
            found |= listed(value)
    elif isinstance(nav, list):
        for item in nav:
            found |= listed(item)
    return found


def with_cli_section(nav, section: list) -> list:
    """``nav`` with the entry pointing at the CLI index replaced by the generated section."""
    out = []
    for item in nav:
        if isinstance(item, dict):
            (title, value), = item.items()
            if value == CLI_INDEX:
                item = {title: section}
            elif isinstance(value, list):
                item = {title: with_cli_section(value, section)}
        out.append(item)
    return out


def on_files(files: Files, config) -> Files:
    pages = cli_pages()
    for src_uri, content in pages.items():
        files.append(File.generated(config, src_uri, content=content))
    section = [CLI_INDEX] + [{f"urident {uri.rsplit('/', 1)[1][:-3]}": uri}
                             for uri in pages if uri != CLI_INDEX]
    nav = config.nav
    if nav:
        nav = with_cli_section(nav, section)
        missing = sorted(f.src_uri for f in files.documentation_pages()
                         if f.src_uri not in listed(nav))
        if missing:
            nav.append({"More": missing})
        config.nav = nav
    return files


SPHINX_ROLE = re.compile(r":(?:class|func|meth|mod|attr|data|exc|obj):(?=<code>)")


def on_page_content(html_text: str, page, config, files) -> str:
    """Docstrings write Sphinx roles (:func:`x`); the API page shows just the code name."""
    return SPHINX_ROLE.sub("", html_text)
