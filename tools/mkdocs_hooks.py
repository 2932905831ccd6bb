"""Documentation build hook: the command-line reference is generated from the `arap` argument parser, so it cannot
drift from the program."""

from __future__ import annotations

import argparse
from typing import Any

MARKER = "<!-- arap command-line reference -->"


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:  # argparse keeps its subcommands in the sub-parsers action
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def cli_reference() -> str:
    """Markdown: the help of ``arap`` and of each of its commands."""
    from arap.cli import build_parser

    parser = build_parser()
    parts = ["## arap", "", "```text", parser.format_help().rstrip(), "```", ""]
    for name, sub in _subcommands(parser).items():
        parts += [f"## arap {name}", "", "```text", sub.format_help().rstrip(), "```", ""]
    return "\n".join(parts)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    if MARKER in markdown:
        return markdown.replace(MARKER, cli_reference())
    return markdown
