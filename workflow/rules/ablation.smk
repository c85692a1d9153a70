# Stage 5, ablation (paper Sec. V.B.7–8, issue 11): per (test α, sampler) one job solving guesses from that
# sampler — once with the models of cr3bp_models.seed, once more per cr3bp_models.extra_seeds (replicates),
# and the learned arms of ablation.fraction_samplers with the models of each data fraction (learning curve);
# then the report: Table 6, capped studies, coverage, rates + Fisher tests, β sweep, expected running time,
# anytime curves and Figs. 21–23.  amorgs.steps.ablation


rule ablation_cell:
    input:
        unpack(ablation_cell_inputs),
    output:
        **step_outputs("ablation_cell"),
    log:
        "logs/ablation_cell/alpha={alpha}/{sampler}.log",
    benchmark:
        "results/benchmarks/ablation_cell/alpha={alpha}/{sampler}.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("ablation_cell")
    resources:
        **step_resources("ablation_cell"),
    params:
        **step_params("ablation_cell"),
    shell:
        STEP


rule ablation_cell_replicate:
    input:
        unpack(lambda w: ablation_cell_inputs(w, layout.CR3BP_REPLICATE_MODEL)),
    output:
        **step_outputs("ablation_cell_replicate"),
    log:
        "logs/ablation_cell/seed={mseed}/alpha={alpha}/{sampler}.log",
    benchmark:
        "results/benchmarks/ablation_cell_replicate/seed={mseed}/alpha={alpha}/{sampler}.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("ablation_cell_replicate")
    resources:
        **step_resources("ablation_cell_replicate"),
    params:
        **step_params("ablation_cell_replicate"),
    shell:
        STEP


rule ablation_cell_fraction:
    input:
        unpack(lambda w: ablation_cell_inputs(w, layout.CR3BP_FRACTION_MODEL)),
    output:
        **step_outputs("ablation_cell_fraction"),
    log:
        "logs/ablation_cell/fraction={fraction}/alpha={alpha}/{sampler}.log",
    benchmark:
        "results/benchmarks/ablation_cell_fraction/fraction={fraction}/alpha={alpha}/{sampler}.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("ablation_cell_fraction")
    resources:
        **step_resources("ablation_cell_fraction"),
    params:
        **step_params("ablation_cell_fraction"),
    shell:
        STEP


rule ablation_report:
    input:
        cells=steps.outputs_of("ablation_cell", CFG, "table")
        + steps.outputs_of("ablation_cell_replicate", CFG, "table")
        + steps.outputs_of("ablation_cell_fraction", CFG, "table"),
        high_quality=layout.HIGH_QUALITY.format(problem="cr3bp"),
        alpha_tables=steps.outputs_of("merge", CFG, "table", problem="cr3bp"),
        training_reports=steps.outputs_of("train_cr3bp", CFG, "report"),
    output:
        **step_outputs("ablation_report"),
    log:
        "logs/ablation_report.log",
    benchmark:
        "results/benchmarks/ablation_report/job.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("ablation_report")
    resources:
        **step_resources("ablation_report"),
    params:
        **step_params("ablation_report"),
    shell:
        STEP
