"""Energies of the incremental potential, one per module, all behind `Energy`."""

from .base import Energy
from .bending import BendingEnergy
from .external import ExternalForceEnergy
from .inertia import InertiaEnergy
from .membrane_fbw import MembraneFBW
from .membrane_stvk import MembraneStVK

# Membrane model name (sim.materials.MEMBRANE_MODELS) -> energy class.
MEMBRANES = {"fbw": MembraneFBW, "stvk": MembraneStVK}


def membrane_params(material) -> tuple[float, float]:
    """Per-point parameters of a material's membrane: (h k_st, h k_sh) for FBW,
    (h mu, h lambda) for StVK."""
    if material.membrane == "fbw":
        return material.h * material.k_st, material.h * material.k_sh
    mu, lam = material.lame
    return material.h * mu, material.h * lam


__all__ = ["Energy", "BendingEnergy", "ExternalForceEnergy", "InertiaEnergy", "MembraneFBW", "MembraneStVK",
           "MEMBRANES", "membrane_params"]
