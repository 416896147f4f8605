"""The ``adaproj`` command.

``main`` owns the process: it puts the thread policy in force before anything heavy
loads (:mod:`adaproj_edge.threads`), imports only the selected command's module (so
``adaproj --help`` lists the commands without loading numpy), and turns every error
from outside into one line on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
from collections.abc import Collection, Sequence

from adaproj_edge import __version__
from adaproj_edge.errors import AdaprojError
from adaproj_edge.extras import MissingExtraError, missing_extra
from adaproj_edge.threads import apply_thread_policy, thread_report

log = logging.getLogger("adaproj_edge.cli")

EXIT_ERROR = 2
"""Exit status for bad input from outside (an argument, a file, a device)."""
EXIT_BROKEN_PIPE = 141
"""Exit status when the reader of our output went away (128 + SIGPIPE, as a shell
reports a process that SIGPIPE ended)."""
EXIT_INTERRUPTED = 130


def build_parser(selected: Collection[str] | None = None) -> argparse.ArgumentParser:
    """The ``adaproj`` argument parser.

    Parameters
    ----------
    selected : collection of str, optional
        Command names whose modules are imported and whose full parsers are built; the
        others are listed by their summary only. Default: every command, in full.

    Returns
    -------
    argparse.ArgumentParser
        The parser; a parsed command's ``args.run(args)`` runs it.
    """
    from adaproj_edge import commands

    parser = argparse.ArgumentParser(
        prog="adaproj", description="Content- and surface-aware projection."
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log more")
    parser.add_argument(
        "--version", action="version", version=f"adaproj {__version__}", help="say the version"
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in commands.MODULES:
        name = commands.command_name(module)
        if selected is None or name in selected:
            commands.load(module).register(sub)
        else:
            sub.add_parser(name, help=commands.summary(module), add_help=False)
    return parser


def _command_word(argv: Sequence[str]) -> str | None:
    """The command named in ``argv`` (the top-level options take no values)."""
    return next((a for a in argv if not a.startswith("-")), None)


def _describe(e: OSError) -> str:
    """One line for an OS error: what failed, on which file."""
    what = e.strerror or str(e)
    files = [str(f) for f in (e.filename, e.filename2) if f is not None]
    return f"{what}: {' -> '.join(files)}" if files else what


def _quiet_stdout() -> None:
    """Point stdout at /dev/null, so that flushing it at exit cannot fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # stdout without a file descriptor (a test's capture)
        pass


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``adaproj`` with ``argv`` (default: the process's arguments).

    Returns
    -------
    int
        The exit status: 0 done, 2 bad input (one line on stderr), 130 interrupted,
        141 the output's reader went away (``adaproj warp ... | head``).
    """
    apply_thread_policy()
    argv = list(sys.argv[1:] if argv is None else argv)
    command = _command_word(argv)
    args = build_parser(set() if command is None else {command}).parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        try:
            rc = args.run(args)
        except ModuleNotFoundError as e:  # an optional part of the install: say which
            missing = missing_extra(e)
            if missing is None:
                raise
            raise missing from e
        sys.stdout.flush()  # a reader that went away shows here, not at exit
    except MissingExtraError as e:
        print(f"adaproj {args.command} needs {e}", file=sys.stderr)
        return EXIT_ERROR
    except AdaprojError as e:
        print(f"adaproj {args.command}: error: {e}", file=sys.stderr)
        return EXIT_ERROR
    except BrokenPipeError:
        _quiet_stdout()
        return EXIT_BROKEN_PIPE
    except OSError as e:  # a path or device the command met: bad input from outside
        log.debug("%s", e, exc_info=True)
        print(f"adaproj {args.command}: error: {_describe(e)}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print(f"adaproj {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        if log.isEnabledFor(logging.DEBUG):
            log.debug("threads: %s", json.dumps(thread_report()))
    return int(rc or 0)


if __name__ == "__main__":
    sys.exit(main())
