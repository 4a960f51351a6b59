"""Fixtures shared by the test modules."""

import ipctk
import pytest


@pytest.fixture
def one_ipc_thread():
    """ipctk's TBB reductions vary between runs (~1e-13); one thread makes them repeat."""
    before = ipctk.get_num_threads()
    ipctk.set_num_threads(1)
    yield
    ipctk.set_num_threads(before)
