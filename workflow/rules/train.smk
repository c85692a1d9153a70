# Stage 4, models: train the GMM-prior CVAE on the filtered De Jong minima at the training α, then sample it
# at the held-out test α and score the samples against the analytic minima.


rule train_dejong_cvae:
    input:
        layout.HIGH_QUALITY.format(problem="dejong"),
    output:
        layout.DEJONG_MODEL,
    log:
        "logs/train_dejong_cvae.log",
    conda:
        "../envs/amorgs.yaml"
    threads: CFG.resources.train.threads
    resources:
        mem_mb=CFG.resources.train.mem_mb,
        runtime=CFG.resources.train.runtime_min,
    params:
        train_alphas=" ".join(map(repr, CFG.problems.dejong.alphas.train_values())),
        preset=CFG.dejong_cvae.preset,
        lr=CFG.dejong_cvae.learning_rate,
        epochs=CFG.dejong_cvae.epochs,
        batch_size=CFG.dejong_cvae.batch_size,
        seed=CFG.dejong_cvae.seed,
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
    conda:
        "../envs/amorgs.yaml"
    threads: CFG.resources.predict.threads
    resources:
        mem_mb=CFG.resources.predict.mem_mb,
        runtime=CFG.resources.predict.runtime_min,
    params:
        test_alphas=" ".join(map(repr, CFG.problems.dejong.alphas.test)),
        n_samples=CFG.dejong_cvae.n_samples,
        seed=CFG.dejong_cvae.seed,
        radius=CFG.dejong_cvae.radius,
    shell:
        "python -m amorgs predict-dejong-cvae --model {input} --test-alphas {params.test_alphas} "
        "--n-samples {params.n_samples} --seed {params.seed} --radius {params.radius} "
        "--samples {output.samples} --metrics {output.metrics} > {log} 2>&1"


# The CR3BP models (paper Sec. IV): each trained on the high-quality rows at the training α only (the test α
# are generated for the ground truth, never trained on); plus Fig. 18's GMM-CVAEs on fractions of the data.


rule train_cr3bp:
    input:
        layout.HIGH_QUALITY.format(problem="cr3bp"),
    output:
        layout.CR3BP_MODEL,
    log:
        "logs/train_cr3bp/{model}.log",
    conda:
        "../envs/amorgs.yaml"
    threads: CFG.resources.train.threads
    resources:
        mem_mb=CFG.resources.train.mem_mb,
        runtime=CFG.resources.train.runtime_min,
    params:
        training=train_cr3bp_params(),
    shell:
        "python -m amorgs train-cr3bp --data {input} --model {wildcards.model} {params.training} "
        "--threads {threads} --output {output} > {log} 2>&1"


rule train_cr3bp_fraction:
    input:
        layout.HIGH_QUALITY.format(problem="cr3bp"),
    output:
        layout.CR3BP_FRACTION_MODEL,
    log:
        "logs/train_cr3bp/fraction={fraction}/cvae_gmm.log",
    conda:
        "../envs/amorgs.yaml"
    threads: CFG.resources.train.threads
    resources:
        mem_mb=CFG.resources.train.mem_mb,
        runtime=CFG.resources.train.runtime_min,
    params:
        training=train_cr3bp_params(),
    shell:
        "python -m amorgs train-cr3bp --data {input} --model cvae_gmm --fraction {wildcards.fraction} "
        "--fraction-label {wildcards.fraction} {params.training} --threads {threads} --output {output} > {log} 2>&1"


rule predict_cr3bp:
    input:
        models=[layout.CR3BP_MODEL.format(model=m) for m in layout.CR3BP_MODELS],
        fraction_models=layout.fraction_models(CFG),
        high_quality=layout.HIGH_QUALITY.format(problem="cr3bp"),
    output:
        samples=layout.CR3BP_SAMPLES,
        metrics=layout.CR3BP_PREDICTION_METRICS,
        figures=[
            report(
                layout.FIGURE.format(name=n), caption="../report/cr3bp_predictions.rst", category="CR3BP predictions"
            )
            for n in layout.PREDICTION_FIGURES
        ],
    log:
        "logs/predict_cr3bp.log",
    conda:
        "../envs/amorgs.yaml"
    threads: CFG.resources.predict.threads
    resources:
        mem_mb=CFG.resources.predict.mem_mb,
        runtime=CFG.resources.predict.runtime_min,
    params:
        models_dir=lambda w, input: os.path.dirname(input.models[0]),
        # FRACTION=PATH, the fraction read back from the folder name fraction={f}
        fraction_models=lambda w, input: " ".join(
            f"{os.path.basename(os.path.dirname(p)).split('=', 1)[1]}={p}" for p in input.fraction_models
        ),
        test_alphas=floats(CFG.problems.cr3bp.alphas.test),
        n_samples=CFG.cr3bp_models.n_samples,
        seed=CFG.cr3bp_models.seed,
        figures_dir=lambda w, output: os.path.dirname(output.figures[0]),
    shell:
        "python -m amorgs predict-cr3bp --models-dir {params.models_dir} --fraction-models {params.fraction_models} "
        "--high-quality {input.high_quality} --test-alphas {params.test_alphas} --n-samples {params.n_samples} "
        "--seed {params.seed} --samples {output.samples} --metrics {output.metrics} "
        "--figures-dir {params.figures_dir} > {log} 2>&1"
