"""Errors raised by mocaplib.

Every error says *where* (file, and marker, trial or entry when known), *what* went wrong and,
when there is one, *what to do*. The CLI prints ``str(error)`` and exits non-zero without a
traceback; library code never imports the CLI.
"""

from __future__ import annotations

import os


class MocapError(Exception):
    """Base class of every error mocaplib raises on purpose.

    Parameters
    ----------
    message
        What is wrong, in one sentence.
    path
        The file concerned, if any; it is put in front of the message.
    hint
        What the user can do about it; appended after the message.
    """

    def __init__(self, message: str, *, path: str | os.PathLike | None = None,
                 hint: str | None = None):
        self.message = message
        self.path = None if path is None else os.fspath(path)
        self.hint = hint
        super().__init__(str(self))

    def __str__(self) -> str:
        text = self.message if self.path is None else f"{self.path}: {self.message}"
        return text if not self.hint else f"{text} ({self.hint})"

    def __reduce__(self):  # keep errors picklable across process pools
        return (_rebuild, (type(self), self.message, self.path, self.hint))


def _rebuild(cls, message, path, hint):
    return cls(message, path=path, hint=hint)


class C3DError(MocapError):
    """A C3D file cannot be read: not a C3D, truncated, corrupt or unsupported."""


class ProtocolError(MocapError):
    """A marker-set protocol is malformed, or a trial does not match any protocol."""


class CalibrationError(MocapError):
    """The subject's skeleton cannot be calibrated from the markers given."""


class FitError(MocapError):
    """Joint angles cannot be fitted to the markers."""


class EventError(MocapError):
    """Gait events or cycles cannot be found in a capture."""


class NoCycleError(EventError):
    """A capture that holds no complete cycle (nor rest): it gives no library entry, which a
    build reports as such, not as a failure."""


class LibraryError(MocapError):
    """A motion library file is malformed, invalid or cannot be written."""


class SynthError(MocapError):
    """A synthetic capture cannot be generated from the command or plan given."""


#: Hint of an error about coordinates that are not in the units the file states.
UNITS_HINT = ("check POINT:UNITS: millimetres stored as 'm' make every length 1000 times too "
              "large, metres stored as 'mm' 1000 times too small; re-export the file")

#: Distance (m) under which two markers count as at one place. Metres stored as 'mm' still
#: leave markers on a segment at least 0.05 mm apart, 50 times more.
MIN_MARKER_SPREAD = 1e-6

#: Hint of an error about markers that do not spread (every marker at one place): no units
#: fix that, the file holds no body.
SPREAD_HINT = ("markers on a body lie centimetres apart; markers at one place come from an "
               "export or labelling fault, not from the units: re-export the capture's "
               "labelled marker trajectories from the capture software")
