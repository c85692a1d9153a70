"""Mark the library's rows made before issue 37 with the code that made them, from git history (run once).

Rows exported before issue 37 carry no NLP fingerprint.  The code that solved them is known from the commit
each shard was exported from: the first committed manifest that lists the shard names it (the file entry's
``git_commit``, or the compaction ``sources`` entry holding the shard).  Three codes solved those rows:

* ``A``: every commit before 645f351 (the Jacobian rewrite);
* ``B``: 645f351 up to b676b97 (exclusive: the C RK8 kernel);
* ``C``: from b676b97 on (today's NLP; its fingerprints are those of generation 4's rows).

Each file entry without ``nlp_fingerprints`` gains ``codes`` ({code: shards}) and the manifest gains
``legacy_codes`` (what each letter is, its commit range).  Shards whose export commit is not in the repository
are counted under ``unknown``.  Usage: ``python scripts/library_legacy_codes.py [data/library/cr3bp]``.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from amorgs.checkout import is_reachable
from amorgs.data.io import write_json

CODES = {
    "A": {"commits": "… up to 8c85173 (before 645f351)", "what": "the NLP before the cheaper constraint Jacobian"},
    "B": {"commits": "645f351 … 9e2f574 (before b676b97)", "what": "the cheaper constraint Jacobian, SX RK8 step"},
    "C": {"commits": "b676b97 …", "what": "the C RK8 kernel: today's NLP"},
}


def git(*args: str) -> str:
    return subprocess.run(["git", *args], capture_output=True, text=True, check=True).stdout


def code_of(commit: str, cache: dict) -> str:
    if commit not in cache:
        if not is_reachable(commit, commit):  # not in the repository
            cache[commit] = "unknown"
        else:
            cache[commit] = "C" if is_reachable("b676b97", commit) else "B" if is_reachable("645f351", commit) else "A"
    return cache[commit]


def first_exports(manifest_path: str) -> dict[tuple[str, int], str]:
    """(α directory, shard) → the commit it was exported from, read from the first committed manifest holding it."""
    first: dict[tuple[str, int], str] = {}
    for commit in git("log", "--reverse", "--format=%H", "--", manifest_path).split():
        manifest = json.loads(git("show", f"{commit}:{manifest_path}"))
        for entry in manifest.get("files", []):  # format 1 manifests (before the consolidated files) hold none
            label = entry["file"].split("/")[0]
            for source in entry.get("sources") or [entry]:
                for shard in source["shards"]:
                    first.setdefault((label, shard), source.get("git_commit", "unknown"))
    return first


def main(library: str = "data/library/cr3bp") -> None:
    path = Path(library) / "provenance.json"
    manifest = json.loads(path.read_text())
    first = first_exports(path.as_posix())
    cache: dict[str, str] = {}
    totals: dict[str, int] = {}
    for entry in manifest["files"]:
        if entry.get("nlp_fingerprints"):
            continue
        label = entry["file"].split("/")[0]
        codes: dict[str, int] = {}
        for shard in entry["shards"]:
            exported = first.get((label, shard))
            if exported is None:  # not yet committed: the entry's own export
                exported = next((s["git_commit"] for s in entry.get("sources") or [entry] if shard in s["shards"]),
                                "unknown")
            code = code_of(exported, cache)
            codes[code] = codes.get(code, 0) + 1
        entry["codes"] = dict(sorted(codes.items()))
        for code, n in codes.items():
            totals[f"generation {entry.get('generation', 1)}, code {code}"] = totals.get(
                f"generation {entry.get('generation', 1)}, code {code}", 0) + n
    manifest["legacy_codes"] = {**CODES, "shards": dict(sorted(totals.items())),
                                "how": "scripts/library_legacy_codes.py: each shard's export commit, from the first "
                                       "committed manifest that lists it"}
    write_json(manifest, path)
    print(json.dumps(manifest["legacy_codes"]["shards"], indent=1))


if __name__ == "__main__":
    main(*sys.argv[1:])
