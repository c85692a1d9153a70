"""Shared test setup."""

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


#: Run first (pytest-xdist hands tests out in collection order): the smoke workflow (≈ 5 min on 2 cores) then the
#: other slow tests, so that the longest run beside everything else instead of last.
FIRST = "tests/integration/test_workflow.py::test_smoke_workflow_tracks_every_job"


def pytest_collection_modifyitems(config, items):
    """Longest first: the smoke workflow, then every ``slow`` test, then the rest, each in collection order."""
    items.sort(key=lambda item: (item.nodeid != FIRST, item.get_closest_marker("slow") is None))
