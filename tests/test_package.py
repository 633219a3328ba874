"""The package's lazily exported public names."""

from __future__ import annotations

import importlib.util
import subprocess
import sys

import mocaplib
from conftest import REPO


def test_no_public_name_is_also_a_submodule():
    # Importing a submodule binds it on the package under its own name, so an exported name
    # that is also a submodule's (say `calibrate`) would give the function or the module
    # depending on what was imported first.
    clashes = [name for name in mocaplib._EXPORTS
               if importlib.util.find_spec(f"mocaplib.{name}") is not None]
    assert clashes == []


def test_exports_resolve_to_their_objects_whatever_was_imported_first():
    code = ("import mocaplib.calibration, mocaplib.ik\n"
            "from mocaplib import calibrate, fit, SubjectModel\n"
            "assert callable(calibrate) and calibrate.__module__ == 'mocaplib.calibration'\n"
            "assert fit.__module__ == 'mocaplib.ik' and isinstance(SubjectModel, type)\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr


def test_every_export_exists():
    missing = [name for name, module in mocaplib._EXPORTS.items()
               if not hasattr(importlib.import_module(module), name)]
    assert missing == []
