# The paper figures, one rule each, saved as results/figures/figNN_<what>.png and shown in `snakemake --report`.


rule fig02_foxholes:
    output:
        report(
            layout.FIGURE.format(name="fig02_foxholes"),
            caption="../report/fig02_foxholes.rst",
            category="De Jong",
        ),
    log:
        "logs/fig02_foxholes.log",
    conda:
        "../envs/amorgs.yaml"
    threads: CFG.resources.figure.threads
    resources:
        mem_mb=CFG.resources.figure.mem_mb,
        runtime=CFG.resources.figure.runtime_min,
    shell:
        "python -m amorgs fig02-foxholes --output {output} > {log} 2>&1"


rule fig16_dejong_predictions:
    input:
        data=layout.HIGH_QUALITY.format(problem="dejong"),
        samples=layout.DEJONG_SAMPLES,
    output:
        report(
            layout.FIGURE.format(name="fig16_dejong_predictions"),
            caption="../report/fig16_dejong_predictions.rst",
            category="De Jong",
        ),
    log:
        "logs/fig16_dejong_predictions.log",
    conda:
        "../envs/amorgs.yaml"
    threads: CFG.resources.figure.threads
    resources:
        mem_mb=CFG.resources.figure.mem_mb,
        runtime=CFG.resources.figure.runtime_min,
    params:
        train_alphas=" ".join(map(repr, CFG.problems.dejong.alphas.train_values())),
    shell:
        "python -m amorgs fig16-dejong-predictions --data {input.data} --samples {input.samples} "
        "--train-alphas {params.train_alphas} --output {output} > {log} 2>&1"
