# Stage 8, global search (issue 41): per (test α, strategy, sampler) one job running seeded searches —
# multi-start, or monotonic basin hopping from the sampler's starts — then the report: runtime to the best known
# m_f with bootstrap intervals, the runtime ECDF and the distinct near-best trajectories.  amorgs.steps.global_search


rule global_search_cell:
    input:
        unpack(global_search_cell_inputs),
    output:
        **step_outputs("global_search_cell"),
    log:
        "logs/global_search_cell/alpha={alpha}/{strategy}-{sampler}.log",
    benchmark:
        "results/benchmarks/global_search_cell/alpha={alpha}/{strategy}-{sampler}.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("global_search_cell")
    resources:
        **step_resources("global_search_cell"),
    params:
        **step_params("global_search_cell"),
    shell:
        STEP


rule global_search_report:
    input:
        events=steps.outputs_of("global_search_cell", CFG, "events"),
        solutions=steps.outputs_of("global_search_cell", CFG, "solutions"),
    output:
        **step_outputs("global_search_report"),
    log:
        "logs/global_search_report.log",
    benchmark:
        "results/benchmarks/global_search_report/job.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("global_search_report")
    resources:
        **step_resources("global_search_report"),
    params:
        **step_params("global_search_report"),
    shell:
        STEP
