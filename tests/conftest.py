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
