"""Per-step solver statistics: what a step cost and where the time went."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field


@dataclass
class StepStats:
    """One time step (or one quasi-static load increment).

    Times are wall-clock seconds. `residual` is the last ||dC||_inf / dt in m/s (the
    paper's stopping quantity); `energy` is the incremental potential at the end, in J.
    """

    step: int = 0
    time: float = 0.0
    newton_iterations: int = 0
    residual: float = 0.0
    energy: float = 0.0
    converged: bool = False
    line_search_steps: int = 0
    factorizations: int = 0  # numerical Cholesky factorizations (the dominant cost)
    t_assembly: float = 0.0
    t_factorization: float = 0.0
    t_solve: float = 0.0
    t_line_search: float = 0.0  # energy evaluations of the line search (CCD apart)
    t_ccd: float = 0.0  # continuous collision detection (predictor and line-search starts)
    t_total: float = 0.0
    extra: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return asdict(self)

    def summary(self) -> str:
        return (
            f"step {self.step:5d}  t={self.time:7.3f}s  newton {self.newton_iterations:3d}  "
            f"|dC|/dt={self.residual:8.2e}  {self.t_total * 1e3:7.1f} ms "
            f"(asm {self.t_assembly * 1e3:.0f} / fact {self.t_factorization * 1e3:.0f} / "
            f"solve {self.t_solve * 1e3:.0f} / ccd {self.t_ccd * 1e3:.0f} / ls {self.t_line_search * 1e3:.0f})"
        )
