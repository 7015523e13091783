"""The garbage collector around a tick loop: what exists before the first tick (modules, the
plan, the world, the built nodes, a fork's inherited heap) lives all run, so it is frozen
out of the collector's full passes, each of which walked all of it (bench.swarm 64 robots
in-process, 5 simulated s: 7 passes, 0.35 s); and a tick's messages live until taken, so
the young passes are made rarer (at CPython's 700 new objects one ran every few
activations and walked them: 978 passes, 0.08 s; at 10,000, 13, 0.003 s). No output
depends on when the collector runs."""

from __future__ import annotations

import gc

YOUNG_OBJECTS = 10_000
"""The collector's threshold for the youngest generation during a tick loop."""


def hold_for_loop() -> tuple[int, ...]:
    """Freeze what exists now and raise the young threshold; the thresholds before, for
    :func:`release_after_loop`."""
    gc.freeze()
    before = gc.get_threshold()
    gc.set_threshold(YOUNG_OBJECTS, *before[1:])
    return before


def release_after_loop(before: tuple[int, ...]) -> None:
    """Undo :func:`hold_for_loop`: the thresholds ``before``, the frozen objects collectable
    again."""
    gc.set_threshold(*before)
    gc.unfreeze()
