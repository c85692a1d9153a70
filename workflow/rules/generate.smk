# Stage 1: multi-start local solves, one job per (problem, α, shard), then one merged table per (problem, α):
# the fresh shards plus, with problems.<name>.library.enabled, the committed library files of that α
# (checked against the library manifest; optionally a fixed slice of their first rows).


rule generate:
    output:
        layout.SHARD,
    log:
        "logs/generate/{problem}/alpha={alpha}/shard-{shard}.log",
    conda:
        "../envs/amorgs.yaml"
    threads: lambda w: problem_cfg(w).generate.workers
    resources:
        mem_mb=lambda w: problem_cfg(w).generate.mem_mb,
        runtime=lambda w: problem_cfg(w).generate.runtime_min,
    params:
        alpha=alpha_value,
        seed=seed_of_shard,
        starts=lambda w: problem_cfg(w).generate.starts_per_shard,
        solver=solver_options,
    shell:
        "python -m amorgs generate --problem {wildcards.problem} --alpha {params.alpha} "
        "--shard {wildcards.shard} --seed {params.seed} --starts {params.starts} --workers {threads} "
        "--solver-options {params.solver:q} --output {output} > {log} 2>&1"


rule merge:
    input:
        fresh=lambda w: layout.shard_paths(CFG, w.problem, w.alpha),
        library=library_shards,
    output:
        layout.ALPHA_TABLE,
    log:
        "logs/merge/{problem}/alpha={alpha}.log",
    conda:
        "../envs/amorgs.yaml"
    threads: CFG.resources.merge.threads
    resources:
        mem_mb=CFG.resources.merge.mem_mb,
        runtime=CFG.resources.merge.runtime_min,
    params:
        library=library_arguments,
    shell:
        "python -m amorgs merge --problem {wildcards.problem} --alpha {wildcards.alpha} "
        "--inputs {input.fresh} --library {input.library} {params.library} --output {output} > {log} 2>&1"
