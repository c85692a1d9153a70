"""Errors a user can cause (bad input file, corrupt or tampered data): the CLI prints their message as one
line naming the file, without a traceback.  Configuration errors are :class:`amorgs.config.ConfigError`."""

from __future__ import annotations


class InputError(ValueError):
    """An input file is missing, unreadable, or fails an integrity check; the message names the file."""
