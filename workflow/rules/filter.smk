# Stage 2: the β-filter over every α table of a problem, with a per-α quality report.  amorgs.steps.filter


rule filter:
    input:
        tables=lambda w: steps.outputs_of("merge", CFG, "table", problem=w.problem),
    output:
        **step_outputs("filter"),
    log:
        "logs/filter/{problem}.log",
    benchmark:
        "results/benchmarks/filter/{problem}.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("filter")
    resources:
        **step_resources("filter"),
    params:
        **step_params("filter"),
    shell:
        STEP
