"""Trajectory design on demand (``amorgs design``, issue 12): N good, verified, η-diverse CR3BP transfers at one α.

The package in three parts and the command that joins them:

    search.py     the request, the checks made before the first solve, the sampler, the solver workers and
                  the search in rounds (:func:`design`, :class:`DesignRequest`, :class:`DesignResult`)
    outputs.py    the files: tables, trajectories (CSV, CCSDS OEM), plot, summary, README (:func:`write_outputs`)
    tracking.py   the MLflow run of a design, opened in the background once solving has begun (through
                  :mod:`amorgs.tracking`, the only module that talks to MLflow)
    command.py    ``amorgs design``: check, prepare, search, write, track (:func:`run_design`)

Importing the package is light: torch, MLflow, matplotlib and the OEM writer load only when a step needs them.
"""

from amorgs.design.command import ProgressLine, run_design
from amorgs.design.outputs import check_output_dir, default_output_dir, write_outputs
from amorgs.design.search import (
    DEFAULT_CONFIG,
    DEFAULT_LIBRARY_DIR,
    DEFAULT_MODELS_DIR,
    DEFAULT_SAMPLER,
    PROBLEM,
    DesignRequest,
    DesignResult,
    Prepared,
    check_beta,
    design,
    library_high_quality,
    make_sampler,
    prepare,
    select_diverse,
)
from amorgs.design.tracking import DESIGN_EXPERIMENT, DESIGN_STORE_DIR

__all__ = [
    "DEFAULT_CONFIG", "DEFAULT_LIBRARY_DIR", "DEFAULT_MODELS_DIR", "DEFAULT_SAMPLER", "DESIGN_EXPERIMENT",
    "DESIGN_STORE_DIR", "PROBLEM", "DesignRequest", "DesignResult", "Prepared", "ProgressLine", "check_beta",
    "check_output_dir", "default_output_dir", "design", "library_high_quality", "make_sampler", "prepare",
    "run_design", "select_diverse", "write_outputs",
]
