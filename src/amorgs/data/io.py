"""Atomic file writes: a reader (or a rerun after a crash) sees either the old file or the complete new one.

Every writer goes through :func:`atomic_path`: the content is written to a hidden temporary file in the
destination's own directory (same filesystem, so the final ``os.replace`` is atomic), flushed to disk, and
only then renamed over the destination.  A process killed mid-write leaves at most a stray ``.*.tmp`` file,
never a truncated table.  The file gets the permissions a plain ``open(path, "w")`` would give it: those of the
file it replaces, or ``0o666`` less the process umask for a new file (``mkstemp`` alone would make it ``0o600``,
unreadable to the group).
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pandas as pd


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on a clean exit fsync it and ``os.replace`` it onto ``path``.

    On an exception the temporary file is removed and ``path`` is left untouched.
    """
    dest = Path(path)
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".tmp", dir=dest.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        os.chmod(tmp, _mode_of_new_file(dest))
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, dest)
    finally:
        tmp.unlink(missing_ok=True)


def _mode_of_new_file(dest: Path) -> int:
    """The permission bits ``open(dest, "w")`` would leave: an existing file's own, else 0o666 less the umask."""
    try:
        return dest.stat().st_mode & 0o7777
    except FileNotFoundError:
        pass
    mask = os.umask(0o022)  # the only portable way to read the umask is to set it; restore at once
    os.umask(mask)
    return 0o666 & ~mask


def write_parquet(df: pd.DataFrame, path: str | Path) -> None:
    """Write ``df`` (index dropped) to ``path`` atomically."""
    with atomic_path(path) as tmp:
        df.to_parquet(tmp, index=False)


def check_writable_folder(folder: str | Path, option: str) -> Path:
    """``folder``, made if missing, after proving that a file can be written in it (a probe file created and
    removed); otherwise ``InputError`` naming ``option`` — before a command does work it could not save."""
    from amorgs.errors import InputError

    path = Path(folder)
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path, prefix=".amorgs-probe-"):
            pass
    except OSError as exc:
        raise InputError(f"{option} {folder}: cannot write there ({exc.strerror or exc})") from None
    return path


def write_json(obj: object, path: str | Path) -> None:
    """Write ``obj`` as indented JSON (NaN written as ``null``) to ``path`` atomically."""
    text = json.dumps(_nan_to_none(obj), indent=2, sort_keys=True) + "\n"
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def read_json(path: str | Path) -> object:
    """Read a JSON file written by :func:`write_json`."""
    return json.loads(Path(path).read_text())


def _nan_to_none(obj: object) -> object:
    if isinstance(obj, float) and obj != obj:
        return None
    if isinstance(obj, dict):
        return {k: _nan_to_none(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_nan_to_none(v) for v in obj]
    return obj
