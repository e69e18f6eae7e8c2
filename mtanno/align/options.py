"""Options of time alignment and their defaults, in a module that imports nothing heavy, so
the command line can show them without loading the kernels."""

from __future__ import annotations

__all__ = ["COSTS", "COST_UNITS", "DEFAULT_BAND", "DEFAULT_COST"]

#: Local costs of stage 2.
COSTS = ("positions", "features")
#: Default local cost.
DEFAULT_COST = "positions"
#: Default widening of the matched segment rectangles, in analysis frames (30 Hz).
DEFAULT_BAND = 4
#: Unit of each cost.
COST_UNITS = {"positions": "leg lengths (mean joint distance)",
              "features": "fraction of differing features"}
