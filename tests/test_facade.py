"""One façade per capture: the package's ``fit`` and ``process`` give what the commands and the
build give, not a cousin of it."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import SAMPLES, real_files

import mocaplib
from mocaplib.cli import main
from mocaplib.model import fitting

WALK = SAMPLES / "walk_straight_normal.c3d"
REST = SAMPLES / "rest.c3d"


def command_angles(monkeypatch, argv: list[str]) -> np.ndarray:
    """The joint angles (F, D) ``mocaplib fit`` computes for ``argv``: the motion its fit
    returns, recorded before anything is written (the CSV keeps 9 digits)."""
    fitted = []
    real = fitting.fit_capture

    def recording(*args, **kwargs):
        fitted.append(real(*args, **kwargs))
        return fitted[-1]

    monkeypatch.setattr(fitting, "fit_capture", recording)
    assert main(["fit", *argv]) == 0
    monkeypatch.undo()
    assert len(fitted) == 1
    return fitted[0].motion.q


@pytest.mark.usefixtures("sample_dir")
def test_the_package_fit_is_the_fit_command_on_a_sample(monkeypatch, tmp_path):
    q = command_angles(monkeypatch, [str(WALK), "--static", str(REST), "--static-pose", "neutral",
                                     "-o", str(tmp_path / "a.csv")])
    motion = mocaplib.fit(WALK, static=REST, static_pose="neutral")
    np.testing.assert_allclose(motion.q, q, rtol=0, atol=1e-9)   # the same computation
    # and the CSV the command wrote holds those angles to its 9 significant digits
    written = np.loadtxt(tmp_path / "a.csv", delimiter=",", skiprows=1)[:, 1:]
    np.testing.assert_allclose(written, q, rtol=5e-9, atol=1e-12)


@pytest.mark.parametrize("path", real_files(), ids=lambda p: p.name)
def test_the_package_fit_is_the_fit_command_on_the_real_files(monkeypatch, tmp_path, path):
    q = command_angles(monkeypatch, [str(path), "-o", str(tmp_path / "a.csv")])
    np.testing.assert_allclose(mocaplib.fit(path).q, q, rtol=0, atol=1e-9)


@pytest.mark.usefixtures("sample_dir")
def test_process_gives_the_cycles_of_the_cycles_command_and_the_entry_of_the_build(
        capsys, tmp_path):
    capture = SAMPLES / "walk_curve_r2_left_normal.c3d"
    done = mocaplib.process(capture, static=REST, static_pose="neutral")
    assert main(["cycles", str(capture), "--static", str(REST), "--static-pose", "neutral",
                 "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["cycles"]
    assert [r["chosen"] for r in rows] == [c.chosen for c in done.cycles]
    # The same computation; BLAS threads (a command's several, a build worker's one) change
    # sums in their last bit, which the pattern fits carry to about 1e-10 m/s.
    np.testing.assert_allclose([r["v"] for r in rows], [c.velocities.v for c in done.cycles],
                               rtol=0, atol=1e-9)
    result = mocaplib.build_library([capture], mocaplib.BuildSettings(static=str(REST),
                                                              static_pose="neutral"),
                            cache_dir=None, progress=False)
    (entry,) = result.library.entries
    chosen = done.chosen
    assert entry.cycle_index == chosen.index
    np.testing.assert_allclose([entry.v, entry.omega, entry.v_l],
                               [chosen.velocities.v, chosen.velocities.omega,
                                chosen.velocities.v_l], rtol=0, atol=1e-9)
    assert done.qc[chosen.index] == pytest.approx(entry.qc, rel=1e-9)
