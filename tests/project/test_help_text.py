"""The command line's help speaks of ideas, never of the tracker's issue numbers."""
import argparse
import re

from bench.cli import build_parser


def _help_texts(parser, path="hftrace"):
    """(command path, text) of every description and argument help under ``parser``."""
    yield path, parser.description or ""
    for action in parser._actions:
        yield path, action.help or ""
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                yield f"{path} {choice.dest}", choice.help or ""
            for name, sub in action.choices.items():
                yield from _help_texts(sub, f"{path} {name}")


def test_no_help_text_cites_an_issue_number():
    cited = [(path, text) for path, text in _help_texts(build_parser())
             if re.search(r"\bissue\b\s*#?\d|\bthe issue's\b", text, re.IGNORECASE)]
    assert cited == [], cited
