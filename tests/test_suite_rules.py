"""Rules the test suite keeps, checked on its own source (see tests/README.md).

A test that signals a running process, or starts a second run while a first one works,
must hold the first at a known point (:mod:`held` or the program's ``MTANNO_TEST_PAUSE``
hook) and wait for events; a fixed sleep or a slowed-down run assumes one process outruns
another, and a loaded machine breaks that assumption (issue 31).
"""

from __future__ import annotations

import ast
from pathlib import Path

TESTS = Path(__file__).resolve().parent
#: Calls that send a signal to another process (directly or through a module's helper).
SIGNALLING = {"send_signal", "killpg", "_signalled", "_interrupt"}
#: What holds a run at a known point.
HOLDS = ("start_held", "MTANNO_TEST_PAUSE", "hold=")


def _test_sources() -> dict[str, str]:
    return {str(p.relative_to(TESTS)): p.read_text() for p in sorted(TESTS.rglob("*.py"))}


def _called(node: ast.AST) -> set[str]:
    names = set()
    for call in ast.walk(node):
        if isinstance(call, ast.Call):
            f = call.func
            names.add(f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", ""))
    return names


def sleeps_outside_loops(sources: dict[str, str]) -> list[str]:
    """``name:line`` of every ``sleep(...)`` call not inside a ``while`` loop."""
    bad = []
    for name, text in sources.items():
        tree = ast.parse(text)
        parents = {c: p for p in ast.walk(tree) for c in ast.iter_child_nodes(p)}
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and _called(node) >= {"sleep"} and (
                    getattr(node.func, "attr", getattr(node.func, "id", "")) == "sleep"):
                up = node
                while up in parents and not isinstance(up, ast.While):
                    up = parents[up]
                if not isinstance(up, ast.While):
                    bad.append(f"{name}:{node.lineno}")
    return bad


def unheld_signals(sources: dict[str, str]) -> list[str]:
    """``name::test`` of every test function that starts a process and signals it without
    a hold point."""
    bad = []
    for name, text in sources.items():
        for node in ast.parse(text).body:
            if not (isinstance(node, ast.FunctionDef) and node.name.startswith("test_")):
                continue
            body = ast.get_source_segment(text, node) or ""
            if "Popen" not in body and "_interrupt" not in body:
                continue
            if _called(node) & SIGNALLING and not any(h in body for h in HOLDS):
                bad.append(f"{name}::{node.name}")
    return bad


def test_sleep_only_in_polling_loops():
    """``time.sleep`` in a test waits for an event in a loop, never a fixed time."""
    bad = sleeps_outside_loops(_test_sources())
    assert not bad, f"time.sleep outside a polling loop: {bad}"


def test_no_run_is_slowed_down_to_lose_a_race():
    hits = [n for n, text in _test_sources().items()
            if n != "test_suite_rules.py" and "_DELAY" in text]
    assert not hits, f"a run slowed down by a delay instead of held at a point: {hits}"


def test_every_signalled_run_is_held_at_a_known_point():
    bad = unheld_signals(_test_sources())
    assert not bad, f"tests that signal a run not held at a known point: {bad}"


def test_the_rules_catch_what_they_forbid():
    """The checks find a fixed sleep and an unheld signal, and pass a held, polled run."""
    bad = ("import time, subprocess\n"
           "def test_x():\n"
           "    p = subprocess.Popen(['x'])\n"
           "    time.sleep(1)\n"
           "    p.send_signal(2)\n")
    good = ("import time\n"
            "def test_y():\n"
            "    p = start_held(['x'], hold='m:f', after=1, gate=g)  # Popen inside\n"
            "    while not g.exists():\n"
            "        time.sleep(0.01)\n"
            "    p.send_signal(2)\n")
    assert sleeps_outside_loops({"bad.py": bad}) == ["bad.py:4"]
    assert unheld_signals({"bad.py": bad}) == ["bad.py::test_x"]
    assert sleeps_outside_loops({"good.py": good}) == unheld_signals({"good.py": good}) == []
