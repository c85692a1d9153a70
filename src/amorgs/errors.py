"""Errors a user can cause: the CLI prints their message as one line naming the file or key, without a
traceback (:func:`amorgs.cli.main`)."""

from __future__ import annotations


class ConfigError(ValueError):
    """An invalid configuration; the message names the file and the dotted key."""


class InputError(ValueError):
    """An input file is missing, unreadable, or fails an integrity check; the message names the file."""
