"""Former module names still import, warn, and are the very modules they were renamed to."""

from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path

import pytest

from mca_drake.deprecation import MODULE_ALIASES


@pytest.mark.parametrize("old_name", sorted(MODULE_ALIASES))
def test_a_former_name_warns_and_is_the_new_module(old_name):
    sys.modules.pop(old_name, None)
    with pytest.warns(DeprecationWarning, match=MODULE_ALIASES[old_name].replace(".", r"\.")):
        old = importlib.import_module(old_name)
    assert old is importlib.import_module(MODULE_ALIASES[old_name])


def test_a_from_import_of_a_former_name_gives_the_same_class():
    sys.modules.pop("mca_drake.systems.classical_washout", None)
    with pytest.warns(DeprecationWarning):
        from mca_drake.systems.classical_washout import ClassicalWashout
    from mca_drake.systems.washout import ClassicalWashout as CurrentWashout

    assert ClassicalWashout is CurrentWashout


def test_an_unknown_module_is_still_an_import_error():
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("mca_drake.systems.no_such_module")


def test_former_names_have_no_file_left():
    """A former name is answered by the finder only: no stale copy sits at the old path."""
    package_root = importlib.import_module("mca_drake").__path__[0]
    for old_name in MODULE_ALIASES:
        relative = old_name.split(".", 1)[1].replace(".", "/")
        assert importlib.util.find_spec(old_name.rsplit(".", 1)[0]) is not None
        assert not (Path(package_root) / f"{relative}.py").exists()
