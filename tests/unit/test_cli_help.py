"""Every `amorgs` subcommand documents itself: help text on every option and one example in its epilog.

The test walks the real parser, so a subcommand or an option added later is held to the same rule.
"""

from __future__ import annotations

import argparse

import pytest

from amorgs.cli import build_parser


def subcommands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    (action,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(action.choices)


def test_there_are_subcommands():
    assert {"step", "check-outputs", "ui", "config-schema", "design", "library-grow"} <= set(subcommands())


def test_the_step_subcommand_knows_every_rule():
    from amorgs.steps import registry

    description = subcommands()["step"].description
    assert all(f"  {name} " in description for name in registry())
    assert all(step.description for step in registry().values())


@pytest.mark.parametrize("name", sorted(subcommands()))
def test_every_option_has_help(name):
    parser = subcommands()[name]
    missing = [
        "/".join(a.option_strings) or a.dest
        for a in parser._actions
        if not isinstance(a, argparse._HelpAction) and not (a.help and a.help.strip() and a.help != argparse.SUPPRESS)
    ]
    assert not missing, f"amorgs {name}: option(s) without help text: {missing}"


@pytest.mark.parametrize("name", sorted(subcommands()))
def test_every_subcommand_shows_an_example(name):
    parser = subcommands()[name]
    assert parser.formatter_class is argparse.RawDescriptionHelpFormatter, f"amorgs {name}: epilog formatting"
    epilog = parser.epilog or ""
    assert "example:" in epilog.lower() and f"amorgs {name}" in epilog, f"amorgs {name}: no example in the epilog"
    assert f"amorgs {name}" in parser.format_help()
