"""GARMENT_REPRODUCIBLE (sim/energies/barrier.py): ipctk's collision builds and potential
sums run on one thread inside `in_order`, so a run repeats bit for bit; without it they
keep ipctk's threads."""

from __future__ import annotations

import ipctk
import pytest

import sim.energies.barrier as barrier


@pytest.mark.parametrize("reproducible", [True, False])
def test_in_order_runs_ipctk_on_one_thread_only_when_asked_and_restores_its_threads(monkeypatch, reproducible):
    monkeypatch.setattr(barrier, "REPRODUCIBLE", reproducible)
    before = ipctk.get_num_threads()
    ipctk.set_num_threads(2)
    try:
        with barrier.in_order():
            assert ipctk.get_num_threads() == (1 if reproducible else 2)
        assert ipctk.get_num_threads() == 2
        with pytest.raises(RuntimeError):  # restored on the way out of an error too
            with barrier.in_order():
                raise RuntimeError("stop")
        assert ipctk.get_num_threads() == 2
    finally:
        ipctk.set_num_threads(before)
