# Stage 4, models.  De Jong: the GMM-prior CVAE on the filtered minima at the training α, sampled at the
# held-out test α and scored against the analytic minima (amorgs.steps.dejong).  CR3BP (paper Sec. IV): each
# model trained on the high-quality rows at the training α only (the test α are generated for the ground
# truth, never trained on); Fig. 18's GMM-CVAEs on fractions of the data; the models of the extra training
# seeds (the ablation's replicates); the samples at the test α (amorgs.steps.train, amorgs.steps.predict).


rule train_dejong_cvae:
    input:
        high_quality=layout.HIGH_QUALITY.format(problem="dejong"),
    output:
        **step_outputs("train_dejong_cvae"),
    log:
        "logs/train_dejong_cvae.log",
    benchmark:
        "results/benchmarks/train_dejong_cvae/job.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("train_dejong_cvae")
    resources:
        **step_resources("train_dejong_cvae"),
    params:
        **step_params("train_dejong_cvae"),
    shell:
        STEP


rule predict_dejong_cvae:
    input:
        model=layout.DEJONG_MODEL,
    output:
        **step_outputs("predict_dejong_cvae"),
    log:
        "logs/predict_dejong_cvae.log",
    benchmark:
        "results/benchmarks/predict_dejong_cvae/job.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("predict_dejong_cvae")
    resources:
        **step_resources("predict_dejong_cvae"),
    params:
        **step_params("predict_dejong_cvae"),
    shell:
        STEP


rule train_cr3bp:
    input:
        high_quality=layout.HIGH_QUALITY.format(problem="cr3bp"),
    output:
        **step_outputs("train_cr3bp"),
    log:
        "logs/train_cr3bp/{model}.log",
    benchmark:
        "results/benchmarks/train_cr3bp/{model}.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("train_cr3bp")
    resources:
        **step_resources("train_cr3bp"),
    params:
        **step_params("train_cr3bp"),
    shell:
        STEP


rule train_cr3bp_fraction:
    input:
        high_quality=layout.HIGH_QUALITY.format(problem="cr3bp"),
    output:
        **step_outputs("train_cr3bp_fraction"),
    log:
        "logs/train_cr3bp/fraction={fraction}/{model}.log",
    benchmark:
        "results/benchmarks/train_cr3bp_fraction/fraction={fraction}/{model}.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("train_cr3bp_fraction")
    resources:
        **step_resources("train_cr3bp_fraction"),
    params:
        **step_params("train_cr3bp_fraction"),
    shell:
        STEP


rule train_cr3bp_replicate:
    input:
        high_quality=layout.HIGH_QUALITY.format(problem="cr3bp"),
    output:
        **step_outputs("train_cr3bp_replicate"),
    log:
        "logs/train_cr3bp/seed={mseed}/{model}.log",
    benchmark:
        "results/benchmarks/train_cr3bp_replicate/seed={mseed}/{model}.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("train_cr3bp_replicate")
    resources:
        **step_resources("train_cr3bp_replicate"),
    params:
        **step_params("train_cr3bp_replicate"),
    shell:
        STEP


rule predict_cr3bp:
    input:
        models=steps.outputs_of("train_cr3bp", CFG, "model"),
        fraction_models=steps.outputs_of("train_cr3bp_fraction", CFG, "model", model="cvae_gmm"),
        high_quality=layout.HIGH_QUALITY.format(problem="cr3bp"),
    output:
        **step_outputs("predict_cr3bp"),
    log:
        "logs/predict_cr3bp.log",
    benchmark:
        "results/benchmarks/predict_cr3bp/job.tsv"
    conda:
        "../envs/amorgs.yaml"
    threads: step_threads("predict_cr3bp")
    resources:
        **step_resources("predict_cr3bp"),
    params:
        **step_params("predict_cr3bp"),
    shell:
        STEP
