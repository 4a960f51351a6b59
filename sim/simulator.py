"""A model and the state it advances, with what a caller asks of a run: step, run frames
to sinks, read positions, set or copy the state (for checkpoints and retries).

    sim = Simulator(bspline_model(patches, materials, ...))   # or garment.build.build_simulator
    sim.step()
    sim.state.save("run.npz")                                 # everything that evolves
    sim.state = State.load("run.npz")
"""

from __future__ import annotations

from typing import Callable, Iterable

import numpy as np

from .driver import drive
from .model import Model
from .sinks import MeshTopology, Sink
from .state import State
from .stats import StepStats
from .stepper import step as advance


class Simulator:
    def __init__(self, model: Model, state: State | None = None):
        self.model = model
        self._state = state if state is not None else model.initial_state()

    @property
    def state(self) -> State:
        """The live state: stepping changes it in place; keep `state.copy()` to go back."""
        return self._state

    @state.setter
    def state(self, state: State) -> None:
        """Continue from `state` (of this model): its components are loaded from it."""
        self.model.apply(state)
        self._state = state

    # The state's most used fields, for reading and for setting up a run.
    C = property(lambda self: self._state.C, lambda self, v: setattr(self._state, "C", v))
    V = property(lambda self: self._state.V, lambda self, v: setattr(self._state, "V", v))
    t = property(lambda self: self._state.t)
    step_count = property(lambda self: self._state.step_count)
    dt = property(lambda self: self._state.dt)

    def set_dt(self, dt: float) -> None:
        """Change the time step (step splitting)."""
        self._state.dt = float(dt)
        self.model.set_dt(dt)

    def step(self) -> StepStats:
        """Advance one time step (or one quasi-static load increment)."""
        return advance(self.model, self._state)

    def run(self, frames: int, steps_per_frame: int = 1, sinks: Iterable[Sink] = (),
            on_step: Callable[[StepStats], None] | None = None) -> list[StepStats]:
        """Write the initial frame, then `frames` frames of `steps_per_frame` steps each,
        without splitting failed steps (sim/driver.py: `drive` for long runs)."""
        return drive(self, frames, steps_per_frame, sinks, on_step=on_step, split=False).stats

    # ------------------------------------------------------------------ queries
    @property
    def n_dofs(self) -> int:
        return self.model.n_dofs

    def control_points(self, name: str) -> np.ndarray:
        return self.model.piece(name).control_points(self.C)

    def velocities(self, name: str) -> np.ndarray:
        return self.model.piece(name).control_points(self.V)

    def positions(self, name: str | None = None) -> np.ndarray | dict[str, np.ndarray]:
        """Embedded mesh vertices (V, 3) of one piece, or a dict of all pieces."""
        if name is None:
            return {p.name: p.W @ self.C for p in self.model.pieces}
        return self.model.piece(name).W @ self.C

    def obstacle_positions(self) -> dict[str, np.ndarray]:
        """Current vertices (V, 3) of every obstacle, by name."""
        if self.model.drive is not None:
            return self.model.drive.positions()
        return {o.name: o.at(self.t) for o in self.model.obstacles}

    def pin_targets(self, t: float) -> np.ndarray:
        """(n_cp, 3) positions with every pinned point moved to its place at time t."""
        return self.model.pin_targets(self.C, t)

    def seam_gaps(self) -> dict[str, float]:
        """Largest gap (m) of each seam, by name (seams without one: their index)."""
        return self.model.sewing.gaps(self.C) if self.model.sewing is not None else {}

    def seam_pairs_held_open(self) -> int:
        """Matched seam vertex pairs that could not be sewn (SeamContact.held_open)."""
        sc = self.model.seam_contact
        return int(sc.held_open().sum()) if sc is not None else 0

    def topologies(self) -> list[MeshTopology]:
        return self.model.topologies()
