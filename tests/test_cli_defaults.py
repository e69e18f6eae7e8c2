"""The command line's defaults are the API's (issue 23). Where a command module would have
to import a heavy module at start-up only for a constant (every ``mtanno`` run imports every
command module), the option keeps the value and this test holds it equal to the constant."""

from __future__ import annotations

import pytest

from mtanno.cli import main


def _option(path: list[str], name: str):
    cmd = main
    for part in path:
        cmd = cmd.commands[part]
    return next(p for p in cmd.params if p.name == name)


@pytest.mark.parametrize(("path", "name", "constant"), [
    (["learn-keyframes"], "runs", "mtanno.keyframes.learn:DEFAULT_RUNS"),
    (["learn-keyframes"], "columns", "mtanno.keyframes.learn:DEFAULT_COLUMNS"),
    (["learn-keyframes"], "generations", "mtanno.keyframes.ga:GAParams.generations"),
    (["learn-keyframes"], "population", "mtanno.keyframes.ga:GAParams.population"),
    (["show"], "width", "mtanno.info:DEFAULT_WIDTH"),
    (["evaluate-retrieval"], "max_hits", "mtanno.evaluation.retrieval:DEFAULT_MAX_HITS"),
    (["report"], "title", "mtanno.evaluation.report:REPORT_TITLE"),
    (["learn-mt"], "iterations", "mtanno.templates.learn:ITER_MAX"),
    (["learn-mt"], "thresh", "mtanno.templates.learn:ITER_THRESH"),
    (["mt", "show"], "top", "mtanno.templates.describe:TOP_FEATURES"),
])
def test_option_default_is_the_api_constant(path, name, constant):
    import importlib

    module, attr = constant.split(":")
    value = importlib.import_module(module)
    for part in attr.split("."):
        value = getattr(value, part)
    assert _option(path, name).default == value
