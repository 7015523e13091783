"""The collector's hold over a tick loop is released as it was (runtime.collector)."""

import gc

from runtime.collector import YOUNG_OBJECTS, hold_for_loop, release_after_loop


def test_hold_freezes_and_raises_the_young_threshold_and_release_undoes_both():
    before_threshold, before_frozen = gc.get_threshold(), gc.get_freeze_count()
    held = hold_for_loop()
    try:
        assert held == before_threshold
        assert gc.get_threshold() == (YOUNG_OBJECTS, *before_threshold[1:])
        assert gc.get_freeze_count() > before_frozen
    finally:
        release_after_loop(held)
    assert gc.get_threshold() == before_threshold
    assert gc.get_freeze_count() == 0
