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
    code = ("import mocaplib.model.calibration, mocaplib.model.ik\n"
            "from mocaplib import calibrate, fit, SubjectModel\n"
            "assert callable(calibrate) and calibrate.__module__ == 'mocaplib.model.calibration'\n"
            "assert fit.__module__ == 'mocaplib.model.fitting' and isinstance(SubjectModel, type)\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr


def test_every_export_exists():
    missing = [name for name, module in mocaplib._EXPORTS.items()
               if not hasattr(importlib.import_module(module), name)]
    assert missing == []


#: Modules that cost a noticeable share of a second to import (``python -X importtime``):
#: each is imported by the stage that uses it, never by the package or the command line.
HEAVY = ("scipy", "pandas", "matplotlib", "jsonschema", "pyvista", "jinja2", "PIL", "tqdm",
         "threadpoolctl", "dask", "distributed")


def _imported_after(code: str, *args: str) -> set[str]:
    """The top-level packages in ``sys.modules`` after running ``code`` in a fresh process."""
    program = f"{code}\nimport sys\nprint(' '.join(sorted({{m.split('.')[0] for m in sys.modules}})))"
    done = subprocess.run([sys.executable, "-c", program, *args], cwd=REPO, capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr
    return set(done.stdout.split("\n")[-2].split())


def test_importing_the_package_imports_nothing_heavy_not_even_numpy():
    loaded = _imported_after("import mocaplib")
    assert "mocaplib" in loaded and not loaded & {*HEAVY, "numpy"}, loaded & {*HEAVY, "numpy"}


def test_the_command_line_and_its_help_import_nothing_heavy():
    loaded = _imported_after("import mocaplib.cli\nmocaplib.cli.build_parser().format_help()")
    assert not loaded & set(HEAVY), loaded & set(HEAVY)


def test_inspect_imports_nothing_heavy(sample_dir):
    loaded = _imported_after("import sys\nfrom mocaplib.cli import main\n"
                             "assert main(['inspect', sys.argv[1]]) == 0",
                             str(sample_dir / "walk_straight_normal.c3d"))
    assert "numpy" in loaded and not loaded & set(HEAVY), loaded & set(HEAVY)


def test_fit_imports_nothing_heavy(sample_dir, tmp_path):
    # the marker low-pass, calibration, fit and the CSV need numpy only (Motion.angles, the
    # DataFrame, loads pandas when asked for)
    loaded = _imported_after("import sys\nfrom mocaplib.cli import main\n"
                             "assert main(['fit', sys.argv[1], '-o', sys.argv[2]]) == 0",
                             str(sample_dir / "walk_straight_normal.c3d"),
                             str(tmp_path / "angles.csv"))
    assert "numpy" in loaded and not loaded & set(HEAVY), loaded & set(HEAVY)
    assert (tmp_path / "angles.csv").read_text().startswith("time_s,pelvis_tx,")


def test_fit_imports_neither_numpy_ma_nor_the_library_modules(sample_dir, tmp_path):
    # numpy.ma costs ~7 ms of the command's start-up (the stages of the fit use
    # mocaplib.numeric's reductions instead of numpy's that import it); the library's modules
    # (entry, library, qc, the build's workflow) and hashlib's OpenSSL about 12 ms more
    unused = ("numpy.ma", "mocaplib.library.entry", "mocaplib.library.format", "mocaplib.gait.qc",
              "mocaplib.build.workflow", "hashlib")
    program = ("import sys\nfrom mocaplib.cli import main\n"
               "assert main(['fit', sys.argv[1], '-o', sys.argv[2]]) == 0\n"
               f"print(*[name for name in {unused!r} if name in sys.modules])")
    done = subprocess.run([sys.executable, "-c", program,
                           str(sample_dir / "walk_straight_normal.c3d"),
                           str(tmp_path / "angles.csv")], cwd=REPO, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1] == ""
