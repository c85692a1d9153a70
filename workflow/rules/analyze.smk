# Stage 3, analysis: the structure of the CR3BP solution set (paper Sec. III.B): hyperplanes, funnels, moving
# averages, diversity and control statistics as tables, Figs. 3–13 as PNG.


rule analyze_cr3bp:
    input:
        solutions=layout.alpha_tables(CFG, "cr3bp"),
        high_quality=layout.HIGH_QUALITY.format(problem="cr3bp"),
    output:
        metrics=layout.CR3BP_ANALYSIS_METRICS,
        tables=[layout.CR3BP_ANALYSIS_TABLE.format(name=n) for n in layout.ANALYSIS_TABLES],
        figures=[
            report(layout.FIGURE.format(name=n), caption="../report/cr3bp_structure.rst", category="CR3BP structure")
            for n in layout.ANALYSIS_FIGURES
        ],
    log:
        "logs/analyze_cr3bp.log",
    conda:
        "../envs/amorgs.yaml"
    threads: CFG.resources.analyze.threads
    resources:
        mem_mb=CFG.resources.analyze.mem_mb,
        runtime=CFG.resources.analyze.runtime_min,
    params:
        beta=CFG.problems.cr3bp.filter.min_final_mass_kg,
        structure=json.dumps(CFG.cr3bp_analysis.params, sort_keys=True),
        tables_dir=lambda w, output: os.path.dirname(output.tables[0]),
        figures_dir=lambda w, output: os.path.dirname(output.figures[0]),
    shell:
        "python -m amorgs analyze-cr3bp --inputs {input.solutions} --high-quality {input.high_quality} "
        "--beta {params.beta} --params {params.structure:q} --metrics {output.metrics} "
        "--tables-dir {params.tables_dir} --figures-dir {params.figures_dir} > {log} 2>&1"
