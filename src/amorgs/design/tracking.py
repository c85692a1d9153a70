"""The MLflow mirror of ``amorgs design``: which store and experiment its runs go to.  Every call to MLflow goes
through :mod:`amorgs.tracking` (:func:`~amorgs.tracking.standalone_run`), the only module that talks to it.
"""

from __future__ import annotations

from pathlib import Path

#: The MLflow store of ``amorgs design`` calls: the workflow's store, so that ``amorgs ui`` shows designs beside
#: workflow runs; a design is a standalone run and never touches a running workflow's invocation
#: (``results/mlflow/invocation.json``).
DESIGN_STORE_DIR = Path("results/mlflow")
DESIGN_EXPERIMENT = "amorgs-design"
