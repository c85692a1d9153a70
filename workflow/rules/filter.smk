# Stage 2: the β-filter over every α of a problem, with a per-α quality report.


rule filter:
    input:
        lambda w: layout.alpha_tables(CFG, w.problem),
    output:
        table=layout.HIGH_QUALITY,
        report=layout.QUALITY_REPORT,
    log:
        "logs/filter/{problem}.log",
    conda:
        "../envs/amorgs.yaml"
    threads: CFG.resources.filter.threads
    resources:
        mem_mb=CFG.resources.filter.mem_mb,
        runtime=CFG.resources.filter.runtime_min,
    params:
        thresholds=filter_arguments,
    shell:
        "python -m amorgs filter --problem {wildcards.problem} --inputs {input} {params.thresholds} "
        "--output {output.table} --report {output.report} > {log} 2>&1"
