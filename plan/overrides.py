"""Scenario overrides given on a command line as KEY=VALUE (``--set``)."""

from __future__ import annotations

import yaml


def parse_overrides(pairs: list[str]) -> dict:
    """['seed=3', 'nodes.a.rate=20'] -> {'seed': 3, 'nodes.a.rate': 20} (values are YAML)."""
    out = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise ValueError(f"--set {pair!r}: expected KEY=VALUE")
        out[key] = yaml.safe_load(value)
    return out
