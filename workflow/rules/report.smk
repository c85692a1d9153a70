# The paper figures drawn by a rule of their own (the others come out of analyze_cr3bp, predict_cr3bp and
# ablation_report), saved as results/figures/figNN_<what>.png and shown in `snakemake --report`.
# amorgs.steps.dejong


rule fig02_foxholes:
    output:
        **step_outputs("fig02_foxholes"),
    log:
        "logs/fig02_foxholes.log",
    benchmark:
        "results/benchmarks/fig02_foxholes/job.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("fig02_foxholes")
    resources:
        **step_resources("fig02_foxholes"),
    params:
        **step_params("fig02_foxholes"),
    shell:
        STEP


rule fig16_dejong_predictions:
    input:
        high_quality=layout.HIGH_QUALITY.format(problem="dejong"),
        samples=layout.DEJONG_SAMPLES,
    output:
        **step_outputs("fig16_dejong_predictions"),
    log:
        "logs/fig16_dejong_predictions.log",
    benchmark:
        "results/benchmarks/fig16_dejong_predictions/job.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("fig16_dejong_predictions")
    resources:
        **step_resources("fig16_dejong_predictions"),
    params:
        **step_params("fig16_dejong_predictions"),
    shell:
        STEP
