"""Every file type mocaplib writes for other programs, by suffix: :data:`FORMATS`.

Every writer takes the data first, the path last, options keyword-only
(``writer(data, path, /, **options)``) and writes atomically; it returns the path. The data is
what the format holds (:attr:`Format.takes`):

- ``"motion"``, a :class:`~mocaplib.model.motion.Motion` (joint coordinates on a skeleton at a
  rate): ``.csv``, ``.mot``, ``.bvh``, ``.gltf``, ``.glb``;
- ``"model"``, a calibrated :class:`~mocaplib.model.subject.SubjectModel`: ``.osim``;
- ``"markers"``, a :class:`~mocaplib.trial.Trial` (its markers, labels and rate): ``.trc``.

:func:`write` chooses the writer by the path's suffix (or the ``suffix`` given). A motion that
is a whole cycle with both ends (its last frame the first pose one period on) is written
``closed=True``: the formats players loop (:attr:`Format.loops`: BVH, glTF) leave the last
frame out, so that the clip loops without showing a frame twice; tables keep it.
"""

from __future__ import annotations

import importlib
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from ..errors import MocapError

if TYPE_CHECKING:
    from ..model.motion import Motion
    from ..model.subject import SubjectModel
    from ..trial import Trial


@dataclass(frozen=True)
class Format:
    """One file type: what it holds (``description``), the kind of data it takes
    (``"motion"``, ``"model"`` or ``"markers"``), the function that writes it (``function``
    of module ``module``, imported when first used: a command loads only the writers it
    needs) and whether players loop it (``loops``)."""

    description: str
    takes: str
    module: str
    function: str
    loops: bool = False

    @property
    def writer(self) -> Callable[..., Path]:
        """``writer(data, path, /, **options)``."""
        return getattr(importlib.import_module(self.module, __package__), self.function)


#: Suffix -> :class:`Format`, every file type mocaplib writes for other programs.
FORMATS: dict[str, Format] = {
    ".csv": Format("joint coordinates, time_s then one column per DOF (rad, m)", "motion",
                   ".angles_csv", "write_angles_csv"),
    ".mot": Format("OpenSim motion (degrees, m)", "motion", ".opensim", "write_mot"),
    ".bvh": Format("BVH animation (Y up, metres)", "motion", ".bvh", "write_bvh", loops=True),
    ".gltf": Format("glTF 2.0 skeleton and animation (Y up, +Z forward, metres)", "motion",
                    ".gltf", "write_gltf", loops=True),
    ".glb": Format("glTF 2.0 binary: the same in one binary file", "motion", ".gltf",
                   "write_glb", loops=True),
    ".osim": Format("OpenSim model with de Leva's segment masses and inertias", "model",
                    ".opensim", "write_osim"),
    ".trc": Format("OpenSim markers (mm)", "markers", ".opensim", "write_trc"),
}
#: The class (or a base class) name of each kind of data.
_KINDS = {"Motion": "motion", "SubjectModel": "model", "Trial": "markers"}


def suffixes(takes: str) -> tuple[str, ...]:
    """The suffixes of the formats that take ``takes`` data ("motion", "model", "markers")."""
    return tuple(suffix for suffix, fmt in FORMATS.items() if fmt.takes == takes)


def format_of(path: str | os.PathLike, takes: str, *, suffix: str | None = None) -> Format:
    """The :class:`Format` ``path``'s suffix (or ``suffix``) names, which must take ``takes``
    data; :class:`MocapError` naming the path and the suffixes that do otherwise."""
    key = (suffix or Path(path).suffix).lower()
    fmt = FORMATS.get(key)
    if fmt is None or fmt.takes != takes:
        raise MocapError(f"unknown output type {key or '(none)'!r} for a {takes}", path=path,
                         hint=f"end the file name with {', '.join(suffixes(takes))}")
    return fmt


def write(data: "Motion | SubjectModel | Trial", path: str | os.PathLike, /, *,
          suffix: str | None = None, closed: bool = False, **options) -> Path:
    """Write ``data`` to ``path`` in the format of its suffix (or of ``suffix``, e.g. ``".mot"``
    whatever the file is called), atomically; returns the path. ``closed``: ``data`` is a
    motion whose last frame closes the cycle (module docstring). ``options`` go to the
    writer."""
    takes = next((_KINDS[c.__name__] for c in type(data).__mro__ if c.__name__ in _KINDS), None)
    if takes is None:
        raise MocapError(f"cannot write a {type(data).__name__}: a Motion, SubjectModel or "
                         "Trial is expected", path=path)
    fmt = format_of(path, takes, suffix=suffix)
    if closed and fmt.loops and len(data.q) > 1:
        data = replace(data, q=data.q[:-1], residuals=None, failed=None, rejected=None)
    return fmt.writer(data, path, **options)
