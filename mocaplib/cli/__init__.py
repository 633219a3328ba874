"""The ``mocaplib`` command line: a thin layer that parses options and calls the library.

No algorithm lives here. Each sub-command is a module in this package with a
``register(subparsers)`` function; errors a user can cause (:class:`MocapError`) are printed
as one line (line feeds in it escaped) without a traceback. Exit codes: 0 success, 1 failure
(some input bad), 2 usage. A negative number in exponent form (``-5e-05``) is a value, as
``-5`` is.
Output that the console's encoding cannot show (ω, ° on an ASCII or cp1252 stdout) is
written with ``?`` in its place rather than stopping the command, and control characters in
what is printed (file names, labels) are escaped.

Every sub-command is registered at start-up, so each imports the stages it runs inside its
``_run``: ``mocaplib --help`` loads no stage and a command loads only its own (``mocaplib fit``
neither the library's modules nor scipy; the start-up each costs is measured in
docs/results/end_to_end.md and held by tests/test_package.py).
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import signal
import sys
from contextlib import contextmanager

from .. import __version__
from ..build.threads import one_thread_by_default
from ..errors import MocapError
from ..io import printable

#: Sub-command modules, in the order ``mocaplib --help`` lists them.
COMMANDS = ("inspect", "protocol", "fit", "events", "cycles", "build", "mirror", "validate",
            "query", "animate", "retarget", "report", "synth")

#: The positional arguments that name a command's one input file (named in an internal error).
INPUT_ARGUMENTS = ("input", "file", "library", "plan")


class _Parser(argparse.ArgumentParser):
    """argparse's parser, taking a negative number in exponent form (``-5e-05``, ``-1.2E3``:
    how Python and most tools print small numbers) for a value, as it takes ``-5`` and
    ``-0.5``, not for an unknown option. Its sub-commands' parsers are of this class too."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        # argparse's own test of a negative number (no exponent), widened
        self._negative_number_matcher = _NEGATIVE_NUMBER


#: A negative number, with or without a fraction and an exponent.
_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="mocaplib",
        description="Turn C3D captures of walking people into a validated motion library.")
    parser.add_argument("--version", action="version", version=f"mocaplib {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"{__name__}.{name}").register(sub)
    parser.set_defaults(parsers=sub.choices)  # each sub-command's parser, by name
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code (also used by the console script). Ctrl-C
    at any moment, loading included, ends it with one line and exit code 130."""
    try:
        with _interrupts_never_lost():
            one_thread_by_default()          # before the sub-commands load numpy
            _tolerate_unencodable_output()
            streams = sys.stdout, sys.stderr
            sys.stdout, sys.stderr = _Printable(sys.stdout), _Printable(sys.stderr)
            try:
                return _main(argv)
            finally:
                sys.stdout, sys.stderr = streams
    except KeyboardInterrupt:
        return interrupted()
    except ImportError as exc:   # a broken install, or Ctrl-C while an extension module loads
        return unloadable(exc)


@contextmanager
def _interrupts_never_lost():
    """Within it, a Ctrl-C that lands in a finalizer or a callback (an object's ``__del__``,
    a module lock's weakref callback while a module loads), where Python cannot raise it and
    prints it as an "Exception ignored" traceback instead, is raised 10 ms later (SIGALRM),
    once out of it: every Ctrl-C ends the command with one line. Without interval timers
    (Windows) nothing changes. The hook and handler before it are put back after it."""
    if not hasattr(signal, "setitimer"):
        yield
        return
    hook, handler = sys.unraisablehook, signal.signal(signal.SIGALRM, _interrupt_again)

    def put_off(unraisable):
        if issubclass(unraisable.exc_type, KeyboardInterrupt):
            signal.setitimer(signal.ITIMER_REAL, 0.01)
        else:
            hook(unraisable)

    sys.unraisablehook = put_off
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        sys.unraisablehook = hook
        signal.signal(signal.SIGALRM, handler)


def _interrupt_again(signum, frame) -> None:
    """The SIGALRM of :func:`_interrupts_never_lost`: the Ctrl-C put off."""
    raise KeyboardInterrupt


def interrupted() -> int:
    """Say that the command was interrupted (Ctrl-C); its exit code, 130."""
    print("mocaplib: interrupted", file=sys.stderr)
    return 130


def unloadable(exc: ImportError) -> int:
    """Say, in one line, that a module mocaplib needs could not be loaded; exit code 1. (A
    Ctrl-C landing inside a C extension's own imports reaches Python as such an error.)"""
    lines = str(exc.__cause__ or exc).strip().splitlines() or [type(exc).__name__]
    print(f"mocaplib: error: a module it needs could not be loaded ({lines[0]}); if it was not "
          "interrupted, reinstall mocaplib and its dependencies in a fresh environment",
          file=sys.stderr)
    return 1


def _main(argv: list[str] | None) -> int:
    from ._common import UsageError, apply_protocol_options  # loads numpy: after the threads

    parser = build_parser()
    try:
        args, unknown = parser.parse_known_args(argv)
        if unknown:  # said by the sub-command's parser, so that its own usage is shown
            args.parsers[args.command].error(f"unrecognized arguments: {' '.join(unknown)}")
    except SystemExit as exc:  # argparse: --help/--version (0) or a usage error (2)
        return int(exc.code or 0)
    try:
        apply_protocol_options(args)
        return int(args.run(args) or 0)
    except UsageError as exc:
        print(f"mocaplib {args.command}: error: {printable(str(exc), keep='')}",
              file=sys.stderr)
        return 2
    except MocapError as exc:
        print(f"mocaplib {args.command}: error: {printable(str(exc), keep='')}",
              file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return interrupted()
    except BrokenPipeError:  # output piped into `head` and the like: not an error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # as the Python docs advise
        return 0
    except Exception as exc:  # a bug, or an input no check foresaw: one line, no traceback
        named = [os.fspath(getattr(args, name)) for name in INPUT_ARGUMENTS
                 if isinstance(getattr(args, name, None), (str, os.PathLike))]
        print(f"mocaplib {args.command}: error: internal error"
              + printable(f"{' with ' + ', '.join(named) if named else ''}: "
                          f"{type(exc).__name__}: {exc} ", keep="")
              + "(a bug in mocaplib: please report it with the command and its input files)",
              file=sys.stderr)
        return 1


class _Printable:
    """A text stream writing control characters escaped (:func:`mocaplib.io.printable`; line
    feeds, tabs and the carriage returns of the progress bar kept): a file name or a C3D
    label cannot move the cursor or re-colour the terminal that shows it."""

    def __init__(self, stream):
        self._stream = stream

    def write(self, text: str) -> int:
        return self._stream.write(printable(text, keep="\n\t\r"))

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _tolerate_unencodable_output() -> None:
    """Replace, rather than fail on, characters stdout/stderr cannot encode."""
    for stream in (sys.stdout, sys.stderr):
        if getattr(stream, "errors", None) == "strict" and hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="replace")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
