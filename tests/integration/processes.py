"""The process table, for the tests that check that no process outlives an interrupted command."""

from __future__ import annotations

import time
from pathlib import Path


def session_pids(sid: int) -> list[int]:
    """Pids of the live processes of session ``sid`` (zombies aside), read from /proc."""
    pids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] != "Z":
            pids.append(int(stat.parent.name))
    return pids


def session_left_after(sid: int, grace_s: float = 10.0) -> list[int]:
    """The live processes of session ``sid`` still there ``grace_s`` seconds from now (checked every 0.1 s; [] as
    soon as none is left).  A process that a command killed on its way out may need a moment to die on a loaded
    machine (``kill`` returns before the target has exited): outliving the command by that moment is not
    outliving it."""
    deadline = time.monotonic() + grace_s
    while (left := session_pids(sid)) and time.monotonic() < deadline:
        time.sleep(0.1)
    return left
