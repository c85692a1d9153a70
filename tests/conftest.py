"""Shared test setup."""

import os

import pytest


@pytest.fixture(autouse=True, scope="session")
def one_torch_thread():
    """Tiny networks: one intra-op thread is fastest on the 2-core CI box and does not spin against the
    solver processes that other tests start."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


#: Run first (pytest-xdist hands tests out in collection order): the smoke workflow (≈ 7 min on 2 cores) then the
#: other slow tests, so that the longest run beside everything else instead of last.
FIRST = "tests/integration/test_workflow.py::test_smoke_workflow_tracks_every_job"
#: The cluster tests: on the worker that runs the smoke workflow, after it (see ``pytest_xdist_make_scheduler``).
CLUSTER_TESTS = "tests/integration/test_workflow_slurm.py::"


#: The CI-only tests (marker ``ci``: the smoke workflow, the killed-run and ``kill -9`` workflow tests — each a
#: workflow run of minutes) run only where this variable is ``1``: ``.ci/run`` sets it, the README's test
#: command leaves them out (they skip and say so) to stay within minutes on two cores.
CI_TESTS = "AMORGS_CI_TESTS"


def pytest_collection_modifyitems(config, items):
    """Longest first: the smoke workflow, then every ``slow`` test, then the rest, each in collection order.
    Tests marked ``ci`` skip unless ``AMORGS_CI_TESTS=1``."""
    items.sort(key=lambda item: (item.nodeid != FIRST, item.get_closest_marker("slow") is None))
    if os.environ.get(CI_TESTS) != "1":
        skip = pytest.mark.skip(reason=f"CI-only (a workflow run of minutes): {CI_TESTS}=1 runs it, as .ci/run does")
        for item in items:
            if item.get_closest_marker("ci") is not None:
                item.add_marker(skip)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """pytest-xdist's ``load`` scheduling (``-n 2``), except that the smoke workflow and the cluster tests are one
    unit of work: one worker runs them one after the other, in collection order, while the others run the rest.
    The cluster smoke test compares its tables with the local smoke run (``AMORGS_SMOKE_WORKDIR``), so that run must
    have finished; and the cluster tests share the cluster's one node (one sets it DOWN, one counts the jobs it
    submitted), so no two may run at once.  (xdist's own ``xdist_group`` mark does nothing under pytest 9.2: xdist
    3.8 renames a node id through an attribute that pytest no longer reads.)"""
    if config.getvalue("dist") != "load":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class SmokeThenCluster(LoadScopeScheduling):
        """Each test its own unit of work (as ``load``, handed out in collection order), but for one unit: the smoke
        workflow and the cluster tests, handed out first (the largest unit)."""

        def _split_scope(self, nodeid: str) -> str:
            return "smoke-workflow" if nodeid == FIRST or nodeid.startswith(CLUSTER_TESTS) else nodeid

    return SmokeThenCluster(config, log)
