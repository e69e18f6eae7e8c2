"""The record of a batch of jobs that goes on past a failure (``mtanno features``,
``mtanno annotate --output-dir``): one outcome per job, in order, each with a ``status``;
the counts by status and the failed ones; every outcome handed to the caller's progress
callback as it is recorded."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Generic, TypeVar

__all__ = ["Outcomes"]

T = TypeVar("T")


@dataclass
class Outcomes(Generic[T]):
    """Outcomes of a batch's jobs; an outcome has a ``status`` (``"failed"`` for a job that
    failed). A batch's summary extends this with its own figures and summary line."""

    outcomes: list[T] = field(default_factory=list)

    def record(self, outcome: T, progress: Callable[[T], None] | None = None) -> None:
        """Append ``outcome`` and pass it to ``progress`` (called once per job)."""
        self.outcomes.append(outcome)
        if progress:
            progress(outcome)

    def count(self, status: str) -> int:
        return sum(o.status == status for o in self.outcomes)

    @property
    def failed(self) -> list[T]:
        return [o for o in self.outcomes if o.status == "failed"]
