"""mocaplib: optical motion capture of walking people (C3D) to a validated motion library.

Public names are imported lazily, so ``import mocaplib`` stays fast and a stage's heavy
dependencies (pyvista, matplotlib) load only when that stage is used.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

_EXPORTS = {
    # errors and the containers users load
    "MocapError": "mocaplib.errors",
    "C3DError": "mocaplib.errors",
    "Trial": "mocaplib.trial",
    "Event": "mocaplib.trial",
    "Skeleton": "mocaplib.skeleton",
    "Motion": "mocaplib.model.motion",
    "SubjectModel": "mocaplib.model.subject",
    "GaitEvent": "mocaplib.gait.foot_events",
    "Cycle": "mocaplib.gait.cycles",
    "Library": "mocaplib.library.format",
    "LibraryEntry": "mocaplib.library.entry",
    "ControlSpace": "mocaplib.library.controlspace",
    # one capture, as the commands run it
    "read_c3d": "mocaplib.io.c3d",
    "fit": "mocaplib.model.fitting",
    "fit_capture": "mocaplib.model.fitting",
    "process": "mocaplib.build.capture",
    "ProcessedCapture": "mocaplib.build.capture",
    # the stages one by one
    "filter_trial": "mocaplib.model.filtering",
    "calibrate": "mocaplib.model.calibration",
    "detect_events": "mocaplib.gait.events",
    "analyse_cycles": "mocaplib.gait.cycles",
    # a library: built, loaded, checked, reported
    "build_library": "mocaplib.build.pipeline",
    "BuildSettings": "mocaplib.build.settings",
    "load_library": "mocaplib.library.format",
    "validate_library": "mocaplib.library.validation",
    "write_report": "mocaplib.report",
}


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'mocaplib' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(list(globals()) + list(_EXPORTS))
