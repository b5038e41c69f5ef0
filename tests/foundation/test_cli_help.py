"""Every help line of the ``feelium`` command reads as a sentence: a group's help is never just its name."""

from __future__ import annotations

import argparse
import re
from collections.abc import Iterator

from feelium.cli import build_parser

DOUBLED = re.compile(r"\b(\w+) \1\b")


def _parsers(parser: argparse.ArgumentParser, path: str = "feelium") -> Iterator[tuple[str, argparse.ArgumentParser]]:
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, child in action.choices.items():
                yield from _parsers(child, f"{path} {name}")


def test_no_help_text_repeats_a_word() -> None:
    """``feelium --help`` once listed ``token       token``: the group had no help of its own."""
    repeated = []
    for path, parser in _parsers(build_parser()):
        texts = [parser.description or ""] + [a.help for a in parser._actions if isinstance(a.help, str)]
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                texts += [c.help for c in action._choices_actions if isinstance(c.help, str)]
        repeated += [f"{path}: {m.group(0)!r}" for text in texts for m in DOUBLED.finditer(" ".join(text.split()))]
    assert not repeated, repeated


def test_every_command_has_its_own_help() -> None:
    """The listing prints each command beside its help: a help that is only the name read "token token"."""
    top = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    bare = [c.dest for c in top._choices_actions if (c.help or "").strip().lower() == c.dest]
    assert not bare, bare
