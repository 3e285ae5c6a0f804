"""The lattice and search settings of a plan (:class:`PlanOptions`), apart from the planning chain
(:mod:`maps.chain` re-exports it) so that a command can build and check them without importing the planner."""

from __future__ import annotations

from dataclasses import dataclass

from maps.geo import MapError

# how a move settles onto the lattice, as the helm's phase: "lattice", the autopilot's tight tolerance (0.2 deg,
# 1 % of a length off the line); "ship", the tolerance scaled to the ship for confined water (maps.autopilot.steady_enough)
SETTLE_PHASES = {"lattice": "settle", "ship": "steady"}


@dataclass
class PlanOptions:
    """Lattice and search settings (defaults: what a master would sail; see the CLI help)."""

    resolution: float | None = None  # lattice spacing, m (default ~4 ship lengths)
    headings: int = 16
    heuristic: str = "admissible"
    weights: tuple[float, float, float] = (1.0 / 120.0, 1.0, 10.0)  # (8.9) for the thesis heuristic
    margin: float = 20.0  # hard clearance of the swept hull, m
    split: bool = False
    size: tuple[int, int] = (35, 44)
    sub: int = 8
    basic_cost: float = 1.0
    spot_turns: bool = True
    ukc_m: float = 0.5
    max_expansions: int = 30_000_000
    replans: int = 3
    clearance_lengths: float = 2.0  # soft zone: moves within this many ship lengths of an obstacle cost more
    clearance_cost: float = 0.5  # extra cost (in basic moves) of a move inside the soft zone
    run_in_s: float | None = None  # steady run-in before each execute point (default max(60 s, 2 L / U))
    smooth: bool = True
    max_memory_gib: float = 2.0
    # how moves settle onto the lattice: "lattice" (the autopilot's tight tolerance) or "ship" (scaled to the ship,
    # maps.autopilot.steady_enough); the planner switches a rudder ship to "ship" where its library does not fit
    settle: str = "lattice"

    def check(self) -> None:
        if self.headings not in (4, 8, 16):
            raise MapError(f"--headings must be 4, 8 or 16, got {self.headings}")
        if self.margin < 0:
            raise MapError(f"--margin must be >= 0 m, got {self.margin:g}")
        if self.resolution is not None and self.resolution <= 0:
            raise MapError(f"--resolution must be > 0 m, got {self.resolution:g}")
        if self.heuristic not in ("admissible", "thesis"):
            raise MapError(f"--heuristic must be 'admissible' or 'thesis', got {self.heuristic!r}")
        if self.settle not in SETTLE_PHASES:
            raise MapError(f"settle must be one of {', '.join(SETTLE_PHASES)}, got {self.settle!r}")
        if self.run_in_s is not None and self.run_in_s < 0:
            raise MapError(f"--run-in must be >= 0 s, got {self.run_in_s:g}")
