# Stage 5, ablation (paper Sec. V.B.7–8): per (test α, sampler) one job solving guesses from that sampler with
# the CR3BP solver options; then Table 6, the capped study, hyperplane coverage and Figs. 21–23.


rule ablation_cell:
    input:
        # the uniform sampler needs no model; the learned ones load theirs from models_dir
        lambda w: [] if w.sampler == "uniform" else [layout.CR3BP_MODEL.format(model=m) for m in layout.CR3BP_MODELS],
    output:
        layout.ABLATION_CELL,
    log:
        "logs/ablation_cell/alpha={alpha}/{sampler}.log",
    params:
        alpha=lambda w: CFG.problems.cr3bp.alpha_values()[w.alpha],
        seed=seed_of_cell,
        starts=CFG.ablation.n_starts,
        solver=json.dumps(CFG.problems.cr3bp.solver_options(), sort_keys=True),
        models=lambda w, input: f"--models-dir {os.path.dirname(input[0])}" if len(input) else "",
    threads: CFG.ablation.workers
    resources:
        mem_mb=CFG.ablation.mem_mb,
        runtime=CFG.ablation.runtime_min,
    conda:
        "../envs/amorgs.yaml"
    shell:
        "python -m amorgs ablation-cell --alpha {params.alpha} --sampler {wildcards.sampler} "
        "{params.models} --starts {params.starts} --seed {params.seed} --workers {threads} "
        "--solver-options {params.solver:q} --output {output} > {log} 2>&1"


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
        figures=[
            report(layout.FIGURE.format(name=n), caption="../report/ablation.rst", category="CR3BP ablation")
            for n in layout.ABLATION_FIGURES
        ],
    log:
        "logs/ablation_report.log",
    params:
        beta=CFG.problems.cr3bp.filter.min_final_mass_kg,
        figures_dir=lambda w, output: os.path.dirname(output.figures[0]),
    threads: CFG.resources.figure.threads
    resources:
        mem_mb=CFG.resources.figure.mem_mb,
        runtime=CFG.resources.figure.runtime_min,
    conda:
        "../envs/amorgs.yaml"
    shell:
        "python -m amorgs ablation-report --cells {input.cells} --high-quality {input.high_quality} "
        "--beta {params.beta} --summary {output.summary} --table6-csv {output.table6_csv} "
        "--table6-md {output.table6_md} --capped {output.capped} --coverage {output.coverage} "
        "--figures-dir {params.figures_dir} > {log} 2>&1"
