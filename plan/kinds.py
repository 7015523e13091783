"""How the plan reaches node classes without depending on the package that defines them.

The node kinds sit above the plan (they import plan modules), so the plan never imports or
names them, not even as a string (tests/test_architecture.py checks both). Importing the
``nodes`` package provides its catalogue here; the scenario checks read it through
:func:`catalogue`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol


class Catalogue(Protocol):
    """The node kinds a scenario may name and how to load a node class."""

    kinds: Mapping[str, str]  # kind -> 'package.module:Class'
    listed: tuple[str, ...]  # the kinds told to users (the test suite's own are not)
    foreign: str  # the class that stands in for a foreign program (scenario key command)
    external: str  # the class of the scenario's external node

    def load(self, ref: str) -> type:
        """The StepNode class named by 'package.module:Class' (raises if it cannot load)."""


_provided: list[Catalogue] = []


def provide(given: Catalogue) -> None:
    """Make ``given`` the catalogue the plan uses (the nodes package calls this on import)."""
    _provided[:] = [given]


def catalogue() -> Catalogue:
    """The provided catalogue; LookupError if the package of node kinds was never imported."""
    if not _provided:
        raise LookupError("no node kinds are known to the plan: import the package of node "
                          "kinds (import nodes) before loading a scenario")
    return _provided[0]


def class_of(spec) -> type | None:
    """The node class of a node spec (its ``kind``, else its ``module``); None where it does
    not load (the scenario's checks report that, naming the key)."""
    kinds = catalogue()
    ref = kinds.kinds.get(spec.kind) if spec.kind else spec.module
    try:
        return kinds.load(ref) if ref else None
    except Exception:  # noqa: BLE001 - the scenario's own checks report it, naming the key
        return None
