"""Deterministic per-shard seeds: the same (base seed, problem, α, shard) always gives the same seed.

Python's ``hash()`` of a string changes between interpreter runs, so the problem name enters as its CRC-32
and α as an integer number of micro-units; numpy's ``SeedSequence`` mixes these stable integers into one
well-spread 32-bit seed.
"""

from __future__ import annotations

import zlib

import numpy as np


def shard_seed(base_seed: int, problem: str, alpha: float, shard: int) -> int:
    """The seed of shard ``shard`` of ``problem`` at ``alpha`` (radians or dimensionless, as the problem's α).

    α is rounded to 1e-6 before mixing, so values that agree to six decimals share seeds; configs keep α
    labels distinct at three decimals, far coarser than that.
    """
    if base_seed < 0 or shard < 0:
        raise ValueError(f"base_seed and shard must be ≥ 0, got {base_seed}, {shard}")
    entropy = [int(base_seed), zlib.crc32(problem.encode()), int(round(float(alpha) * 1_000_000)), int(shard)]
    return int(np.random.SeedSequence(entropy).generate_state(1, dtype=np.uint32)[0])


def cell_seed(base_seed: int, problem: str, alpha: float, sampler: str) -> int:
    """The seed of one ablation cell (``sampler`` at ``alpha``), mixed like :func:`shard_seed` with the
    sampler's name in place of the shard number."""
    if base_seed < 0:
        raise ValueError(f"base_seed must be ≥ 0, got {base_seed}")
    entropy = [int(base_seed), zlib.crc32(problem.encode()), int(round(float(alpha) * 1_000_000)), zlib.crc32(sampler.encode())]
    return int(np.random.SeedSequence(entropy).generate_state(1, dtype=np.uint32)[0])


def transfer_seed(base_seed: int, problem: str, source_alpha: float, alpha: float, shard: int) -> int:
    """The seed of one transfer shard: the solutions of ``source_alpha`` solved at ``alpha`` (issue 38), mixed
    like :func:`shard_seed` with the source α as one more integer of micro-units."""
    if base_seed < 0 or shard < 0:
        raise ValueError(f"base_seed and shard must be ≥ 0, got {base_seed}, {shard}")
    entropy = [int(base_seed), zlib.crc32(problem.encode()), int(round(float(source_alpha) * 1_000_000)),
               int(round(float(alpha) * 1_000_000)), int(shard)]
    return int(np.random.SeedSequence(entropy).generate_state(1, dtype=np.uint32)[0])
