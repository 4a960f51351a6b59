"""Settling drag: a decay of the cloth's absolute velocity after each step, from a start time.

It brings a garment to rest on a still body instead of letting it swing about it
(garment dress: 10/s, near critical for the 1-2 Hz swings of a skirt), while the cloth
still falls freely under gravity. Dropping the velocities instead (quasi-static steps)
moves the cloth at most g dt a step: skirt_04's hem was still 10 cm up after 2.5 s.
The stepper applies it (sim/stepper.py); sewing's pulled-shut steps drop velocities
altogether and come first.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Drag:
    rate: float = 0.0  # 1/s; 0: none
    start: float = 0.0  # s: steps ending before this keep their velocity (the pre-roll)

    def kept(self, t_next: float, dt: float) -> float:
        """The fraction of its velocity the cloth keeps after the step ending at t_next."""
        if self.rate == 0.0 or t_next < self.start - 1e-9 * dt:
            return 1.0
        return float(np.exp(-self.rate * dt))
