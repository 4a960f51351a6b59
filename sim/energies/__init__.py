"""Energies of the incremental potential, one per module, all behind `Energy`."""

from .base import Energy
from .bending import BendingEnergy
from .external import ExternalForceEnergy
from .inertia import InertiaEnergy
from .membrane_fbw import MembraneFBW
from .membrane_stvk import MembraneStVK

__all__ = ["Energy", "BendingEnergy", "ExternalForceEnergy", "InertiaEnergy", "MembraneFBW", "MembraneStVK"]
