"""Former module names, kept importable for code written against them.

A renamed module leaves no file behind: `install_module_aliases` (run when `mca_drake` is
imported) puts a finder on `sys.meta_path` that answers an import of a former name with the
module it now is, after a `DeprecationWarning`. Names, classes and `isinstance` checks are
those of the new module. `MODULE_ALIASES` lists them; the changelog says when they go.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings
from types import ModuleType

# former module name -> the module it now is
MODULE_ALIASES = {
    "mca_drake.torch_plant": "mca_drake.learning.torch_plant",
    "mca_drake.systems.classical_washout": "mca_drake.systems.washout",
    "mca_drake.systems.nmpc_controller": "mca_drake.systems.nmpc",
    "mca_drake.systems.dpc_policy": "mca_drake.systems.dpc",
    "mca_drake.learning.dpc": "mca_drake.learning.dpc_training",
    "mca_drake.learning.policy": "mca_drake.learning.policy_network",
    "mca_drake.live.rsi_driver": "mca_drake.live.rsi.driver",
    "mca_drake.live.rsi_emulator": "mca_drake.live.rsi.emulator",
    "mca_drake.live.rsi_link": "mca_drake.live.rsi.link",
    "mca_drake.live.rsi_motion": "mca_drake.live.rsi.motion",
    "mca_drake.live.rsi_xml": "mca_drake.live.rsi.xml",
}


class _AliasLoader(importlib.abc.Loader):
    """Loads a former name as the module it now is (already executed: nothing to run)."""

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        new_name = MODULE_ALIASES[spec.name]
        warnings.warn(
            f"{spec.name} is deprecated; import {new_name} instead",
            DeprecationWarning,
            stacklevel=2,
        )
        return importlib.import_module(new_name)

    def exec_module(self, module: ModuleType) -> None:
        pass


class _AliasFinder(importlib.abc.MetaPathFinder):
    """Finds the former names of `MODULE_ALIASES`, and nothing else."""

    def find_spec(self, fullname, path=None, target=None):
        if fullname not in MODULE_ALIASES:
            return None
        return importlib.machinery.ModuleSpec(fullname, _AliasLoader())


def install_module_aliases() -> None:
    """Makes the former module names importable (once per process)."""
    if not any(isinstance(finder, _AliasFinder) for finder in sys.meta_path):
        sys.meta_path.insert(0, _AliasFinder())
