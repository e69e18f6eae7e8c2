"""Command modules of the ``mtanno`` command line, one per pipeline stage.

Each module defines its Click commands and lists them in ``COMMANDS``; :mod:`mtanno.cli`
adds every module found here to the ``mtanno`` group. Commands stay thin: they parse
options, call the stage's Python API and report.
"""
