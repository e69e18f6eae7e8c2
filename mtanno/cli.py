"""Command line: a thin Click layer over the Python API.

Exit codes: 0 success, 1 some inputs failed (the others were processed), 2 usage error or
bad input, 3 output locked by another run, 130 interrupted (SIGINT or SIGTERM), 129 hung up
(SIGHUP), 141 standard output closed by its reader (``mtanno info X | head``: no message,
the SIGPIPE convention). Errors a user can fix are printed as one line ``mtanno: path:line: what is
wrong``, usage errors too; an interruption as ``mtanno: interrupted (SIGINT)``. The
``mtanno`` program starts in :mod:`mtanno.__main__`, which handles the signals before this
module is imported and after the command returned.
"""

from __future__ import annotations

import importlib
import os
import pkgutil
import sys

import click

import mtanno.commands
from mtanno._version import __version__

#: Exit code of a command stopped by SIGINT or SIGTERM (128 + SIGINT, as shells report it);
#: SIGHUP gives 129 (:func:`mtanno.util.workers.exit_code`).
EXIT_INTERRUPTED = 130


class _UsageLine(click.UsageError):
    """A usage error (bad option value, unknown option, missing argument) as one line,
    ``mtanno: <what is wrong> (see 'mtanno CMD --help')``, exit code 2, instead of Click's
    usage, hint and error lines."""

    def __init__(self, exc: click.UsageError):
        super().__init__(exc.format_message(), exc.ctx)

    def show(self, file=None) -> None:
        where = self.ctx.command_path if self.ctx is not None else "mtanno"
        click.echo(f"mtanno: {self.format_message().rstrip('.')} (see '{where} --help')",
                   err=True)


def _one_line(exc: click.UsageError) -> click.UsageError:
    # "no arguments: show the help" is a UsageError too, and must show the help
    if isinstance(exc, (_UsageLine, getattr(click.exceptions, "NoArgsIsHelpError", ()))):
        return exc
    return _UsageLine(exc)


class _Main(click.Group):
    """The ``mtanno`` group: records the command line for the provenance of outputs, says
    when numba compiles the kernels (:mod:`mtanno.util.jitnote`), and turns an interruption
    (SIGINT, or SIGTERM or SIGHUP handled like it, see :mod:`mtanno.util.workers`) into one
    line and exit code 130 (129 for SIGHUP) instead of Click's "Aborted!" and 1; usage
    errors are one line too (:class:`_UsageLine`)."""

    def main(self, args=None, prog_name=None, **extra):
        from mtanno.errors import MtannoError
        from mtanno.util.provenance import set_command_line
        from mtanno.util.stdout import guarded_stdout

        set_command_line(["mtanno", *(sys.argv[1:] if args is None else args)])
        try:  # a full device under standard output says so (help texts too)
            with guarded_stdout():
                return super().main(args=args, prog_name=prog_name, **extra)
        except MtannoError as exc:  # outside a command's own error report (--help)
            click.echo(f"mtanno: {exc}", err=True)
            sys.exit(2)

    def make_context(self, info_name, args, parent=None, **extra):
        try:  # the group's own options (mtanno --bogus)
            return super().make_context(info_name, args, parent=parent, **extra)
        except click.UsageError as exc:
            raise _one_line(exc) from None
        except BrokenPipeError as exc:  # mtanno --help | head -1
            from mtanno.commands._common import closed_output_edge

            closed_output_edge(exc)
            raise

    def invoke(self, ctx):
        from mtanno.errors import interrupted_line
        from mtanno.util.jitnote import install_compile_note
        from mtanno.util.workers import Interrupted, interruptible, must_hard_exit

        # one line on stderr if kernels must be compiled first (not with -q: _quiet_note)
        install_compile_note().set_quiet(False)
        try:
            with interruptible():
                return super().invoke(ctx)
        except click.UsageError as exc:
            raise _one_line(exc) from None
        except BrokenPipeError as exc:  # outside user_errors (Click's help, a summary line)
            from mtanno.commands._common import closed_output_edge

            closed_output_edge(exc)
            raise
        except KeyboardInterrupt as exc:
            name = exc.name if isinstance(exc, Interrupted) else "SIGINT"
            code = exc.exit_code if isinstance(exc, Interrupted) else EXIT_INTERRUPTED
            click.echo(interrupted_line(name), err=True)
            if must_hard_exit() and sys.stdout is sys.__stdout__:  # not under CliRunner
                # a stopped worker pool could hold up the interpreter's shutdown
                sys.stdout.flush()
                sys.stderr.flush()
                os._exit(code)
            sys.exit(code)


@click.group(cls=_Main, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="mtanno")
def main() -> None:
    """mtanno: find, retrieve and annotate human motions in mocap archives.

    The stages pass files: `mtanno features` turns ASF/AMC and BVH files into Parquet
    feature files (40 boolean relational features per frame at 30 Hz), which later stages
    read. Run `mtanno COMMAND --help` for each command.
    """


def _silence_note(ctx, param, value):
    """The callback of every command's ``-q``/``--quiet``: no compile note either."""
    if value:
        from mtanno.util.jitnote import silence

        silence()
    return value


def _quiet_note(command: click.Command) -> None:
    """Make ``-q``/``--quiet`` of ``command`` (and of its subcommands) silence the compile
    note (:mod:`mtanno.util.jitnote`), so a quiet run prints nothing but errors."""
    for param in command.params:
        if param.name == "quiet" and param.callback is None:
            param.callback = _silence_note
    for sub in getattr(command, "commands", {}).values():
        _quiet_note(sub)


def _register_command_modules() -> None:
    """Add the commands of every module in :mod:`mtanno.commands` (each lists its Click
    commands in ``COMMANDS``), so a pipeline stage brings its own command module."""
    for info in sorted(pkgutil.iter_modules(mtanno.commands.__path__), key=lambda i: i.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"mtanno.commands.{info.name}")
        for command in getattr(module, "COMMANDS", ()):
            _quiet_note(command)
            main.add_command(command)


_register_command_modules()


if __name__ == "__main__":  # pragma: no cover
    main()
