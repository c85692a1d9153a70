"""The ablation report's studies as one table, :data:`STUDIES`: one :class:`Study` per table it writes.

A study is a pure function of the cell tables (:class:`amorgs.ablation.report.StudyInputs` → a table and its
MLflow metrics), the name of its table (``results/tables/<stem>.csv``), the title of its Markdown rendering
(``<stem>.md``; none: CSV only) and whether a config may leave it empty.  :func:`amorgs.ablation.report.summarize`
runs them in table order, the ablation report step writes and logs what they return, the rule's outputs
(:func:`table_files`) and ``check-outputs`` (:data:`OPTIONAL_STEMS`) come from here.  Adding a study: its function
(in :mod:`amorgs.ablation.report`, on the statistics of :mod:`amorgs.ablation.statistics` and
:mod:`amorgs.ablation.running_time`) and one :class:`Study` below.

The function is a dotted name ``"package.module:callable"`` resolved only when the report runs, so this module
imports neither pandas nor the statistics (the workflow reads the table when it plans the DAG).
"""

from __future__ import annotations

from dataclasses import dataclass

from amorgs.ablation.arms import BASELINE_ARM, REUSE_ARM


@dataclass(frozen=True)
class Study:
    """One table of the ablation report.

    name: its key in :attr:`amorgs.ablation.summary.AblationSummary.tables`.
    compute: ``(inputs: StudyInputs) -> (table, metrics)``, a dotted name; ``metrics`` maps
        :func:`amorgs.alphas.metric_key` keys to numbers (NaN dropped by the report).
    title: the Markdown table's title (``<stem>.md`` beside the CSV); none: CSV only.
    markdown: a dotted ``(table) -> str`` that renders the Markdown file instead of the plain table (Table 6 in
        the paper's orientation).
    optional: a config may ask for none of it (no iteration caps, no break-even, no learning curve, one training
        seed, no reuse arm): its CSV then says so in one row, and ``check-outputs`` accepts that.
    """

    name: str
    compute: str
    title: str | None = None
    markdown: str | None = None
    optional: bool = False

    @property
    def stem(self) -> str:
        """The file stem under ``results/tables/``: ``table6`` or ``ablation_<name>``."""
        return self.name if self.name == "table6" else f"ablation_{self.name}"

    @property
    def files(self) -> tuple[str, ...]:
        """The file names it writes: the CSV and, with a title or a renderer, the Markdown."""
        md = (f"{self.stem}.md",) if self.title or self.markdown else ()
        return (f"{self.stem}.csv", *md)


_R = "amorgs.ablation.report"

STUDIES: tuple[Study, ...] = (
    Study("table6", f"{_R}:table6_study", markdown=f"{_R}:table6_markdown"),
    Study("capped", f"{_R}:capped_study_per_alpha"),
    Study("coverage", f"{_R}:coverage_study"),
    Study("rates", f"{_R}:rates_study",
          "High-quality rate per arm: k of n starts, Wilson 95 % interval, one-sided Fisher p (arm > reference)"),
    Study("beta_sweep", f"{_R}:beta_sweep_study", "High-quality rate vs β per arm (Wilson 95 %, one-sided Fisher p)"),
    Study("ert", f"{_R}:ert_study",
          f"Expected running time aRT = cost spent ÷ high-quality found; speed-up = aRT({BASELINE_ARM}) ÷ "
          f"aRT(arm); versus_reuse = aRT({REUSE_ARM}) ÷ aRT(arm), > 1: the arm beats reuse; bootstrap 95 %; the "
          "reuse arms drawn as ablation_reuse_pool states"),
    Study("ert_distinct", f"{_R}:ert_distinct_study",
          "What a designer wants: aRT = cost spent ÷ new η-distinct high-quality optima (paper Eq. 12; each arm's "
          "starts in order, a solution counts when farther than η from every one counted before — repeats find "
          "nothing new); speed-up and versus_reuse as in ablation_ert, bootstrap 95 %"),
    Study("reuse_pool", f"{_R}:reuse_pool_study",
          "Reuse arms: the training α reused, its pool of high-quality rows, and the draw every table of this "
          "report counts — without replacement until the pool is exhausted, then with replacement", optional=True),
    Study("iteration_capped", f"{_R}:iteration_capped_study",
          f"Fig. 22 with a fixed iteration cap: % within cap (Wilson 95 %), throughput, ratios to {BASELINE_ARM} "
          "(ratio of percentages: Katz 95 %; throughput ratio: bootstrap 95 %)", optional=True),
    Study("break_even", f"{_R}:break_even_study",
          "Break-even: new α after which an arm's up-front CPU (data; training) is repaid by the CPU it saves over "
          f"{BASELINE_ARM}, for K high-quality solutions per α (bootstrap 95 %)", optional=True),
    Study("learning_curve", f"{_R}:learning_curve_study",
          "Learning curve: aRT of the learned arms vs the fraction of the training data their models saw; "
          f"speed-up = aRT({BASELINE_ARM}) ÷ aRT(arm), bootstrap 95 %", optional=True),
    Study("seeds", f"{_R}:seeds_study",
          "Per model-training seed: high quality k of n (Wilson 95 %) and aRT in iterations; the other tables pool "
          "the seeds", optional=True),
    Study("anytime", f"{_R}:anytime_study"),
    Study("anytime_bands", f"{_R}:anytime_bands_study"),
)

#: Name → study.
BY_NAME: dict[str, Study] = {s.name: s for s in STUDIES}
#: The tables a config may leave empty (``check-outputs`` accepts them with no rows).
OPTIONAL_STEMS: tuple[str, ...] = tuple(s.stem for s in STUDIES if s.optional)


def table_files() -> tuple[str, ...]:
    """Every file name the ablation report writes under ``results/tables/``, in table order."""
    return tuple(f for s in STUDIES for f in s.files)
