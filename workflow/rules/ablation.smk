# Stage 5, ablation (paper Sec. V.B.7–8, issue 11): per (test α, sampler) one job solving guesses from that
# sampler with the CR3BP solver options — once with the models of cr3bp_models.seed, and once more per
# cr3bp_models.extra_seeds (replicates: their own models, their own cell seed); then Table 6, the capped
# studies, coverage, rates + Fisher tests, the β sweep, expected running time, anytime curves and figures.
ABLATION_CELL_SHELL = (
    "python -m amorgs ablation-cell --alpha {params.alpha} --sampler {wildcards.sampler} {params.args} "
    "--model-seed {params.model_seed} {params.replicate} --starts {params.starts} --seed {params.seed} "
    "--workers {threads} --solver-options {params.solver:q} --output {output} > {log} 2>&1"
)


rule ablation_cell:
    input:
        unpack(ablation_cell_inputs),
    output:
        layout.ABLATION_CELL,
    log:
        "logs/ablation_cell/alpha={alpha}/{sampler}.log",
    conda:
        "../envs/amorgs.yaml"
    threads: CFG.ablation.workers
    resources:
        mem_mb=CFG.ablation.mem_mb,
        runtime=CFG.ablation.runtime_min,
    params:
        alpha=lambda w: CFG.problems.cr3bp.alpha_values()[w.alpha],
        seed=seed_of_cell,
        model_seed=CFG.cr3bp_models.seed,
        replicate="",
        starts=CFG.ablation.n_starts,
        solver=json.dumps(CFG.problems.cr3bp.solver_options(), sort_keys=True),
        args=ablation_cell_args,
    shell:
        ABLATION_CELL_SHELL


rule train_cr3bp_replicate:
    # the models of one extra training seed: train_cr3bp's settings with this seed
    input:
        layout.HIGH_QUALITY.format(problem="cr3bp"),
    output:
        layout.CR3BP_REPLICATE_MODEL,
    log:
        "logs/train_cr3bp/seed={mseed}/{model}.log",
    wildcard_constraints:
        mseed=r"\d+",
    conda:
        "../envs/amorgs.yaml"
    threads: CFG.resources.train.threads
    resources:
        mem_mb=CFG.resources.train.mem_mb,
        runtime=CFG.resources.train.runtime_min,
    params:
        training=lambda w: train_cr3bp_params(int(w.mseed)),
    shell:
        "python -m amorgs train-cr3bp --data {input} --model {wildcards.model} {params.training} "
        "--threads {threads} --output {output} > {log} 2>&1"


rule ablation_cell_replicate:
    input:
        unpack(lambda w: ablation_cell_inputs(w, layout.CR3BP_REPLICATE_MODEL)),
    output:
        layout.ABLATION_REPLICATE_CELL,
    log:
        "logs/ablation_cell/seed={mseed}/alpha={alpha}/{sampler}.log",
    wildcard_constraints:
        mseed=r"\d+",
    conda:
        "../envs/amorgs.yaml"
    threads: CFG.ablation.workers
    resources:
        mem_mb=CFG.ablation.mem_mb,
        runtime=CFG.ablation.runtime_min,
    params:
        alpha=lambda w: CFG.problems.cr3bp.alpha_values()[w.alpha],
        seed=seed_of_replicate_cell,
        model_seed=lambda w: int(w.mseed),
        replicate="--replicate",
        starts=CFG.ablation.n_starts,
        solver=json.dumps(CFG.problems.cr3bp.solver_options(), sort_keys=True),
        args=ablation_cell_args,
    shell:
        ABLATION_CELL_SHELL


rule ablation_report:
    input:
        cells=layout.ablation_cells(CFG),
        high_quality=layout.HIGH_QUALITY.format(problem="cr3bp"),
    output:
        summary=layout.ABLATION_SUMMARY,
        table6_csv=layout.TABLE.format(name="table6.csv"),
        table6_md=layout.TABLE.format(name="table6.md"),
        capped=layout.TABLE.format(name="ablation_capped.csv"),
        coverage=layout.TABLE.format(name="ablation_coverage.csv"),
        stat_tables=[
            layout.TABLE.format(name=n)
            for n in layout.ABLATION_TABLES
            if n.startswith("ablation_") and n not in ("ablation_capped.csv", "ablation_coverage.csv")
        ],
        figures=[
            report(layout.FIGURE.format(name=n), caption="../report/ablation.rst", category="CR3BP ablation")
            for n in layout.ABLATION_FIGURES
        ],
    log:
        "logs/ablation_report.log",
    conda:
        "../envs/amorgs.yaml"
    threads: CFG.resources.figure.threads
    resources:
        mem_mb=CFG.resources.figure.mem_mb,
        runtime=CFG.resources.figure.runtime_min,
    params:
        beta=CFG.problems.cr3bp.filter.min_final_mass_kg,
        figures_dir=lambda w, output: os.path.dirname(output.figures[0]),
        tables_dir=lambda w, output: os.path.dirname(output.table6_csv),
        beta_sweep=floats(CFG.ablation.beta_sweep_kg),
        caps=" ".join(map(str, CFG.ablation.iteration_caps)),
        max_iter=CFG.problems.cr3bp.solver.max_iter,
        n_boot=CFG.ablation.n_boot,
        seed=CFG.ablation.seed,
    shell:
        "python -m amorgs ablation-report --cells {input.cells} --high-quality {input.high_quality} "
        "--beta {params.beta} --summary {output.summary} --table6-csv {output.table6_csv} "
        "--table6-md {output.table6_md} --capped {output.capped} --coverage {output.coverage} "
        "--tables-dir {params.tables_dir} --beta-sweep {params.beta_sweep} --iteration-caps {params.caps} "
        "--max-iter {params.max_iter} --n-boot {params.n_boot} --seed {params.seed} "
        "--figures-dir {params.figures_dir} > {log} 2>&1"
