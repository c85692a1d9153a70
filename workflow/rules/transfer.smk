# Transfer data (issue 38 §1): the high-quality solutions of one training α solved as warm starts at another
# training α, one job per (α_from → α_to, shard), labelled with what each solve gave — the selector's
# training data.  amorgs.steps.transfer


rule transfer:
    input:
        high_quality=layout.HIGH_QUALITY.format(problem="cr3bp"),
    output:
        **step_outputs("transfer"),
    log:
        "logs/transfer/{problem}/alpha={alpha}/from={source}/shard-{shard}.log",
    benchmark:
        "results/benchmarks/transfer/{problem}/alpha={alpha}/from={source}/shard-{shard}.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("transfer")
    resources:
        **step_resources("transfer"),
    params:
        **step_params("transfer"),
    shell:
        STEP


rule train_selector:
    input:
        tables=steps.outputs_of("transfer", CFG, "table"),
    output:
        **step_outputs("train_selector"),
    log:
        "logs/train_selector.log",
    benchmark:
        "results/benchmarks/train_selector/job.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("train_selector")
    resources:
        **step_resources("train_selector"),
    params:
        **step_params("train_selector"),
    shell:
        STEP
