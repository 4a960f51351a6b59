"""Cloth materials: the paper's parameter set and the constants the energies use.

Conventions follow the paper's public reference implementation (docs/design.md section 4), so
the paper's table of (E_st, E_sh, E_bd, nu, h) reproduces the paper's behaviour:

    k_st = E_st / (2 (1 + nu))        stretch stiffness, Pa
    k_sh = (E_sh / E_st) k_st         shear stiffness, Pa
    D    = E_bd h^3 / (12 (1 - nu^2)) bending stiffness, N m
"""

from __future__ import annotations

from dataclasses import dataclass, replace

# "none" switches the membrane off (bending-only benchmarks such as the plate).
MEMBRANE_MODELS = ("fbw", "stvk", "none")
QUADRATURES = ("reduced", "gauss2", "gauss3")
# Smallest control net per direction each quadrature supports: the reduced rule needs a
# boundary ring around a non-empty interior region (docs/design.md section 3).
MIN_CONTROL_POINTS = {"reduced": 5, "gauss2": 3, "gauss3": 3}


@dataclass(frozen=True)
class Material:
    """Areal cloth material. Moduli in Pa, thickness h in m, density rho in kg/m^3."""

    E_st: float = 2.0e6
    E_sh: float = 1.0e4
    E_bd: float = 8.0e3
    nu: float = 0.243
    h: float = 3.18e-4
    rho: float = 472.6
    membrane: str = "fbw"
    quadrature: str = "reduced"

    @property
    def k_st(self) -> float:
        return self.E_st / (2.0 * (1.0 + self.nu))

    @property
    def k_sh(self) -> float:
        return self.E_sh / self.E_st * self.k_st

    @property
    def bending_stiffness(self) -> float:
        return self.E_bd * self.h**3 / (12.0 * (1.0 - self.nu**2))

    @property
    def lame(self) -> tuple[float, float]:
        """Plane-stress Lame parameters (mu, lambda) from E_st and nu, for StVK."""
        mu = self.E_st / (2.0 * (1.0 + self.nu))
        lam = self.E_st * self.nu / (1.0 - self.nu**2)
        return mu, lam

    @property
    def areal_density(self) -> float:
        return self.rho * self.h

    def with_(self, **changes) -> "Material":
        return replace(self, **changes)


# Cotton as measured by Penava et al. 2014, the paper's default (section 6); the softer
# cloth of the paper's Hiphop Dance scene (its table of statistics), which it pairs with
# dhat = 3e-4 m and mu = 0.1.
PRESETS: dict[str, Material] = {
    "cotton": Material(),
    "hiphop": Material(E_st=5.0e5, E_sh=2.5e3, E_bd=8.0e2),
}
