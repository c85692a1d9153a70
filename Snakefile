# amorgs workflow: generate → merge → filter per problem; the De Jong CVAE; the CR3BP structure analysis, models,
# predictions and warm-start ablation; the paper figures.
# Thin by design: the rules live in workflow/rules/, the work in the amorgs package (`python -m amorgs ...`).
# Run:  snakemake --cores 2 [--configfile config/smoke.yaml]      (profile: workflow/profiles/default)
from snakemake.utils import min_version

min_version("9.0")


configfile: "config/default.yaml"


include: "workflow/rules/common.smk"
include: "workflow/rules/generate.smk"
include: "workflow/rules/filter.smk"
include: "workflow/rules/analyze.smk"
include: "workflow/rules/train.smk"
include: "workflow/rules/ablation.smk"
include: "workflow/rules/report.smk"


# Short bookkeeping jobs run on the submit host under the SLURM executor.
localrules:
    all,
    merge,
    filter,
    fig02_foxholes,
    fig16_dejong_predictions,
    ablation_report,


onstart:
    start_tracking()


onsuccess:
    finish_tracking("FINISHED")


onerror:
    finish_tracking("FAILED")


rule all:
    default_target: True
    input:
        layout.targets(CFG),
