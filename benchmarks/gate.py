"""What the library's gate costs (issue 39): CPU of export's checks per shard against the CPU that solved it.

``amorgs library-export`` re-verifies every new row (``amorgs.data.library.verify_rows``: the independent DOP853
re-propagation of each successful solve) and re-solves one seeded start per new shard bit for bit
(``resolve_check``).  This script takes the library's shards of today's code (rows with an ``nlp_fingerprint``
equal to this checkout's: only those re-solve), up to ``--shards`` per α, runs both checks on them in this
process and prints, per α: shards, rows, the gate's CPU seconds per shard (verify, re-solve) and its share of
the shards' own solve CPU (``cpu_s``) — the overhead that library growth pays.  CPU is ``time.process_time``
of this process (one core; machine load barely changes it).  Writes the table to ``docs/performance.md``
(section ``gate``)::

    python benchmarks/gate.py                       # data/library, config/library.yaml, 4 shards per α
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import pandas as pd

from amorgs.config import load_config
from amorgs.data.library import read_library, read_manifest, resolve_check, verify_rows
from amorgs.problems import get_problem

sys.path.insert(0, str(Path(__file__).resolve().parent))
from solve import machine, markdown, write_section  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--library-dir", default="data/library")
    ap.add_argument("--config", default="config/library.yaml")
    ap.add_argument("--shards", type=int, default=4, help="shards per α (default 4)")
    args = ap.parse_args()
    options = load_config(args.config).problems.cr3bp.solver
    problem = get_problem("cr3bp")
    solver = problem.make_local_solver(options)
    manifest = read_manifest(args.library_dir, "cr3bp")
    rows = []
    for entry in manifest["per_alpha"]:
        alpha = float(entry["alpha"])
        df = read_library(args.library_dir, "cr3bp", f"{alpha:.3f}")
        mine = df[df["nlp_fingerprint"] == solver.fingerprint(alpha)]
        shards = sorted(mine["shard"].unique())[: args.shards]
        if not shards:
            continue
        verify_s = resolve_s = solve_s = 0.0
        n_rows = 0
        for shard in shards:
            table = mine[mine["shard"] == shard]
            t0 = time.process_time()
            verify_rows(table, problem, options, f"shard {shard}")
            t1 = time.process_time()
            resolve_check(table, solver, problem, f"shard {shard}")
            t2 = time.process_time()
            verify_s, resolve_s = verify_s + t1 - t0, resolve_s + t2 - t1
            solve_s += float(table["cpu_s"].sum())
            n_rows += len(table)
        rows.append({"α": f"{alpha:g}", "shards": len(shards), "rows": n_rows,
                     "solve CPU s per shard": solve_s / len(shards),
                     "verify CPU s per shard": verify_s / len(shards),
                     "re-solve CPU s per shard": resolve_s / len(shards),
                     "gate share of solve CPU %": 100.0 * (verify_s + resolve_s) / solve_s})
        print(rows[-1], flush=True)
    table = pd.DataFrame(rows)
    total = 100.0 * ((table["verify CPU s per shard"] + table["re-solve CPU s per shard"]) * table["shards"]).sum() / (
        (table["solve CPU s per shard"] * table["shards"]).sum())
    text = (f"The library gate's cost (`python benchmarks/gate.py --shards {args.shards}`; {machine()}; the shards of "
            f"today's code in {args.library_dir}, {int(table['shards'].sum())} shards): per α the CPU of export's "
            "row re-verification and of its one re-solve per shard, against the CPU that solved the shard. "
            f"Overall the gate adds **{total:.1f} %** to the library's solve CPU.\n\n" + markdown(rows))
    print(text)
    write_section("gate", text)


if __name__ == "__main__":
    main()
