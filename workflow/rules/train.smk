# Stage 3, models: train the GMM-prior CVAE on the filtered De Jong minima at the training α, then sample it
# at the held-out test α and score the samples against the analytic minima.


rule train_dejong_cvae:
    input:
        layout.HIGH_QUALITY.format(problem="dejong"),
    output:
        layout.DEJONG_MODEL,
    log:
        "logs/train_dejong_cvae.log",
    params:
        train_alphas=" ".join(map(repr, CFG.problems.dejong.alphas.train_values())),
        preset=CFG.dejong_cvae.preset,
        lr=CFG.dejong_cvae.learning_rate,
        epochs=CFG.dejong_cvae.epochs,
        batch_size=CFG.dejong_cvae.batch_size,
        seed=CFG.dejong_cvae.seed,
    threads: CFG.resources.train.threads
    resources:
        mem_mb=CFG.resources.train.mem_mb,
        runtime=CFG.resources.train.runtime_min,
    conda:
        "../envs/amorgs.yaml"
    shell:
        "python -m amorgs train-dejong-cvae --data {input} --train-alphas {params.train_alphas} "
        "--preset {params.preset} --learning-rate {params.lr} --epochs {params.epochs} "
        "--batch-size {params.batch_size} --seed {params.seed} --threads {threads} --output {output} > {log} 2>&1"


rule predict_dejong_cvae:
    input:
        layout.DEJONG_MODEL,
    output:
        samples=layout.DEJONG_SAMPLES,
        metrics=layout.DEJONG_METRICS,
    log:
        "logs/predict_dejong_cvae.log",
    params:
        test_alphas=" ".join(map(repr, CFG.problems.dejong.alphas.test)),
        n_samples=CFG.dejong_cvae.n_samples,
        seed=CFG.dejong_cvae.seed,
        radius=CFG.dejong_cvae.radius,
    threads: CFG.resources.predict.threads
    resources:
        mem_mb=CFG.resources.predict.mem_mb,
        runtime=CFG.resources.predict.runtime_min,
    conda:
        "../envs/amorgs.yaml"
    shell:
        "python -m amorgs predict-dejong-cvae --model {input} --test-alphas {params.test_alphas} "
        "--n-samples {params.n_samples} --seed {params.seed} --radius {params.radius} "
        "--samples {output.samples} --metrics {output.metrics} > {log} 2>&1"
