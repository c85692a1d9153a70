# Stage 3, analysis: the structure of the CR3BP solution set (paper Sec. III.B): hyperplanes, funnels, moving
# averages, diversity and control statistics as tables, Figs. 3–13 as PNG.  amorgs.steps.analyze


rule analyze_cr3bp:
    input:
        solutions=steps.outputs_of("merge", CFG, "table", problem="cr3bp"),
        high_quality=layout.HIGH_QUALITY.format(problem="cr3bp"),
    output:
        **step_outputs("analyze_cr3bp"),
    log:
        "logs/analyze_cr3bp.log",
    benchmark:
        "results/benchmarks/analyze_cr3bp/job.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("analyze_cr3bp")
    resources:
        **step_resources("analyze_cr3bp"),
    params:
        **step_params("analyze_cr3bp"),
    shell:
        STEP
