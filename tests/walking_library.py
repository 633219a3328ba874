"""Libraries of walking cycles built once per session for the poulaine, C3 and retargeting
targets: the shipped synthetic walks and the real lab walks of ../shared/data/c3d."""

from __future__ import annotations

from functools import lru_cache

import pytest

from conftest import SAMPLES, SHARED_C3D

#: The real captures of people walking (not running, jumping or standing) in the shared folder.
REAL_WALKS = ("cmu/07_01.c3d", "cmu/07_12.c3d", "biomechzoo/HC030A05.c3d",
              "biomechzoo/HC030A22.c3d", "motonms_unipd/Walking1.c3d",
              "motonms_unipd/Walking3.c3d", "btkdata/PiG_Motion-FlatFoot-Full.c3d",
              "btkdata/Gait.c3d", "ezc3d_testfiles/Qualisys.c3d", "ezc3d_testfiles/BTS.c3d")


def _library(paths, settings):
    """The library of ``paths`` processed with ``settings`` and, by entry id, the sidecar's
    record of the capture whose chosen cycle it is."""
    from mocaplib.library.format import assemble_library
    from mocaplib.build.workflow import process_capture

    entries, records = [], {}
    for path in paths:
        result = process_capture(path, settings)
        assert result.ok, result.error
        entries += result.entries
        chosen = [c for c in result.diagnostics["cycles"] if c["chosen"]]
        records[f"{path.stem}_c{chosen[0]['index']}"] = result.diagnostics
    return assemble_library(entries, settings=settings.to_dict()), records


@lru_cache(maxsize=1)
def synthetic_walks():
    """The 21 synthetic walks (straight and curved, 3 speeds), chosen cycles, calibrated on the
    session's static as the quick start builds them (without the forward reference)."""
    from mocaplib.build.settings import BuildSettings

    paths = sorted(SAMPLES.glob("walk_*.c3d"))
    if not paths:
        pytest.skip(f"no synthetic walks in {SAMPLES}")
    return _library(paths, BuildSettings(static=str(SAMPLES / "rest.c3d"),
                                         static_pose="neutral"))


@lru_cache(maxsize=1)
def real_walks():
    """The real walks, every complete cycle that passes the default QC."""
    from mocaplib.build.settings import BuildSettings

    paths = [SHARED_C3D / name for name in REAL_WALKS]
    if not all(path.is_file() for path in paths):
        pytest.skip(f"real C3D files not found in {SHARED_C3D}")
    return _library(paths, BuildSettings(all_cycles=True))
