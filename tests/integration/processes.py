"""The process table, for the tests that check that no process outlives an interrupted command."""

from __future__ import annotations

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
