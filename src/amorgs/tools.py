"""The ``amorgs`` tools around the workflow (the workflow's own steps are :mod:`amorgs.steps`).

``library-export`` (check finished library-config shards and consolidate them into ``data/library``),
``library-compact`` (one compact file per (α, generation): the same rows, fewer bytes),
``library-grow`` (batches of library generation, each exported), ``models-export`` (ship a run's checkpoints),
``design`` (N good transfers at one α), ``boundary-conditions`` (recompute or check the resource), ``ui``
(the MLflow UI on ``results/mlflow``), ``frontier-plan`` and ``frontier`` (the frontier study's fold configs,
and the aggregation of its finished folds), ``check-outputs`` (every output a config promises exists, is
non-empty and is tracked), ``config-schema`` (the JSON Schema generated from the config model) and
``reference-export`` (commit a finished run's tables and figures with provenance, or ``--check`` them) and
``reference-certify`` (re-solve a seeded sample of a reference's starts: the reproducibility certificate).  Heavy
imports happen inside the command that needs them.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

from amorgs.ablation.arms import ARMS, REUSE_ARM
from amorgs.analysis.structure_params import ETA
from amorgs.config import SCHEMA_PATH
from amorgs.design.search import STRATEGIES as DESIGN_STRATEGIES
from amorgs.models.names import PAPER_MODELS
from amorgs.problems import PROBLEMS
from amorgs.problems.cr3bp import BETA_KG
from amorgs.solvers.basin_hopping import HopSettings

#: The hop defaults of ``design --strategy mbh`` and ``global-search``.
HOPS = HopSettings()
#: One example per tool, shown in its ``--help`` epilog.
EXAMPLES = {
    "library-export": "amorgs library-export --solutions-dir results/library-grow/results/cr3bp/solutions "
    "--library-dir data/library",
    "library-compact": "amorgs library-compact --library-dir data/library   # then commit data/library",
    "models-export": "amorgs models-export --models-dir results/cr3bp/models --dest data/models/cr3bp",
    "boundary-conditions": "amorgs boundary-conditions --check     # recompute and compare with the stored resource",
    "ui": "amorgs ui --port 5000     # then browse http://127.0.0.1:5000",
    "check-outputs": "amorgs check-outputs --config config/smoke.yaml   # exit 0: complete; 1: missing or broken;\n"
    "                                                    # 3: complete but untracked in MLflow",
    "config-schema": "amorgs config-schema --write     # after changing src/amorgs/config.py",
    "config-show": "amorgs config-show config/smoke.yaml     # what the smoke run uses, every key",
    "frontier-plan": "amorgs frontier-plan --config config/frontier.yaml --runs-dir results/frontier/runs --loo 0.1 0.5 1.0 "
    "--sparse 3 5",
    "frontier": "amorgs frontier results/frontier/runs/*/ --dest results/frontier",
    "best-known": "amorgs best-known --from-library data/library --add results/global-search/solutions.parquet",
    "global-search": "amorgs global-search --alpha 0.3 --searches 30 --budget 10000 --workers 2 "
    "--dest results/global-search/alpha=0.300",
    "reference-export": "amorgs reference-export --config config/study.yaml --dest reference/study   # after the run\n"
    "  amorgs reference-export --dest reference/study --check                      # verify the committed files",
    "reference-certify": "amorgs reference-certify reference/frontier/sparse-3 --sample 20 --seed 0   # exit 1: a re-solve differs\n"
    "  amorgs reference-certify reference/frontier/sparse-3 --at-commit   # with the code that made it\n"
    "  amorgs reference-certify --all --sample 3                          # every reference by its route (CI)",
}


def cmd_library_compact(args: argparse.Namespace) -> None:
    from amorgs.data.library import compact_library

    summary = compact_library(args.library_dir, args.problem)
    before, after = summary["before"], summary["after"]
    if not summary["files_rewritten"]:
        print(f"{args.library_dir}/{args.problem}: already compact ({before['files']} files, {before['bytes'] / 2**20:.1f} MiB)")
        return
    print(f"{args.library_dir}/{args.problem}: {before['files']} files, {before['bytes'] / 2**20:.1f} MiB -> "
          f"{after['files']} files, {after['bytes'] / 2**20:.1f} MiB (same rows, checked bit for bit)")


def cmd_library_export(args: argparse.Namespace) -> None:
    from amorgs.config import load_config
    from amorgs.data.library import export_library

    summary = export_library(args.solutions_dir, args.library_dir, args.problem, load_config(args.config), args.config)
    if not summary["files_added"]:
        print(f"{args.library_dir}/{args.problem}: nothing new: the {summary['held_identical']} shard(s) under "
              f"{args.solutions_dir} are already in the library, identical")
        return
    print(
        f"{args.library_dir}/{args.problem}: {summary['files_added']} new file(s), {summary['rows_added']} new rows; "
        f"library now {summary['shards']} shards in {summary['files']} files, {summary['rows']} solves "
        f"({summary['converged']} converged, {summary['cpu_hours']:.2f} CPU-hours, "
        f"{summary['bytes_per_row']:.0f} bytes per solve)"
    )


def cmd_models_export(args: argparse.Namespace) -> None:
    from amorgs.config import load_config
    from amorgs.models.shipped import export_models, export_selector

    if args.selector:
        manifest = export_selector(args.models_dir, args.dest, load_config(args.config), args.config, args.library_dir)
        record = manifest["selector"]
        print(f"{args.dest}: selector of {args.config} (transfer pairs of {len(record['train_alphas'])} α) shipped "
              f"beside the checkpoints; manifest {args.dest}/provenance.json")
        return
    manifest = export_models(args.models_dir, args.dest, load_config(args.config), args.config, args.library_dir)
    size = sum(f["bytes"] for f in manifest["files"])
    print(f"{args.dest}: {len(manifest['files'])} checkpoints ({size / 1e6:.2f} MB), trained on a library of "
          f"{manifest['library_rows']} solves; manifest {args.dest}/provenance.json")


def cmd_library_grow(args: argparse.Namespace) -> None:
    from amorgs.library_grow import grow

    summaries = grow(args.config, args.library_dir, args.problem, args.workdir, args.cores, args.batches, args.hours,
                     args.nice, alphas=args.alphas, until_converged=args.until_converged, profile=args.profile,
                     new_library=args.new_library)
    failed = [s for s in summaries if s["snakemake_exit"] != 0]
    if failed:
        raise SystemExit(f"library-grow: Snakemake failed in batch {failed[-1]['batch']} (exit "
                         f"{failed[-1]['snakemake_exit']}); what finished was exported — see its log in {args.workdir}")


def cmd_boundary_conditions(args: argparse.Namespace) -> None:
    from amorgs.problems.cr3bp import boundary

    if not args.check:
        boundary.write_boundary_conditions(args.output)
        print(f"{args.output or boundary.resource_path()}: written")
        return
    stored = boundary.load_boundary_conditions(args.output)
    bad = _compare(stored, boundary.compute_boundary_conditions(), "", rel_tol=args.rel_tol)
    where = args.output or boundary.resource_path()
    if bad:
        raise SystemExit(f"{where} differs from a fresh computation:\n  " + "\n  ".join(bad))
    print(f"{where}: matches a fresh computation (relative tolerance {args.rel_tol:g})")


def _compare(stored: object, fresh: object, path: str, rel_tol: float) -> list[str]:
    """Differences between two JSON trees: numbers compared to ``rel_tol``, everything else exactly."""
    if isinstance(stored, dict) and isinstance(fresh, dict):
        keys = sorted(set(stored) | set(fresh))
        return [d for k in keys for d in _compare(stored.get(k), fresh.get(k), f"{path}.{k}".lstrip("."), rel_tol)]
    if isinstance(stored, list) and isinstance(fresh, list) and len(stored) == len(fresh):
        return [d for i, (a, b) in enumerate(zip(stored, fresh)) for d in _compare(a, b, f"{path}[{i}]", rel_tol)]
    if isinstance(stored, (int, float)) and isinstance(fresh, (int, float)) and not isinstance(stored, bool):
        return [] if math.isclose(stored, fresh, rel_tol=rel_tol, abs_tol=rel_tol) else [f"{path}: {stored} vs {fresh}"]
    return [] if stored == fresh else [f"{path}: {stored!r} vs {fresh!r}"]


def cmd_design(args: argparse.Namespace) -> None:
    from amorgs.design import DesignRequest, run_design
    from amorgs.design.search import DEFAULT_FRONTIERS

    request = DesignRequest(
        alpha=args.alpha, n=args.n, sampler=args.sampler, beta_kg=args.beta, eta=args.eta, seed=args.seed,
        workers=args.workers, round_size=args.round_size, max_starts=args.max_starts, max_cpu_s=args.max_cpu_s,
        library_dir=args.library_dir, models_dir=args.models_dir, config=args.config,
        frontier=tuple(args.frontier) if args.frontier else DEFAULT_FRONTIERS, strategy=args.strategy, hop=args.hop,
        hop_scale=args.hop_scale, hop_shape=args.hop_shape, patience=args.patience,
        hop_variables=tuple(args.hop_variables),
    )
    result, paths = run_design(request, args.output, track=not args.no_mlflow, store_dir=args.mlflow_dir,
                               progress=not args.quiet)
    out = paths["reports"][0].parent
    print(f"{out}: {len(result.selected)} of {args.n} solutions (α = {args.alpha:g} N, m_f ≥ {args.beta:g} kg, "
          f"η = {args.eta:g}) from {result.starts} starts, {result.cpu_s:.0f} CPU s, {result.wall_s:.0f} s wall")
    known = result.info.get("best_known_m_f_kg")
    if known is not None and len(result.selected):
        gaps = ", ".join(f"{g:.3f}" for g in result.selected["below_best_known_kg"])
        print(f"best known m_f at α = {args.alpha:g}: {known:.3f} kg ({result.info['best_known_source']}); the "
              f"returned solutions are {gaps} kg below it ({result.info.get('strategy', args.strategy)})")
    if result.best_known is not None:
        source = result.best_known["source"]
        print(f"best known trajectory (the best-known record's, found at α = "
              f"{float(source.get('from_alpha', args.alpha)):g} N in {source.get('where') or 'an unnamed run'}): "
              f"{out / 'best_known.csv'}, {out / 'trajectories' / 'best-known.oem'}")
    if result.found < args.n:
        print(f"amorgs design: only {result.found} of {args.n} found before the budget ran out "
              f"({result.stop_reason}); raise --max-starts / --max-cpu-s or lower -n", file=sys.stderr)
        raise SystemExit(3)


def cmd_frontier_plan(args: argparse.Namespace) -> None:
    from amorgs.frontier import plan, run_command

    folds = plan(args.config, args.runs_dir, tuple(args.loo), tuple(args.sparse), tuple(args.set))
    for fold, run in folds:
        print(f"# {fold.name}: train {list(fold.train)}, test {list(fold.test)}")
        print(run_command(run, args.snakemake))
    print(f"# then: amorgs frontier {' '.join(str(run) for _, run in folds)} --dest results/frontier")


def cmd_frontier(args: argparse.Namespace) -> None:
    from amorgs.frontier import OUTPUTS, aggregate

    table = aggregate(args.runs, args.dest, tuple(args.learned) if args.learned else None, args.reuse, args.n_boot, args.seed,
                      track=not args.no_mlflow, store_dir=args.mlflow_dir)
    ratios = table[table["ratio_to_reuse"].notna() & (table["unit"] == "iterations")
                   & (table["target"] == "high_quality")]
    for r in ratios.itertuples(index=False):
        print(f"{r.run:>12}  α = {r.alpha:<5g} gap {r.gap:.3g} N ({r.gap_relative:.0%})  {r.sampler}: aRT ÷ reuse "
              f"= {r.ratio_to_reuse:.3g} ({r.ratio_to_reuse_ci95_low:.3g}–{r.ratio_to_reuse_ci95_high:.3g}), n = {r.n}")
    print(f"{args.dest}: {', '.join(OUTPUTS)}")


def cmd_best_known(args: argparse.Namespace) -> None:
    from pathlib import Path

    import pandas as pd

    from amorgs.data import best_known as bk
    from amorgs.errors import InputError
    from amorgs.tracking import git_state

    record = bk.read_record(args.record)
    commit = git_state(Path.cwd())["git_commit"]
    improved = []
    if args.from_library:
        improved += bk.from_library(record, args.from_library, commit)
    for path in args.add or []:
        if not Path(path).is_file():
            raise InputError(f"--add {path}: no such file")
        table = pd.read_parquet(path) if path.endswith(".parquet") else pd.read_csv(path)
        where = bk.source_where(path, Path.cwd())
        if Path(where).is_absolute():
            print(f"--add {path}: outside this checkout — the record will name a file only this machine has "
                  "(commit the table, then add it from the checkout)", file=sys.stderr)
        improved += bk.add_solutions(record, table, {"kind": "search", "where": where, "commit": commit})
    if args.lift or args.from_library or args.add:
        improved += bk.lift(record)
    if improved:
        bk.save_record(record, args.record)
    for label, entry in sorted(record["alphas"].items()):
        mark = " (new)" if label in improved else ""
        lifted = f" (α = {entry['source']['from_alpha']:g}'s trajectory)" if entry["source"]["kind"] == "lift" else ""
        print(f"α = {label}: {entry['m_f_kg']:.3f} kg — {entry['source']['kind']}{lifted} {entry['source']['where']}{mark}")
    print(f"{args.record}: {len(set(improved))} α improved" if improved else f"{args.record}: unchanged")


def cmd_global_search(args: argparse.Namespace) -> None:
    from pathlib import Path

    import shlex

    from amorgs.ablation.global_study import (
        CHECKPOINT_DIR,
        GlobalStudy,
        clear_checkpoint,
        compare,
        finished_searches,
        inputs_identity,
        run_study,
        without_cells,
    )
    from amorgs.certification import record_entry, under_reference
    from amorgs.data.io import atomic_path, check_writable_folder, read_json, write_parquet
    from amorgs.errors import InputError
    from amorgs.figures.global_search import fig_runtime_ecdf
    from amorgs.reference import export_global_study
    from amorgs.solvers.basin_hopping import HopSettings
    from amorgs.solvers.options import IpoptOptions

    dest = Path(args.dest)
    check_writable_folder(dest, "--dest")
    try:
        hops = HopSettings(distribution=args.hop, scale=args.hop_scale, shape=args.hop_shape, patience=args.patience,
                           variables=tuple(args.hop_variables))
    except ValueError as exc:
        raise InputError(f"--hop: {exc}") from None
    study = GlobalStudy(alpha=args.alpha, samplers=tuple(args.samplers), strategies=tuple(args.strategies),
                        searches=args.searches, budget=args.budget, seed=args.seed, hops=hops, deltas=tuple(args.deltas),
                        solver=IpoptOptions(max_iter=args.max_iter), library_dir=args.library_dir, models_dir=args.models_dir,
                        library_alphas=tuple(args.library_alphas) if args.library_alphas else None)
    if args.from_events and args.extend:
        raise InputError("--from-events and --extend: choose one (--extend solves the new cells)")
    if args.from_events:
        import pandas as pd

        from amorgs.ablation.global_study import summarize

        source = Path(args.from_events)
        missing = [n for n in ("events.parquet", "solutions.parquet") if not (source / n).is_file()]
        if missing:
            raise InputError(f"--from-events {source}: no {' or '.join(missing)} (a finished global-search --dest)")
        tables = summarize(study, pd.read_parquet(source / "events.parquet"),
                           pd.read_parquet(source / "solutions.parquet"))
        held = read_json(source / "study.json") if (source / "study.json").is_file() else {}
        same = without_cells(held) == without_cells(json.loads(json.dumps(study.summary())))
        inputs = held.get("inputs") if same else None  # only what these settings' searches drew on
    else:  # each finished search is kept in dest/.searches until events.parquet holds it: a rerun resumes
        study.check()
        finished = finished_searches(dest, study) if args.extend else None
        tables = run_study(study, args.workers, checkpoint=dest / CHECKPOINT_DIR, finished=finished)
        inputs = inputs_identity(study)
    for name in ("events", "solutions"):
        write_parquet(tables[name], dest / f"{name}.parquet")
    if not args.from_events:  # its searches are in events.parquet now; not part of the reference
        left = clear_checkpoint(dest / CHECKPOINT_DIR, study)
        if left:
            print(f"{dest / CHECKPOINT_DIR}: {left} searches of other cells kept for a later run", file=sys.stderr)
    readable = compare(tables["runtime_to_target"])
    texts = {f"{name}.csv": tables[name].to_csv(index=False)
             for name in ("runtime_to_target", "runtime_ecdf", "ert_ratios", "ert_pairs", "distinct", "best_known")}
    texts["runtime_to_target.md"] = readable.to_markdown() + "\n"
    texts["study.json"] = json.dumps({**study.summary(), **({"inputs": inputs} if inputs else {})}, indent=1,
                                     sort_keys=True) + "\n"
    for name, text in texts.items():
        with atomic_path(dest / name) as tmp:
            tmp.write_text(text)
    best = tables["best_known"].iloc[0]
    fig = fig_runtime_ecdf(tables["runtime_ecdf"], tables["runtime_to_target"], {study.alpha: float(best["m_f"])},
                           study.deltas, study.budget)
    fig.savefig(dest / "fig_runtime_ecdf.png", dpi=130)
    manifest = export_global_study(dest, study, "amorgs " + " ".join(shlex.quote(a) for a in sys.argv[1:]))
    certifiable = manifest["certifiable"]
    where = ""
    if under_reference(dest):  # a committed reference: certified by its route from now on
        where = f"; certified with today's code in {record_entry(dest, {'route': 'today', **manifest['identity']})}"
    print(f"α = {study.alpha:g}: best known m_f {best['m_f']:.3f} kg ({best['source']}); ERT in IPOPT iterations "
          f"(95 % bootstrap), successes/searches:")
    print(readable.to_string())
    pairs = tables["ert_pairs"]
    if len(pairs):
        print("ERT ratios (95 % bootstrap; below 1 = faster): hopping ÷ multi-start from the same sampler, and each "
              "sampler ÷ reuse under the same strategy:")
        for r in pairs[pairs["ratio"].map(math.isfinite)].itertuples(index=False):
            print(f"  δ = {r.delta:g} kg: {r.strategy} × {r.sampler} ÷ {r.baseline}: {r.ratio:.2f} "
                  f"({r.ratio_lo:.2f}–{r.ratio_hi:.2f})")
    print(f"{dest}: events.parquet, solutions.parquet, study.json, runtime_to_target.{{csv,md}}, runtime_ecdf.csv, "
          f"ert_ratios.csv, ert_pairs.csv, distinct.csv, best_known.csv, fig_runtime_ecdf.png; {certifiable['events']} of "
          f"{certifiable['of_events']} events re-solvable (starts.parquet, config.yaml, provenance.json{where})")


def cmd_ui(args: argparse.Namespace) -> None:
    from amorgs import tracking

    if not (tracking.STORE_DIR / tracking.DB_NAME).exists():
        raise SystemExit(f"no MLflow store at {tracking.STORE_DIR / tracking.DB_NAME}: run the workflow first")
    cmd = tracking.ui_command(host=args.host, port=args.port)
    print(" ".join(cmd), flush=True)
    os.execve(cmd[0], cmd, {**tracking.SERVER_ENV, **os.environ})


def cmd_check_outputs(args: argparse.Namespace) -> None:
    from amorgs.checks import UNTRACKED, check_outputs
    from amorgs.config import load_config

    problems = check_outputs(load_config(args.config), tracked=not args.no_mlflow)
    if problems == [UNTRACKED]:  # every file is fine; only the MLflow history is missing
        print(f"{args.config}: every expected output is present and non-empty, but untracked\n  {UNTRACKED}", file=sys.stderr)
        raise SystemExit(3)
    if problems:
        raise SystemExit("missing or empty outputs:\n  " + "\n  ".join(problems))
    print(f"{args.config}: every expected output is present, non-empty and tracked")


def cmd_reference_export(args: argparse.Namespace) -> None:
    from amorgs.reference import export_reference, verify_reference

    if args.check:
        manifest = verify_reference(args.dest)
        print(f"{args.dest}: {len(manifest['files'])} files match {args.dest}/provenance.json "
              f"(run of {manifest['config_file']} at {manifest['git_commit'][:10]})")
        return
    if args.config is None:
        raise SystemExit("amorgs reference-export: --config is required (the config of the finished run)")
    if args.add_arms:
        from amorgs.reference import add_arms_to_reference

        manifest = add_arms_to_reference(args.dest, args.add_arms, args.config, args.run_dir, args.library_dir)
        print(f"{args.dest}: arms {', '.join(args.add_arms)} added from the run of {args.config} "
              f"({manifest['cpu_hours']['total']:.2f} CPU-hours; reproduced exactly: {manifest['reproduced'] or 'none'}); "
              f"the other arms kept from {manifest['earlier_run']['git_commit'][:10]}")
        return
    from amorgs.certification import check_exportable, record_entry

    check_exportable(args.run_dir)
    manifest = export_reference(args.config, args.dest, args.run_dir, args.library_dir, figures=not args.no_figures,
                                tables=not args.starts_only)
    registry = record_entry(args.dest, {"route": "today", **manifest["identity"]})
    print(f"{args.dest}: {len(manifest['files'])} files from the run of {args.config} "
          f"({manifest['cpu_hours']['total']:.2f} CPU-hours, library of {manifest['library']['rows']} solves); "
          f"manifest {args.dest}/provenance.json; certified with today's code in {registry}")


def cmd_reference_certify(args: argparse.Namespace) -> None:
    from pathlib import Path

    from amorgs.certification import certify_all, certify_reference, record_at_commit, reference_name
    from amorgs.data.io import check_writable_folder, write_json
    from amorgs.errors import InputError

    if args.all:
        if args.reference or args.at_commit or args.record or args.blas_core:
            raise SystemExit("amorgs reference-certify --all: takes no reference, --at-commit, --blas-core or --record")
        failed = skipped = 0
        for r in certify_all(".", args.sample, args.seed, args.workers, args.skip_unsupported_cpu):
            failed += not r["ok"]
            skipped += bool(r.get("skipped"))
            mark = "skip" if r.get("skipped") else "ok  " if r["ok"] else "FAIL"
            print(f"{mark} reference/{r['reference']} [{r['route']}]: {r['line']}", flush=True)
        if skipped:
            print(f"{skipped} reference(s) not checked: this CPU cannot run the BLAS kernels they are pinned to",
                  file=sys.stderr)
        if failed:
            raise SystemExit(f"{failed} reference(s) not certified")
        return
    if args.skip_unsupported_cpu:
        raise SystemExit("amorgs reference-certify --skip-unsupported-cpu: only with --all")
    if not args.reference:
        raise SystemExit("amorgs reference-certify: name a reference directory, or --all")
    if args.record and not args.at_commit:
        raise SystemExit("amorgs reference-certify --record: only with --at-commit (records the commit it stays valid at)")
    if args.blas_core and not args.at_commit:
        raise SystemExit("amorgs reference-certify --blas-core: only with --at-commit (today's NLP reads no BLAS)")
    # Named by the reference's path under reference/ ("global-search--alpha=0.300"): two references whose folders
    # share a name (a sparse design's study at the same α) keep their own certificates.
    name = reference_name(args.reference).replace("/", "--")
    output = Path(args.output or f"results/certificates/{name}-seed{args.seed}.json")
    if output.is_dir():
        raise InputError(f"--output {output}: a directory")
    try:  # refuse an output that cannot be written before any solve
        check_writable_folder(output.parent, "--output")
    except InputError:
        raise InputError(f"--output {output}: cannot write there") from None
    cert = certify_reference(args.reference, args.sample, args.seed, args.workers, args.at_commit, args.blas_core)
    write_json(cert, output)
    verdict = "reproduced exactly" if cert["exact"] else "NOT reproduced"
    at = f"at commit {cert['code_commit'][:12]}" if cert["route"] == "commit" else "with this checkout's code"
    print(f"{args.reference}: {cert['matched']} of {cert['sample']} re-solved starts (seed {args.seed}, of "
          f"{cert['of_starts']}) match iterations, status and m_f exactly {at} — {verdict}; largest |Δm_f| "
          f"{cert['max_abs_dm_f_kg']:.3g} kg; certificate {output}")
    if not cert["exact"]:
        raise SystemExit(1)
    if args.record:
        print(f"recorded in {record_at_commit(args.reference, cert, args.why or '')}: {args.reference} stays valid at "
              f"commit {cert['code_commit'][:12]}")


def cmd_config_schema(args: argparse.Namespace) -> None:
    from amorgs.config import schema_text

    text = schema_text()
    if args.check:
        if not SCHEMA_PATH.is_file() or SCHEMA_PATH.read_text() != text:
            raise SystemExit(f"{SCHEMA_PATH} is not the schema generated from src/amorgs/config.py; "
                             "run `amorgs config-schema --write`")
        print(f"{SCHEMA_PATH}: current")
    elif args.write:
        from amorgs.data.io import atomic_path

        with atomic_path(SCHEMA_PATH) as tmp:
            tmp.write_text(text)
        print(f"{SCHEMA_PATH}: written")
    else:
        print(text, end="")


def cmd_config_show(args: argparse.Namespace) -> None:
    import yaml

    from amorgs.config import deep_merge, from_mapping, read_yaml

    merged: dict = {}
    for path in args.configs:  # in order, as Snakemake merges several --configfile
        merged = deep_merge(merged, read_yaml(path))
    cfg = from_mapping(merged, " + ".join(args.configs) if args.configs else "defaults")
    print(f"# effective config of {' + '.join(args.configs) or 'the typed defaults'}: hash {cfg.hash}")
    print(yaml.safe_dump(cfg.model_dump(mode="json"), sort_keys=False, allow_unicode=True), end="")


def add_tools(sub: argparse._SubParsersAction) -> None:
    """Add every tool's subcommand to ``sub``."""
    p = sub.add_parser("library-export", help="check finished library-config shards and add them to the library",
                       description="Add the finished shards of the library's own config to the library. The library "
                                   "belongs to one config (seed, starts per shard, solver options, recorded in its "
                                   "manifest): shards of any other config, a shard index it holds with other solves, "
                                   "or a damaged table stop the export, naming the file; another config needs "
                                   "another --library-dir.")
    p.add_argument("--problem", default="cr3bp", choices=PROBLEMS, help="problem whose shards are exported")
    p.add_argument("--solutions-dir", default="results/cr3bp/solutions", help="where the generate rule wrote the shards")
    p.add_argument("--library-dir", default="data/library", help="library root (data/library)")
    p.add_argument("--config", default="config/library.yaml",
                   help="the config that generated them; it must be the library's (same seed, starts, solver options)")
    p.set_defaults(func=cmd_library_export)

    p = sub.add_parser("library-compact", help="rewrite the library as one compact file per (α, generation)",
                       description="Merge each α's files of one solver generation into one Parquet file without the "
                                   "guess columns (the seeded draw reproduces them): the same rows, checked bit for "
                                   "bit, in fewer bytes; the manifest keeps where every shard came from. Run it on a "
                                   "committed library (git checkout undoes an interrupted run).")
    p.add_argument("--problem", default="cr3bp", choices=PROBLEMS, help="problem whose library is compacted")
    p.add_argument("--library-dir", default="data/library", help="library root (data/library)")
    p.set_defaults(func=cmd_library_compact)

    p = sub.add_parser("models-export", help="ship a workflow run's CR3BP checkpoints in the repository (for design)")
    p.add_argument("--models-dir", default="results/cr3bp/models", help="the train step's checkpoints")
    p.add_argument("--dest", default="data/models/cr3bp", help="where the shipped checkpoints live")
    p.add_argument("--config", default="config/default.yaml", help="the config of the run that trained them")
    p.add_argument("--library-dir", default="data/library", help="the library they were trained on (its hash is recorded)")
    p.add_argument("--selector", action="store_true",
                   help="ship the run's transfer selector (selector.joblib) beside the shipped checkpoints instead, "
                        "e.g. --config config/selector-model.yaml --models-dir <its run>/results/cr3bp/models")
    p.set_defaults(func=cmd_models_export)

    p = sub.add_parser(
        "library-grow",
        help="grow the library: generate the next batch of library-config shards, export, repeat",
        epilog="example: nice -n 19 amorgs library-grow --batches 20 --hours 3   # then commit data/library",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--config", default="config/library.yaml", help="the library config (seed, α, starts per shard)")
    p.add_argument("--problem", default="cr3bp", choices=("cr3bp",), help="problem whose library grows")
    p.add_argument("--library-dir", default="data/library", help="library root")
    p.add_argument("--new-library", action="store_true",
                   help="start a new library where --library-dir holds none (otherwise refused)")
    p.add_argument("--workdir", default="results/library-grow", help="Snakemake working directory of the batches")
    p.add_argument("--cores", type=int, default=2, help="cores Snakemake may use (on a cluster: for its local jobs)")
    p.add_argument("--profile", default=None,
                   help="Snakemake profile of the batches, e.g. workflow/profiles/slurm (default: this machine)")
    p.add_argument("--batches", type=int, default=1, help="batches to run (each: every α × generate.shards shards)")
    p.add_argument("--hours", type=float, default=None, help="start no new batch after this many hours")
    p.add_argument("--nice", type=int, default=19, help="niceness added before starting (0: none)")
    p.add_argument("--alphas", type=float, nargs="+", default=None,
                   help="grow only these library α (e.g. the focus α 1.0 of the structure analysis); default: all")
    p.add_argument("--until-converged", type=int, default=None, metavar="N",
                   help="each batch grows only the α with fewer than N verified converged solutions; "
                        "stop when none is left")
    p.set_defaults(func=cmd_library_grow)

    p = sub.add_parser("boundary-conditions", help="recompute (or --check) the CR3BP boundary conditions")
    p.add_argument("--output", help="the resource file (default: resources/boundary_conditions.json)")
    p.add_argument("--check", action="store_true", help="compare the stored file with a fresh computation")
    p.add_argument("--rel-tol", type=float, default=1e-9, help="--check: relative tolerance on numbers")
    p.set_defaults(func=cmd_boundary_conditions)

    p = sub.add_parser(
        "design",
        help="N good, verified, η-diverse CR3BP transfers at one α, exported (tables, CSV, CCSDS OEM, plot)",
        description="Solve warm starts at one α in rounds until N high-quality (converged and verified by\n"
                    "independent re-propagation, m_f ≥ β) and η-diverse (paper Eq. 12) solutions are found or a\n"
                    "budget runs out; write them with dense trajectories in the rotating frame and an Earth-centred\n"
                    "inertial frame (epoch 2030-01-01T00:00:00 TDB at departure) as CSV, CCSDS OEM and a 3-D plot.",
        epilog="example:\n  amorgs design --alpha 0.42 -n 20            # → results/design/alpha=0.420/\n"
               "  amorgs design --alpha 0.42 -n 5 --seed 7 --max-starts 64 --output my-design\n"
               "exit status: 0 all N found, 3 fewer found before the budget ran out (files still written)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--alpha", required=True, type=float, help="maximum thrust α in N, within [0.1, 1.0]")
    p.add_argument("-n", "--n", dest="n", required=True, type=int, help="number of solutions wanted (≥ 1)")
    p.add_argument("--sampler", default="auto",
                   help="warm-start sampler (default auto: the arm the committed frontier, --frontier, measured best "
                        f"at this α's distance from the library's α — {REUSE_ARM}, the library solutions of the "
                        "nearest α, unless a learned arm beat it significantly there; the choice and its reason "
                        "are printed); or " + ", ".join(a.name for a in ARMS if not a.learned)
                        + "; the learned " + ", ".join(a.name for a in ARMS if a.learned and set(a.models) <= set(PAPER_MODELS))
                        + " (their models are shipped in data/models/cr3bp)"
                        + "".join(f", {a.name}" for a in ARMS if a.learned and not set(a.models) <= set(PAPER_MODELS))
                        + " (needs a workflow run's models: --models-dir results/cr3bp/models)")
    p.add_argument("--frontier", nargs="+", default=None, metavar="CSV",
                   help="the frontier tables --sampler auto follows, read together (amorgs frontier; default the "
                        "committed ones: the five arms' and the transfer selector's under reference/)")
    p.add_argument("--beta", type=float, default=BETA_KG, help=f"β: minimum final fuel mass m_f in kg (default {BETA_KG:g})")
    p.add_argument("--eta", type=float, default=ETA,
                   help="η of Eq. 12, dimensionless: solutions must differ by more than η in (τ_s/40, τ_i/15, τ_f/15) "
                        "(default 0.02 ≈ 0.8 TU of τ_s or 0.3 TU of τ_i, τ_f)")
    p.add_argument("--seed", type=int, default=0, help="seed of the warm starts; same seed, same result (default 0)")
    p.add_argument("--workers", type=int, default=2, help="solver processes (default 2)")
    p.add_argument("--strategy", default="multistart", choices=list(DESIGN_STRATEGIES),
                   help="multistart: every start from the sampler; mbh: monotonic basin hopping, each slot of a round "
                        "a chain hopping from its best solution (docs/global-search.md); auto: mbh where the committed "
                        "global-search study nearest in α found it significantly faster to within 2 kg of the best "
                        "known m_f from the same sampler, multistart otherwise (the choice and its evidence are printed)")
    p.add_argument("--hop", default=HOPS.distribution, help="mbh: hop distribution (pareto, cauchy, gaussian, uniform)")
    p.add_argument("--hop-scale", type=float, default=HOPS.scale, help="mbh: hop step per unit draw, fraction of the box")
    p.add_argument("--hop-shape", type=float, default=HOPS.shape, help="mbh: Pareto tail index")
    p.add_argument("--patience", type=int, default=HOPS.patience, help="mbh: hops without improvement before a restart")
    p.add_argument("--hop-variables", nargs="+", default=list(HOPS.variables), metavar="NAME",
                   help="mbh: the stored variables a hop moves, e.g. tau_s tau_i tau_f (the times); default: all")
    p.add_argument("--round-size", type=int, default=16,
                   help="starts solved per round; the stop criteria are checked between rounds (default 16)")
    p.add_argument("--max-starts", type=int, default=400, help="budget: at most this many solves (default 400)")
    p.add_argument("--max-cpu-s", type=float, default=3600.0,
                   help="budget: start no new round after this many CPU seconds, workers included (default 3600)")
    p.add_argument("--output", default=None, help="output folder (default results/design/alpha=<label>/)")
    p.add_argument("--library-dir", default="data/library", help="the solution library shipped in the repository")
    p.add_argument("--models-dir", default="data/models/cr3bp", help="checkpoints of the learned samplers")
    p.add_argument("--config", default="config/default.yaml",
                   help="config giving the solver options (problems.cr3bp.solver), training α and filter β")
    p.add_argument("--mlflow-dir", default="results/mlflow",
                   help="MLflow store of the design run (default: the workflow's store, so `amorgs ui` shows it)")
    p.add_argument("--no-mlflow", action="store_true", help="do not mirror the call to MLflow")
    p.add_argument("--quiet", action="store_true", help="no progress bar on stderr")
    p.set_defaults(func=cmd_design)

    p = sub.add_parser(
        "frontier-plan", help="write one config per fold of the frontier study and print the commands that run them",
        description="Folds of the frontier (issue 21): leave-one-α-out (--loo: each α in turn is the test α, the other\n"
                    "library α train) and sparse grids (--sparse k: k training α, tested at the library α nearest\n"
                    "each mid-gap).  Each fold is the base config with its own α, written to <runs-dir>/<fold>/config.yaml\n"
                    "and run by the printed Snakemake command in that directory.")
    p.add_argument("--config", default="config/frontier.yaml", help="the base config of every fold")
    p.add_argument("--runs-dir", default="results/frontier/runs", help="one directory per fold is made here")
    p.add_argument("--loo", type=float, nargs="+", default=[], metavar="ALPHA",
                   help="library α to leave out, one fold each (N)")
    p.add_argument("--sparse", type=int, nargs="+", default=[], metavar="K", help="sparse grid sizes, one fold each")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key of the base config in every fold, e.g. --set ablation.n_starts=10 (repeatable)")
    p.add_argument("--snakemake", default="snakemake", help="the snakemake executable in the printed commands")
    p.set_defaults(func=cmd_frontier_plan)

    p = sub.add_parser("frontier", help="aggregate finished frontier folds: aRT(learned) ÷ aRT(reuse) against the gap",
                       description="Per (design, test α, arm): starts pooled over the model seeds, aRT in IPOPT\n"
                                   "iterations and CPU s with bootstrap intervals, and aRT(learned) ÷ aRT(reuse) with\n"
                                   "its interval, against the gap to the nearest training α; the table, its Markdown\n"
                                   "and the figure go to --dest and to MLflow.")
    p.add_argument("runs", nargs="+", help="finished fold directories (each with config.yaml and results/)")
    p.add_argument("--dest", default="results/frontier", help="where frontier.csv, frontier.md, fig_frontier.png go")
    p.add_argument("--learned", nargs="+", default=None,
                   help="arms compared with reuse (default: every arm of the folds but the reuse arm and uniform)")
    p.add_argument("--reuse", default=REUSE_ARM, help=f"the reuse arm (default {REUSE_ARM})")
    p.add_argument("--n-boot", type=int, default=2000, help="bootstrap resamples")
    p.add_argument("--seed", type=int, default=0, help="seed of the bootstrap")
    p.add_argument("--mlflow-dir", default="results/mlflow", help="MLflow store of the aggregation's run")
    p.add_argument("--no-mlflow", action="store_true", help="do not mirror the aggregation to MLflow")
    p.set_defaults(func=cmd_frontier)

    p = sub.add_parser("best-known", help="the best known trajectory per α: show, or raise it from the library or a search",
                       description="Each α's best verified m_f and the solution holding it (data/best_known/cr3bp.json),\n"
                                   "the target global searches are timed against; an entry rises only to a solution\n"
                                   "that passes the independent DOP853 check here.  A trajectory stays feasible when the\n"
                                   "maximum thrust grows (its throttles rescaled), so after --from-library or --add, and\n"
                                   "with --lift, every entry is carried to the record's other α where it flies and is better.")
    p.add_argument("--record", default="data/best_known/cr3bp.json", help="the record (JSON)")
    p.add_argument("--from-library", default=None, metavar="DIR", help="offer each library α's best verified rows")
    p.add_argument("--add", nargs="+", default=None, metavar="TABLE",
                   help="offer the best rows of solutions tables (parquet or csv: a global search's solutions.parquet, "
                        "a design's solutions.parquet)")
    p.add_argument("--lift", action="store_true",
                   help="carry every entry to the record's other α where the same trajectory flies (throttles "
                        "rescaled by α ratio, all ≤ 1) and beats the entry there — done after --from-library and --add "
                        "anyway")
    p.set_defaults(func=cmd_best_known)

    p = sub.add_parser("global-search", help="time global search strategies × samplers to the best known trajectory",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="R seeded searches per (strategy, sampler) at one α, each with the same budget of\n"
                                   "IPOPT iterations: multi-start, or monotonic basin hopping from the sampler's starts.\n"
                                   "Reports the expected iterations to come within δ of the best known m_f (library\n"
                                   "and study), with bootstrap intervals, the runtime ECDF and distinct near-best ones.\n"
                                   "Prints a line per finished search; each is kept in DEST/.searches until the tables\n"
                                   "are written, so the same command, run again after an interruption, resumes.")
    p.add_argument("--alpha", type=float, required=True, help="the α (N) searched")
    p.add_argument("--samplers", nargs="+", default=["uniform", "nearest_alpha"], help="arms whose starts seed searches")
    p.add_argument("--strategies", nargs="+", default=["multistart", "mbh"],
                   help="multistart, mbh and/or mbh_warm (hops re-solved from near a solution)")
    p.add_argument("--searches", type=int, default=30, help="independent searches per cell (default 30)")
    p.add_argument("--budget", type=int, default=5000, help="IPOPT iterations per search (default 5000)")
    p.add_argument("--max-iter", type=int, default=1000, help="IPOPT iteration cap per solve (default 1000)")
    p.add_argument("--hop", default=HOPS.distribution, help="hop distribution: pareto, cauchy, gaussian or uniform")
    p.add_argument("--hop-scale", type=float, default=HOPS.scale, help="hop step per unit draw, fraction of the box width")
    p.add_argument("--hop-shape", type=float, default=HOPS.shape, help="Pareto tail index")
    p.add_argument("--patience", type=int, default=HOPS.patience, help="hops without improvement before a restart")
    p.add_argument("--hop-variables", nargs="+", default=list(HOPS.variables), metavar="NAME",
                   help="the stored variables a hop moves, e.g. tau_s tau_i tau_f (the times); default: all")
    p.add_argument("--deltas", type=float, nargs="+", default=[0.1, 0.5, 2.0],
                   help="targets: within δ kg of the best known m_f (default 0.1 0.5 2)")
    p.add_argument("--seed", type=int, default=0, help="seed of the searches and the bootstrap")
    p.add_argument("--workers", type=int, default=1, help="solver processes")
    p.add_argument("--library-dir", default="data/library", help="the solution library (reuse arms, best known)")
    p.add_argument("--library-alphas", type=float, nargs="+", default=None, metavar="ALPHA",
                   help="the library α the reuse arms draw on, e.g. a sparse design's training α 0.1 0.5 1.0 "
                        "(default: every library α but --alpha)")
    p.add_argument("--models-dir", default=None, help="checkpoints of learned samplers (e.g. data/models/cr3bp)")
    p.add_argument("--dest", default="results/global-search", help="where the tables and the figure go")
    p.add_argument("--from-events", default=None, metavar="DIR",
                   help="no solves: recompute the tables and the figure from a finished study's events.parquet and "
                        "solutions.parquet in DIR (with this code's statistics)")
    p.add_argument("--extend", action="store_true",
                   help="DEST holds a finished study of these settings with fewer cells (same library manifest and "
                        "model files, its study.json's inputs): keep its searches, solve only the new cells' and "
                        "rewrite the tables of all (a study split over sessions)")
    p.set_defaults(func=cmd_global_search)

    p = sub.add_parser("ui", help="open the MLflow UI on results/mlflow")
    p.add_argument("--host", default="127.0.0.1", help="address the UI listens on")
    p.add_argument("--port", type=int, default=5000, help="port the UI listens on")
    p.set_defaults(func=cmd_ui)

    p = sub.add_parser("check-outputs", help="check that every output of a config exists, is non-empty and tracked")
    p.add_argument("--config", required=True, help="config file, e.g. config/smoke.yaml")
    p.add_argument("--no-mlflow", action="store_true", help="skip the MLflow checks")
    p.set_defaults(func=cmd_check_outputs)

    p = sub.add_parser("config-schema", help="print (or --write, or --check) the JSON Schema generated from the config model")
    p.add_argument("--write", action="store_true", help=f"write it to {SCHEMA_PATH}")
    p.add_argument("--check", action="store_true", help=f"exit 1 if {SCHEMA_PATH} is not the generated schema")
    p.set_defaults(func=cmd_config_schema)

    p = sub.add_parser("config-show", help="print the effective config: the files' overrides merged over the defaults")
    p.add_argument("configs", nargs="*", metavar="CONFIG",
                   help="config files, merged in the order given (none: the typed defaults)")
    p.set_defaults(func=cmd_config_show)

    p = sub.add_parser("reference-export", help="commit a finished run's tables, figures and summary with provenance")
    p.add_argument("--config", default=None, help="the config of the finished run (e.g. config/study.yaml)")
    p.add_argument("--dest", required=True, help="where the reference result lives (e.g. reference/study)")
    p.add_argument("--run-dir", default=".", help="the checkout the run ran in (its results/ and data/library)")
    p.add_argument("--library-dir", default="data/library", help="the library the run read, relative to --run-dir")
    p.add_argument("--no-figures", action="store_true", help="leave the figures out (tables, summaries and starts only)")
    p.add_argument("--starts-only", action="store_true",
                   help="only the starts (starts.parquet), the config and the manifest: no report outputs")
    p.add_argument("--check", action="store_true", help="verify the files of --dest against its manifest instead")
    p.add_argument("--add-arms", nargs="+", metavar="ARM", default=None,
                   help="add these arms' starts to the reference in --dest from a later run of its design that ran only "
                        "their cells (arms it holds are rerun as a check: they must reproduce exactly)")
    p.set_defaults(func=cmd_reference_export)

    p = sub.add_parser("reference-certify",
                       help="re-solve a seeded sample of a committed reference's starts: do iterations and m_f match exactly?")
    p.add_argument("reference", nargs="?", default=None,
                   help="the committed reference directory (with starts.parquet), e.g. reference/frontier/sparse-3")
    p.add_argument("--all", action="store_true",
                   help="certify every committed reference by its route in reference/certification.json (CI)")
    p.add_argument("--skip-unsupported-cpu", action="store_true",
                   help="with --all: report a reference pinned to BLAS kernels this CPU cannot run (e.g. SkylakeX "
                        "without AVX-512) as not checked here, instead of failing (CI on such a machine)")
    p.add_argument("--at-commit", nargs="?", const="recorded", default=None, metavar="COMMIT",
                   help="re-solve with the code of COMMIT (default: the one recorded for the reference) in a temporary "
                        "git worktree, in this environment, instead of this checkout's code")
    p.add_argument("--blas-core", default=None, metavar="KERNELS",
                   help="with --at-commit: force numpy's OpenBLAS to this kernel set (e.g. SkylakeX, Haswell) — the one "
                        "the reference was made with, for code that built its NLP with numpy's BLAS (before 2026-12-05); "
                        "default: the one recorded for the reference, if any")
    p.add_argument("--record", action="store_true",
                   help="with --at-commit: record in reference/certification.json that the reference stays valid at "
                        "that commit (only after an exact certificate)")
    p.add_argument("--why", default=None, help="with --record: the reason recorded")
    p.add_argument("--sample", type=int, default=20, help="how many starts to re-solve (default 20)")
    p.add_argument("--seed", type=int, default=0, help="seed of the sample (default 0)")
    p.add_argument("--workers", type=int, default=1, help="solver processes (default 1)")
    p.add_argument("--output", default=None,
                   help="the certificate (JSON; default results/certificates/<name>-seed<seed>.json, <name> its "
                        "path under reference/ with / as --)")
    p.set_defaults(func=cmd_reference_certify)
