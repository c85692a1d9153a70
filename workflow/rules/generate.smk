# Stage 1: multi-start local solves, one job per (problem, α, shard), then one merged table per (problem, α):
# the fresh shards plus, with problems.<name>.library.enabled, the committed library files of that α
# (checked against the library manifest; optionally a fixed slice of their first rows).  amorgs.steps.generate


rule generate:
    output:
        **step_outputs("generate"),
    log:
        "logs/generate/{problem}/alpha={alpha}/shard-{shard}.log",
    benchmark:
        "results/benchmarks/generate/{problem}/alpha={alpha}/shard-{shard}.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("generate")
    resources:
        **step_resources("generate"),
    params:
        **step_params("generate"),
    shell:
        STEP


rule merge:
    input:
        fresh=lambda w: steps.outputs_of("generate", CFG, "table", problem=w.problem, alpha=w.alpha),
        library=library_shards,
    output:
        **step_outputs("merge"),
    log:
        "logs/merge/{problem}/alpha={alpha}.log",
    benchmark:
        "results/benchmarks/merge/{problem}/alpha={alpha}.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("merge")
    resources:
        **step_resources("merge"),
    params:
        **step_params("merge"),
    shell:
        STEP
