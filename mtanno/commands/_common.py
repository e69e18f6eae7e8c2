"""Helpers shared by the command modules: error reporting, progress bars."""

from __future__ import annotations

import functools
import sys

import click

from mtanno.errors import MtannoError


def user_errors(code: int):
    """Turn MtannoError into a one-line message and exit ``code`` (no traceback)."""

    def deco(fn):
        @functools.wraps(fn)
        def wrapper(*args, **kwargs):
            try:
                return fn(*args, **kwargs)
            except MtannoError as exc:
                click.echo(f"mtanno: {exc}", err=True)
                sys.exit(code)

        return wrapper

    return deco


def show_progress(quiet: bool) -> bool:
    return not quiet and sys.stderr.isatty()
