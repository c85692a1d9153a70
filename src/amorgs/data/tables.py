"""The solution table: one row per local solve (see ``docs/data-format.md``).

Columns common to every problem are listed in :data:`COMMON_COLUMNS` with their kind; each problem adds its
decision variables twice, as ``guess_<name>`` (the initial guess) and ``<name>`` (the solution, NaN when the
solver returned none).  ``(problem, alpha, seed, start)`` identifies a row; ``shard`` records which
generate job produced it.  Only :data:`TIMING_COLUMNS` differ between two runs of the same configuration.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import pandas as pd
from pandas.api import types

#: Column → kind (``str``, ``float``, ``int``, ``bool``) of the columns every solution table carries.
COMMON_COLUMNS: dict[str, str] = {
    "problem": "str",
    "alpha": "float",
    "seed": "int",
    "shard": "int",
    "start": "int",
    "status": "str",
    "converged": "bool",
    "solver_success": "bool",
    "objective": "float",
    "iterations": "int",
    "wall_s": "float",
    "cpu_s": "float",
    "defect": "float",
    "verify_defect": "float",
    "options_hash": "str",
}

#: The columns that identify one solve.
KEY_COLUMNS = ("problem", "alpha", "seed", "start")

#: Wall-clock and CPU seconds: the only columns that change when the same configuration is rerun.
TIMING_COLUMNS = ("wall_s", "cpu_s")

_KIND_CHECKS = {
    "str": lambda s: types.is_string_dtype(s) or types.is_object_dtype(s),
    "float": types.is_float_dtype,
    "int": types.is_integer_dtype,
    "bool": types.is_bool_dtype,
}


def variable_columns(variable_names: Sequence[str]) -> list[str]:
    """The guess and solution columns of a problem, in table order: ``guess_<v>…`` then ``<v>…``."""
    return [f"guess_{v}" for v in variable_names] + list(variable_names)


def validate_solutions(df: pd.DataFrame, variable_names: Sequence[str] | None = None, where: str = "") -> None:
    """Check columns, kinds and key uniqueness; ``ValueError`` names the file (``where``) and the column.

    ``variable_names`` given: the guess and solution columns of those variables must be present and float.
    """
    prefix = f"{where}: " if where else ""
    expected = dict(COMMON_COLUMNS)
    expected.update({c: "float" for c in variable_columns(variable_names or ())})
    missing = [c for c in expected if c not in df.columns]
    if missing:
        raise ValueError(f"{prefix}solution table lacks column(s) {missing}")
    for col, kind in expected.items():
        if len(df) and not _KIND_CHECKS[kind](df[col]):
            raise ValueError(f"{prefix}column {col!r} should be {kind}, has dtype {df[col].dtype}")
    dup = df.duplicated(list(KEY_COLUMNS))
    if dup.any():
        row = df.loc[dup, list(KEY_COLUMNS)].iloc[0].to_dict()
        raise ValueError(f"{prefix}{int(dup.sum())} duplicated solve(s), first {row}")


def merge_shards(frames: Iterable[pd.DataFrame]) -> pd.DataFrame:
    """Concatenate shard tables of one (problem, α) into one table sorted by ``(shard, start)``.

    The shards must have the same columns (in any order: the first shard's order is kept) and no solve may
    appear twice (``ValueError`` otherwise).
    """
    frames = list(frames)
    if not frames:
        raise ValueError("merge_shards needs at least one shard")
    columns = list(frames[0].columns)
    for i, f in enumerate(frames[1:], start=1):
        if set(f.columns) != set(columns):
            diff = sorted(set(f.columns) ^ set(columns))
            raise ValueError(f"shard {i} has different columns from shard 0: {diff}")
        frames[i] = f[columns]  # the same columns in another order (a file written before a column moved)
    merged = pd.concat(frames, ignore_index=True).sort_values(["shard", "start"], kind="stable")
    merged = merged.reset_index(drop=True)
    validate_solutions(merged)
    return merged
