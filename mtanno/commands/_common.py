"""Helpers shared by the command modules: error reporting, progress bars, and the option
types that refuse values which make no sense (NaN, an empty name list, a scheduler address
that is none) before a command starts."""

from __future__ import annotations

import functools
import math
import sys

import click

from mtanno.errors import MtannoError

#: How the API's parameter names read on the command line where they are not ``--name``
#: (:meth:`mtanno.errors.MtannoError.for_command`).
ARGUMENT_NAMES = {"training": "TRAINING"}


#: The ``--help`` epilogs that several commands share.
EXIT_BAD_INPUT = "Exit codes: 0 success, 2 bad input."
EXIT_BAD_INPUT_OR_PLOT = "Exit codes: 0 success, 2 bad input or matplotlib missing."
EXIT_PER_CLASS = ("Exit codes: 0 success, 1 some classes failed or a training folder gave no "
                  "example (the others were used), 2 usage error or bad input.")


def user_errors(code: int, *, flags: dict[str, str] | None = None):
    """Turn MtannoError (and an OSError of the file system) into a one-line message and
    exit ``code`` (no traceback). The API's parameter names in the message become the
    command's flags (``features_dir=`` → ``--features-dir``; ``flags`` names those of the
    command that are not ``--name``, beside :data:`ARGUMENT_NAMES`). A reader that closed
    standard output early (``| head``) ends the command quietly with exit code 141
    (:func:`closed_output_edge`)."""

    names = {**ARGUMENT_NAMES, **(flags or {})}

    def deco(fn):
        @functools.wraps(fn)
        def wrapper(*args, **kwargs):
            try:
                return fn(*args, **kwargs)
            except MtannoError as exc:
                click.echo(f"mtanno: {exc.for_command(names)}", err=True)
                sys.exit(getattr(exc, "exit_code", code))  # LockBusy: 3
            except OSError as exc:  # the file system said no where no reader expected it
                closed_output_edge(exc)
                where = f"{exc.filename}: " if exc.filename else ""
                click.echo(f"mtanno: {where}{exc.strerror or exc}", err=True)
                sys.exit(code)

        return wrapper

    return deco


def closed_output_edge(exc: BaseException) -> None:
    """End the command quietly (no message, exit code 141: the SIGPIPE convention) if
    ``exc`` is a broken pipe because the reader of standard output or error is gone
    (``mtanno info X | head -2``); return otherwise (another pipe broke: an error)."""
    if not isinstance(exc, BrokenPipeError):
        return
    from mtanno.util.output import end_closed_output, output_closed

    if output_closed():
        end_closed_output()


def wait_option(fn):
    """``--wait``: wait for another run that holds the output folder's lock instead of
    exiting with code 3 (:func:`mtanno.util.locks.folder_lock`)."""
    return click.option("--wait", is_flag=True,
                        help="If another mtanno run is writing into the same output, wait "
                             "for it to finish instead of exiting with code 3.")(fn)


def inside_input_option(fn):
    """``--inside-input``: allow an output folder that is, or lies inside, an input folder
    (refused otherwise: :func:`mtanno.util.preflight.check_outputs`, ``inside_input``)."""
    return click.option("--inside-input", "inside_input", is_flag=True,
                        help="Allow the output folder to be, or lie inside, an input folder "
                             "(refused otherwise, so that outputs never land among the input "
                             "data by mistake); outputs the next run would read as inputs "
                             "stay refused.")(fn)


class Number(click.FloatRange):
    """A float option inside ``[min, max]`` that is a number: NaN is refused always (it
    passes every comparison, so a range alone lets it through), ±∞ unless ``allow_inf``.
    A refused value is a usage error (exit code 2): ``--tau must be a number ≥ 0, got nan``."""

    name = "number"

    def __init__(self, min: float | None = None, max: float | None = None, *,
                 allow_inf: bool = False, **kwargs):
        super().__init__(min, max, **kwargs)
        self.allow_inf = allow_inf

    def convert(self, value, param, ctx):
        rv = click.FLOAT.convert(value, param, ctx)
        if math.isnan(rv) or (math.isinf(rv) and not self.allow_inf):
            kind = "a number" if self.allow_inf else "a finite number"
            if self.min is not None and self.max is not None:
                kind += f" in [{self.min:g}, {self.max:g}]"
            elif self.min is not None:
                kind += f" ≥ {self.min:g}"
            elif self.max is not None:
                kind += f" ≤ {self.max:g}"
            raise click.UsageError(f"{_option(param)} must be {kind}, got {value}", ctx)
        return super().convert(rv, param, ctx)


def _option(param) -> str:
    """How the user wrote the option (``--tau``), for a message."""
    opts = getattr(param, "opts", None)
    return opts[0] if opts else getattr(param, "name", None) or "the value"


#: τ, the threshold on a match's cost: a number ≥ 0; ∞ is allowed (every match counts).
TAU = Number(min=0, allow_inf=True)
#: δ, the quantization delta of a template: a number in [0, 0.5].
DELTA = Number(0, 0.5)


class NameList(click.ParamType):
    """A comma-separated list of names (``NAME,...``): every name non-empty, so ``''`` or
    ``a,,b`` is a usage error instead of "no names" read as "all". The value stays a
    string (names stripped, joined by commas), as the commands split it."""

    name = "names"

    def convert(self, value, param, ctx):
        names = [n.strip() for n in str(value).split(",")]
        if not all(names):
            raise click.UsageError(f"{_option(param)} must be comma-separated names, none "
                                   f"empty, got {value!r}", ctx)
        return ",".join(names)


NAMES = NameList()


def _check_scheduler(ctx, param, value):
    """The ``--scheduler`` callback: the address checked before the command starts."""
    if value is None:
        return None
    from mtanno.errors import MtannoError
    from mtanno.util.workers import scheduler_address

    try:
        return scheduler_address(value)
    except MtannoError as exc:
        raise click.UsageError(exc.for_command(), ctx) from None


def scheduler_option(fn):
    """``--scheduler ADDRESS|local:N``: run the tasks on a dask.distributed cluster
    (:class:`mtanno.util.workers.DaskPool`, docs/scaling.md) instead of ``--jobs`` processes;
    an address that is none is a usage error (:func:`mtanno.util.workers.scheduler_address`)."""
    return click.option("--scheduler", default=None, metavar="ADDRESS|local:N",
                        callback=_check_scheduler,
                        help="Run the tasks on a dask.distributed cluster (scheduler address, "
                             "or local:N for N local workers) instead of --jobs processes; "
                             "same results. Needs pip install 'mtanno[dask]'; "
                             "docs/scaling.md.")(fn)


#: ``[TRAINING]...``: folders of training examples (ROOT/CLASS/*.parquet) for the commands
#: that learn from them; :func:`training_options` gives the other ways to name them.
training_argument = click.argument("training", nargs=-1, metavar="[TRAINING]...")


def training_options(*, manifest_help: str, truth_help: str):
    """``--manifest``, ``--features-dir``, ``--split`` and ``--truth``: where the training
    examples of learn-mt, learn-keyframes and tune come from
    (:func:`mtanno.templates.training.collect_sources`); ``manifest_help`` and ``truth_help``
    say what each command makes of them."""
    return stack(
        click.option("--manifest", type=click.Path(dir_okay=False), default=None,
                     help=manifest_help),
        click.option("--features-dir", type=click.Path(file_okay=False), default=None,
                     help="With --manifest: folder holding the feature files, mirroring the "
                          "manifest's file paths (DIR/<file>.parquet)."),
        click.option("--split", default=None, metavar="NAME",
                     help="With --manifest: use only rows whose split column is NAME "
                          "(e.g. train)."),
        click.option("--truth", type=click.Path(dir_okay=False), default=None,
                     help=truth_help))


def stack(*decorators):
    """One decorator that applies ``decorators`` as if they were written one above the other
    in this order (the first outermost): a group of options, or a whole command's decorator
    stack, that several commands share."""

    def deco(fn):
        for d in reversed(decorators):
            fn = d(fn)
        return fn

    return deco


def waiting_note(folder):
    """The ``on_wait`` callback of a folder lock: one line on standard error."""
    return lambda holder: click.echo(f"mtanno: waiting for {holder} to release {folder}",
                                     err=True)


def lock_output(folder, *, wait: bool, what: str = "output folder"):
    """The folder lock of a command's output (:func:`mtanno.util.locks.folder_lock`), saying on
    standard error when it waits."""
    from mtanno.util.locks import folder_lock

    return folder_lock(folder, wait=wait, what=what, on_wait=waiting_note(folder))


def show_progress(quiet: bool) -> bool:
    """Whether a command shows a progress bar: on a terminal, and not with -q."""
    return not quiet and sys.stderr.isatty()


class ProgressBar:
    """A tqdm bar on standard error fed by an API's ``progress(done, total)`` callback
    (``compose``, ``report``, ``index``): shown only where :func:`show_progress` says so,
    made at the first call (when the total is known), closed on leaving the ``with``."""

    def __init__(self, desc: str, unit: str, *, quiet: bool = False):
        self.desc, self.unit = desc, unit
        self.shown = show_progress(quiet)
        self.bar = None

    def __call__(self, done: int, total: int) -> None:
        if not self.shown:
            return
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(total=total, unit=self.unit, desc=self.desc)
        self.bar.total = total
        self.bar.update(done - self.bar.n)

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            self.bar.close()
