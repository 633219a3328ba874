"""A `mocaplib query` BVH and glTF as Blender itself poses them (benchmarks/blender_feet.py,
whose page is docs/results/blender.md): Blender's default imports, every bone where an
independent reader puts it, the file's frame rate and frames, the feet planted. Skipped where
Blender is not installed (Debian: apt-get install blender)."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest

from mocaplib.cli import main

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from blender_feet import BELOW, JOINTS, gltf_importer_missing, measure  # noqa: E402
from character import HOVER, SLIDE  # noqa: E402

BLENDER = shutil.which("blender")
pytestmark = pytest.mark.skipif(BLENDER is None, reason="Blender is not installed "
                                                        "(Debian: apt-get install blender)")


@pytest.mark.usefixtures("sample_dir")
@pytest.mark.parametrize("name", ["walk.bvh", "walk.glb"])
def test_blender_poses_a_query_walk_as_the_reader_does_with_planted_feet(tmp_path, name):
    from test_planting import sample_library

    if name.endswith(".glb") and (missing := gltf_importer_missing(BLENDER)):
        pytest.skip(missing)
    _, library = sample_library()
    bvh = tmp_path / "walk.bvh"
    assert main(["query", str(library), "1.2", "0.1", "0", "--bvh", str(bvh), "--gltf",
                 str(bvh.with_suffix(".glb")), "--cycles", "3", "--rate", "60"]) == 0
    row = measure("walk", tmp_path / name, False, BLENDER)
    # measured: joints 0.0005 mm (BVH) and 0.0017 mm (glTF) from the readers, 60 fps, 198
    # frames keyed, slide 0.001 mm, 0.0007 mm below the floor, hover 0.00003 mm
    assert row["joints_mm"] <= 1000 * JOINTS, row
    assert row["blender_fps"] == pytest.approx(60.0) and row["frames"] == row["blender_frames"]
    assert row["stances"] >= 4, row
    assert row["slide_mm"] <= 1000 * SLIDE and row["below_mm"] <= 1000 * BELOW, row
    assert row["hover_mm"] <= 1000 * HOVER, row
